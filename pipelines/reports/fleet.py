"""The report of a night or a backfill (:func:`fleet_report`).

What happened to every hoist-day (and each hoist's ingest, for a night), the failed
ones with their reasons, the sanity checks and discoveries (:func:`outcome_table`, the
summary); the hoist-days it ran in detail (a night: all of them, up to
``max_detailed``; a backfill: the few most eventful, with a day-by-day trend per hoist
over the whole range). Written by :func:`pipelines.reports.build.write_fleet_report`.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import polars as pl

from pipelines.provenance import code_version
from pipelines.reports import check_figures
from pipelines.reports.data import MIN_VISIT_SAMPLES, RunTables, run_tables
from pipelines.reports.document import Report, Section, Table, stamped_stem
from pipelines.reports.period import HoistPeriod, Step
from pipelines.reports.sections import hoist_sections
from transforms.alarms import rule_thresholds
from warehouse.store import DataRoot

if TYPE_CHECKING:
    from pipelines.hoists import HoistSource
    from pipelines.partitions import PartitionOutcome

__all__ = ["Kind", "fleet_report", "outcome_table"]


Kind = Literal["nightly", "backfill"]


def fleet_report(
    data: DataRoot,
    *,
    kind: Kind,
    outcomes: Sequence[PartitionOutcome],
    sources: Sequence[HoistSource],
    sanity: bool,
    title: str | None = None,
    hoist_rows: Sequence[Mapping[str, object]] = (),
    discoveries: Mapping[str, str] | None = None,
    range_text: str = "",
    max_detailed: int | None = None,
    stamp: dt.datetime | None = None,
) -> Report:
    """The report of a night or a backfill (module docstring).

    ``hoist_rows``: a night's per-hoist ingest (``HoistNight.row()``); ``discoveries``:
    ``"site/hoist/day" -> JSON path`` or ``"discovery failed: ..."``.
    """
    stamp = stamp or dt.datetime.now(dt.UTC)
    discoveries = discoveries or {}
    limit = max_detailed if max_detailed is not None else (14 if kind == "nightly" else 3)
    descriptions = {(s.site, s.hoist): s for s in sources}
    ran = sorted((o for o in outcomes if o.status == "succeeded" and o.run_id), key=lambda o: o.key)
    tables = run_tables(data, [o.run_id for o in ran if o.run_id])
    name = stamped_stem(kind, stamp)
    if range_text:
        name += "_" + range_text.replace(" .. ", "_")
    report = Report(
        title=title or f"ropeload {kind} {range_text or f'{stamp:%Y-%m-%d %H:%M} UTC'}",
        file_name=f"{name}.html",
        about=[
            f"{len(sources)} hoist(s): " + ", ".join(f"{s.key} ({s.timezone})" for s in sources),
            "hoist-days are UTC days; times inside each hoist-day are the hoist's local time",
            f"code {code_version()}, data root {data.path}",
        ],
        created_utc=stamp,
    )
    report.sections.append(_summary(outcomes, ran, sanity, hoist_rows, discoveries))
    if kind == "backfill" and ran:
        report.sections += _trends(ran, tables, descriptions)
    report.sections += _in_detail(
        data, ran, tables, descriptions, kind=kind, sanity=sanity, discoveries=discoveries,
        limit=limit,
    )  # fmt: skip
    return report


def _summary(
    outcomes: Sequence[PartitionOutcome],
    ran: Sequence[PartitionOutcome],
    sanity: bool,
    hoist_rows: Sequence[Mapping[str, object]],
    discoveries: Mapping[str, str],
) -> Section:
    """What happened to every hoist-day, each hoist's ingest, checks and discoveries."""
    statuses = ("succeeded", "skipped", "empty", "failed")
    counts = {s: sum(o.status == s for o in outcomes) for s in statuses}
    summary = Section("Summary", anchor="summary")
    summary.say(
        f"{len(outcomes)} hoist-days: {counts['succeeded']} run, {counts['skipped']} already "
        f"done, {counts['empty']} without data, {counts['failed']} failed; "
        f"{sum(o.samples for o in ran)} samples."
    )
    for outcome in sorted((o for o in outcomes if o.status == "failed"), key=lambda o: o.key):
        summary.say(f"{outcome.key} FAILED: {outcome.message}", "fail")
    for row in hoist_rows:
        if row.get("error"):
            summary.say(f"{row['hoist']}: ingest FAILED: {row['error']}", "fail")
        elif row.get("refused"):
            summary.say(f"{row['hoist']}: {row['refused']} file(s) refused by ingest", "warn")
    checks = sum(o.checks for o in outcomes)
    failed_checks = sum(o.checks_failed for o in outcomes)
    if not sanity:
        summary.say("Simulation sanity check: skipped (not asked for).")
    else:
        summary.say(
            f"Simulation sanity check: {checks - failed_checks} of {checks} trips passed.",
            "warn" if failed_checks else "ok",
        )
    for key, where in sorted(discoveries.items()):
        level = "fail" if where.startswith("discovery failed") else "info"
        summary.say(f"Discovery {key}: {where}", level)
    if hoist_rows:
        columns = ["hoist", "new_files", "refused", "rows_landed", "rows_quarantined",
                   "watermark_before", "watermark_after", "days", "error"]  # fmt: skip
        summary.tables.append(
            Table(
                "Ingest per hoist",
                ["hoist", "new files", "refused", "rows landed", "rows quarantined",
                 "watermark before (UTC)", "watermark after (UTC)", "UTC days touched", "error"],
                [[_text(r.get(c)) for c in columns] for r in hoist_rows],
                key="hoists",
            )
        )  # fmt: skip
    summary.tables.append(outcome_table(outcomes))
    return summary


