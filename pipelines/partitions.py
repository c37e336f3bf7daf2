"""Partitions (one hoist x one UTC day), what happened to each, and the report of many.

Contents
--------
:class:`Partition`
    The unit of work of a backfill and of a night.
:class:`PartitionOutcome`, :func:`new_outcome`, :func:`failed_outcome`
    What happened to one partition (logged as it is made).
:class:`BackfillReport`, :func:`fleet_report`
    All outcomes of one backfill (or night): counts, failures, findings, a table; its
    HTML report.
"""

from __future__ import annotations

import datetime as dt
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import polars as pl

from pipelines.executors import is_transient
from pipelines.hoists import HoistSource, lake_inputs
from pipelines.run_period import LEAD_IN
from pipelines.steps import report_failed
from warehouse.store import DataRoot

if TYPE_CHECKING:
    from pipelines.executors import Executor

__all__ = [
    "BackfillReport",
    "Partition",
    "PartitionOutcome",
    "Status",
    "failed_outcome",
    "fleet_report",
    "new_outcome",
]

# The lines of a backfill's and a night's partitions keep the name they always had.
logger = logging.getLogger("pipelines.backfill")

Status = Literal["succeeded", "skipped", "empty", "failed"]


@dataclass(frozen=True)
class Partition:
    """One hoist x one UTC day, and the new raw files to ingest for it."""

    source: HoistSource
    day: dt.date
    files: tuple[Path, ...] = ()

    @property
    def key(self) -> str:
        return f"{self.source.site}/{self.source.hoist}/{self.day.isoformat()}"

    @property
    def start(self) -> dt.datetime:
        return dt.datetime.combine(self.day, dt.time(0), tzinfo=dt.UTC)

    @property
    def end(self) -> dt.datetime:
        return self.start + dt.timedelta(days=1)

    def inputs(self, data: DataRoot) -> tuple[str, ...]:
        """Sources a run of this day reads now: the day and run_period's lead-in."""
        return lake_inputs(
            data, self.source.site, self.source.hoist, self.start - LEAD_IN, self.end
        )

    def has_samples(self, data: DataRoot) -> bool:
        """Whether any field samples are landed in the day itself."""
        return bool(lake_inputs(data, self.source.site, self.source.hoist, self.start, self.end))


@dataclass(frozen=True)
class PartitionOutcome:
    """What happened to one partition."""

    key: str
    site: str
    hoist: str
    day: dt.date
    status: Status
    message: str = ""
    run_id: str | None = None
    samples: int = 0
    files_ingested: int = 0
    checks: int = 0
    checks_failed: int = 0
    attempts: int = 1
    #: Trips the sanity check could not compare (each with its reason in sanity_checks).
    checks_skipped: int = 0
    #: The optional steps' outcomes that did not go as planned, in words (e.g. "sanity
    #: check: failed: ValueError: ..."): findings of a day that still counts as done.
    findings: tuple[str, ...] = ()
    #: The new files ingest refused for this day, one ``<file>: <reason>`` line each:
    #: whatever the day's status, they fail the backfill (or night) that ingested them.
    refused: tuple[str, ...] = ()
    ingest_s: float = 0.0
    run_s: float = 0.0

    @property
    def work_s(self) -> float:
        """Seconds spent in the plain functions (ingest + run)."""
        return self.ingest_s + self.run_s

    def row(self) -> dict[str, object]:
        return {
            "partition": self.key,
            "status": self.status,
            "samples": self.samples,
            "files_ingested": self.files_ingested,
            "checks_failed": self.checks_failed,
            "attempts": self.attempts,
            "seconds": round(self.work_s, 3),
            "run_id": self.run_id or "",
            "message": self.message,
        }


def new_outcome(partition: Partition, status: Status, **values: object) -> PartitionOutcome:
    """A partition's outcome, logged (INFO when it ran or failed, DEBUG otherwise)."""
    outcome = PartitionOutcome(
        key=partition.key,
        site=partition.source.site,
        hoist=partition.source.hoist,
        day=partition.day,
        status=status,
        **values,  # type: ignore[arg-type]
    )
    level = logging.INFO if status in ("succeeded", "failed") else logging.DEBUG
    logger.log(level, "%s: %s (%s)", outcome.key, status, outcome.message)
    return outcome


