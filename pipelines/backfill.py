"""``ropeload backfill``: many hoist-days, one partition at a time, resumable.

Contents
--------
:class:`HoistSource`, :func:`load_hoists`
    The hoists a mine runs and where their raw logs arrive (convention below).
:class:`Partition`, :func:`plan_backfill`
    The partition plan: one hoist x one UTC day, with the raw files to ingest for it.
:func:`run_partition`
    The unit of work: ingest the day's new files, then compensate, reconcile and alarm
    the UTC day (:func:`pipelines.run_period.run_period`) unless the ledger says the
    day is already done with exactly the inputs now landed.
:func:`completed_partitions`, :func:`partition_ledger`
    The completion ledger, read from the ``runs`` table.
:func:`backfill`
    Plan + partitions on a bounded thread pool, with retries of transient errors only,
    a progress callback and a summary of failed partitions (:class:`BackfillReport`).

Hoists and incoming files (``--hoists DIR``, ``--incoming DIR``)::

    <hoists>/<any name>.toml           one hoist description per file (schemas/hoists/README.md)
    <incoming>/<site>/<hoist>/**       that hoist's raw logs (CSV, TDMS) as the logger writes them

``--incoming`` defaults to ``<data>/incoming``. A raw file belongs to the UTC days its
name's date stamp covers: ``..._YYYYMMDD.csv`` is that local day (the hoist's
``timezone``), ``..._YYYYMMDD_HH00.csv`` that local hour; files without a stamp are
ingested while planning so their time range is known from the manifest.

Ledger and idempotence. A partition is *done* when the latest ``runs`` row for exactly
its period ``[day 00:00Z, day+1 00:00Z)`` of its site and hoist succeeded, read exactly
the ``source_sha256`` now landed in the lake for that day, and used the current hoist
description (``hoist_sha256``). The ``runs`` row is written in the same warehouse
transaction as the marts (:func:`warehouse.landing.land_results`), so the ledger can
never say done for a landing that was not published, nor miss one that was: a backfill
killed at any point and restarted re-runs only unfinished days, and re-running a day
replaces its marts and rope tensions (run_period's idempotent landing), never adds to
them. Late files for an old day, or a recalibrated hoist description, make the day
not-done again. Failed partitions get a ``runs`` row with ``status = 'failed'`` and the
reason, so ``ropeload query "select * from runs where status = 'failed'"`` lists them.
"""

from __future__ import annotations

import atexit
import datetime as dt
import logging
import re
import sys
import threading
import time
import zoneinfo
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Literal, TextIO

import duckdb
import polars as pl
import pyarrow as pa

from pipelines.ingest import ingest_paths
from pipelines.ingest.sources import expand_paths
from pipelines.lake import scan_lake
from pipelines.provenance import code_version, new_run_id, utc_now
from pipelines.run_period import LEAD_IN, NoSamplesError, run_period
from pipelines.steps import StepOutcome, land_steps, one_line, report_failed, step_table_exists
from schemas.hoist import HoistDescription, hoist_sha256, load_hoist
from schemas.tables import TABLES
from warehouse.landing import RunRecord, insert_frame, land_run
from warehouse.store import DataRoot, open_reader, open_writer

if TYPE_CHECKING:
    from rich.progress import Progress

    from pipelines.sanity import SanityOutcome

__all__ = [
    "PROCESS_BASE_BYTES",
    "WORKER_BYTES_PER_BLOCK_SAMPLE",
    "BackfillPlan",
    "BackfillReport",
    "HoistSource",
    "Partition",
    "PartitionOutcome",
    "StderrProgress",
    "backfill",
    "check_sanity",
    "completed_partitions",
    "failed_outcome",
    "file_days",
    "file_span",
    "fingerprint",
    "hoist_lookup",
    "incoming_notes",
    "is_transient",
    "known_files",
    "lake_inputs",
    "land_sanity_checks",
    "load_hoists",
    "partition_ledger",
    "partition_states",
    "plan_backfill",
    "record_failures",
    "run_partition",
    "run_partition_with_retries",
    "run_partitions",
    "workers_within_budget",
]

logger = logging.getLogger(__name__)

Status = Literal["succeeded", "skipped", "empty", "failed"]
#: Trips per hoist-day the simulation sanity check replays at most (spread over the day).
SANITY_TRIPS = 20
_STAMP = re.compile(r"(?<!\d)(\d{8})(?:[_T-](\d{2})00)?(?!\d)")
_RAW_SUFFIXES = {".csv", ".tdms"}


# ---------------------------------------------------------------------------- hoists


@dataclass(frozen=True)
class HoistSource:
    """One hoist: its description file and the folder its raw logs arrive in."""

    path: Path
    site: str
    hoist: str
    timezone: str
    incoming: Path

    @property
    def key(self) -> str:
        return f"{self.site}/{self.hoist}"

    def description(self) -> HoistDescription:
        return load_hoist(self.path)


