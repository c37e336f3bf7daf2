"""``ropeload nightly``: every hoist's new raw files since its watermark, processed and landed.

Contents
--------
:func:`watermarks`
    How far each hoist's landed data reach (what is new:
    :func:`pipelines.hoists.find_new_files`).
:func:`ingest_new_files`
    One hoist's new files into the lake (:func:`pipelines.ingest.ingest_paths`).
:func:`nightly_partitions`
    The hoist-days to (re)run after that ingest.
:func:`nightly`
    The night, written once: ingest per hoist, then the hoist-days on an executor
    (:func:`pipelines.hoist_day.run_partitions`, the backfill's unit of work, so a night
    and a backfill land identical rows), discovery, the report. The executor -- a
    thread pool or Prefect tasks (:mod:`pipelines.executors`) -- is the only difference
    between ``ropeload nightly`` and its flow.

Hoists and incoming folders follow :mod:`pipelines.hoists`' convention
(``<hoists>/*.toml``, ``<incoming>/<site>/<hoist>/**``).

Watermark. The ingest manifest *is* the watermark: a raw file is new when its path
and size are not in the manifest. Unlike a modification-time watermark this survives
copies that keep old mtimes (``rsync -a``, robocopy), clock skew and late files; a
file that grew since (a logger still writing) is new again and ingest resumes after
the bytes it already consumed. Each hoist's time watermark (end of its landed data,
``max(time_end_utc)`` of its manifest rows) is reported, and a night also re-runs the
last ``lookback_days`` UTC days before that watermark that the completion ledger does
not mark done (a failed or interrupted earlier night heals itself). Re-running a night
changes nothing: no file is new, every day is done.

Simulation sanity check and discovery. Each hoist-day run by a night is also checked
against the hoist's simulation (:func:`pipelines.hoist_day.check_sanity`, landed in
``sanity_checks``, its outcome in ``run_steps``; a day counts as done once the check has
an outcome). For each hoist with a failed check, discovery
(:func:`pipelines.discover.discover_period`) runs over its latest failed day and writes
``<data>/reports/discovery/<site>_<hoist>_<day>.json`` (and a plot), landing its
findings in ``discovery_findings`` (:mod:`pipelines.night_discovery`).

Optional steps never fail a night (:mod:`pipelines.steps`): a sanity check, discovery or
report that fails is landed as that step's outcome with the day's run and said on
stdout; the day's compensation is done and is not recomputed the next night. Neither
does ordinary data: a record that ends (or starts) mid-trip, a trip across UTC
midnight, a payload change after the last stop, a 10-20 Hz logger. What the incoming
convention leaves unread -- a folder no hoist description claims, a hoist without its
folder or raw files -- is named, one line each (exit status unchanged).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import importlib.util
import logging
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import polars as pl

from pipelines.backfill import has_samples_or_error
from pipelines.executors import PlainExecutor
from pipelines.hoist_day import run_partitions
from pipelines.hoists import HoistSource, find_new_files, hoist_lookup, incoming_notes, known_files
from pipelines.ingest import IngestReport, ingest_paths
from pipelines.ledger import completed_partitions, days_with_runs, record_failures
from pipelines.night_discovery import discover_days, discovery_words
from pipelines.night_pending import PendingWork, key_parts, load_pending, save_pending
from pipelines.partitions import BackfillReport, Partition, PartitionOutcome, fleet_report
from warehouse.lock import LockTimeoutError, WarehouseLock, describe_holder, read_holder
from warehouse.store import DataRoot, open_reader

if TYPE_CHECKING:
    from pipelines.executors import Executor

__all__ = [
    "HoistNight",
    "NightlyReport",
    "failed_night",
    "ingest_new_files",
    "nightly",
    "nightly_partitions",
    "sanity_available",
    "watermarks",
]

logger = logging.getLogger(__name__)


def watermarks(data: DataRoot) -> dict[tuple[str, str], dt.datetime]:
    """End of the landed data per (site, hoist): ``max(time_end_utc)`` of the manifest."""
    if not data.warehouse.exists():
        return {}
    con = open_reader(data)
    try:
        frame = con.sql(
            "SELECT site, hoist, max(time_end_utc) AS watermark FROM manifest "
            "WHERE site IS NOT NULL AND time_end_utc IS NOT NULL GROUP BY site, hoist"
        ).pl()
    finally:
        con.close()
    return {
        (row["site"], row["hoist"]): row["watermark"].astimezone(dt.UTC)
        for row in frame.iter_rows(named=True)
    }


@dataclass
class HoistNight:
    """One hoist's night: its new files, their ingest, the days to run."""

    source: HoistSource
    new_files: list[Path]
    ingest: IngestReport | None
    watermark_before: dt.datetime | None
    watermark_after: dt.datetime | None
    days: list[dt.date] = field(default_factory=list)
    ingest_s: float = 0.0
    error: str = ""

    def row(self) -> dict[str, object]:
        totals = self.ingest.totals() if self.ingest is not None else {}
        return {
            "hoist": self.source.key,
            "new_files": len(self.new_files),
            "refused": len(self.ingest.refused) if self.ingest is not None else 0,
            "rows_landed": totals.get("rows_landed", 0),
            "rows_quarantined": totals.get("rows_quarantined", 0),
            "watermark_before": _iso(self.watermark_before),
            "watermark_after": _iso(self.watermark_after),
            "days": ", ".join(d.isoformat() for d in self.days),
            "error": self.error,
        }


