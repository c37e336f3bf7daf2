"""``ropeload query``: read-only in fact, machine formats, one-line errors.

The escape probes are the ones a hostile tester got through a keyword filter: each must
be refused (exit 1, one line ``ropeload query: refused: ...``), leave every file under
the test's folder (data root, lake, an outside folder) byte for byte and mtime as it
was, create none, and show none of the outside file's content.
"""

from __future__ import annotations

import csv
import datetime as dt
import hashlib
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import duckdb
import polars as pl
import pytest

from pipelines.cli import main
from pipelines.query import format_result
from schemas.tables import POSITION_SUMMARY, conform
from warehouse.landing import RunRecord, land_results, land_rope_tensions
from warehouse.store import DataRoot, open_reader, open_writer

DAY = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
SECRET = "ROPELOAD-TEST-SECRET-7f3a"  # content of the outside files; must never be printed
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def data(tmp_path):
    root = DataRoot.resolve(tmp_path / "data")
    with open_writer(root) as con:
        con.execute(
            "INSERT INTO runs (run_id, command, code_version, started_at_utc, status) VALUES "
            "('r1', 'demo', 'test', TIMESTAMPTZ '2026-03-02 06:00:00+00', 'succeeded'),"
            "('r2', 'run', 'test', TIMESTAMPTZ '2026-03-03 06:00:00+00', 'failed')"
        )
    return root


def _land(root: DataRoot) -> None:
    """A run with 4 trips (12 position rows) and 24 hourly lake samples of 1..24 N."""
    run = RunRecord(
        run_id="r1", command="run", code_version="test", started_at_utc=DAY, site="s",
        hoist="h", period_start_utc=DAY, period_end_utc=DAY + dt.timedelta(days=1),
    )  # fmt: skip
    positions = pl.DataFrame(
        [
            {"run_id": "r1", "site": "s", "hoist": "h", "trip_id": trip, "position": position,
             "time_start_utc": DAY + dt.timedelta(minutes=10 * trip + k), "load_after_n": 1.0e5}
            for trip in range(4)
            for k, position in enumerate(("bottom", "middle", "pithead"))
        ]
    )  # fmt: skip
    samples = pl.DataFrame(
        {"time_utc": [DAY + dt.timedelta(hours=h) for h in range(24)],
         "load_n": [float(h + 1) for h in range(24)]},
        schema={"time_utc": pl.Datetime("us", "UTC"), "load_n": pl.Float64},
    )  # fmt: skip
    with open_writer(root) as con:
        land_results(con, run, position_summary=conform(positions, POSITION_SUMMARY))
        land_rope_tensions(root, samples, site="s", hoist="h", period_start_utc=DAY,
                           period_end_utc=DAY + dt.timedelta(days=1))  # fmt: skip


@pytest.fixture(scope="module")
def audit(tmp_path_factory):
    """(folder, data root): a landed warehouse and lake, and an outside folder with secrets."""
    top = tmp_path_factory.mktemp("query")
    root = DataRoot.resolve(top / "data")
    _land(root)
    outside = top / "outside"
    outside.mkdir()
    (outside / "secret.txt").write_text(SECRET + "\n")
    (outside / "secret.csv").write_text(f"marker\n{SECRET}\n")
    pl.DataFrame({"marker": [SECRET]}).write_parquet(outside / "secret.parquet")
    other = duckdb.connect(str(outside / "other.duckdb"))
    other.execute("CREATE TABLE t (a INTEGER)")
    other.close()
    return top, root


def _files(top: Path) -> dict[str, tuple[int, int, str]]:
    """Every file and folder under ``top``: size, mtime (ns), sha256 (files)."""
    state = {}
    for path in sorted(top.rglob("*")):
        stat = path.stat()
        digest = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "dir"
        state[str(path.relative_to(top))] = (stat.st_size, stat.st_mtime_ns, digest)
    return state