def _source(path: Path, incoming_root: Path) -> HoistSource:
    description = load_hoist(path)
    site, name = description.hoist.site, description.hoist.name
    return HoistSource(
        path=path.absolute(),
        site=site,
        hoist=name,
        timezone=description.hoist.timezone,
        incoming=(incoming_root / site / name).absolute(),
    )


def load_hoists(
    hoists: str | Path | Sequence[str | Path], *, data: DataRoot, incoming: str | Path | None = None
) -> list[HoistSource]:
    """Hoists from a folder of hoist descriptions (``*.toml``) or a list of files.

    ``incoming`` (default ``<data>/incoming``) holds ``<site>/<hoist>/`` per hoist.
    Raises ValueError for an empty folder or two files describing the same hoist.
    """
    root = Path(incoming) if incoming is not None else data.path / "incoming"
    if isinstance(hoists, str | Path):
        hoists = [hoists]
    files: list[Path] = []
    for entry in map(Path, hoists):
        if entry.is_dir():
            found = sorted(entry.glob("*.toml"))
            if not found:
                raise ValueError(f"{entry}: no hoist descriptions (*.toml) in this folder")
            files.extend(found)
        elif entry.is_file():
            files.append(entry)
        else:
            raise FileNotFoundError(f"{entry}: no such hoist description or folder")
    sources = [_source(path, root) for path in files]
    seen: dict[str, Path] = {}
    for source in sources:
        if source.key in seen:
            raise ValueError(
                f"{source.path}: hoist {source.key} is also described in {seen[source.key]}"
            )
        seen[source.key] = source.path
    return sources


# ------------------------------------------------------------------- files and days


def _utc_days(first: dt.datetime, last: dt.datetime) -> list[dt.date]:
    """UTC days touched by ``first <= t < last``."""
    a = first.astimezone(dt.UTC).date()
    b = (last.astimezone(dt.UTC) - dt.timedelta(microseconds=1)).date()
    return [a + dt.timedelta(days=k) for k in range((b - a).days + 1)]


def file_span(path: str | Path, timezone: str) -> tuple[dt.datetime, dt.datetime] | None:
    """UTC span ``[start, end)`` a raw file covers by the date stamp in its name, or None.

    ``..._YYYYMMDD.<ext>`` is that local day of ``timezone``, ``..._YYYYMMDD_HH00.<ext>``
    that local hour. The last stamp in the name wins (a site code may hold digits).
    """
    stamps = list(_STAMP.finditer(Path(path).stem))
    if not stamps:
        return None
    match = stamps[-1]
    try:
        day = dt.datetime.strptime(match.group(1), "%Y%m%d")
    except ValueError:
        return None
    zone = zoneinfo.ZoneInfo(timezone)
    if match.group(2) is not None:
        start = day.replace(hour=int(match.group(2)), tzinfo=zone)
        end = start + dt.timedelta(hours=1)
    else:
        start = day.replace(tzinfo=zone)
        end = (day + dt.timedelta(days=1)).replace(tzinfo=zone)
    return start.astimezone(dt.UTC), end.astimezone(dt.UTC)


def file_days(path: str | Path, timezone: str) -> list[dt.date] | None:
    """UTC days a raw file covers according to the date stamp in its name, or None.

    >>> file_days("mine_hoist_20260302.csv", "Asia/Shanghai")
    [datetime.date(2026, 3, 1), datetime.date(2026, 3, 2)]
    >>> file_days("mine_hoist_20260302_0900.csv", "Asia/Shanghai")
    [datetime.date(2026, 3, 2)]
    >>> file_days("export.csv", "UTC") is None
    True
    """
    span = file_span(path, timezone)
    return None if span is None else _utc_days(*span)


def _raw_files(source: HoistSource) -> list[Path]:
    if not source.incoming.is_dir():
        return []
    return [p for p in expand_paths([source.incoming]) if p.suffix.lower() in _RAW_SUFFIXES]


