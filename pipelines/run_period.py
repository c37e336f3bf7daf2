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
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from pipelines.lake import scan_lake
from pipelines.provenance import hoist_run, new_run_id, utc_now
from schemas.hoist import HoistDescription, load_hoist
from transforms.alarms import evaluate_alarms
from transforms.compensation import CompensationSettings, compensate
from transforms.reconciliation import reconcile
from warehouse.landing import land_results, land_rope_tensions
from warehouse.store import DataRoot, open_writer

__all__ = ["LEAD_IN", "CheckedRun", "NoSamplesError", "RunResult", "run_checked", "run_period"]

logger = logging.getLogger(__name__)


#: Default lead-in before a period (see :func:`run_period`).
LEAD_IN = dt.timedelta(minutes=30)


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
    rope_tensions: pl.DataFrame
    position_summary: pl.DataFrame
    trip_summary: pl.DataFrame
    alarms: pl.DataFrame
    inputs: tuple[str, ...]


def _period(
    samples: pl.DataFrame, start: dt.datetime | None, end: dt.datetime | None
) -> tuple[dt.datetime, dt.datetime]:
    first = start or samples["time_utc"].min()
    last = end or samples["time_utc"].max() + dt.timedelta(microseconds=1)
    return first.astimezone(dt.UTC), last.astimezone(dt.UTC)


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

    Raises
    ------
    NoSamplesError
        When no samples are landed for the hoist in the period.
    """
    started = utc_now()
    hoist = hoist or load_hoist(hoist_path)
    site, name = hoist.hoist.site, hoist.hoist.name
    scan_start = None if start is None else start - lead_in
    samples = scan_lake(
        data, "field_samples", site=site, hoist=name, start=scan_start, end=end
    ).collect()
    in_period = samples if start is None else samples.filter(pl.col("time_utc") >= start)
    if in_period.height == 0:
        raise NoSamplesError(_no_samples_message(data, site, name, start, end))
    period_start, period_end = _period(in_period, start, end)
    run_id = new_run_id(command)
    logger.info(
        "run %s: %s/%s %s .. %s UTC, %d samples (and %d of lead-in)",
        run_id,
        site,
        name,
        period_start,
        period_end,
        in_period.height,
        samples.height - in_period.height,
    )
    tensions = compensate(samples, hoist, settings=settings).filter(
        pl.col("time_utc") >= period_start
    )
    reconciled = reconcile(tensions, hoist, run_id=run_id, payload_kg=payload_kg)
    alarms = evaluate_alarms(
        tensions, hoist, run_id=run_id, trip_payloads=reconciled.trip_summary, payload_kg=payload_kg
    )
    inputs = tuple(sorted(samples["source_sha256"].unique().to_list()))
    run = hoist_run(
        run_id=run_id,
        command=command,
        started_at_utc=started,
        hoist=hoist,
        hoist_path=hoist_path,
        period=(period_start, period_end),
        inputs=inputs,
        message=f"{in_period.height} samples, {alarms.height} alarms",
    )
    with open_writer(data) as con:
        land_rope_tensions(
            data,
            tensions,
            site=site,
            hoist=name,
            period_start_utc=period_start,
            period_end_utc=period_end,
        )
        land_results(
            con,
            run,
            position_summary=reconciled.position_summary,
            trip_summary=reconciled.trip_summary,
            alarms=alarms,
        )
    logger.info(
        "run %s landed: %d trips, %d position visits, %d alarms",
        run_id,
        reconciled.trip_summary.height,
        reconciled.position_summary.height,
        alarms.height,
    )
    return RunResult(
        run_id=run_id,
        site=site,
        hoist=name,
        period_start_utc=period_start,
        period_end_utc=period_end,
        samples=in_period.height,
        rope_tensions=tensions,
        position_summary=reconciled.position_summary,
        trip_summary=reconciled.trip_summary,
        alarms=alarms,
        inputs=inputs,
    )


@dataclass(frozen=True)
class CheckedRun:
    """A run, its simulation sanity check and the HTML report of both (:func:`run_checked`).

    ``sanity`` is what :func:`pipelines.backfill.check_sanity` returned, None when the
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
) -> CheckedRun:
    """:func:`run_period`, then the simulation sanity check of its trips, then its report.

    The report (:func:`pipelines.reports.write_run_report`, under ``<data>/reports/``)
    is written whatever the sanity check does. The check is an optional step: its
    findings, and its own failure, are landed (``sanity_checks``, ``run_steps``) and
    said in the report, never raised (``sanity_error`` stays None; kept for callers).
    Errors of the run itself propagate (nothing was landed, there is nothing to report).
    """
    from pipelines.backfill import check_sanity
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