def failed_outcome(partition: Partition, exc: BaseException, *, attempts: int) -> PartitionOutcome:
    """The outcome of a partition that raised ``exc`` on its last attempt."""
    reason = " ".join(str(exc).split()) or "(no message)"
    kind = "transient, retries exhausted" if is_transient(exc) else "not retried"
    return new_outcome(
        partition,
        "failed",
        message=f"{type(exc).__name__}: {reason} ({kind})",
        attempts=attempts,
    )


@dataclass
class BackfillReport:
    """All partition outcomes of one backfill (or night), in completion order."""

    outcomes: list[PartitionOutcome] = field(default_factory=list)
    wall_s: float = 0.0
    #: The HTML report written for it (pipelines.reports), if any.
    report_path: Path | None = None
    #: Things to say that are not a partition's outcome, one line each (e.g. an incoming
    #: folder no hoist claims); they do not fail it.
    notes: list[str] = field(default_factory=list)
    #: Files refused that belong to no partition (undated files ingested while
    #: planning), one ``<file>: <reason>`` line each; they fail it.
    refused_files: list[str] = field(default_factory=list)

    def count(self, status: Status) -> int:
        return sum(o.status == status for o in self.outcomes)

    @property
    def failed(self) -> list[PartitionOutcome]:
        return sorted((o for o in self.outcomes if o.status == "failed"), key=lambda o: o.key)

    @property
    def refused(self) -> list[str]:
        """Every refused file once (a file covering two days is read by both), as
        ``<file>: <reason>``."""
        lines = [*self.refused_files, *(r for o in self.outcomes for r in o.refused)]
        return sorted(dict.fromkeys(lines))

    @property
    def ok(self) -> bool:
        return not self.failed and not self.refused

    @property
    def samples(self) -> int:
        return sum(o.samples for o in self.outcomes)

    @property
    def work_s(self) -> float:
        return sum(o.work_s for o in self.outcomes)

    def table(self) -> pl.DataFrame:
        rows = [o.row() for o in sorted(self.outcomes, key=lambda o: o.key)]
        return pl.DataFrame(
            rows,
            schema={
                "partition": pl.String,
                "status": pl.String,
                "samples": pl.Int64,
                "files_ingested": pl.Int64,
                "checks_failed": pl.Int64,
                "attempts": pl.Int64,
                "seconds": pl.Float64,
                "run_id": pl.String,
                "message": pl.String,
            },
        )

    def __str__(self) -> str:
        head = (
            f"{len(self.outcomes)} partitions: {self.count('succeeded')} run, "
            f"{self.count('skipped')} already done, {self.count('empty')} without data, "
            f"{self.count('failed')} failed; {self.samples} samples in {self.wall_s:.1f} s"
        )
        lines = [head, *self.notes]
        found = sorted((o for o in self.outcomes if o.findings), key=lambda o: o.key)
        if found:
            lines.append("findings (optional steps that did not complete; the days are done):")
            lines += [f"  {o.key}: {finding}" for o in found for finding in o.findings]
        if self.failed:
            lines.append("failed partitions:")
            lines += [f"  {o.key}: {o.message}" for o in self.failed]
        if self.refused:
            lines.append("refused files (put a corrected file in the incoming folder):")
            lines += [f"  {line}" for line in self.refused]
        if self.report_path is not None:
            lines.append(f"report: {self.report_path}")
        return "\n".join(lines) + "\n"


def fleet_report(
    executor: Executor, data: DataRoot, *, key: str, notes: list[str], **fleet: Any
) -> Path | None:
    """The HTML report of a night or a backfill (:func:`pipelines.reports.write_fleet_report`
    with ``fleet``), published under ``key`` by ``executor``; its path.

    An optional step: a report that cannot be written (or published) is a finding, not a
    failed night or backfill; it is appended to ``notes`` (and landed with the runs,
    :func:`pipelines.steps.report_failed`).
    """
    path = None
    try:
        from pipelines.reports import write_fleet_report

        written = executor.call(write_fleet_report, data, **fleet)
        path = written.path
        executor.publish(written, key)
    except Exception as exc:
        notes.append(report_failed(data, fleet["outcomes"], exc))
    return path
