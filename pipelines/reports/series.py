"""What a report reads from the lake: one hoist-period's series, reduced for its plots.

:func:`period_series` -- one hoist-period of rope tensions, reduced to what the plots
draw: load before / after / expected (and the 95 % band when landed), the load error
against the expected load, each rope's deviation from the mean of the four, the lowest
and highest rope tension, each min/max-downsampled per pixel bucket
(:mod:`pipelines.reports.downsample`); and the worst rope of every trip, from every
sample. Column names as in :mod:`pipelines.reports.data`.
"""

from __future__ import annotations

import datetime as dt
import zoneinfo
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import polars as pl

from pipelines.reports.data import BUCKETS, Zone
from pipelines.reports.downsample import bucket_extremes, downsample_minmax
from schemas.hoist import HoistDescription
from schemas.tables import ROPES
from transforms.reconciliation import STEADY_PHASES, expected_load_expr

__all__ = ["PeriodSeries", "period_series"]

_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)


@dataclass
class PeriodSeries:
    """One hoist-period, downsampled for plotting (times: naive local ``datetime64``).

    ``lines[name] = (t, y)`` for ``before_kn``, ``after_kn``, ``expected_kn``,
    ``error_before_pct``, ``error_after_pct``, ``deviation{i}_pct``, ``lowest_kn``,
    ``highest_kn``; ``band = (t, lo_kn, hi_kn)`` when the band columns are landed;
    ``worst_rope``: per trip the rope furthest from the mean and that fraction.
    """

    start_utc: dt.datetime
    end_utc: dt.datetime
    samples: int
    lines: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    band: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    worst_rope: pl.DataFrame = field(default_factory=pl.DataFrame)
    extremes: dict[str, float] = field(default_factory=dict)
    first_utc: dt.datetime | None = None
    last_utc: dt.datetime | None = None

    @property
    def span_utc(self) -> tuple[dt.datetime, dt.datetime]:
        """What the time axes show: the samples' extent (the period when none)."""
        if self.first_utc is None or self.last_utc is None:
            return self.start_utc, self.end_utc
        return self.first_utc, self.last_utc


def _payload_expr(trips: pl.DataFrame) -> pl.Expr:
    """Each sample's trip payload [kg] (null outside trips or where none was inferred)."""
    known = trips.filter(pl.col("payload_kg").is_not_null()) if trips.width else trips
    if not known.height:
        return pl.lit(None, dtype=pl.Float64)
    return (
        pl.col("trip_id")
        .cast(pl.Int64)
        .replace_strict(
            known["trip_id"].cast(pl.Int64),
            known["payload_kg"].cast(pl.Float64),
            default=None,
            return_dtype=pl.Float64,
        )
    )


