"""Landing result frames in the warehouse, idempotently.

Contents
--------
:class:`RunRecord`, :func:`land_run`
    The lineage root: one ``runs`` row per run (upsert by ``run_id``).
:func:`land_results`
    A run's marts in one go: ``position_summary``, ``trip_summary``, ``alarms``,
    ``sanity_checks``.
:func:`land_friction_parameter_sets`, :func:`land_discovery_findings`
    Calibration and discovery results.
:func:`land_rope_tensions`, :class:`RopeTensionStage`
    The compensated samples, as Parquet in the lake (one file per UTC hour), staged
    block by block and published at landing.
:func:`insert_frame`
    The shared step: conform a frame to its Arrow schema and ``INSERT ... BY NAME``.

Idempotence. Landing the same run again, or another run over the same period, replaces
rows, never duplicates them. For each mart passed to :func:`land_results` the rows
deleted before the insert are those of the same ``run_id`` and those of the same site and
hoist whose time falls in the run's period (``period_start_utc <= t < period_end_utc``;
t is ``time_start_utc``, alarms' ``start_utc``); alarms also by ``alarm_id``, and
sanity checks by the (run, trip) of the trip rows replaced. What crosses the period's
edges is seen in part: the run's row an earlier row holds whole, begun before the period
or running past its end, is not landed and the earlier row stays (:func:`_covered`).
A mart passed as an empty
frame clears the period (a re-run that finds no alarms removes the old ones); a mart
left out (``None``) is not touched.

All functions take the connection of :func:`warehouse.store.open_writer`, so a landing
is published whole or not at all, and readers keep their snapshot meanwhile.
"""

from __future__ import annotations

import datetime as dt
import os
import shutil
import uuid
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import duckdb
import polars as pl
import pyarrow as pa

from schemas.tables import ROPE_TENSIONS, RUNS, TABLES, conform
from warehouse.parquet_files import write_parquet_atomic, writer_alive
from warehouse.store import DataRoot

__all__ = [
    "RopeTensionStage",
    "RunRecord",
    "drop_orphan_sanity_checks",
    "insert_frame",
    "land_discovery_findings",
    "land_friction_parameter_sets",
    "land_results",
    "land_rope_tensions",
    "land_run",
]


@dataclass(frozen=True)
class RunRecord:
    """One ``runs`` row (schema RUNS); ``inputs`` are the source_sha256 the run read;
    ``timezone`` the hoist's IANA time zone for a run over one hoist."""

    run_id: str
    command: str
    code_version: str
    started_at_utc: dt.datetime
    status: str = "succeeded"
    hoist_sha256: str | None = None
    parameter_set: str | None = None
    site: str | None = None
    hoist: str | None = None
    period_start_utc: dt.datetime | None = None
    period_end_utc: dt.datetime | None = None
    inputs: Sequence[str] = field(default_factory=tuple)
    finished_at_utc: dt.datetime | None = None
    message: str | None = None
    timezone: str | None = None

    def to_frame(self) -> pl.DataFrame:
        row = asdict(self)
        row["inputs"] = list(self.inputs)
        return conform(pl.DataFrame([row], schema_overrides={"inputs": pl.List(pl.String)}), RUNS)


def insert_frame(con: duckdb.DuckDBPyConnection, table: str, frame: pl.DataFrame | pa.Table) -> int:
    """Insert ``frame`` into ``table`` after casting it to the table's Arrow schema."""
    schema = TABLES[table]
    if isinstance(frame, pl.DataFrame):
        frame = conform(frame, schema).to_arrow()
    arrow = frame.select(schema.names).cast(schema)
    if arrow.num_rows == 0:
        return 0
    name = f"_landing_{uuid.uuid4().hex}"
    con.register(name, arrow)
    try:
        con.execute(f"INSERT INTO {table} BY NAME SELECT * FROM {name}")
    finally:
        con.unregister(name)
    return arrow.num_rows


def land_run(con: duckdb.DuckDBPyConnection, run: RunRecord) -> None:
    """Insert or replace the ``runs`` row of ``run.run_id``."""
    con.execute("DELETE FROM runs WHERE run_id = ?", [run.run_id])
    insert_frame(con, "runs", run.to_frame())