# (id, SQL with {data} {lake} {part} {outside}, what the one-line refusal must name)
ESCAPES = [
    ("copy-to-warehouse", "COPY (SELECT 'x') TO '{data}/warehouse.duckdb'", "COPY statements"),
    ("copy-to-lake-partition", "COPY (SELECT * FROM rope_tensions) TO '{part}/part-99999.parquet'",
     "COPY statements"),
    ("copy-to-outside", "COPY runs TO '{outside}/runs.csv'", "COPY statements"),
    ("copy-from", "COPY runs FROM '{outside}/secret.csv'", "COPY statements"),
    ("attach-then-insert",
     "ATTACH '{outside}/other.duckdb' AS other (READ_ONLY false); INSERT INTO other.t VALUES (1)",
     "2 statements (ATTACH, INSERT)"),
    ("attach", "ATTACH '{outside}/other.duckdb' AS other (READ_ONLY false)", "ATTACH statements"),
    ("detach", "DETACH warehouse", "DETACH statements"),
    ("export-database", "EXPORT DATABASE '{outside}/export'", "EXPORT statements"),
    ("import-database", "IMPORT DATABASE '{outside}'", "IMPORT (PRAGMA)"),
    ("select-then-copy", "select 1; copy (select 'x') to '{outside}/x.csv'",
     "2 statements (SELECT, COPY)"),
    ("copy-then-select", "copy (select 'x') to '{outside}/x.csv'; select 1",
     "2 statements (COPY, SELECT)"),
    ("explain-analyze-copy",
     "EXPLAIN ANALYZE COPY (SELECT 1 AS a) TO '{part}/part-explain.parquet'",
     "under EXPLAIN, COPY statements"),
    ("explain-analyze-options-copy",
     "EXPLAIN ANALYZE (FORMAT JSON) COPY (SELECT 1 AS a) TO '{part}/part-explain.parquet'",
     "under EXPLAIN, COPY statements"),
    # a bracket inside a quoted name or a string of the options is no bracket: counted,
    # it moved the end of the options onto the write's own tail (``FROM runs``), which
    # alone was checked, and EXPLAIN ANALYZE ran the CREATE (exit 0)
    ("explain-options-bracket-in-a-quoted-name",
     'EXPLAIN (ANALYZE "(") CREATE TEMP TABLE x AS SELECT 1 AS ")" FROM runs',
     "under EXPLAIN, CREATE statements"),
    ("explain-options-bracket-in-a-dollar-string",
     "EXPLAIN (ANALYZE $$($$) INSERT INTO runs (run_id) SELECT 'x' AS \")\" FROM runs",
     "under EXPLAIN, INSERT statements"),
    ("explain-options-bracket-in-an-escape-string",
     "EXPLAIN (ANALYZE E'(') CREATE TEMP TABLE x AS SELECT 1 AS \")\" FROM runs",
     "under EXPLAIN, CREATE statements"),
    ("read-csv-passwd", "SELECT * FROM read_csv('/etc/passwd', sep = ':')",
     'cannot access file "/etc/passwd"'),
    ("read-csv-outside", "SELECT * FROM read_csv('{outside}/secret.csv')",
     'cannot access file "{outside}/secret.csv"'),
    ("read-text-outside", "SELECT content FROM read_text('{outside}/secret.txt')",
     'cannot access file "{outside}/secret.txt"'),
    ("read-blob-outside", "SELECT content FROM read_blob('{outside}/secret.txt')",
     'cannot access file "{outside}/secret.txt"'),
    ("glob-etc", "SELECT * FROM glob('/etc/*')", 'cannot access file "/etc/*"'),
    ("glob-outside", "SELECT * FROM glob('{outside}/*')", 'cannot access file "{outside}/*"'),
    ("read-parquet-outside", "SELECT * FROM read_parquet('{outside}/secret.parquet')",
     'cannot access file "{outside}/secret.parquet"'),
    ("relative-path", "SELECT content FROM read_text('../outside/secret.txt')",
     'cannot access file "../outside/secret.txt"'),
    ("dot-dot-out-of-the-lake", "SELECT content FROM read_text('{lake}/../../outside/secret.txt')",
     "cannot access file"),
    ("data-root-outside-the-lake", "SELECT content FROM read_text('{data}/.warehouse.lock')",
     "cannot access file"),
    ("nested-query-function",
     "SELECT * FROM query('SELECT content FROM read_text(''{outside}/secret.txt'')')",
     "cannot access file"),
    ("set", "SET threads = 1", "SET statements"),
    ("set-external-access", "SET enable_external_access = true", "SET statements"),
    ("reset", "RESET lock_configuration", "RESET (SET)"),
    ("use", "USE memory", "USE (SET)"),
    ("pragma", "PRAGMA threads = 1", "PRAGMA (SET)"),
    ("pragma-show", "PRAGMA show_tables", "PRAGMA statements"),
    ("insert", "INSERT INTO runs (run_id) VALUES ('x')", "INSERT statements"),
    ("with-insert", "WITH a AS (SELECT 'x' AS run_id) INSERT INTO runs (run_id) SELECT * FROM a",
     "INSERT statements"),
    # DuckDB parses a SELECT whose WITH holds a COPY or DML as a SELECT statement, and
    # the sandbox's allowed lake is writable: the COPY overwrote a lake file (exit 0)
    ("with-copy-over-a-lake-file",
     "WITH x AS (COPY (SELECT 1 AS a) TO '{part}/hour-00.parquet') SELECT 1",
     "COPY inside WITH"),
    ("with-copy-to-outside",
     "WITH x AS (COPY (SELECT 1 AS a) TO '{outside}/x.csv'), y AS (SELECT 2) SELECT * FROM y",
     "COPY inside WITH"),
    ("with-copy-nested",
     "WITH x AS (WITH y AS (COPY (SELECT 1 AS a) TO '{part}/y.parquet') SELECT 1) SELECT 1",
     "COPY inside WITH"),
    ("explain-analyze-with-copy",
     "EXPLAIN ANALYZE WITH x AS (COPY (SELECT 1 AS a) TO '{part}/hour-00.parquet') SELECT 1",
     "under EXPLAIN, COPY inside WITH"),
    ("with-insert-returning",
     "WITH x AS (INSERT INTO runs (run_id) VALUES ('x') RETURNING *) SELECT * FROM x",
     "INSERT inside WITH"),
    ("with-delete-returning", "WITH x AS (DELETE FROM runs RETURNING *) SELECT count(*) FROM x",
     "DELETE inside WITH"),
    ("with-update-returning",
     "WITH x AS (UPDATE runs SET status = 'x' RETURNING *) SELECT count(*) FROM x",
     "UPDATE inside WITH"),
    ("create", "CREATE TABLE x AS SELECT 1", "CREATE statements"),
    ("create-temp", "CREATE TEMP TABLE x AS SELECT 1", "CREATE statements"),
    ("drop", "DROP TABLE runs", "DROP statements"),
    ("update", "UPDATE runs SET status = 'x'", "UPDATE statements"),
    ("delete", "DELETE FROM runs", "DELETE statements"),
    ("alter", "ALTER TABLE runs ADD COLUMN x INTEGER", "ALTER statements"),
    ("checkpoint", "CHECKPOINT", "CHECKPOINT (CALL)"),
    ("force-checkpoint", "FORCE CHECKPOINT", "FORCE (CALL)"),
    ("vacuum", "VACUUM", "VACUUM statements"),
    ("install", "INSTALL httpfs", "INSTALL (LOAD)"),
    ("load", "LOAD httpfs", "LOAD statements"),
    ("update-extensions", "UPDATE EXTENSIONS", "UPDATE statements"),
    ("call", "CALL checkpoint()", "CALL statements"),
    ("begin", "BEGIN TRANSACTION", "BEGIN (TRANSACTION)"),
    ("empty", " ; -- nothing", "no SQL statement"),
]  # fmt: skip


