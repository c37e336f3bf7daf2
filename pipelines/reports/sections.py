"""The sections of one hoist-period: what a run computed, in words, tables and figures.

:func:`hoist_sections` gives, for one run's period of one hoist: a heading with the
period and the steps' outcome in words; the load before / after / expected; the rope
tensions against the imbalance, slack and tight-rope limits; the alarms (timeline and
table); the reconciliation per position; the trips; the sanity check; the discovery
findings. A part that cannot be drawn says so and why; the others are still drawn.
"""

from __future__ import annotations

import datetime as dt
import json
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import polars as pl

from pipelines.lake import scan_lake
from pipelines.reports import figures
from pipelines.reports.data import MIN_VISIT_SAMPLES, PeriodSeries, RunTables, Zone, period_series
from pipelines.reports.document import Section, Table
from schemas.hoist import HoistDescription
from transforms.alarms import ALARM_RULES, RuleThresholds, rule_thresholds
from warehouse.store import DataRoot

__all__ = ["HoistPeriod", "Step", "hoist_sections"]

StepStatus = Literal["done", "skipped", "failed"]


@dataclass(frozen=True)
class Step:
    """A step of the command for this hoist-period and how it went, in words."""

    name: str
    status: StepStatus
    detail: str = ""

    @classmethod
    def from_outcome(cls, outcome: object) -> Step:
        """From a landed step outcome (:class:`pipelines.steps.StepOutcome`, or a
        ``run_steps`` row as a dict)."""
        get = outcome.get if isinstance(outcome, dict) else lambda k: getattr(outcome, k, None)
        name = str(get("step") or "step").replace("_", " ")
        status = str(get("status") or "done")
        return cls(name, status if status in ("done", "skipped", "failed") else "done",  # type: ignore[arg-type]
                   str(get("message") or ""))  # fmt: skip

    def sentence(self) -> str:
        """``sanity check: 5 of 6 trips passed.``, ``discovery: skipped: <why>.``,
        ``sanity check: FAILED: <reason>.``"""
        verb = {"done": "", "skipped": "skipped", "failed": "FAILED"}[self.status]
        words = ": ".join(w for w in (verb, self.detail) if w) or "done"
        return f"{self.name[:1].upper()}{self.name[1:]}: {words.rstrip('.')}."


@dataclass
class HoistPeriod:
    """One run's period of one hoist, to be reported in detail.

    ``frame``: the run's rope tensions when still in memory (``ropeload run``, demo);
    otherwise they are read from the lake. ``discovery_json``: a discovery report written
    for this period (its residual trace is drawn when present).
    """

    run_id: str
    description: HoistDescription
    start_utc: dt.datetime
    end_utc: dt.datetime
    label: str
    steps: Sequence[Step] = ()
    frame: pl.DataFrame | None = None
    discovery_json: Path | None = None
    anchor: str = ""
    extra: dict[str, object] = field(default_factory=dict)

    @property
    def site(self) -> str:
        return self.description.hoist.site

    @property
    def hoist(self) -> str:
        return self.description.hoist.name

    @property
    def zone(self) -> Zone:
        return Zone(self.description.hoist.timezone)


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _pct(value: float | None, digits: int = 2) -> str:
    return "" if value is None else f"{value * 100:.{digits}f} %"


def _num(value: float | None, scale: float = 1.0, digits: int = 2) -> str:
    if value is None or value != value:  # None or NaN
        return ""
    return f"{value / scale:.{digits}f}"


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
    out += _guarded("Load", lambda: [_load(period, series(), visits, zone, limits)])
    out += _guarded("Rope tensions", lambda: [_ropes(period, series(), zone, limits)])
    out += _guarded("Alarms", lambda: [_alarms(period, tables.alarms, zone, series().span_utc)])
    out += _guarded(
        "Reconciliation per position",
        lambda: [
            _reconciliation(
                period, tables.position_summary, visits, zone, limits, series().span_utc
            )
        ],
    )
    out += _guarded("Trips", lambda: [_trips(period, tables.trip_summary, series(), zone, limits)])
    out += _guarded("Sanity check", lambda: [_sanity(period, tables.sanity_checks)])
    out += _guarded("Discovery", lambda: _discovery(data, period))
    if series_holder and series_holder[0].samples == 0:
        head.say("No rope tensions are landed for this period: the time plots are empty.", "warn")
    return out


