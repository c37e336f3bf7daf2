"""Where ropeload keeps its data, and how the DuckDB warehouse is opened.

Data root layout (``--data DIR``, ``$ROPELOAD_DATA``, default ``./ropeload-data``)::

    <data>/lake/<table>/site=<site>/hoist=<hoist>/date=<YYYY-MM-DD>/part-*.parquet
    <data>/reports/...               report figures, discovery JSON
    <data>/warehouse.duckdb          the published warehouse (readers open this)
    <data>/.warehouse.lock           writers serialise on this (flock)
    <data>/.nightly.lock             one night at a time (flock, pipelines.nightly)
    <data>/state/nightly-pending.json  what a night planned and has not done

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

The file is written in the storage format of :data:`STORAGE_VERSION`, which DuckDB 1.4,
1.5 (the CLI from PyPI) and 2.0 all open; a file in a newer format is rewritten once by
the next writer.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import duckdb

from schemas.names import PathEscapeError, join_inside, printable, safe_name, undecodable

__all__ = [
    "DATA_ENV",
    "DEFAULT_DATA",
    "STORAGE_VERSION",
    "DataRoot",
    "data_root_problem",
    "open_reader",
    "open_writer",
    "storage_version",
    "write_text_atomic",
]

DATA_ENV = "ROPELOAD_DATA"
DEFAULT_DATA = Path("ropeload-data")

#: Storage format of ``warehouse.duckdb`` (``STORAGE_VERSION`` of DuckDB's ``ATTACH``).
#: DuckDB 2.0 writes format 69 by default, which no DuckDB 1.x opens: the CLI from PyPI
#: (``duckdb-cli`` 1.5) reads formats 64-68, DuckDB 1.4 (LTS) 64-67. ``v1.4.0`` (format 67)
#: is read by both and by DuckDB 2.0; nothing the warehouse stores needs a newer format,
#: and the demo warehouse is the same size in both (warehouse/README.md, "DuckDB CLI").
STORAGE_VERSION = "v1.4.0"
_ISO_DAY = re.compile(r"\d{4}-\d{2}-\d{2}")


def write_text_atomic(path: Path, text: str) -> Path:
    """Write ``text`` (UTF-8) as ``path``, whole or not at all: a temporary file of its
    own beside it, renamed into place (a reader never sees half a file, a crash leaves
    the old one). Returns ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as out:
            out.write(text)
        Path(name).replace(path)
    except BaseException:
        Path(name).unlink(missing_ok=True)
        raise
    return path


#: Characters DuckDB does not take literally in a file path: the lake's views read
#: ``<data>/lake/<table>/site=*/...`` as a file pattern (``* ? [ ]``; ``data[X]`` matches
#: ``dataX``, another data root), and it takes a backslash for a folder separator on
#: every system (the warehouse of a data root ``d<backslash>x`` was written as
#: ``d/x/warehouse.duckdb.next``). A data root whose path has one is refused
#: (:func:`data_root_problem`).
_PATTERN_CHARACTERS = {
    "*": "a file pattern",
    "?": "a file pattern",
    "[": "a file pattern",
    "]": "a file pattern",
    "\\": "a folder separator",
}


def data_root_problem(path: str | os.PathLike[str]) -> str | None:
    """Why DuckDB would not read ``path`` (a data root) as the folder it names, or None.

    >>> data_root_problem("/srv/ropeload") is None
    True
    >>> data_root_problem("/srv/rope[1]")
    "its path has '[', which DuckDB reads as a file pattern: use a path without * ? [ ] \\\\"
    """
    text = str(path)
    if undecodable(text) is not None:  # bytes of the name that are not UTF-8
        return "its path is not UTF-8 text, which DuckDB cannot open: rename it"
    for character, reading in _PATTERN_CHARACTERS.items():
        if character in text:
            return (
                f"its path has {character!r}, which DuckDB reads as {reading}: "
                "use a path without * ? [ ] \\"
            )
    return None


def _check_data_root(root: DataRoot) -> None:
    problem = data_root_problem(root.path)
    if problem is not None:
        raise ValueError(f"data root {printable(root.path)}: {problem}")


