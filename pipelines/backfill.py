"""``ropeload backfill``: many hoist-days, one partition at a time, resumable.

Contents
--------
:class:`BackfillPlan`, :func:`plan_backfill`
    The partition plan: one hoist x one UTC day, with the raw files to ingest for it.
:func:`backfill`
    The backfill, written once: plan, the partitions on an executor (a thread pool with
    retries of transient errors only, or Prefect tasks: :mod:`pipelines.executors`), the
    failed ones recorded, a report (:class:`~pipelines.partitions.BackfillReport`).

The pieces live by idea: the hoists and their incoming files in :mod:`pipelines.hoists`
(the ``--hoists`` / ``--incoming`` convention), a partition and its outcome in
:mod:`pipelines.partitions`, the completion ledger in :mod:`pipelines.ledger`, the work
of one hoist-day (ingest, :func:`~pipelines.run_period.run_period`, the sanity check) in
:mod:`pipelines.hoist_day`.

Idempotence. A partition is done when the ledger says so (:mod:`pipelines.ledger`):
its latest run succeeded with exactly the inputs now landed and the current hoist
description. A backfill killed at any point and restarted re-runs only unfinished days,
and re-running a day replaces its marts and rope tensions (run_period's idempotent
landing), never adds to them.
"""

from __future__ import annotations

import datetime as dt
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pipelines.executors import PlainExecutor
from pipelines.hoist_day import run_partitions
from pipelines.hoists import (
    HoistSource,
    file_span,
    hoist_lookup,
    incoming_notes,
    is_new,
    known_files,
    raw_files,
    utc_days,
)
from pipelines.ingest import ingest_paths
from pipelines.ledger import completed_partitions, record_failures
from pipelines.partitions import (
    BackfillReport,
    Partition,
    PartitionOutcome,
    fleet_report,
    new_outcome,
)
from pipelines.run_period import LEAD_IN
from warehouse.store import DataRoot

if TYPE_CHECKING:
    from pipelines.executors import Executor