def period_series(
    frame: pl.LazyFrame | pl.DataFrame,
    *,
    hoist: HoistDescription,
    trips: pl.DataFrame,
    zone: Zone,
    start_utc: dt.datetime,
    end_utc: dt.datetime,
    buckets: int = BUCKETS,
    chunk: dt.timedelta | None = dt.timedelta(hours=1),
) -> PeriodSeries:
    """Rope tensions of one hoist-period reduced to the report's plot lines.

    The samples are read ``chunk`` at a time and only those that can be a bucket's
    smallest or largest value, or a trip's largest rope deviation, are kept
    (:func:`_reduced_table`), so a long period costs memory for its plot, not its samples.
    ``chunk=None`` reads every sample at once (the same lines, more memory).

    ``frame`` holds ``ROPE_TENSIONS`` rows (the lake's names); ``trips`` the run's
    ``trip_summary`` (its ``payload_kg`` gives the expected load during trips, by
    :func:`transforms.reconciliation.expected_load_expr`). The load error is drawn on the
    steady phases of trips only (``STEADY_PHASES``): while the winder accelerates the
    ropes stretch and the conveyance's acceleration is not the winder's.
    """
    lazy = frame.lazy() if isinstance(frame, pl.DataFrame) else frame
    names = lazy.collect_schema().names()
    band = "load_lo_n" in names and "load_hi_n" in names
    shared, columns = _plot_columns(hoist, trips, band=band)
    start_utc, end_utc = start_utc.astimezone(dt.UTC), end_utc.astimezone(dt.UTC)
    zone_of_column = lazy.collect_schema()["time_utc"].time_zone  # type: ignore[union-attr]
    period = lazy.filter(_between(start_utc, end_utc, zone_of_column))

    def rows(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return (
            period.filter(_between(lo, hi, zone_of_column))
            .with_columns(pl.col("time_utc").dt.convert_time_zone("UTC"))
            .with_columns(shared)
            .select(columns)
            .collect()
        )

    extent = period.select(
        pl.len(), pl.col("time_utc").min().alias("first"), pl.col("time_utc").max().alias("last")
    ).collect()
    table, samples, (t0, t1) = _reduced_table(rows, extent.row(0), buckets, chunk=chunk)
    out = PeriodSeries(start_utc=start_utc, end_utc=end_utc, samples=samples)
    if table.height == 0:
        return out
    t = table["t"].to_numpy()
    # the buckets span the samples, not the period: a day with ten minutes of logs gets
    # its 2000 buckets over those ten minutes (t0, t1 from _reduced_table)
    out.first_utc = _EPOCH + dt.timedelta(microseconds=t0)
    out.last_utc = _EPOCH + dt.timedelta(microseconds=t1)
    _add_lines(out, t, table, zone, buckets, t0, t1)
    if band:
        out.band = _band(t, table, zone, buckets, t0, t1)
    out.worst_rope = _worst_rope(table)
    return out


def _plot_columns(
    hoist: HoistDescription, trips: pl.DataFrame, *, band: bool
) -> tuple[list[pl.Expr], list[pl.Expr]]:
    """The expressions computed once per sample (``_mean``, ``_expected``, ``_steady``)
    and the plot columns built on them (``t``, ``trip_id`` and the value columns)."""
    tensions = [pl.col(f"tension{i}_n") for i in ROPES]
    # computed once per sample (the columns below reuse them)
    shared = [
        pl.mean_horizontal(tensions).alias("_mean"),
        pl.when(pl.col("trip_id").is_not_null())
        .then(expected_load_expr(hoist, payload_kg=_payload_expr(trips)))
        .alias("_expected"),
        (pl.col("trip_id").is_not_null() & pl.col("phase").is_in(list(STEADY_PHASES))).alias(
            "_steady"
        ),
    ]
    mean, expected, steady = pl.col("_mean"), pl.col("_expected"), pl.col("_steady")
    f32 = pl.Float32
    columns = [
        pl.col("time_utc").dt.epoch("us").alias("t"),
        pl.col("trip_id").cast(pl.Int64),
        (pl.col("load_raw_n") / 1e3).cast(f32).alias("before_kn"),
        (pl.col("load_n") / 1e3).cast(f32).alias("after_kn"),
        (expected / 1e3).cast(f32).alias("expected_kn"),
        pl.when(steady)
        .then((pl.col("load_raw_n") / expected - 1) * 100)
        .cast(f32)
        .alias("error_before_pct"),
        pl.when(steady)
        .then((pl.col("load_n") / expected - 1) * 100)
        .cast(f32)
        .alias("error_after_pct"),
        *[
            ((c - mean) / mean * 100).cast(f32).alias(f"deviation{i}_pct")
            for i, c in zip(ROPES, tensions, strict=True)
        ],
        (pl.min_horizontal(tensions) / 1e3).cast(f32).alias("lowest_kn"),
        (pl.max_horizontal(tensions) / 1e3).cast(f32).alias("highest_kn"),
    ]  # fmt: skip
    if band:
        columns += [
            (pl.col("load_lo_n") / 1e3).cast(f32).alias("lo_kn"),
            (pl.col("load_hi_n") / 1e3).cast(f32).alias("hi_kn"),
        ]
    return shared, columns


def _between(lo: dt.datetime, hi: dt.datetime, zone_of_column: str | None) -> pl.Expr:
    """lo <= time_utc < hi on the column as stored (so the lake scan prunes by it)."""
    if zone_of_column is None:
        lo, hi = (t.astimezone(dt.UTC).replace(tzinfo=None) for t in (lo, hi))
    else:
        lo, hi = (t.astimezone(zoneinfo.ZoneInfo(zone_of_column)) for t in (lo, hi))
    return (pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi)


def _add_lines(
    out: PeriodSeries, t: np.ndarray, table: pl.DataFrame, zone: Zone, buckets: int, t0: int,
    t1: int,
) -> None:  # fmt: skip
    """Each value column of ``table`` min/max-downsampled into ``out.lines`` (local
    time), and its smallest and largest value into ``out.extremes``."""
    for name in table.columns:
        if name in ("t", "trip_id", "lo_kn", "hi_kn"):
            continue
        y = table[name].fill_null(np.nan).to_numpy()
        t_out, y_out = downsample_minmax(t, y, buckets, t0=t0, t1=t1)
        out.lines[name] = (zone.wall(t_out), y_out)
        finite = y[np.isfinite(y)]
        if finite.size:
            out.extremes[f"{name}_min"] = float(finite.min())
            out.extremes[f"{name}_max"] = float(finite.max())


def _worst_rope(table: pl.DataFrame) -> pl.DataFrame:
    """Per trip the rope furthest from the mean of the four, and that fraction."""
    deviations = [pl.col(f"deviation{i}_pct").abs() for i in ROPES]
    return (
        table.lazy()
        .filter(pl.col("trip_id").is_not_null())
        .group_by("trip_id")
        .agg([d.max().alias(f"rope{i}") for i, d in zip(ROPES, deviations, strict=True)])
        .unpivot(index="trip_id", variable_name="rope", value_name="pct")
        .with_columns(pl.col("rope").str.strip_prefix("rope").cast(pl.Int32))
        .sort("trip_id", "pct", "rope", descending=[False, True, False])
        .group_by("trip_id", maintain_order=True)
        .first()
        .select("trip_id", "rope", (pl.col("pct") / 100).alias("fraction"))
        .collect()
    )


def _reduced_table(
    rows: Callable[[dt.datetime, dt.datetime], pl.DataFrame],
    extent: tuple[int, dt.datetime | None, dt.datetime | None],
    buckets: int,
    *,
    chunk: dt.timedelta | None,
) -> tuple[pl.DataFrame, int, tuple[int, int]]:
    """The rows (columns ``t``, ``trip_id`` and values) that the plot lines, extremes,
    band and per-trip worst rope need, how many rows there were, and the buckets' span
    (first sample's time, last sample's time + 1) [us].

    ``rows(lo, hi)`` gives the rows of ``lo <= t < hi``; ``extent`` is (count, first
    time, last time) of the period. Buckets span the samples' first to last time (as
    in :func:`period_series`); per chunk of ``chunk`` and value column the rows holding
    a bucket's first smallest and first largest value are kept, and per trip the rows
    holding each rope's largest deviation. Every bucket's and trip's extremes over the
    whole period are among them, so the lines drawn from the kept rows are those of all
    rows.
    """
    samples, first, last = extent
    if not samples or first is None or last is None:
        return rows(_EPOCH, _EPOCH), 0, (0, 0)  # no rows, but the columns
    first_utc, last_utc = first.astimezone(dt.UTC), last.astimezone(dt.UTC)
    t0 = (first_utc - _EPOCH) // dt.timedelta(microseconds=1)
    t1 = (last_utc - _EPOCH) // dt.timedelta(microseconds=1) + 1
    end = last_utc + dt.timedelta(microseconds=1)
    if chunk is None:
        return rows(first_utc, end).sort("t"), samples, (t0, t1)
    step = int(chunk.total_seconds() * 1e6)
    kept = []
    for lo in range(t0, t1, step):
        part = rows(
            _EPOCH + dt.timedelta(microseconds=lo),
            min(_EPOCH + dt.timedelta(microseconds=lo + step), end),
        )
        if part.height == 0:
            continue
        if not part["t"].is_sorted():
            part = part.sort("t")
        t = part["t"].to_numpy()
        keep = np.zeros(part.height, dtype=bool)
        for name in part.columns:
            if name in ("t", "trip_id"):
                continue
            y = part[name].cast(pl.Float64).fill_null(np.nan).to_numpy()
            _, i_min, _, i_max, _ = bucket_extremes(t, y, buckets, t0=t0, t1=t1)
            keep[i_min] = True
            keep[i_max] = True
        trips = part.with_row_index("_i").filter(pl.col("trip_id").is_not_null())
        for i in ROPES:
            deviation = pl.col(f"deviation{i}_pct").abs()
            # the largest number, and one NaN (a missing pressure) if any: a trip's
            # maximum over the kept rows is then its maximum over all, however NaN counts
            largest = trips.filter(deviation.fill_nan(None).is_not_null()).group_by("trip_id")
            nan = trips.filter(deviation.is_nan()).group_by("trip_id")
            for worst in (
                largest.agg(pl.col("_i").sort_by(deviation, descending=True).first()),
                nan.agg(pl.col("_i").first()),
            ):
                keep[worst["_i"].to_numpy()] = True
        keep[[0, -1]] = True  # the samples' extent (the time axes)
        kept.append(part.filter(pl.Series(keep)))
    return pl.concat(kept), samples, (t0, t1)


def _band(
    t: np.ndarray, table: pl.DataFrame, zone: Zone, buckets: int, t0: int, t1: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Outer envelope of the band per bucket: lowest ``lo`` and highest ``hi``."""
    lo = table["lo_kn"].fill_null(np.nan).to_numpy()
    hi = table["hi_kn"].fill_null(np.nan).to_numpy()
    b_lo, _, lo_min, _, _ = bucket_extremes(t, lo, buckets, t0=t0, t1=t1)
    b_hi, _, _, _, hi_max = bucket_extremes(t, hi, buckets, t0=t0, t1=t1)
    both, at_lo, at_hi = np.intersect1d(b_lo, b_hi, return_indices=True)
    if both.size == 0:
        return None
    centre = t0 + (both + 0.5) * ((t1 - t0) / buckets)
    return zone.wall(np.round(centre).astype(np.int64)), lo_min[at_lo], hi_max[at_hi]
