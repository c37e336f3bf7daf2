"""The conveyance's motion: the smoothed time derivative the pipeline takes of logged
signals, and the conveyance's speed where the log lacks it.

Not an equation of the paper; the kinematics every step that speaks of the conveyance's
motion reads (the compensation's acceleration and trip labels, the frames of
:mod:`transforms.kinematics`, discovery's trips and replays), written once here so that
``transforms`` and ``discovery`` (which imports no transforms) share it.

Functions
    :func:`smoothed_derivative` -- Savitzky-Golay derivative per gap-free segment, at each
    segment's own logger rate when sample times are given.
    :func:`conveyance_speed` -- the logged speed where present, else isolated holes
    interpolated, else the depth's smoothed time derivative.

Conventions (contract section 1a): depth [m] below the pithead, increasing downwards;
speed [m/s] positive downwards, so speed = d depth / dt.
"""

from __future__ import annotations

import itertools

import numpy as np
from numba import njit

from physics.filter_design import savgol_coeffs, savgol_filter
from physics.trip_rule import RATE_RATIO, RATE_RUN
from physics.white_noise import difference_noise_sigma

__all__ = [
    "DEADBAND_SIGMAS",
    "SPEED_HOLE_S",
    "conveyance_speed",
    "depth_noise_m",
    "longest_unlogged_s",
    "quantum_of_turns",
    "reading_quantum_m",
    "reading_turns",
    "smoothed_derivative",
]

#: A hole in the logged speed at most this long [s] (from the last logged sample before
#: it to the first after, in one gap-free segment) is interpolated linearly in time.
SPEED_HOLE_S = 1.0


def smoothed_derivative(
    y: np.ndarray,
    segment_id: np.ndarray | None,
    *,
    dt_s: float,
    window_s: float = 0.1,
    polyorder: int = 2,
    out: np.ndarray | None = None,
    time_s: np.ndarray | None = None,
) -> np.ndarray:
    """Time derivative by a Savitzky-Golay filter, each segment on its own.

    A least-squares polynomial of degree ``polyorder`` over a centred window of
    ``window_s`` (odd number of samples, at least ``polyorder + 2``) is
    differentiated at each sample; edges use the polynomial fitted to the first/last
    window (``mode="interp"``). Segments shorter than the window fall back to
    ``numpy.gradient``; single samples give 0. NaN in, NaN out (bridged linearly for
    the filter).

    Parameters
    ----------
    y : numpy.ndarray
        Uniformly sampled values within each segment.
    segment_id : numpy.ndarray or None
        Segment id per sample; None: one segment. With ``time_s``, segments of one
        logger rate each (:func:`physics.trip_rule.segment_ids`).
    dt_s : float
        Nominal sample spacing [s].
    window_s : float
        Smoothing window [s].
    polyorder : int
        Polynomial degree.
    out : numpy.ndarray, optional
        Float64 array of ``y``'s length to write into (a reused buffer); every element
        is written.
    time_s : numpy.ndarray, optional
        Sample times [s]. Given, and a segment's mean spacing off ``dt_s`` by more than
        :data:`physics.trip_rule.RATE_RATIO` (a logger that changed its rate mid-file),
        each segment is differentiated with its own spacing (its median step) and a
        window of ``window_s`` at that spacing; else (one rate) all with ``dt_s``, as
        without times.

    Returns
    -------
    numpy.ndarray
        dy/dt in units of y per second.

    >>> t = np.arange(0.0, 1.0, 0.01)
    >>> dy = smoothed_derivative(3.0 * t**2, None, dt_s=0.01)
    >>> bool(np.allclose(dy, 6.0 * t))
    True
    >>> t = np.r_[np.arange(0.0, 1.0, 0.02), 1.0 + np.arange(0.0, 1.0, 0.01)]  # 50, 100 Hz
    >>> seg = (t >= 1.0).astype(np.int64)
    >>> dy = smoothed_derivative(3.0 * t**2, seg, dt_s=0.02, time_s=t)
    >>> bool(np.allclose(dy, 6.0 * t))
    True

    References
    ----------
    Savitzky, A., Golay, M. J. E. (1964), Anal. Chem. 36(8), 1627-1639,
    doi:10.1021/ac60214a047.
    """
    y = np.asarray(y, dtype=np.float64)
    seg = np.zeros(y.size, dtype=np.int64) if segment_id is None else np.asarray(segment_id)
    if out is None:
        out = np.zeros_like(y)
    if y.size == 0:
        return out
    starts = np.flatnonzero(np.concatenate([[True], seg[1:] != seg[:-1]]))
    bounds = [*starts.tolist(), y.size]
    own = time_s is not None and _rates_differ(time_s, bounds, dt_s)
    for a, b in itertools.pairwise(bounds):
        step = _segment_spacing(time_s, a, b, dt_s) if own else dt_s
        n_win = max(round(window_s / step) | 1, polyorder + 2 | 1)
        _segment_derivative(y[a:b], n_win, polyorder, step, out=out[a:b])
    return out


