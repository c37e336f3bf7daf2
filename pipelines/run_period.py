"""``ropeload run``: compensate, reconcile and alarm one hoist over a period, then land it.

The plain function behind the CLI command and the Prefect ``run`` flow. Reads the
landed samples from the lake, computes rope tensions (:mod:`transforms.compensation`),
per-position / per-trip reconciliation (:mod:`transforms.reconciliation`) and alarms
(:mod:`transforms.alarms`), and lands them with a ``runs`` row that names the hoist
description's hash, the friction parameter set and every source file read. Re-running
the same period replaces what it landed before: no duplicates.
"""

from __future__ import annotations

import datetime as dt
import logging
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from pipelines.lake import scan_lake
from pipelines.provenance import hoist_run, new_run_id, utc_now
from schemas.hoist import HoistDescription, load_hoist
from schemas.tables import ALARMS, ROPES, conform
from transforms.alarms import evaluate_alarms_in_blocks
from transforms.blocks import DEFAULT_BLOCK, block_edges, compensate_blocks, record_context
from transforms.compensation import CompensationSettings
from transforms.reconciliation import (
    stint_partials,
    summarise_positions_from_partials,
    summarise_trips_from_partials,
    trip_partials,
)
from warehouse.landing import RopeTensionStage, land_results
from warehouse.store import DataRoot, open_writer

__all__ = ["LEAD_IN", "CheckedRun", "NoSamplesError", "RunResult", "run_checked", "run_period"]

logger = logging.getLogger(__name__)


#: Default lead-in before a period (see :func:`run_period`).
LEAD_IN = dt.timedelta(minutes=30)


def _utc(value: dt.datetime) -> dt.datetime:
    return value.replace(tzinfo=dt.UTC) if value.tzinfo is None else value.astimezone(dt.UTC)


class NoSamplesError(LookupError):
    """Nothing landed for the hoist in the period asked for."""


def _no_samples_message(
    data: DataRoot, site: str, hoist: str, start: dt.datetime | None, end: dt.datetime | None
) -> str:
    """Which hoist and period had no samples, which days it has, and what to do."""
    days = sorted(
        p.name.removeprefix("date=")
        for p in data.partition_dir("field_samples", site=site, hoist=hoist).glob("date=*")
        if any(p.glob("*.parquet"))
    )

    def when(value: dt.datetime | None, default: str) -> str:
        return default if value is None else f"{value.astimezone(dt.UTC):%Y-%m-%d %H:%M:%S}"

    period = f"{when(start, 'the beginning')} .. {when(end, 'the end')} UTC"
    if not days:
        return (
            f"no samples of hoist {site}/{hoist} are landed in {data.path}: ingest its logs "
            f"first (ropeload ingest --data {data.path} PATH...)"
        )
    landed = days[0] if len(days) == 1 else f"{days[0]} .. {days[-1]} ({len(days)} days)"
    return (
        f"no samples of hoist {site}/{hoist} landed in {period} (landed days: {landed}): "
        "choose --from/--to within them, or ingest that period's logs first (ropeload ingest)"
    )


@dataclass(frozen=True)
class RunResult:
    """What one run computed and landed."""

    run_id: str
    site: str
    hoist: str
    period_start_utc: dt.datetime
    period_end_utc: dt.datetime
    samples: int
    #: the landed compensated samples of the period (a lazy scan of the lake; a frame
    #: when made by hand)
    rope_tensions: pl.LazyFrame | pl.DataFrame
    position_summary: pl.DataFrame
    trip_summary: pl.DataFrame
    alarms: pl.DataFrame
    inputs: tuple[str, ...]


