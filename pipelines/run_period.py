"""``ropeload run``: compensate, reconcile and alarm one hoist over a period, then land it.

The plain function behind the CLI command and the Prefect ``run`` flow. Reads the
landed samples from the lake, computes rope tensions (:mod:`transforms.compensation`),
per-position / per-trip reconciliation (:mod:`transforms.reconciliation`) and alarms
(:mod:`transforms.alarms`), and lands them with a ``runs`` row that names the hoist
description's hash, the friction parameter set and every source file read. Re-running
the same period replaces what it landed before: no duplicates. The block pipeline
(extent, context pass, compensation staged by a background writer, partials,
alarms) is :mod:`pipelines.run_blocks`.
"""

from __future__ import annotations

import datetime as dt
import logging
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from pipelines.ingest.field_checks import depth_misfit
from pipelines.lake import as_utc, scan_lake
from pipelines.provenance import hoist_run, new_run_id, utc_now
from pipelines.run_blocks import (
    Extent,
    FieldSamples,
    block_alarms,
    compensate_and_stage,
    period_extent,
    read_context,
    summarise_partials,
)
from schemas.hoist import HoistDescription, load_hoist
from transforms.blocks import DEFAULT_BLOCK
from transforms.compensation import CompensationSettings
from warehouse.landing import RopeTensionStage, RunRecord, land_results
from warehouse.store import DataRoot, open_writer

__all__ = [
    "LEAD_IN",
    "CheckedRun",
    "DescriptionMisfitError",
    "NoSamplesError",
    "RunResult",
    "check_period",
    "record_start",
    "refuse_misfit",
    "run_checked",
    "run_period",
]

logger = logging.getLogger(__name__)


#: Default lead-in before a period (see :func:`run_period`).
LEAD_IN = dt.timedelta(minutes=30)


def record_start(period_start: dt.datetime, lead_in: dt.timedelta = LEAD_IN) -> dt.datetime:
    """Where a run of the period starting at ``period_start`` starts reading (UTC; a
    naive time is UTC): ``lead_in`` before it, so the filters and the friction state
    are settled when the period begins."""
    return as_utc(period_start) - lead_in


def check_period(start: dt.datetime | None, end: dt.datetime | None) -> None:
    """ValueError (one line) where ``end`` is not after ``start``: an empty period."""
    if start is not None and end is not None and not end > start:
        raise ValueError(
            f"the period is empty: --to {end:%Y-%m-%d %H:%M:%S} UTC is not after "
            f"--from {start:%Y-%m-%d %H:%M:%S} UTC"
        )


class DescriptionMisfitError(ValueError):
    """The hoist description does not fit the landed record (its shaft and the logged
    depth): a user error, one line (:func:`pipelines.ingest.field_checks.depth_misfit`)."""


def refuse_misfit(samples: pl.LazyFrame, hoist: HoistDescription, hoist_path: str | Path) -> None:
    """Raise :class:`DescriptionMisfitError` where the landed ``samples`` leave the shaft
    the description at ``hoist_path`` gives (:func:`depth_misfit`); a run and a
    discovery would read those depths as not logged."""
    misfit = depth_misfit(samples, hoist)
    if misfit is not None:
        raise DescriptionMisfitError(
            f"{hoist_path}: {misfit}: is it this hoist's description? (a run would read "
            "those depths as not logged)"
        )


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

    The steps are those of :mod:`pipelines.run_blocks`, in order (long only by the
    documentation of its parameters).

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
    samples = FieldSamples(data, hoist.hoist.site, hoist.hoist.name, hoist)
    start, end = (None if t is None else as_utc(t) for t in (start, end))
    check_period(start, end)
    scan_start = None if start is None else record_start(start, lead_in)
    extent = period_extent(samples.scan(scan_start, end), start, end)
    if extent is None:
        raise NoSamplesError(_no_samples_message(data, samples.site, samples.hoist, start, end))
    refuse_misfit(samples.scan(scan_start, end), hoist, hoist_path)
    run_id = new_run_id(command)
    logger.info(
        "run %s: %s/%s %s .. %s UTC, %d samples (and %d of lead-in), blocks of %s",
        run_id, samples.site, samples.hoist, extent.period_start, extent.period_end,
        extent.in_period, extent.rows - extent.in_period, block,
    )  # fmt: skip
    context = read_context(samples, hoist, extent, settings=settings, block=block)
    inputs = tuple(sorted(samples.source_files(scan_start, end)))
    stage = RopeTensionStage(data, site=samples.site, hoist=samples.hoist)
    try:
        stints, trips = compensate_and_stage(
            samples, hoist, stage, extent, context=context, settings=settings, block=block
        )
        positions, trip_summary = summarise_partials(
            stints, trips, hoist, run_id=run_id, payload_kg=payload_kg
        )
        alarms = block_alarms(
            stage, hoist, run_id=run_id, trips=trip_summary, payload_kg=payload_kg,
            start=extent.period_start, end=extent.period_end, block=block, logged=samples,
            sample_step_s=1.0 / context.sample_rate_hz,
        )  # fmt: skip
        run = hoist_run(
            run_id=run_id, command=command, started_at_utc=started, hoist=hoist,
            hoist_path=hoist_path, period=(extent.period_start, extent.period_end),
            inputs=inputs, message=_run_message(extent.in_period, alarms.height, settings),
        )  # fmt: skip
        positions, trip_summary, alarms = _publish(
            data, stage, run, extent, positions, trip_summary, alarms
        )
    finally:
        stage.discard()
    logger.info(
        "run %s landed: %d trips, %d position visits, %d alarms",
        run_id, trip_summary.height, positions.height, alarms.height,
    )  # fmt: skip
    return _result(run_id, samples, extent, positions, trip_summary, alarms, inputs)


