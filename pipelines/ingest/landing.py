"""Landing samples in the Parquet lake: partitions, dedup against landed data, atomic parts.

Layout: ``<data>/lake/<table>/site=<site>/hoist=<hoist>/date=<YYYY-MM-DD>/part-*.parquet``
(UTC date), Arrow schema from :mod:`schemas.tables`, zstd (time and source line
delta-encoded), each part sorted by time.

Identity and dedup
    A sample is identified by ``(site, hoist, time_utc)``. Before landing, a batch is
    checked against itself (sorted by time, then source row: the first occurrence wins)
    and against the parts already in the partition whose time range overlaps the batch
    (Parquet row-group statistics prune the rest). A row equal in every value column to
    the landed one (null equals null) is an exact duplicate and is not landed again; a
    row with other values for a landed time is returned as a conflict for quarantine
    (``REASON_CONFLICT``). ``source_sha256``/``source_line`` are lineage, not values,
    but an equal row landed from the same file (``source_sha256``: an ingest of it
    killed after its parts and before its manifest row) is counted as landed by that
    file, not as a duplicate, so that the manifest says what the file put in the lake.

Atomic parts, no multi-file step
    A part is written to a hidden temporary file in the partition directory
    (``.part-*.tmp``, which the ``*.parquet`` glob of readers never matches), fsynced,
    and published with ``os.replace``; then the directory is fsynced. Small appends
    (a growing file picked up every few minutes) are merged into the partition's newest
    part while it is below ``SMALL_PART_ROWS``: the merged part (old rows + new rows)
    replaces the old one under the *same name*, again with one ``os.replace``. So every
    visible change is a single atomic rename: a reader (or a crash) sees the old part or
    the new one, never both, never half; no row is ever visible twice or lost. A
    leftover temporary file of a crashed writer is removed the next time that partition
    is landed (writers are serialised by the warehouse lock). Bigger batches become new
    parts of up to one batch each (``batch_bytes`` of the reader, ~0.8 M rows of a
    100 Hz log for the 64 MiB default), so a hoist-day is about a dozen parts.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq

from schemas.tables import TABLES
from warehouse.parquet_files import write_parquet_atomic
from warehouse.store import DataRoot

__all__ = ["MAX_PART_ROWS", "SMALL_PART_ROWS", "LakeTable", "Landed", "write_parquet_atomic"]

#: A newest part below this many rows takes the next small batch in (rewritten in place).
SMALL_PART_ROWS = 200_000
#: ... as long as the merged part stays at or below this many rows.
MAX_PART_ROWS = 2_000_000
_LINEAGE = ("time_utc", "source_sha256", "source_line")


@dataclass
class Landed:
    """Outcome of landing one batch: counts, and rows (by ``_row``) that conflict."""

    landed: int = 0
    duplicate: int = 0
    conflicts: list[int] = field(default_factory=list)


@dataclass(frozen=True)
class _Part:
    path: Path
    seq: int
    rows: int
    time_min_us: int | None
    time_max_us: int | None


class LakeTable:
    """One lake table of one data root; lands batches of samples with dedup."""

    def __init__(self, data: DataRoot, table: str) -> None:
        self.data, self.table = data, table
        self.root = data.table_dir(table)
        self.schema: pa.Schema = TABLES[table]
        self.values = [f.name for f in self.schema if f.name not in _LINEAGE]
        self._parts_cache: dict[Path, tuple[tuple[int, int], _Part]] = {}

    def land(self, samples: pl.DataFrame, *, site: str, hoist: str, source_sha256: str) -> Landed:
        """Land ``samples`` (table columns except ``source_sha256``, plus ``_row``)."""
        result = Landed()
        if samples.height == 0:
            return result
        frame = samples.with_columns(pl.lit(source_sha256).alias("source_sha256"))
        if not _sorted_by_time_and_row(frame):
            frame = frame.sort("time_utc", "_row")
        frame = self._drop_batch_duplicates(frame, result)
        for date, part in _by_date(frame):
            directory = self.data.partition_dir(self.table, site=site, hoist=hoist, date=date)
            part = self._drop_landed(directory, part, result)
            if part.height:
                self._write(directory, part, source_sha256)
                result.landed += part.height
        return result

    def landed_duplicates(self, rows: pl.DataFrame, *, site: str, hoist: str) -> list[int]:
        """The ``_row`` of those ``rows`` (the samples' columns, plus ``_row``) equal in
        every value column to a landed sample of the same time: rows a reader held back
        (a logger clock's step back, :attr:`.batch.Batch.held`) that are exact
        duplicates. Nothing is written."""
        if rows.height == 0:
            return []
        frame = rows.sort("time_utc", "_row")
        found: list[int] = []
        for date, part in _by_date(frame):
            directory = self.data.partition_dir(self.table, site=site, hoist=hoist, date=date)
            probe = Landed()
            kept = self._drop_landed(directory, part, probe)
            matched = part.join(kept.select("_row"), on="_row", how="anti")
            conflicts = set(probe.conflicts)
            found.extend(r for r in matched["_row"].to_list() if r not in conflicts)
        return found

    def _drop_batch_duplicates(self, frame: pl.DataFrame, result: Landed) -> pl.DataFrame:
        time = frame["time_utc"]
        repeated = (time == time.shift(1)).fill_null(False)
        if not repeated.any():
            return frame
        groups = frame.filter(pl.col("time_utc").is_duplicated())
        same = pl.all_horizontal(
            pl.col(c).eq_missing(pl.col(c).first().over("time_utc")) for c in self.values
        )
        later = groups.with_columns(same.alias("_same")).filter(
            pl.col("_row") != pl.col("_row").first().over("time_utc")
        )
        result.duplicate += int(later["_same"].sum())
        result.conflicts.extend(later.filter(~pl.col("_same"))["_row"].to_list())
        return frame.join(later.select("_row"), on="_row", how="anti", maintain_order="left")

    def _drop_landed(self, directory: Path, part: pl.DataFrame, result: Landed) -> pl.DataFrame:
        low = part["time_utc"].min()
        high = part["time_utc"].max()
        epoch = pl.col("time_utc").dt.epoch("us")
        low_us, high_us = part.select(epoch.min().alias("low"), epoch.max().alias("high")).row(0)
        overlapping = [
            p.path
            for p in self._parts(directory)
            if p.time_min_us is None
            or p.time_max_us is None
            or (p.time_max_us >= low_us and p.time_min_us <= high_us)
        ]
        if not overlapping:
            return part
        lines = "source_line" in self.schema.names and "source_line" in part.columns
        lineage = [pl.col("source_sha256").alias("_landed_sha")]
        lineage += [pl.col("source_line").alias("_landed_line")] if lines else []
        landed = (
            pl.scan_parquet(overlapping, hive_partitioning=False)
            .filter(pl.col("time_utc").is_between(low, high))
            .select("time_utc", *self.values, *lineage)
            .collect()
        )
        if landed.height == 0:
            return part
        matched = part.join(landed, on="time_utc", how="inner", suffix="__landed")
        if matched.height == 0:
            return part
        same = pl.all_horizontal(pl.col(c).eq_missing(pl.col(f"{c}__landed")) for c in self.values)
        # the same rows of the same file at the same line: landed by an attempt at this
        # file that ended (killed) before its manifest row was written; they are this
        # file's, not duplicates of another's (the manifest then counts what the file
        # landed). A row repeating an earlier line of the file is a duplicate still.
        own = (
            pl.col("_landed_sha") == pl.col("source_sha256")
            if "source_sha256" in part.columns
            else pl.lit(False)
        )
        if lines:
            own = own & pl.col("_landed_line").eq_missing(pl.col("source_line"))
        flags = matched.select("_row", same.alias("_same"), (same & own).alias("_own"))
        result.landed += int(flags["_own"].sum())
        result.duplicate += int((flags["_same"] & ~flags["_own"]).sum())
        result.conflicts.extend(flags.filter(~pl.col("_same"))["_row"].to_list())
        return part.join(flags.select("_row"), on="_row", how="anti", maintain_order="left")

    def _parts(self, directory: Path) -> list[_Part]:
        if not directory.is_dir():
            return []
        for stale in directory.glob(".part-*.tmp"):
            stale.unlink(missing_ok=True)
        parts = []
        for path in sorted(directory.glob("part-*.parquet")):
            stat = path.stat()
            key = (stat.st_mtime_ns, stat.st_size)
            cached = self._parts_cache.get(path)
            if cached is None or cached[0] != key:
                cached = (key, _read_part(path))
                self._parts_cache[path] = cached
            parts.append(cached[1])
        return parts

    def _write(self, directory: Path, rows: pl.DataFrame, source_sha256: str) -> None:
        parts = self._parts(directory)
        newest = max(parts, key=lambda p: p.seq) if parts else None
        columns = self.schema.names
        new = rows.select(columns)
        if (
            newest is not None
            and newest.rows < SMALL_PART_ROWS
            and newest.rows + new.height <= MAX_PART_ROWS
        ):
            merged = pl.concat([pl.read_parquet(newest.path, hive_partitioning=False), new])
            target = newest.path
        else:
            merged = new
            seq = newest.seq + 1 if newest is not None else 1
            token = hashlib.sha256(f"{source_sha256}/{directory.name}/{seq}".encode()).hexdigest()
            target = directory / f"part-{seq:05d}-{token[:12]}.parquet"
        if not merged["time_utc"].is_sorted():
            merged = merged.sort("time_utc", maintain_order=True)
        write_parquet_atomic(merged, target, self.schema)
        self._parts_cache.pop(target, None)


def _sorted_by_time_and_row(frame: pl.DataFrame) -> bool:
    """Whether ``frame`` is already in (time_utc, _row) order (a file read in order is)."""
    time = frame["time_utc"]
    if time.null_count() or not time.is_sorted():
        return False
    step = pl.col("time_utc").diff() != pl.duration(microseconds=0)
    return bool(frame.select((step | (pl.col("_row").diff() > 0)).all()).item())


def _by_date(frame: pl.DataFrame) -> list[tuple[str, pl.DataFrame]]:
    """Split a time-sorted frame by UTC date (no split work for the common one-day batch)."""
    first, last = frame["time_utc"][0], frame["time_utc"][-1]
    if first.date() == last.date():
        return [(first.date().isoformat(), frame)]
    dated = frame.with_columns(pl.col("time_utc").dt.strftime("%Y-%m-%d").alias("_date"))
    return [
        (date, part.drop("_date"))
        for (date,), part in dated.partition_by("_date", as_dict=True).items()
    ]


def _read_part(path: Path) -> _Part:
    meta = pq.read_metadata(path)
    seq = int(path.name.split("-")[1]) if path.name.count("-") >= 2 else 0
    lows, highs = [], []
    for i in range(meta.num_row_groups):
        stats = meta.row_group(i).column(0).statistics
        if stats is None or not stats.has_min_max:
            return _Part(path, seq, meta.num_rows, None, None)
        lows.append(stats.min_raw)
        highs.append(stats.max_raw)
    if not lows:
        return _Part(path, seq, meta.num_rows, None, None)
    return _Part(path, seq, meta.num_rows, min(lows), max(highs))
