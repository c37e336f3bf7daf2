"""Prefect 3 flows of ropeload: thin wiring around the plain functions the CLI calls.

Flows (name -> plain function it wraps)::

    ingest     pipelines.ingest.ingest_paths
    calibrate  pipelines.calibrate.calibrate_rig
    run        pipelines.run_period.run_period + pipelines.backfill.check_sanity
    discover   pipelines.discover.discover_period
    backfill   pipelines.backfill: plan_backfill, run_partition (one task per hoist-day),
               record_failures; report + artifacts from pipelines.reports
    nightly    pipelines.nightly: ingest_new_files (one task per hoist), nightly_partitions,
               run_partition with the sanity check (one task per hoist-day), discover_day
               per hoist with a failed check; report + artifacts

Tasks wrap plain functions at coarse units (a hoist's new files, a hoist-day), never
rows. Retries only for transient failures (:func:`pipelines.backfill.is_transient`:
I/O errors, DuckDB lock conflicts), never for bad data. Task results are not cached or
persisted (they are in-process values; the warehouse is the record).

Concurrency: :func:`task_runner` gives ``ThreadPoolTaskRunner(max_workers=N)`` or, with a
Dask address (``"local"`` for a ``LocalCluster`` of N single-threaded worker processes),
prefect-dask's ``DaskTaskRunner``; use it as ``backfill_flow.with_options(task_runner=...)``
(:func:`run_backfill_flow` and :func:`run_nightly_flow` do that). Writers to one data
root are serialised by the warehouse lock, whatever runs them.

A backfill or night with failed partitions publishes its report, then raises
:class:`PartitionsFailed` (the flow run ends Failed; ``.report`` has the outcomes).
"""

from __future__ import annotations

from pipelines.prefect_env import apply_prefect_defaults

apply_prefect_defaults()

import datetime as dt  # noqa: E402  (Prefect's environment first)
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from prefect import Flow, Task, flow, task, unmapped  # noqa: E402
from prefect.artifacts import create_markdown_artifact, create_table_artifact  # noqa: E402
from prefect.cache_policies import NO_CACHE  # noqa: E402
from prefect.client.schemas.objects import State, TaskRun  # noqa: E402
from prefect.futures import PrefectFuture, as_completed  # noqa: E402
from prefect.task_runners import ThreadPoolTaskRunner  # noqa: E402

from pipelines.backfill import (  # noqa: E402
    BackfillPlan,
    BackfillReport,
    HoistSource,
    Partition,
    PartitionOutcome,
    StderrProgress,
    check_sanity,
    failed_outcome,
    incoming_notes,
    is_transient,
    known_files,
    load_hoists,
    plan_backfill,
    record_failures,
    run_partition,
)
from pipelines.ingest import FilesRefused, IngestReport, ingest_paths  # noqa: E402
from pipelines.ingest.field_checks import hoist_lookup_from_files  # noqa: E402
from pipelines.log import enable_run_logs  # noqa: E402
from pipelines.nightly import (  # noqa: E402
    HoistNight,
    NightlyReport,
    days_to_discover,
    discover_day,
    discovery_outcome,
    discovery_words,
    failed_night,
    ingest_new_files,
    land_discoveries,
    nightly_partitions,
)
from pipelines.reports import Report  # noqa: E402
from pipelines.run_period import RunResult, run_period  # noqa: E402
from pipelines.steps import StepOutcome, report_failed  # noqa: E402
from warehouse.store import DataRoot  # noqa: E402

enable_run_logs()  # the module loggers' INFO lines go to the flow and task run logs

__all__ = [
    "PARTITION_RETRIES",
    "PartitionsFailed",
    "backfill_flow",
    "calibrate_flow",
    "discover_flow",
    "ingest_flow",
    "nightly_flow",
    "run_backfill_flow",
    "run_flow",
    "run_nightly_flow",
    "task_runner",
]

#: Retries of a partition task after a transient failure, and the waits between them [s].
PARTITION_RETRIES = 2
_RETRY_DELAYS_S = [2.0, 10.0]


