"""The sections of a hoist-period drawn from its rope tensions and summaries.

The load before / after / expected (:func:`load_section`), the rope tensions against
the imbalance, slack and tight-rope limits (:func:`ropes_section`), the alarms
(:func:`alarms_section`), the reconciliation per position
(:func:`reconciliation_section`) and the trips (:func:`trips_section`); called by
:func:`pipelines.reports.sections.hoist_sections`.
"""

from __future__ import annotations

import datetime as dt

import polars as pl

from pipelines.reports import figures
from pipelines.reports.data import MIN_VISIT_SAMPLES, Zone
from pipelines.reports.document import Section, Table
from pipelines.reports.period import HoistPeriod, num_text, pct_text
from pipelines.reports.series import PeriodSeries
from transforms.alarms import ALARM_RULES, RuleThresholds

__all__ = [
    "alarms_section",
    "load_section",
    "reconciliation_section",
    "ropes_section",
    "trips_section",
]


def load_section(
    period: HoistPeriod,
    series: PeriodSeries,
    visits: pl.DataFrame,
    zone: Zone,
    limits: RuleThresholds,
) -> Section:
    section = Section("Load before and after compensation", level=3)
    if series.band is None:
        section.say(
            "No uncertainty band yet: this run landed no 95 % band (load_lo_n / load_hi_n).",
            "info",
        )
    ext = series.extremes
    if "after_kn_max" in ext:
        section.say(
            f"Load after compensation {ext['after_kn_min']:.1f} .. {ext['after_kn_max']:.1f} kN "
            f"(before: {ext.get('before_kn_min', float('nan')):.1f} .. "
            f"{ext.get('before_kn_max', float('nan')):.1f} kN). The lower panel shows the "
            "difference to the expected load, where before and after are told apart."
        )
    section.figures.append(
        figures.load_figure(
            series,
            zone=zone,
            tolerance_fraction=limits.reconciliation_tolerance_fraction,
            visits=visits,
            title=f"Load on the four ropes, {period.site}/{period.hoist}, {period.label}",
        )
    )
    return section


def ropes_section(
    period: HoistPeriod, series: PeriodSeries, zone: Zone, limits: RuleThresholds
) -> Section:
    section = Section("Rope tensions: imbalance, slack and tight rope", level=3)
    section.say(
        f"Limits from the hoist description: imbalance +-{limits.imbalance_fraction * 100:g} % "
        "of the mean of the four ropes (China Coal Mine Safety Regulations, multi-rope friction "
        f"hoists); slack rope below {limits.slack_n / 1e3:.2f} kN (60 % of the empty "
        "conveyance's share, Quebec S-2.1 r. 14 s. 253.2); tight rope above "
        f"{limits.tight_n / 1e3:.2f} kN (maximum static load + 10 % of the breaking strength)."
    )
    ext = series.extremes
    devs = [
        (r, max(abs(ext[f"deviation{r}_pct_min"]), abs(ext[f"deviation{r}_pct_max"])))
        for r in range(1, 5)
        if f"deviation{r}_pct_max" in ext
    ]
    if devs:
        rope, worst = max(devs, key=lambda d: d[1])
        section.say(
            f"Largest deviation from the mean: {worst:.2f} % on rope {rope}; tensions "
            f"{ext.get('lowest_kn_min', float('nan')):.2f} .. "
            f"{ext.get('highest_kn_max', float('nan')):.2f} kN."
        )
    section.figures.append(
        figures.ropes_figure(
            series,
            zone=zone,
            thresholds=limits,
            title=f"Rope tensions against the limits, {period.site}/{period.hoist}, {period.label}",
        )
    )
    return section


def alarms_section(
    period: HoistPeriod,
    alarms: pl.DataFrame,
    zone: Zone,
    span: tuple[dt.datetime, dt.datetime],
) -> Section:
    section = Section(f"Alarms ({alarms.height})", level=3)
    if not alarms.height:
        section.say("No alarm was raised in this period.", "ok")
        return section
    by_rule = alarms.group_by("rule").len().sort("rule")
    section.say(
        "; ".join(f"{r['len']} x {r['rule']}" for r in by_rule.iter_rows(named=True))
        + ". The timeline has one lane per rope (and one for the hoist-wide rules); a "
        "diamond marks each alarm's peak (hover for the values)."
    )
    section.figures.append(
        figures.alarm_timeline(
            alarms,
            zone=zone,
            start=min(span[0], alarms["start_utc"].min()),
            end=max(span[1], alarms["end_utc"].max()),
            title=f"Alarms by rope, {period.site}/{period.hoist}, {period.label}",
        )
    )
    tz = zone.label(period.start_utc, period.end_utc)
    rows = []
    for row in alarms.sort("start_utc").iter_rows(named=True):
        duration = (row["end_utc"] - row["start_utc"]).total_seconds()
        rule = ALARM_RULES.get(row["rule"])
        rows.append(
            [
                row["rule"],
                "hoist" if row["rope"] is None else str(row["rope"]),
                zone.text(row["start_utc"]),
                zone.text(row["end_utc"]),
                f"{duration:.1f}",
                figures.peak_text(row["peak_value"], row["unit"]),
                zone.text(row["peak_time_utc"], "%H:%M:%S"),
                figures.peak_text(row["threshold"], row["unit"]),
                (row["message"] or "").split(" [")[0] or (rule.citation if rule else ""),
            ]
        )
    section.tables.append(
        Table(
            "",
            ["rule", "rope", f"start ({tz})", f"end ({tz})", "duration [s]", "peak",
             "peak at", "threshold", "what"],
            rows,
            key="alarms",
        )
    )  # fmt: skip
    return section


