"""``ropeload query``: read-only SQL on the published warehouse."""

from __future__ import annotations

import io
import json
from typing import Literal

import polars as pl

from warehouse.store import DataRoot, open_reader

__all__ = ["OutputFormat", "format_result", "run_query"]

OutputFormat = Literal["table", "csv", "json"]


def run_query(sql: str, *, data: DataRoot) -> pl.DataFrame:
    """Run ``sql`` against a read-only snapshot of the warehouse.

    The connection is opened ``read_only``: statements that write fail with DuckDB's
    own message, and a nightly run landing at the same time is not disturbed.
    """
    con = open_reader(data)
    try:
        relation = con.sql(sql)  # None for statements without a result set
        return pl.DataFrame() if relation is None else relation.pl()
    finally:
        con.close()


def format_result(frame: pl.DataFrame, output: OutputFormat) -> str:
    """Render a query result for people (``table``) or programs (``csv``, ``json``)."""
    if output == "csv":
        return frame.write_csv()
    if output == "json":
        buffer = io.StringIO()
        buffer.write(json.dumps(frame.to_dicts(), default=str, indent=None))
        buffer.write("\n")
        return buffer.getvalue()
    with pl.Config(
        tbl_rows=200,
        tbl_cols=40,
        fmt_str_lengths=80,
        tbl_width_chars=200,
        tbl_hide_dataframe_shape=False,
    ):
        return f"{frame}\n"
