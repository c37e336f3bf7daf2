"""Atomic Parquet writes: floats stored BYTE_STREAM_SPLIT, losslessly."""

from __future__ import annotations

import numpy as np
import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq

from warehouse.parquet_files import write_parquet_atomic


def test_float_columns_round_trip_byte_stream_split(tmp_path) -> None:
    rng = np.random.default_rng(0)
    values = rng.normal(6e6, 5e3, 1000)
    values[::97] = np.nan
    frame = pl.DataFrame(
        {
            "t": np.arange(1000, dtype=np.int64),
            "p": values,
            "q": pl.Series(values).fill_nan(None),
            "s": ["a", "b"] * 500,
        }
    )
    schema = pa.schema(
        [("t", pa.int64()), ("p", pa.float64()), ("q", pa.float64()), ("s", pa.string())]
    )
    target = tmp_path / "x" / "data.parquet"
    write_parquet_atomic(frame, target, schema, delta=("t",))
    back = pl.read_parquet(target)
    assert back.equals(frame, null_equal=True)
    meta = pq.ParquetFile(target).metadata.row_group(0)
    encodings = {meta.column(k).path_in_schema: meta.column(k).encodings for k in range(4)}
    assert "BYTE_STREAM_SPLIT" in encodings["p"]
    assert "BYTE_STREAM_SPLIT" in encodings["q"]
    assert "DELTA_BINARY_PACKED" in encodings["t"]
    assert not list(tmp_path.glob("x/.*.tmp"))


def test_sorted_lake_columns_are_delta_encoded_by_default(tmp_path) -> None:
    start = np.datetime64("2026-03-02T00:00:00", "us")
    frame = pl.DataFrame(
        {
            "time_utc": pl.Series(start + np.arange(5000) * np.timedelta64(10_000, "us")),
            "source_line": np.arange(5000, dtype=np.int64),
            "trip_id": np.repeat(np.arange(5, dtype=np.int64), 1000),
        }
    ).with_columns(pl.col("time_utc").dt.replace_time_zone("UTC"))
    schema = pa.schema(
        [
            ("time_utc", pa.timestamp("us", tz="UTC")),
            ("source_line", pa.int64()),
            ("trip_id", pa.int64()),
        ]
    )
    target = tmp_path / "data.parquet"
    write_parquet_atomic(frame, target, schema)
    assert pl.read_parquet(target).equals(frame)
    meta = pq.ParquetFile(target).metadata.row_group(0)
    encodings = {meta.column(k).path_in_schema: meta.column(k).encodings for k in range(3)}
    assert "DELTA_BINARY_PACKED" in encodings["time_utc"]
    assert "DELTA_BINARY_PACKED" in encodings["source_line"]
    assert "DELTA_BINARY_PACKED" not in encodings["trip_id"]
