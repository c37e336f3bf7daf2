"""The sections of one hoist-period: what a run computed, in words, tables and figures.

:func:`hoist_sections` gives, for one run's period of one hoist: a heading with the
period and the steps' outcome in words; the load before / after / expected; the rope
tensions against the imbalance, slack and tight-rope limits; the alarms (timeline and
table); the reconciliation per position; the trips; the sanity check; the discovery
findings. A part that cannot be drawn says so and why; the others are still drawn.

The parts are drawn by :mod:`~pipelines.reports.series_sections` (from the rope
tensions and summaries) and :mod:`~pipelines.reports.check_sections` (sanity check,
discovery); the period and its steps are :mod:`~pipelines.reports.period`.
"""

from __future__ import annotations

from collections.abc import Callable

import polars as pl

from pipelines.lake import scan_lake
from pipelines.reports.check_sections import discovery_sections, sanity_section
from pipelines.reports.data import MIN_VISIT_SAMPLES, RunTables, Zone
from pipelines.reports.document import Section
from pipelines.reports.period import HoistPeriod, count_text, pct_text
from pipelines.reports.series import PeriodSeries, period_series
from pipelines.reports.series_sections import (
    alarms_section,
    load_section,
    reconciliation_section,
    ropes_section,
    trips_section,
)
from transforms.alarms import rule_thresholds
from warehouse.store import DataRoot

__all__ = ["hoist_sections"]


def _guarded(title: str, build: Callable[[], list[Section]]) -> list[Section]:
    """``build()``, or one section saying in words why it could not be drawn."""
    try:
        return build()
    except Exception as exc:  # a report part must not hide the others
        reason = " ".join(str(exc).split()) or type(exc).__name__
        return [
            Section(title, level=3).say(
                f"This part of the report could not be drawn: {type(exc).__name__}: {reason}",
                "fail",
            )
        ]


def hoist_sections(data: DataRoot, period: HoistPeriod, tables: RunTables) -> list[Section]:
    """Every section of one hoist-period (module docstring)."""
    zone = period.zone
    limits = rule_thresholds(period.description)
    head = _head(period, tables, zone)
    series_holder: list[PeriodSeries] = []

    def series() -> PeriodSeries:
        if not series_holder:
            frame = period.frame
            if frame is None:
                frame = scan_lake(
                    data, "rope_tensions", site=period.site, hoist=period.hoist,
                    start=period.start_utc, end=period.end_utc,
                )  # fmt: skip
            series_holder.append(
                period_series(
                    frame,
                    hoist=period.description,
                    trips=tables.trip_summary,
                    zone=zone,
                    start_utc=period.start_utc,
                    end_utc=period.end_utc,
                )
            )
        return series_holder[0]

    visits = _visits(tables.position_summary, zone)
    out = [head]
    out += _guarded("Load", lambda: [load_section(period, series(), visits, zone, limits)])
    out += _guarded("Rope tensions", lambda: [ropes_section(period, series(), zone, limits)])
    out += _guarded(
        "Alarms", lambda: [alarms_section(period, tables.alarms, zone, series().span_utc)]
    )
    out += _guarded(
        "Reconciliation per position",
        lambda: [
            reconciliation_section(
                period, tables.position_summary, visits, zone, limits, series().span_utc
            )
        ],
    )
    out += _guarded(
        "Trips", lambda: [trips_section(period, tables.trip_summary, series(), zone, limits)]
    )
    out += _guarded("Sanity check", lambda: [sanity_section(period, tables.sanity_checks)])
    out += _guarded("Discovery", lambda: discovery_sections(data, period))
    if series_holder and series_holder[0].samples == 0:
        head.say("No rope tensions are landed for this period: the time plots are empty.", "warn")
    return out


def _head(period: HoistPeriod, tables: RunTables, zone: Zone) -> Section:
    head = Section(f"{period.site}/{period.hoist}: {period.label}", anchor=period.anchor)
    utc = f"{period.start_utc:%Y-%m-%d %H:%M} .. {period.end_utc:%Y-%m-%d %H:%M} UTC"
    if zone.instead_of:
        head.say(
            f"Period {utc}; run {period.run_id}. Times here are UTC: the clocks of "
            f"{zone.instead_of} go back within this period, so its local times repeat."
        )
    else:
        head.say(
            f"Period {zone.text(period.start_utc, '%Y-%m-%d %H:%M')} .. "
            f"{zone.text(period.end_utc, '%Y-%m-%d %H:%M')} local time "
            f"({zone.label(period.start_utc, period.end_utc)}), {utc}; run {period.run_id}."
        )
    for step in period.steps:
        head.say(step.sentence(), "fail" if step.status == "failed" else "info")
    trips, alarms = tables.trip_summary, tables.alarms
    visits = tables.position_summary.filter(pl.col("samples") >= MIN_VISIT_SAMPLES) if (
        tables.position_summary.width
    ) else tables.position_summary  # fmt: skip
    words = [count_text(trips.height, "trip"), count_text(alarms.height, "alarm")]
    errors = visits.filter(pl.col("error_after_fraction").is_not_null()) if visits.width else visits
    if errors.height:
        before = errors["error_before_fraction"].abs().max()
        after = errors["error_after_fraction"].abs().max()
        words.append(
            f"load against expected at {errors.height} position visits: worst {pct_text(before)} "
            f"before compensation, {pct_text(after)} after"
        )
    if trips.height and trips["max_imbalance_after_fraction"].is_not_null().any():
        worst = trips.sort("max_imbalance_after_fraction", descending=True, nulls_last=True).row(
            0, named=True
        )
        rope = worst.get("max_imbalance_after_rope")
        words.append(
            f"worst rope imbalance {pct_text(worst['max_imbalance_after_fraction'])}"
            + (f" on rope {rope}" if rope is not None else "")
            + f" (trip {worst['trip_id']})"
        )
    head.say("; ".join(words) + ".")
    return head


def _visits(summary: pl.DataFrame, zone: Zone) -> pl.DataFrame:
    """Position visits with an expected load and at least MIN_VISIT_SAMPLES samples."""
    if not summary.width:
        return pl.DataFrame(schema={"position": pl.String, "mid_local": pl.Datetime("us")})
    mid = pl.col("time_start_utc") + (pl.col("time_end_utc") - pl.col("time_start_utc")) / 2
    return (
        summary.filter(
            (pl.col("samples") >= MIN_VISIT_SAMPLES) & pl.col("expected_load_n").is_not_null()
        )
        .with_columns(mid.alias("mid_utc"))
        .with_columns(
            zone.expr("mid_utc").alias("mid_local"),
            (pl.col("error_before_fraction") * 100).alias("error_before_pct"),
            (pl.col("error_after_fraction") * 100).alias("error_after_pct"),
        )
        .with_columns(
            pl.format(
                "{} trip {}, {}",
                pl.col("position"),
                pl.col("trip_id").cast(pl.String).fill_null("-"),
                pl.col("mid_local").dt.strftime("%H:%M:%S"),
            ).alias("label")
        )
    )