def _iso(value: dt.datetime | None) -> str:
    return "" if value is None else value.strftime("%Y-%m-%d %H:%M:%SZ")


def _days_touched(report: IngestReport) -> set[dt.date]:
    days: set[dt.date] = set()
    for result in report:
        if result.status not in ("landed", "partial") or result.time_start_utc is None:
            continue
        assert result.time_end_utc is not None
        first = result.time_start_utc.astimezone(dt.UTC).date()
        last = result.time_end_utc.astimezone(dt.UTC).date()
        days.update(first + dt.timedelta(days=k) for k in range((last - first).days + 1))
    return days


def ingest_new_files(
    source: HoistSource, *, data: DataRoot, known: set[tuple[str, int]] | None = None
) -> HoistNight:
    """Ingest one hoist's new raw files; the days they touched become ``days``."""
    t0 = time.perf_counter()
    known = known_files(data) if known is None else known
    before = watermarks(data).get((source.site, source.hoist))
    new = find_new_files(source, known)
    report = None
    if new:
        report = ingest_paths(new, data=data, hoist_lookup=hoist_lookup(source))
    after = watermarks(data).get((source.site, source.hoist)) if new else before
    night = HoistNight(source, new, report, before, after, ingest_s=time.perf_counter() - t0)
    if report is not None:
        night.days = sorted(_days_touched(report))
    logger.info(
        "%s: %d new file(s), days touched: %s; watermark %s -> %s",
        source.key,
        len(new),
        ", ".join(map(str, night.days)) or "none",
        _iso(before) or "-",
        _iso(after) or "-",
    )
    return night


def failed_night(source: HoistSource, exc: BaseException) -> HoistNight:
    """A hoist whose ingest step raised: reported, the other hoists go on."""
    reason = " ".join(str(exc).split()) or "(no message)"
    return HoistNight(source, [], None, None, None, error=f"{type(exc).__name__}: {reason}")