def _head(period: HoistPeriod, tables: RunTables, zone: Zone) -> Section:
    head = Section(f"{period.site}/{period.hoist}: {period.label}", anchor=period.anchor)
    head.say(
        f"Period {zone.text(period.start_utc, '%Y-%m-%d %H:%M')} .. "
        f"{zone.text(period.end_utc, '%Y-%m-%d %H:%M')} local time "
        f"({zone.label(period.start_utc)}), "
        f"{period.start_utc:%Y-%m-%d %H:%M} .. {period.end_utc:%Y-%m-%d %H:%M} UTC; run "
        f"{period.run_id}."
    )
    for step in period.steps:
        head.say(step.sentence(), "fail" if step.status == "failed" else "info")
    trips, alarms = tables.trip_summary, tables.alarms
    visits = tables.position_summary.filter(pl.col("samples") >= MIN_VISIT_SAMPLES) if (
        tables.position_summary.width
    ) else tables.position_summary  # fmt: skip
    words = [_count(trips.height, "trip"), _count(alarms.height, "alarm")]
    errors = visits.filter(pl.col("error_after_fraction").is_not_null()) if visits.width else visits
    if errors.height:
        before = errors["error_before_fraction"].abs().max()
        after = errors["error_after_fraction"].abs().max()
        words.append(
            f"load against expected at {errors.height} position visits: worst {_pct(before)} "
            f"before compensation, {_pct(after)} after"
        )
    if trips.height and trips["max_imbalance_after_fraction"].is_not_null().any():
        worst = trips.sort("max_imbalance_after_fraction", descending=True, nulls_last=True).row(
            0, named=True
        )
        rope = worst.get("max_imbalance_after_rope")
        words.append(
            f"worst rope imbalance {_pct(worst['max_imbalance_after_fraction'])}"
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


def _load(
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


def _ropes(
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


def _alarms(
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
    tz = zone.label(period.start_utc)
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
                figures._peak_text(row["peak_value"], row["unit"]),
                zone.text(row["peak_time_utc"], "%H:%M:%S"),
                figures._peak_text(row["threshold"], row["unit"]),
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


def _reconciliation(
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
                _pct(before.mean()),
                _pct(after.mean()),
                _pct(before.max()),
                _pct(after.max()),
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


def _trips(
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
    tz = zone.label(period.start_utc)
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
                _num(row["payload_kg"], 1.0, 0),
                _num(row["payload_spread_kg"], 1.0, 0),
                _num(row["max_load_after_n"], 1e3, 1),
                _pct(row["worst_fraction"]),
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


_LIMIT = re.compile(r"limit ([0-9.]+) x")


def _sanity(period: HoistPeriod, checks: pl.DataFrame) -> Section:
    section = Section("Sanity check against the simulation", level=3)
    step = next((s for s in period.steps if s.name == "sanity check"), None)
    if step is not None and step.status != "done":
        section.say(step.sentence(), "fail" if step.status == "failed" else "info")
    if not checks.height:
        if step is None or step.status == "done":
            section.say("No trip was checked against the simulation in this period.")
        return section
    if "status" not in checks.columns:
        checks = checks.with_columns(
            pl.when(pl.col("passed"))
            .then(pl.lit("passed"))
            .otherwise(pl.lit("failed"))
            .alias("status")
        )
    checks = checks.with_columns(
        pl.col("status").fill_null(
            pl.when(pl.col("passed")).then(pl.lit("passed")).otherwise(pl.lit("failed"))
        )
    )
    failed = checks.filter(pl.col("status") == "failed")
    compared = checks.filter(pl.col("status") != "skipped")
    skipped = checks.height - compared.height
    section.say(
        f"{compared.height - failed.height} of {compared.height} trips passed: the RMS of "
        "measured minus simulated sensor pressure within the limit times the sensor noise"
        + (f"; {skipped} trip(s) could not be compared (reasons in the table)" if skipped else "")
        + ".",
        "warn" if failed.height else "ok",
    )
    factor = [float(m.group(1)) if (m := _LIMIT.search(msg or "")) else None
              for msg in checks["message"].to_list()]  # fmt: skip
    checks = checks.with_columns(
        pl.Series("factor", factor, dtype=pl.Float64),
        pl.format("trip {}", pl.col("trip_id")).alias("label"),
    ).with_columns((pl.col("factor") * pl.col("noise_pa")).alias("limit_pa"))
    section.figures.append(
        figures.sanity_figure(
            checks,
            title="Measured minus simulated sensor pressure, RMS per trip, against the pass "
            f"limit, {period.site}/{period.hoist}, {period.label}",
        )
    )
    rows = [
        [
            str(r["trip_id"]),
            "FAILED" if r["status"] == "failed" else str(r["status"]),
            _num(r["rms_gap_pa"], 1e3),
            _num(r["noise_pa"], 1e3),
            ""
            if not r["noise_pa"] or r["rms_gap_pa"] is None or r["rms_gap_pa"] != r["rms_gap_pa"]
            else f"{r['rms_gap_pa'] / r['noise_pa']:.2f}",
            r["message"] or "",
        ]
        for r in checks.iter_rows(named=True)
    ]
    section.tables.append(
        Table("", ["trip", "check", "RMS gap [kPa]", "noise [kPa]", "gap / noise", "what"],
              rows, key="sanity")
    )  # fmt: skip
    return section


def _discovery(data: DataRoot, period: HoistPeriod) -> list[Section]:
    from pipelines.reports.data import discovery_rows

    section = Section("Discovery: what the hoist's model misses", level=3)
    step = next((s for s in period.steps if s.name == "discovery"), None)
    rows = discovery_rows(
        data, site=period.site, hoist=period.hoist, start=period.start_utc, end=period.end_utc
    )
    if step is not None and (step.status != "skipped" or not rows.height):
        section.say(step.sentence(), "fail" if step.status == "failed" else "info")
    if not rows.height:
        if step is None:
            section.say("No discovery findings are landed for this period.")
        return [section]
    section.say(
        "Findings of the discovery runs over this period (each iteration adds the effect it "
        "names to the model and looks again):"
    )
    table_rows = []
    found: list[str] = []
    sections = [section]
    zone = period.zone
    for row in rows.iter_rows(named=True):
        obj = json.loads(row["report_json"])
        table_rows.append(
            [
                row["run_id"],
                str(row["iteration"]),
                row["effect"],
                "" if row["confidence"] is None else f"{row['confidence']:.2f}",
                _num(row["gap_before_pa"], 1e3),
                _num(row["gap_after_pa"], 1e3),
                _num(obj.get("noise_pa"), 1e3),
                f"{zone.text(row['period_start_utc'], '%Y-%m-%d %H:%M')} .. "
                f"{zone.text(row['period_end_utc'], '%Y-%m-%d %H:%M')}",
            ]
        )
        effect = row["effect"]
        if effect not in ("none", "ambiguous"):
            found.append(effect)
        regions = obj.get("where") or []
        if regions:
            added = effect not in ("none", "ambiguous")
            what = f"before and after adding {effect}" if added else f"no further effect ({effect})"
            section.figures.append(
                figures.discovery_regions_figure(
                    regions,
                    noise_pa=obj.get("noise_pa"),
                    effect=effect if added else None,
                    title=f"Measured minus simulated pressure per regime, {period.hoist}, "
                    f"iteration {row['iteration']}: {what}",
                )
            )
    section.say(
        "Effects found: " + (", ".join(found) if found else "none (the model explains the data)")
        + "."
    )  # fmt: skip
    section.tables.insert(
        0,
        Table(
            "",
            ["discovery run", "iteration", "effect", "confidence", "gap before [kPa]",
             "gap after [kPa]", "noise [kPa]", f"period ({zone.label(period.start_utc)})"],
            table_rows,
            key="discovery",
        ),
    )  # fmt: skip
    trace = _residual_trace(data, period)
    if trace is not None:
        added = ", ".join(trace.get("effects") or found) or "nothing"
        section.figures.append(
            figures.discovery_trace_figure(
                trace,
                title=f"Measured minus simulated pressure, sensor {trace.get('sensor')}, trip "
                f"{trace.get('trip_id')} ({trace.get('direction')}), before and after adding "
                f"{added}",
            )
        )
    return sections


def _residual_trace(data: DataRoot, period: HoistPeriod) -> dict[str, object] | None:
    """The worst trip's residual from the discovery JSON of this period, if written."""
    path = period.discovery_json
    if path is None:
        day = period.start_utc.date()
        try:
            path = data.under("reports", "discovery", f"{period.site}_{period.hoist}_{day}.json")
        except ValueError:
            return None
    if not path.is_file():
        return None
    try:
        trace = json.loads(path.read_text()).get("residual_trace")
    except (OSError, ValueError):
        return None
    return trace if isinstance(trace, dict) and isinstance(trace.get("before"), dict) else None