def _rates_differ(time_s: np.ndarray, bounds: list[int], dt_s: float) -> bool:
    """Whether a segment of more than :data:`~physics.trip_rule.RATE_RUN` samples has a
    mean step off ``dt_s`` by more than :data:`~physics.trip_rule.RATE_RATIO`: the
    logger changed its rate, and ``dt_s`` (the record's median step, which then lies
    anywhere among the rates' steps) is no segment's own spacing."""
    a = np.asarray(bounds[:-1])
    b = np.asarray(bounds[1:])
    long = b - a > RATE_RUN
    if not long.any():
        return False
    a, b = a[long], b[long]
    mean = (time_s[b - 1] - time_s[a]) / (b - a - 1)
    return bool(((mean > RATE_RATIO * dt_s) | (mean * RATE_RATIO < dt_s)).any())


def _segment_spacing(time_s: np.ndarray, a: int, b: int, dt_s: float) -> float:
    """A segment's own spacing, its median step (``dt_s`` for a single sample)."""
    if b - a < 2:
        return dt_s
    return float(np.median(np.diff(time_s[a:b])))


def _segment_derivative(
    part: np.ndarray, n_win: int, polyorder: int, dt_s: float, *, out: np.ndarray
) -> None:
    """:func:`smoothed_derivative` of one segment, written into ``out`` (its slice)."""
    bad = ~np.isfinite(part)
    if bad.all():
        out[:] = np.nan
        return
    if bad.any():
        idx = np.arange(part.size)
        part = np.interp(idx, idx[~bad], part[~bad])
    if part.size >= _DIRECT_FACTOR * n_win:
        d = _savgol_derivative(part, n_win, polyorder, dt_s, out=out)
        if bad.any():
            d[bad] = np.nan
        return
    if part.size >= n_win:
        d = savgol_filter(part, n_win, polyorder, deriv=1, delta=dt_s)
    elif part.size >= 2:
        d = np.gradient(part, dt_s)
    else:
        d = np.zeros(1)
    d[bad] = np.nan
    out[:] = d


#: Segments at least this many windows long take the direct convolution path.
_DIRECT_FACTOR = 4


@njit(cache=True, nogil=True)
def _correlate_antisymmetric(y, weights, out):  # pragma: no cover - numba
    """out[i] = sum_k weights[k] (y[i + k + 1] - y[i - k - 1]) for every i whose window fits.

    An odd-symmetric (derivative) filter applied to differences: half the products of a
    plain correlation, and a flat stretch of ``y`` gives exactly 0. Each sum is taken in
    k order; the outputs are computed a block at a time, tap by tap, so that the
    compiler vectorises across them.
    """
    h = weights.shape[0]
    stop = y.shape[0] - h
    block = 512
    acc = np.empty(block)
    for start in range(h, stop, block):
        m = min(block, stop - start)
        for j in range(m):
            acc[j] = 0.0
        for k in range(h):
            w = weights[k]
            ahead = y[start + k + 1 : start + k + 1 + m]
            behind = y[start - k - 1 : start - k - 1 + m]
            for j in range(m):
                acc[j] += w * (ahead[j] - behind[j])
        for j in range(m):
            out[start + j] = acc[j]