def reconciliation_section(
    period: HoistPeriod,
    summary: pl.DataFrame,
    visits: pl.DataFrame,
    zone: Zone,
    limits: RuleThresholds,
    span: tuple[dt.datetime, dt.datetime],
) -> Section:
    section = Section("Reconciliation per position", level=3)
    tol = limits.reconciliation_tolerance_fraction
    depths = period.description.shaft.positions_m
    order = sorted(depths, key=lambda name: float(depths[name]))
    short = summary.filter(pl.col("samples") < MIN_VISIT_SAMPLES).height if summary.width else 0
    section.say(
        "Each point is one visit of a position (a trip passing it or a stay): the mean load "
        "there against the expected load (m_c + m_p + m_t(z))(g + a) for the trip's payload, "
        f"before and after compensation; tolerance +-{tol * 100:g} % (hoist description). "
        f"Passes of fewer than {MIN_VISIT_SAMPLES} samples are left out ({short} here)."
    )
    if not visits.height:
        section.say("No position visit with an expected load in this period.", "warn")
        return section
    positions = [p for p in order if p in set(visits["position"].to_list())]
    section.figures.append(
        figures.reconciliation_figure(
            visits,
            zone=zone,
            tolerance_fraction=tol,
            positions=positions,
            start=span[0],
            end=span[1],
            title=f"Load minus expected load per position visit, {period.site}/{period.hoist}, "
            f"{period.label}",
        )
    )
    rows = []
    for position in positions:
        part = visits.filter(pl.col("position") == position)
        before = part["error_before_fraction"].abs()
        after = part["error_after_fraction"].abs()
        rows.append(
            [
                position,
                f"{part['depth_m'].mean():.0f}",
                str(part.height),
                pct_text(before.mean()),
                pct_text(after.mean()),
                pct_text(before.max()),
                pct_text(after.max()),
                f"{int((after <= tol).sum())}/{part.height}",
            ]
        )
    section.tables.append(
        Table(
            "",
            ["position", "depth [m]", "visits", "mean |error| before", "mean |error| after",
             "worst before", "worst after", "within tolerance after"],
            rows,
            key="reconciliation",
        )
    )  # fmt: skip
    return section


def trips_section(
    period: HoistPeriod,
    trips: pl.DataFrame,
    series: PeriodSeries,
    zone: Zone,
    limits: RuleThresholds,
) -> Section:
    section = Section(f"Trips ({trips.height})", level=3)
    if not trips.height:
        section.say("No trip in this period.")
        return section
    worst = series.worst_rope
    if worst.height:
        trips = trips.join(
            worst.rename({"rope": "_rope", "fraction": "_fraction"}), on="trip_id", how="left"
        ).with_columns(
            pl.coalesce("max_imbalance_after_rope", "_rope").alias("worst_rope"),
            pl.coalesce("max_imbalance_after_fraction", "_fraction").alias("worst_fraction"),
        )
    else:
        trips = trips.with_columns(
            pl.col("max_imbalance_after_rope").alias("worst_rope"),
            pl.col("max_imbalance_after_fraction").alias("worst_fraction"),
        )
    trips = trips.with_columns(
        (pl.col("worst_fraction") * 100).alias("worst_pct"),
        pl.format("{} {}", pl.col("trip_id"), pl.col("direction").fill_null("")).alias("label"),
    )
    tz = zone.label(period.start_utc, period.end_utc)
    rows = []
    for row in trips.iter_rows(named=True):
        seconds = (row["time_end_utc"] - row["time_start_utc"]).total_seconds()
        rows.append(
            [
                str(row["trip_id"]),
                row["direction"] or "",
                zone.text(row["time_start_utc"]),
                zone.text(row["time_end_utc"], "%H:%M:%S"),
                f"{seconds:.0f}",
                num_text(row["payload_kg"], 1.0, 0),
                num_text(row["payload_spread_kg"], 1.0, 0),
                num_text(row["max_load_after_n"], 1e3, 1),
                pct_text(row["worst_fraction"]),
                "" if row["worst_rope"] is None else str(row["worst_rope"]),
                zone.text(row["max_imbalance_after_time_utc"], "%H:%M:%S"),
            ]
        )
    section.tables.append(
        Table(
            "",
            ["trip", "direction", f"start ({tz})", "end", "duration [s]", "payload [kg]",
             "payload spread [kg]", "max load [kN]", "worst imbalance", "rope", "at"],
            rows,
            key="trips",
        )
    )  # fmt: skip
    section.figures.append(
        figures.trips_figure(
            trips,
            imbalance_fraction=limits.imbalance_fraction,
            title=f"Worst rope imbalance per trip, {period.site}/{period.hoist}, {period.label}",
        )
    )
    return section
