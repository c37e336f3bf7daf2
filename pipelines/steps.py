"""Optional steps of a hoist-day run: their outcome is a finding, never a failed day.

A day's work is its compensation (:func:`pipelines.run_period.run_period`: rope
tensions, marts, the ``runs`` row). What follows it is optional: the simulation sanity
check, discovery after a failed check, the report. Such a step can fail (data it cannot
replay, a discovery that finds nothing to fit, a figure that cannot be drawn); that is
landed as the step's outcome in the ``run_steps`` table -- ``done``, ``skipped`` or
``failed`` with a one-line reason -- under the day's ``run_id``, and the day stays done:
the completion ledger (:func:`pipelines.ledger.completed_partitions`) does not send
it back to be recomputed the next night.

``ropeload query "select * from run_steps where status = 'failed'"`` lists the steps
that failed and why.
"""

from __future__ import annotations

import datetime as dt
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import duckdb
import polars as pl

from schemas.tables import RUN_STEPS, conform
from warehouse.landing import insert_frame
from warehouse.store import DataRoot, open_reader, open_writer

__all__ = [
    "STEPS",
    "StepOutcome",
    "StepStatus",
    "land_steps",
    "one_line",
    "record_steps",
    "report_failed",
    "step_table_exists",
    "steps_of",
]

logger = logging.getLogger(__name__)

#: The optional steps, as named in ``run_steps.step``.
STEPS = ("sanity_check", "discovery", "report")

StepStatus = Literal["done", "skipped", "failed"]


@dataclass(frozen=True)
class StepOutcome:
    """What one optional step of a run did: ``status`` and, in words, what or why."""

    step: str
    status: StepStatus
    message: str = ""

    def __post_init__(self) -> None:
        if self.step not in STEPS:
            raise ValueError(f"step: one of {STEPS}, got {self.step!r}")
        if self.status not in ("done", "skipped", "failed"):
            raise ValueError(f"status: done, skipped or failed, got {self.status!r}")

    @property
    def failed(self) -> bool:
        return self.status == "failed"

    def line(self) -> str:
        """``sanity check: failed: ValueError: ...`` (``done`` says only the message)."""
        name = self.step.replace("_", " ")
        if self.status == "done":
            return f"{name}: {self.message or 'done'}"
        return f"{name}: {self.status}" + (f": {self.message}" if self.message else "")


def one_line(exc: BaseException) -> str:
    """``Type: message`` on one line (the reason landed for a failed step)."""
    message = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {message}" if message else type(exc).__name__


def land_steps(
    con: duckdb.DuckDBPyConnection,
    *,
    run_id: str,
    site: str,
    hoist: str,
    outcomes: Iterable[StepOutcome],
) -> int:
    """Land step outcomes of ``run_id`` on an open writer connection (in its transaction);
    a step landed again for the same run replaces the earlier row."""
    rows = [
        {
            "run_id": run_id,
            "step": o.step,
            "site": site,
            "hoist": hoist,
            "status": o.status,
            "message": o.message,
            "finished_at_utc": dt.datetime.now(dt.UTC),
        }
        for o in outcomes
    ]
    if not rows:
        return 0
    con.execute(
        "DELETE FROM run_steps WHERE run_id = ? AND list_contains(?, step)",
        [run_id, [r["step"] for r in rows]],
    )
    return insert_frame(con, "run_steps", conform(pl.DataFrame(rows), RUN_STEPS))


def record_steps(
    data: DataRoot, *, run_id: str, site: str, hoist: str, outcomes: Sequence[StepOutcome]
) -> int:
    """:func:`land_steps` in a writer transaction of its own."""
    if not outcomes:
        return 0
    with open_writer(data) as con:
        return land_steps(con, run_id=run_id, site=site, hoist=hoist, outcomes=outcomes)


def step_table_exists(con: duckdb.DuckDBPyConnection) -> bool:
    """Whether the warehouse has ``run_steps`` (a reader of a warehouse no writer has
    migrated since may not)."""
    ((count,),) = con.sql(
        "SELECT count(*) FROM information_schema.tables WHERE table_name = 'run_steps'"
    ).fetchall()
    return bool(count)


def steps_of(data: DataRoot, run_ids: Iterable[str]) -> pl.DataFrame:
    """The ``run_steps`` rows of ``run_ids`` (empty when none or no warehouse yet)."""
    empty = conform(pl.DataFrame(), RUN_STEPS).clear()
    ids = sorted(set(run_ids))
    if not ids or not data.warehouse.exists():
        return empty
    con = open_reader(data)
    try:
        if not step_table_exists(con):
            return empty
        return con.sql(
            "SELECT * FROM run_steps WHERE list_contains(?, run_id) ORDER BY run_id, step",
            params=[ids],
        ).pl()
    finally:
        con.close()


def report_failed(data: DataRoot, outcomes: Iterable[object], exc: BaseException) -> str:
    """A night's or backfill's report could not be written: land a ``failed`` report
    step with the reason for every day it run (``outcomes`` with a ``run_id`` that
    succeeded) and return the line to print. Never raises (a warehouse that cannot take
    the finding either is logged): the report is optional, the days are done."""
    reason = one_line(exc)
    logger.warning("the report could not be written (a finding; the days stand): %s", reason)
    try:
        with open_writer(data) as con:
            for outcome in outcomes:
                run_id = getattr(outcome, "run_id", None)
                if run_id and getattr(outcome, "status", "") == "succeeded":
                    land_steps(
                        con,
                        run_id=run_id,
                        site=getattr(outcome, "site", ""),
                        hoist=getattr(outcome, "hoist", ""),
                        outcomes=[StepOutcome("report", "failed", reason)],
                    )
    except Exception as landing:  # the report's failure is still said on stdout
        logger.warning("the report's failure could not be landed: %s", one_line(landing))
    return f"report: failed: {reason}"
