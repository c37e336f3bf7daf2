"""Gap-aware signal conditioning for logged pressures, displacements and speeds.

Segments
    :func:`segment_ids` -- contiguous-segment numbers from sample times (numpy).
    :func:`with_segment_id` -- the same as a column of a LazyFrame/DataFrame.
    :func:`seconds_expr` -- a time column as float seconds (expression).

Spikes
    :func:`hampel` -- Hampel identifier per segment (numpy in, numpy out; numba).
    :func:`remove_spikes` -- the same on frame columns.

Low-pass
    :func:`lowpass` -- zero-phase Butterworth (``scipy.signal.sosfiltfilt``) per segment.
    :func:`lowpass_columns` -- the same on frame columns.

A *gap* is a sample spacing larger than ``gap_factor`` times the nominal spacing (the
median spacing unless given). Every filter runs on each contiguous segment on its own,
so nothing is smeared across a gap (the logger drops samples, files overlap, a hoist
may be off for hours).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import TypeVar

import numpy as np
import polars as pl
from numba import njit
from scipy import signal

__all__ = [
    "MAD_TO_SIGMA",
    "box_smooth",
    "box_smooth_into",
    "despike_median3",
    "first_difference_sigma",
    "fresh_state",
    "hampel",
    "lowpass",
    "lowpass_columns",
    "lowpass_work_size",
    "play_operator",
    "remove_spikes",
    "seconds_expr",
    "segment_ids",
    "with_segment_id",
]

Frame = TypeVar("Frame", pl.DataFrame, pl.LazyFrame)

#: Scale from median absolute deviation to standard deviation for Gaussian noise.
MAD_TO_SIGMA = 1.4826


def segment_ids(
    t_s: np.ndarray, *, gap_factor: float = 3.0, nominal_dt_s: float | None = None
) -> np.ndarray:
    """Number contiguous segments: a new segment starts after each gap.

    Parameters
    ----------
    t_s : numpy.ndarray
        Sample times [s], increasing.
    gap_factor : float
        A spacing above ``gap_factor * nominal_dt_s`` is a gap [-].
    nominal_dt_s : float, optional
        Nominal sample spacing [s]; default the median spacing.

    Returns
    -------
    numpy.ndarray
        int64 segment id per sample, starting at 0.

    >>> segment_ids(np.array([0.0, 0.01, 0.02, 0.5, 0.51])).tolist()
    [0, 0, 0, 1, 1]
    """
    t = np.ascontiguousarray(t_s, dtype=np.float64)
    if t.size < 2:
        return np.zeros(t.size, dtype=np.int64)
    nominal = float(np.median(np.diff(t))) if nominal_dt_s is None else nominal_dt_s
    out = np.empty(t.size, dtype=np.int64)
    _segment_kernel(t, gap_factor * nominal, out)
    return out


@njit(cache=True, nogil=True)
def _segment_kernel(t, max_step, out):  # pragma: no cover - numba
    """out[i] = number of steps t[j] - t[j-1] > max_step for j <= i (cumsum of the breaks)."""
    count = 0
    out[0] = 0
    for i in range(1, t.shape[0]):
        if t[i] - t[i - 1] > max_step:
            count += 1
        out[i] = count


def seconds_expr(frame_schema: pl.Schema, time_col: str) -> pl.Expr:
    """``time_col`` (a Datetime, or float seconds) as float seconds, an expression."""
    dtype = frame_schema[time_col]
    if dtype.is_temporal():
        return pl.col(time_col).dt.epoch("us").cast(pl.Float64) * 1e-6
    if dtype.is_numeric():
        return pl.col(time_col).cast(pl.Float64)
    raise TypeError(f"{time_col}: expected a datetime or seconds column, got {dtype}")


def with_segment_id(
    frame: Frame,
    time_col: str,
    *,
    gap_factor: float = 3.0,
    nominal_dt_s: float,
    name: str = "segment_id",
) -> Frame:
    """Add a contiguous-segment id column (Int64) to a frame sorted by ``time_col``.

    ``time_col`` is a Datetime or float seconds column; a spacing above
    ``gap_factor * nominal_dt_s`` [s] starts a new segment. (Unlike
    :func:`segment_ids` the nominal spacing is required: a lazy frame has no cheap
    median; take it from the log's ``sample_rate_hz``.)

    >>> df = pl.DataFrame({"t_s": [0.0, 0.01, 0.02, 0.5, 0.51]})
    >>> with_segment_id(df, "t_s", nominal_dt_s=0.01)["segment_id"].to_list()
    [0, 0, 0, 1, 1]
    """
    t = seconds_expr(frame.collect_schema(), time_col)
    gap = (t.diff() > gap_factor * nominal_dt_s).fill_null(False)
    return frame.with_columns(gap.cast(pl.Int64).cum_sum().alias(name))


@njit(cache=True, nogil=True)
def _sorted_median(a, m):  # pragma: no cover - numba
    """Median of a[:m], sorting a[:m] in place (insertion sort: m is a small window)."""
    for i in range(1, m):
        key = a[i]
        j = i - 1
        while j >= 0 and a[j] > key:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = key
    if m % 2 == 1:
        return a[m // 2]
    return 0.5 * (a[m // 2 - 1] + a[m // 2])


@njit(cache=True, nogil=True)
def _hampel_kernel(x, seg, half, threshold):  # pragma: no cover
    n = x.shape[0]
    out = x.copy()
    buf = np.empty(2 * half + 1)
    dev = np.empty(2 * half + 1)
    for i in range(n):
        if not np.isfinite(x[i]):
            continue
        m = 0
        for j in range(max(0, i - half), min(n, i + half + 1)):
            if seg[j] == seg[i] and np.isfinite(x[j]):
                buf[m] = x[j]
                m += 1
        med = _sorted_median(buf, m)
        distance = abs(x[i] - med)
        if distance == 0.0:
            continue
        for k in range(m):
            dev[k] = abs(buf[k] - med)
        mad = _sorted_median(dev, m)
        if distance > threshold * mad:
            out[i] = med
    return out


def hampel(
    x: np.ndarray,
    segment_id: np.ndarray | None = None,
    *,
    window: int = 7,
    n_sigmas: float = 4.0,
) -> tuple[np.ndarray, np.ndarray]:
    r"""Hampel identifier per segment: replace spikes by the local median.

    Sample i is a spike when

    .. math::
        |x_i - m_i| > n_\sigma \cdot 1.4826 \cdot
        \operatorname{median}_{j \in W_i} |x_j - m_i|,
        \qquad m_i = \operatorname{median}_{j \in W_i} x_j

    with W_i the centred window of ``window`` samples, cut at segment boundaries (so a
    window never reaches across a gap). NaN samples are ignored and stay NaN.

    Parameters
    ----------
    x : numpy.ndarray
        Signal.
    segment_id : numpy.ndarray or None
        Segment id per sample (:func:`segment_ids`); None: one segment.
    window : int
        Odd window length [samples].
    n_sigmas : float
        Threshold in robust standard deviations [-].

    Returns
    -------
    cleaned, is_spike : numpy.ndarray
        Cleaned signal and a Boolean spike mask.

    Notes
    -----
    Where the window is flat (MAD 0, e.g. a quantised signal at rest) any deviation
    from the median counts as a spike.

    References
    ----------
    Pearson, R. K. (2002), Outliers in process modeling and identification, IEEE
    Trans. Control Syst. Technol. 10(1), 55-63, doi:10.1109/87.974338.

    >>> y, spikes = hampel(np.array([1.0, 1.1, 0.9, 50.0, 1.0, 1.1, 0.9]))
    >>> float(y[3]), spikes.tolist()
    (1.0, [False, False, False, True, False, False, False])
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    seg = (
        np.zeros(x.size, dtype=np.int64)
        if segment_id is None
        else np.ascontiguousarray(segment_id, dtype=np.int64)
    )
    cleaned = _hampel_kernel(x, seg, window // 2, n_sigmas * MAD_TO_SIGMA)
    return cleaned, cleaned != x


def remove_spikes(
    frame: Frame,
    columns: Sequence[str],
    *,
    segment_col: str = "segment_id",
    window: int = 7,
    n_sigmas: float = 4.0,
    flag_suffix: str | None = "_spike",
) -> Frame:
    """Apply :func:`hampel` to frame columns (replaced in place), per segment.

    Sequential, so it runs in ``map_batches`` over the whole column with the segment
    ids beside it. If ``flag_suffix`` is given, a Boolean column
    ``<column><flag_suffix>`` marks the replaced samples. Nulls stay null.
    """

    def make(column: str) -> pl.Expr:
        def _batch(s: pl.Series) -> pl.Series:
            parts = s.struct.unnest()
            y, _ = hampel(
                parts["x"].cast(pl.Float64).to_numpy(),
                parts["seg"].to_numpy(),
                window=window,
                n_sigmas=n_sigmas,
            )
            return pl.Series(y, dtype=pl.Float64).fill_nan(None)

        return pl.struct(x=pl.col(column), seg=pl.col(segment_col)).map_batches(
            _batch, return_dtype=pl.Float64
        )

    if flag_suffix is None:
        return frame.with_columns(make(c).alias(c) for c in columns)
    tmp = {c: f"__{c}_hampel" for c in columns}
    frame = frame.with_columns(make(c).alias(tmp[c]) for c in columns)
    frame = frame.with_columns(
        [(pl.col(tmp[c]) != pl.col(c)).fill_null(False).alias(c + flag_suffix) for c in columns]
        + [pl.col(tmp[c]).alias(c) for c in columns]
    )
    return frame.drop(list(tmp.values()))


def _fill_nan_linear(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    bad = ~np.isfinite(x)
    if bad.any() and (~bad).any():
        idx = np.arange(x.size)
        x = x.copy()
        x[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
    return x, bad


def lowpass(
    x: np.ndarray,
    segment_id: np.ndarray | None,
    *,
    sample_rate_hz: float,
    cutoff_hz: float,
    order: int = 4,
    out: np.ndarray | None = None,
    work: np.ndarray | None = None,
) -> np.ndarray:
    r"""Zero-phase Butterworth low-pass, each segment filtered on its own.

    Forward-backward filtering (``scipy.signal.sosfiltfilt``) of an order-``order``
    Butterworth section cascade: magnitude response

    .. math:: |H(f)|^2 = \frac{1}{1 + (f/f_c)^{2N}}

    applied twice (squared), no phase lag. Each segment is padded by odd extension of
    three cut-off periods (scipy's default pad is shorter and leaves ~3 % edge error
    on a sine at a fifth of the cut-off). NaN samples inside a segment are bridged
    linearly for the filter and returned as NaN. Segments too short for the
    edge padding use a shorter pad; segments of fewer than ``3 * order`` samples are
    returned unfiltered.

    Parameters
    ----------
    x : numpy.ndarray
        Signal, uniformly sampled within each segment.
    segment_id : numpy.ndarray or None
        Segment id per sample (:func:`segment_ids`); None: one segment.
    sample_rate_hz, cutoff_hz : float
        Nominal sampling rate and -3 dB (one pass) cut-off [Hz].
    order : int
        Butterworth order (per pass).
    out : numpy.ndarray, optional
        Float64 array of ``x``'s length to write into; may be ``x`` itself (filtered in
        place: each segment is read whole before it is written).
    work : numpy.ndarray, optional
        A float64 scratch array for the forward pass (a reused buffer), used when it
        holds the longest segment plus twice the pad (:func:`lowpass_work_size`);
        otherwise one is allocated.

    Returns
    -------
    numpy.ndarray
        Filtered signal, same shape.

    >>> t = np.arange(0, 2, 0.01)
    >>> y = lowpass(np.sin(2 * np.pi * t), None, sample_rate_hz=100, cutoff_hz=10)
    >>> bool(np.max(np.abs(y - np.sin(2 * np.pi * t))) < 0.01)
    True
    """
    x = np.asarray(x, dtype=np.float64)
    seg = np.zeros(x.size, dtype=np.int64) if segment_id is None else np.asarray(segment_id)
    sos = signal.butter(order, cutoff_hz, btype="low", fs=sample_rate_hz, output="sos")
    default_pad = _lowpass_pad(sample_rate_hz, cutoff_hz, order)
    zi = signal.sosfilt_zi(sos)
    if out is None:
        out = x.copy()
    elif out is not x:
        out[:] = x
    starts = np.flatnonzero(np.concatenate([[True], seg[1:] != seg[:-1]])) if x.size else []
    bounds = [*list(starts), x.size]
    longest = max((b - a for a, b in itertools.pairwise(bounds)), default=0)
    size = longest + 2 * default_pad
    # the forward pass, reused per segment
    work = np.empty(size) if work is None or work.size < size else work[:size]
    for a, b in itertools.pairwise(bounds):
        part, bad = _fill_nan_linear(x[a:b])
        if b - a < 3 * order or bad.all():
            continue
        kernel = _sosfiltfilt_two_kernel if sos.shape[0] == 2 else _sosfiltfilt_kernel
        kernel(sos, zi, np.ascontiguousarray(part), min(default_pad, b - a - 1), work, out[a:b])
        if bad.any():
            out[a:b][bad] = np.nan
    return out


def _lowpass_pad(sample_rate_hz: float, cutoff_hz: float, order: int) -> int:
    """Odd-extension pad of :func:`lowpass` [samples]: three cut-off periods (scipy's
    default, 3 (2 sections + 1) samples, leaves a start-up transient of a few % at the
    edges), at least scipy's."""
    sections = (order + 1) // 2
    return max(3 * (2 * sections + 1), int(3 * sample_rate_hz / cutoff_hz))


def lowpass_work_size(n: int, *, sample_rate_hz: float, cutoff_hz: float, order: int = 4) -> int:
    """Samples of the scratch array :func:`lowpass` needs for a segment of ``n`` samples."""
    return n + 2 * _lowpass_pad(sample_rate_hz, cutoff_hz, order)


@njit(inline="always")
def _sos_sections(sos, state, x_cur):  # pragma: no cover - numba
    """One sample through the second-order sections (scipy's transposed direct form II)."""
    for s in range(sos.shape[0]):
        x_new = sos[s, 0] * x_cur + state[s, 0]
        state[s, 0] = sos[s, 1] * x_cur - sos[s, 4] * x_new + state[s, 1]
        state[s, 1] = sos[s, 2] * x_cur - sos[s, 5] * x_new
        x_cur = x_new
    return x_cur


@njit(cache=True, nogil=True)
def _sosfiltfilt_kernel(sos, zi, x, pad, work, out):  # pragma: no cover - numba
    """``scipy.signal.sosfiltfilt(sos, x, padlen=pad)`` into ``out``, bit for bit.

    The same steps (odd extension by ``pad``, forward pass from ``zi x_ext[0]``,
    backward pass from ``zi y[-1]``) and the same arithmetic order as scipy's
    ``_sosfilt``, without materialising the extension or the reversed copies: two
    passes over memory instead of about eight. ``work`` holds at least
    ``len(x) + 2 pad`` samples.
    """
    m = x.shape[0]
    n_sec = sos.shape[0]
    total = m + 2 * pad
    state = np.empty((n_sec, 2))
    x_first = 2.0 * x[0] - x[pad]
    for s in range(n_sec):
        state[s, 0] = zi[s, 0] * x_first
        state[s, 1] = zi[s, 1] * x_first
    for j in range(pad):
        work[j] = _sos_sections(sos, state, 2.0 * x[0] - x[pad - j])
    for j in range(m):
        work[pad + j] = _sos_sections(sos, state, x[j])
    for k in range(pad):
        work[pad + m + k] = _sos_sections(sos, state, 2.0 * x[m - 1] - x[m - 2 - k])
    y_last = work[total - 1]
    for s in range(n_sec):
        state[s, 0] = zi[s, 0] * y_last
        state[s, 1] = zi[s, 1] * y_last
    for j in range(total - 1, pad + m - 1, -1):
        _sos_sections(sos, state, work[j])
    for j in range(pad + m - 1, pad - 1, -1):
        out[j - pad] = _sos_sections(sos, state, work[j])


@njit(inline="always")
def _two_sections(sos, state, x_cur):  # pragma: no cover - numba
    """:func:`_sos_sections` for two sections (order 4) with the state in a tuple: the
    same arithmetic, kept in registers instead of memory (1.75x faster)."""
    x1 = sos[0, 0] * x_cur + state[0]
    s0 = sos[0, 1] * x_cur - sos[0, 4] * x1 + state[1]
    s1 = sos[0, 2] * x_cur - sos[0, 5] * x1
    x2 = sos[1, 0] * x1 + state[2]
    s2 = sos[1, 1] * x1 - sos[1, 4] * x2 + state[3]
    s3 = sos[1, 2] * x1 - sos[1, 5] * x2
    return x2, (s0, s1, s2, s3)


@njit(cache=True, nogil=True)
def _sosfiltfilt_two_kernel(sos, zi, x, pad, work, out):  # pragma: no cover - numba
    """:func:`_sosfiltfilt_kernel` for two sections, bit for bit (:func:`_two_sections`)."""
    m = x.shape[0]
    total = m + 2 * pad
    x_first = 2.0 * x[0] - x[pad]
    state = (zi[0, 0] * x_first, zi[0, 1] * x_first, zi[1, 0] * x_first, zi[1, 1] * x_first)
    for j in range(pad):
        work[j], state = _two_sections(sos, state, 2.0 * x[0] - x[pad - j])
    for j in range(m):
        work[pad + j], state = _two_sections(sos, state, x[j])
    for k in range(pad):
        work[pad + m + k], state = _two_sections(sos, state, 2.0 * x[m - 1] - x[m - 2 - k])
    y_last = work[total - 1]
    state = (zi[0, 0] * y_last, zi[0, 1] * y_last, zi[1, 0] * y_last, zi[1, 1] * y_last)
    for j in range(total - 1, pad + m - 1, -1):
        _, state = _two_sections(sos, state, work[j])
    for j in range(pad + m - 1, pad - 1, -1):
        out[j - pad], state = _two_sections(sos, state, work[j])


def lowpass_columns(
    frame: Frame,
    columns: Sequence[str],
    *,
    segment_col: str = "segment_id",
    sample_rate_hz: float,
    cutoff_hz: float,
    order: int = 4,
) -> Frame:
    """Apply :func:`lowpass` to frame columns (replaced in place), per segment.

    The filter is sequential, so it runs in ``map_batches`` over the whole column
    (with the segment ids beside it), once per column. Nulls stay null.
    """

    def make(column: str) -> pl.Expr:
        def _batch(s: pl.Series) -> pl.Series:
            parts = s.struct.unnest()
            y = lowpass(
                parts["x"].cast(pl.Float64).to_numpy(),
                parts["seg"].to_numpy(),
                sample_rate_hz=sample_rate_hz,
                cutoff_hz=cutoff_hz,
                order=order,
            )
            return pl.Series(y, dtype=pl.Float64).fill_nan(None)

        return (
            pl.struct(x=pl.col(column), seg=pl.col(segment_col))
            .map_batches(_batch, return_dtype=pl.Float64)
            .alias(column)
        )

    return frame.with_columns([make(c) for c in columns])


#: Length of the resumable state of :func:`_play_kernel`.
PLAY_STATE_SIZE = 3


def fresh_state(size: int) -> np.ndarray:
    """A resumable kernel's state before its first call (``state[0] == 0``: nothing seen).

    The sequential kernels of the compensation take a float64 ``state`` array and run
    over a block of samples: ``state[0]`` is 1 once a call has run (the rest then holds
    what the kernel carries to the next sample), ``state[1]`` is set by the caller to 1
    when the block's first sample continues the previous block's gap-free segment. The
    kernel leaves its state after the block's last sample there, so calling it on two
    consecutive blocks gives the result of one call on both (block processing, issue 16).

    >>> fresh_state(3).tolist()
    [0.0, 0.0, 0.0]
    """
    return np.zeros(size)


@njit(cache=True, nogil=True)
def _play_kernel(x, seg, half_width, out, state):  # pragma: no cover - numba
    """The play operator over a block; ``state`` = [ran, continues segment, y]
    (:func:`fresh_state`)."""
    resume = state[0] != 0.0 and state[1] != 0.0
    y = state[2] if resume else np.nan
    for i in range(x.shape[0]):
        if (i == 0 and not resume) or (i > 0 and seg[i] != seg[i - 1]):
            y = np.nan
        xi = x[i]
        if np.isfinite(xi):
            if not np.isfinite(y):
                y = xi
            elif xi > y + half_width:
                y = xi - half_width
            elif xi < y - half_width:
                y = xi + half_width
        out[i] = y
    state[0] = 1.0
    state[2] = y


def play_operator(
    x: np.ndarray, segment_id: np.ndarray | None = None, *, half_width: float
) -> np.ndarray:
    r"""Play (backlash) operator: follows ``x`` only once it leaves a band of +-``half_width``.

    .. math::
        y_i = \min\bigl(\max(y_{i-1},\; x_i - w),\; x_i + w\bigr)

    A monotone motion larger than w passes through (lagging by w); jitter and
    quantisation flicker smaller than w do not move the output. Used to drive
    rate-independent friction state (LuGre bristles, Maxwell-slip elements) from a noisy
    displacement record, where the *increments* of the input matter: a smoothed
    derivative overshoots at a stop and noise moves the state by its own amplitude.
    The state restarts at each segment (``segment_id`` change); NaN inputs hold it.

    Parameters
    ----------
    x : numpy.ndarray
        Input, e.g. piston displacement [m].
    segment_id : numpy.ndarray, optional
        Contiguous-segment ids (see :func:`segment_ids`); default one segment.
    half_width : float
        w, half the band width, in the unit of ``x`` (>= 0).

    References
    ----------
    Krasnosel'skii, M. A., Pokrovskii, A. V. (1989), Systems with Hysteresis, Springer,
    ch. 1 (the play operator); Visintin, A. (1994), Differential Models of Hysteresis.

    >>> play_operator(np.array([0.0, 0.05, -0.05, 0.3, 0.25, 0.0]), half_width=0.1).round(2)
    array([0. , 0. , 0. , 0.2, 0.2, 0.1])
    """
    if half_width < 0:
        raise ValueError(f"half_width must be >= 0, got {half_width}")
    values = np.ascontiguousarray(x, dtype=np.float64)
    seg = (
        np.zeros(values.shape[0], dtype=np.int64)
        if segment_id is None
        else np.ascontiguousarray(segment_id, dtype=np.int64)
    )
    out = np.empty_like(values)
    _play_kernel(values, seg, float(half_width), out, fresh_state(PLAY_STATE_SIZE))
    return out


@njit(cache=True, nogil=True)
def _moving_average(x, half, out):  # pragma: no cover - numba
    """Centred mean over 2 half + 1 samples; the window shrinks at the ends."""
    n = x.shape[0]
    total = 0.0
    count = 0
    for j in range(min(half, n - 1) + 1):
        total += x[j]
        count += 1
    for i in range(n):
        out[i] = total / count
        enter = i + half + 1
        leave = i - half
        if enter < n:
            total += x[enter]
            count += 1
        if leave >= 0:
            total -= x[leave]
            count -= 1


def box_smooth(x: np.ndarray, *, sigma_samples: float, passes: int = 3) -> np.ndarray:
    r"""Near-Gaussian smoothing by repeated centred moving averages, O(n).

    ``passes`` moving averages of width w = 2h + 1 have the variance
    passes (w^2 - 1) / 12 of a Gaussian of standard deviation ``sigma_samples``, so h
    is chosen from it. The kernel's weights are all positive: a monotone input stays
    monotone (no overshoot, unlike a Butterworth filter), which matters where the
    output drives a history-dependent state. The window shrinks at the ends.

    Parameters
    ----------
    x : numpy.ndarray
        Finite samples.
    sigma_samples : float
        Standard deviation of the equivalent Gaussian [samples].
    passes : int
        Number of moving averages (3 is within a few percent of a Gaussian).

    References
    ----------
    Wells, W. M. (1986), Efficient synthesis of Gaussian filters by cascaded uniform
    filters, IEEE TPAMI 8(2), 234-239, doi:10.1109/TPAMI.1986.4767776.

    >>> box_smooth(np.r_[np.zeros(5), np.ones(5)], sigma_samples=1.0).round(3).tolist()
    [0.0, 0.0, 0.037, 0.148, 0.37, 0.63, 0.852, 0.963, 1.0, 1.0]
    """
    values = np.array(x, dtype=np.float64)  # a copy: the passes overwrite it
    work = np.empty_like(values)
    return box_smooth_into(values, work, sigma_samples=sigma_samples, passes=passes)


def box_smooth_into(
    values: np.ndarray, work: np.ndarray, *, sigma_samples: float, passes: int = 3
) -> np.ndarray:
    """:func:`box_smooth` on caller-owned arrays: ``values`` (contiguous float64, the
    input) and ``work`` (same length) are both overwritten; returns the one holding the
    result. For loops that reuse their work arrays."""
    half = max(round((np.sqrt(12.0 * sigma_samples**2 / passes + 1.0) - 1.0) / 2.0), 0)
    current, other = values, work
    for _ in range(passes):
        _moving_average(current, half, other)
        current, other = other, current
    return current


@njit(cache=True, nogil=True)
def _median3_kernel(x, seg, threshold, out):  # pragma: no cover - numba
    """3-point median where a sample is a spike; ``out`` may be ``x`` (the raw previous
    sample is kept in a register, so the median always sees raw neighbours)."""
    n = x.shape[0]
    a = np.nan  # raw x[i - 1]
    for i in range(n):
        b = x[i]
        out[i] = b
        if not (i == 0 or i == n - 1 or seg[i - 1] != seg[i] or seg[i + 1] != seg[i]):
            c = x[i + 1]
            if np.isfinite(a) and np.isfinite(b) and np.isfinite(c):
                med = max(min(a, b), min(max(a, b), c))
                if abs(b - med) > threshold:
                    out[i] = med
        a = b


def despike_median3(
    x: np.ndarray,
    segment_id: np.ndarray | None = None,
    *,
    n_sigmas: float = 6.0,
    out: np.ndarray | None = None,
    sigma: float | None = None,
) -> tuple[np.ndarray, float]:
    r"""Replace single-sample spikes by the median of the sample and its two neighbours.

    A sample is a spike when it differs from that 3-point median by more than
    ``n_sigmas`` times the signal's white-noise sigma, estimated once for the whole
    record from first differences (sigma = 1.4826 MAD(diff x) / sqrt 2, on at most
    ~200 k of them). A 3-point
    median passes every feature at least two samples wide (steps, pressure shocks), so
    only isolated outliers go; at 100 Hz, peaks of ringing above ~10 Hz may be clipped,
    which a following 10 Hz low-pass removes anyway. Linear in n, a few ns per sample:
    the cheap alternative to :func:`hampel` for pressures that are low-passed next.

    Returns the despiked signal and the sigma used. ``out``: a float64 array of x's
    length to write into; may be ``x`` itself (despiked in place). ``sigma``: the
    noise sigma, when it is known from a longer record than ``x`` (a block of a day,
    :func:`first_difference_sigma` of the day's differences).

    >>> despike_median3(np.array([0.0, 0.1, 9.0, 0.0, 0.1, 0.0, 0.1]))[0].tolist()
    [0.0, 0.1, 0.1, 0.0, 0.1, 0.0, 0.1]
    """
    values = np.ascontiguousarray(x, dtype=np.float64)
    if sigma is None:
        # every step-th first difference (the median of 200 k of them is plenty), without
        # differencing the whole record
        step = max(1, (values.size - 1) // 200_000)
        at = np.arange(0, max(values.size - 1, 0), step)
        sigma = first_difference_sigma(values[at + 1] - values[at])
    seg = (
        np.zeros(values.shape[0], dtype=np.int64)
        if segment_id is None
        else np.ascontiguousarray(segment_id, dtype=np.int64)
    )
    if out is None:
        out = np.empty_like(values)
    _median3_kernel(values, seg, n_sigmas * sigma, out)
    return out, sigma


def first_difference_sigma(differences: np.ndarray) -> float:
    """White-noise sigma from first differences x[i+1] - x[i]: 1.4826 MAD / sqrt 2.

    Non-finite differences are ignored; 0 when none is left.

    >>> round(first_difference_sigma(np.array([0.1, -0.1, 0.1, -0.1, np.nan])), 6)
    0.104836
    """
    d = np.asarray(differences, dtype=np.float64)
    d = d[np.isfinite(d)]
    if d.size == 0:
        return 0.0
    return float(MAD_TO_SIGMA * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))