@pytest.mark.parametrize(("sql", "names"), [p[1:] for p in ESCAPES], ids=[p[0] for p in ESCAPES])
def test_escape_is_refused_and_touches_nothing(audit, sql, names, capsys, monkeypatch):
    top, root = audit
    monkeypatch.chdir(root.path)  # '../outside/...' is the secret folder from here
    fill = {
        "data": root.path,
        "lake": root.lake,
        "part": root.partition_dir("rope_tensions", site="s", hoist="h", date="2026-03-02"),
        "outside": top / "outside",
    }
    before = _files(top)
    status = main(["query", "--data", str(root.path), "--format", "csv", sql.format(**fill)])
    out, err = capsys.readouterr()
    assert status == 1
    assert out == ""
    assert err.startswith("ropeload query: refused: ")
    assert err.endswith("\n")
    assert err.count("\n") == 1, err
    assert names.format(**fill) in err
    assert SECRET not in err
    assert "root:" not in err
    assert _files(top) == before  # nothing written, nothing created, not even an mtime


@pytest.mark.parametrize(
    "sql",
    [
        "COPY (SELECT 'x') TO '{data}/warehouse.duckdb'",
        "COPY (SELECT 'x') TO '{outside}/x.csv'",
        "ATTACH '{outside}/other.duckdb' AS other (READ_ONLY false)",
        "EXPORT DATABASE '{outside}/export'",
        "INSERT INTO runs (run_id) VALUES ('x')",
        "SELECT content FROM read_text('{outside}/secret.txt')",
        "SELECT * FROM read_csv('/etc/passwd', sep = ':')",
        "SELECT * FROM glob('/etc/*')",
        "SET enable_external_access = true",
        "RESET allowed_directories",
        "PRAGMA threads = 1",
        "INSTALL httpfs",
        "LOAD httpfs",
    ],
)
def test_sandboxed_connection_stops_escapes_on_its_own(audit, sql):
    """Second fence: with no statement check at all, DuckDB itself refuses these."""
    top, root = audit
    before = _files(top)
    con = open_reader(root, sandbox=True)
    try:
        with pytest.raises(duckdb.Error):
            con.sql(sql.format(data=root.path, outside=top / "outside")).fetchall()
    finally:
        con.close()
    assert _files(top) == before


