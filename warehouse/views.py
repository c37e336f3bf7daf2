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

:func:`refresh_views` (re)creates everything; :func:`warehouse.store.open_writer` calls
it before publishing, so the views follow the data root and pick up the first files of
a lake table. A reader whose data root moved since the last writer can call it with
``temporary=True`` on its read-only connection: temporary views shadow the stored ones.
"""

from __future__ import annotations

import logging
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


def refresh_views(
    con: duckdb.DuckDBPyConnection, root: DataRoot, *, temporary: bool = False
) -> list[str]:
    """Create or replace every view for ``root``; return their names in creation order.

    ``temporary=True`` creates connection-local views (allowed on a read-only
    connection); otherwise the views are stored in the database (inside a writer), and
    :data:`RETIRED_VIEWS` are dropped.
    """
    kind = "TEMPORARY VIEW" if temporary else "VIEW"
    if not temporary:
        for view in RETIRED_VIEWS:
            con.execute(f"DROP VIEW IF EXISTS {view}")
    created = []
    for view, table in LAKE_VIEWS.items():
        escaped = escaping_links(root.table_dir(table)) if root.table_dir(table).is_dir() else []
        if escaped:  # the view's pattern would follow it (the writers refuse to)
            raise escape_error(f"lake table {table!r}", escaped)
        try:
            con.execute(f"CREATE OR REPLACE {kind} {view} AS {raw_view_sql(root, table)}")
        except duckdb.Error:
            # a damaged file would fail every writer of the data root, every hoist's:
            # the view leaves it out and says so (a run reading its day fails there)
            good, bad = readable_files(root.table_dir(table))
            if not bad:
                raise
            logger.warning(
                "%s: %d unreadable Parquet file(s) left out of the view: %s",
                view, len(bad), ", ".join(str(p) for p in bad),
            )  # fmt: skip
            con.execute(f"CREATE OR REPLACE {kind} {view} AS {raw_view_sql(root, table, good)}")
        created.append(view)
    for path in model_files():
        body = path.read_text(encoding="utf-8").strip().rstrip(";")
        try:
            con.execute(f"CREATE OR REPLACE {kind} {path.stem} AS\n{body}")
        except duckdb.Error as exc:
            raise RuntimeError(f"{path}: cannot create view {path.stem}: {exc}") from exc
        created.append(path.stem)
    return created
