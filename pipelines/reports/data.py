"""What a report reads: the runs' marts from the warehouse and their series from the lake.

* :func:`run_tables` -- ``runs``, ``position_summary``, ``trip_summary``, ``alarms`` and
  ``sanity_checks`` of a set of runs, in one read-only connection;
  :func:`discovery_rows` -- the ``discovery_findings`` of a hoist over a period.
* :func:`pipelines.reports.series.period_series` -- one hoist-period of rope tensions
  from the lake, reduced to what the plots draw (its own module).
* Local time: :class:`Zone` converts UTC to the hoist's zone (``[hoist] timezone``)
  and names it for axis titles.

Column names: the lake keeps ``load_raw_n`` (before, ``p x A``) / ``load_n`` (after)
and ``tension{i}_n``; ``trip_summary`` columns are read under their issue-18 names
(``max_load_after_n``, ``max_imbalance_after_fraction``, ``max_imbalance_after_rope``)
and also accepted under the earlier ones.
"""

from __future__ import annotations

import datetime as dt
import itertools
import zoneinfo
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl

from warehouse.store import DataRoot, open_reader

__all__ = [
    "BUCKETS",
    "MIN_VISIT_SAMPLES",
    "RunTables",
    "Zone",
    "discovery_rows",
    "run_tables",
]

_ZERO = dt.timedelta(0)

#: Pixel buckets of a time-series plot (about the width of a wide screen).
BUCKETS = 2000
#: Position stints with fewer samples are a pass by the edge of a position's window,
#: not a visit: left out of the reconciliation plots (transforms.reconciliation uses the
#: same bound for a trip's payload spread).
MIN_VISIT_SAMPLES = 5

_TRIP_RENAMES = {
    "max_load_n": "max_load_after_n",
    "max_imbalance_fraction": "max_imbalance_after_fraction",
}
_TRIP_OPTIONAL = {
    "max_load_after_n": pl.Float64,
    "max_imbalance_after_fraction": pl.Float64,
    "max_imbalance_after_rope": pl.Int32,
    "max_imbalance_after_time_utc": pl.Datetime("us", "UTC"),
}


@dataclass(frozen=True)
class Zone:
    """A hoist's time zone: UTC -> local wall time, and its name for axis titles.

    ``instead_of``: set on the UTC zone that :meth:`for_period` puts in place of a
    hoist's zone whose clocks go back within a period (its name).
    """

    name: str
    instead_of: str = ""

    @property
    def info(self) -> zoneinfo.ZoneInfo:
        return zoneinfo.ZoneInfo(self.name)

    def for_period(self, start: dt.datetime, end: dt.datetime) -> Zone:
        """This zone, or UTC in its place when its clocks go back between ``start`` and
        ``end``: local wall time repeats an hour there, so a time axis in it would run
        backwards (a period inside the repeated hour: from 02:30 to 02:29) and a table's
        times would be ambiguous."""
        if self.instead_of or not self._goes_back(start, end):
            return self
        return Zone("UTC", instead_of=self.name)

    def _goes_back(self, start: dt.datetime, end: dt.datetime) -> bool:
        """Whether the zone's UTC offset decreases somewhere in ``[start, end]`` (sampled
        every 30 minutes: zones change their offset at most a few times a year)."""
        step = dt.timedelta(minutes=30)
        moments = [start + k * step for k in range(max(int((end - start) / step), 0) + 1)]
        offsets = [m.astimezone(self.info).utcoffset() or _ZERO for m in [*moments, end]]
        return any(b < a for a, b in itertools.pairwise(offsets))

    def label(self, start: dt.datetime, end: dt.datetime | None = None) -> str:
        """``Asia/Shanghai, UTC+08:00``: the offsets at ``start`` and ``end`` (both when
        daylight saving changes between them; a period holding two changes, spring and
        autumn, names the one its ends share). UTC in place of a zone (:meth:`for_period`)
        says why."""
        if self.instead_of:
            return f"UTC, as the clocks of {self.instead_of} go back in this period"
        offsets = []
        for moment in (start, end or start):
            offset = moment.astimezone(self.info).strftime("%z")
            text = f"UTC{offset[:3]}:{offset[3:]}"
            if text not in offsets:
                offsets.append(text)
        return f"{self.name}, {' / '.join(offsets)}"

    def axis_title(self, start: dt.datetime, end: dt.datetime | None = None) -> str:
        return f"{'time' if self.instead_of else 'local time'} ({self.label(start, end)})"

    def local(self, moment: dt.datetime) -> dt.datetime:
        return moment.astimezone(self.info)

    def text(self, moment: dt.datetime | None, fmt: str = "%Y-%m-%d %H:%M:%S") -> str:
        return "" if moment is None else self.local(moment).strftime(fmt)

    def expr(self, column: str) -> pl.Expr:
        """A UTC datetime column as naive local wall time (for plots and tables)."""
        return pl.col(column).dt.convert_time_zone(self.name).dt.replace_time_zone(None)

    def wall(self, epoch_us: np.ndarray) -> np.ndarray:
        """UTC microseconds since the epoch -> naive local ``datetime64[us]``."""
        series = pl.Series(np.asarray(epoch_us, dtype=np.int64)).cast(pl.Datetime("us", "UTC"))
        return series.dt.convert_time_zone(self.name).dt.replace_time_zone(None).to_numpy()


