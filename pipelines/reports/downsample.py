"""Downsampling long series for plotting without losing their peaks.

A 100 Hz hoist-day is 8.6 M samples per series; a browser draws a few thousand points per
line comfortably, and a plot is at most ~2000 pixels wide. Taking every n-th sample would
drop the short peaks an engineer looks for (a rope's imbalance spike lasts a second).
Min/max per pixel bucket keeps them: the time range is cut into ``buckets`` equal spans
and each span keeps its smallest and its largest sample, at their own times, in time
order. Drawn as a line this is, pixel for pixel, the envelope the full series would draw.

An empty bucket (a logger gap longer than a bucket) becomes one NaN point, so the line
breaks there instead of bridging the gap.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bucket_extremes", "downsample_minmax"]


def bucket_extremes(
    t: np.ndarray,
    y: np.ndarray,
    buckets: int,
    *,
    t0: float | None = None,
    t1: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per non-empty bucket: its number, and the positions and values of its extremes.

    Parameters
    ----------
    t : array
        Sample times, ascending (any numeric type; datetime64 is taken as its integer
        count).
    y : array
        Values; NaN samples are ignored (a bucket of only NaN counts as empty).
    buckets : int
        Number of equal time spans over ``[t0, t1]``.
    t0, t1 : float, optional
        The range (default the first and last time): a fixed range keeps the buckets of
        series of different extent aligned, e.g. to a plot's full period.

    Returns
    -------
    bucket, i_min, y_min, i_max, y_max : arrays
        One entry per bucket holding a finite value: the bucket number, the position in
        ``t`` of its first smallest value and that value, likewise its largest.
    """
    if buckets < 1:
        raise ValueError(f"buckets must be >= 1, got {buckets}")
    t = np.asarray(t)
    y = np.asarray(y)
    if y.dtype.kind != "f":
        y = y.astype(np.float64)
    if t.shape != y.shape or t.ndim != 1:
        raise ValueError(f"t and y must be 1-d of one length, got {t.shape} and {y.shape}")
    if t.dtype.kind == "M":
        t = t.view(np.int64)
    n = t.size
    none = np.zeros(0, dtype=np.int64)
    if n == 0:
        return none, none, np.zeros(0), none, np.zeros(0)
    first = t[0] if t0 is None else t0
    last = t[-1] if t1 is None else t1
    # bucket k holds first + k w <= t < first + (k + 1) w (the last one also t = last);
    # t is sorted, so each bucket is one slice, found by bisection
    edges = float(first) + (float(last) - float(first)) * np.arange(1, buckets) / buckets
    if t.dtype.kind in "iu":
        edges = np.ceil(edges).astype(t.dtype)  # t >= edge <=> t >= ceil(edge)
    if np.any(t[1:] < t[:-1]):
        raise ValueError("t must be ascending")
    bounds = np.r_[0, np.searchsorted(t, edges, side="left"), n]
    counts = np.diff(bounds)
    occupied = np.flatnonzero(counts > 0)
    starts = bounds[occupied]
    sizes = counts[occupied]
    y_min = np.fmin.reduceat(y, starts)  # fmin / fmax skip NaN; all NaN gives NaN
    y_max = np.fmax.reduceat(y, starts)
    finite = ~np.isnan(y_min)

    def first_hit(extreme: np.ndarray) -> np.ndarray:
        hits = np.flatnonzero(y == np.repeat(extreme, sizes))
        at = np.minimum(np.searchsorted(hits, starts), max(hits.size - 1, 0))
        return hits[at] if hits.size else np.zeros(starts.size, dtype=np.int64)

    i_min, i_max = first_hit(y_min), first_hit(y_max)
    return occupied[finite], i_min[finite], y_min[finite], i_max[finite], y_max[finite]


def downsample_minmax(
    t: np.ndarray,
    y: np.ndarray,
    buckets: int,
    *,
    t0: float | None = None,
    t1: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and largest sample of each of ``buckets`` equal time spans.

    Returns ``(t_out, y_out)``: per bucket holding finite values, its minimum and its
    maximum sample at their own times, in time order (one point when they coincide);
    one NaN point (at the first empty bucket's start) where buckets are empty between
    kept ones, so that a plotted line breaks across a gap. At most ``3 * buckets``
    points; ``t_out`` has ``t``'s dtype. The global minimum and maximum, and each
    bucket's extremes, are kept exactly.

    >>> t = np.arange(10.0)
    >>> downsample_minmax(t, np.array([0, 5, 1, 1, 1, 1, 1, -3, 1, 1.0]), 2)
    (array([0., 1., 5., 7.]), array([ 0.,  5.,  1., -3.]))
    """
    t = np.asarray(t)
    bucket, i_min, _, i_max, _ = bucket_extremes(t, y, buckets, t0=t0, t1=t1)
    if bucket.size == 0:
        return t[:0].copy(), np.zeros(0)
    first_i = np.minimum(i_min, i_max)
    second_i = np.where(i_min == i_max, -2, np.maximum(i_min, i_max))
    # a break (NaN) after a kept bucket followed by an empty one, at that empty bucket's
    # start time (strictly between the two kept samples around it)
    gap = np.r_[np.diff(bucket) > 1, False]
    slots = np.stack([first_i, second_i, np.where(gap, -1, -2)], axis=1).ravel()
    slots = slots[slots != -2]
    t_num = t.view(np.int64) if t.dtype.kind == "M" else t
    first_t = float(t_num[0]) if t0 is None else float(t0)
    last_t = float(t_num[-1]) if t1 is None else float(t1)
    break_t = first_t + (bucket[gap] + 1) * ((last_t - first_t) / buckets)
    is_sample = slots >= 0
    t_out = np.empty(slots.size, dtype=t_num.dtype)
    t_out[is_sample] = t_num[slots[is_sample]]
    t_out[~is_sample] = np.round(break_t) if t_num.dtype.kind in "iu" else break_t
    y_out = np.full(slots.size, np.nan)
    y_out[is_sample] = np.asarray(y)[slots[is_sample]]
    return (t_out.view(t.dtype) if t.dtype.kind == "M" else t_out), y_out
