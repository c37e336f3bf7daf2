"""``ropeload demo``: the whole job on built-in data, and a warehouse an analyst can open."""

from __future__ import annotations

import re

import duckdb
import pytest

from pipelines.cli import main


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    data = tmp_path_factory.mktemp("demo")
    return data, data / "warehouse.duckdb"


def _demo(data, capsys) -> str:
    assert main(["demo", "--data", str(data), "--hours", "0.25", "--seed", "3"]) == 0
    return capsys.readouterr().out


def _counts(warehouse) -> dict[str, int]:
    con = duckdb.connect(str(warehouse), read_only=True)
    try:
        return {
            table: con.sql(f"select count(*) from {table}").fetchall()[0][0]
            for table in ("manifest", "position_summary", "trip_summary", "alarms")
        }
    finally:
        con.close()


def test_demo_prints_per_position_summary(demo_run, capsys):
    data, warehouse = demo_run
    out = _demo(data, capsys)
    assert "ingested 1 file(s)" in out
    rows = {
        m.group(1): [float(x) for x in m.group(2, 3, 4)]
        for m in re.finditer(
            r"^\s+(pithead|middle|bottom)\s+\d+\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)",
            out,
            flags=re.MULTILINE,
        )
    }
    assert set(rows) == {"pithead", "middle", "bottom"}
    for measured, compensated, expected in rows.values():
        # compensation brings the load to the applied one: issue 13's 1 % at stops. The
        # stick-slip solution on identified ropes leaves 0.6 % on this own simulation,
        # whose LuGre seals near their capacity more slowly than its elasto-plastic
        # ones (the share-out of the first waves met issue 5's 0.5 % here, and left 2-5 %
        # on independent data: benchmarks/eval_compensation.py)
        assert abs(compensated / expected - 1) < 0.01
        assert abs(measured / expected - 1) > abs(compensated / expected - 1)
    assert warehouse.exists()


def test_demo_warehouse_opens_read_only_for_analysts(demo_run):
    _, warehouse = demo_run
    counts = _counts(warehouse)
    assert counts["manifest"] == 1
    assert counts["position_summary"] > 0
    assert counts["trip_summary"] > 0


def test_demo_again_creates_no_duplicates(demo_run, capsys):
    data, warehouse = demo_run
    before = _counts(warehouse)
    _demo(data, capsys)
    assert _counts(warehouse) == before


def test_the_demo_of_another_seed_in_the_same_folder_is_refused(demo_run, capsys):
    """A demo with another seed where one is landed: refused with one line, nothing
    landed (its samples conflicted with the landed ones, the run compared the old
    samples with the new simulation's truth: 7-10 % 'errors')."""
    data, warehouse = demo_run
    if not warehouse.exists():  # run alone: seed 3's demo first
        _demo(data, capsys)
    before = _counts(warehouse)
    assert main(["demo", "--data", str(data), "--hours", "0.25", "--seed", "4"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "already holds the demo of another seed" in err[0]
    assert _counts(warehouse) == before
    assert not list((data / "incoming").glob(".demo-next*"))
