"""Prefect 3 flows of ropeload: thin wiring around the plain functions the CLI calls.

Flows (name -> plain function it wraps)::

    ingest     pipelines.ingest.ingest_paths
    calibrate  pipelines.calibrate.calibrate_rig
    run        pipelines.run_period.run_period + pipelines.hoist_day.check_sanity
    discover   pipelines.discover.discover_period
    demo       pipelines.demo.run_demo
    query      pipelines.query.run_query
    backfill   pipelines.backfill.backfill: plan_backfill, run_partition (one task per
               hoist-day), record_failures; report + artifacts from pipelines.reports
    nightly    pipelines.nightly.nightly: ingest_new_files (one task per hoist),
               nightly_partitions, run_partition with the sanity check (one task per
               hoist-day), discover_day per hoist with a failed check; report + artifacts

The backfill and the night are written once (:func:`pipelines.backfill.backfill`,
:func:`pipelines.nightly.nightly`); their flows run that same sequence with
:class:`pipelines.tasks.PrefectExecutor`, which submits each step as its task
(:mod:`pipelines.tasks`: retries of transient failures only, no caching).

Concurrency: :func:`~pipelines.tasks.task_runner` gives ``ThreadPoolTaskRunner(max_workers=N)``
or, with a Dask address (``"local"`` for a ``LocalCluster`` of N single-threaded worker
processes), prefect-dask's ``DaskTaskRunner``; use it as
``backfill_flow.with_options(task_runner=...)`` (:func:`run_backfill_flow` and
:func:`run_nightly_flow` do that). Writers to one data root are serialised by the
warehouse lock, whatever runs them.

A backfill or night with failed partitions publishes its report, then raises
:class:`PartitionsFailed` (the flow run ends Failed; ``.report`` has the outcomes).
"""

from __future__ import annotations

from pipelines.prefect_env import apply_prefect_defaults

apply_prefect_defaults()

import datetime as dt  # noqa: E402  (Prefect's environment first)
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from prefect import Flow, flow, task  # noqa: E402

from pipelines.backfill import BackfillPlan, backfill  # noqa: E402
from pipelines.hoists import load_hoists  # noqa: E402
from pipelines.ingest import FilesRefused, IngestReport  # noqa: E402
from pipelines.nightly import NightlyReport, nightly  # noqa: E402
from pipelines.partitions import BackfillReport, Partition  # noqa: E402
from pipelines.progress import StderrProgress  # noqa: E402
from pipelines.run_period import RunResult  # noqa: E402
from pipelines.tasks import (  # noqa: E402
    TASK_OPTIONS,
    TRANSIENT_OPTIONS,
    PrefectExecutor,
    ingest_task,
    publish_task,
    run_period_task,
    run_report_task,
    sanity_task,
    task_runner,
)
from warehouse.store import DataRoot  # noqa: E402

__all__ = [
    "PartitionsFailed",
    "backfill_flow",
    "calibrate_flow",
    "demo_flow",
    "discover_flow",
    "ingest_flow",
    "nightly_flow",
    "query_flow",
    "run_backfill_flow",
    "run_flow",
    "run_nightly_flow",
]


class PartitionsFailed(RuntimeError):
    """Some partitions of a backfill or night failed, or files were refused; ``report``
    has every outcome."""

    def __init__(self, report: BackfillReport | NightlyReport) -> None:
        runs = report.runs if isinstance(report, NightlyReport) else report
        failed = runs.failed
        reasons = "; ".join(f"{o.key}: {o.message}" for o in failed[:3])
        more = f" (and {len(failed) - 3} more)" if len(failed) > 3 else ""
        line = f"{len(failed)} partition(s) failed: {reasons}{more}" if failed else ""
        errors = list(getattr(report, "hoist_errors", []))
        if errors:
            line = "; ".join(filter(None, [line, f"{len(errors)} hoist(s) not run: {errors[0]}"]))
        refused = list(getattr(report, "refused", []))
        if refused:  # the files ingest refused, one line each
            line = "; ".join(filter(None, [line, f"{len(refused)} file(s) refused"]))
            line += ":\n" + "\n".join(refused)
        super().__init__(line or "some files were refused")
        self.report = report


