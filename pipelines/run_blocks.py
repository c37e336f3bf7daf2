"""The block pipeline of ``ropeload run`` (:func:`pipelines.run_period.run_period`).

In the order a run does them: the extent of what is landed (:func:`period_extent`),
the context pass (:func:`read_context`), the per-block compensation whose rows a
background thread stages while the next block is computed (:func:`compensate_and_stage`),
the summaries from the blocks' partials (:func:`summarise_partials`) and the alarms of
the staged rows (:func:`block_alarms`). Memory is bounded by the block, not the period
(:mod:`transforms.blocks`).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import polars as pl

from pipelines.ingest.field_checks import within_limits
from pipelines.lake import in_time_order, scan_lake
from schemas.hoist import HoistDescription
from schemas.tables import ALARMS, ROPES, conform
from transforms.alarm_checks import LOGGED_PRESSURE
from transforms.alarms import evaluate_alarms_in_blocks
from transforms.blocks import CompensationContext, block_edges, compensate_blocks, record_context
from transforms.compensation import CompensationSettings
from transforms.reconciliation import (
    stint_partials,
    summarise_positions_from_partials,
    summarise_trips_from_partials,
    trip_partials,
)
from warehouse.landing import RopeTensionStage
from warehouse.store import DataRoot

__all__ = [
    "Extent",
    "FieldSamples",
    "block_alarms",
    "compensate_and_stage",
    "period_extent",
    "read_context",
    "summarise_partials",
]

#: What the context pass reads (:func:`transforms.blocks.record_context`).
_CONTEXT_COLUMNS = [
    "time_utc", "depth_m", "speed_m_s", "oil_temp_c", *(f"p{i}_pa" for i in ROPES),
    *(f"x{i}_m" for i in ROPES),
]  # fmt: skip
#: What each block's compensation reads.
_BLOCK_COLUMNS = _CONTEXT_COLUMNS
#: What :func:`transforms.alarms.evaluate_alarms` reads of the rope tensions.
_ALARM_COLUMNS = [
    "time_utc", "trip_id", "depth_m", "speed_m_s", "acceleration_up_m_s2", "load_n",
    *(f"p{i}_pa" for i in ROPES), *(f"tension{i}_n" for i in ROPES),
    *(f"tension_raw{i}_n" for i in ROPES),
]  # fmt: skip


@dataclass(frozen=True)
class FieldSamples:
    """The landed field samples of one hoist in the lake; ``description``: the hoist's,
    beyond whose limits :meth:`read` reads a depth, piston or speed as not logged
    (samples landed without it, :func:`pipelines.ingest.field_checks.within_limits`)."""

    data: DataRoot
    site: str
    hoist: str
    description: HoistDescription | None = None

    def scan(self, lo: dt.datetime | None, hi: dt.datetime | None) -> pl.LazyFrame:
        """``lo <= time_utc < hi``, sorted by time."""
        return scan_lake(
            self.data, "field_samples", site=self.site, hoist=self.hoist, start=lo, end=hi
        )

    def read(
        self, lo: dt.datetime, hi: dt.datetime, columns: Sequence[str | pl.Expr]
    ) -> pl.DataFrame:
        """``columns`` of ``lo <= time_utc < hi`` in time order (:func:`pipelines.lake.
        in_time_order`: the landed order, sorted only where it is not)."""
        rows = scan_lake(
            self.data, "field_samples", site=self.site, hoist=self.hoist, start=lo, end=hi,
            sort=False,
        )  # fmt: skip
        if self.description is not None:
            rows = within_limits(rows, self.description)
        return in_time_order(rows.select(columns))

    def source_files(self, lo: dt.datetime | None, hi: dt.datetime | None) -> set[str]:
        """The source files read (``runs.inputs``), without sorting the period's rows."""
        return set(
            scan_lake(
                self.data, "field_samples", site=self.site, hoist=self.hoist, start=lo, end=hi,
                sort=False,
            )
            .select(pl.col("source_sha256").unique())
            .collect(engine="streaming")["source_sha256"]
            .to_list()
        )  # fmt: skip


@dataclass(frozen=True)
class Extent:
    """What a run reads (lead-in included) and the period it lands."""

    rows: int
    first: dt.datetime
    last: dt.datetime
    in_period: int
    period_start: dt.datetime
    period_end: dt.datetime

    @property
    def stop(self) -> dt.datetime:
        """Just after the last sample read (an exclusive end)."""
        return self.last + dt.timedelta(microseconds=1)


