"""Per trip: the payload, its spread over the positions, and each rope's extremes
(TRIP_SUMMARY), from the samples or from per-block partials (:func:`trip_partials`).
"""

from __future__ import annotations

import polars as pl

from schemas.tables import ROPES, TRIP_SUMMARY, conform
from transforms.load_exprs import (
    rope_extremes_aggs,
    rope_imbalance_expr,
    trip_payload_expr,
    trip_payload_spread_expr,
    with_optional_columns,
    worst_rope_exprs,
)

__all__ = ["summarise_trips", "summarise_trips_from_partials", "trip_partials"]


def trip_partials(rope_tensions: pl.LazyFrame | pl.DataFrame) -> pl.DataFrame:
    """Extents and peaks per trip of one block of samples (:func:`summarise_trips`);
    concatenate the partials of every block for :func:`summarise_trips_from_partials`."""
    lazy = with_optional_columns(rope_tensions)
    band = "load_hi_n" in lazy.collect_schema().names()
    return (
        lazy.filter(pl.col("trip_id").is_not_null())
        .sort("time_utc")
        .with_columns(rope_imbalance_expr("tension", i).alias(f"_imbalance{i}") for i in ROPES)
        .group_by("trip_id")
        .agg(
            pl.col("direction").drop_nulls().first(),
            pl.col("time_utc").first().alias("time_start_utc"),
            pl.col("time_utc").last().alias("time_end_utc"),
            pl.col("depth_m").drop_nulls().first().alias("depth_start_m"),
            pl.col("depth_m").drop_nulls().last().alias("depth_end_m"),
            pl.col("load_n").max().alias("max_load_after_n"),
            *([pl.col("load_hi_n").max().alias("max_load_after_hi_n")] if band else []),
            *rope_extremes_aggs(),
        )
        .collect()
    )


def summarise_trips(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    position_summary: pl.DataFrame,
    *,
    run_id: str,
    site: str,
    hoist_name: str,
) -> pl.DataFrame:
    """One row per trip: extent, payload (over positions, by samples) and its spread, peaks.

    Peaks are over the trip's samples after compensation: ``max_load_after_n``; per rope
    i the largest and smallest tension and the largest imbalance |T_i - mean T| / mean T
    with the time of its sample (``max_imbalance_after{i}_fraction``, ``..._time_utc``);
    and the worst rope's: ``max_imbalance_after_fraction`` (the largest per-sample
    rope-to-mean imbalance of the trip), ``max_imbalance_after_rope`` (1-4, the lowest on
    a tie) and ``max_imbalance_after_time_utc``. Returns the TRIP_SUMMARY schema.
    """
    return summarise_trips_from_partials(
        trip_partials(rope_tensions),
        position_summary,
        run_id=run_id,
        site=site,
        hoist_name=hoist_name,
    )


def summarise_trips_from_partials(
    partials: pl.DataFrame,
    position_summary: pl.DataFrame,
    *,
    run_id: str,
    site: str,
    hoist_name: str,
) -> pl.DataFrame:
    """:func:`summarise_trips` from the :func:`trip_partials` of every block."""
    band = "max_load_after_hi_n" in partials.columns
    extremes = []
    for i in ROPES:
        imbalance = pl.col(f"max_imbalance_after{i}_fraction")
        extremes += [
            pl.col(f"max_tension_after{i}_n").max(),
            pl.col(f"min_tension_after{i}_n").min(),
            imbalance.max(),
            pl.col(f"max_imbalance_after{i}_time_utc")
            .sort_by(imbalance, descending=True, nulls_last=True, maintain_order=True)
            .first(),
        ]
    trips = (
        partials.sort("time_start_utc")
        .group_by("trip_id", maintain_order=True)
        .agg(
            pl.col("direction").drop_nulls().first(),
            pl.col("time_start_utc").first(),
            pl.col("time_end_utc").last(),
            pl.col("depth_start_m").drop_nulls().first(),
            pl.col("depth_end_m").drop_nulls().last(),
            pl.col("max_load_after_n").max(),
            *([pl.col("max_load_after_hi_n").max()] if band else []),
            *extremes,
        )
        .with_columns(worst_rope_exprs())
    )
    payloads = (
        position_summary.filter(pl.col("trip_id").is_not_null())
        .with_columns(pl.col("trip_id").cast(pl.Int64))
        .group_by("trip_id")
        .agg(
            trip_payload_expr().alias("payload_kg"),
            trip_payload_spread_expr().alias("payload_spread_kg"),
        )
    )
    result = (
        trips.join(payloads, on="trip_id", how="left")
        .with_columns(run_id=pl.lit(run_id), site=pl.lit(site), hoist=pl.lit(hoist_name))
        .sort("trip_id")
    )
    return conform(result, TRIP_SUMMARY)
