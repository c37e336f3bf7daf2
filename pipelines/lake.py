"""Reading the Parquet lake: one hoist's samples over a period, lazily.

The lake is Hive-partitioned ``site=/hoist=/date=`` (UTC date), so a period read prunes
to the partitions it needs before any file is opened.
"""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path

import polars as pl

from schemas.names import escape_error, escaping_paths
from schemas.tables import TABLES, polars_schema
from warehouse.store import DataRoot

__all__ = ["in_time_order", "lake_partitions", "scan_lake"]


def as_utc(value: dt.datetime) -> dt.datetime:
    """``value`` in UTC; a naive time is taken as UTC."""
    return value.replace(tzinfo=dt.UTC) if value.tzinfo is None else value.astimezone(dt.UTC)


def scan_lake(
    data: DataRoot,
    table: str,
    *,
    site: str,
    hoist: str,
    start: dt.datetime | None = None,
    end: dt.datetime | None = None,
    sort: bool = True,
) -> pl.LazyFrame:
    """Lazy scan of ``table`` for one site and hoist, ``start <= time_utc < end``.

    Sorted by time unless ``sort`` is False (for aggregates that do not need the order:
    a sort makes polars read every selected column of the period at once).

    Returns an empty frame with the table's schema when nothing is landed. Naive
    datetimes are taken as UTC. ``site`` and ``hoist`` must be safe names
    (:meth:`warehouse.store.DataRoot.partition_dir`; UnsafeNameError otherwise).
    """
    schema = TABLES[table]
    root = data.partition_dir(table, site=site, hoist=hoist)
    first = as_utc(start).date().isoformat() if start is not None else None
    # the end is exclusive: a period ending at midnight reads nothing of the next day
    last = None if end is None else (as_utc(end) - dt.timedelta(microseconds=1)).date().isoformat()
    files = [
        file for day in _date_folders(root, first, last) for file in sorted(day.glob("*.parquet"))
    ]
    if not files:
        return pl.LazyFrame(schema=polars_schema(schema))
    escaped = escaping_paths(data.table_dir(table), files)
    if escaped:  # a link planted in the lake (the writers refuse to follow one)
        raise escape_error(f"lake table {table!r}", escaped)
    frame = pl.scan_parquet(files, hive_partitioning=False)
    if start is not None:
        frame = frame.filter(pl.col("time_utc") >= as_utc(start))
    if end is not None:
        frame = frame.filter(pl.col("time_utc") < as_utc(end))
    return frame.sort("time_utc") if sort else frame


def _date_folders(root: Path, first: str | None, last: str | None) -> list[Path]:
    """``root``'s ``date=`` folders from ``first`` to ``last`` (ISO days, inclusive;
    None: no bound), in name order: the days' names are read, only their files listed
    (a year of hourly files is ~9,000 a hoist, read for every block of a run)."""
    try:
        entries = list(os.scandir(root))
    except (FileNotFoundError, NotADirectoryError):
        return []
    days = [
        entry
        for entry in entries
        if entry.name.startswith("date=")
        and (first is None or entry.name.removeprefix("date=") >= first)
        and (last is None or entry.name.removeprefix("date=") <= last)
        and entry.is_dir()
    ]
    return [Path(entry.path) for entry in sorted(days, key=lambda entry: entry.name)]


def in_time_order(frame: pl.LazyFrame) -> pl.DataFrame:
    """``frame`` collected in time order (``time_utc``), rows of one time in the order read.

    Rows already in order -- a hoist's files as ingest lands them, read in their names'
    order -- are taken as they are: a sort would gather every column again (a 24 h day of
    100 Hz read block by block three times in a run: ~3 s of CPU and a third of its page
    faults). Else a stable sort. :func:`scan_lake`'s ``sort=True`` is the lazy form (it
    may order rows of one time either way).
    """
    rows = frame.collect()
    if rows["time_utc"].is_sorted():
        # flagged sorted, as a sort leaves it (a filter on time then slices, not copies),
        # and one array per column (a read holds one per row group)
        return rows.rechunk().with_columns(pl.col("time_utc").set_sorted())
    return rows.sort("time_utc", maintain_order=True)


def lake_partitions(data: DataRoot, table: str) -> pl.DataFrame:
    """All (site, hoist, date) partitions of ``table`` with their file counts."""
    rows = []
    for path in sorted(data.table_dir(table).glob("site=*/hoist=*/date=*")):
        rows.append(
            {
                "site": path.parent.parent.name.removeprefix("site="),
                "hoist": path.parent.name.removeprefix("hoist="),
                "date": path.name.removeprefix("date="),
                "files": len(list(path.glob("*.parquet"))),
            }
        )
    return pl.DataFrame(
        rows, schema={"site": pl.String, "hoist": pl.String, "date": pl.String, "files": pl.Int64}
    )