def test_sandbox_does_not_leak_into_other_connections(audit):
    """DuckDB settings are per instance: plain readers of the same file keep theirs."""
    _, root = audit
    plain = open_reader(root)  # open during the sandboxed query
    try:
        assert main(["query", "--data", str(root.path), "select count(*) from runs"]) == 0
        assert plain.sql("SELECT current_setting('enable_external_access')").fetchall() == [(True,)]
        plain.execute("SET threads = 1")  # not locked
    finally:
        plain.close()


def _csv(capsys, root: DataRoot, sql: str) -> list[str]:
    assert main(["query", "--data", str(root.path), "--format", "csv", sql]) == 0
    return capsys.readouterr().out.splitlines()


def test_views_marts_and_the_lake_stay_queryable(audit, capsys):
    _, root = audit
    assert _csv(capsys, root, "select run_id, status from runs") == [
        "run_id,status",
        "r1,succeeded",
    ]
    assert _csv(capsys, root, "select count(*) as n from position_summary") == ["n", "12"]
    # the compensated layer is a view over the lake Parquet: 1 + 2 + ... + 24 N
    assert _csv(
        capsys,
        root,
        "select count(*) as n, sum(load_after_n) as s, min(site) as site from rope_tensions",
    ) == ["n,s,site", "24,300.0,s"]
    assert _csv(
        capsys,
        root,
        "with per_hour as (select hour(time_utc) as h, load_n from lake_rope_tensions) "
        "select load_n from per_hour where h = 23",
    ) == ["load_n", "24.0"]
    assert _csv(capsys, root, "select run_id, position_rows from audit_runs") == [
        "run_id,position_rows",
        "r1,12",
    ]
    lake_glob = f"{root.lake}/rope_tensions/*/*/*/*.parquet"
    assert _csv(capsys, root, f"from read_parquet('{lake_glob}') select count(*) as n") == [
        "n",
        "24",
    ]
    assert _csv(capsys, root, "select count(*) as n from (describe position_summary)") == [
        "n",
        str(len(POSITION_SUMMARY)),
    ]
    plan = _csv(capsys, root, "explain select * from rope_tensions")
    assert plan[0] == "explain_key,explain_value"
    assert _csv(capsys, root, "explain (format json) select 1 as a")[0] == (
        "explain_key,explain_value"
    )


