"""Quarantined rows go to the warehouse table ``quarantine`` (schema ``QUARANTINE``).

One row per rejected raw row: source sha256 and path, line (1-based, CSV; null for
TDMS and MCAP, where ``raw`` starts with the sample or message index), topic (MCAP),
reason and the raw text. Query it, e.g.::

    ropeload query "SELECT reason, count(*) FROM quarantine GROUP BY ALL"
"""

from __future__ import annotations

from pathlib import Path

import duckdb
import polars as pl

from schemas.tables import QUARANTINE

__all__ = ["insert_quarantine"]


def insert_quarantine(
    con: duckdb.DuckDBPyConnection,
    rejected: pl.DataFrame,
    *,
    source_sha256: str,
    source_path: Path,
    has_lines: bool,
) -> None:
    """Append ``rejected`` (columns row, topic, reason, raw) to the quarantine table."""
    if rejected.height == 0:
        return
    rows = rejected.select(
        pl.lit(source_sha256).alias("source_sha256"),
        pl.lit(str(source_path)).alias("source_path"),
        (pl.col("row") if has_lines else pl.lit(None, pl.Int64)).alias("line"),
        pl.col("topic"),
        pl.col("reason"),
        pl.col("raw"),
    )
    con.register("_quarantine_batch", rows.to_arrow().cast(QUARANTINE))
    try:
        con.execute("INSERT INTO quarantine SELECT * FROM _quarantine_batch")
    finally:
        con.unregister("_quarantine_batch")