def _in_detail(
    data: DataRoot,
    ran: Sequence[PartitionOutcome],
    tables: RunTables,
    descriptions: Mapping[tuple[str, str], HoistSource],
    *,
    kind: Kind,
    sanity: bool,
    discoveries: Mapping[str, str],
    limit: int,
) -> list[Section]:
    """The ``limit`` most eventful hoist-days run, each with every section of
    :func:`pipelines.reports.sections.hoist_sections`."""
    out: list[Section] = []
    alarms = tables.alarms.group_by("run_id").len() if tables.alarms.width else None
    per_run = dict(alarms.iter_rows()) if alarms is not None else {}
    chosen = sorted(ran, key=lambda o: _eventfulness(o, per_run), reverse=True)[:limit]
    if len(chosen) < len(ran):
        out.append(
            Section("Hoist-days in detail", anchor="detail").say(
                f"{len(chosen)} of the {len(ran)} hoist-days run are shown in detail: those "
                "with the most failed sanity checks, then the most alarms, then the latest. "
                "Any other day: ropeload run --hoist FILE --from DAY --to NEXT_DAY writes its "
                "own report."
            )
        )
    landed = _landed_steps(data, [o.run_id for o in chosen if o.run_id])
    for k, outcome in enumerate(sorted(chosen, key=lambda o: o.key)):
        source = descriptions.get((outcome.site, outcome.hoist))
        if source is None or outcome.run_id is None:
            continue
        start = dt.datetime.combine(outcome.day, dt.time(0), tzinfo=dt.UTC)
        found = discoveries.get(outcome.key)
        period = HoistPeriod(
            run_id=outcome.run_id,
            description=source.description(),
            start_utc=start,
            end_utc=start + dt.timedelta(days=1),
            label=f"UTC day {outcome.day}",
            steps=_day_steps(
                outcome,
                kind=kind,
                sanity=sanity,
                discoveries=discoveries,
                landed={n: s for n, s in landed.get(outcome.run_id, {}).items() if n != "report"},
            ),
            discovery_json=Path(found) if found and found.endswith(".json") else None,
            anchor=f"day{k}",
        )
        out += hoist_sections(data, period, tables.of(outcome.run_id))
    return out


def _trends(
    ran: Sequence[PartitionOutcome],
    tables: RunTables,
    sources: Mapping[tuple[str, str], HoistSource],
) -> list[Section]:
    """Day by day per hoist over the backfill's range."""
    out = []
    for (site, hoist), source in sorted(sources.items()):
        days = {o.run_id: o.day for o in ran if (o.site, o.hoist) == (site, hoist) and o.run_id}
        if not days:
            continue
        limits = rule_thresholds(source.description())
        daily = _daily(tables, days)
        section = Section(f"{site}/{hoist}: day by day", anchor=f"trend-{site}-{hoist}")
        worst = daily.sort("worst_imbalance_pct", descending=True, nulls_last=True).row(
            0, named=True
        )
        section.say(
            f"{daily.height} day(s) run; {int(daily['alarms'].sum())} alarm(s); worst load error "
            f"after compensation {daily['worst_error_after_pct'].max() or 0:.2f} % "
            f"(before {daily['worst_error_before_pct'].max() or 0:.2f} %); worst rope "
            f"imbalance {worst['worst_imbalance_pct'] or 0:.2f} % on {worst['day']}."
        )
        section.figures.append(
            check_figures.trend_figure(
                daily,
                imbalance_fraction=limits.imbalance_fraction,
                tolerance_fraction=limits.reconciliation_tolerance_fraction,
                title=f"{site}/{hoist}: load error, rope imbalance and alarms, day by day",
            )
        )
        out.append(section)
    return out