def _period_clause(run: RunRecord, time_column: str) -> tuple[str, list[object]]:
    """SQL predicate (and parameters) for rows this run replaces."""
    clause, params = "run_id = ?", [run.run_id]
    if run.period_start_utc is not None and run.period_end_utc is not None:
        clause += f" OR (site = ? AND hoist = ? AND {time_column} >= ? AND {time_column} < ?)"
        params += [run.site, run.hoist, run.period_start_utc, run.period_end_utc]
    return clause, params


def _own(frame: pl.DataFrame, run: RunRecord, table: str) -> pl.DataFrame:
    """Check the frame belongs to ``run`` (run_id; site/hoist when the run names them)."""
    if frame.height and set(frame["run_id"].unique().to_list()) != {run.run_id}:
        raise ValueError(f"{table}: rows must all have run_id {run.run_id!r}")
    for key in ("site", "hoist"):
        expected = getattr(run, key)
        if frame.height and expected is not None and set(frame[key].unique()) != {expected}:
            raise ValueError(f"{table}: rows must all have {key} {expected!r}")
    return frame


def land_results(
    con: duckdb.DuckDBPyConnection,
    run: RunRecord,
    *,
    position_summary: pl.DataFrame | None = None,
    trip_summary: pl.DataFrame | None = None,
    alarms: pl.DataFrame | None = None,
    sanity_checks: pl.DataFrame | None = None,
) -> dict[str, int]:
    """Land a run and its marts, replacing what the run (or its period) landed before;
    with ``trip_summary``, the sanity checks of trips no run holds any more go too
    (:func:`drop_orphan_sanity_checks`).

    Returns rows inserted per table. Raises ValueError when a frame's ``run_id`` (or
    site / hoist) is not the run's.
    """
    inserted: dict[str, int] = {}
    con.execute("BEGIN TRANSACTION")
    try:
        land_run(con, run)
        # trips first: a trip an earlier run's row holds keeps that run's visits
        held_trips: list[tuple[int, str, int]] = []
        for table, frame, time_column in (
            ("trip_summary", trip_summary, "time_start_utc"),
            ("position_summary", position_summary, "time_start_utc"),
            ("alarms", alarms, "start_utc"),
        ):
            if frame is None:
                continue
            _own(frame, run, table)
            clause, params = _period_clause(run, time_column)
            if table == "alarms" and frame.height:
                ids = frame["alarm_id"].to_list()
                clause += " OR list_contains(?, alarm_id)"
                params.append(ids)
            held, holders, kept = _covered(con, run, table, frame)
            clause = f"({clause}) AND NOT list_contains(?, o.rowid)"
            params.append(kept)
            if table == "trip_summary":
                held_trips = holders
            if table == "position_summary" and held_trips:  # the holders' visits stay
                clause += (
                    " AND NOT coalesce((o.run_id, o.trip_id) IN "
                    "(SELECT unnest(?::VARCHAR[]), unnest(?::BIGINT[])), false)"
                )
                params += [[r for _, r, _ in held_trips], [t for _, _, t in held_trips]]
                trip_ids = [n for n, _, _ in held_trips]
                held = held | frame["trip_id"].is_in(trip_ids).fill_null(False)
            con.execute(f"DELETE FROM {table} o WHERE {clause}", params)
            inserted[table] = insert_frame(con, table, frame.filter(~held))
        if sanity_checks is not None:
            # the checks of the trips this landing replaced went with them (below)
            _own(sanity_checks, run, "sanity_checks")
            delete, params = "run_id = ?", [run.run_id]
            if trip_summary is None:  # the checks of the period's trips are replaced
                clause, period = _period_clause(run, "time_start_utc")
                delete += (
                    " OR (run_id, trip_id) IN "
                    f"(SELECT run_id, trip_id FROM trip_summary WHERE {clause})"
                )
                params += period
            con.execute(f"DELETE FROM sanity_checks WHERE {delete}", params)
            inserted["sanity_checks"] = insert_frame(con, "sanity_checks", sanity_checks)
        if trip_summary is not None and run.site is not None and run.hoist is not None:
            drop_orphan_sanity_checks(con, site=run.site, hoist=run.hoist)
        con.execute("COMMIT")
    except BaseException:
        con.execute("ROLLBACK")
        raise
    return inserted


#: Per mart: its (start, end) columns and the columns whose values must agree for an
#: earlier row to be the same event, trip or visit as a later run's (:func:`_covered`).
_COVERED_KEYS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "alarms": ("start_utc", "end_utc", ("rule", "rope")),
    "trip_summary": ("time_start_utc", "time_end_utc", ()),
    "position_summary": ("time_start_utc", "time_end_utc", ("position",)),
}


