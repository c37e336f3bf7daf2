"""Where ropeload keeps its data, and how the DuckDB warehouse is opened.

Data root layout (``--data DIR``, ``$ROPELOAD_DATA``, default ``./ropeload-data``)::

    <data>/lake/<table>/site=<site>/hoist=<hoist>/date=<YYYY-MM-DD>/part-*.parquet
    <data>/warehouse.duckdb          the published warehouse (readers open this)
    <data>/.warehouse.lock           writers serialise on this (flock)

Readers never wait for writers (issue 6, DuckDB locking in stack.md): a writer copies
the published file to ``warehouse.duckdb.next``, lands into the copy, checkpoints it
and publishes it with an atomic ``os.replace``. A reader that opened the old file keeps
reading that snapshot (POSIX keeps the unlinked inode alive); a reader that opens after
the replace sees the whole new landing. Nobody ever sees half a landing, and a writer
that dies leaves the published file untouched.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import duckdb

__all__ = ["DATA_ENV", "DEFAULT_DATA", "DataRoot", "open_reader", "open_writer"]

DATA_ENV = "ROPELOAD_DATA"
DEFAULT_DATA = Path("ropeload-data")


@dataclass(frozen=True)
class DataRoot:
    """Paths under one data root."""

    path: Path

    @classmethod
    def resolve(cls, data: str | os.PathLike[str] | None = None) -> DataRoot:
        """``data`` if given, else ``$ROPELOAD_DATA``, else ``./ropeload-data``."""
        chosen = data if data is not None else os.environ.get(DATA_ENV) or DEFAULT_DATA
        return cls(Path(chosen).expanduser().absolute())

    @property
    def lake(self) -> Path:
        return self.path / "lake"

    def table_dir(self, table: str) -> Path:
        return self.lake / table

    @property
    def warehouse(self) -> Path:
        return self.path / "warehouse.duckdb"

    @property
    def lock_file(self) -> Path:
        return self.path / ".warehouse.lock"


@contextlib.contextmanager
def open_writer(root: DataRoot) -> Iterator[duckdb.DuckDBPyConnection]:
    """Open the warehouse for writing; publish atomically when the block succeeds.

    Writers are serialised by an exclusive ``flock``; migrations are applied first, so
    every writer sees the current schema. The views (:mod:`warehouse.views`) are
    refreshed on the way in and again before publishing, so they point at this data
    root and at lake tables landed in the block. On an exception nothing is published.
    """
    from warehouse.migrate import apply_migrations  # here: migrate imports store's types
    from warehouse.views import refresh_views

    root.path.mkdir(parents=True, exist_ok=True)
    with root.lock_file.open("a+") as lock:
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX)
        try:
            staging = root.warehouse.with_name(root.warehouse.name + ".next")
            staging.unlink(missing_ok=True)
            Path(str(staging) + ".wal").unlink(missing_ok=True)
            if root.warehouse.exists():
                shutil.copyfile(root.warehouse, staging)
            con = duckdb.connect(str(staging))
            try:
                apply_migrations(con)
                refresh_views(con, root)  # usable inside the block ...
                yield con
                refresh_views(con, root)  # ... and following lake tables landed in it
                con.execute("CHECKPOINT")
            except BaseException:
                con.close()
                staging.unlink(missing_ok=True)
                raise
            con.close()
            with staging.open("rb") as handle:
                os.fsync(handle.fileno())
            staging.replace(root.warehouse)
            directory = os.open(root.path, os.O_RDONLY)
            try:
                os.fsync(directory)
            finally:
                os.close(directory)
        finally:
            fcntl.flock(lock.fileno(), fcntl.LOCK_UN)


def open_reader(root: DataRoot) -> duckdb.DuckDBPyConnection:
    """Open the published warehouse read-only (a consistent snapshot).

    Raises FileNotFoundError with the path when nothing has been landed yet.
    """
    if not root.warehouse.exists():
        raise FileNotFoundError(
            f"no warehouse at {root.warehouse}: run 'ropeload ingest' or 'ropeload demo' first"
        )
    return duckdb.connect(str(root.warehouse), read_only=True)
