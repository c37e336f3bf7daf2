"""Gap-aware signal conditioning for logged pressures, displacements and speeds.

Segments
    :func:`segment_ids` -- contiguous-segment numbers from sample times (numpy; its home
    is :mod:`physics.trip_rule`, whose trips a logger gap may end).
    :func:`with_segment_id` -- the same as a column of a LazyFrame/DataFrame.
    :func:`seconds_expr` -- a time column as float seconds (expression).

Spikes and noise
    :func:`despike_median3` -- single-sample spikes against a 3-point median (numba),
    the noise :func:`physics.white_noise.difference_noise_sigma` of first differences.

Smoothing and play
    :func:`box_smooth` / :func:`box_smooth_into` -- near-Gaussian, monotone smoothing.
    :func:`play_operator` -- a play (backlash) operator per segment, resumable
    (:func:`play_kernel`, :func:`fresh_state`).

The zero-phase low-pass is :mod:`transforms.lowpass`.

A *gap* is a sample spacing larger than ``gap_factor`` times the nominal spacing (the
median spacing unless given). Every filter runs on each contiguous segment on its own,
so nothing is smeared across a gap (the logger drops samples, files overlap, a hoist
may be off for hours).
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
import polars as pl
from numba import njit

from physics.trip_rule import segment_ids
from physics.white_noise import difference_noise_sigma
from transforms.lowpass import lowpass

__all__ = [
    "MAX_CUTOFF_SHARE",
    "box_smooth",
    "box_smooth_into",
    "despike_median3",
    "despiked_lowpass",
    "fresh_state",
    "play_kernel",
    "play_operator",
    "play_step",
    "pressure_cutoff_at",
    "sampled_differences",
    "seconds_expr",
    "segment_ids",
    "with_segment_id",
]

Frame = TypeVar("Frame", pl.DataFrame, pl.LazyFrame)


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


#: Length of the resumable state of :func:`play_kernel`.
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


@njit(cache=True, nogil=True, inline="always")
def play_step(x: float, y: float, half_width: float) -> float:  # pragma: no cover - numba
    """One step of the play operator: its output y follows x once x leaves y +- w; a NaN
    y (a segment's start) starts at x."""
    if not np.isfinite(y):
        return x
    if x > y + half_width:
        return x - half_width
    if x < y - half_width:
        return x + half_width
    return y


@njit(cache=True, nogil=True)
def play_kernel(x, seg, half_width, out, state):  # pragma: no cover - numba
    """The play operator over a block; ``state`` = [ran, continues segment, y]
    (:func:`fresh_state`)."""
    resume = state[0] != 0.0 and state[1] != 0.0
    y = state[2] if resume else np.nan
    for i in range(x.shape[0]):
        if (i == 0 and not resume) or (i > 0 and seg[i] != seg[i - 1]):
            y = np.nan
        if np.isfinite(x[i]):
            y = play_step(x[i], y, half_width)
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
    play_kernel(values, seg, float(half_width), out, fresh_state(PLAY_STATE_SIZE))
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


def sampled_differences(values: np.ndarray, most: int = 200_000) -> np.ndarray:
    """Every k-th first difference of ``values``, about ``most`` of them at most (the
    median of 200 k is plenty for a noise sigma or a reading step), without differencing
    the whole record.

    >>> sampled_differences(np.arange(10.0) ** 2, most=3).tolist()
    [1.0, 7.0, 13.0]
    """
    step = max(1, (values.size - 1) // most)
    at = np.arange(0, max(values.size - 1, 0), step)
    return values[at + 1] - values[at]


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
    the cheap despiker for pressures that are low-passed next.

    Returns the despiked signal and the sigma used. ``out``: a float64 array of x's
    length to write into; may be ``x`` itself (despiked in place). ``sigma``: the
    noise sigma, when it is known from a longer record than ``x`` (a block of a day,
    :func:`~physics.white_noise.difference_noise_sigma` of the day's first differences).

    >>> despike_median3(np.array([0.0, 0.1, 9.0, 0.0, 0.1, 0.0, 0.1]))[0].tolist()
    [0.0, 0.1, 0.1, 0.0, 0.1, 0.0, 0.1]
    """
    values = np.ascontiguousarray(x, dtype=np.float64)
    if sigma is None:
        sigma = difference_noise_sigma(sampled_differences(values), 1)
    seg = (
        np.zeros(values.shape[0], dtype=np.int64)
        if segment_id is None
        else np.ascontiguousarray(segment_id, dtype=np.int64)
    )
    if out is None:
        out = np.empty_like(values)
    _median3_kernel(values, seg, n_sigmas * sigma, out)
    return out, sigma


#: A low-pass cut-off stays below this share of the logger's rate (Nyquist is 0.5).
MAX_CUTOFF_SHARE = 0.4


def pressure_cutoff_at(cutoff_hz: float, sample_rate_hz: float) -> float:
    """The pressure low-pass's cut-off a logger's rate allows [Hz]: ``cutoff_hz``, at most
    :data:`MAX_CUTOFF_SHARE` x ``sample_rate_hz``.

    >>> pressure_cutoff_at(10.0, 50.0), pressure_cutoff_at(10.0, 10.0)
    (10.0, 4.0)
    """
    return min(cutoff_hz, MAX_CUTOFF_SHARE * sample_rate_hz)


def despiked_lowpass(
    values: np.ndarray,
    segment_id: np.ndarray,
    *,
    sample_rate_hz: float,
    cutoff_hz: float,
    spike_sigmas: float,
    sigma: float | None = None,
    work: np.ndarray | None = None,
) -> np.ndarray:
    """A pressure as the compensation filters it, in place in ``values`` (float64):
    :func:`despike_median3` (``sigma``: the record's noise, else this signal's), then
    :func:`transforms.lowpass.lowpass` at ``cutoff_hz`` (``work``: its scratch)."""
    despike_median3(values, segment_id, n_sigmas=spike_sigmas, out=values, sigma=sigma)
    return lowpass(
        values, segment_id, sample_rate_hz=sample_rate_hz, cutoff_hz=cutoff_hz, out=values,
        work=work,
    )  # fmt: skip
