"""Per position: the load and tensions at each named shaft position a trip stops or
passes at (POSITION_SUMMARY), from the samples or from per-block partial sums.

A stint is one visit of a position (consecutive samples within its window); its means
are sums and counts, so blocks of a day give partial sums that add up to the day's
(:func:`stint_partials`, :class:`StintCarry` carrying the open stint across a block
edge). The reconciliation's expressions: :mod:`transforms.load_exprs`.
"""

from __future__ import annotations

from typing import NamedTuple

import polars as pl

from physics.tension import tail_rope_length_m
from schemas.hoist import HoistDescription
from schemas.tables import POSITION_SUMMARY, ROPES, conform
from transforms.load_exprs import (
    STEADY_PHASES,
    PayloadSource,
    expected_load_expr,
    imbalance_expr,
    inferred_payload_expr,
    with_optional_columns,
    with_reference_payload,
)

__all__ = [
    "StintCarry",
    "stint_partials",
    "summarise_positions",
    "summarise_positions_from_partials",
]


_STINT_MEANS = (
    "depth_m",
    *(f"tension_raw{i}_n" for i in ROPES),
    *(f"tension{i}_n" for i in ROPES),
    "load_raw_n",
    "load_n",
    "load_lo_n",
    "load_hi_n",
    "_payload_sample_kg",
)


class StintCarry(NamedTuple):
    """Where a block's stints continue from: the previous block's last ``position`` and
    ``trip_id`` and the number of stints so far (:func:`stint_partials`)."""

    position: str | None = None
    trip_id: int | None = None
    stints: int = 0


def stint_partials(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    hoist: HoistDescription,
    *,
    carry: StintCarry | None = None,
) -> tuple[pl.DataFrame, StintCarry]:
    """Sums, counts and extents per stint of one block of samples (issue 16).

    A stint is a run of consecutive samples with the same ``trip_id`` and ``position``
    (:func:`summarise_positions`); ``carry`` continues the numbering of the previous
    block, so a stint cut by a block edge gets one number in both. Concatenate the
    partials of every block and pass them to :func:`summarise_positions_from_partials`.
    """
    carry = carry or StintCarry()
    lazy = with_optional_columns(rope_tensions).sort("time_utc")
    names = lazy.collect_schema().names()
    previous = [
        pl.lit(carry.position, dtype=pl.String),
        pl.lit(carry.trip_id, dtype=pl.Int64),
    ]
    changed = pl.col("position").ne_missing(
        pl.col("position").shift(1, fill_value=previous[0])
    ) | pl.col("trip_id").ne_missing(pl.col("trip_id").shift(1, fill_value=previous[1]))
    if carry.stints == 0:  # the record's first sample starts a stint
        changed = changed | (pl.int_range(pl.len()) == 0)
    steady = pl.col("phase").is_null() | pl.col("phase").is_in(STEADY_PHASES)
    numbered = lazy.with_columns(
        _stint=(changed.cast(pl.Int64).cum_sum() + (carry.stints - 1)),
        _payload_sample_kg=pl.when(steady).then(inferred_payload_expr(hoist)),
    ).collect()
    if numbered.height == 0:
        return _empty_partials(), carry
    last = numbered.row(numbered.height - 1, named=True)
    following = StintCarry(last["position"], last["trip_id"], int(last["_stint"]) + 1)
    present = [c for c in _STINT_MEANS if c in names or c == "_payload_sample_kg"]
    partials = (
        numbered.lazy()
        .filter(pl.col("position").is_not_null())
        .group_by("_stint")
        .agg(
            pl.col("trip_id").first(),
            pl.col("position").first(),
            pl.col("time_utc").min().alias("time_start_utc"),
            pl.col("time_utc").max().alias("time_end_utc"),
            pl.col("acceleration_up_m_s2").fill_null(0.0).sum().alias("_sum_accel"),
            *(pl.col(c).cast(pl.Float64).sum().alias(f"_sum_{c}") for c in present),
            *(pl.col(c).count().cast(pl.Int64).alias(f"_n_{c}") for c in present),
            pl.len().cast(pl.Int64).alias("samples"),
        )
        .collect()
    )
    return partials, following


def _empty_partials() -> pl.DataFrame:
    return pl.DataFrame(
        schema={
            "_stint": pl.Int64,
            "trip_id": pl.Int64,
            "position": pl.String,
            "time_start_utc": pl.Datetime("us", "UTC"),
            "time_end_utc": pl.Datetime("us", "UTC"),
            "_sum_accel": pl.Float64,
            **{f"_sum_{c}": pl.Float64 for c in _STINT_MEANS},
            **{f"_n_{c}": pl.Int64 for c in _STINT_MEANS},
            "samples": pl.Int64,
        }
    )


