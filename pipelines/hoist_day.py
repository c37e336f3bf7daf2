"""One hoist-day's work: ingest its new files, run it, check it against the simulation.

Contents
--------
:func:`run_partition`
    The unit of work of a backfill and a night: ingest the day's new files, then
    compensate, reconcile and alarm the UTC day (:func:`pipelines.run_period.run_period`)
    unless the ledger (:mod:`pipelines.ledger`) says the day is already done with exactly
    the inputs now landed; the sanity check on request.
:func:`run_partitions`
    Many partitions on an executor (:mod:`pipelines.executors`), outcomes as they complete.
:func:`check_sanity`, :func:`land_sanity_checks`
    The simulation sanity check of a run's period, landed with its outcome.
"""

from __future__ import annotations

import datetime as dt
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import polars as pl

from pipelines.hoists import hoist_lookup
from pipelines.identified_ropes import identified_ropes
from pipelines.ingest import ingest_paths
from pipelines.ingest.field_checks import within_limits
from pipelines.lake import as_utc, scan_lake
from pipelines.ledger import partition_states
from pipelines.partitions import Partition, PartitionOutcome, failed_outcome, new_outcome
from pipelines.run_period import NoSamplesError, record_start, run_period
from pipelines.steps import StepOutcome, land_steps, one_line
from schemas.hoist import HoistDescription, load_hoist
from transforms.compensation_record import CompensationSettings
from warehouse.landing import drop_orphan_sanity_checks, insert_frame
from warehouse.store import DataRoot, open_reader, open_writer

if TYPE_CHECKING:
    from pipelines.executors import Executor
    from pipelines.sanity import SanityOutcome

__all__ = [
    "SANITY_LEAD_IN",
    "SANITY_LEAD_OUT",
    "SANITY_TRIPS",
    "check_sanity",
    "land_sanity_checks",
    "run_partition",
    "run_partitions",
]

# The lines of a backfill's and a night's partitions keep the name they always had.
logger = logging.getLogger("pipelines.backfill")

#: Trips per hoist-day the simulation sanity check replays at most: None, every trip of
#: the period, in one chain of replays (session 48). A sample of N trips is checked in
#: four blocks spread over the day, each after a warm-up trip replayed from rest, and a
#: block's first trips replay worse than the same trips in the day's chain: on the four
#: validation days (``benchmarks/eval_sanity.py``) every trip in the chain passed 251 of
#: 263 (95.4 %), 20 sampled 68 of 76 (89.5 %), half of the failures a block's first
#: trip. The cost, a simulated 24 h, 100 Hz day of 120 trips (``benchmarks/bench_sanity.py``):
#: 74 s for every trip, 39 s for 20 (the record's reading, ~35 s, is paid either way);
#: ``--sanity-trips`` samples.
SANITY_TRIPS: int | None = None


def run_partition(
    partition: Partition,
    *,
    data: DataRoot,
    force: bool = False,
    command: str = "backfill",
    sanity: bool = False,
    sanity_trips: int | None = SANITY_TRIPS,
    band_member_step_s: float = 0.0,
) -> PartitionOutcome:
    """Ingest the partition's new files, then run its UTC day unless already done.

    With ``sanity`` the simulation sanity check (:func:`check_sanity`: every trip, or
    ``sanity_trips`` sampled) runs on the day's samples and is landed under the run's id.
    It is an optional step: whatever it finds, and also when it fails, its outcome is
    landed and the day succeeds (the failure is in ``findings``). A day whose
    compensation is done but whose check is missing (a crash between the two, or a day
    first run without ``sanity``) gets only the check.

    Raises whatever ingest or :func:`~pipelines.run_period.run_period` raise (the
    callers decide about retries, :func:`~pipelines.executors.is_transient`); a day
    without samples is an ``empty`` outcome, not an error.
    """
    t0 = time.perf_counter()
    ingested, notes, refused = _ingest(partition, data)
    t1 = time.perf_counter()
    if not partition.has_samples(data):
        return new_outcome(
            partition,
            "empty",
            message="; ".join(["no landed samples", *notes]),
            files_ingested=ingested,
            refused=refused,
            ingest_s=t1 - t0,
        )
    state, row = "todo", None
    if not force:
        state, row = partition_states(data, [partition], sanity=sanity)[partition.key]
    if state == "done":
        return new_outcome(
            partition,
            "skipped",
            message="; ".join(["done: same inputs and hoist description", *notes]),
            files_ingested=ingested,
            refused=refused,
            ingest_s=t1 - t0,
        )
    if state == "sanity":
        assert row is not None
        run_id = str(row["run_id"])
        head = f"compensation already landed (run {run_id}); its sanity check run now"
        trips = int(row["trips"] or 0)  # type: ignore[call-overload]
        samples = 0
    else:
        try:
            result = run_period(
                hoist_path=partition.source.path,
                data=data,
                start=partition.start,
                end=partition.end,
                command=command,
                settings=CompensationSettings(band_member_step_s=band_member_step_s),
            )
        except NoSamplesError as exc:
            return new_outcome(
                partition,
                "empty",
                message="; ".join([str(exc), *notes]),
                files_ingested=ingested,
                refused=refused,
                ingest_s=t1 - t0,
            )
        run_id, trips, samples = result.run_id, result.trip_summary.height, result.samples
        head = f"{trips} trips, {result.alarms.height} alarms"
    checks: dict[str, Any] = {}
    if sanity and trips:
        checks = _checked(partition, data, run_id=run_id, max_trips=sanity_trips, notes=notes)
    t2 = time.perf_counter()
    return new_outcome(
        partition,
        "succeeded",
        message="; ".join([head, *notes]),
        run_id=run_id,
        samples=samples,
        files_ingested=ingested,
        refused=refused,
        ingest_s=t1 - t0,
        run_s=t2 - t1,
        **checks,
    )