def _savgol_derivative(
    y: np.ndarray, n_win: int, polyorder: int, dt_s: float, *, out: np.ndarray | None = None
) -> np.ndarray:
    """:func:`physics.filter_design.savgol_filter` (``deriv=1``), faster.

    The interior is the same filter (:func:`~physics.filter_design.savgol_coeffs`), whose
    first-derivative coefficients are odd-symmetric, applied to the differences
    y[i + k] - y[i - k] by a compiled loop (equal to ``scipy.signal.savgol_filter`` to
    ~1e-14 relative; the least-squares coefficients are odd only to ~1e-14, and a flat
    signal here gives exactly 0, not ~1e-14 y); the ``n_win // 2`` samples at each end
    are the polynomial fits of ``savgol_filter`` on the first and last 2 ``n_win``
    samples, which only see the first and last window.
    """
    y = np.ascontiguousarray(y, dtype=np.float64)
    h = n_win // 2
    # correlation weights for y[i + k] and y[i - k], k = 1..h (savgol_coeffs is in
    # convolution order), made exactly odd
    coeffs = savgol_coeffs(n_win, polyorder, deriv=1, delta=dt_s)[::-1]
    odd = 0.5 * (coeffs[h + 1 :] - coeffs[:h][::-1])
    if out is None:
        out = np.empty_like(y)
    _correlate_antisymmetric(y, np.ascontiguousarray(odd), out)
    span = 2 * n_win
    head = savgol_filter(y[:span], n_win, polyorder, deriv=1, delta=dt_s)
    tail = savgol_filter(y[-span:], n_win, polyorder, deriv=1, delta=dt_s)
    out[:h] = head[:h]
    out[-h:] = tail[-h:]
    return out


#: The derived speed's standstill, in standard deviations of its scatter from the
#: depth's noise: a day's 10^6-10^7 samples cross 6 sigma by chance about never (a
#: Gaussian's two tails beyond 6 sigma hold 2e-9), where 4 sigma made a trip of
#: every few thousand samples.
DEADBAND_SIGMAS = 6.0