def _publish(
    data: DataRoot,
    stage: RopeTensionStage,
    run: RunRecord,
    extent: Extent,
    positions: pl.DataFrame,
    trip_summary: pl.DataFrame,
    alarms: pl.DataFrame,
) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame]:
    """The staged rope tensions and the run's tables, in one writer block; the tables'
    rows as landed: less those an earlier run's rows hold whole (a trip, a stop or an
    alarm across the period's start, :func:`warehouse.landing.land_results`)."""
    with open_writer(data) as con:
        stage.publish(extent.period_start, extent.period_end)
        land_results(con, run, position_summary=positions, trip_summary=trip_summary, alarms=alarms)
        landed = []
        for table, frame, key in (
            ("position_summary", positions, "time_start_utc"),
            ("trip_summary", trip_summary, "time_start_utc"),
            ("alarms", alarms, "alarm_id"),
        ):
            kept = con.execute(
                f"SELECT DISTINCT {key} FROM {table} WHERE run_id = ?", [run.run_id]
            ).fetchall()
            values = pl.Series(key, [row[0] for row in kept], dtype=frame[key].dtype)
            landed.append(frame.filter(pl.col(key).is_in(values.implode())))
    return landed[0], landed[1], landed[2]


def _result(
    run_id: str,
    samples: FieldSamples,
    extent: Extent,
    positions: pl.DataFrame,
    trip_summary: pl.DataFrame,
    alarms: pl.DataFrame,
    inputs: tuple[str, ...],
) -> RunResult:
    """The :class:`RunResult` of a landed run (its rope tensions a scan of the lake)."""
    return RunResult(
        run_id=run_id, site=samples.site, hoist=samples.hoist,
        period_start_utc=extent.period_start, period_end_utc=extent.period_end,
        samples=extent.in_period,
        rope_tensions=scan_lake(
            samples.data, "rope_tensions", site=samples.site, hoist=samples.hoist,
            start=extent.period_start, end=extent.period_end,
        ),
        position_summary=positions, trip_summary=trip_summary, alarms=alarms, inputs=inputs,
    )  # fmt: skip


@dataclass(frozen=True)
class CheckedRun:
    """A run, its simulation sanity check and the HTML report of both (:func:`run_checked`).

    ``sanity`` is what :func:`pipelines.hoist_day.check_sanity` returned, None when the
    check did not run; ``sanity_error`` an error it raised (then said in the report and
    for the caller to raise); ``sanity_words`` how it went; ``report`` the HTML file
    (None where it could not be written: the ``report`` step landed says why).
    """

    result: RunResult
    sanity: object | None
    sanity_error: Exception | None
    sanity_words: str
    report: Path | None


def _run_message(samples: int, alarms: int, settings: CompensationSettings) -> str:
    """The ``runs.message`` of a run: what it did and, when asked for, how its band's
    members ran (an analyst reading the band should know)."""
    message = f"{samples} samples, {alarms} alarms"
    if settings.band_member_step_s > 0:
        message += f"; band members on {settings.band_member_step_s:g} s means"
    return message


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
    settings: CompensationSettings | None = None,
    sanity_trips: int | None = None,
) -> CheckedRun:
    """:func:`run_period`, then the simulation sanity check of its trips (every trip, or
    ``sanity_trips`` sampled: :data:`pipelines.hoist_day.SANITY_TRIPS`), then its report.

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
        settings=settings,
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
            max_trips=sanity_trips,
        )
        checks = found.checks
    reason = "no trip in the period" if sanity else "not asked for (--no-sanity)"
    step = sanity_step(checks, error=error, reason=reason)
    if found is not None:
        step = Step("sanity check", found.step.status, found.step.message)
    report = write_run_report(data, result, hoist=hoist, steps=[step], command=command)
    sentence = step.sentence()
    return CheckedRun(
        result=result,
        sanity=checks,
        sanity_error=error,
        sanity_words=sentence[:1].lower() + sentence[1:].rstrip("."),
        report=report.path,
    )