class PartitionsFailed(RuntimeError):
    """Some partitions of a backfill or night failed; ``report`` has every outcome."""

    def __init__(self, report: BackfillReport | NightlyReport) -> None:
        runs = report.runs if isinstance(report, NightlyReport) else report
        failed = runs.failed
        reasons = "; ".join(f"{o.key}: {o.message}" for o in failed[:3])
        more = f" (and {len(failed) - 3} more)" if len(failed) > 3 else ""
        super().__init__(f"{len(failed)} partition(s) failed: {reasons}{more}")
        self.report = report


def _retry_transient(task: Task[..., Any], task_run: TaskRun, state: State[Any]) -> bool:
    """Prefect ``retry_condition_fn``: retry only what :func:`is_transient` accepts."""
    try:
        state.result()
    except Exception as exc:
        return is_transient(exc)
    return False


_TASK: dict[str, Any] = {"cache_policy": NO_CACHE, "persist_result": False}
_TRANSIENT: dict[str, Any] = {
    **_TASK,
    "retries": PARTITION_RETRIES,
    "retry_delay_seconds": _RETRY_DELAYS_S,
    "retry_condition_fn": _retry_transient,
}


def task_runner(*, max_workers: int = 2, dask: str | None = None) -> Any:
    """``ThreadPoolTaskRunner(max_workers)``, or a ``DaskTaskRunner`` for ``dask``.

    ``dask="local"`` starts a ``LocalCluster`` of ``max_workers`` single-threaded worker
    processes (no dashboard) for the flow run; any other value is a scheduler address
    (``tcp://host:8786``) whose cluster size bounds the concurrency. prefect-dask is
    imported only here: a clear error if it is missing.
    """
    if max_workers < 1:
        raise ValueError(f"max_workers must be >= 1, got {max_workers}")
    if dask is None:
        return ThreadPoolTaskRunner(max_workers=max_workers)
    try:
        from prefect_dask import DaskTaskRunner
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise RuntimeError(
            "--dask needs the packages prefect-dask and dask[distributed] "
            f"(not importable: {exc}); install them or run without --dask"
        ) from exc
    if dask == "local":
        return DaskTaskRunner(
            cluster_kwargs={
                "n_workers": max_workers,
                "threads_per_worker": 1,
                "processes": True,
                "dashboard_address": None,
            }
        )
    return DaskTaskRunner(address=dask)


# --------------------------------------------------------------------------- tasks


@task(name="ingest-files", **_TRANSIENT)
def ingest_task(paths: list[str], data: DataRoot, hoists: list[str] | None = None) -> IngestReport:
    return ingest_paths(paths, data=data, hoist_lookup=hoist_lookup_from_files(hoists or []))


@task(name="run-period", **_TRANSIENT)
def run_period_task(
    hoist_path: str,
    data: DataRoot,
    start: dt.datetime | None,
    end: dt.datetime | None,
    payload_kg: float | None,
    block_minutes: float = 60.0,
) -> RunResult:
    return run_period(
        hoist_path=hoist_path,
        data=data,
        start=start,
        end=end,
        payload_kg=payload_kg,
        block=dt.timedelta(minutes=block_minutes),
    )


@task(name="sanity-check", **_TRANSIENT)
def sanity_task(
    hoist_path: str, data: DataRoot, run_id: str, start: dt.datetime, end: dt.datetime
) -> Any:
    """The sanity check of a run (:func:`pipelines.backfill.check_sanity`): its failure is
    landed as a finding and returned, only transient errors raise (and are retried)."""
    return check_sanity(hoist_path=hoist_path, data=data, run_id=run_id, start=start, end=end)


@task(name="plan-backfill", **_TRANSIENT)
def plan_task(
    sources: list[HoistSource],
    data: DataRoot,
    start: dt.date,
    end: dt.date,
    force: bool,
    sanity: bool,
) -> BackfillPlan:
    return plan_backfill(sources, data=data, start=start, end=end, force=force, sanity=sanity)


@task(name="partition", task_run_name="{partition.key}", **_TRANSIENT)
def partition_task(
    partition: Partition, data: DataRoot, force: bool, command: str, sanity: bool
) -> PartitionOutcome:
    return run_partition(partition, data=data, force=force, command=command, sanity=sanity)