def incoming_notes(sources: Sequence[HoistSource]) -> list[str]:
    """One line per thing in the incoming convention that will not be processed: a hoist
    without its ``<incoming>/<site>/<hoist>/`` folder or without raw files in it, an
    incoming folder no hoist description claims (its logs are never read), raw files
    outside any ``<site>/<hoist>/`` folder. Hidden entries (``.name``) are ignored."""
    notes: list[str] = []
    claimed = {(s.site, s.hoist) for s in sources}
    sites = {s.site for s in sources}
    for source in sources:
        if not source.incoming.is_dir():
            notes.append(
                f"hoist {source.key} ({source.path.name}): no incoming folder {source.incoming}"
            )
        elif not _raw_files(source):
            notes.append(
                f"hoist {source.key} ({source.path.name}): no raw files (CSV, TDMS) in "
                f"{source.incoming}"
            )
    roots = sorted({s.incoming.parent.parent for s in sources})
    for root in roots:
        if not root.is_dir():
            continue
        stray = [p for p in root.iterdir() if p.is_file() and p.suffix.lower() in _RAW_SUFFIXES]
        for site_dir in sorted(p for p in root.iterdir() if p.is_dir()):
            if site_dir.name.startswith("."):
                continue
            if site_dir.name not in sites:
                notes.append(
                    f"incoming folder {site_dir}: no hoist description has "
                    f"[hoist] site = '{site_dir.name}'; its logs are not read"
                )
                continue
            stray += [
                p for p in site_dir.iterdir() if p.is_file() and p.suffix.lower() in _RAW_SUFFIXES
            ]
            for hoist_dir in sorted(p for p in site_dir.iterdir() if p.is_dir()):
                if not hoist_dir.name.startswith(".") and (
                    (site_dir.name, hoist_dir.name) not in claimed
                ):
                    notes.append(
                        f"incoming folder {hoist_dir}: no hoist description claims it "
                        f"([hoist] site = '{site_dir.name}', name = '{hoist_dir.name}'); "
                        "its logs are not read"
                    )
        for folder in sorted({p.parent for p in stray}):
            count = sum(p.parent == folder for p in stray)
            notes.append(
                f"incoming folder {folder}: {count} raw file(s) outside any <site>/<hoist> "
                "folder; not read"
            )
    return notes


def known_files(data: DataRoot) -> set[tuple[str, int]]:
    """(absolute path, size) of every file in the ingest manifest.

    A raw file whose path and size are here has been ingested (or refused) already: the
    manifest is the watermark. A file that grew since (a logger still writing) is new.
    """
    if not data.warehouse.exists():
        return set()
    con = open_reader(data)
    try:
        rows = con.sql("SELECT source_path, size_bytes FROM manifest").fetchall()
    finally:
        con.close()
    return {(str(path), int(size)) for path, size in rows}


def _is_new(path: Path, known: set[tuple[str, int]]) -> bool:
    return (str(path), path.stat().st_size) not in known


def lake_inputs(
    data: DataRoot, site: str, hoist: str, start: dt.datetime, end: dt.datetime
) -> tuple[str, ...]:
    """Sorted ``source_sha256`` of the field samples landed for a hoist in ``[start, end)``."""
    shas = (
        scan_lake(data, "field_samples", site=site, hoist=hoist, start=start, end=end)
        .select(pl.col("source_sha256").unique())
        .collect()["source_sha256"]
    )
    return tuple(sorted(s for s in shas.to_list() if s is not None))


# ---------------------------------------------------------------------- partitions


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


def _outcome(partition: Partition, status: Status, **values: object) -> PartitionOutcome:
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


#: ``runs.command`` values whose runs land a day's marts (run_period); others, such as
#: ``discover`` over the same period, do not count in the ledger.
LEDGER_COMMANDS = ("run", "backfill", "nightly")