def nightly_partitions(
    nights: Sequence[HoistNight],
    *,
    data: DataRoot,
    lookback_days: int = 3,
    sanity: bool = True,
    pending: PendingWork | None = None,
) -> list[Partition]:
    """Hoist-days to run: days new files touched (and the day after, whose run reads
    them as lead-in), not-done days among the ``lookback_days`` before each hoist's
    watermark, the hoist's days an earlier night planned and did not finish
    (``pending``, :mod:`pipelines.night_pending`), and the days never run of files
    ingested in the last :data:`RECENT_INGEST` (:func:`recently_ingested_days`: a night
    killed during its ingest had saved no plan, and its files were no longer new). Days
    the ledger marks done are left out."""
    candidates: list[Partition] = []
    ran = days_with_runs(data)
    for night in nights:
        days = set(night.days) | {d + dt.timedelta(days=1) for d in night.days}
        if night.watermark_after is not None:
            last = night.watermark_after.date()
            days |= {last - dt.timedelta(days=k) for k in range(max(lookback_days, 0))}
        site, hoist = night.source.site, night.source.hoist
        if pending is not None:
            days |= pending.days_of(site, hoist)
        # never run only (a recalibration's re-runs are the lookback's)
        days |= {
            day for day in recently_ingested_days(data, site, hoist)
            if (site, hoist, day) not in ran
        }  # fmt: skip
        candidates += [Partition(night.source, day) for day in sorted(days)]
    candidates = [p for p in candidates if has_samples_or_error(p, data)]
    done = completed_partitions(data, candidates, sanity=sanity)
    todo = [p for p in candidates if p.key not in done]
    logger.info("%d hoist-day(s) to run: %s", len(todo), ", ".join(p.key for p in todo))
    return todo


@dataclass
class NightlyReport:
    """A night: per-hoist ingest and the partition outcomes."""

    hoists: list[HoistNight]
    runs: BackfillReport
    discoveries: dict[str, str] = field(default_factory=dict)
    discover_s: float = 0.0
    #: The night's HTML report (pipelines.reports), if written.
    report_path: Path | None = None
    #: One line each: incoming folders no hoist claims, hoists without a folder or raw
    #: files (:func:`pipelines.hoists.incoming_notes`), an optional step's failure.
    #: Said, landed where there is a day to land it with, never a failed night.
    notes: list[str] = field(default_factory=list)
    #: Hoist descriptions that could not be read, ``<file>: <reason>`` each: their hoists
    #: were not run (the others were); they fail the night.
    unreadable: list[str] = field(default_factory=list)

    @property
    def refused(self) -> list[str]:
        """The files the night's ingest refused, one ``<file>: <reason>`` each."""
        lines = [r for n in self.hoists if n.ingest is not None for r in n.ingest.refusal_lines()]
        return [*lines, *self.runs.refused]

    @property
    def hoist_errors(self) -> list[str]:
        """Hoists the night could not take up: unreadable descriptions, failed ingests."""
        failed = [f"{n.source.key}: ingest failed: {n.error}" for n in self.hoists if n.error]
        return [*self.unreadable, *failed]

    @property
    def ok(self) -> bool:
        return self.runs.ok and not self.refused and not self.hoist_errors

    @property
    def work_s(self) -> float:
        """Seconds spent inside the plain functions (ingest + runs + discovery)."""
        return sum(n.ingest_s for n in self.hoists) + self.runs.work_s + self.discover_s

    def hoist_table(self) -> pl.DataFrame:
        return pl.DataFrame([n.row() for n in self.hoists], infer_schema_length=None)

    def __str__(self) -> str:
        lines = []
        for night in self.hoists:
            row = night.row()
            lines.append(
                f"{row['hoist']}: {row['new_files']} new file(s), {row['refused']} refused, "
                f"{row['rows_landed']} rows landed; watermark {row['watermark_before'] or '-'}"
                f" -> {row['watermark_after'] or '-'}"
                + (f"; ingest failed: {night.error}" if night.error else "")
            )
            if night.ingest is not None:
                lines += [f"  refused {line}" for line in night.ingest.refusal_lines()]
        lines += self.notes
        checks = sum(o.checks for o in self.runs.outcomes)
        failed = sum(o.checks_failed for o in self.runs.outcomes)
        skipped = sum(o.checks_skipped for o in self.runs.outcomes)
        lines.append(
            f"sanity checks: {checks - failed}/{checks} trips passed"
            + (f", {skipped} skipped (reasons in sanity_checks)" if skipped else "")
        )
        lines += [f"discovery {key}: {where}" for key, where in self.discoveries.items()]
        report = "" if self.report_path is None else f"report: {self.report_path}\n"
        return "\n".join(lines) + "\n" + str(self.runs) + report


