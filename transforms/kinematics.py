"""Piston and hoist kinematics, trip phases and shaft positions.

Derivatives
    :func:`smoothed_derivative` -- Savitzky-Golay derivative per contiguous segment.
    :func:`with_piston_velocity` -- piston velocity and chamber outflow per cylinder.
    :func:`with_acceleration` -- conveyance acceleration from its speed.

Trips
    :func:`with_trip_phases` -- phase (accelerate / run / decelerate / creep /
    standstill), direction (up / down) and trip id per sample.

Positions
    :func:`position_expr` / :func:`with_position` -- pithead / middle / bottom (the
    hoist's ``shaft.positions``) within ``position_window``, else null.

Conventions (contract section 1a): displacement x positive rod out, so piston
velocity > 0 pushes oil out of the chamber (flow ``q = A_bore v`` > 0); conveyance
speed positive downwards, so ``direction`` is ``"down"`` for speed > 0. Frames in,
frames out (DataFrame or LazyFrame); sorted by time, with a segment id column
(:func:`transforms.filtering.with_segment_id`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import TypeVar

import numpy as np
import polars as pl
from numba import njit
from scipy import signal

from physics.trip_rule import (
    DIRECTIONS,
    PHASES,
    STANDSTILL_SPEED_M_S,
    named_codes,
    ordered_positions,
    position_codes,
    trip_label_codes,
)
from schemas.hoist import HoistDescription
from transforms.filtering import seconds_expr

__all__ = [
    "position_expr",
    "smoothed_derivative",
    "with_acceleration",
    "with_piston_velocity",
    "with_position",
    "with_trip_phases",
]

Frame = TypeVar("Frame", pl.DataFrame, pl.LazyFrame)


def smoothed_derivative(
    y: np.ndarray,
    segment_id: np.ndarray | None,
    *,
    dt_s: float,
    window_s: float = 0.1,
    polyorder: int = 2,
    out: np.ndarray | None = None,
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
        Segment id per sample; None: one segment.
    dt_s : float
        Nominal sample spacing [s].
    window_s : float
        Smoothing window [s].
    polyorder : int
        Polynomial degree.
    out : numpy.ndarray, optional
        Float64 array of ``y``'s length to write into (a reused buffer); every element
        is written.

    Returns
    -------
    numpy.ndarray
        dy/dt in units of y per second.

    >>> t = np.arange(0.0, 1.0, 0.01)
    >>> dy = smoothed_derivative(3.0 * t**2, None, dt_s=0.01)
    >>> bool(np.allclose(dy, 6.0 * t))
    True

    References
    ----------
    Savitzky, A., Golay, M. J. E. (1964), Anal. Chem. 36(8), 1627-1639,
    doi:10.1021/ac60214a047.
    """
    y = np.asarray(y, dtype=np.float64)
    seg = np.zeros(y.size, dtype=np.int64) if segment_id is None else np.asarray(segment_id)
    n_win = max(round(window_s / dt_s) | 1, polyorder + 2 | 1)
    if out is None:
        out = np.zeros_like(y)
    if y.size == 0:
        return out
    starts = np.flatnonzero(np.concatenate([[True], seg[1:] != seg[:-1]]))
    bounds = [*starts.tolist(), y.size]
    for a, b in itertools.pairwise(bounds):
        _segment_derivative(y[a:b], n_win, polyorder, dt_s, out=out[a:b])
    return out


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
        d = signal.savgol_filter(part, n_win, polyorder, deriv=1, delta=dt_s, mode="interp")
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
    """``savgol_filter(y, n_win, polyorder, deriv=1, delta=dt_s, mode="interp")``, faster.

    The interior is the same filter (``savgol_coeffs``), whose first-derivative
    coefficients are odd-symmetric, applied to the differences y[i + k] - y[i - k] by a
    compiled loop (equal to scipy to ~1e-14 relative; scipy's least-squares coefficients
    are odd only to ~1e-14, and a flat signal here gives exactly 0, not ~1e-14 y); the
    ``n_win // 2`` samples at each end are scipy's own polynomial fits, taken from
    ``savgol_filter`` on the first and last 2 ``n_win`` samples, which only see the first
    and last window.
    """
    y = np.ascontiguousarray(y, dtype=np.float64)
    h = n_win // 2
    # correlation weights for y[i + k] and y[i - k], k = 1..h (savgol_coeffs is in
    # convolution order), made exactly odd
    coeffs = signal.savgol_coeffs(n_win, polyorder, deriv=1, delta=dt_s)[::-1]
    odd = 0.5 * (coeffs[h + 1 :] - coeffs[:h][::-1])
    if out is None:
        out = np.empty_like(y)
    _correlate_antisymmetric(y, np.ascontiguousarray(odd), out)
    span = 2 * n_win
    head = signal.savgol_filter(y[:span], n_win, polyorder, deriv=1, delta=dt_s, mode="interp")
    tail = signal.savgol_filter(y[-span:], n_win, polyorder, deriv=1, delta=dt_s, mode="interp")
    out[:h] = head[:h]
    out[-h:] = tail[-h:]
    return out