def run_period(
    *,
    hoist_path: str | Path,
    data: DataRoot,
    start: dt.datetime | None = None,
    end: dt.datetime | None = None,
    payload_kg: float | None = None,
    hoist: HoistDescription | None = None,
    settings: CompensationSettings | None = None,
    command: str = "run",
    lead_in: dt.timedelta = LEAD_IN,
    block: dt.timedelta = DEFAULT_BLOCK,
) -> RunResult:
    """Compensate, reconcile and alarm ``start <= t < end`` of one hoist; land the results.

    Parameters
    ----------
    hoist_path : path
        The hoist description (its content hash goes into the ``runs`` row).
    data : DataRoot
        Lake and warehouse.
    start, end : datetime, optional
        Period (UTC if naive); default everything landed for the hoist.
    payload_kg : float, optional
        Known payload at standstill for the reconciliation check (e.g. 0 for an
        empty conveyance); default: inferred per trip only.
    hoist : HoistDescription, optional
        Already loaded description (must be the content of ``hoist_path``).
    settings : CompensationSettings, optional
        Signal-processing choices.
    command : str
        Recorded in ``runs.command``.
    lead_in : timedelta
        Samples this long before ``start`` are compensated too and then dropped: the
        filters and the seals' friction state start from the hoist's real history, not
        from rest (the friction left by earlier motion persists for hours).
    block : timedelta
        Samples are read, compensated, reconciled and staged for landing this many at a
        time (:mod:`transforms.blocks`; default an hour, 360 k samples at 100 Hz), so
        memory is bounded by the block, not the period; the results are those of the
        whole period at once (within the tolerance :mod:`transforms.blocks` states).

    Raises
    ------
    NoSamplesError
        When no samples are landed for the hoist in the period.
    """
    started = utc_now()
    hoist = hoist or load_hoist(hoist_path)
    settings = settings or CompensationSettings()
    site, name = hoist.hoist.site, hoist.hoist.name
    start, end = (None if t is None else _utc(t) for t in (start, end))
    scan_start = None if start is None else start - lead_in

    def scan(lo: dt.datetime | None, hi: dt.datetime | None) -> pl.LazyFrame:
        return scan_lake(data, "field_samples", site=site, hoist=name, start=lo, end=hi)

    record = scan(scan_start, end)
    extent = record.select(
        pl.len().alias("rows"),
        pl.col("time_utc").min().alias("first"),
        pl.col("time_utc").max().alias("last"),
        ((pl.col("time_utc") >= start).sum() if start is not None else pl.len()).alias("in_period"),
    ).collect()
    rows, first, last, in_period = extent.row(0)
    if not rows or not in_period:
        raise NoSamplesError(_no_samples_message(data, site, name, start, end))
    period_start = (start or first).astimezone(dt.UTC)
    period_end = (end or last + dt.timedelta(microseconds=1)).astimezone(dt.UTC)
    run_id = new_run_id(command)
    logger.info(
        "run %s: %s/%s %s .. %s UTC, %d samples (and %d of lead-in), blocks of %s",
        run_id,
        site,
        name,
        period_start,
        period_end,
        in_period,
        rows - in_period,
        block,
    )
    columns = ["time_utc", *(f"p{i}_pa" for i in ROPES), *(f"x{i}_m" for i in ROPES)]
    context = record_context(
        lambda lo, hi: scan(lo, hi).select(columns).collect(),
        hoist,
        start=first,
        end=last + dt.timedelta(microseconds=1),
        rows=rows,
        settings=settings,
        block=block,
    )

    # the source files read (runs.inputs), without sorting the period's rows
    inputs = set(
        scan_lake(
            data, "field_samples", site=site, hoist=name, start=scan_start, end=end, sort=False
        )
        .select(pl.col("source_sha256").unique())
        .collect(engine="streaming")["source_sha256"]
        .to_list()
    )
    wanted = ["time_utc", "depth_m", "speed_m_s", "oil_temp_c", *columns[1:]]

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return scan(lo, hi).select(wanted).collect()

    stage = RopeTensionStage(data, site=site, hoist=name)
    # a block's rows are written while the next block is computed (at most one waits:
    # memory stays bounded by two blocks; a writing error surfaces at the next block)
    writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="stage")
    try:
        stints, trips = [], []
        carry = None
        written: Future[None] | None = None
        for tensions in compensate_blocks(
            read,
            hoist,
            start=first,
            end=last + dt.timedelta(microseconds=1),
            context=context,
            settings=settings,
            block=block,
        ):
            tensions = tensions.filter(pl.col("time_utc") >= period_start)
            if written is not None:
                written.result()
            written = writer.submit(stage.add, tensions)
            part, carry = stint_partials(tensions, hoist, carry=carry)
            stints.append(part)
            trips.append(trip_partials(tensions))
        if written is not None:
            written.result()
        positions = summarise_positions_from_partials(
            pl.concat(stints, how="diagonal_relaxed"), hoist, run_id=run_id, payload_kg=payload_kg
        )
        trip_summary = summarise_trips_from_partials(
            pl.concat(trips, how="diagonal_relaxed"),
            positions,
            run_id=run_id,
            site=site,
            hoist_name=name,
        )
        alarms = _block_alarms(
            stage, hoist, run_id=run_id, trips=trip_summary, payload_kg=payload_kg,
            start=period_start, end=period_end, block=block,
        )  # fmt: skip
        run = hoist_run(
            run_id=run_id,
            command=command,
            started_at_utc=started,
            hoist=hoist,
            hoist_path=hoist_path,
            period=(period_start, period_end),
            inputs=tuple(sorted(inputs)),
            message=f"{in_period} samples, {alarms.height} alarms",
        )
        with open_writer(data) as con:
            stage.publish(period_start, period_end)
            land_results(
                con, run, position_summary=positions, trip_summary=trip_summary, alarms=alarms
            )
    finally:
        writer.shutdown(wait=True)
        stage.discard()
    logger.info(
        "run %s landed: %d trips, %d position visits, %d alarms",
        run_id,
        trip_summary.height,
        positions.height,
        alarms.height,
    )
    return RunResult(
        run_id=run_id,
        site=site,
        hoist=name,
        period_start_utc=period_start,
        period_end_utc=period_end,
        samples=in_period,
        rope_tensions=scan_lake(
            data, "rope_tensions", site=site, hoist=name, start=period_start, end=period_end
        ),
        position_summary=positions,
        trip_summary=trip_summary,
        alarms=alarms,
        inputs=tuple(sorted(inputs)),
    )