def _ingest(partition: Partition, data: DataRoot) -> tuple[int, list[str], tuple[str, ...]]:
    """The partition's new files into the lake: how many landed, a note per refused one,
    and the refused files' ``<file>: <reason>`` lines (they fail the command)."""
    if not partition.files:
        return 0, [], ()
    report = ingest_paths(partition.files, data=data, hoist_lookup=hoist_lookup(partition.source))
    ingested = sum(f.status in ("landed", "partial") for f in report)
    notes = [f"refused {f.path.name}: {f.message}" for f in report.refused]
    return ingested, notes, tuple(report.refusal_lines())


def _checked(
    partition: Partition, data: DataRoot, *, run_id: str, max_trips: int | None, notes: list[str]
) -> dict[str, Any]:
    """The day's sanity check (:func:`check_sanity`): its counts and findings as fields of
    the day's outcome; what it found goes first in ``notes``."""
    checked = check_sanity(
        hoist_path=partition.source.path,
        data=data,
        run_id=run_id,
        start=partition.start,
        end=partition.end,
        max_trips=max_trips,
    )
    notes.insert(0, checked.words())
    return {
        "checks": checked.compared,
        "checks_failed": checked.count("failed"),
        "checks_skipped": checked.count("skipped"),
        "findings": (checked.words(),) if checked.step.failed else (),
    }


def run_partitions(
    executor: Executor,
    partitions: Sequence[Partition],
    *,
    data: DataRoot,
    force: bool = False,
    command: str = "backfill",
    sanity: bool = False,
    progress: Callable[[PartitionOutcome], None] | None = None,
    band_member_step_s: float = 0.0,
) -> list[PartitionOutcome]:
    """:func:`run_partition` of each partition on ``executor``; outcomes in completion order.

    A partition whose last attempt raised is a failed outcome with the reason
    (:func:`~pipelines.partitions.failed_outcome`); ``progress(outcome)`` per outcome.
    """
    outcomes: list[PartitionOutcome] = []
    if not partitions:
        return outcomes
    for done in executor.map(
        run_partition,
        list(partitions),
        pooled=True,
        data=data,
        force=force,
        command=command,
        sanity=sanity,
        band_member_step_s=band_member_step_s,
    ):
        if done.error is not None:
            outcome = failed_outcome(done.item, done.error, attempts=done.attempts)
        else:
            assert done.value is not None
            outcome = done.value
            if done.attempts > 1:
                outcome = replace(outcome, attempts=done.attempts)
        outcomes.append(outcome)
        if progress is not None:
            progress(outcome)
    return outcomes


#: Samples before a period that the sanity check replays to warm up the friction state.
SANITY_LEAD_IN = dt.timedelta(hours=6)
#: Samples after a period it reads so that a trip running across the period's end (a trip
#: across UTC midnight) is checked whole, in the period it started in.
SANITY_LEAD_OUT = dt.timedelta(minutes=15)


