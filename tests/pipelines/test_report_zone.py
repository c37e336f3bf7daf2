"""A report's local times over a daylight-saving change name both offsets."""

from __future__ import annotations

import datetime as dt

import polars as pl

from pipelines.reports.data import Zone
from pipelines.reports.period import HoistPeriod
from pipelines.reports.series_sections import alarms_section
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from schemas.tables import ALARMS, conform


def test_an_alarm_table_across_the_spring_change_names_both_offsets():
    """Berlin, 2026-03-29 00:00-03:00 UTC: clocks go from UTC+01:00 to UTC+02:00 at
    01:00 UTC, so a table of local times must say both (it said the start's only, and
    an alarm at 03:00:25 local read as 02:00:25 UTC)."""
    start = dt.datetime(2026, 3, 29, tzinfo=dt.UTC)
    period = HoistPeriod("r", load_hoist(EXAMPLE_HOIST), start, start + dt.timedelta(hours=3), "")
    at = start + dt.timedelta(hours=1, seconds=25)
    alarm = {"alarm_id": "a", "run_id": "r", "site": "s", "hoist": "h", "rule": "slack_rope",
             "rope": 1, "start_utc": at, "end_utc": at + dt.timedelta(seconds=5),
             "peak_time_utc": at, "peak_value": 1.0, "threshold": 2.0}  # fmt: skip
    alarms = conform(pl.DataFrame([alarm]), ALARMS)
    zone = Zone("Europe/Berlin")
    section = alarms_section(period, alarms, zone, (period.start_utc, period.end_utc))
    (table,) = section.tables
    tz = "Europe/Berlin, UTC+01:00 / UTC+02:00"
    assert table.columns[2:4] == [f"start ({tz})", f"end ({tz})"]
    assert table.rows[0][2] == "2026-03-29 03:00:25"  # CEST: 01:00:25 UTC
