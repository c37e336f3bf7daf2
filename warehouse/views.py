"""Warehouse views: raw (over the lake Parquet), staging, intermediate and marts.

Layers (dbt naming; one model per file under ``warehouse/models/<layer>/``):

``lake_*``
    Views over the lake Parquet, built here because they hold absolute paths:
    ``lake_field_samples``, ``lake_rig_samples``, ``lake_rope_tensions``. Columns and
    types are the Arrow schemas of :mod:`schemas.tables` (the lake's own names) plus the
    Hive keys ``site``, ``hoist``, ``date``. With no file landed yet the view is an empty,
    fully typed relation, so every layer above it can be created and queried. (Called
    ``raw_*`` before issue 18, when "raw" also meant "uncompensated" in column names;
    :func:`refresh_views` drops the old names.)
``stg_*`` (``models/staging``)
    One per raw source: rename, cast, units only.
``int_*`` (``models/intermediate``)
    Joins the marts share (run inputs joined to the manifest).
marts (``models/marts``)
    ``rope_tensions`` (the compensated layer), ``hoists``, ``rope_trip_extremes`` and the
    ``audit_*`` lineage views. The
    landed mart tables (``position_summary``, ``trip_summary``, ``alarms``,
    ``sanity_checks``, ``friction_parameter_sets``, ``discovery_findings``) are tables
    made by migrations.

:func:`refresh_views` (re)creates whatever changed under them;
:func:`warehouse.store.open_writer` calls it before publishing, so the views follow the
data root and pick up the first files of a lake table. A reader whose data root moved
since the last writer can call it with ``temporary=True`` on its read-only connection:
temporary views shadow the stored ones.
"""

from __future__ import annotations

import hashlib
import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq

from schemas.names import escape_error, escaping_links
from schemas.tables import LAKE_PARTITIONS, TABLES, duckdb_columns

logger = logging.getLogger(__name__)

if TYPE_CHECKING:
    from warehouse.store import DataRoot

__all__ = [
    "LAKE_VIEWS",
    "MODELS_DIR",
    "MODEL_LAYERS",
    "RETIRED_VIEWS",
    "model_files",
    "raw_view_sql",
    "refresh_views",
]

MODELS_DIR = Path(__file__).parent / "models"
MODEL_LAYERS = ("staging", "intermediate", "marts")

#: lake view name -> lake table (``<data>/lake/<table>/site=/hoist=/date=/*.parquet``)
LAKE_VIEWS = {
    "lake_field_samples": "field_samples",
    "lake_rig_samples": "rig_samples",
    "lake_rope_tensions": "rope_tensions",
}
#: Views of earlier releases that no longer exist: dropped by :func:`refresh_views`.
RETIRED_VIEWS = ("raw_field_samples", "raw_rig_samples", "raw_rope_tensions")

_PARTITION_TYPES = {"site": "VARCHAR", "hoist": "VARCHAR", "date": "DATE"}


def model_files() -> list[Path]:
    """Model SQL files in creation order: by layer, then by name."""
    return [path for layer in MODEL_LAYERS for path in sorted((MODELS_DIR / layer).glob("*.sql"))]