def _covered(
    con: duckdb.DuckDBPyConnection, run: RunRecord, table: str, frame: pl.DataFrame
) -> tuple[pl.Series, list[tuple[int, str, int]], list[int]]:
    """The run's rows of ``table`` (an alarm, a trip, a position visit) an earlier run's
    row of the same hoist (and rule and rope, or position) holds whole (starts no later,
    ends no earlier), where that row saw more of it than this run can:

    - begun before this run's period: an event, trip or stop across the period's start,
      seen by this run from the start on (a re-run of part of a day counted it twice: 8
      trip rows for 7 trips after a re-run from inside the third). An earlier row that
      ends before this run's does not hold it: a run of the next period, whose part of a
      stop across the periods' edge stays beside the earlier period's part;
    - begun in the period and running to its end or past it: one across the period's
      end, seen by this run only up to the end. That earlier row is kept, not replaced
      (a re-run ending inside a trip had replaced the whole trip by its first part, and
      the rest of it was lost), unless a row of this run's that it does not hold
      overlaps it; it is kept too where this run found no row of it (an alarm whose
      first part is shorter than its rule's least duration).

    Returns the mask of ``frame``'s rows so held (not landed); for trips, per held trip
    its ``trip_id`` and the holder's ``run_id`` and ``trip_id`` (the trip's visits are
    the holder's too: the holder's stay, the run's go); and the ``rowid`` of the earlier
    rows begun in the period that are kept. Read before the period's rows are deleted.
    """
    held = pl.Series("held", [False] * frame.height, dtype=pl.Boolean)
    if run.period_start_utc is None or run.period_end_utc is None:
        return held, [], []
    start, end, same = _COVERED_KEYS[table]
    trip = table == "trip_summary"
    columns = [start, end, "site", "hoist", *same, *(["trip_id"] if trip else [])]
    name = f"_covered_{uuid.uuid4().hex}"
    con.register(name, frame.select(columns).with_row_index("_row").to_arrow())
    try:

        def agree(a: str, b: str) -> str:
            return "".join(f" AND {a}.{c} IS NOT DISTINCT FROM {b}.{c}" for c in same)

        # an earlier row across the period's end, no row of this run's beside it
        kept = (
            f"o.run_id <> ? AND o.site = ? AND o.hoist = ? AND o.{start} >= ? "
            f"AND o.{start} < ? AND o.{end} >= ? AND NOT EXISTS (SELECT 1 FROM {name} m "
            f"WHERE m.{start} < o.{end} AND o.{start} < m.{end}{agree('m', 'o')} "
            f"AND NOT (o.{start} <= m.{start} AND o.{end} >= m.{end}))"
        )
        period = [run.period_start_utc, run.period_end_utc, run.period_end_utc]
        found = con.execute(
            f"SELECT o.rowid FROM {table} o WHERE {kept}",
            [run.run_id, run.site, run.hoist, *period],
        ).fetchall()
        rowids = [int(r) for (r,) in found]
        holder = ", n.trip_id, o.run_id, o.trip_id" if trip else ""
        rows = con.execute(
            f"SELECT DISTINCT n._row{holder} FROM {name} n JOIN {table} o ON o.run_id <> ? "
            f"AND o.site = n.site AND o.hoist = n.hoist{agree('o', 'n')} "
            f"AND o.{start} <= n.{start} AND o.{end} >= n.{end} "
            f"AND (o.{start} < ? OR list_contains(?, o.rowid))",
            [run.run_id, run.period_start_utc, rowids],
        ).fetchall()
    finally:
        con.unregister(name)
    if rows:
        held = held.scatter(sorted({int(r[0]) for r in rows}), True)
    holders = sorted({(int(n), str(r), int(t)) for _, n, r, t in rows}) if trip else []
    return held, holders, rowids


def drop_orphan_sanity_checks(con: duckdb.DuckDBPyConnection, *, site: str, hoist: str) -> None:
    """Drop the hoist's sanity checks whose trip has no ``trip_summary`` row: a later run
    over the period (with or without a check of its own) took its trips over, and a
    verdict on a trip no run holds would still count in the audit."""
    con.execute(
        "DELETE FROM sanity_checks c WHERE c.site = ? AND c.hoist = ? AND NOT EXISTS "
        "(SELECT 1 FROM trip_summary t WHERE t.run_id = c.run_id AND t.trip_id = c.trip_id)",
        [site, hoist],
    )


