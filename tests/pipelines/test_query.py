"""``ropeload query``: read-only SQL, machine formats, one-line errors."""

from __future__ import annotations

import json

import pytest

from pipelines.cli import main
from warehouse.store import DataRoot, open_writer


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
