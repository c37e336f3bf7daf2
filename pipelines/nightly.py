"""``ropeload nightly``: every hoist's new raw files since its watermark, processed and landed.

Contents
--------
:func:`find_new_files`, :func:`watermarks`
    What is new for a hoist, and how far its landed data reach.
:func:`ingest_new_files`
    One hoist's new files into the lake (:func:`pipelines.ingest.ingest_paths`).
:func:`nightly_partitions`
    The hoist-days to (re)run after that ingest.
:func:`nightly`
    The whole night as plain functions: ingest per hoist, then the hoist-days on a
    bounded thread pool (:func:`pipelines.backfill.run_partitions`, the backfill's
    unit of work, so a night and a backfill land identical rows).

Hoists and incoming folders follow :mod:`pipelines.backfill`'s convention
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
against the hoist's simulation (:func:`pipelines.backfill.check_sanity`, landed in
``sanity_checks``, its outcome in ``run_steps``; a day counts as done once the check has
an outcome). For each hoist with a failed check, discovery
(:func:`pipelines.discover.discover_period`) runs over its latest failed day and writes
``<data>/reports/discovery/<site>_<hoist>_<day>.json`` (and a plot), landing its
findings in ``discovery_findings``.

Optional steps never fail a night (:mod:`pipelines.steps`): a sanity check, discovery or
report that fails is landed as that step's outcome with the day's run and said on
stdout; the day's compensation is done and is not recomputed the next night. Neither
does ordinary data: a record that ends (or starts) mid-trip, a trip across UTC
midnight, a payload change after the last stop, a 10-20 Hz logger. What the incoming
convention leaves unread -- a folder no hoist description claims, a hoist without its
folder or raw files -- is named, one line each (exit status unchanged).
"""

from __future__ import annotations

import datetime as dt
import importlib.util
import json
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import polars as pl

from pipelines.backfill import (
    BackfillReport,
    HoistSource,
    Partition,
    PartitionOutcome,
    _has_samples_or_error,
    completed_partitions,
    hoist_lookup,
    incoming_notes,
    known_files,
    record_failures,
    run_partitions,
)
from pipelines.ingest import IngestReport, ingest_paths
from pipelines.ingest.sources import expand_paths
from pipelines.steps import StepOutcome, one_line, record_steps, report_failed
from warehouse.store import DataRoot, open_reader

__all__ = [
    "HoistNight",
    "NightlyReport",
    "days_to_discover",
    "discover_day",
    "discover_days",
    "discovery_outcome",
    "discovery_words",
    "failed_night",
    "find_new_files",
    "ingest_new_files",
    "land_discoveries",
    "nightly",
    "nightly_partitions",
    "sanity_available",
    "watermarks",
]

_RAW_SUFFIXES = {".csv", ".tdms"}

logger = logging.getLogger(__name__)


def find_new_files(source: HoistSource, known: set[tuple[str, int]]) -> list[Path]:
    """Raw files (CSV, TDMS) under ``source.incoming`` whose (path, size) is not in ``known``."""
    if not source.incoming.is_dir():
        return []
    return [
        path
        for path in expand_paths([source.incoming])
        if path.suffix.lower() in _RAW_SUFFIXES and (str(path), path.stat().st_size) not in known
    ]


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


def _ingest_or_error(
    source: HoistSource, *, data: DataRoot, known: set[tuple[str, int]]
) -> HoistNight:
    try:
        return ingest_new_files(source, data=data, known=known)
    except Exception as exc:
        return failed_night(source, exc)


def nightly_partitions(
    nights: Sequence[HoistNight], *, data: DataRoot, lookback_days: int = 3, sanity: bool = True
) -> list[Partition]:
    """Hoist-days to run: days new files touched (and the day after, whose run reads
    them as lead-in), plus not-done days among the ``lookback_days`` before each
    hoist's watermark. Days the ledger marks done are left out."""
    candidates: list[Partition] = []
    for night in nights:
        days = set(night.days) | {d + dt.timedelta(days=1) for d in night.days}
        if night.watermark_after is not None:
            last = night.watermark_after.date()
            days |= {last - dt.timedelta(days=k) for k in range(max(lookback_days, 0))}
        candidates += [Partition(night.source, day) for day in sorted(days)]
    candidates = [p for p in candidates if _has_samples_or_error(p, data)]
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
    #: files (:func:`pipelines.backfill.incoming_notes`), an optional step's failure.
    #: Said, landed where there is a day to land it with, never a failed night.
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        refused = any(n.ingest is not None and not n.ingest.ok for n in self.hoists)
        return self.runs.ok and not refused and not any(n.error for n in self.hoists)

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


def days_to_discover(outcomes: Sequence[PartitionOutcome]) -> list[tuple[str, str, dt.date]]:
    """(site, hoist, day): each hoist's latest day with a failed sanity check."""
    latest: dict[tuple[str, str], dt.date] = {}
    for outcome in outcomes:
        if outcome.checks_failed:
            key = (outcome.site, outcome.hoist)
            latest[key] = max(outcome.day, latest.get(key, outcome.day))
    return [(site, hoist, day) for (site, hoist), day in sorted(latest.items())]


