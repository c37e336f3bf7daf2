"""Atomic Parquet files: what a reader can see is always a whole file or none.

Used by ingest for the lake tables and by the warehouse for compensated samples: the
file is written to a hidden temporary name in the target folder, fsynced, and renamed
over the target; the folder is fsynced after the rename.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq

__all__ = ["SORTED_COLUMNS", "write_parquet_atomic"]

_ROW_GROUP_ROWS = 256 * 1024
#: Lake columns that are sorted or nearly so in every file (each file is sorted by time;
#: a part's source lines rise with it): stored DELTA_BINARY_PACKED by default.
SORTED_COLUMNS = ("time_utc", "source_line")


def write_parquet_atomic(
    frame: pl.DataFrame,
    target: Path,
    schema: pa.Schema,
    *,
    delta: Sequence[str] | None = None,
) -> None:
    """Write ``frame`` as ``target`` (zstd, ``schema``) via temp file, fsync, ``os.replace``.

    ``delta``: integer or timestamp columns (sorted or nearly so: time, source line) to
    store with DELTA_BINARY_PACKED instead of trying a dictionary first, which for
    all-distinct values only costs time (a third less CPU and size for a field batch;
    for a 100 Hz day of rope tensions the time column is written in 0.05 s instead of
    0.66 s, and takes 0.1 MB instead of 34 MB). Default: the ``SORTED_COLUMNS`` of
    ``schema``.

    Floating-point columns are stored BYTE_STREAM_SPLIT (no dictionary attempt): the
    bytes of equal significance side by side, which zstd compresses far better than
    interleaved noisy mantissas -- for a 100 Hz day of rope tensions about 2x faster
    to write and 30 % smaller than a dictionary attempt falling back to PLAIN. Lossless.
    """
    if delta is None:
        delta = [name for name in SORTED_COLUMNS if name in schema.names]
    target.parent.mkdir(parents=True, exist_ok=True)
    table = frame.to_arrow().cast(schema)
    temporary = target.with_name(f".{target.stem}.{os.getpid()}.tmp")
    floats = [f.name for f in schema if pa.types.is_floating(f.type) and f.name not in delta]
    encoding: dict = {
        "use_dictionary": [n for n in schema.names if n not in delta and n not in floats],
        "use_byte_stream_split": floats,
    }
    if delta:
        encoding["column_encoding"] = dict.fromkeys(delta, "DELTA_BINARY_PACKED")
    try:
        with temporary.open("wb") as handle:
            pq.write_table(
                table,
                handle,
                compression="zstd",
                compression_level=1,
                row_group_size=_ROW_GROUP_ROWS,
                **encoding,
            )
            handle.flush()
            os.fsync(handle.fileno())
        temporary.replace(target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    directory = os.open(target.parent, os.O_RDONLY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)