def check_sanity(
    *,
    hoist_path: str | Path,
    data: DataRoot,
    run_id: str,
    start: dt.datetime,
    end: dt.datetime,
    max_trips: int | None = SANITY_TRIPS,
    hoist: HoistDescription | None = None,
    threshold: float | None = None,
    motion: str = "auto",
) -> SanityOutcome:
    """Simulation sanity check of a run's period (:func:`pipelines.sanity.sanity_check`):
    the trips that start moving in ``[start, end)``, landed under ``run_id`` with the
    step's outcome (:func:`land_sanity_checks`). A trip passes when its RMS gap is at
    most ``threshold`` x the pressure noise (default
    :data:`pipelines.sanity.PASS_LIMIT_X_NOISE`); ``motion`` drives the replays
    (:func:`discovery.planning.plan_replay`).

    An optional step: an error of the check itself (data it cannot replay, a numerical
    failure, a lake file it cannot read) is landed as a ``failed`` outcome with the
    reason and returned, not raised. Only an error landing the outcome is raised (the
    warehouse is unavailable: the caller's retry runs the check alone again, since the
    day's compensation is already done).
    """
    from pipelines.sanity import PASS_LIMIT_X_NOISE, SanityOutcome, sanity_check, sanity_step

    description = hoist or load_hoist(hoist_path)
    site, name = description.hoist.site, description.hoist.name
    try:
        # hours before the period: the replay of an earlier trip loads the seals' state;
        # minutes after it: the period's last trip ends in the record
        samples = scan_lake(
            data,
            "field_samples",
            site=site,
            hoist=name,
            start=start - SANITY_LEAD_IN,
            end=end + SANITY_LEAD_OUT,
        )
        # values beyond the description's limits, landed without it, as the run reads them
        samples = within_limits(samples, description).collect()
        # the ropes as the run's compensation identified them: from where its record
        # starts, its means and the cached identification's (pipelines.identified_ropes)
        run_record = samples.filter(
            (pl.col("time_utc") >= record_start(start)) & (pl.col("time_utc") < as_utc(end))
        )
        frame = sanity_check(
            samples,
            description,
            run_id=run_id,
            max_trips=max_trips,
            report_from=start,
            report_to=end,
            threshold=PASS_LIMIT_X_NOISE if threshold is None else threshold,
            number_from=record_start(start),  # the run's trips count from its lead-in
            motion=motion,
            identified_ropes=identified_ropes(run_record, description, data=data),
        )
        frame = _of_landed_trips(data, frame, run_id)
        step = sanity_step(frame)
    except Exception as exc:
        logger.warning(
            "sanity check of %s failed (landed as its finding; the run stands): %s",
            run_id,
            one_line(exc),
            exc_info=logger.isEnabledFor(logging.DEBUG),
        )
        step = StepOutcome("sanity_check", "failed", one_line(exc))
        frame = _unchecked_trips(data, run_id, site=site, hoist=name, why=step.message)
    land_sanity_checks(data, frame, site=site, hoist=name, run_id=run_id, step=step)
    logger.info("sanity check of %s: %s", run_id, step.line())
    return SanityOutcome(frame, step)


def _of_landed_trips(data: DataRoot, checks: pl.DataFrame, run_id: str) -> pl.DataFrame:
    """The checks of trips the run landed: a trip that starts moving in the period but an
    earlier run's row holds whole (:func:`warehouse.landing.land_results`: one across
    the end of a re-run's period) is that run's, and a verdict on it would be dropped at
    landing yet counted in the step's words (a re-run said 3 of 3 trips passed and kept
    2). Trips of a run that has none landed any more are none of its checks."""
    if not checks.height:
        return checks
    return checks.filter(pl.col("trip_id").is_in(_landed_trip_ids(data, run_id)))


def _landed_trip_ids(data: DataRoot, run_id: str) -> list[int]:
    """The ``trip_id`` of each ``trip_summary`` row the run holds, in order."""
    con = open_reader(data)
    try:
        landed = con.execute(
            "SELECT trip_id FROM trip_summary WHERE run_id = ? ORDER BY trip_id", [run_id]
        ).fetchall()
    finally:
        con.close()
    return [trip_id for (trip_id,) in landed]


def _empty_checks() -> pl.DataFrame:
    from schemas.tables import SANITY_CHECKS, conform

    return conform(pl.DataFrame(), SANITY_CHECKS).clear()


#: The message of each trip's row when the sanity check itself could not run, before
#: its reason (the step's message in ``run_steps``).
NOT_RUN_WORDS = "the sanity check could not run"


def _unchecked_trips(
    data: DataRoot, run_id: str, *, site: str, hoist: str, why: str
) -> pl.DataFrame:
    """``SANITY_CHECKS`` rows of a check that could not run: each trip the run landed
    ``skipped`` with ``why``, so that an audit of the run's trips finds a row for each,
    as it does for a trip the check skipped (none where the warehouse cannot be read:
    the step's row still says why)."""
    from schemas.tables import SANITY_CHECKS, conform

    try:
        trips = _landed_trip_ids(data, run_id)
    except Exception:  # the landing below says what is wrong with the warehouse
        return _empty_checks()
    rows = [
        {"run_id": run_id, "site": site, "hoist": hoist, "trip_id": trip_id,
         "message": f"{NOT_RUN_WORDS}: {why}", "status": "skipped"}
        for trip_id in trips
    ]  # fmt: skip
    return conform(pl.DataFrame(rows), SANITY_CHECKS) if rows else _empty_checks()


def land_sanity_checks(
    data: DataRoot,
    frame: pl.DataFrame,
    *,
    site: str,
    hoist: str,
    run_id: str | None = None,
    step: StepOutcome | None = None,
) -> int:
    """Land a run's sanity checks (and, with ``step``, the check's outcome in
    ``run_steps``, same transaction); drop the hoist's checks whose trip a later run
    replaced (a run of part of an earlier run's period takes over its trips there: the
    earlier checks of those trips are no one's)."""
    run_ids = sorted(set(frame["run_id"].to_list()) | ({run_id} if run_id else set()))
    with open_writer(data) as con:
        con.execute("DELETE FROM sanity_checks WHERE list_contains(?, run_id)", [run_ids])
        landed = insert_frame(con, "sanity_checks", frame)
        # after the insert: a run that took this one's trips over while it was being
        # checked (a night and a backfill of the same day) leaves these checks no one's
        drop_orphan_sanity_checks(con, site=site, hoist=hoist)
        if step is not None and run_id is not None:
            land_steps(con, run_id=run_id, site=site, hoist=hoist, outcomes=[step])
        return landed