def summarise_positions(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    hoist: HoistDescription,
    *,
    run_id: str,
    site: str | None = None,
    hoist_name: str | None = None,
    payload_kg: PayloadSource = None,
) -> pl.DataFrame:
    """One row per trip and named position: the paper's Table 2 for every trip.

    Samples count for a position where the ``position`` column names it (trip
    segmentation marks samples within the hoist's ``position_window`` of a named depth).
    One row per stint: a run of consecutive samples with the same ``trip_id`` and
    ``position`` (standstill samples carry no trip id and give one row per stay). A trip
    usually passes a position once, but a sample just outside the position window (the
    conveyance's bounce at a stop, a logger's jitter) splits a pass into two stints: the
    grain is ``(run_id, position, time_start_utc)``, not the trip and position
    (warehouse/README.md). Tensions are averaged over the stint; ``payload_kg`` is
    the payload inferred there from its steady samples (:data:`STEADY_PHASES`; null when
    the stint is all acceleration). ``expected_load_n`` uses the reference payload:
    ``payload_kg`` when known (a float for every trip, or a frame with ``trip_id`` and
    ``payload_kg``),
    otherwise the mean of the trip's inferred payloads, so the error then measures how
    far the positions disagree.

    The whole record is one block of :func:`stint_partials`. Returns a frame with the
    POSITION_SUMMARY schema.
    """
    partials, _ = stint_partials(rope_tensions, hoist)
    return summarise_positions_from_partials(
        partials, hoist, run_id=run_id, site=site, hoist_name=hoist_name, payload_kg=payload_kg
    )


def summarise_positions_from_partials(
    partials: pl.DataFrame,
    hoist: HoistDescription,
    *,
    run_id: str,
    site: str | None = None,
    hoist_name: str | None = None,
    payload_kg: PayloadSource = None,
) -> pl.DataFrame:
    """:func:`summarise_positions` from the :func:`stint_partials` of every block."""
    sums = [c for c in partials.columns if c.startswith("_sum_") and c != "_sum_accel"]
    counts = [f"_n_{c.removeprefix('_sum_')}" for c in sums]
    grouped = partials.group_by("_stint").agg(
        pl.col("trip_id").first(),
        pl.col("position").first(),
        pl.col("time_start_utc").min(),
        pl.col("time_end_utc").max(),
        pl.col("_sum_accel").sum(),
        *(pl.col(c).sum() for c in (*sums, *counts)),
        pl.col("samples").sum(),
    )
    alias = {
        "depth_m": "depth_m",
        "load_raw_n": "load_before_n",
        "load_n": "load_after_n",
        "load_lo_n": "load_after_lo_n",
        "load_hi_n": "load_after_hi_n",
        "_payload_sample_kg": "payload_kg",
        **{f"tension_raw{i}_n": f"tension_before{i}_n" for i in ROPES},
        **{f"tension{i}_n": f"tension_after{i}_n" for i in ROPES},
    }
    means = [
        pl.when(pl.col(f"_n_{c}") > 0).then(pl.col(f"_sum_{c}") / pl.col(f"_n_{c}")).alias(alias[c])
        for c in (s.removeprefix("_sum_") for s in sums)
    ]
    grouped = grouped.with_columns(*means, _accel_m_s2=pl.col("_sum_accel") / pl.col("samples"))
    expected = expected_load_expr(
        hoist,
        payload_kg=pl.col("reference_payload_kg"),
        acceleration_up_m_s2=pl.col("_accel_m_s2"),
    )
    result = (
        with_reference_payload(grouped, payload_kg)
        .with_columns(
            run_id=pl.lit(run_id),
            site=pl.lit(site or hoist.hoist.site),
            hoist=pl.lit(hoist_name or hoist.hoist.name),
            tail_rope_length_m=tail_rope_length_m(hoist, pl.col("depth_m")),
            expected_load_n=expected,
            imbalance_after_fraction=imbalance_expr("tension_after"),
        )
        .with_columns(
            error_before_fraction=pl.col("load_before_n") / pl.col("expected_load_n") - 1.0,
            error_after_fraction=pl.col("load_after_n") / pl.col("expected_load_n") - 1.0,
        )
        .sort("time_start_utc")
    )
    return conform(result, POSITION_SUMMARY)
