"""Logs written by the sims writers come back sample for sample (within quantisation)."""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest

from pipelines.ingest import ingest_paths
from schemas.hoist import EXAMPLE_HOIST, load_hoist

field_logs = pytest.importorskip("sims.field_logs")


@pytest.fixture(scope="module")
def truth() -> pl.DataFrame:
    rng = np.random.default_rng(4)
    n = 3000
    start = dt.datetime(2026, 3, 1, 15, 59, 0, tzinfo=dt.UTC)  # crosses local midnight
    jitter = rng.integers(-2000, 2000, n)
    t_us = np.arange(n) * 10_000 + jitter
    frame = pl.DataFrame(
        {
            "time_utc": pl.Series(
                [start + dt.timedelta(microseconds=int(u)) for u in t_us],
                dtype=pl.Datetime("us", "UTC"),
            ),
            **{f"p{i}_pa": 4.8e6 + rng.normal(0, 5e4, n) for i in range(1, 5)},
            **{f"x{i}_m": rng.normal(0, 5e-3, n) for i in range(1, 5)},
            "depth_m": np.linspace(0, 600, n),
            "speed_m_s": rng.normal(0, 1, n),
            "oil_temp_c": 30 + rng.normal(0, 1, n),
        }
    )
    frame = frame.with_columns(pl.col("time_utc").dt.truncate("1ms"))  # the CSV prints ms
    return frame.with_columns(
        pl.when(pl.int_range(n) % 97 == 0).then(None).otherwise(pl.col("p2_pa")).alias("p2_pa")
    )


_STEP = {"p": 1e3, "x": 1e-4, "depth_m": 1e-2, "speed_m_s": 1e-3, "oil_temp_c": 0.1}


def _compare(landed: pl.DataFrame, truth: pl.DataFrame, p_step: float) -> None:
    landed = landed.sort("time_utc")
    assert landed.height == truth.height
    assert landed["time_utc"].to_list() == truth["time_utc"].to_list()
    for column in truth.columns[1:]:
        step = (
            p_step
            if column.startswith("p")
            else _STEP.get(column[0] if column[0] == "x" else column)
        )
        got, want = landed[column].to_numpy(), truth[column].to_numpy()
        assert np.array_equal(np.isnan(got), np.isnan(want)), column
        assert np.nanmax(np.abs(got - want)) <= step / 2 * 1.0001, column


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"units": {"p": "bar"}, "delimiter": ";", "decimal": ",", "missing": "-9999"},
        {"units": {"p": "kPa", "x": "m"}, "delimiter": "\t", "with_offset": True, "missing": "NaN"},
    ],
)
def test_csv_round_trip(options, truth, tmp_path, root):
    hoist = load_hoist(EXAMPLE_HOIST)
    path = field_logs.write_csv(truth, tmp_path / "log.csv", hoist=hoist, **options)
    (result,) = ingest_paths([path], data=root).files
    assert (result.status, result.rows_landed, result.rows_quarantined) == (
        "landed",
        truth.height,
        0,
    )
    landed = pl.read_parquet(sorted(root.table_dir("field_samples").rglob("*.parquet")))
    p_step = {"MPa": 1e3, "bar": 1e3, "kPa": 1e3}[options.get("units", {}).get("p", "MPa")]
    _compare(landed, truth, p_step)


def test_tdms_round_trip(truth, tmp_path, root):
    hoist = load_hoist(EXAMPLE_HOIST)
    path = field_logs.write_tdms(truth, tmp_path / "log.tdms", hoist=hoist)
    (result,) = ingest_paths([path], data=root).files
    assert (result.status, result.rows_landed) == ("landed", truth.height)
    landed = pl.read_parquet(sorted(root.table_dir("field_samples").rglob("*.parquet")))
    _compare(landed, truth, 1e3)


def test_cut_last_line_round_trip_then_growth(truth, tmp_path, root):
    hoist = load_hoist(EXAMPLE_HOIST)
    path = field_logs.write_csv(truth, tmp_path / "live.csv", hoist=hoist, cut_last_line=True)
    (first,) = ingest_paths([path], data=root).files
    assert (first.status, first.rows_landed) == ("partial", truth.height - 1)
    field_logs.write_csv(truth, path, hoist=hoist)
    (second,) = ingest_paths([path], data=root).files
    assert (second.rows_read, second.rows_landed, second.rows_duplicate) == (1, 1, 0)
