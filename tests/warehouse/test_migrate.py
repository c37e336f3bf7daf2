"""Migrations: idempotent, upgrade in place, and tables equal to the Arrow schemas."""

from __future__ import annotations

import datetime as dt

import duckdb
import pyarrow as pa
import pytest

from schemas.tables import LAKE_PARTITIONS, TABLES
from warehouse.migrate import apply_migrations, migration_files
from warehouse.store import DataRoot, open_reader, open_writer
from warehouse.views import LAKE_VIEWS, refresh_views

# Arrow type -> the type name DuckDB reports in information_schema (independent of
# schemas.tables' own mapping, so a wrong mapping there is caught here).
EXPECTED_SQL = {
    pa.float64(): "DOUBLE",
    pa.float32(): "FLOAT",
    pa.int64(): "BIGINT",
    pa.int32(): "INTEGER",
    pa.string(): "VARCHAR",
    pa.bool_(): "BOOLEAN",
    pa.timestamp("us", tz="UTC"): "TIMESTAMP WITH TIME ZONE",
    pa.list_(pa.string()): "VARCHAR[]",
    pa.map_(pa.string(), pa.int64()): "MAP(VARCHAR, BIGINT)",
    pa.map_(pa.string(), pa.float64()): "MAP(VARCHAR, DOUBLE)",
}
LAKE_ONLY = {"field_samples", "rig_samples", "rope_tensions"}


def _columns(con: duckdb.DuckDBPyConnection, table: str) -> list[tuple[str, str, str]]:
    return con.sql(
        "SELECT column_name, data_type, is_nullable FROM information_schema.columns "
        f"WHERE table_name = '{table}' ORDER BY ordinal_position"
    ).fetchall()


def test_migrations_twice_is_a_no_op(tmp_path):
    con = duckdb.connect(str(tmp_path / "w.duckdb"))
    first = apply_migrations(con)
    assert first == [n for n, _ in migration_files()]
    tables = con.sql("SELECT table_name FROM information_schema.tables ORDER BY 1").fetchall()
    assert apply_migrations(con) == []
    assert con.sql("SELECT table_name FROM information_schema.tables ORDER BY 1").fetchall() == (
        tables
    )
    versions = con.sql("SELECT version FROM schema_migrations ORDER BY 1").fetchall()
    assert [v for (v,) in versions] == first


def test_old_database_is_upgraded_in_place_keeping_data(tmp_path):
    path = tmp_path / "old.duckdb"
    con = duckdb.connect(str(path))
    # a database as the first release left it: only migration 0001, with data in it
    con.execute(
        "CREATE TABLE schema_migrations (version INTEGER PRIMARY KEY, name VARCHAR NOT NULL,"
        " applied_at TIMESTAMPTZ NOT NULL DEFAULT now())"
    )
    number, first = migration_files()[0]
    con.execute(first.read_text())
    con.execute("INSERT INTO schema_migrations (version, name) VALUES (?, ?)", [number, first.stem])
    started = dt.datetime(2026, 3, 1, tzinfo=dt.UTC)
    con.execute(
        "INSERT INTO runs (run_id, command, code_version, started_at_utc, status, inputs) "
        "VALUES ('old-run', 'ingest', 'v0', ?, 'succeeded', ['abc'])",
        [started],
    )
    con.execute(
        "INSERT INTO manifest VALUES ('abc', '/logs/a.csv', 'csv', 10, 10, 's', 'h', 1, 1, 0, 0,"
        " MAP {}, NULL, NULL, 'landed', NULL, ?)",
        [started],
    )
    con.close()

    root = DataRoot(tmp_path)
    path.rename(root.warehouse)
    with open_writer(root) as writer:  # migrations run on the way in
        assert "position_summary" in {
            t for (t,) in writer.sql("SELECT table_name FROM information_schema.tables").fetchall()
        }
    reader = open_reader(root)
    try:
        assert reader.sql("SELECT run_id, inputs FROM runs").fetchall() == [("old-run", ["abc"])]
        assert reader.sql("SELECT source_path FROM manifest").fetchall() == [("/logs/a.csv",)]
        versions = [v for (v,) in reader.sql("SELECT version FROM schema_migrations").fetchall()]
        assert sorted(versions) == [n for n, _ in migration_files()]
        # the views built on the upgraded database see the old data
        assert reader.sql("SELECT source_paths FROM audit_runs").fetchall() == [(["/logs/a.csv"],)]
    finally:
        reader.close()


