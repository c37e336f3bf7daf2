"""Reports of the commands that compute: one run (``run``, ``demo``), a night, a backfill.

* :func:`run_report` -- one run of one hoist: the steps and every section of
  :func:`pipelines.reports.sections.hoist_sections`, from the run's frame in memory.
* :func:`fleet_report` -- a night or a backfill: what happened to every hoist-day (and
  each hoist's ingest, for a night), the failed ones with their reasons, the sanity
  checks and discoveries; the hoist-days it ran in detail (a night: all of them, up to
  ``max_detailed``; a backfill: the few most eventful, with a day-by-day trend per
  hoist over the whole range).
* :func:`write_report` -- the HTML under ``<data>/reports/`` (the name is checked by
  :meth:`warehouse.store.DataRoot.under`).

File names: ``<run id>_<site>_<hoist>.html`` for a run (the run id starts with the
command: ``run-...``, ``demo-...``), ``nightly-<UTC stamp>.html``,
``backfill-<UTC stamp>_<from>_<to>.html``.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import polars as pl

from pipelines.provenance import code_version
from pipelines.reports import figures
from pipelines.reports.data import MIN_VISIT_SAMPLES, RunTables, Zone, run_tables
from pipelines.reports.document import Report, Section, Table
from pipelines.reports.sections import HoistPeriod, Step, hoist_sections
from schemas.hoist import HoistDescription
from transforms.alarms import rule_thresholds
from warehouse.store import DataRoot

if TYPE_CHECKING:
    from pipelines.hoists import HoistSource
    from pipelines.partitions import PartitionOutcome
    from pipelines.run_period import RunResult

__all__ = [
    "fleet_report",
    "run_report",
    "run_report_path",
    "sanity_step",
    "write_fleet_report",
    "write_report",
    "write_run_report",
]

Kind = Literal["nightly", "backfill"]


def write_report(report: Report, data: DataRoot) -> Path:
    """Write ``report`` as ``<data>/reports/<report.file_name>``; returns the path."""
    target = data.under("reports", report.file_name)
    return report.write(target.parent)


def sanity_step(checks: object, *, error: BaseException | None = None, reason: str = "") -> Step:
    """The sanity check as a :class:`Step`: its result, why it was skipped, or its error.

    ``checks``: what :func:`pipelines.hoist_day.check_sanity` returned (its outcome with
    the step's words, or the ``sanity_checks`` rows), None when it did not run.
    """
    if error is not None:
        message = " ".join(str(error).split()) or type(error).__name__
        return Step("sanity check", "failed", f"{type(error).__name__}: {message}")
    if checks is None:
        return Step("sanity check", "skipped", reason)
    outcome = getattr(checks, "step", None)
    if outcome is not None:
        return Step.from_outcome(outcome)
    frame = checks if isinstance(checks, pl.DataFrame) else pl.DataFrame()
    if not frame.height:
        return Step("sanity check", "done", "no trip to check")
    passed = int(frame["passed"].fill_null(False).sum())
    failed = int((~frame["passed"].fill_null(True)).sum())
    return Step(
        "sanity check",
        "done",
        f"{passed} of {passed + failed} trips passed" + (f", {failed} failed" if failed else ""),
    )


def run_report(
    data: DataRoot,
    result: RunResult,
    *,
    hoist: HoistDescription,
    steps: Sequence[Step] = (),
    command: str = "run",
    discovery_json: Path | None = None,
) -> Report:
    """The report of one run (``ropeload run``, ``ropeload demo``)."""
    zone = Zone(hoist.hoist.timezone)
    tables = run_tables(data, [result.run_id])
    start, end = result.period_start_utc, result.period_end_utc
    label = _period_label(zone, start, end)
    compute = Step(
        "compensation, reconciliation and alarms",
        "done",
        f"{result.samples} samples, {result.trip_summary.height} trip(s), "
        f"{result.position_summary.height} position visit(s), {result.alarms.height} alarm(s)",
    )
    if not any(step.name == "discovery" for step in steps):
        steps = [*steps, _run_discovery_step(steps, hoist)]
    period = HoistPeriod(
        run_id=result.run_id,
        description=hoist,
        start_utc=start,
        end_utc=end,
        label=label,
        steps=[compute, *steps],
        frame=result.rope_tensions,
        discovery_json=discovery_json,
        anchor="hoist",
    )
    report = Report(
        title=f"ropeload {command}: {result.site}/{result.hoist}, {label}",
        file_name=f"{result.run_id}_{result.site}_{result.hoist}.html",
        about=[
            f"hoist {result.site}/{result.hoist}; times in its local time, "
            f"{zone.label(start, end)}",
            f"run {result.run_id}, code {code_version()}, data root {data.path}",
        ],
    )
    report.sections = hoist_sections(data, period, tables)
    return report


def _run_discovery_step(steps: Sequence[Step], hoist: HoistDescription) -> Step:
    """Why a single run did not run discovery, and how to run it."""
    sanity = next((s for s in steps if s.name == "sanity check"), None)
    failed = sanity is not None and sanity.status == "done" and "failed" in sanity.detail
    how = (
        f"ropeload discover --hoist <{hoist.hoist.name}.toml> --from T --to T --json FILE "
        "names the effect the model misses"
    )
    if failed:
        return Step("discovery", "skipped", f"a run does not start it; {how}")
    return Step(
        "discovery",
        "skipped",
        "not needed: no trip failed the sanity check"
        if sanity is not None and sanity.status == "done"
        else f"a run does not start it (the nightly does, after a failed sanity check); {how}",
    )


def _period_label(zone: Zone, start: dt.datetime, end: dt.datetime) -> str:
    a, b = zone.local(start), zone.local(end - dt.timedelta(microseconds=1))
    if a.date() == b.date():
        return f"{a:%Y-%m-%d %H:%M} .. {zone.local(end):%H:%M} local"
    return f"{a:%Y-%m-%d %H:%M} .. {zone.local(end):%Y-%m-%d %H:%M} local"


# ------------------------------------------------------------------ night / backfill


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


def _text(value: object) -> str:
    return "" if value is None else str(value)


def _outcome_table(outcomes: Sequence[PartitionOutcome]) -> Table:
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


def _eventfulness(outcome: PartitionOutcome, alarms: Mapping[str, int]) -> tuple[int, int, str]:
    return (outcome.checks_failed, alarms.get(outcome.run_id or "", 0), outcome.day.isoformat())


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
    statuses = ("succeeded", "skipped", "empty", "failed")
    counts = {s: sum(o.status == s for o in outcomes) for s in statuses}
    name = f"{kind}-{stamp:%Y%m%dT%H%M%SZ}"
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
    summary.tables.append(_outcome_table(outcomes))
    report.sections.append(summary)
    if kind == "backfill" and ran:
        report.sections += _trends(ran, tables, descriptions)
    alarms = tables.alarms.group_by("run_id").len() if tables.alarms.width else None
    per_run = dict(alarms.iter_rows()) if alarms is not None else {}
    chosen = sorted(ran, key=lambda o: _eventfulness(o, per_run), reverse=True)[:limit]
    if len(chosen) < len(ran):
        report.sections.append(
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
        report.sections += hoist_sections(data, period, tables.of(outcome.run_id))
    return report


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
            figures.trend_figure(
                daily,
                imbalance_fraction=limits.imbalance_fraction,
                tolerance_fraction=limits.reconciliation_tolerance_fraction,
                title=f"{site}/{hoist}: load error, rope imbalance and alarms, day by day",
            )
        )
        out.append(section)
    return out


def write_fleet_report(
    data: DataRoot,
    *,
    kind: Kind,
    outcomes: Sequence[PartitionOutcome],
    sources: Sequence[HoistSource],
    sanity: bool,
    range_text: str = "",
    hoist_rows: Sequence[Mapping[str, object]] = (),
    discoveries: Mapping[str, str] | None = None,
    max_detailed: int | None = None,
) -> Report:
    """:func:`fleet_report`, written under ``<data>/reports/`` (``report.path``).

    The report is an optional step of every hoist-day it covers: its outcome is landed
    in ``run_steps`` (``report: done`` with the path). Should building it fail, a short
    report saying why (and what happened to every hoist-day) is written instead, and
    ``report: failed`` is landed: the days stay done.
    """
    ran = [o for o in outcomes if o.status == "succeeded" and o.run_id]
    try:
        report = fleet_report(
            data,
            kind=kind,
            outcomes=outcomes,
            sources=sources,
            sanity=sanity,
            range_text=range_text,
            hoist_rows=hoist_rows,
            discoveries=discoveries,
            max_detailed=max_detailed,
        )
        error = None
    except Exception as exc:  # an optional step: said in a fallback report, not raised
        error = exc
        report = _fallback(f"ropeload {kind} {range_text}".strip(), kind, exc, outcomes)
    write_report(report, data)
    _record(data, [(o.run_id, o.site, o.hoist) for o in ran if o.run_id], report, error)
    return report


def _fallback(
    title: str, name: str, exc: BaseException, outcomes: Sequence[PartitionOutcome]
) -> Report:
    """A report that only says why the report could not be made, and the outcomes."""
    stamp = dt.datetime.now(dt.UTC)
    report = Report(title=title, file_name=f"{name}-{stamp:%Y%m%dT%H%M%SZ}.html")
    section = Section("The report could not be drawn", anchor="failed")
    reason = " ".join(str(exc).split()) or type(exc).__name__
    section.say(f"Report FAILED: {type(exc).__name__}: {reason}", "fail")
    if outcomes:
        section.tables.append(_outcome_table(outcomes))
    report.sections.append(section)
    return report


def _record(
    data: DataRoot,
    runs: Sequence[tuple[str, str, str]],
    report: Report,
    error: BaseException | None,
) -> None:
    """Land the report's outcome (``run_steps``, step ``report``) for each run it covers."""
    try:
        from pipelines.steps import StepOutcome, one_line, record_steps
    except ImportError:  # a tree without landed step outcomes
        return
    outcome = (
        StepOutcome("report", "done", str(report.path))
        if error is None
        else StepOutcome("report", "failed", f"{one_line(error)} (fallback {report.path})")
    )
    for run_id, site, hoist in runs:
        record_steps(data, run_id=run_id, site=site, hoist=hoist, outcomes=[outcome])


def run_report_path(data: DataRoot, result: RunResult) -> Path:
    """Where :func:`write_run_report` writes the report of ``result``."""
    return data.under("reports", f"{result.run_id}_{result.site}_{result.hoist}.html")


def write_run_report(
    data: DataRoot,
    result: RunResult,
    *,
    hoist: HoistDescription,
    steps: Sequence[Step] = (),
    command: str = "run",
) -> Report:
    """:func:`run_report`, written under ``<data>/reports/`` (``report.path``); its
    outcome landed as the run's ``report`` step (a failure: a fallback report saying why).
    """
    try:
        report = run_report(data, result, hoist=hoist, steps=steps, command=command)
        error = None
    except Exception as exc:  # an optional step: said in a fallback report, not raised
        error = exc
        report = _fallback(f"ropeload {command}: {result.site}/{result.hoist}", command, exc, ())
        report.file_name = run_report_path(data, result).name
    write_report(report, data)
    _record(data, [(result.run_id, result.site, result.hoist)], report, error)
    return report
