"""Piston and hoist kinematics, trip phases and shaft positions.

Derivatives
    :func:`smoothed_derivative` -- Savitzky-Golay derivative per contiguous segment (its
    home is :mod:`physics.conveyance`, beside the conveyance's speed from its depth).
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

from collections.abc import Sequence
from typing import TypeVar

import numpy as np
import polars as pl

from physics.conveyance import conveyance_speed, smoothed_derivative
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
    with the thresholds given here) on the frame's columns; a null speed is the
    conveyance's speed from its depth (:func:`physics.conveyance.conveyance_speed`), and
    gives nulls where the depth is unknown too.
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
    t, segment = columns["t"].to_numpy(), columns["segment"].to_numpy()
    depth = columns["depth"].to_numpy()
    steps = np.diff(t)
    speed = conveyance_speed(
        t, columns["v"].fill_null(np.nan).to_numpy(), depth, segment,
        dt_s=float(np.median(steps)) if steps.size else 1.0,
    )  # fmt: skip
    unknown = ~np.isfinite(speed)
    phase, direction, trip_id = trip_label_codes(
        t,
        np.where(unknown, 0.0, speed),
        columns["a"].to_numpy(),
        segment,
        depth,
        hoist,
        standstill_speed_m_s=standstill_speed_m_s,
        acceleration_fraction=acceleration_fraction,
        creep_factor=creep_factor,
    )
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