@pytest.mark.parametrize("table", sorted(set(TABLES) - LAKE_ONLY))
def test_tables_match_arrow_schemas(tmp_path, table):
    con = duckdb.connect(str(tmp_path / "w.duckdb"))
    apply_migrations(con)
    expected = [
        (f.name, EXPECTED_SQL[f.type], "YES" if f.nullable else "NO") for f in TABLES[table]
    ]
    assert _columns(con, table) == expected


@pytest.mark.parametrize(("view", "table"), sorted(LAKE_VIEWS.items()))
def test_raw_lake_views_match_arrow_schemas(tmp_path, view, table):
    con = duckdb.connect(str(tmp_path / "w.duckdb"))
    apply_migrations(con)
    refresh_views(con, DataRoot(tmp_path))  # no files yet: typed empty views
    expected = [(f.name, EXPECTED_SQL[f.type]) for f in TABLES[table]]
    expected += [("site", "VARCHAR"), ("hoist", "VARCHAR"), ("date", "DATE")]
    assert [(n, t) for n, t, _ in _columns(con, view)] == expected
    assert tuple(n for n, _ in expected[-3:]) == LAKE_PARTITIONS
    assert con.sql(f"SELECT count(*) FROM {view}").fetchall() == [(0,)]


def test_issue18_renames_keep_old_rows_and_retire_the_raw_views(tmp_path):
    """A warehouse at migration 0002 with a trip and old-named views, upgraded by a writer."""
    root = DataRoot(tmp_path)
    con = duckdb.connect(str(root.warehouse))
    con.execute(
        "CREATE TABLE schema_migrations (version INTEGER PRIMARY KEY, name VARCHAR NOT NULL,"
        " applied_at TIMESTAMPTZ NOT NULL DEFAULT now())"
    )
    for number, path in migration_files()[:2]:
        con.execute(path.read_text())
        con.execute("INSERT INTO schema_migrations (version, name) VALUES (?, ?)",
                    [number, path.stem])  # fmt: skip
    con.execute(
        "INSERT INTO trip_summary (run_id, site, hoist, trip_id, max_load_n,"
        " max_imbalance_fraction) VALUES ('old', 's', 'h', 0, 123.0, 0.01)"
    )
    con.execute("CREATE VIEW raw_rope_tensions AS SELECT 1 AS load_n")
    con.close()
    with open_writer(root):
        pass
    reader = open_reader(root)
    try:
        row = reader.sql(
            "SELECT max_load_after_n, max_imbalance_after_fraction, max_imbalance_after_rope "
            "FROM trip_summary"
        ).fetchall()
        views = {v for (v,) in reader.sql("SELECT view_name FROM duckdb_views()").fetchall()}
        extremes = reader.sql(
            "SELECT rope, max_imbalance_after_fraction, source_path FROM rope_trip_extremes "
            "ORDER BY rope"
        ).fetchall()
    finally:
        reader.close()
    assert row == [(123.0, 0.01, None)]
    assert "raw_rope_tensions" not in views
    assert {"lake_rope_tensions", "hoists", "rope_trip_extremes"} <= views
    # old rows have no per-rope extremes: the view still has the trip's four ropes, empty
    assert extremes == [(i, None, None) for i in (1, 2, 3, 4)]


def test_the_new_file_test_reads_a_warehouse_from_before_the_aliases(tmp_path):
    """A warehouse migrated up to 0005 (before ``manifest_aliases``): the nightly's
    new-file test, which runs before any writer migrates it, reads the manifest alone
    (it failed every night with a catalog error until another command migrated it)."""
    from pipelines.hoists import known_files

    root = DataRoot(tmp_path)
    with open_writer(root) as con:
        con.execute(
            "INSERT INTO manifest (source_sha256, source_path, format, size_bytes, rows_read, "
            "rows_landed, rows_quarantined, rows_duplicate, status, ingested_at_utc) "
            "VALUES ('s', '/in/a.csv', 'csv', 10, 0, 0, 0, 0, 'landed', now())"
        )
    con = duckdb.connect(str(root.warehouse))
    con.execute("DROP TABLE manifest_aliases")
    con.execute("DELETE FROM schema_migrations WHERE version = 6")
    con.close()
    assert known_files(root) == {("/in/a.csv", 10)}