def _latest_runs(data: DataRoot) -> pl.DataFrame:
    """Latest ``runs`` row per (site, hoist, UTC day) among runs covering exactly a day."""
    empty = pl.DataFrame(
        schema={
            "site": pl.String,
            "hoist": pl.String,
            "day": pl.Date,
            "status": pl.String,
            "inputs": pl.List(pl.String),
            "hoist_sha256": pl.String,
            "run_id": pl.String,
            "trips": pl.Int64,
            "checks": pl.Int64,
            "sanity_steps": pl.Int64,
        }
    )
    if not data.warehouse.exists():
        return empty
    con = open_reader(data)
    try:
        runs = con.sql(
            "SELECT run_id, site, hoist, status, inputs, hoist_sha256, "
            "epoch_us(period_start_utc) AS start_us, epoch_us(period_end_utc) AS end_us, "
            "epoch_us(coalesce(finished_at_utc, started_at_utc)) AS at_us, "
            "(SELECT count(*) FROM trip_summary t WHERE t.run_id = r.run_id) AS trips, "
            "(SELECT count(*) FROM sanity_checks c WHERE c.run_id = r.run_id) AS checks, "
            + (
                "(SELECT count(*) FROM run_steps s WHERE s.run_id = r.run_id "
                "AND s.step = 'sanity_check') AS sanity_steps "
                if step_table_exists(con)
                else "0 AS sanity_steps "
            )
            + "FROM runs r WHERE site IS NOT NULL AND period_start_utc IS NOT NULL "
            f"AND command IN ({', '.join(repr(c) for c in LEDGER_COMMANDS)})"
        ).pl()
    finally:
        con.close()
    day_us = 86_400_000_000
    return (
        runs.filter(
            (pl.col("end_us") - pl.col("start_us") == day_us) & (pl.col("start_us") % day_us == 0)
        )
        .with_columns(
            day=pl.from_epoch(pl.col("start_us") // day_us * 86_400, time_unit="s").dt.date()
        )
        .sort("at_us")
        .group_by("site", "hoist", "day")
        .last()
        .select(empty.columns)
    )


PartitionState = Literal["done", "sanity", "todo"]


def partition_states(
    data: DataRoot, partitions: Iterable[Partition], *, sanity: bool = False
) -> dict[str, tuple[PartitionState, dict[str, object] | None]]:
    """Per partition key: its state in the ledger and its latest run's ledger row.

    ``done``: the latest run of exactly its day succeeded, read exactly the inputs now
    landed, with the current hoist description, and (with ``sanity``) its sanity check
    has an outcome (``run_steps``, or trip rows landed before that table existed) or it
    had no trip. ``sanity``: all of that but the sanity check's outcome: only the check
    is left to do, the compensation stands. ``todo``: anything else.
    """
    latest = {
        (r["site"], r["hoist"], r["day"]): r for r in _latest_runs(data).iter_rows(named=True)
    }
    shas: dict[Path, str] = {}
    states: dict[str, tuple[PartitionState, dict[str, object] | None]] = {}
    for partition in partitions:
        row = latest.get((partition.source.site, partition.source.hoist, partition.day))
        states[partition.key] = ("todo", row)
        if row is None or row["status"] != "succeeded":
            continue
        sha = shas.get(partition.source.path)
        if sha is None:
            sha = shas[partition.source.path] = hoist_sha256(partition.source.path)
        if row["hoist_sha256"] != sha:
            continue
        inputs = tuple(sorted(row["inputs"] or ()))
        try:
            landed = partition.inputs(data)
        except Exception:  # unreadable lake day: not done; running it reports why
            continue
        if not inputs or inputs != landed:
            continue
        checked = not row["trips"] or row["checks"] or row["sanity_steps"]
        states[partition.key] = ("sanity" if sanity and not checked else "done", row)
    return states


def completed_partitions(
    data: DataRoot, partitions: Iterable[Partition], *, sanity: bool = False
) -> set[str]:
    """Keys of the partitions the ledger says are done (see the module docstring and
    :func:`partition_states`).

    With ``sanity``, a day with trips is done only once its sanity check has an outcome
    (landed after the run: a crash in between leaves the check to do, not the day).
    Whatever that outcome -- trips failed, skipped, or the check itself failed -- the
    day is done: an optional step's failure is a finding (:mod:`pipelines.steps`).
    """
    return {
        key
        for key, (state, _) in partition_states(data, partitions, sanity=sanity).items()
        if state == "done"
    }


def partition_ledger(data: DataRoot) -> pl.DataFrame:
    """The latest run per (site, hoist, UTC day): ``status``, ``run_id``, ``inputs``."""
    return _latest_runs(data).sort("site", "hoist", "day")


@dataclass(frozen=True)
class BackfillPlan:
    """Partitions to run, and those found done or without data while planning."""

    todo: tuple[Partition, ...]
    done: tuple[Partition, ...]
    empty: tuple[Partition, ...]
    undated_ingested: int = 0

    @property
    def total(self) -> int:
        return len(self.todo) + len(self.done) + len(self.empty)

    def settled(self) -> list[PartitionOutcome]:
        """Outcomes of the partitions that need no work."""
        return [
            _outcome(p, "skipped", message="done: same inputs and hoist description")
            for p in self.done
        ] + [_outcome(p, "empty", message="no raw files and no landed samples") for p in self.empty]


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
    candidates: list[Partition] = []
    for source in sources:
        per_day: dict[dt.date, list[Path]] = {day: [] for day in days}
        loose: list[Path] = []
        for path in _raw_files(source):
            if not _is_new(path, known):
                continue
            span = file_span(path, source.timezone)
            if span is None:
                loose.append(path)
                continue
            # a day's run reads LEAD_IN before its midnight too (run_period's lead-in)
            for day in _utc_days(span[0], span[1] + LEAD_IN):
                if day in per_day:
                    per_day[day].append(path)
        if loose:
            ingest_paths(loose, data=data, hoist_lookup=hoist_lookup(source))
            undated += len(loose)
        candidates += [Partition(source, day, tuple(sorted(per_day[day]))) for day in days]
    done = set() if force else completed_partitions(data, candidates, sanity=sanity)
    todo, finished, empty = [], [], []
    for partition in candidates:
        if partition.key in done and not partition.files:
            finished.append(partition)
        elif not partition.files and not _has_samples_or_error(partition, data):
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
    return BackfillPlan(tuple(todo), tuple(finished), tuple(empty), undated)


def _has_samples_or_error(partition: Partition, data: DataRoot) -> bool:
    """True when the day has samples, or cannot be read (its run will report why)."""
    try:
        return partition.has_samples(data)
    except Exception:
        return True


def hoist_lookup(source: HoistSource) -> Callable[[str, str], HoistDescription | None]:
    """Ingest's ``hoist_lookup`` for one hoist's files (the depth-in-shaft check)."""
    description = source.description()

    def lookup(site: str, hoist: str) -> HoistDescription | None:
        return description if (site, hoist) == (source.site, source.hoist) else None

    return lookup


def run_partition(
    partition: Partition,
    *,
    data: DataRoot,
    force: bool = False,
    command: str = "backfill",
    sanity: bool = False,
    sanity_trips: int = SANITY_TRIPS,
) -> PartitionOutcome:
    """Ingest the partition's new files, then run its UTC day unless already done.

    With ``sanity`` the simulation sanity check (:func:`check_sanity`, at most
    ``sanity_trips`` trips) runs on the day's samples and is landed under the run's id.
    It is an optional step: whatever it finds, and also when it fails, its outcome is
    landed and the day succeeds (the failure is in ``findings``). A day whose
    compensation is done but whose check is missing (a crash between the two, or a day
    first run without ``sanity``) gets only the check.

    Raises whatever ingest or :func:`~pipelines.run_period.run_period` raise (the
    callers decide about retries, :func:`is_transient`); a day without samples is an
    ``empty`` outcome, not an error.
    """
    t0 = time.perf_counter()
    notes: list[str] = []
    ingested = 0
    if partition.files:
        report = ingest_paths(
            partition.files, data=data, hoist_lookup=hoist_lookup(partition.source)
        )
        ingested = sum(f.status in ("landed", "partial") for f in report)
        notes += [f"refused {f.path.name}: {f.message}" for f in report.refused]
    t1 = time.perf_counter()
    if not partition.has_samples(data):
        return _outcome(
            partition,
            "empty",
            message="; ".join(["no landed samples", *notes]),
            files_ingested=ingested,
            ingest_s=t1 - t0,
        )
    state, row = "todo", None
    if not force:
        state, row = partition_states(data, [partition], sanity=sanity)[partition.key]
    if state == "done":
        return _outcome(
            partition,
            "skipped",
            message="; ".join(["done: same inputs and hoist description", *notes]),
            files_ingested=ingested,
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
            )
        except NoSamplesError as exc:
            return _outcome(partition, "empty", message=str(exc), ingest_s=t1 - t0)
        run_id, trips, samples = result.run_id, result.trip_summary.height, result.samples
        head = f"{trips} trips, {result.alarms.height} alarms"
    checks = failed_checks = skipped_checks = 0
    findings: list[str] = []
    if sanity and trips:
        checked = check_sanity(
            hoist_path=partition.source.path,
            data=data,
            run_id=run_id,
            start=partition.start,
            end=partition.end,
            max_trips=sanity_trips,
        )
        checks, failed_checks = checked.compared, checked.count("failed")
        skipped_checks = checked.count("skipped")
        if checked.step.failed:
            findings.append(checked.words())
        notes.insert(0, checked.words())
    t2 = time.perf_counter()
    return _outcome(
        partition,
        "succeeded",
        message="; ".join([head, *notes]),
        run_id=run_id,
        samples=samples,
        files_ingested=ingested,
        checks=checks,
        checks_failed=failed_checks,
        checks_skipped=skipped_checks,
        findings=tuple(findings),
        ingest_s=t1 - t0,
        run_s=t2 - t1,
    )


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
    max_trips: int = SANITY_TRIPS,
    hoist: HoistDescription | None = None,
    threshold: float = 1.5,
) -> SanityOutcome:
    """Simulation sanity check of a run's period (:func:`pipelines.sanity.sanity_check`):
    the trips that start moving in ``[start, end)``, landed under ``run_id`` with the
    step's outcome (:func:`land_sanity_checks`). A trip passes when its RMS gap is at
    most ``threshold`` x the pressure noise.

    An optional step: an error of the check itself (data it cannot replay, a numerical
    failure, a lake file it cannot read) is landed as a ``failed`` outcome with the
    reason and returned, not raised. Only an error landing the outcome is raised (the
    warehouse is unavailable: the caller's retry runs the check alone again, since the
    day's compensation is already done).
    """
    from pipelines.sanity import SanityOutcome, sanity_check, sanity_step

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
        frame = sanity_check(
            samples,
            description,
            run_id=run_id,
            max_trips=max_trips,
            report_from=start,
            report_to=end,
            threshold=threshold,
        )
        step = sanity_step(frame)
    except Exception as exc:
        logger.warning(
            "sanity check of %s failed (landed as its finding; the run stands): %s",
            run_id,
            one_line(exc),
            exc_info=logger.isEnabledFor(logging.DEBUG),
        )
        frame = _empty_checks()
        step = StepOutcome("sanity_check", "failed", one_line(exc))
    land_sanity_checks(data, frame, site=site, hoist=name, run_id=run_id, step=step)
    logger.info("sanity check of %s: %s", run_id, step.line())
    return SanityOutcome(frame, step)


