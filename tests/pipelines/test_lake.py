"""Lake scans: partition pruning by period, empty lake, time filter."""

from __future__ import annotations

import datetime as dt

import polars as pl
import pytest

from pipelines.lake import in_time_order, lake_partitions, scan_lake
from schemas.tables import FIELD_SAMPLES
from warehouse.store import DataRoot


def _land(root: DataRoot, date: str, times: list[dt.datetime]) -> None:
    part = root.table_dir("field_samples") / "site=s" / "hoist=h" / f"date={date}"
    part.mkdir(parents=True)
    frame = pl.DataFrame(
        {
            "time_utc": times,
            **{f"p{i}_pa": [1e6] * len(times) for i in range(1, 5)},
            "source_sha256": ["x"] * len(times),
            "source_line": list(range(len(times))),
        }
    ).with_columns(pl.col("time_utc").dt.replace_time_zone("UTC"))
    table = pl.DataFrame(schema=pl.from_arrow(FIELD_SAMPLES.empty_table()).schema)
    frame = pl.concat([table, frame], how="diagonal_relaxed").select(table.columns)
    frame.write_parquet(part / "part-0.parquet")


@pytest.fixture
def root(tmp_path):
    root = DataRoot.resolve(tmp_path)
    _land(root, "2026-03-01", [dt.datetime(2026, 3, 1, 23, 59, 59)])
    _land(root, "2026-03-02", [dt.datetime(2026, 3, 2, 0, 0, s) for s in range(3)])
    return root


def test_scan_period_filters_time(root):
    frame = scan_lake(
        root,
        "field_samples",
        site="s",
        hoist="h",
        start=dt.datetime(2026, 3, 2, 0, 0, 1),
        end=dt.datetime(2026, 3, 3),
    ).collect()
    assert frame.height == 2
    assert frame["time_utc"].dt.second().to_list() == [1, 2]


def test_scan_without_period_reads_all_sorted(root):
    frame = scan_lake(root, "field_samples", site="s", hoist="h").collect()
    assert frame.height == 4
    assert frame["time_utc"].is_sorted()


def test_scan_of_unknown_hoist_is_empty_with_schema(root):
    frame = scan_lake(root, "field_samples", site="s", hoist="other").collect()
    assert frame.height == 0
    assert frame.columns == FIELD_SAMPLES.names


def test_partitions_listed(root):
    parts = lake_partitions(root, "field_samples")
    assert parts["date"].to_list() == ["2026-03-01", "2026-03-02"]
    assert parts["files"].to_list() == [1, 1]


def test_in_time_order_keeps_ordered_rows_and_sorts_others_stably():
    t = [dt.datetime(2026, 3, 2, 0, 0, s, tzinfo=dt.UTC) for s in (0, 1, 1, 2)]
    ordered = pl.LazyFrame({"time_utc": t, "line": [0, 1, 2, 3]})
    rows = in_time_order(ordered)
    assert rows["line"].to_list() == [0, 1, 2, 3]
    # flagged sorted, as a sort leaves it: a filter on time can slice
    assert rows["time_utc"].flags["SORTED_ASC"]
    # out of order (two files overlapping): sorted, the rows of one time as read
    shuffled = pl.LazyFrame({"time_utc": [t[3], t[1], t[0], t[2]], "line": [3, 1, 0, 2]})
    assert in_time_order(shuffled)["line"].to_list() == [0, 1, 2, 3]
    tied = pl.LazyFrame({"time_utc": [t[3], t[2], t[1]], "line": [9, 7, 8]})
    assert in_time_order(tied)["line"].to_list() == [7, 8, 9]