def land_friction_parameter_sets(con: duckdb.DuckDBPyConnection, frame: pl.DataFrame) -> int:
    """Insert or replace friction parameter sets by ``parameter_set``."""
    names = frame["parameter_set"].to_list()
    con.execute(
        "DELETE FROM friction_parameter_sets WHERE list_contains(?, parameter_set)", [names]
    )
    return insert_frame(con, "friction_parameter_sets", frame)


def land_discovery_findings(
    con: duckdb.DuckDBPyConnection, run: RunRecord, frame: pl.DataFrame
) -> int:
    """Replace the run's findings, and those of the same site/hoist and period."""
    _own(frame, run, "discovery_findings")
    clause, params = "run_id = ?", [run.run_id]
    if run.period_start_utc is not None and run.period_end_utc is not None:
        clause += " OR (site = ? AND hoist = ? AND period_start_utc = ? AND period_end_utc = ?)"
        params += [run.site, run.hoist, run.period_start_utc, run.period_end_utc]
    con.execute(f"DELETE FROM discovery_findings WHERE {clause}", params)
    return insert_frame(con, "discovery_findings", frame)


def land_rope_tensions(
    root: DataRoot,
    frame: pl.DataFrame,
    *,
    site: str,
    hoist: str,
    period_start_utc: dt.datetime,
    period_end_utc: dt.datetime,
) -> list[Path]:
    """Write compensated samples to the lake in one go (:class:`RopeTensionStage`).

    Call inside :func:`warehouse.store.open_writer` (writers are serialised there).
    Returns the files written or removed.
    """
    stage = RopeTensionStage(root, site=site, hoist=hoist)
    try:
        stage.add(frame)
        return stage.publish(period_start_utc, period_end_utc)
    finally:
        stage.discard()


def _hour_file(root: DataRoot, site: str, hoist: str, hour: dt.datetime) -> Path:
    directory = root.partition_dir("rope_tensions", site=site, hoist=hoist, date=hour.date())
    return directory / f"hour-{hour:%H}.parquet"


def _remove_stale_stages(table: Path) -> None:
    """Remove the staging folders of runs that died (their pid is gone or reused)."""
    for folder in table.glob(".staging-*"):
        try:
            pid = int(folder.name.split("-")[1])
            alive = writer_alive(pid, folder.stat().st_mtime)
        except (ValueError, IndexError, OSError):
            continue  # not ours, or gone meanwhile
        if not alive:
            shutil.rmtree(folder, ignore_errors=True)


def _fsync_folder(folder: Path) -> None:
    handle = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(handle)
    finally:
        os.close(handle)


