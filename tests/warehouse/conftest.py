"""A demo warehouse for the analysts' tests: the README's queries, keys, the DuckDB CLI."""

from __future__ import annotations

import datetime as dt

import pytest

from pipelines.cli import main
from schemas.hoist import EXAMPLE_HOIST
from warehouse.store import DataRoot, open_reader


@pytest.fixture(scope="session")
def demo_warehouse(tmp_path_factory) -> DataRoot:
    """What an analyst finds after the README's first steps, every mart filled (~20 s once).

    ``ropeload demo`` (15 min of the paper hoist's synthetic day: 2 trips, 1 alarm), then
    ``ropeload run`` over the same period (adds the simulation sanity checks; replaces the
    demo's marts) and ``ropeload discover`` over the first trip (a discovery finding).
    Tests must not write to it: copy the folder first.
    """
    data = tmp_path_factory.mktemp("demo-warehouse")
    root = DataRoot.resolve(data)
    assert main(["demo", "--data", str(data), "--hours", "0.25", "--seed", "3"]) == 0
    assert main(["run", "--hoist", str(EXAMPLE_HOIST), "--data", str(data)]) == 0
    con = open_reader(root)
    try:
        start, end = con.sql(
            "select time_start_utc, time_end_utc from trip_summary order by time_start_utc"
        ).fetchall()[0]
    finally:
        con.close()
    window = [
        (start - dt.timedelta(seconds=10)).isoformat(),
        (end + dt.timedelta(seconds=10)).isoformat(),
    ]
    report = data / "reports" / "discovery.json"
    report.parent.mkdir(exist_ok=True)
    argv = ["discover", "--hoist", str(EXAMPLE_HOIST), "--data", str(data), "--json", str(report)]
    assert main([*argv, "--from", window[0], "--to", window[1]]) == 0
    return root