def _derivative_expr(
    column: str, segment_col: str, dt_s: float, window_s: float, polyorder: int
) -> pl.Expr:
    def _batch(s: pl.Series) -> pl.Series:
        parts = s.struct.unnest()
        d = smoothed_derivative(
            parts["y"].cast(pl.Float64).to_numpy(),
            parts["seg"].to_numpy(),
            dt_s=dt_s,
            window_s=window_s,
            polyorder=polyorder,
        )
        return pl.Series(d, dtype=pl.Float64).fill_nan(None)

    return pl.struct(y=pl.col(column), seg=pl.col(segment_col)).map_batches(
        _batch, return_dtype=pl.Float64
    )


def with_piston_velocity(
    frame: Frame,
    x_cols: Sequence[str],
    *,
    bore_area_m2: float,
    dt_s: float,
    segment_col: str = "segment_id",
    window_s: float = 0.1,
    polyorder: int = 2,
) -> Frame:
    """Add piston velocity ``v{i}_m_s`` and chamber outflow ``q{i}_m3_s`` per cylinder.

    For the i-th column of ``x_cols`` (piston displacement [m], positive rod out):
    v = dx/dt by :func:`smoothed_derivative` per segment, and q = A_bore v [m3/s], the
    oil leaving the rodless chamber (negative: flowing in).

    >>> df = pl.DataFrame({"x1_m": np.arange(50) * 1e-4, "segment_id": np.zeros(50, int)})
    >>> out = with_piston_velocity(df, ["x1_m"], bore_area_m2=0.5, dt_s=0.01)
    >>> round(out["v1_m_s"][25], 9), round(out["q1_m3_s"][25], 9)
    (0.01, 0.005)
    """
    exprs = []
    for i, column in enumerate(x_cols, start=1):
        v = _derivative_expr(column, segment_col, dt_s, window_s, polyorder)
        exprs.append(v.alias(f"v{i}_m_s"))
    frame = frame.with_columns(exprs)
    return frame.with_columns(
        (pl.col(f"v{i}_m_s") * bore_area_m2).alias(f"q{i}_m3_s") for i in range(1, len(x_cols) + 1)
    )


def with_acceleration(
    frame: Frame,
    *,
    dt_s: float,
    speed_col: str = "speed_m_s",
    segment_col: str = "segment_id",
    window_s: float = 0.5,
    polyorder: int = 2,
    name: str = "acceleration_m_s2",
) -> Frame:
    """Add the conveyance acceleration [m/s2] (positive downwards) from its speed.

    Savitzky-Golay derivative of ``speed_col`` [m/s] per segment; see
    :func:`smoothed_derivative`. The 0.5 s default window suits encoder speed at
    100 Hz: it rounds the corners of the trip profile by about a quarter window.
    """
    return frame.with_columns(
        _derivative_expr(speed_col, segment_col, dt_s, window_s, polyorder).alias(name)
    )