def test_views_follow_a_moved_data_root(tmp_path, capsys):
    """Stored raw views name the old lake, outside the sandbox; the reader re-points them."""
    old = DataRoot.resolve(tmp_path / "old")
    _land(old)
    moved = DataRoot.resolve(tmp_path / "moved")
    old.path.rename(moved.path)
    assert _csv(
        capsys, moved, "select count(*) as n, sum(load_after_n) as s from rope_tensions"
    ) == [
        "n,s",
        "24,300.0",
    ]
    # and the old place is not readable through the moved root's sandbox
    status = main(["query", "--data", str(moved.path), f"from read_text('{old.path}/x')"])
    assert status == 1
    assert "refused: cannot access file" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("sql", "names"),
    [
        ("COPY (SELECT 'x') TO '{data}/warehouse.duckdb'", "COPY statements"),
        ("SELECT content FROM read_text('{outside}/secret.txt')", "cannot access file"),
    ],
)
def test_refusal_through_the_installed_command(audit, sql, names):
    top, root = audit
    before = _files(top)
    sql = sql.format(data=root.path, outside=top / "outside")
    done = subprocess.run(
        [sys.executable, "-m", "pipelines.cli", "query", "--data", str(root.path), sql],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    assert done.returncode == 1
    assert done.stdout == ""
    assert done.stderr.startswith("ropeload query: refused: ")
    assert names in done.stderr
    assert done.stderr.count("\n") == 1
    assert SECRET not in done.stderr
    assert _files(top) == before


def test_query_prints_csv(data, capsys):
    status = main(
        [
            "query",
            "--data",
            str(data.path),
            "--format",
            "csv",
            "select run_id, status from runs order by run_id",
        ]
    )
    assert status == 0
    assert capsys.readouterr().out.splitlines() == ["run_id,status", "r1,succeeded", "r2,failed"]


def test_query_prints_json(data, capsys):
    assert (
        main(
            [
                "query",
                "--data",
                str(data.path),
                "--format",
                "json",
                "select count(*) as n from runs",
            ]
        )
        == 0
    )
    assert json.loads(capsys.readouterr().out) == [{"n": 2}]


def test_query_table_for_people(data, capsys):
    assert main(["query", "--data", str(data.path), "select run_id from runs"]) == 0
    out = capsys.readouterr().out
    assert "r1" in out
    assert "r2" in out


def test_table_format_keeps_every_column_whole():
    long = "/srv/ropeload/incoming/" + "x" * 150 + ".csv"
    frame = pl.DataFrame({f"column_{i:02d}": [long] for i in range(30)})
    table = format_result(frame, "table")
    assert all(f"column_{i:02d}" in table for i in range(30))
    assert long in table
    assert "…" not in table


@pytest.mark.parametrize(
    "sql",
    [
        "EXPLAIN SELECT run_id FROM runs",
        "EXPLAIN (FORMAT JSON) SELECT run_id FROM runs",
        "EXPLAIN (SELECT run_id FROM runs)",  # a bracketed query, not options
        "EXPLAIN (SELECT run_id FROM runs) UNION (SELECT 'x')",
        "EXPLAIN ANALYZE (SELECT run_id FROM runs)",
    ],
)
def test_explain_of_a_query_in_brackets_is_planned(data, capsys, sql):
    """A bracket after EXPLAIN is DuckDB's options or the query's own first bracket: both
    readings are checked (the second was refused as "no SQL statement given")."""
    assert main(["query", "--data", str(data.path), "--format", "csv", sql]) == 0, (
        capsys.readouterr().err
    )
    assert capsys.readouterr().out.startswith("explain_key,explain_value")


def test_query_is_read_only(data, capsys):
    status = main(["query", "--data", str(data.path), "delete from runs"])
    assert status == 1
    err = capsys.readouterr().err
    assert err.startswith("ropeload query: ")
    assert "read-only" in err.lower()
    assert len(err.strip().splitlines()) == 1


def test_query_data_from_environment(data, capsys, monkeypatch):
    monkeypatch.setenv("ROPELOAD_DATA", str(data.path))
    assert main(["query", "--format", "csv", "select count(*) as n from runs"]) == 0
    assert capsys.readouterr().out.splitlines() == ["n", "2"]


def test_query_without_warehouse_says_what_to_do(tmp_path, capsys):
    status = main(["query", "--data", str(tmp_path / "empty"), "select 1"])
    assert status == 1
    assert "run 'ropeload ingest' or 'ropeload demo' first" in capsys.readouterr().err


def test_query_sql_error_is_one_line(data, capsys):
    assert main(["query", "--data", str(data.path), "select * from no_such_table"]) == 1
    err = capsys.readouterr().err
    assert "no_such_table" in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("sql", "text"),
    [
        ("select interval '1 month 2 days' as span", "1 month 2 days"),
        ("select 'infinity'::date as d", "infinity"),
        ("select 'infinity'::timestamp as t", "infinity"),
        ("select union_value(k := 1) as u", "1"),
        ("select ['infinity'::timestamp] as l", "[infinity]"),
        ("select {'a': 'infinity'::date} as s", "{'a': infinity}"),
        ("select map {'k': 'infinity'::date} as m", "{k=infinity}"),
        ("select [[{'d': '-infinity'::date}]] as l", "-infinity"),
        # polars took these wrongly: a UHUGEINT as -1, a HUGEINT beyond 38 digits
        # rounded in JSON, a BIT as its internal bytes
        (
            "select 340282366920938463463374607431768211455::uhugeint as u",
            "340282366920938463463374607431768211455",
        ),
        (
            "select 170141183460469231731687303715884105727::hugeint as h",
            "170141183460469231731687303715884105727",
        ),
        ("select '10101'::bit as b", "10101"),
        # polars' CSV writer refused a BLOB (and JSON had Python's repr)
        ("select 'abc'::blob as b", "abc"),
        # DuckDB 2.0's extension types reach polars as Arrow extensions: CSV refused
        # them, JSON and the table showed their internal bytes (``select * from
        # duckdb_settings()`` holds one, typed_value)
        ("select typed_value from duckdb_settings() where name = 'lock_configuration'", "true"),
        ("select 4242::variant as v", "4242"),
        ("select {'rope': 3}::variant as v", "'rope': 3"),
        ("select [4242::variant] as v", "4242"),
        (
            "select 12345678901234567890123456789012345678901234567890::bignum as n",
            "12345678901234567890123456789012345678901234567890",
        ),
        ("select 'POINT(1 2)'::geometry as g", "POINT (1 2)"),
    ],
)
def test_results_polars_cannot_hold_are_shown_as_duckdb_text(data, capsys, sql, text):
    """An interval, a date at infinity (also inside a list, struct or map), a union:
    polars has no type for them; the result shows DuckDB's text of the value instead of
    a traceback (polars panicked on a nested one)."""
    for output in ("table", "csv", "json"):
        assert main(["query", "--data", str(data.path), "--format", output, sql]) == 0
        out = capsys.readouterr().out
        assert text in out, (output, out)


