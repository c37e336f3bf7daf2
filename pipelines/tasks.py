"""Prefect 3 tasks of ropeload, its task runners, and the Prefect executor.

Tasks wrap plain functions at coarse units (a hoist's new files, a hoist-day), never
rows. Retries only for transient failures (:func:`pipelines.executors.is_transient`:
I/O errors, DuckDB lock conflicts), never for bad data. Task results are not cached or
persisted (they are in-process values; the warehouse is the record).

:class:`PrefectExecutor` is the :class:`~pipelines.executors.Executor` of the flows: the
sequence of a backfill or a night (:func:`pipelines.backfill.backfill`,
:func:`pipelines.nightly.nightly`) names plain functions, and it submits each one's task
to the flow's task runner (:func:`task_runner`: threads or a Dask cluster).
"""

from __future__ import annotations

from pipelines.prefect_env import apply_prefect_defaults

apply_prefect_defaults()

import datetime as dt  # noqa: E402  (Prefect's environment first)
from collections.abc import Callable, Iterator, Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, TypeVar  # noqa: E402

from prefect import Task, task, unmapped  # noqa: E402
from prefect.artifacts import create_markdown_artifact, create_table_artifact  # noqa: E402
from prefect.cache_policies import NO_CACHE  # noqa: E402
from prefect.client.schemas.objects import State, TaskRun  # noqa: E402
from prefect.futures import PrefectFuture, as_completed  # noqa: E402
from prefect.task_runners import ThreadPoolTaskRunner  # noqa: E402

from pipelines.backfill import BackfillPlan, plan_backfill  # noqa: E402
from pipelines.executors import Done, is_transient  # noqa: E402
from pipelines.hoist_day import check_sanity, run_partition  # noqa: E402
from pipelines.hoists import HoistSource  # noqa: E402
from pipelines.ingest import IngestReport, ingest_paths  # noqa: E402
from pipelines.ingest.field_checks import hoist_lookup_from_files  # noqa: E402
from pipelines.ledger import record_failures  # noqa: E402
from pipelines.log import enable_run_logs  # noqa: E402
from pipelines.night_discovery import discover_day  # noqa: E402
from pipelines.nightly import HoistNight, ingest_new_files  # noqa: E402
from pipelines.partitions import Partition, PartitionOutcome  # noqa: E402
from pipelines.reports import Report, write_fleet_report  # noqa: E402
from pipelines.run_period import RunResult, run_period  # noqa: E402
from transforms.compensation_record import CompensationSettings  # noqa: E402
from warehouse.store import DataRoot  # noqa: E402

enable_run_logs()  # the module loggers' INFO lines go to the flow and task run logs

__all__ = [
    "PARTITION_RETRIES",
    "TASKS",
    "TASK_OPTIONS",
    "TRANSIENT_OPTIONS",
    "PrefectExecutor",
    "discover_task",
    "ingest_hoist_task",
    "ingest_task",
    "partition_task",
    "plan_task",
    "publish_task",
    "record_failures_task",
    "report_task",
    "run_period_task",
    "run_report_task",
    "sanity_task",
    "task_runner",
]

R = TypeVar("R")
T = TypeVar("T")

#: Retries of a partition task after a transient failure, and the waits between them [s].
PARTITION_RETRIES = 2
_RETRY_DELAYS_S = [2.0, 10.0]


def _retry_transient(task: Task[..., Any], task_run: TaskRun, state: State[Any]) -> bool:
    """Prefect ``retry_condition_fn``: retry only what :func:`is_transient` accepts."""
    try:
        state.result()
    except Exception as exc:
        return is_transient(exc)
    return False