class RopeTensionStage:
    """A run's compensated samples, staged block by block and published at landing.

    ``<lake>/rope_tensions/site=/hoist=/date=/hour-HH.parquet``: one file per UTC hour,
    so a re-run of part of a day rewrites the hours it touches (at most two partly), not
    the day (issue 16). :meth:`add` writes a block's rows under a hidden staging folder
    of the table (readers' ``*.parquet`` globs of the partitions never see it);
    :meth:`publish` (inside :func:`warehouse.store.open_writer`) replaces, hour by
    hour, the rows of ``period_start <= t < period_end`` and keeps the rest of each hour,
    every file written atomically (:func:`warehouse.parquet_files.write_parquet_atomic`),
    so a reader sees an hour old or new, never half. A day landed before hour files (one
    ``data.parquet``) is split into hour files the first time a run touches it. Memory:
    one hour of rows at a time.
    """

    def __init__(self, root: DataRoot, *, site: str, hoist: str) -> None:
        self.root, self.site, self.hoist = root, site, hoist
        # partition_dir checks the names: nothing from the data leaves the lake
        table = root.partition_dir("rope_tensions", site=site, hoist=hoist).parent.parent
        _remove_stale_stages(table)
        self.folder = table / f".staging-{os.getpid()}-{uuid.uuid4().hex}"
        self.parts: dict[dt.datetime, list[Path]] = {}

    def add(self, frame: pl.DataFrame) -> None:
        """Stage a block's ROPE_TENSIONS rows (any order of blocks; rows sorted by time)."""
        if frame.height == 0:
            return
        frame = conform(frame, ROPE_TENSIONS)
        hours = frame["time_utc"].dt.truncate("1h")
        self.folder.mkdir(parents=True, exist_ok=True)
        for (hour,), part in (
            frame.with_columns(_hour=hours)
            .partition_by("_hour", as_dict=True, maintain_order=True)
            .items()
        ):
            paths = self.parts.setdefault(hour, [])
            path = self.folder / f"{hour:%Y%m%dT%H}-{len(paths):04d}.parquet"
            # the lake's own format: an hour the run covers whole is then just renamed
            write_parquet_atomic(part.drop("_hour"), path, ROPE_TENSIONS)
            paths.append(path)

    def files(self) -> list[Path]:
        """The staged files, in time order."""
        return [path for hour in sorted(self.parts) for path in self.parts[hour]]

    def publish(self, period_start_utc: dt.datetime, period_end_utc: dt.datetime) -> list[Path]:
        """Replace the period's rows in the lake by the staged ones; returns the files
        written or removed."""
        start = period_start_utc.astimezone(dt.UTC)
        end = period_end_utc.astimezone(dt.UTC)
        hour = start.replace(minute=0, second=0, microsecond=0)
        inside = (pl.col("time_utc") >= start) & (pl.col("time_utc") < end)
        hours = []
        while hour < end:
            hours.append(hour)
            hour += dt.timedelta(hours=1)
        written = []
        # a day file of the earlier layout is split into hour files first, whole: from
        # then on an hour file is the only home of its rows (after a crash in between,
        # the hour files written supersede the day file's rows of their hour)
        for day in sorted({h.date() for h in hours}):
            written += self._retire_day_file(day)
        for hour in hours:
            whole = start <= hour and hour + dt.timedelta(hours=1) <= end
            written += self._replace_hour(
                hour, self.parts.get(hour, []), inside=inside, whole=whole
            )
        return written

    def _replace_hour(
        self, hour: dt.datetime, staged: list[Path], *, inside: pl.Expr, whole: bool
    ) -> list[Path]:
        """Replace the period's rows of one hour; ``whole``: the period covers the hour."""
        target = _hour_file(self.root, self.site, self.hoist, hour)
        if whole and len(staged) == 1:  # nothing of the old hour is kept: a rename
            target.parent.mkdir(parents=True, exist_ok=True)
            staged[0].replace(target)
            _fsync_folder(target.parent)
            return [target]
        old = [target] if target.exists() and not whole else []
        in_hour = (pl.col("time_utc") >= hour) & (pl.col("time_utc") < hour + dt.timedelta(hours=1))
        frames = [
            conform(pl.read_parquet(path, hive_partitioning=False).filter(in_hour & ~inside),
                    ROPE_TENSIONS)
            for path in old
        ]  # fmt: skip
        frames += [pl.read_parquet(path).filter(inside) for path in staged]
        new = pl.concat(frames) if frames else pl.DataFrame()
        if new.height == 0:
            if target.exists():
                target.unlink()
                return [target]
            return []
        write_parquet_atomic(new.sort("time_utc"), target, ROPE_TENSIONS)
        return [target]

    def _retire_day_file(self, day: dt.date) -> list[Path]:
        """Split a day's ``data.parquet`` (the layout before hour files) into hour files.

        Until the day file is removed a reader sees its rows twice (once per day)."""
        legacy = (
            self.root.partition_dir("rope_tensions", site=self.site, hoist=self.hoist, date=day)
            / "data.parquet"
        )
        if not legacy.exists():
            return []
        written = []
        midnight = dt.datetime.combine(day, dt.time(), dt.UTC)
        for k in range(24):
            hour = midnight + dt.timedelta(hours=k)
            target = _hour_file(self.root, self.site, self.hoist, hour)
            if target.exists():
                continue  # written before a crash: it holds the day file's rows of its hour
            in_hour = (pl.col("time_utc") >= hour) & (
                pl.col("time_utc") < hour + dt.timedelta(hours=1)
            )
            rows = pl.scan_parquet(legacy, hive_partitioning=False).filter(in_hour).collect()
            if rows.height:
                write_parquet_atomic(conform(rows, ROPE_TENSIONS), target, ROPE_TENSIONS)
                written.append(target)
        legacy.unlink()
        return [*written, legacy]

    def discard(self) -> None:
        """Remove the staging folder (after publishing, or when the run failed)."""
        shutil.rmtree(self.folder, ignore_errors=True)
        self.parts = {}