def _empty_checks() -> pl.DataFrame:
    from schemas.tables import SANITY_CHECKS
    from transforms.reconciliation import conform

    return conform(pl.DataFrame(), SANITY_CHECKS).clear()


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
    ``run_steps``, same transaction); drop the hoist's checks whose run was replaced."""
    run_ids = sorted(set(frame["run_id"].to_list()) | ({run_id} if run_id else set()))
    with open_writer(data) as con:
        con.execute(
            "DELETE FROM sanity_checks WHERE list_contains(?, run_id) OR (site = ? AND hoist = ? "
            "AND run_id NOT IN (SELECT run_id FROM trip_summary))",
            [run_ids, site, hoist],
        )
        landed = insert_frame(con, "sanity_checks", frame)
        if step is not None and run_id is not None:
            land_steps(con, run_id=run_id, site=site, hoist=hoist, outcomes=[step])
        return landed


# ---------------------------------------------------------------- errors and retries


def is_transient(exc: BaseException) -> bool:
    """Worth retrying: I/O trouble and lock time-outs; never bad data or code errors.

    Missing files and permission errors are not transient (retrying cannot fix them);
    other ``OSError`` (NFS hiccups, ``EAGAIN``, a full disk being cleaned) and DuckDB
    I/O errors ("Could not set lock on file") are.
    """
    if isinstance(
        exc, FileNotFoundError | PermissionError | IsADirectoryError | NotADirectoryError
    ):
        return False
    return isinstance(exc, OSError | TimeoutError | duckdb.IOException)