def with_trip_phases(
    frame: Frame,
    hoist: HoistDescription,
    *,
    speed_col: str = "speed_m_s",
    acceleration_col: str = "acceleration_m_s2",
    segment_col: str = "segment_id",
    time_col: str = "time_utc",
    depth_col: str = "depth_m",
    standstill_speed_m_s: float = STANDSTILL_SPEED_M_S,
    acceleration_fraction: float = 0.3,
    creep_factor: float = 1.5,
) -> Frame:
    """Label each sample with trip ``phase``, ``direction`` and ``trip_id``.

    The trip rule of :mod:`physics.trip_rule` (:func:`~physics.trip_rule.trip_label_codes`
    with the thresholds given here) on the frame's columns; a null speed gives nulls.
    ``depth_col`` is optional (without it a logger gap longer than
    :data:`~physics.trip_rule.TRIP_BRIDGE_S` inside a motion starts a new trip).

    Adds columns ``phase`` (String), ``direction`` (String) and ``trip_id`` (Int64).
    Needs ``acceleration_col`` (:func:`with_acceleration`); a LazyFrame is collected.
    """
    if isinstance(frame, pl.LazyFrame):  # one evaluation of the plan
        return with_trip_phases(
            frame.collect(), hoist, speed_col=speed_col, acceleration_col=acceleration_col,
            segment_col=segment_col, time_col=time_col, depth_col=depth_col,
            standstill_speed_m_s=standstill_speed_m_s,
            acceleration_fraction=acceleration_fraction, creep_factor=creep_factor,
        ).lazy()  # fmt: skip
    schema = frame.collect_schema()
    if time_col not in schema:
        raise ValueError(f"{time_col}: no such column (logger gaps inside a trip need times)")
    depth = pl.col(depth_col).cast(pl.Float64) if depth_col in schema else pl.lit(np.nan)
    columns = frame.select(
        seconds_expr(schema, time_col).alias("t"),
        pl.col(speed_col).cast(pl.Float64).alias("v"),
        pl.col(acceleration_col).cast(pl.Float64).fill_null(np.nan).alias("a"),
        pl.col(segment_col).cast(pl.Int64).alias("segment"),
        depth.fill_null(np.nan).alias("depth"),
    )
    speed = columns["v"]
    phase, direction, trip_id = trip_label_codes(
        columns["t"].to_numpy(),
        speed.fill_null(0.0).to_numpy(),
        columns["a"].to_numpy(),
        columns["segment"].to_numpy(),
        columns["depth"].to_numpy(),
        hoist,
        standstill_speed_m_s=standstill_speed_m_s,
        acceleration_fraction=acceleration_fraction,
        creep_factor=creep_factor,
    )
    unknown = speed.is_null().to_numpy()
    phase[unknown], direction[unknown], trip_id[unknown] = -1, -1, -1
    labels = pl.DataFrame(
        [
            named_codes("phase", phase, PHASES),
            named_codes("direction", direction, DIRECTIONS),
            pl.Series("trip_id", trip_id, dtype=pl.Int64).set(pl.Series(trip_id < 0), None),
        ]
    )
    return frame.with_columns(labels)


def position_expr(depth: pl.Expr, hoist: HoistDescription) -> pl.Expr:
    """Named shaft position at ``depth`` [m] within the hoist's ``position_window``.

    :func:`physics.trip_rule.position_codes` as an expression: the nearest named
    position (``shaft.positions``) whose depth is within ``shaft.position_window`` of
    ``depth``; null elsewhere (String).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> df = pl.DataFrame({"depth_m": [1.0, 100.0, 318.0, 604.0]})
    >>> df.select(position_expr(pl.col("depth_m"), hoist))["position"].to_list()
    ['pithead', None, 'middle', 'bottom']
    """
    names = [name for name, _ in ordered_positions(hoist)]

    def batch(depth_m: pl.Series) -> pl.Series:
        codes = position_codes(depth_m.cast(pl.Float64).fill_null(np.nan).to_numpy(), hoist)
        return named_codes("position", codes, names)

    return depth.map_batches(batch, return_dtype=pl.String).alias("position")


def with_position(frame: Frame, hoist: HoistDescription, *, depth_col: str = "depth_m") -> Frame:
    """Add the ``position`` column (:func:`position_expr`) from ``depth_col`` [m]."""
    return frame.with_columns(position_expr(pl.col(depth_col), hoist))
