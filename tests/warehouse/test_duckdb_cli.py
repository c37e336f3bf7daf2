"""The DuckDB CLI from PyPI opens the warehouse read-only and answers as ropeload does.

The binary is the real one of the ``duckdb-cli`` dev dependency (1.5, what ``pip install
duckdb-cli`` gives an analyst; it reads storage formats <= 68, DuckDB 2.0 writes 69 by
default). The warehouse is the demo's (tests/warehouse/conftest.py).
"""

from __future__ import annotations

import hashlib
import json
import os
import select
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import duckdb
import pytest

from pipelines.cli import main
from warehouse.landing import RunRecord, land_run
from warehouse.store import (
    STORAGE_VERSION,
    DataRoot,
    _downgrade_storage,
    open_reader,
    open_writer,
    storage_version,
)

CLI = Path(sys.executable).parent / "duckdb"


def cli(database: Path, sql: str) -> subprocess.CompletedProcess[str]:
    """``duckdb -readonly <database> -json -c <sql>``: the analyst's command line."""
    return subprocess.run(
        [str(CLI), "-readonly", str(database), "-json", "-c", sql],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def cli_rows(database: Path, sql: str) -> list[dict]:
    done = cli(database, sql)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout or "[]")


def ropeload_rows(root: DataRoot, sql: str, capsys) -> list[dict]:
    capsys.readouterr()
    assert main(["query", "--data", str(root.path), "--format", "json", sql]) == 0
    return json.loads(capsys.readouterr().out)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_the_cli_is_the_pypi_one_that_refuses_duckdb_2_files(tmp_path):
    """The problem, shown: this CLI cannot read a file in DuckDB 2.0's default format."""
    assert CLI.exists(), "the duckdb-cli dev dependency is missing: uv sync"
    version = subprocess.run([str(CLI), "--version"], capture_output=True, text=True, check=True)
    assert version.stdout.startswith("v1.5."), version.stdout
    newest = tmp_path / "newest.duckdb"
    con = duckdb.connect(str(newest))  # DuckDB 2.0 without the project's setting
    con.execute("create table t as select 1 as a")
    con.close()
    refused = cli(newest, "select * from t")
    assert refused.returncode != 0
    assert "version number 69" in refused.stderr + refused.stdout


def test_the_warehouse_is_in_a_format_duckdb_1_reads(demo_warehouse):
    con = open_reader(demo_warehouse)
    try:
        assert storage_version(con) == f"{STORAGE_VERSION}+" == "v1.4.0+"
    finally:
        con.close()


ANSWERS = {
    "marts": "select count(*) as n, sum(samples) as samples, min(position) as first "
    "from position_summary",
    "lake views (absolute paths)": "select count(*) as n, sum(load_after_n) as load, "
    "max(tension_before2_n) as t2 from rope_tensions",
    "lake view as stored": "select count(*) as n, max(source_line) as last from lake_field_samples",
    "worst rope and its raw file": "select rope, trip_id, max_imbalance_after_fraction as imb, "
    "source_path from rope_trip_extremes order by imb desc limit 1",
    "time zone": "select timezone, run_count from hoists",
    "lineage": "select count(*) as n, count(distinct source_path) as files "
    "from audit_position_lineage where covers_position",
    "local time": "select strftime(timezone(h.timezone, t.max_imbalance_after_time_utc), "
    "'%Y-%m-%d %H:%M:%S.%g') as local from trip_summary t join hoists h using (site, hoist) "
    "order by trip_id",
}


@pytest.mark.parametrize("name", sorted(ANSWERS))
def test_the_cli_answers_as_ropeload_query(demo_warehouse, name, capsys):
    sql = ANSWERS[name]
    before = _sha256(demo_warehouse.warehouse)
    by_cli = cli_rows(demo_warehouse.warehouse, sql)
    by_ropeload = ropeload_rows(demo_warehouse, sql, capsys)
    assert by_cli, f"{name}: no rows"
    assert len(by_cli) == len(by_ropeload)
    for ours, theirs in zip(by_cli, by_ropeload, strict=True):
        assert ours.keys() == theirs.keys()
        for key, value in ours.items():
            if isinstance(value, float):
                assert value == pytest.approx(theirs[key], rel=1e-12), key  # summation order
            else:
                assert value == theirs[key], key
    assert _sha256(demo_warehouse.warehouse) == before  # read-only in fact