@task(name="discover", task_run_name="discover {source.key} {day}", **_TASK)
def discover_task(source: HoistSource, day: dt.date, data: DataRoot) -> tuple[Path, float]:
    """The discrepancy report of one day, and the seconds it took (work, not overhead)."""
    t0 = time.perf_counter()
    path = discover_day(source, day, data=data)
    return path, time.perf_counter() - t0


@task(name="ingest-new-files", task_run_name="ingest {source.key}", **_TRANSIENT)
def ingest_hoist_task(
    source: HoistSource, data: DataRoot, known: set[tuple[str, int]]
) -> HoistNight:
    return ingest_new_files(source, data=data, known=known)


@task(name="record-failures", **_TRANSIENT)
def record_failures_task(data: DataRoot, outcomes: list[PartitionOutcome], command: str) -> int:
    return record_failures(data, outcomes, command=command)


@task(name="report", **_TASK)
def report_task(data: DataRoot, **fleet: Any) -> Report:
    """The night's or backfill's HTML report (:func:`pipelines.reports.write_fleet_report`)."""
    from pipelines.reports import write_fleet_report

    return write_fleet_report(data, **fleet)


@task(name="run-report", **_TASK)
def run_report_task(data: DataRoot, result: RunResult, hoist: str, steps: list[Any]) -> Report:
    """A run's HTML report (:func:`pipelines.reports.write_run_report`)."""
    from pipelines.reports import write_run_report
    from schemas.hoist import load_hoist

    return write_run_report(data, result, hoist=load_hoist(hoist), steps=steps, command="run")


@task(name="publish-artifacts", **_TASK)
def publish_task(report: Report, key: str) -> None:
    """The report as a markdown artifact (figures as PNG, the HTML's path), its tables as
    table artifacts."""
    from pipelines.reports import figure_png

    markdown = report.markdown(png=figure_png)
    create_markdown_artifact(markdown=markdown, key=key, description=report.title)
    for name, rows in report.tables.items():
        if rows:
            create_table_artifact(
                table=rows, key=f"{key}-{name}", description=f"{report.title}: {name}"
            )


def _outcomes(
    partitions: Sequence[Partition],
    data: DataRoot,
    *,
    force: bool,
    command: str,
    sanity: bool,
    progress: StderrProgress | None,
) -> list[PartitionOutcome]:
    """Submit one partition task each; collect outcomes (failures as failed outcomes)."""
    if not partitions:
        return []
    futures: list[PrefectFuture[PartitionOutcome]] = partition_task.map(
        list(partitions),
        data=unmapped(data),
        force=unmapped(force),
        command=unmapped(command),
        sanity=unmapped(sanity),
    )
    by_future = {id(f): p for f, p in zip(futures, partitions, strict=True)}
    outcomes = []
    for future in as_completed(futures):
        try:
            outcome = future.result()
        except Exception as exc:
            attempts = 1 + PARTITION_RETRIES if is_transient(exc) else 1
            outcome = failed_outcome(by_future[id(future)], exc, attempts=attempts)
        outcomes.append(outcome)
        if progress is not None:
            progress(outcome)
    return outcomes


# --------------------------------------------------------------------------- flows