__all__ = [
    "BackfillPlan",
    "backfill",
    "has_samples_or_error",
    "plan_backfill",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class BackfillPlan:
    """Partitions to run, and those found done or without data while planning."""

    todo: tuple[Partition, ...]
    done: tuple[Partition, ...]
    empty: tuple[Partition, ...]
    undated_ingested: int = 0
    #: Undated files ingest refused while planning, ``<file>: <reason>`` each.
    refused: tuple[str, ...] = ()

    @property
    def total(self) -> int:
        return len(self.todo) + len(self.done) + len(self.empty)

    def settled(self) -> list[PartitionOutcome]:
        """Outcomes of the partitions that need no work."""
        return [
            new_outcome(p, "skipped", message="done: same inputs and hoist description")
            for p in self.done
        ] + [
            new_outcome(p, "empty", message="no raw files and no landed samples")
            for p in self.empty
        ]


def _days(start: dt.date, end: dt.date) -> list[dt.date]:
    if end < start:
        raise ValueError(f"backfill range: end {end} is before start {start}")
    return [start + dt.timedelta(days=k) for k in range((end - start).days + 1)]


def plan_backfill(
    sources: Sequence[HoistSource],
    *,
    data: DataRoot,
    start: dt.date,
    end: dt.date,
    force: bool = False,
    sanity: bool = False,
) -> BackfillPlan:
    """One partition per hoist and UTC day ``start..end`` (both included).

    New raw files (path and size not in the manifest) are attached to the days their
    name stamps cover; undated new files are ingested here. Partitions the ledger says
    are done are set apart (unless ``force``), and so are days with neither new files
    nor landed samples.
    """
    days = _days(start, end)
    known = known_files(data)
    undated = 0
    refused: list[str] = []
    candidates: list[Partition] = []
    for source in sources:
        per_day: dict[dt.date, list[Path]] = {day: [] for day in days}
        loose: list[Path] = []
        for path in raw_files(source):
            if not is_new(path, known):
                continue
            span = file_span(path, source.timezone)
            if span is None:
                loose.append(path)
                continue
            # a day's run reads LEAD_IN before its midnight too (run_period's lead-in)
            for day in utc_days(span[0], span[1] + LEAD_IN):
                if day in per_day:
                    per_day[day].append(path)
        if loose:
            ingested = ingest_paths(loose, data=data, hoist_lookup=hoist_lookup(source))
            refused += ingested.refusal_lines()
            undated += len(loose)
        candidates += [Partition(source, day, tuple(sorted(per_day[day]))) for day in days]
    done = set() if force else completed_partitions(data, candidates, sanity=sanity)
    todo, finished, empty = [], [], []
    for partition in candidates:
        if partition.key in done and not partition.files:
            finished.append(partition)
        elif not partition.files and not has_samples_or_error(partition, data):
            empty.append(partition)
        else:
            todo.append(partition)
    logger.info(
        "plan %s .. %s: %d hoist-days, %d to run, %d done, %d without data, %d undated "
        "files ingested",
        start,
        end,
        len(candidates),
        len(todo),
        len(finished),
        len(empty),
        undated,
    )
    return BackfillPlan(tuple(todo), tuple(finished), tuple(empty), undated, tuple(refused))


def has_samples_or_error(partition: Partition, data: DataRoot) -> bool:
    """True when the day has samples, or cannot be read (its run will report why)."""
    try:
        return partition.has_samples(data)
    except Exception:
        return True


def backfill(
    sources: Sequence[HoistSource],
    *,
    data: DataRoot,
    start: dt.date,
    end: dt.date,
    max_workers: int = 2,
    retries: int = 2,
    retry_delay_s: float = 1.0,
    force: bool = False,
    sanity: bool = False,
    band_member_step_s: float = 0.0,
    progress: Callable[[PartitionOutcome], None] | None = None,
    on_plan: Callable[[BackfillPlan], None] | None = None,
    write_report: bool = True,
    executor: Executor | None = None,
) -> BackfillReport:
    """Run every hoist-day of ``start..end`` not yet done, ``max_workers`` at a time.

    ``executor`` runs the steps (:mod:`pipelines.executors`); by default a
    :class:`~pipelines.executors.PlainExecutor` of ``max_workers`` threads, ``retries``
    and ``retry_delay_s`` (the Prefect flow passes its own and ignores those three).

    With ``write_report`` one HTML report of the whole backfill is written under
    ``<data>/reports/`` (:func:`pipelines.reports.write_fleet_report`; its path in
    ``report.report_path``; published as ``backfill-report`` by a Prefect executor).

    Resumable and idempotent (module docstring). Never raises for a failed partition:
    failures are in ``report.failed`` with their reasons and in ``runs``; nor for a
    refused file: ``report.refused`` names it (and ``report.ok`` is False).
    ``on_plan(plan)`` is called once before the partitions start (e.g. to size a bar).
    """
    if executor is None:
        executor = PlainExecutor(max_workers, retries, retry_delay_s)
    t0 = time.perf_counter()
    plan = executor.call(
        plan_backfill, sources, data=data, start=start, end=end, force=force, sanity=sanity
    )
    if on_plan is not None:
        on_plan(plan)
    report = BackfillReport(outcomes=plan.settled(), refused_files=list(plan.refused))
    for outcome in report.outcomes:
        if progress is not None:
            progress(outcome)
    report.outcomes += run_partitions(
        executor, plan.todo, data=data, force=force, sanity=sanity, progress=progress,
        band_member_step_s=band_member_step_s,
    )  # fmt: skip
    executor.call(record_failures, data, report.outcomes, command="backfill")
    report.wall_s = time.perf_counter() - t0
    report.notes = incoming_notes(sources)
    if write_report:
        report.report_path = fleet_report(
            executor, data, key="backfill-report", notes=report.notes, kind="backfill",
            outcomes=report.outcomes, sources=sources, sanity=sanity,
            range_text=f"{start} .. {end}",
        )  # fmt: skip
    return report