@dataclass
class RunTables:
    """The marts of a set of runs (empty frames with their columns when none)."""

    runs: pl.DataFrame
    position_summary: pl.DataFrame
    trip_summary: pl.DataFrame
    alarms: pl.DataFrame
    sanity_checks: pl.DataFrame

    def of(self, run_id: str) -> RunTables:
        """The rows of one run."""

        def one(frame: pl.DataFrame) -> pl.DataFrame:
            return frame.filter(pl.col("run_id") == run_id) if frame.width else frame

        return RunTables(
            runs=one(self.runs),
            position_summary=one(self.position_summary),
            trip_summary=one(self.trip_summary),
            alarms=one(self.alarms),
            sanity_checks=one(self.sanity_checks),
        )


def _normalise_trips(trips: pl.DataFrame) -> pl.DataFrame:
    renames = {
        old: new for old, new in _TRIP_RENAMES.items() if old in trips.columns and new not in trips
    }
    trips = trips.rename(renames)
    missing = [pl.lit(None, dtype=t).alias(n) for n, t in _TRIP_OPTIONAL.items() if n not in trips]
    return trips.with_columns(missing) if missing else trips


def run_tables(data: DataRoot, run_ids: Sequence[str]) -> RunTables:
    """``runs`` and the marts of ``run_ids`` from the warehouse, oldest first."""
    orders = {
        "runs": "started_at_utc",
        "position_summary": "time_start_utc",
        "trip_summary": "time_start_utc",
        "alarms": "start_utc",
        "sanity_checks": "trip_id",
    }
    frames: dict[str, pl.DataFrame] = {}
    ids = sorted(set(run_ids))
    if not data.warehouse.exists():
        frames = {name: pl.DataFrame() for name in orders}
    else:
        con = open_reader(data)
        try:
            for name, order in orders.items():
                frames[name] = con.sql(
                    f"SELECT * FROM {name} WHERE list_contains($ids, run_id) ORDER BY {order}",
                    params={"ids": ids},
                ).pl()
        finally:
            con.close()
    if frames["trip_summary"].width:
        frames["trip_summary"] = _normalise_trips(frames["trip_summary"])
    return RunTables(**frames)


def discovery_rows(
    data: DataRoot, *, site: str, hoist: str, start: dt.datetime, end: dt.datetime
) -> pl.DataFrame:
    """``discovery_findings`` of a hoist whose period overlaps ``[start, end)``."""
    if not data.warehouse.exists():
        return pl.DataFrame()
    con = open_reader(data)
    try:
        return con.sql(
            "SELECT * FROM discovery_findings WHERE site = $site AND hoist = $hoist "
            "AND period_start_utc < $end AND period_end_utc > $start "
            "ORDER BY period_start_utc, run_id, iteration",
            params={"site": site, "hoist": hoist, "start": start, "end": end},
        ).pl()
    finally:
        con.close()