#: What :func:`transforms.alarms.evaluate_alarms` reads of the rope tensions.
_ALARM_COLUMNS = [
    "time_utc", "trip_id", "depth_m", "speed_m_s", "acceleration_up_m_s2", "load_n",
    *(f"p{i}_pa" for i in ROPES), *(f"tension{i}_n" for i in ROPES),
    *(f"tension_raw{i}_n" for i in ROPES),
]  # fmt: skip


def _block_alarms(
    stage: RopeTensionStage,
    hoist: HoistDescription,
    *,
    run_id: str,
    trips: pl.DataFrame,
    payload_kg: float | None,
    start: dt.datetime,
    end: dt.datetime,
    block: dt.timedelta,
) -> pl.DataFrame:
    """Alarms of the staged rope tensions, block by block
    (:func:`transforms.alarms.evaluate_alarms_in_blocks`)."""
    files = stage.files()
    if not files:
        return conform(pl.DataFrame(), ALARMS)
    staged = pl.scan_parquet(files).select(_ALARM_COLUMNS)

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return staged.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi)).collect()

    return evaluate_alarms_in_blocks(
        read,
        block_edges(start, end, block),
        hoist,
        run_id=run_id,
        trip_payloads=trips,
        payload_kg=payload_kg,
    )


@dataclass(frozen=True)
class CheckedRun:
    """A run, its simulation sanity check and the HTML report of both (:func:`run_checked`).

    ``sanity`` is what :func:`pipelines.hoist_day.check_sanity` returned, None when the
    check did not run; ``sanity_error`` an error it raised (then said in the report and
    for the caller to raise); ``sanity_words`` how it went; ``report`` the HTML file.
    """

    result: RunResult
    sanity: object | None
    sanity_error: Exception | None
    sanity_words: str
    report: Path


def run_checked(
    *,
    hoist_path: str | Path,
    data: DataRoot,
    start: dt.datetime | None = None,
    end: dt.datetime | None = None,
    payload_kg: float | None = None,
    sanity: bool = True,
    hoist: HoistDescription | None = None,
    command: str = "run",
    block: dt.timedelta = DEFAULT_BLOCK,
) -> CheckedRun:
    """:func:`run_period`, then the simulation sanity check of its trips, then its report.

    The report (:func:`pipelines.reports.write_run_report`, under ``<data>/reports/``)
    is written whatever the sanity check does. The check is an optional step: its
    findings, and its own failure, are landed (``sanity_checks``, ``run_steps``) and
    said in the report, never raised (``sanity_error`` stays None; kept for callers).
    Errors of the run itself propagate (nothing was landed, there is nothing to report).
    """
    from pipelines.hoist_day import check_sanity
    from pipelines.reports import Step, sanity_step, write_run_report

    hoist = hoist or load_hoist(hoist_path)
    result = run_period(
        hoist_path=hoist_path,
        data=data,
        start=start,
        end=end,
        payload_kg=payload_kg,
        hoist=hoist,
        command=command,
        block=block,
    )
    checks: object | None = None
    error: Exception | None = None
    found = None
    if sanity and result.trip_summary.height:
        # an optional step: a failure of the check itself is landed as its finding
        # (run_steps) and said in the report, it does not fail the run
        found = check_sanity(
            hoist_path=hoist_path,
            data=data,
            run_id=result.run_id,
            start=result.period_start_utc,
            end=result.period_end_utc,
            hoist=hoist,
        )
        checks = found.checks
    reason = "no trip in the period" if sanity else "not asked for (--no-sanity)"
    step = sanity_step(checks, error=error, reason=reason)
    if found is not None:
        step = Step("sanity check", found.step.status, found.step.message)
    report = write_run_report(data, result, hoist=hoist, steps=[step], command=command)
    assert report.path is not None
    sentence = step.sentence()
    return CheckedRun(
        result=result,
        sanity=checks,
        sanity_error=error,
        sanity_words=sentence[:1].lower() + sentence[1:].rstrip("."),
        report=report.path,
    )