def test_a_date_at_infinity_leaves_the_other_columns_as_they_are(data, capsys):
    """``coalesce(t, 'infinity')`` beside a list and a timestamp: only that column is
    DuckDB's text; the list stays a JSON list and the timestamp keeps its format (all
    three were DuckDB's text, the list as ``"[a, b]"``, when any column held infinity)."""
    plain = "select ['a', 'b'] as l, timestamptz '2026-03-02 06:00:00+00' as t"
    assert main(["query", "--data", str(data.path), "--format", "json", plain]) == 0
    expected = json.loads(capsys.readouterr().out)[0]
    sql = plain + ", coalesce(null, 'infinity'::timestamptz) as e"
    assert main(["query", "--data", str(data.path), "--format", "json", sql]) == 0
    assert json.loads(capsys.readouterr().out) == [{**expected, "e": "infinity"}]
    assert expected["l"] == ["a", "b"]


def test_a_hugeint_beyond_38_digits_beside_a_date_at_infinity(data, capsys):
    """Both columns DuckDB's text: the HUGEINT's re-read as text returned before the date
    at infinity was looked for, and printing it panicked in polars (a traceback)."""
    sql = "select 170141183460469231731687303715884105727::hugeint as h, 'infinity'::date as d"
    for output in ("table", "csv", "json"):
        assert main(["query", "--data", str(data.path), "--format", output, sql]) == 0
        out = capsys.readouterr().out
        assert "170141183460469231731687303715884105727" in out, (output, out)
        assert "infinity" in out, (output, out)