def _start_cli_session(database: Path) -> subprocess.Popen[bytes]:
    """An interactive ``duckdb -readonly`` with the file open, fed through a pipe."""
    return subprocess.Popen(
        [str(CLI), "-readonly", "-json", str(database)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,  # the wrapper script and the binary: one group to stop
    )


def _ask(session: subprocess.Popen[bytes], sql: str) -> list[dict]:
    assert session.stdin is not None
    assert session.stdout is not None
    session.stdin.write(sql.encode() + b";\n")
    session.stdin.flush()
    ready, _, _ = select.select([session.stdout], [], [], 30)
    assert ready, "the CLI did not answer in 30 s"
    return json.loads(os.read(session.stdout.fileno(), 1 << 16))


def test_a_cli_holding_the_file_open_neither_blocks_nor_breaks_a_writer(demo_warehouse, tmp_path):
    root = DataRoot.resolve(tmp_path / "data")
    shutil.copytree(demo_warehouse.path, root.path)
    session = _start_cli_session(root.warehouse)
    try:
        assert _ask(session, "select count(*) as n from runs") == [{"n": 3}]
        t0 = time.perf_counter()
        with open_writer(root, lock_timeout_s=10) as con:  # migrations, views, publish
            land_run(
                con,
                RunRecord(
                    run_id="while-the-cli-reads",
                    command="run",
                    code_version="test",
                    started_at_utc=demo_start(con),
                ),
            )
        assert time.perf_counter() - t0 < 10
        # the CLI keeps its snapshot, still answers, and the writer published
        assert _ask(session, "select count(*) as n from runs") == [{"n": 3}]
        assert cli_rows(root.warehouse, "select count(*) as n from runs") == [{"n": 4}]
        assert cli_rows(root.warehouse, "select count(*) as n from rope_trip_extremes") == [
            {"n": 8}
        ]
        assert session.poll() is None
    finally:
        if session.stdin is not None:
            session.stdin.close()
        try:
            session.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(session.pid, signal.SIGKILL)
            session.wait()
    assert session.returncode == 0, session.stderr.read() if session.stderr else ""


def demo_start(con: duckdb.DuckDBPyConnection):
    return con.sql("select min(started_at_utc) from runs").fetchall()[0][0]


def test_a_warehouse_in_duckdb_2_format_is_rewritten_once_by_the_next_writer(
    demo_warehouse, tmp_path
):
    """A warehouse an earlier ropeload wrote (format 69): the next writer converts it."""
    root = DataRoot.resolve(tmp_path / "data")
    shutil.copytree(demo_warehouse.path, root.path)
    primary_keys = "select count(*) from duckdb_constraints() where constraint_type = 'PRIMARY KEY'"
    original = duckdb.connect(str(root.warehouse), read_only=True)
    try:
        keys_before = original.sql(primary_keys).fetchall()
    finally:
        original.close()
    old = root.warehouse.with_name("v2.duckdb")
    con = duckdb.connect(":memory:")
    con.execute(f"attach '{root.warehouse}' as src (read_only)")
    con.execute(f"attach '{old}' as dst (storage_version 'latest')")
    con.execute("copy from database src to dst")
    con.close()
    old.replace(root.warehouse)
    assert "version number 69" in cli(root.warehouse, "select 1").stderr
    counts = "select (select count(*) from trip_summary) as trips, count(*) as runs from runs"
    reader = open_reader(root)
    try:
        assert storage_version(reader) == "v2.0.0+"
        expected = reader.sql(counts).fetchall()
    finally:
        reader.close()

    with open_writer(root):
        pass
    assert cli_rows(root.warehouse, counts) == [{"trips": 2, "runs": 3}]
    assert expected == [(2, 3)]
    copy = tmp_path / "copy.duckdb"
    shutil.copyfile(root.warehouse, copy)
    assert not _downgrade_storage(copy)  # once: a file in the format is left as it is
    with open_writer(root):
        pass
    reader = open_reader(root)
    try:
        assert storage_version(reader) == "v1.4.0+"
        assert reader.sql(counts).fetchall() == expected
        keys = reader.sql(primary_keys).fetchall()
    finally:
        reader.close()
    # every table's key survives the conversion (runs, manifest, alarms, ... as migrated)
    assert keys == keys_before
    assert keys[0][0] >= 5
