"""Reports of the commands that compute: one run (``run``, ``demo``), a night, a backfill.

* :func:`run_report` -- one run of one hoist: the steps and every section of
  :func:`pipelines.reports.sections.hoist_sections`, from the run's frame in memory.
* :func:`write_fleet_report` -- a night or a backfill
  (:func:`pipelines.reports.fleet.fleet_report`): what happened to every hoist-day, the
  failed ones with their reasons, the sanity checks and discoveries; the hoist-days it
  ran in detail.
* :func:`write_report` -- the HTML under ``<data>/reports/`` (the name is checked by
  :meth:`warehouse.store.DataRoot.under`).

File names: ``<run id>_<site>_<hoist>.html`` for a run (the run id starts with the
command: ``run-...``, ``demo-...``), ``nightly-<UTC stamp>-<6 hex>.html``,
``backfill-<UTC stamp>-<6 hex>_<from>_<to>.html`` (the hex digits keep two started in
the same second apart).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import polars as pl

from pipelines.provenance import code_version
from pipelines.reports.data import Zone, run_tables
from pipelines.reports.document import Report, Section, stamped_stem
from pipelines.reports.fleet import Kind, fleet_report, outcome_table
from pipelines.reports.period import HoistPeriod, Step
from pipelines.reports.sections import hoist_sections
from schemas.hoist import HoistDescription
from warehouse.store import DataRoot, open_writer

if TYPE_CHECKING:
    from pipelines.hoists import HoistSource
    from pipelines.partitions import PartitionOutcome
    from pipelines.run_period import RunResult

__all__ = [
    "run_report",
    "run_report_path",
    "sanity_step",
    "write_fleet_report",
    "write_report",
    "write_run_report",
]


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
    shown = zone.for_period(start, end)  # the sections' times: UTC if the clocks go back
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
            f"hoist {result.site}/{result.hoist}; times in "
            + ("" if shown.instead_of else "its local time, ")
            + shown.label(start, end),
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
    """:func:`~pipelines.reports.fleet.fleet_report`, written under ``<data>/reports/``
    (``report.path``).

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
    report = Report(title=title, file_name=f"{stamped_stem(name, stamp)}.html")
    section = Section("The report could not be drawn", anchor="failed")
    reason = " ".join(str(exc).split()) or type(exc).__name__
    section.say(f"Report FAILED: {type(exc).__name__}: {reason}", "fail")
    if outcomes:
        section.tables.append(outcome_table(outcomes))
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
        from pipelines.steps import StepOutcome, land_steps, one_line
    except ImportError:  # a tree without landed step outcomes
        return
    outcome = (
        StepOutcome("report", "done", str(report.path))
        if error is None
        else StepOutcome(
            "report",
            "failed",
            one_line(error)
            + (f" (fallback {report.path})" if report.path is not None else " (not written)"),
        )
    )
    if not runs:
        return
    with open_writer(data) as con:  # one transaction for every run the report covers
        for run_id, site, hoist in runs:
            land_steps(con, run_id=run_id, site=site, hoist=hoist, outcomes=[outcome])


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
    outcome landed as the run's ``report`` step (a failure: a fallback report saying why;
    where not even that can be written, e.g. ``reports`` is a file, the step is landed
    failed and ``report.path`` stays None: the run stands).
    """
    try:
        report = run_report(data, result, hoist=hoist, steps=steps, command=command)
        error = None
    except Exception as exc:  # an optional step: said in a fallback report, not raised
        error = exc
        report = _fallback(f"ropeload {command}: {result.site}/{result.hoist}", command, exc, ())
        report.file_name = run_report_path(data, result).name
    try:
        write_report(report, data)
    except (OSError, ValueError) as exc:  # the reports folder unusable: a finding
        error = exc
    _record(data, [(result.run_id, result.site, result.hoist)], report, error)
    return report