def test_a_result_repeating_a_column_name_keeps_each_column_s_values(data, capsys):
    """A join's two ``n`` (the second a HUGEINT sum), a BIT beside an int of the same
    name: each column keeps its own values (the text casts went by name: a traceback,
    or the first column's value twice)."""
    sql = (
        "with a as (select 1 id, 5 n), b as (select 1 id, 7 n) "
        "select a.n, sum(b.n) as n, 7 as v, '101'::bit as v from a join b using (id) group by a.n"
    )
    assert main(["query", "--data", str(data.path), "--format", "json", sql]) == 0
    assert json.loads(capsys.readouterr().out) == [{"n": 5, "n_1": "7", "v": 7, "v_1": "101"}]


def test_an_interval_inside_a_list_is_text_without_a_panic_on_stderr(data, capfd):
    """polars panics on an INTERVAL inside a list or struct; the panic was caught but
    Rust had already printed it (19 lines with RUST_BACKTRACE set): such a column is
    DuckDB's text from the start."""
    sql = "select [interval 2 day] as s, {'a': interval 1 hour} as t"
    assert main(["query", "--data", str(data.path), "--format", "json", sql]) == 0
    out, err = capfd.readouterr()
    assert json.loads(out) == [{"s": "[2 days]", "t": "{'a': '01:00:00'}"}]
    assert "panicked" not in err


def test_csv_writes_nested_values_as_json_and_json_is_strict(data, capsys):
    """A map or list column (the manifest's quarantine counts are one) goes to CSV as its
    JSON text; a NaN or an infinity goes to JSON as null, never as bare NaN."""
    sql = "select map(['a', 'b'], [1, 2]) as m, [1.5, 'nan'::double] as l"
    assert main(["query", "--data", str(data.path), "--format", "csv", sql]) == 0
    rows = list(csv.reader(io.StringIO(capsys.readouterr().out)))
    assert rows[0] == ["m", "l"]
    assert json.loads(rows[1][1]) == [1.5, None]
    assert main(["query", "--data", str(data.path), "--format", "json",
                 "select 'nan'::double as x, 'inf'::double as y, 1.5 as z"]) == 0  # fmt: skip
    assert json.loads(capsys.readouterr().out, parse_constant=pytest.fail) == [
        {"x": None, "y": None, "z": "1.5"}  # a DECIMAL exact, as DuckDB's CLI writes it
    ]


def test_a_nanosecond_timestamp_is_shown(data, capsys):
    """A TIMESTAMP_NS result (its int64 nanoseconds all within Python's dates): shown,
    not an overflow in the range check."""
    sql = "select '2020-01-01 12:00:00'::TIMESTAMP_NS as t"
    assert main(["query", "--data", str(data.path), "--format", "csv", sql]) == 0
    assert "2020-01-01" in capsys.readouterr().out