# --------------------------------------------------------------------------- flows


@flow(name="ingest", persist_result=False)
def ingest_flow(
    paths: list[str],
    data: str | None = None,
    hoists: list[str] | None = None,
    complete: bool = False,
) -> IngestReport:
    """``ropeload ingest``: files and folders into the lake (``hoists``: description files
    for the depth-in-shaft check; ``complete``: the CSVs are finished exports,
    :func:`~pipelines.ingest.ingest_paths`).

    A refused file fails the flow run: :class:`~pipelines.ingest.FilesRefused` is raised
    after every file was tried, its message one line per refused file, ``.report`` the
    whole report (the other files landed).
    """
    report = ingest_task(paths, DataRoot.resolve(data), hoists, complete)
    if not report.ok:
        raise FilesRefused(report)
    return report


@flow(name="run", persist_result=False)
def run_flow(
    hoist: str,
    data: str | None = None,
    start: dt.datetime | None = None,
    end: dt.datetime | None = None,
    payload_kg: float | None = None,
    sanity: bool = True,
    block_minutes: float = 60.0,
    band_member_step_s: float = 0.0,
    sanity_trips: int | None = None,
) -> RunResult:
    """``ropeload run``: compensate, reconcile, alarm and sanity-check a period of one hoist."""
    from pipelines.reports import Step, sanity_step

    root = DataRoot.resolve(data)
    result = run_period_task(hoist, root, start, end, payload_kg, block_minutes, band_member_step_s)
    reason = "not asked for (sanity=False)" if not sanity else "no trip in the period"
    steps = [sanity_step(None, reason=reason)]
    if sanity and result.trip_summary.height:
        # an optional step: its failure is landed as a finding, not a failed run
        found = sanity_task(
            hoist, root, result.run_id, result.period_start_utc, result.period_end_utc,
            sanity_trips,
        )  # fmt: skip
        steps = [Step("sanity check", found.step.status, found.step.message)]
    publish_task(run_report_task(root, result, hoist, steps), "run-report")
    return result


@flow(name="calibrate", persist_result=False)
def calibrate_flow(
    data: str | None = None,
    rig_id: str | None = None,
    recordings: list[str] | None = None,
    parameter_set: str | None = None,
) -> Any:
    """``ropeload calibrate``: rig recordings -> a friction parameter set."""
    from pipelines.calibrate import calibrate_rig

    calibrate = task(name="calibrate-rig", **TRANSIENT_OPTIONS)(calibrate_rig)
    return calibrate(
        data=DataRoot.resolve(data),
        rig_id=rig_id,
        recordings=recordings or (),
        parameter_set=parameter_set,
    )


@flow(name="discover", persist_result=False)
def discover_flow(
    hoist: str,
    json_path: str,
    data: str | None = None,
    start: dt.datetime | None = None,
    end: dt.datetime | None = None,
) -> Any:
    """``ropeload discover``: the discrepancy report of a period already ingested."""
    from pipelines.discover import discover_period

    discover = task(name="discover-period", **TASK_OPTIONS)(discover_period)
    return discover(
        hoist_path=hoist, data=DataRoot.resolve(data), start=start, end=end, json_path=json_path
    )


@flow(name="demo", persist_result=False)
def demo_flow(data: str | None = None, seed: int = 7, hours: float = 1.0) -> str:
    """``ropeload demo``: the whole job on built-in synthetic data; its printed summary."""
    from pipelines.demo import run_demo

    demo = task(name="demo", **TASK_OPTIONS)(run_demo)
    return demo(data=DataRoot.resolve(data), seed=seed, hours=hours)


@flow(name="query", persist_result=False)
def query_flow(sql: str, data: str | None = None) -> Any:
    """``ropeload query``: one read-only SELECT on the warehouse and lake (a polars frame;
    a statement that is not one is refused, :class:`pipelines.query.QueryRefused`)."""
    from pipelines.query import run_query

    query = task(name="query", **TASK_OPTIONS)(run_query)
    return query(sql, data=DataRoot.resolve(data))


def _progress(show: bool) -> StderrProgress | None:
    """The progress bar of a flow run (sized once the partitions are known), or None."""
    return StderrProgress(0) if show else None