def sanity_available() -> bool:
    """Whether the simulation sanity check (``pipelines.sanity``) is installed."""
    return importlib.util.find_spec("pipelines.sanity") is not None


def _ingest(
    executor: Executor, sources: Sequence[HoistSource], *, data: DataRoot
) -> list[HoistNight]:
    """Each hoist's new files (:func:`ingest_new_files` on ``executor``), in the order of
    ``sources``; a hoist whose ingest raised is a failed night, the others go on."""
    known = known_files(data)
    done = {d.item.key: d for d in executor.map(ingest_new_files, sources, data=data, known=known)}
    nights = []
    for source in sources:
        result = done[source.key]
        if result.error is not None:
            nights.append(failed_night(source, result.error))
        else:
            assert result.value is not None
            nights.append(result.value)
    return nights


def nightly(
    sources: Sequence[HoistSource],
    *,
    data: DataRoot,
    max_workers: int = 2,
    retries: int = 2,
    lookback_days: int = 3,
    sanity: bool = True,
    progress: Callable[[PartitionOutcome], None] | None = None,
    on_plan: Callable[[list[Partition]], None] | None = None,
    write_report: bool = True,
    executor: Executor | None = None,
    unreadable: Sequence[str] = (),
) -> NightlyReport:
    """One night for ``sources``: ingest new files per hoist, run the affected days.

    ``unreadable``: hoist descriptions left out of ``sources`` because they could not be
    read (:func:`pipelines.hoists.load_hoists`), ``<file>: <reason>`` each: said in the
    night's report and failing it, not holding up the other hoists.

    ``executor`` runs the steps (:mod:`pipelines.executors`); by default a
    :class:`~pipelines.executors.PlainExecutor` of ``max_workers`` threads and
    ``retries`` (the Prefect flow passes its own and ignores those two).

    Never raises for a failed partition or a refused file: see ``report.ok``. Raises
    :class:`NightRunningError` where another night holds the data root.
    ``on_plan(partitions)`` is called once the hoist-days to run are known. With
    ``write_report`` the night's HTML report is written under ``<data>/reports/``
    (:func:`pipelines.reports.write_fleet_report`; ``report.report_path``; published as
    ``nightly-report`` by a Prefect executor).
    """
    with _one_night_at_a_time(data):
        return _night(
            sources, data=data, executor=executor or PlainExecutor(max_workers, retries),
            lookback_days=lookback_days, sanity=sanity, progress=progress, on_plan=on_plan,
            write_report=write_report, unreadable=unreadable,
        )  # fmt: skip


#: Files ingested this recently have their days checked by every night (done days cost
#: a ledger lookup): a night killed during its ingest is finished within this time.
RECENT_INGEST = dt.timedelta(days=7)


def recently_ingested_days(
    data: DataRoot, site: str, hoist: str, within: dt.timedelta = RECENT_INGEST
) -> set[dt.date]:
    """UTC days (and the day after each, its lead-in's reader) of the hoist's files that
    landed rows in the last ``within``, from the manifest; none without a warehouse."""
    if not data.warehouse.exists():
        return set()
    since = dt.datetime.now(dt.UTC) - within
    con = open_reader(data)
    try:
        spans = con.execute(
            "SELECT time_start_utc, time_end_utc FROM manifest WHERE site = ? AND hoist = ? "
            "AND rows_landed > 0 AND ingested_at_utc >= ? AND time_start_utc IS NOT NULL",
            [site, hoist, since],
        ).fetchall()
    finally:
        con.close()
    days: set[dt.date] = set()
    for start, end in spans:
        first, last = start.astimezone(dt.UTC).date(), (end or start).astimezone(dt.UTC).date()
        days |= {first + dt.timedelta(days=k) for k in range((last - first).days + 2)}
    return days