def failed_outcome(partition: Partition, exc: BaseException, *, attempts: int) -> PartitionOutcome:
    """The outcome of a partition that raised ``exc`` on its last attempt."""
    reason = " ".join(str(exc).split()) or "(no message)"
    kind = "transient, retries exhausted" if is_transient(exc) else "not retried"
    return _outcome(
        partition,
        "failed",
        message=f"{type(exc).__name__}: {reason} ({kind})",
        attempts=attempts,
    )


def run_partition_with_retries(
    partition: Partition,
    *,
    data: DataRoot,
    retries: int = 2,
    retry_delay_s: float = 1.0,
    force: bool = False,
    command: str = "backfill",
    sanity: bool = False,
) -> PartitionOutcome:
    """:func:`run_partition`, retrying transient errors; a final error is a failed outcome."""
    attempt = 0
    while True:
        attempt += 1
        try:
            outcome = run_partition(
                partition, data=data, force=force, command=command, sanity=sanity
            )
        except Exception as exc:
            if is_transient(exc) and attempt <= retries:
                logger.warning(
                    "%s: %s: %s; retry %d of %d in %.0f s",
                    partition.key,
                    type(exc).__name__,
                    exc,
                    attempt,
                    retries,
                    retry_delay_s * attempt,
                )
                time.sleep(retry_delay_s * attempt)
                continue
            return failed_outcome(partition, exc, attempts=attempt)
        return replace(outcome, attempts=attempt) if attempt > 1 else outcome


def record_failures(
    data: DataRoot, outcomes: Iterable[PartitionOutcome], *, command: str = "backfill"
) -> int:
    """One ``runs`` row with ``status = 'failed'`` and the reason per failed partition."""
    failed = [o for o in outcomes if o.status == "failed"]
    if not failed:
        return 0
    logger.info("%d failed partition(s) recorded in the runs table", len(failed))
    with open_writer(data) as con:
        for outcome in failed:
            start = dt.datetime.combine(outcome.day, dt.time(0), tzinfo=dt.UTC)
            now = utc_now()
            land_run(
                con,
                RunRecord(
                    run_id=new_run_id(command),
                    command=command,
                    code_version=code_version(),
                    started_at_utc=now,
                    finished_at_utc=now,
                    status="failed",
                    site=outcome.site,
                    hoist=outcome.hoist,
                    period_start_utc=start,
                    period_end_utc=start + dt.timedelta(days=1),
                    message=outcome.message,
                ),
            )
    return len(failed)


# ------------------------------------------------------------------------- reporting


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

    def count(self, status: Status) -> int:
        return sum(o.status == status for o in self.outcomes)

    @property
    def failed(self) -> list[PartitionOutcome]:
        return sorted((o for o in self.outcomes if o.status == "failed"), key=lambda o: o.key)

    @property
    def ok(self) -> bool:
        return not self.failed

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
        if self.report_path is not None:
            lines.append(f"report: {self.report_path}")
        return "\n".join(lines) + "\n"