#: Options of every task: no caching, no persisted results (the warehouse is the record).
TASK_OPTIONS: dict[str, Any] = {"cache_policy": NO_CACHE, "persist_result": False}
#: ... and of a task retried after a transient failure (:func:`_retry_transient`).
TRANSIENT_OPTIONS: dict[str, Any] = {
    **TASK_OPTIONS,
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


@task(name="ingest-files", **TRANSIENT_OPTIONS)
def ingest_task(
    paths: list[str], data: DataRoot, hoists: list[str] | None = None, complete: bool = False
) -> IngestReport:
    return ingest_paths(
        paths, data=data, hoist_lookup=hoist_lookup_from_files(hoists or []), complete=complete
    )


@task(name="run-period", **TRANSIENT_OPTIONS)
def run_period_task(
    hoist_path: str,
    data: DataRoot,
    start: dt.datetime | None,
    end: dt.datetime | None,
    payload_kg: float | None,
    block_minutes: float = 60.0,
    band_member_step_s: float = 0.0,
) -> RunResult:
    return run_period(
        hoist_path=hoist_path,
        data=data,
        start=start,
        end=end,
        payload_kg=payload_kg,
        block=dt.timedelta(minutes=block_minutes),
        settings=CompensationSettings(band_member_step_s=band_member_step_s),
    )


@task(name="sanity-check", **TRANSIENT_OPTIONS)
def sanity_task(
    hoist_path: str,
    data: DataRoot,
    run_id: str,
    start: dt.datetime,
    end: dt.datetime,
    max_trips: int | None = None,
) -> Any:
    """The sanity check of a run (:func:`pipelines.hoist_day.check_sanity`): its failure is
    landed as a finding and returned, only transient errors raise (and are retried)."""
    return check_sanity(
        hoist_path=hoist_path, data=data, run_id=run_id, start=start, end=end, max_trips=max_trips
    )


@task(name="plan-backfill", **TRANSIENT_OPTIONS)
def plan_task(
    sources: list[HoistSource],
    data: DataRoot,
    start: dt.date,
    end: dt.date,
    force: bool,
    sanity: bool,
) -> BackfillPlan:
    return plan_backfill(sources, data=data, start=start, end=end, force=force, sanity=sanity)


@task(name="partition", task_run_name="{partition.key}", **TRANSIENT_OPTIONS)
def partition_task(
    partition: Partition,
    data: DataRoot,
    force: bool,
    command: str,
    sanity: bool,
    band_member_step_s: float = 0.0,
) -> PartitionOutcome:
    return run_partition(
        partition, data=data, force=force, command=command, sanity=sanity,
        band_member_step_s=band_member_step_s,
    )  # fmt: skip


@task(name="discover", task_run_name="discover {day.source.key} {day.day}", **TASK_OPTIONS)
def discover_task(day: Partition, data: DataRoot) -> tuple[Path, float]:
    """The discrepancy report of one day, and the seconds it took (work, not overhead)."""
    return discover_day(day, data=data)


@task(name="ingest-new-files", task_run_name="ingest {source.key}", **TRANSIENT_OPTIONS)
def ingest_hoist_task(
    source: HoistSource, data: DataRoot, known: set[tuple[str, int]]
) -> HoistNight:
    return ingest_new_files(source, data=data, known=known)


@task(name="record-failures", **TRANSIENT_OPTIONS)
def record_failures_task(data: DataRoot, outcomes: list[PartitionOutcome], command: str) -> int:
    return record_failures(data, outcomes, command=command)


@task(name="report", **TASK_OPTIONS)
def report_task(data: DataRoot, **fleet: Any) -> Report:
    """The night's or backfill's HTML report (:func:`pipelines.reports.write_fleet_report`)."""
    return write_fleet_report(data, **fleet)


@task(name="run-report", **TASK_OPTIONS)
def run_report_task(data: DataRoot, result: RunResult, hoist: str, steps: list[Any]) -> Report:
    """A run's HTML report (:func:`pipelines.reports.write_run_report`)."""
    from pipelines.reports import write_run_report
    from schemas.hoist import load_hoist

    return write_run_report(data, result, hoist=load_hoist(hoist), steps=steps, command="run")


@task(name="publish-artifacts", **TASK_OPTIONS)
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


# ------------------------------------------------------------------------ executor

#: The task of each plain function a backfill or a night names (:class:`PrefectExecutor`).
TASKS: dict[Callable[..., Any], Task[..., Any]] = {
    plan_backfill: plan_task,
    run_partition: partition_task,
    ingest_new_files: ingest_hoist_task,
    discover_day: discover_task,
    record_failures: record_failures_task,
    write_fleet_report: report_task,
}


class PrefectExecutor:
    """:class:`~pipelines.executors.Executor` of a flow: each plain function as its task
    (:data:`TASKS`), on the flow's task runner; retries are the task's own (transient
    errors only). Use inside a flow run."""

    def map(
        self, fn: Callable[..., R], items: Sequence[T], *, pooled: bool = False, **common: Any
    ) -> Iterator[Done[T, R]]:
        """One task per item, all submitted at once (``pooled`` or not); as they complete."""
        items = list(items)
        if not items:
            return
        chosen = TASKS[fn]
        futures: list[PrefectFuture[R]] = chosen.map(
            items, **{name: unmapped(value) for name, value in common.items()}
        )
        by_future = {id(f): item for f, item in zip(futures, items, strict=True)}
        for future in as_completed(futures):
            item = by_future[id(future)]
            try:
                yield Done(item, future.result())
            except Exception as exc:
                attempts = 1 + (chosen.retries or 0) if is_transient(exc) else 1
                yield Done(item, error=exc, attempts=attempts)

    def call(self, fn: Callable[..., R], *args: Any, **kwargs: Any) -> R:
        """``fn``'s task, run now; raises its error."""
        return TASKS[fn](*args, **kwargs)

    def publish(self, report: Report, key: str) -> None:
        """The report as artifacts under ``key`` (:func:`publish_task`)."""
        publish_task(report, key)
