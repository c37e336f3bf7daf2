"""Where ropeload keeps its data, and how the DuckDB warehouse is opened.

Data root layout (``--data DIR``, ``$ROPELOAD_DATA``, default ``./ropeload-data``)::

    <data>/lake/<table>/site=<site>/hoist=<hoist>/date=<YYYY-MM-DD>/part-*.parquet
    <data>/reports/...               report figures, discovery JSON
    <data>/warehouse.duckdb          the published warehouse (readers open this)
    <data>/.warehouse.lock           writers serialise on this (flock)

Nothing derived from input data becomes a path outside the data root: site, hoist
and rig names are safe names (:mod:`schemas.names`, checked where they enter), and
every path built from data comes from :meth:`DataRoot.partition_dir` or
:meth:`DataRoot.under`, which check the names again and refuse a result that
resolves (symlinks followed) outside its fixed folder (:meth:`DataRoot.inside`).

Readers never wait for writers (issue 6, DuckDB locking in stack.md): a writer copies
the published file to ``warehouse.duckdb.next``, lands into the copy, checkpoints it
and publishes it with an atomic ``os.replace``. A reader that opened the old file keeps
reading that snapshot (POSIX keeps the unlinked inode alive); a reader that opens after
the replace sees the whole new landing. Nobody ever sees half a landing, and a writer
that dies leaves the published file untouched.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import fcntl
import os
import re
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import duckdb

from schemas.names import PathEscapeError, join_inside, safe_name

__all__ = ["DATA_ENV", "DEFAULT_DATA", "DataRoot", "open_reader", "open_writer"]

DATA_ENV = "ROPELOAD_DATA"
DEFAULT_DATA = Path("ropeload-data")
_ISO_DAY = re.compile(r"\d{4}-\d{2}-\d{2}")


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

    def inside(self, path: str | os.PathLike[str]) -> Path:
        """``path`` if it resolves (symlinks followed) to the data root or below it.

        Raises :class:`schemas.names.PathEscapeError` otherwise. Returns ``path``
        unchanged (as a :class:`Path`).
        """
        path = Path(path)
        real_root, real = self.path.resolve(), path.resolve()
        if real != real_root and not real.is_relative_to(real_root):
            raise PathEscapeError(f"{path} resolves to {real}, outside the data root {real_root}")
        return path

    def under(self, folder: str, *parts: str) -> Path:
        """``<data>/<folder>/<parts...>``, each part one plain path component.

        ``folder`` is a fixed folder of the layout (``reports``, ``incoming``); it may
        be a symlink (e.g. to another disk), but what is named below it from data must
        stay inside it (:func:`schemas.names.join_inside`: raises
        :class:`~schemas.names.UnsafeNameError` for a part like ``..`` or ``a/b``,
        :class:`~schemas.names.PathEscapeError` for an escape through a symlink).
        """
        safe_name(folder, key="folder", source=f"data root {self.path}")
        return join_inside(self.path / folder, *parts, source=f"data root folder {folder!r}")

    def partition_dir(
        self, table: str, *, site: str, hoist: str, date: dt.date | str | None = None
    ) -> Path:
        """``<data>/lake/<table>/site=<site>/hoist=<hoist>[/date=<YYYY-MM-DD>]``.

        ``table``, ``site`` and ``hoist`` must be safe names
        (:func:`schemas.names.safe_name`, :class:`~schemas.names.UnsafeNameError`
        otherwise), ``date`` a date or an ISO ``YYYY-MM-DD`` string; the result must
        resolve inside the table's folder (:class:`~schemas.names.PathEscapeError`).
        The lake and table folders may be symlinks; partitions below may not leave them.
        """
        source = f"lake table {table!r}"
        safe_name(table, key="table", source="lake")
        safe_name(site, key="site", source=source)
        safe_name(hoist, key="hoist", source=source)
        parts = [f"site={site}", f"hoist={hoist}"]
        if date is not None:
            day = date.isoformat() if isinstance(date, dt.date) else date
            if not (isinstance(day, str) and _ISO_DAY.fullmatch(day)):
                raise ValueError(f"{source}: date {date!r} is not YYYY-MM-DD")
            parts.append(f"date={day}")
        return join_inside(self.table_dir(table), *parts, source=source)


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