class OutputPathError(ValueError):
    """A user-named output file that would land among the data root's own files."""


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

    @property
    def night_lock_file(self) -> Path:
        return self.path / ".nightly.lock"

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

    def output_file(self, path: str | os.PathLike[str], *, option: str) -> Path:
        """``path``, a file the user names for a command's output (``--json FILE``),
        if writing it cannot touch the data root's own files: it resolves (symlinks
        followed) outside the data root or under its ``reports`` folder, and is not a
        folder. Raises :class:`OutputPathError` (one line naming ``option``) otherwise,
        before anything runs: a JSON written over ``warehouse.duckdb`` or into the lake
        would destroy what every command reads.
        """
        path = Path(path).expanduser().absolute()
        real, root = path.resolve(), self.path.resolve()
        reports = (self.path / "reports").resolve()
        inside = real == root or real.is_relative_to(root)
        if inside and not real.is_relative_to(reports):
            raise OutputPathError(
                f"{option} {path}: inside the data root {root}, whose files ropeload "
                f"keeps; write it outside the data root or under {self.path / 'reports'}"
            )
        if real.is_dir():
            raise OutputPathError(f"{option} {path}: is a folder, not a file")
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
def open_writer(
    root: DataRoot, *, lock_timeout_s: float | None = None
) -> Iterator[duckdb.DuckDBPyConnection]:
    """Open the warehouse for writing; publish atomically when the block succeeds.

    Writers are serialised by an exclusive lock (:class:`warehouse.lock.WarehouseLock`:
    waits at most ``lock_timeout_s``, default ``$ROPELOAD_LOCK_TIMEOUT`` or 600 s, then
    raises :class:`~warehouse.lock.LockTimeoutError` naming the holder). When the previous
    holder died holding the lock, the temporary files of dead writers in the lake are
    removed first (:func:`warehouse.parquet_files.remove_stale_temporaries`); the
    staging copy of a dead writer is replaced in any case. Migrations are applied
    first, so every writer sees the current schema. The views (:mod:`warehouse.views`)
    are refreshed on the way in and again before publishing, so they point at this data
    root and at lake tables landed in the block. On an exception nothing is published.
    """
    from warehouse.lock import WarehouseLock
    from warehouse.migrate import apply_migrations  # here: migrate imports store's types
    from warehouse.parquet_files import remove_stale_temporaries
    from warehouse.views import refresh_views

    _check_data_root(root)
    root.path.mkdir(parents=True, exist_ok=True)
    with WarehouseLock(root.lock_file, timeout_s=lock_timeout_s) as lock:
        staging = root.warehouse.with_name(root.warehouse.name + ".next")
        staging.unlink(missing_ok=True)
        Path(str(staging) + ".wal").unlink(missing_ok=True)
        shutil.rmtree(str(staging) + ".tmp", ignore_errors=True)  # DuckDB's spill folder
        if lock.previous_crashed and root.lake.is_dir():
            remove_stale_temporaries(root.lake)
        if root.warehouse.exists():
            shutil.copyfile(root.warehouse, staging)
            _downgrade_storage(staging)  # once, for a file a DuckDB-2.0 default wrote
        # a new file gets STORAGE_VERSION; an existing one keeps its own
        con = duckdb.connect(
            str(staging), config={"storage_compatibility_version": STORAGE_VERSION}
        )
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


def _version_tuple(version: str) -> tuple[int, ...]:
    """``'v1.4.0+'`` -> ``(1, 4, 0)``; ``()`` when DuckDB reports no version."""
    return tuple(int(part) for part in re.findall(r"\d+", version)[:3])


def storage_version(con: duckdb.DuckDBPyConnection, database: str | None = None) -> str:
    """The storage format DuckDB reports for ``database`` (default: the current one),
    e.g. ``'v1.4.0+'``: the oldest DuckDB that reads the file."""
    row = con.execute(
        "SELECT tags['storage_version'] FROM duckdb_databases() "
        "WHERE database_name = coalesce(?, current_database())",
        [database],
    ).fetchall()
    return (row[0][0] or "") if row else ""


def _downgrade_storage(path: Path) -> bool:
    """Rewrite the database file ``path`` in :data:`STORAGE_VERSION` if it is newer.

    DuckDB keeps a file's storage format for its life (``storage_compatibility_version``
    only applies to new files), so a file written in DuckDB 2.0's default format is
    copied whole -- tables, data, keys, views -- into a new file of the older format
    (``COPY FROM DATABASE``), which replaces it. Called on the writer's private copy, so
    the published file is untouched until the writer publishes. Returns True if rewritten.
    """
    target = path.with_name(path.name + ".storage")
    target.unlink(missing_ok=True)
    con = duckdb.connect(":memory:")
    try:
        con.execute(f"ATTACH {_sql_text(str(path))} AS old_format (READ_ONLY)")
        found = storage_version(con, "old_format")
        if _version_tuple(found) <= _version_tuple(STORAGE_VERSION):
            return False
        con.execute(
            f"ATTACH {_sql_text(str(target))} AS new_format "
            f"(STORAGE_VERSION {_sql_text(STORAGE_VERSION)})"
        )
        con.execute("COPY FROM DATABASE old_format TO new_format")
        con.execute("DETACH new_format")
    except BaseException:
        target.unlink(missing_ok=True)
        raise
    finally:
        con.close()
    target.replace(path)
    return True


