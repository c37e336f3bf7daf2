"""A report's local times over a daylight-saving change name both offsets."""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl

from pipelines.reports.data import Zone, run_tables
from pipelines.reports.period import HoistPeriod
from pipelines.reports.sections import hoist_sections
from pipelines.reports.series_sections import alarms_section
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from schemas.tables import ALARMS, ROPES, conform
from warehouse.store import DataRoot


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


def _rope_tensions(start: dt.datetime, minutes: int) -> pl.DataFrame:
    """A record at 1 Hz: tensions with a slow swing, no trips."""
    n = minutes * 60
    time = pl.datetime_range(start, start + (n - 1) * dt.timedelta(seconds=1), "1s", eager=True)
    swing = 1_000.0 * np.sin(np.arange(n) / 300.0)
    tensions = {f"tension{i}_n": 50_000.0 + i * 100.0 + swing for i in ROPES}
    load = sum(tensions.values())
    return pl.DataFrame(
        {"time_utc": time, "trip_id": pl.Series([None] * n, dtype=pl.Int64),
         "phase": ["standstill"] * n, "depth_m": np.full(n, 600.0),
         "acceleration_up_m_s2": np.zeros(n), **tensions, "load_raw_n": load * 1.03,
         "load_n": load}
    )  # fmt: skip


def test_time_axes_run_forward_when_the_clocks_go_back(tmp_path):
    """Berlin, 2026-10-25 00:30-01:30 UTC: clocks go back from 03:00 CEST to 02:00 CET
    at 01:00 UTC, so the period is 02:30 .. 02:30 local wall time. The time axes were
    drawn in wall time: a range from 02:30:00 to 02:29:59.99 (every line off the plot,
    the figures empty in a browser) and lines running back an hour at the change."""
    start = dt.datetime(2026, 10, 25, 0, 30, tzinfo=dt.UTC)
    end = start + dt.timedelta(hours=1)
    text = EXAMPLE_HOIST.read_text().replace('"Asia/Shanghai"', '"Europe/Berlin"')
    (tmp_path / "hoist.toml").write_text(text)
    hoist = load_hoist(tmp_path / "hoist.toml")
    period = HoistPeriod("r", hoist, start, end, "", frame=_rope_tensions(start, 60))
    data = DataRoot.resolve(tmp_path / "data")
    sections = hoist_sections(data, period, run_tables(data, ["r"]))
    drawn = [f for s in sections for f in s.figures]
    assert len(drawn) == 2  # load, ropes
    for fig in drawn:
        title = fig.layout.title.text
        low, high = (np.datetime64(v) for v in fig.layout.xaxis.range)
        assert high - low >= np.timedelta64(59, "m"), title
        for trace in fig.data:
            x = np.asarray(trace.x, dtype="datetime64[us]")
            assert (np.diff(x) >= np.timedelta64(0)).all(), (title, trace.name)
            assert ((x >= low) & (x <= high)).all(), (title, trace.name)
    words = " ".join(n.text for s in sections for n in s.notes)
    assert "Europe/Berlin" in words