class NightRunningError(RuntimeError):
    """Another night holds the data root: this one does nothing."""


@contextlib.contextmanager
def _one_night_at_a_time(data: DataRoot) -> Iterator[None]:
    """Hold the data root's night lock (``<data>/.nightly.lock``) for the night, or
    raise :class:`NightRunningError` naming the holder at once: two nights at once (a
    scheduled one over a manual one) both planned the same days before either landed
    one, and both computed them. The lock goes with its process (``flock``): a killed
    night leaves nothing to clear."""
    data.path.mkdir(parents=True, exist_ok=True)
    lock = WarehouseLock(data.night_lock_file, timeout_s=0.0, on_wait=lambda _: None)
    try:
        lock.acquire()
    except LockTimeoutError:
        holder = describe_holder(read_holder(lock.path))
        raise NightRunningError(
            f"another nightly runs on {data.path}: {holder}; this one did nothing"
        ) from None
    try:
        yield
    finally:
        lock.release()


def _night(
    sources: Sequence[HoistSource],
    *,
    data: DataRoot,
    executor: Executor,
    lookback_days: int,
    sanity: bool,
    progress: Callable[[PartitionOutcome], None] | None,
    on_plan: Callable[[list[Partition]], None] | None,
    write_report: bool,
    unreadable: Sequence[str],
) -> NightlyReport:
    """:func:`nightly`'s night, under its lock."""
    t0 = time.perf_counter()
    notes = [f"hoist description {line}; its hoist was not run" for line in unreadable]
    notes += incoming_notes(sources)
    nights = _ingest(executor, sources, data=data)
    pending = load_pending(data)
    configured = {(source.site, source.hoist) for source in sources}
    elsewhere = sorted(
        {"/".join(key_parts(k)[:2]) for k in [*pending.runs, *pending.discoveries]}
        - {f"{site}/{hoist}" for site, hoist in configured}
    )
    if elsewhere:  # kept for when the hoist is back; said, not dropped
        notes.append(f"pending work of hoist(s) not in the hoists folder: {', '.join(elsewhere)}")
    partitions = nightly_partitions(
        nights, data=data, lookback_days=lookback_days, sanity=sanity, pending=pending
    )
    # the plan is kept before the work starts: a night killed now is finished by the next
    ours = {(n.source.site, n.source.hoist) for n in nights}
    pending.runs = {k for k in pending.runs if key_parts(k)[:2] not in ours}
    pending.runs |= {p.key for p in partitions}
    save_pending(data, pending)
    if on_plan is not None:
        on_plan(partitions)
    outcomes = run_partitions(
        executor, partitions, data=data, command="nightly", sanity=sanity, progress=progress
    )
    executor.call(record_failures, data, outcomes, command="nightly")
    pending.runs -= {o.key for o in outcomes if o.status != "failed"}
    save_pending(data, pending)
    found, discover_s = discover_days(executor, sources, outcomes, data, pending=pending)
    discoveries = {key: discovery_words(step) for key, step in found.items()}
    runs = BackfillReport(outcomes=outcomes, wall_s=time.perf_counter() - t0)
    night = NightlyReport(
        hoists=nights, runs=runs, discoveries=discoveries, discover_s=discover_s, notes=notes,
        unreadable=list(unreadable),
    )  # fmt: skip
    if write_report:
        night.report_path = fleet_report(
            executor, data, key="nightly-report", notes=night.notes, kind="nightly",
            outcomes=outcomes, sources=sources, sanity=sanity,
            hoist_rows=[n.row() for n in nights], discoveries=discoveries,
        )  # fmt: skip
    return night