def conveyance_speed(
    time_s: np.ndarray,
    speed: np.ndarray,
    depth: np.ndarray,
    segment_id: np.ndarray,
    *,
    dt_s: float,
    window_s: float = 0.5,
    hole_s: float = SPEED_HOLE_S,
    depth_sigma_m: float | None = None,
    depth_quantum_m: float | None = None,
) -> np.ndarray:
    """The conveyance's speed [m/s, positive down] where the log lacks it (a new array).

    The logged ``speed`` where it is finite; a hole of it no longer than ``hole_s``
    between logged samples of one gap-free segment interpolated linearly in time (an
    isolated missing value); elsewhere the time derivative of ``depth`` [m, increasing
    downwards], :func:`smoothed_derivative` over ``window_s`` within each gap-free segment
    (``segment_id``, :func:`physics.trip_rule.segment_ids`; ``dt_s`` its nominal spacing
    [s]), zero within :data:`DEADBAND_SIGMAS` x its scatter from the depth's noise
    (``depth_sigma_m`` [m], else :func:`depth_noise_m` of these samples: a record
    compensated block by block gives the record's, so each block stands still alike),
    4 x that within half a window of a segment's ends, and at least the slope one step
    of the depth's reading makes (``depth_quantum_m`` [m], else :func:`reading_quantum_m`
    of these samples' changes; a record's own, given, for its blocks alike). NaN where
    neither is known
    (a log with neither speed nor depth keeps NaN: the caller's fill applies as before).
    ``time_s`` [s], increasing.

    >>> t = np.arange(0.0, 10.0, 0.02)
    >>> depth = 0.25 * t**2  # 0.5 m/s2 downwards from rest
    >>> v = conveyance_speed(t, np.full(t.size, np.nan), depth, np.zeros(t.size, np.int64),
    ...                      dt_s=0.02)
    >>> bool(np.allclose(v, 0.5 * t))
    True
    """
    t = np.asarray(time_s, dtype=np.float64)
    v = np.array(speed, dtype=np.float64)  # a copy: filled below
    missing = ~np.isfinite(v)
    if not missing.any():
        return v
    seg = np.asarray(segment_id)
    known = np.flatnonzero(~missing)
    if known.size:
        holes = np.flatnonzero(missing)
        after = np.searchsorted(known, holes)  # the first logged sample after each hole
        inside = (after > 0) & (after < known.size)
        holes, after = holes[inside], after[inside]
        p, q = known[after - 1], known[after]
        short = (seg[p] == seg[q]) & (t[q] - t[p] <= hole_s)
        holes, p, q = holes[short], p[short], q[short]
        share = (t[holes] - t[p]) / (t[q] - t[p])
        v[holes] = v[p] + share * (v[q] - v[p])
        missing = ~np.isfinite(v)
    z = np.asarray(depth, dtype=np.float64)
    if missing.any() and np.isfinite(z[missing]).any():
        # dz/dt = (dz/di) / (dt/di), the same filter on both, t on the logger's grid: a
        # dropped sample (at 10 m/s a 0.2 m step of the depth, which a derivative on a
        # uniform grid spreads as 0.4 m/s over its window) counts, the timestamps'
        # jitter does not (the encoder is read on the grid: its depth follows that)
        rate = smoothed_derivative(z, seg, dt_s=dt_s, window_s=window_s, time_s=t)
        grid = _grid_time(t, seg, dt_s)
        pace = smoothed_derivative(grid, seg, dt_s=dt_s, window_s=window_s, time_s=t)
        # (dt_s, or a segment's own spacing, cancels in the ratio)
        ok = pace > 0.0
        derived = np.where(ok, rate / np.where(ok, pace, 1.0), rate)
        # an encoder's noise at standstill is no motion: a least-squares slope over n
        # samples scatters by sigma_z / (dt sqrt(n (n^2 - 1) / 12)); within
        # DEADBAND_SIGMAS of those the conveyance stands (a noisy depth made 343 trips
        # of two)
        sigma_z = depth_noise_m(z) if depth_sigma_m is None else depth_sigma_m
        q = reading_quantum_m(np.diff(z)) if depth_quantum_m is None else depth_quantum_m
        band = _deadband(t, z, seg, sigma_z, q, dt_s=dt_s, window_s=window_s)
        derived = np.where(np.abs(derived) < band, 0.0, derived)
        v[missing] = derived[missing]
    return v


def _deadband(
    t: np.ndarray,
    z: np.ndarray,
    seg: np.ndarray,
    sigma_z: float,
    q: float,
    *,
    dt_s: float,
    window_s: float,
    polyorder: int = 2,
) -> np.ndarray:
    """Per sample, the derived speed's standstill [m/s] (:func:`conveyance_speed`), for the
    derivative :func:`smoothed_derivative` takes there: each segment at the spacing it
    is differentiated with (its own where the logger's rate changes), a segment shorter
    than the window at ``numpy.gradient``'s scatter, and at least the filter's response
    to one quantisation step ``q`` of the depth (an encoder read to the centimetre that
    toggles between two counts at rest: 1.5 q / window at its peak, 0.03 m/s at 1 cm
    over 0.5 s; the band 2 q / window, so a peak at the band is not left to rounding)."""
    band = np.zeros(z.size)
    starts = np.flatnonzero(np.concatenate([[True], seg[1:] != seg[:-1]]))
    bounds = [*starts.tolist(), z.size]
    own = _rates_differ(t, bounds, dt_s)
    for a, b in itertools.pairwise(bounds):
        step = _segment_spacing(t, a, b, dt_s) if own else dt_s
        n_win = max(round(window_s / step) | 1, polyorder + 2 | 1)
        if b - a < 2:
            continue
        if b - a < n_win:  # numpy.gradient: (z[i+1] - z[i-1]) / 2 dt, one-sided at ends
            band[a:b] = max(DEADBAND_SIGMAS * np.sqrt(2.0) * sigma_z, q) / step
            continue
        # a least-squares slope over n samples scatters by sigma_z / (dt sqrt(n (n^2 - 1)
        # / 12)); one quantisation step moves it by up to 1.5 q / (n dt): the band 2 x
        # q / (n dt), as a peak equal to the band came out a single-row trip or none
        # by rounding (whole record against block by block, a review)
        n = max(window_s / step, 3.0)
        deadband = max(
            DEADBAND_SIGMAS * sigma_z / (step * np.sqrt(n * (n * n - 1.0) / 12.0)),
            2.0 * q / (n * step),
        )
        # within half a window of a segment's ends the filter fits one side only: its
        # slope scatters up to ~4 x as much (a noisy record's last 0.1 s was a trip)
        index = np.arange(b - a)
        edge = np.minimum(index, b - a - 1 - index) < n / 2.0
        band[a:b] = np.where(edge, 4.0 * deadband, deadband)
    return band


