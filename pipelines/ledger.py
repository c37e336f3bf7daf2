"""The completion ledger: which hoist-days are done, read from the ``runs`` table.

Contents
--------
:func:`partition_states`, :func:`completed_partitions`, :func:`partition_ledger`
    Done, only the sanity check left, or to do; per partition.
:func:`record_failures`
    A ``runs`` row with ``status = 'failed'`` and the reason per failed partition.
:func:`fingerprint`
    Rows and checksums of the marts and lake results: re-running a night or a backfill
    range must leave it unchanged.

A partition is *done* when the latest ``runs`` row for exactly its period ``[day 00:00Z,
day+1 00:00Z)`` of its site and hoist succeeded, read exactly the ``source_sha256`` now
landed in the lake for that day, and used the current hoist description
(``hoist_sha256``). The ``runs`` row is written in the same warehouse transaction as the
marts (:func:`warehouse.landing.land_results`), so the ledger can never say done for a
landing that was not published, nor miss one that was. Late files for an old day, or a
recalibrated hoist description, make the day not-done again. Failed partitions get a
``runs`` row with ``status = 'failed'`` and the reason, so ``ropeload query "select *
from runs where status = 'failed'"`` lists them.
"""

from __future__ import annotations

import datetime as dt
import logging
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Literal

import duckdb
import polars as pl
import pyarrow as pa

from pipelines.partitions import Partition, PartitionOutcome
from pipelines.provenance import code_version, new_run_id, utc_now
from pipelines.steps import step_table_exists
from schemas.hoist import hoist_sha256
from schemas.tables import TABLES
from warehouse.landing import RunRecord, land_run
from warehouse.store import DataRoot, open_reader, open_writer

__all__ = [
    "FINGERPRINT_LAKE",
    "FINGERPRINT_TABLES",
    "LEDGER_COMMANDS",
    "PartitionState",
    "completed_partitions",
    "days_with_runs",
    "fingerprint",
    "partition_ledger",
    "partition_states",
    "record_failures",
]

# The lines of a backfill's and a night's partitions keep the name they always had.
logger = logging.getLogger("pipelines.backfill")


#: ``runs.command`` values whose runs land a day's marts (run_period); others, such as
#: ``discover`` over the same period, do not count in the ledger.
LEDGER_COMMANDS = ("run", "backfill", "nightly")