@flow(name="backfill", persist_result=False)
def backfill_flow(
    hoists: list[str],
    start: dt.date,
    end: dt.date,
    data: str | None = None,
    incoming: str | None = None,
    force: bool = False,
    sanity: bool = False,
    show_progress: bool = False,
    band_member_step_s: float = 0.0,
) -> BackfillReport:
    """``ropeload backfill``: every hoist-day of ``start..end`` not done yet, resumable.

    :func:`pipelines.backfill.backfill` with one task per step and partition on the
    flow's task runner; a report artifact at the end.
    """
    root = DataRoot.resolve(data)
    progress = _progress(show_progress)

    def on_plan(plan: BackfillPlan) -> None:
        if progress is not None:
            progress.resize(plan.total)

    report = backfill(
        load_hoists(hoists, data=root, incoming=incoming),
        data=root,
        start=start,
        end=end,
        force=force,
        sanity=sanity,
        band_member_step_s=band_member_step_s,
        progress=progress,
        on_plan=on_plan,
        executor=PrefectExecutor(),
    )
    if not report.ok:
        raise PartitionsFailed(report)
    return report


@flow(name="nightly", persist_result=False)
def nightly_flow(
    hoists: str,
    data: str | None = None,
    incoming: str | None = None,
    lookback_days: int = 3,
    sanity: bool = True,
    show_progress: bool = False,
) -> NightlyReport:
    """The night: each hoist's new files since its watermark, the affected days, a report.

    :func:`pipelines.nightly.nightly` with one task per step, hoist and hoist-day on the
    flow's task runner. ``hoists`` is a folder of hoist descriptions
    (:mod:`pipelines.hoists` convention).
    """
    root = DataRoot.resolve(data)
    progress = _progress(show_progress)

    def on_plan(partitions: list[Partition]) -> None:
        if progress is not None:
            progress.resize(len(partitions))

    unreadable: list[str] = []  # a broken description holds up no other hoist
    report = nightly(
        load_hoists(hoists, data=root, incoming=incoming, unreadable=unreadable),
        unreadable=unreadable,
        data=root,
        lookback_days=lookback_days,
        sanity=sanity,
        progress=progress,
        on_plan=on_plan,
        executor=PrefectExecutor(),
    )
    if not report.ok:
        raise PartitionsFailed(report)
    return report


# ------------------------------------------------------------- callers with a runner


def _with_runner(chosen: Flow[..., Any], *, max_workers: int, dask: str | None) -> Flow[..., Any]:
    return chosen.with_options(task_runner=task_runner(max_workers=max_workers, dask=dask))


def run_backfill_flow(
    hoists: Sequence[str | Path],
    *,
    start: dt.date,
    end: dt.date,
    data: str | Path | None = None,
    incoming: str | Path | None = None,
    max_workers: int = 2,
    dask: str | None = None,
    force: bool = False,
    sanity: bool = False,
    show_progress: bool = False,
    band_member_step_s: float = 0.0,
) -> BackfillReport:
    """:func:`backfill_flow` on ``max_workers`` threads or a Dask cluster (``dask``)."""
    return _with_runner(backfill_flow, max_workers=max_workers, dask=dask)(
        hoists=[str(h) for h in hoists],
        start=start,
        end=end,
        data=None if data is None else str(data),
        incoming=None if incoming is None else str(incoming),
        force=force,
        sanity=sanity,
        show_progress=show_progress,
        band_member_step_s=band_member_step_s,
    )


def run_nightly_flow(
    hoists: str | Path,
    *,
    data: str | Path | None = None,
    incoming: str | Path | None = None,
    lookback_days: int = 3,
    max_workers: int = 2,
    dask: str | None = None,
    sanity: bool = True,
    show_progress: bool = False,
) -> NightlyReport:
    """:func:`nightly_flow` on ``max_workers`` threads or a Dask cluster (``dask``)."""
    return _with_runner(nightly_flow, max_workers=max_workers, dask=dask)(
        hoists=str(hoists),
        data=None if data is None else str(data),
        incoming=None if incoming is None else str(incoming),
        lookback_days=lookback_days,
        sanity=sanity,
        show_progress=show_progress,
    )