def open_reader(root: DataRoot, *, sandbox: bool = False) -> duckdb.DuckDBPyConnection:
    """Open the published warehouse read-only (a consistent snapshot).

    ``sandbox=True`` is for SQL typed by people (``ropeload query``): the connection
    cannot write any file or read one outside ``<data>/lake``, whatever SQL it is given
    (:func:`_open_sandboxed`). Plain readers (``sandbox=False``) run the pipeline's own SQL.

    Raises FileNotFoundError with the path when nothing has been landed yet, ValueError
    for a data root DuckDB would not read as named (:func:`data_root_problem`).
    """
    _check_data_root(root)
    if not root.warehouse.exists():
        raise FileNotFoundError(
            f"no warehouse at {root.warehouse}: run 'ropeload ingest' or 'ropeload demo' first"
        )
    if sandbox:
        return _open_sandboxed(root)
    return duckdb.connect(str(root.warehouse), read_only=True)


def _sql_text(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def _open_sandboxed(root: DataRoot) -> duckdb.DuckDBPyConnection:
    """A read-only connection locked to the warehouse and the lake (measured, DuckDB 2.0).

    - A private in-memory DuckDB instance attaches the warehouse ``READ_ONLY`` and uses
      it. Not ``duckdb.connect(path)``: that returns the per-path instance that other
      connections of this process share, and the settings below are instance-wide.
    - ``allowed_directories`` is ``<data>/lake/`` (the raw views read its Parquet) and
      ``enable_external_access`` is off: any other path (``read_csv('/etc/passwd')``,
      ``glob``, ``ATTACH``, ``COPY ... TO``, ``EXPORT DATABASE``, URLs) fails with a
      Permission Error, and so do extension installs and loads. DuckDB normalises ``..``
      before the prefix check (``<lake>/../x`` is refused); the check is on the path as
      spelled, so a lake that is a symlink works, and so would a symlink planted inside
      the lake (only writers of the lake can plant one).
    - Still readable besides the lake: the attached warehouse file itself (DuckDB allows
      it), whose bytes (``read_blob``) hold nothing its tables do not show. Still
      writable: the lake, by a ``COPY`` statement, so :mod:`pipelines.query` refuses
      every statement but one ``SELECT`` before anything runs.
    - Sorts and joins too big for memory spill into a private folder of the system temp
      directory, which DuckDB creates on first spill and removes on close (not next to
      the warehouse, not in the working directory).
    - ``lock_configuration`` last: no ``SET``, ``RESET`` or ``PRAGMA`` can undo any of it.

    If the stored raw views point at another place than ``root`` (a data root moved, or
    named by another path than the writer's), they and the models above them are
    recreated as temporary views for ``root`` first: the stored ones would be refused.
    """
    import tempfile
    import uuid

    from warehouse.views import LAKE_VIEWS, refresh_views  # views imports store's types

    spill = Path(tempfile.gettempdir()) / f"ropeload-query-{uuid.uuid4().hex}"
    # in this order: allowed_directories must be set before enable_external_access goes
    # off (DuckDB 2.0 refuses both as ``connect`` config: "before the database is started")
    settings = {
        "temp_directory": _sql_text(str(spill)),
        "allowed_directories": f"[{_sql_text(str(root.lake) + os.sep)}]",
        "enable_external_access": "false",
        "autoload_known_extensions": "false",
        "autoinstall_known_extensions": "false",
        "allow_community_extensions": "false",
    }
    con = duckdb.connect(":memory:")
    try:
        con.execute(f"ATTACH {_sql_text(str(root.warehouse))} AS warehouse (READ_ONLY)")
        con.execute("USE warehouse")
        for name, value in settings.items():
            con.execute(f"SET {name} = {value}")
        stored = con.execute(
            "SELECT view_name, sql FROM duckdb_views() WHERE database_name = 'warehouse'"
        ).fetchall()
        here = {view: str(root.table_dir(table) / "site=*") for view, table in LAKE_VIEWS.items()}
        if any(
            view in here and "read_parquet(" in sql and _sql_text(here[view])[:-1] not in sql
            for view, sql in stored
        ):
            refresh_views(con, root, temporary=True)
        con.execute("SET lock_configuration = true")
    except BaseException:
        con.close()
        raise
    return con