def period_extent(
    record: pl.LazyFrame, start: dt.datetime | None, end: dt.datetime | None
) -> Extent | None:
    """Rows, first and last time of ``record`` and its rows from ``start`` on; None when
    it has no row in the period."""
    extent = record.select(
        pl.len().alias("rows"),
        pl.col("time_utc").min().alias("first"),
        pl.col("time_utc").max().alias("last"),
        ((pl.col("time_utc") >= start).sum() if start is not None else pl.len()).alias("in_period"),
    ).collect()
    rows, first, last, in_period = extent.row(0)
    if not rows or not in_period:
        return None
    return Extent(
        rows=rows,
        first=first,
        last=last,
        in_period=in_period,
        period_start=(start or first).astimezone(dt.UTC),
        period_end=(end or last + dt.timedelta(microseconds=1)).astimezone(dt.UTC),
    )


def read_context(
    samples: FieldSamples,
    hoist: HoistDescription,
    extent: Extent,
    *,
    settings: CompensationSettings,
    block: dt.timedelta,
) -> CompensationContext:
    """The context pass over the whole read (:func:`transforms.blocks.record_context`);
    identified ropes are remembered in ``<data>/cache/rope_springs``."""
    return record_context(
        lambda lo, hi: samples.read(lo, hi, _CONTEXT_COLUMNS),
        hoist,
        start=extent.first,
        end=extent.stop,
        rows=extent.rows,
        settings=settings,
        block=block,
        cache_dir=samples.data.under("cache", "rope_springs"),
    )


def compensate_and_stage(
    samples: FieldSamples,
    hoist: HoistDescription,
    stage: RopeTensionStage,
    extent: Extent,
    *,
    context: CompensationContext,
    settings: CompensationSettings,
    block: dt.timedelta,
) -> tuple[list[pl.DataFrame], list[pl.DataFrame]]:
    """Compensate block by block, stage each block's rows of the period, and return the
    blocks' stint and trip partials.

    A block's rows are written by a background thread while the next block is computed
    (at most one waits: memory stays bounded by two blocks; a writing error surfaces at
    the next block). Every write is done when this returns or raises.
    """

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return samples.read(lo, hi, _BLOCK_COLUMNS)

    writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="stage")
    try:
        stints, trips = [], []
        carry = None
        written: Future[None] | None = None
        for tensions in compensate_blocks(
            read,
            hoist,
            start=extent.first,
            end=extent.stop,
            context=context,
            settings=settings,
            block=block,
        ):
            tensions = tensions.filter(pl.col("time_utc") >= extent.period_start)
            if written is not None:
                written.result()
            written = writer.submit(stage.add, tensions)
            part, carry = stint_partials(tensions, hoist, carry=carry)
            stints.append(part)
            trips.append(trip_partials(tensions))
        if written is not None:
            written.result()
    finally:
        writer.shutdown(wait=True)
    return stints, trips


def summarise_partials(
    stints: list[pl.DataFrame],
    trips: list[pl.DataFrame],
    hoist: HoistDescription,
    *,
    run_id: str,
    payload_kg: float | None,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """``position_summary`` and ``trip_summary`` of the period from the blocks' partials."""
    positions = summarise_positions_from_partials(
        pl.concat(stints, how="diagonal_relaxed"), hoist, run_id=run_id, payload_kg=payload_kg
    )
    trip_summary = summarise_trips_from_partials(
        pl.concat(trips, how="diagonal_relaxed"),
        positions,
        run_id=run_id,
        site=hoist.hoist.site,
        hoist_name=hoist.hoist.name,
    )
    return positions, trip_summary


def block_alarms(
    stage: RopeTensionStage,
    hoist: HoistDescription,
    *,
    run_id: str,
    trips: pl.DataFrame,
    payload_kg: float | None,
    start: dt.datetime,
    end: dt.datetime,
    block: dt.timedelta,
    logged: FieldSamples | None = None,
    sample_step_s: float | None = None,
) -> pl.DataFrame:
    """Alarms of the staged rope tensions, block by block
    (:func:`transforms.alarms.evaluate_alarms_in_blocks`, ``sample_step_s`` the record's
    logger step); the sensor rules read the pressures as ``logged`` (the landed field
    samples) holds them, where given (:data:`transforms.alarm_checks.LOGGED_PRESSURE`:
    the staged ones are filtered)."""
    files = stage.files()
    if not files:
        return conform(pl.DataFrame(), ALARMS)
    staged = pl.scan_parquet(files).select(_ALARM_COLUMNS)

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        rows = staged.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi)).collect()
        if logged is None:
            return rows
        sensors = logged.read(
            lo, hi,
            ["time_utc", *(pl.col(f"p{i}_pa").alias(LOGGED_PRESSURE.format(i=i)) for i in ROPES)],
        )  # fmt: skip
        if sensors["time_utc"].equals(rows["time_utc"]):  # the staged rows are the logged
            return rows.hstack(sensors.drop("time_utc"))  # ones, in order: no join needed
        return rows.join(sensors, on="time_utc", how="left", maintain_order="left")

    return evaluate_alarms_in_blocks(
        read,
        block_edges(start, end, block),
        hoist,
        run_id=run_id,
        trip_payloads=trips,
        payload_kg=payload_kg,
        sample_step_s=sample_step_s,
    )