def _daily(tables: RunTables, days: Mapping[str, dt.date]) -> pl.DataFrame:
    """Per run (hoist-day): worst load error before / after, worst imbalance, alarms."""
    ids = pl.DataFrame(
        {"run_id": list(days), "day": list(days.values())},
        schema={"run_id": pl.String, "day": pl.Date},
    )
    visits = tables.position_summary
    if visits.width:
        errors = (
            visits.filter(pl.col("samples") >= MIN_VISIT_SAMPLES)
            .group_by("run_id")
            .agg(
                (pl.col("error_before_fraction").abs().max() * 100).alias("worst_error_before_pct"),
                (pl.col("error_after_fraction").abs().max() * 100).alias("worst_error_after_pct"),
            )
        )
        ids = ids.join(errors, on="run_id", how="left")
    trips = tables.trip_summary
    if trips.width:
        ids = ids.join(
            trips.group_by("run_id").agg(
                (pl.col("max_imbalance_after_fraction").max() * 100).alias("worst_imbalance_pct")
            ),
            on="run_id",
            how="left",
        )
    alarms = tables.alarms
    counts = alarms.group_by("run_id").len("alarms") if alarms.width else None
    if counts is not None:
        ids = ids.join(counts, on="run_id", how="left")
    for name in ("worst_error_before_pct", "worst_error_after_pct", "worst_imbalance_pct"):
        if name not in ids.columns:
            ids = ids.with_columns(pl.lit(None, dtype=pl.Float64).alias(name))
    if "alarms" not in ids.columns:
        ids = ids.with_columns(pl.lit(0, dtype=pl.UInt32).alias("alarms"))
    return ids.with_columns(pl.col("alarms").fill_null(0)).sort("day")


def _eventfulness(outcome: PartitionOutcome, alarms: Mapping[str, int]) -> tuple[int, int, str]:
    return (outcome.checks_failed, alarms.get(outcome.run_id or "", 0), outcome.day.isoformat())


def outcome_table(outcomes: Sequence[PartitionOutcome]) -> Table:
    rank = {"failed": 0, "succeeded": 1, "skipped": 2, "empty": 3}
    ordered = sorted(outcomes, key=lambda o: (rank[o.status], o.key))
    rows = [
        [
            o.key,
            o.status.upper() if o.status == "failed" else o.status,
            str(o.samples),
            str(o.files_ingested),
            f"{o.checks - o.checks_failed}/{o.checks}" if o.checks else "",
            f"{o.work_s:.1f}",
            o.message,
        ]
        for o in ordered
    ]
    return Table(
        "",
        ["hoist-day (UTC day)", "status", "samples", "files ingested", "sanity passed",
         "seconds", "what happened"],
        rows,
        key="partitions",
    )  # fmt: skip


def _text(value: object) -> str:
    return "" if value is None else str(value)


def _landed_steps(data: DataRoot, run_ids: Sequence[str]) -> dict[str, dict[str, Step]]:
    """``run_steps`` (the optional steps' landed outcomes) per run id and step name."""
    try:
        from pipelines.steps import steps_of
    except ImportError:  # a tree without landed step outcomes
        return {}
    out: dict[str, dict[str, Step]] = {}
    for row in steps_of(data, run_ids).iter_rows(named=True):
        step = Step.from_outcome(row)
        out.setdefault(row["run_id"], {})[step.name] = step
    return out


def _day_steps(
    outcome: PartitionOutcome,
    *,
    kind: Kind,
    sanity: bool,
    discoveries: Mapping[str, str],
    landed: Mapping[str, Step] | None = None,
) -> list[Step]:
    """The steps of one hoist-day in words: from ``run_steps`` where landed, else from
    what the partition's outcome says."""
    steps = _derived_day_steps(outcome, kind=kind, sanity=sanity, discoveries=discoveries)
    landed = landed or {}
    merged = [landed.get(step.name, step) for step in steps]
    return merged + [s for name, s in landed.items() if name not in {m.name for m in merged}]


def _derived_day_steps(
    outcome: PartitionOutcome,
    *,
    kind: Kind,
    sanity: bool,
    discoveries: Mapping[str, str],
) -> list[Step]:
    compute = {
        "succeeded": Step("compensation, reconciliation and alarms", "done", outcome.message),
        "skipped": Step("run", "skipped", outcome.message),
        "empty": Step("run", "skipped", outcome.message or "no samples"),
        "failed": Step("run", "failed", outcome.message),
    }[outcome.status]
    steps = [compute]
    if outcome.status != "succeeded":
        return steps
    if not sanity:
        flag = "--no-sanity given" if kind == "nightly" else "not asked for (backfill --sanity)"
        steps.append(Step("sanity check", "skipped", flag))
    elif outcome.checks:
        passed = outcome.checks - outcome.checks_failed
        steps.append(Step("sanity check", "done", f"{passed} of {outcome.checks} trips passed"))
    else:
        steps.append(Step("sanity check", "done", "no trip to check"))
    found = discoveries.get(outcome.key)
    if found is not None and found.startswith("discovery failed"):
        steps.append(Step("discovery", "failed", found.removeprefix("discovery failed: ")))
    elif found is not None:
        steps.append(Step("discovery", "done", f"report {found}"))
    elif kind == "backfill":
        steps.append(Step("discovery", "skipped", "a backfill does not run it (ropeload discover)"))
    elif outcome.checks_failed:
        steps.append(
            Step("discovery", "skipped", "it runs on the hoist's latest day with a failed check")
        )
    else:
        steps.append(Step("discovery", "skipped", "not needed: no trip failed the sanity check"))
    return steps