def _latest_runs(data: DataRoot) -> pl.DataFrame:
    """Latest ``runs`` row per (site, hoist, UTC day) among runs covering exactly a day."""
    empty = pl.DataFrame(
        schema={
            "site": pl.String,
            "hoist": pl.String,
            "day": pl.Date,
            "status": pl.String,
            "inputs": pl.List(pl.String),
            "hoist_sha256": pl.String,
            "run_id": pl.String,
            "trips": pl.Int64,
            "checks": pl.Int64,
            "sanity_steps": pl.Int64,
        }
    )
    if not data.warehouse.exists():
        return empty
    con = open_reader(data)
    try:
        runs = con.sql(
            "SELECT run_id, site, hoist, status, inputs, hoist_sha256, "
            "epoch_us(period_start_utc) AS start_us, epoch_us(period_end_utc) AS end_us, "
            "epoch_us(coalesce(finished_at_utc, started_at_utc)) AS at_us, "
            "(SELECT count(*) FROM trip_summary t WHERE t.run_id = r.run_id) AS trips, "
            "(SELECT count(*) FROM sanity_checks c WHERE c.run_id = r.run_id) AS checks, "
            + (
                "(SELECT count(*) FROM run_steps s WHERE s.run_id = r.run_id "
                "AND s.step = 'sanity_check') AS sanity_steps "
                if step_table_exists(con)
                else "0 AS sanity_steps "
            )
            + "FROM runs r WHERE site IS NOT NULL AND period_start_utc IS NOT NULL "
            f"AND command IN ({', '.join(repr(c) for c in LEDGER_COMMANDS)})"
        ).pl()
    finally:
        con.close()
    day_us = 86_400_000_000
    return (
        runs.filter(
            (pl.col("end_us") - pl.col("start_us") == day_us) & (pl.col("start_us") % day_us == 0)
        )
        .with_columns(
            day=pl.from_epoch(pl.col("start_us") // day_us * 86_400, time_unit="s").dt.date()
        )
        .sort("at_us")
        .group_by("site", "hoist", "day")
        .last()
        .select(empty.columns)
    )


def days_with_runs(data: DataRoot) -> set[tuple[str, str, dt.date]]:
    """(site, hoist, UTC day) of every day a ledger run covered exactly, whatever its
    outcome: a day not here was never run (the nightly's recently ingested days)."""
    return {(r["site"], r["hoist"], r["day"]) for r in _latest_runs(data).iter_rows(named=True)}


PartitionState = Literal["done", "sanity", "todo"]


def partition_states(
    data: DataRoot, partitions: Iterable[Partition], *, sanity: bool = False
) -> dict[str, tuple[PartitionState, dict[str, object] | None]]:
    """Per partition key: its state in the ledger and its latest run's ledger row.

    ``done``: the latest run of exactly its day succeeded, read exactly the inputs now
    landed, with the current hoist description, and (with ``sanity``) its sanity check
    has an outcome (``run_steps``, or trip rows landed before that table existed) or it
    had no trip. ``sanity``: all of that but the sanity check's outcome: only the check
    is left to do, the compensation stands. ``todo``: anything else.
    """
    latest = {
        (r["site"], r["hoist"], r["day"]): r for r in _latest_runs(data).iter_rows(named=True)
    }
    shas: dict[Path, str] = {}
    states: dict[str, tuple[PartitionState, dict[str, object] | None]] = {}
    for partition in partitions:
        row = latest.get((partition.source.site, partition.source.hoist, partition.day))
        states[partition.key] = ("todo", row)
        if row is None or row["status"] != "succeeded":
            continue
        sha = shas.get(partition.source.path)
        if sha is None:
            sha = shas[partition.source.path] = hoist_sha256(partition.source.path)
        if row["hoist_sha256"] != sha:
            continue
        inputs = tuple(sorted(row["inputs"] or ()))
        try:
            landed = partition.inputs(data)
        except Exception:  # unreadable lake day: not done; running it reports why
            continue
        if not inputs or inputs != landed:
            continue
        checked = not row["trips"] or row["checks"] or row["sanity_steps"]
        states[partition.key] = ("sanity" if sanity and not checked else "done", row)
    return states


def completed_partitions(
    data: DataRoot, partitions: Iterable[Partition], *, sanity: bool = False
) -> set[str]:
    """Keys of the partitions the ledger says are done (see the module docstring and
    :func:`partition_states`).

    With ``sanity``, a day with trips is done only once its sanity check has an outcome
    (landed after the run: a crash in between leaves the check to do, not the day).
    Whatever that outcome -- trips failed, skipped, or the check itself failed -- the
    day is done: an optional step's failure is a finding (:mod:`pipelines.steps`).
    """
    return {
        key
        for key, (state, _) in partition_states(data, partitions, sanity=sanity).items()
        if state == "done"
    }


def partition_ledger(data: DataRoot) -> pl.DataFrame:
    """The latest run per (site, hoist, UTC day): ``status``, ``run_id``, ``inputs``."""
    return _latest_runs(data).sort("site", "hoist", "day")


def record_failures(
    data: DataRoot, outcomes: Iterable[PartitionOutcome], *, command: str = "backfill"
) -> int:
    """One ``runs`` row with ``status = 'failed'`` and the reason per failed partition."""
    failed = [o for o in outcomes if o.status == "failed"]
    if not failed:
        return 0
    logger.info("%d failed partition(s) recorded in the runs table", len(failed))
    with open_writer(data) as con:
        for outcome in failed:
            start = dt.datetime.combine(outcome.day, dt.time(0), tzinfo=dt.UTC)
            now = utc_now()
            land_run(
                con,
                RunRecord(
                    run_id=new_run_id(command),
                    command=command,
                    code_version=code_version(),
                    started_at_utc=now,
                    finished_at_utc=now,
                    status="failed",
                    site=outcome.site,
                    hoist=outcome.hoist,
                    period_start_utc=start,
                    period_end_utc=start + dt.timedelta(days=1),
                    message=outcome.message,
                ),
            )
    return len(failed)


# ----------------------------------------------------------------------- idempotence


#: What :func:`fingerprint` compares: warehouse marts and lake results, and the columns
#: left out (run ids and wall-clock stamps differ between equal runs by design; ingest
#: accounting differs after a crash mid-file although the landed rows are the same).
FINGERPRINT_TABLES: dict[str, tuple[str, ...]] = {
    "position_summary": ("run_id",),
    "trip_summary": ("run_id",),
    "alarms": ("run_id",),
    "sanity_checks": ("run_id",),
    "quarantine": (),
}
FINGERPRINT_LAKE: dict[str, tuple[str, ...]] = {"field_samples": (), "rope_tensions": ()}


def fingerprint(data: DataRoot) -> dict[str, tuple[int, int]]:
    """(rows, order-independent checksum) per mart and lake result table.

    Two data roots with equal fingerprints hold the same rows (run ids aside); re-running
    a night or a backfill range must leave the fingerprint unchanged. Also
    ``runs_per_day`` (rows, distinct (site, hoist, day)) of succeeded day runs and
    ``manifest`` (rows, checksum of source_sha256 and status).
    """
    out: dict[str, tuple[int, int]] = {}
    con = open_reader(data)
    try:
        for table, skip in FINGERPRINT_TABLES.items():
            columns = [c for c in TABLES[table].names if c not in skip]
            out[table] = _checksum(con, table, columns, table)
        out["manifest"] = _checksum(
            con, "manifest", ["source_sha256", "status", "rows_read"], "manifest"
        )
        ((rows, days),) = con.sql(
            "SELECT count(*), count(DISTINCT (site, hoist, period_start_utc)) FROM runs "
            "WHERE status = 'succeeded' AND period_end_utc - period_start_utc = INTERVAL 1 DAY"
        ).fetchall()
        out["runs_per_day"] = (int(rows), int(days))
        for table, skip in FINGERPRINT_LAKE.items():
            files = sorted(data.table_dir(table).glob("site=*/hoist=*/date=*/*.parquet"))
            if not files:
                out[table] = (0, 0)
                continue
            columns = [c for c in TABLES[table].names if c not in skip]
            listed = ", ".join(f"'{f}'" for f in files)
            out[table] = _checksum(
                con, f"read_parquet([{listed}], hive_partitioning = false)", columns, table
            )
    finally:
        con.close()
    return out


def _checksum(
    con: duckdb.DuckDBPyConnection, relation: str, columns: Sequence[str], table: str
) -> tuple[int, int]:
    """Row count and order-independent hash sum; doubles hashed as float32, so that the
    last-bit noise of multi-threaded float sums (~1e-16 relative) is not a difference."""
    schema = TABLES[table]
    quoted = ", ".join(
        f'CAST("{c}" AS FLOAT)' if schema.field(c).type == pa.float64() else f'"{c}"'
        for c in columns
    )
    ((rows, total),) = con.sql(
        f"SELECT count(*), coalesce(sum(hash({quoted})::HUGEINT) % 18446744073709551557, 0) "
        f"FROM {relation}"
    ).fetchall()
    return int(rows), int(total)