def _quote(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def _sql_columns(table: str) -> list[tuple[str, str]]:
    """(name, DuckDB type) of a lake table's columns, from the Arrow schema."""
    columns = []
    for part in duckdb_columns(TABLES[table]).split(",\n    "):
        name, sql_type = part.split(" ", 1)
        columns.append((name, sql_type.removesuffix(" NOT NULL")))
    return columns


def raw_view_sql(root: DataRoot, table: str, files: Sequence[Path] | None = None) -> str:
    """``SELECT`` of one lake table: typed columns of its Arrow schema + Hive keys (of
    ``files`` only, where given, else every file of the table)."""
    columns = _sql_columns(table)
    columns += [(key, _PARTITION_TYPES[key]) for key in LAKE_PARTITIONS]
    directory = root.table_dir(table)
    if not (files if files is not None else any(directory.glob("site=*/hoist=*/date=*/*.parquet"))):
        select = ", ".join(f"CAST(NULL AS {sql_type}) AS {name}" for name, sql_type in columns)
        return f"SELECT {select} WHERE false"
    pattern = str(directory / "site=*" / "hoist=*" / "date=*" / "*.parquet")
    source = _quote(pattern)
    if files is not None:  # the readable files only (:func:`refresh_views`)
        source = "[" + ", ".join(_quote(str(f)) for f in files) + "]"
    hive_types = ", ".join(f"{_quote(k)}: {_PARTITION_TYPES[k]}" for k in LAKE_PARTITIONS)
    select = ", ".join(f"CAST({name} AS {sql_type}) AS {name}" for name, sql_type in columns)
    return (
        f"SELECT {select} FROM read_parquet({source}, hive_partitioning = true, "
        f"union_by_name = true, hive_types = {{{hive_types}}})"
    )


def readable_files(directory: Path) -> tuple[list[Path], list[Path]]:
    """The lake table's Parquet files under ``directory`` that open (their footer
    reads), and those that do not (damaged from outside: a truncated copy, a stray
    ``touch``; the pipeline's own writes are atomic)."""
    good, bad = [], []
    for path in sorted(directory.glob("site=*/hoist=*/date=*/*.parquet")):
        try:
            pq.read_metadata(path)
            good.append(path)
        except (OSError, pa.ArrowException):
            bad.append(path)
    return good, bad


#: The comment every view :func:`refresh_views` stores carries the fingerprint of the
#: whole set it made (``ropeload-views:<sha256>``) and how far its lake files were checked
#: (``checked-from:<mtime_ns>``): a writer whose views, models and tables are as they were
#: skips re-creating them (see :func:`refresh_views`).
_FINGERPRINT_PREFIX = "ropeload-views:"
_CHECKED = " checked-from:"

#: A Parquet file starts and ends with these four bytes (its footer's length before the
#: last four): a file without them is damaged for sure.
_PARQUET_MAGIC = b"PAR1"
_PARTITION_LEVELS = ("site=", "hoist=", "date=")
#: A ``footers_from_ns`` after every file's time: :func:`unsound_files` reads no footer.
_NO_FOOTERS = 2**63


def unsound_files(directory: Path, *, footers_from_ns: int | None = None) -> tuple[list[Path], int]:
    """The lake table's ``*.parquet`` files under ``directory`` that are not sound
    Parquet, and the newest file's modification time [ns since the epoch] (0: none).

    Every file is tested for the format's magic bytes at both ends (eight bytes read; a
    file shorter than a footer fails). The footer is read too (``pq.read_metadata``, as
    binding a view over the file would) of the files modified at or after
    ``footers_from_ns`` (every file's when None): a writer reads the footers of the
    files new since the views were last checked, not of the whole lake. A file damaged
    from outside with its time set back (``cp -p`` of a damaged copy) and its ends
    whole is not found (DuckDB fails on it when a query reads it)."""
    found, newest = [], 0
    for path in _lake_files(directory):
        try:
            fd = os.open(path, os.O_RDONLY)
        except OSError:
            found.append(Path(path))
            continue
        try:
            status = os.fstat(fd)
            size, newest = status.st_size, max(newest, status.st_mtime_ns)
            sound = (
                size >= 12
                and os.pread(fd, 4, 0) == _PARQUET_MAGIC
                and os.pread(fd, 4, size - 4) == _PARQUET_MAGIC
            )
        except OSError:
            sound = False
        finally:
            os.close(fd)
        if sound and (footers_from_ns is None or status.st_mtime_ns >= footers_from_ns):
            try:
                pq.read_metadata(path)
            except (OSError, pa.ArrowException):
                sound = False
        if not sound:
            found.append(Path(path))
    return sorted(found), newest


def _lake_files(directory: Path) -> list[str]:
    """``site=*/hoist=*/date=*/*.parquet`` under ``directory`` (directory entries only)."""
    found: list[str] = []
    folders = [(os.fspath(directory), 0)]
    while folders:  # strings, not paths: a lake has many files
        folder, depth = folders.pop()
        with os.scandir(folder) as entries:
            for entry in entries:
                if depth < 3 and entry.name.startswith(_PARTITION_LEVELS[depth]):
                    if entry.is_dir():
                        folders.append((entry.path, depth + 1))
                elif depth == 3 and entry.name.endswith(".parquet"):
                    found.append(entry.path)
    return found


def _lake_definition(
    root: DataRoot, table: str, view: str, footers_from_ns: int | None
) -> tuple[str, int]:
    """The ``SELECT`` of a lake view -- over every file of the table, or over the
    readable ones where some are not (:func:`unsound_files`, then every footer read;
    said in the log) -- and the table's newest file's time [ns]."""
    directory = root.table_dir(table)
    if not directory.is_dir():
        return raw_view_sql(root, table), 0
    escaped = escaping_links(directory)
    if escaped:  # the view's pattern would follow it (the writers refuse to)
        raise escape_error(f"lake table {table!r}", escaped)
    unsound, newest = unsound_files(directory, footers_from_ns=footers_from_ns)
    if not unsound:
        return raw_view_sql(root, table), newest
    good, bad = readable_files(directory)
    if not bad:  # its ends damaged, its footer whole: DuckDB reads it
        return raw_view_sql(root, table), newest
    _warn_unreadable(view, bad)
    return raw_view_sql(root, table, good), newest


def _warn_unreadable(view: str, bad: list[Path]) -> None:
    logger.warning(
        "%s: %d unreadable Parquet file(s) left out of the view: %s",
        view, len(bad), ", ".join(str(p) for p in bad),
    )  # fmt: skip


def _fingerprint(con: duckdb.DuckDBPyConnection, definitions: dict[str, str]) -> str:
    """sha256 of the views' definitions, of the tables under them (every column's name,
    type and place: a migration that changes a table the models read makes the views
    again) and of DuckDB's version (which binds them)."""
    tables = con.execute(
        "SELECT table_name, column_index, column_name, data_type FROM duckdb_columns() "
        "WHERE database_name = current_database() AND NOT internal "
        "AND table_name NOT IN (SELECT view_name FROM duckdb_views() "
        "WHERE database_name = current_database()) ORDER BY table_name, column_index"
    ).fetchall()
    digest = hashlib.sha256(f"duckdb {duckdb.__version__}\0".encode())
    for name, body in definitions.items():
        digest.update(f"{name}\0{body}\0".encode())
    digest.update(repr(tables).encode())
    return _FINGERPRINT_PREFIX + digest.hexdigest()


def _stored_marks(con: duckdb.DuckDBPyConnection) -> dict[str, tuple[str, int]]:
    """Each stored view's (fingerprint, checked-from time [ns]) from its comment (views
    without one left out)."""
    rows = con.execute(
        "SELECT view_name, comment FROM duckdb_views() WHERE database_name = "
        "current_database() AND NOT internal AND NOT temporary"
    ).fetchall()
    marks = {}
    for name, comment in rows:
        fingerprint, _, checked = (comment or "").partition(_CHECKED)
        if fingerprint.startswith(_FINGERPRINT_PREFIX) and checked.isdigit():
            marks[name] = (fingerprint, int(checked))
    return marks


def refresh_views(
    con: duckdb.DuckDBPyConnection, root: DataRoot, *, temporary: bool = False
) -> list[str]:
    """Create or replace every view for ``root``; return their names in creation order.

    ``temporary=True`` creates connection-local views (allowed on a read-only
    connection); otherwise the views are stored in the database (inside a writer), and
    :data:`RETIRED_VIEWS` are dropped.

    Stored views are made again only when something under them changed: each carries
    the fingerprint of the set (:func:`_fingerprint`: every view's definition, with the
    lake views' data root and whether their table has files, the tables' columns and
    DuckDB's version) in its comment, and a writer that finds every view with the
    fingerprint it would store leaves them. A view over a lake table's glob reads every
    file's footer when it is made (``union_by_name``), and the models over it again:
    made twice per writer, they cost 2.7 s a writer at 1,500 files a table (session
    51), a year of hourly files ten times that. The views read the lake at query time,
    so files landed since are in them either way. A file damaged from outside is left
    out (the view made over the readable files, said in the log), as when the view is
    made: each refresh tests every lake file's magic bytes and reads the footers of the
    files modified since the views' last check (:func:`unsound_files`; the comment
    keeps that time).
    """
    kind = "TEMPORARY VIEW" if temporary else "VIEW"
    stored = {} if temporary else _stored_marks(con)
    kept = set(stored.values())
    stored_fingerprint, checked = kept.pop() if len(kept) == 1 else (None, None)
    definitions, newest = {}, checked or 0
    # with no check stored the views are made whatever the files: binding them reads
    # every footer, so only the magic bytes are tested here
    footers_from = checked if checked is not None else _NO_FOOTERS
    for view, table in LAKE_VIEWS.items():
        definitions[view], newest_here = _lake_definition(root, table, view, footers_from)
        newest = max(newest, newest_here)
    models = {path.stem: path for path in model_files()}
    for name, path in models.items():
        definitions[name] = path.read_text(encoding="utf-8").strip().rstrip(";")
    if not temporary:
        fingerprint = _fingerprint(con, definitions)
        retired = con.execute(
            "SELECT count(*) FROM duckdb_views() WHERE database_name = current_database() "
            f"AND view_name IN ({', '.join(_quote(v) for v in RETIRED_VIEWS)})"
        ).fetchall()[0][0]
        if not retired and stored_fingerprint == fingerprint and set(stored) >= set(definitions):
            if newest != checked:
                _mark(con, definitions, fingerprint, newest)
            return list(definitions)
        for view in RETIRED_VIEWS:
            con.execute(f"DROP VIEW IF EXISTS {view}")
    for view, table in LAKE_VIEWS.items():
        try:
            con.execute(f"CREATE OR REPLACE {kind} {view} AS {definitions[view]}")
        except duckdb.Error:
            # a damaged file would fail every writer of the data root, every hoist's:
            # the view leaves it out and says so (a run reading its day fails there)
            good, bad = readable_files(root.table_dir(table))
            if not bad:
                raise
            _warn_unreadable(view, bad)
            definitions[view] = raw_view_sql(root, table, good)
            con.execute(f"CREATE OR REPLACE {kind} {view} AS {definitions[view]}")
    for name, path in models.items():
        try:
            con.execute(f"CREATE OR REPLACE {kind} {name} AS\n{definitions[name]}")
        except duckdb.Error as exc:
            raise RuntimeError(f"{path}: cannot create view {name}: {exc}") from exc
    if not temporary:
        # the fingerprint of what was made (a footer found damaged only now changes it)
        _mark(con, definitions, _fingerprint(con, definitions), newest)
    return list(definitions)


def _mark(
    con: duckdb.DuckDBPyConnection, views: dict[str, str], fingerprint: str, checked_ns: int
) -> None:
    """Store ``fingerprint`` and the lake files' check time in every view's comment."""
    comment = _quote(f"{fingerprint}{_CHECKED}{checked_ns}")
    for name in views:
        con.execute(f"COMMENT ON VIEW {name} IS {comment}")