def discover_day(source: HoistSource, day: dt.date, *, data: DataRoot) -> Path:
    """Discovery over one hoist-day after a failed sanity check; returns the JSON path."""
    from pipelines.discover import discover_period

    start = dt.datetime.combine(day, dt.time(0), tzinfo=dt.UTC)
    target = data.under("reports", "discovery", f"{source.site}_{source.hoist}_{day}.json")
    discover_period(
        hoist_path=source.path,
        data=data,
        start=start,
        end=start + dt.timedelta(days=1),
        json_path=target,
    )
    logger.info("discovery of %s %s (a sanity check failed): %s", source.key, day, target)
    return target


def discovery_outcome(path: Path | None, exc: BaseException | None = None) -> StepOutcome:
    """The discovery step of a day: its report (and the effect named), or why it failed."""
    if exc is not None:
        return StepOutcome("discovery", "failed", one_line(exc))
    assert path is not None
    try:
        effect = json.loads(path.read_text(encoding="utf-8")).get("effect", "?")
    except (OSError, ValueError):
        effect = "?"
    return StepOutcome("discovery", "done", f"effect {effect}; report {path}")


def land_discoveries(
    outcomes: Sequence[PartitionOutcome], found: dict[str, StepOutcome], data: DataRoot
) -> None:
    """Land each discovery's outcome as a step of the day's run it analysed (never
    raises: the outcome is said on stdout anyway)."""
    runs = {o.key: o for o in outcomes if o.run_id}
    for key, step in found.items():
        outcome = runs.get(key)
        if outcome is None or outcome.run_id is None:
            continue
        try:
            record_steps(
                data, run_id=outcome.run_id, site=outcome.site, hoist=outcome.hoist,
                outcomes=[step],
            )  # fmt: skip
        except Exception as exc:
            logger.warning("%s: discovery outcome not landed: %s", key, one_line(exc))


def discovery_words(step: StepOutcome) -> str:
    """What a night prints per discovery: the report's path, or why it failed."""
    if step.failed:
        return f"discovery failed: {step.message}"
    return step.message.rsplit("report ", 1)[-1]


def discover_days(
    sources: Sequence[HoistSource], outcomes: Sequence[PartitionOutcome], data: DataRoot
) -> dict[str, StepOutcome]:
    """Discovery over each hoist's latest day with a failed check (:func:`discover_day`);
    its outcome per ``site/hoist/day``, also landed with the day's run. An optional step:
    a discovery that fails is a finding, it never fails the night."""
    by_key = {(s.site, s.hoist): s for s in sources}
    found: dict[str, StepOutcome] = {}
    for site, hoist, day in days_to_discover(outcomes):
        key = f"{site}/{hoist}/{day}"
        try:
            found[key] = discovery_outcome(discover_day(by_key[(site, hoist)], day, data=data))
        except Exception as exc:
            logger.warning("discovery of %s failed (a finding): %s", key, one_line(exc))
            found[key] = discovery_outcome(None, exc)
    land_discoveries(outcomes, found, data)
    return found


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
) -> NightlyReport:
    """One night for ``sources``: ingest new files per hoist, run the affected days.

    Never raises for a failed partition or a refused file: see ``report.ok``.
    ``on_plan(partitions)`` is called once the hoist-days to run are known. With
    ``write_report`` the night's HTML report is written under ``<data>/reports/``
    (:func:`pipelines.reports.write_fleet_report`; ``report.report_path``).
    """
    t0 = time.perf_counter()
    notes = incoming_notes(sources)
    known = known_files(data)
    nights = [_ingest_or_error(source, data=data, known=known) for source in sources]
    partitions = nightly_partitions(nights, data=data, lookback_days=lookback_days, sanity=sanity)
    if on_plan is not None:
        on_plan(partitions)
    outcomes = run_partitions(
        partitions,
        data=data,
        max_workers=max_workers,
        retries=retries,
        progress=progress,
        command="nightly",
        sanity=sanity,
    )
    record_failures(data, outcomes, command="nightly")
    t_discover = time.perf_counter()
    found = discover_days(sources, outcomes, data)
    discoveries = {key: discovery_words(step) for key, step in found.items()}
    discover_s = time.perf_counter() - t_discover
    runs = BackfillReport(outcomes=outcomes, wall_s=time.perf_counter() - t0)
    night = NightlyReport(
        hoists=nights, runs=runs, discoveries=discoveries, discover_s=discover_s, notes=notes
    )
    if write_report:
        try:  # optional: a report that cannot be written is a finding, not a failed night
            from pipelines.reports import write_fleet_report

            night.report_path = write_fleet_report(
                data,
                kind="nightly",
                outcomes=outcomes,
                sources=sources,
                sanity=sanity,
                hoist_rows=[n.row() for n in nights],
                discoveries=discoveries,
            ).path
        except Exception as exc:
            night.notes.append(report_failed(data, outcomes, exc))
    return night