def reading_turns(changes_m: np.ndarray, keep: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """(sizes, counts) of a reading's reversals (a change whose next non-zero change goes
    the other way), sizes rounded to 1e-9, the ``keep`` smallest: what
    :func:`reading_quantum_m` reads, and what parts of a record read apart add up to
    (:func:`quantum_of_turns` of their concatenation).

    >>> reading_turns(np.diff([0.0, 0.01, 0.0, 0.01, 0.03, 0.01]))
    (array([0.01, 0.02]), array([2, 1]))
    """
    d1 = np.asarray(changes_m, dtype=np.float64)
    d1 = d1[np.isfinite(d1) & (d1 != 0.0)]
    turns = np.abs(d1[:-1][np.sign(d1[:-1]) != np.sign(d1[1:])])
    sizes, counts = np.unique(np.round(turns, 9), return_counts=True)
    return sizes[:keep], counts[:keep]


def quantum_of_turns(sizes: np.ndarray, counts: np.ndarray) -> float:
    """The smallest reversal size that at least three reversals share, 0 if none: sizes
    and counts of :func:`reading_turns`, of one record or of its parts concatenated
    (a size listed by several parts counts their sum).

    >>> quantum_of_turns(np.array([0.01, 0.02, 0.01]), np.array([2, 1, 1]))
    0.01
    """
    sizes, counts = np.asarray(sizes, dtype=np.float64), np.asarray(counts)
    if sizes.size == 0:
        return 0.0
    unique, where = np.unique(sizes, return_inverse=True)
    total = np.bincount(where, weights=counts)
    shared = unique[total >= 3]
    return float(shared[0]) if shared.size else 0.0


def reading_quantum_m(changes_m: np.ndarray) -> float:
    """A quantised reading's step from the changes between consecutive readings (the
    depth's [m]): the smallest size that at least three of its reversals share
    (:func:`reading_turns`; an encoder read to the centimetre that toggles between two
    counts at rest, 0.01 m); 0 where none repeats (a continuous reading, whose noise
    :func:`depth_noise_m` measures, or a motion that never turns back: the steps of a
    steady travel are no quantum).

    >>> toggling = np.tile([300.0, 300.0, 300.01, 300.01], 10)
    >>> steady = np.linspace(0.0, 1.0, 11)
    >>> reading_quantum_m(np.diff(toggling)), reading_quantum_m(np.diff(steady))
    (0.01, 0.0)
    """
    return quantum_of_turns(*reading_turns(changes_m))


def depth_noise_m(depth_m: np.ndarray) -> float:
    """The logged depth's white noise [m]: :func:`physics.white_noise.
    difference_noise_sigma` of its second differences (a conveyance's motion is smooth,
    its second differences ~a dt^2); 0 where fewer than 20 are known or the depth does
    not jitter (an encoder read to the centimetre at rest).

    >>> depth = 300.0 + np.random.default_rng(0).normal(0, 0.01, 5000)
    >>> round(depth_noise_m(depth), 3), float(depth_noise_m(np.full(100, 300.0)))
    (0.01, 0.0)
    """
    d2 = np.diff(np.asarray(depth_m, dtype=np.float64), 2)
    if np.count_nonzero(np.isfinite(d2)) < 20:
        return 0.0
    return difference_noise_sigma(d2, 2)


def _grid_time(t: np.ndarray, seg: np.ndarray, dt_s: float) -> np.ndarray:
    """Sample times on the logger's grid [s, from each segment's start]: each step rounded
    to whole steps (at least one) of its segment's spacing (:func:`_segment_spacing`)."""
    grid = np.zeros(t.size)
    starts = np.flatnonzero(np.concatenate([[True], seg[1:] != seg[:-1]]))
    for a, b in itertools.pairwise([*starts.tolist(), t.size]):
        if b - a < 2:
            continue
        # the record's spacing where the segment's is within 1.5 x of it: a record read
        # block by block then grids each block's part alike (a part's median moves with
        # the timestamps' jitter, and the speed from the depth by 1e-4 with it)
        step = _segment_spacing(t, a, b, dt_s)
        step = dt_s if 1.0 / 1.5 <= step / dt_s <= 1.5 else step
        grid[a + 1 : b] = np.cumsum(np.maximum(1.0, np.round(np.diff(t[a:b]) / step))) * step
    return grid


def longest_unlogged_s(time_s: np.ndarray, speed: np.ndarray, lo_s: float, hi_s: float) -> float:
    """The longest stretch [s] of ``[lo_s, hi_s]`` whose samples lack a logged (finite)
    speed: from the last logged sample before them (or ``lo_s``) to the first after (or
    ``hi_s``); ``time_s`` increasing. A logger gap (no samples at all, bridged by the
    trip rule) is not counted: nothing of it is the depth's derivative.
    A replay follows the logged speed; where it is missing longer than
    :data:`SPEED_HOLE_S` the depth's derivative stands in, which a simulation
    differentiating it again cannot follow (``pipelines.sanity``, ``ropeload discover``).

    >>> t = np.arange(0.0, 10.0, 0.1)
    >>> v = np.where((t > 3.0) & (t < 5.0), np.nan, 1.0)
    >>> round(longest_unlogged_s(t, v, 0.0, 10.0), 1), longest_unlogged_s(t, v, 6.0, 9.0)
    (2.0, 0.0)
    >>> gap = np.r_[np.arange(0.0, 5.0, 0.1), np.arange(6.5, 10.0, 0.1)]  # 1.5 s, no rows
    >>> longest_unlogged_s(gap, np.ones(gap.size), 0.0, 10.0)
    0.0
    >>> beside = np.where((gap > 4.75) & (gap < 5.0), np.nan, 1.0)  # two rows before it
    >>> round(longest_unlogged_s(gap, beside, 0.0, 10.0), 1)
    0.2
    """
    t = np.asarray(time_s, dtype=np.float64)
    # the window by bisection (``time_s`` increasing): a check per trip of a day-long
    # record reads its trip's samples, not the day's
    a, b = np.searchsorted(t, lo_s, side="left"), np.searchsorted(t, hi_s, side="right")
    if b <= a:
        return 0.0
    rows = t[a:b]
    # the window's ends stand as logged samples; a stretch runs from the logged sample
    # before its rows without a speed to the one after, its logger gaps (steps over 3 x
    # the median, a missing row's two) left out
    times = np.concatenate([[lo_s], rows, [hi_s]])
    logged = np.concatenate([[True], np.isfinite(np.asarray(speed[a:b], dtype=np.float64)), [True]])
    steps = np.diff(times)
    step = float(np.median(np.diff(rows))) if rows.size > 1 else 0.0
    counted = np.where(steps > 3.0 * step, 0.0, steps) if step > 0.0 else steps
    elapsed = np.concatenate([[0.0], np.cumsum(counted)])
    at = np.flatnonzero(logged)
    holes = np.flatnonzero(np.diff(at) > 1)  # logged neighbours with rows between them
    if holes.size == 0:
        return 0.0
    longest = float(np.max(elapsed[at[holes + 1]] - elapsed[at[holes]]))
    # a sample's own spacing is no hole: count only beyond the logged neighbours
    return longest if longest > 1.5 * step else 0.0