@flow(name="ingest", persist_result=False)
def ingest_flow(
    paths: list[str], data: str | None = None, hoists: list[str] | None = None
) -> IngestReport:
    """``ropeload ingest``: files and folders into the lake (``hoists``: description files
    for the depth-in-shaft check).

    A refused file fails the flow run: :class:`~pipelines.ingest.FilesRefused` is raised
    after every file was tried, its message one line per refused file, ``.report`` the
    whole report (the other files landed).
    """
    report = ingest_task(paths, DataRoot.resolve(data), hoists)
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
) -> RunResult:
    """``ropeload run``: compensate, reconcile, alarm and sanity-check a period of one hoist."""
    from pipelines.reports import Step, sanity_step

    root = DataRoot.resolve(data)
    result = run_period_task(hoist, root, start, end, payload_kg, block_minutes)
    reason = "not asked for (sanity=False)" if not sanity else "no trip in the period"
    steps = [sanity_step(None, reason=reason)]
    if sanity and result.trip_summary.height:
        # an optional step: its failure is landed as a finding, not a failed run
        found = sanity_task(
            hoist, root, result.run_id, result.period_start_utc, result.period_end_utc
        )
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

    calibrate = task(name="calibrate-rig", **_TRANSIENT)(calibrate_rig)
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

    discover = task(name="discover-period", **_TASK)(discover_period)
    return discover(
        hoist_path=hoist, data=DataRoot.resolve(data), start=start, end=end, json_path=json_path
    )


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
) -> BackfillReport:
    """``ropeload backfill``: every hoist-day of ``start..end`` not done yet, resumable.

    One task per partition on the flow's task runner; a report artifact at the end.
    """
    root = DataRoot.resolve(data)
    sources = load_hoists(hoists, data=root, incoming=incoming)
    plan = plan_task(sources, root, start, end, force, sanity)
    progress = StderrProgress(plan.total) if show_progress else None
    report = BackfillReport(outcomes=plan.settled())
    for outcome in report.outcomes:
        if progress is not None:
            progress(outcome)
    report.outcomes += _outcomes(
        plan.todo, root, force=force, command="backfill", sanity=sanity, progress=progress
    )
    record_failures_task(root, report.outcomes, "backfill")
    report.notes = incoming_notes(sources)
    try:  # optional: a report that cannot be written is a finding, not a failed backfill
        summary = report_task(
            root, kind="backfill", outcomes=report.outcomes, sources=sources, sanity=sanity,
            range_text=f"{start} .. {end}",
        )  # fmt: skip
        report.report_path = summary.path
        publish_task(summary, "backfill-report")
    except Exception as exc:
        report.notes.append(report_failed(root, report.outcomes, exc))
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

    ``hoists`` is a folder of hoist descriptions (``pipelines.backfill`` convention).
    """
    root = DataRoot.resolve(data)
    sources = load_hoists(hoists, data=root, incoming=incoming)
    notes = incoming_notes(sources)
    known = known_files(root)
    futures = ingest_hoist_task.map(sources, data=unmapped(root), known=unmapped(known))
    nights = [_night(future, source) for future, source in zip(futures, sources, strict=True)]
    partitions = nightly_partitions(nights, data=root, lookback_days=lookback_days, sanity=sanity)
    progress = StderrProgress(len(partitions)) if show_progress else None
    outcomes = _outcomes(
        partitions, root, force=False, command="nightly", sanity=sanity, progress=progress
    )
    record_failures_task(root, outcomes, "nightly")
    by_key = {(s.site, s.hoist): s for s in sources}
    discoveries = {
        f"{site}/{hoist}/{day}": discover_task.submit(by_key[(site, hoist)], day, root)
        for site, hoist, day in days_to_discover(outcomes)
    }
    found = {key: _discovered(future) for key, future in discoveries.items()}
    land_discoveries(outcomes, {key: step for key, (step, _) in found.items()}, root)
    report = NightlyReport(
        hoists=nights,
        runs=BackfillReport(outcomes=outcomes),
        discoveries={key: discovery_words(step) for key, (step, _) in found.items()},
        discover_s=sum(seconds for _, seconds in found.values()),
        notes=notes,
    )
    try:  # optional: a report that cannot be written is a finding, not a failed night
        summary = report_task(
            root, kind="nightly", outcomes=outcomes, sources=sources, sanity=sanity,
            hoist_rows=[n.row() for n in nights], discoveries=report.discoveries,
        )  # fmt: skip
        report.report_path = summary.path
        publish_task(summary, "nightly-report")
    except Exception as exc:
        report.notes.append(report_failed(root, outcomes, exc))
    if not report.ok:
        raise PartitionsFailed(report)
    return report


def _discovered(future: PrefectFuture[tuple[Path, float]]) -> tuple[StepOutcome, float]:
    """A discovery task's outcome: a failed discovery is a finding, not a failed night."""
    try:
        path, seconds = future.result()
    except Exception as exc:
        return discovery_outcome(None, exc), 0.0
    return discovery_outcome(path), seconds


def _night(future: PrefectFuture[HoistNight], source: HoistSource) -> HoistNight:
    try:
        return future.result()
    except Exception as exc:
        return failed_night(source, exc)


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