class StderrProgress:
    """Progress of the partitions on stderr: a live bar (rich) on a terminal only.

    Call it with each :class:`PartitionOutcome`; :meth:`resize` once the number of
    partitions is known. On a terminal rich redraws one line
    (``partitions ━━━━━━━━━━━━━━━━━━━━━━━━━━ 12/60 1 failed 0:00:41 eta 0:03:05 <key>``)
    and lines written to ``sys.stderr`` meanwhile (the log) go above it. Elsewhere (CI,
    cron, a log file) it says nothing until the last partition, then one summary line
    ``60/60 partitions, 1 failed, 245 s``. The bar ends at the last partition, on
    :meth:`close`, or at exit. ``stream``: default ``sys.stderr``.
    """

    def __init__(
        self, total: int, *, label: str = "partitions", stream: TextIO | None = None
    ) -> None:
        self.total, self.label = total, label
        self.done = 0
        self.failed = 0
        self._stream = sys.stderr if stream is None else stream
        self._started = time.perf_counter()
        self._lock = threading.Lock()
        self._closed = False
        self._bar: Progress | None = None
        if self._stream.isatty():
            from rich.console import Console  # 0.2 s to import: only for a terminal
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[failed]} failed"),
                TimeElapsedColumn(),
                TextColumn("eta"),
                TimeRemainingColumn(),
                TextColumn("{task.fields[key]}"),
                console=Console(file=self._stream, force_terminal=True),
                refresh_per_second=2,
                redirect_stdout=False,  # stdout is the command's result, never the bar's
                redirect_stderr=self._stream is sys.stderr,  # log lines go above the bar
            )
            self._task = self._bar.add_task(label, total=total, failed=0, key="")
            self._start_bar()

    def _start_bar(self) -> None:
        """Draw the bar once there is something to count (not for an empty plan)."""
        if self._bar is not None and self.total and not self._bar.live.is_started:
            self._bar.start()
            atexit.register(self.close)

    def resize(self, total: int) -> None:
        """Set the number of partitions once known (after planning)."""
        with self._lock:
            self.total = total
            if self._bar is not None:
                self._bar.update(self._task, total=total)
                self._start_bar()
        if total and self.done >= total:
            self.close()

    def __call__(self, outcome: PartitionOutcome) -> None:
        with self._lock:
            self.done += 1
            self.failed += outcome.status == "failed"
            if self._bar is not None:
                self._bar.update(self._task, advance=1, failed=self.failed, key=outcome.key)
        if self.total and self.done >= self.total:
            self.close()

    def close(self) -> None:
        """End the bar (a terminal) or write the summary line (elsewhere); once."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        if self._bar is not None:
            if self._bar.live.is_started:
                self._bar.stop()
                atexit.unregister(self.close)
            return
        elapsed = time.perf_counter() - self._started
        self._stream.write(
            f"{self.done}/{self.total} {self.label}, {self.failed} failed, {elapsed:.0f} s\n"
        )
        self._stream.flush()


#: Memory of a backfill or night (``benchmarks/bench_day.py --backfill 4``, 100 Hz
#: hoist-days, hour blocks): one worker's process peaks at ~1.3 GB, each further worker
#: adds ~0.4 GB (four: 2.46 GB). A worker's share grows with its block's samples.
PROCESS_BASE_BYTES = 0.9e9
WORKER_BYTES_PER_BLOCK_SAMPLE = 0.4e9 / 360_000


def workers_within_budget(
    workers: int,
    budget_bytes: float,
    *,
    block: dt.timedelta = dt.timedelta(hours=1),
    sample_rate_hz: float = 100.0,
) -> int:
    """The most workers (at most ``workers``, at least 1) whose memory fits ``budget_bytes``.

    Estimate: :data:`PROCESS_BASE_BYTES` + workers x :data:`WORKER_BYTES_PER_BLOCK_SAMPLE`
    x the samples of a block (``sample_rate_hz`` x ``block``).

    >>> [workers_within_budget(8, gb * 1e9) for gb in (8.0, 2.5, 2.4, 1.0)]
    [8, 4, 3, 1]
    """
    per_worker = WORKER_BYTES_PER_BLOCK_SAMPLE * sample_rate_hz * block.total_seconds()
    fit = int((budget_bytes - PROCESS_BASE_BYTES) / per_worker + 1e-9)  # 1.6 / 0.4 is 4
    return max(1, min(workers, fit))


def run_partitions(
    partitions: Sequence[Partition],
    *,
    data: DataRoot,
    max_workers: int = 2,
    retries: int = 2,
    retry_delay_s: float = 1.0,
    force: bool = False,
    progress: Callable[[PartitionOutcome], None] | None = None,
    command: str = "backfill",
    sanity: bool = False,
) -> list[PartitionOutcome]:
    """Partitions on a pool of ``max_workers`` threads; outcomes in completion order."""
    if max_workers < 1:
        raise ValueError(f"max_workers must be >= 1, got {max_workers}")
    outcomes: list[PartitionOutcome] = []
    with ThreadPoolExecutor(max_workers=max_workers, thread_name_prefix="partition") as pool:
        futures = [
            pool.submit(
                run_partition_with_retries,
                partition,
                data=data,
                retries=retries,
                retry_delay_s=retry_delay_s,
                force=force,
                command=command,
                sanity=sanity,
            )
            for partition in partitions
        ]
        for future in as_completed(futures):
            outcome = future.result()
            outcomes.append(outcome)
            if progress is not None:
                progress(outcome)
    return outcomes


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
    progress: Callable[[PartitionOutcome], None] | None = None,
    on_plan: Callable[[BackfillPlan], None] | None = None,
    write_report: bool = True,
) -> BackfillReport:
    """Run every hoist-day of ``start..end`` not yet done, ``max_workers`` at a time.

    With ``write_report`` one HTML report of the whole backfill is written under
    ``<data>/reports/`` (:func:`pipelines.reports.write_fleet_report`; its path in
    ``report.report_path``).

    Resumable and idempotent (module docstring). Never raises for a failed partition:
    failures are in ``report.failed`` with their reasons and in ``runs``.
    ``on_plan(plan)`` is called once before the partitions start (e.g. to size a bar).
    """
    if max_workers < 1:
        raise ValueError(f"max_workers must be >= 1, got {max_workers}")
    t0 = time.perf_counter()
    plan = plan_backfill(sources, data=data, start=start, end=end, force=force, sanity=sanity)
    if on_plan is not None:
        on_plan(plan)
    report = BackfillReport(outcomes=plan.settled())
    for outcome in report.outcomes:
        if progress is not None:
            progress(outcome)
    report.outcomes += run_partitions(
        plan.todo,
        data=data,
        max_workers=max_workers,
        retries=retries,
        retry_delay_s=retry_delay_s,
        force=force,
        progress=progress,
        sanity=sanity,
    )
    record_failures(data, report.outcomes)
    report.wall_s = time.perf_counter() - t0
    report.notes = incoming_notes(sources)
    if write_report:
        try:  # optional: a report that cannot be written is a finding, not a failure
            from pipelines.reports import write_fleet_report

            report.report_path = write_fleet_report(
                data,
                kind="backfill",
                outcomes=report.outcomes,
                sources=sources,
                sanity=sanity,
                range_text=f"{start} .. {end}",
            ).path
        except Exception as exc:
            report.notes.append(report_failed(data, report.outcomes, exc))
    return report


# ----------------------------------------------------------------------- idempotence

#: What :func:`fingerprint` compares: warehouse marts and lake results, and the columns
#: left out (run ids and wall-clock stamps differ between equal runs by design; ingest
#: accounting differs after a crash mid-file although the landed rows are the same).
FINGERPRINT_TABLES: dict[str, tuple[str, ...]] = {
    "position_summary": ("run_id",),
    "trip_summary": ("run_id",),
    "alarms": ("run_id",),
    "sanity_checks": ("run_id",),
    "quarantine": (),
}
FINGERPRINT_LAKE: dict[str, tuple[str, ...]] = {"field_samples": (), "rope_tensions": ()}


def fingerprint(data: DataRoot) -> dict[str, tuple[int, int]]:
    """(rows, order-independent checksum) per mart and lake result table.

    Two data roots with equal fingerprints hold the same rows (run ids aside); re-running
    a night or a backfill range must leave the fingerprint unchanged. Also
    ``runs_per_day`` (rows, distinct (site, hoist, day)) of succeeded day runs and
    ``manifest`` (rows, checksum of source_sha256 and status).
    """
    out: dict[str, tuple[int, int]] = {}
    con = open_reader(data)
    try:
        for table, skip in FINGERPRINT_TABLES.items():
            columns = [c for c in TABLES[table].names if c not in skip]
            out[table] = _checksum(con, table, columns, table)
        out["manifest"] = _checksum(
            con, "manifest", ["source_sha256", "status", "rows_read"], "manifest"
        )
        ((rows, days),) = con.sql(
            "SELECT count(*), count(DISTINCT (site, hoist, period_start_utc)) FROM runs "
            "WHERE status = 'succeeded' AND period_end_utc - period_start_utc = INTERVAL 1 DAY"
        ).fetchall()
        out["runs_per_day"] = (int(rows), int(days))
        for table, skip in FINGERPRINT_LAKE.items():
            files = sorted(data.table_dir(table).glob("site=*/hoist=*/date=*/*.parquet"))
            if not files:
                out[table] = (0, 0)
                continue
            columns = [c for c in TABLES[table].names if c not in skip]
            listed = ", ".join(f"'{f}'" for f in files)
            out[table] = _checksum(
                con, f"read_parquet([{listed}], hive_partitioning = false)", columns, table
            )
    finally:
        con.close()
    return out


def _checksum(
    con: duckdb.DuckDBPyConnection, relation: str, columns: Sequence[str], table: str
) -> tuple[int, int]:
    """Row count and order-independent hash sum; doubles hashed as float32, so that the
    last-bit noise of multi-threaded float sums (~1e-16 relative) is not a difference."""
    schema = TABLES[table]
    quoted = ", ".join(
        f'CAST("{c}" AS FLOAT)' if schema.field(c).type == pa.float64() else f'"{c}"'
        for c in columns
    )
    ((rows, total),) = con.sql(
        f"SELECT count(*), coalesce(sum(hash({quoted})::HUGEINT) % 18446744073709551557, 0) "
        f"FROM {relation}"
    ).fetchall()
    return int(rows), int(total)
