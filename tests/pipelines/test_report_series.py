"""The report's plot lines read chunk by chunk equal those of the whole period (issue 16).

A random record of 3.5 h at 10 Hz (noise, a spike, trips, a gap, ties, NaN tensions):
reduced an hour at a time, :func:`period_series` must give the lines, band, extremes and
per-trip worst rope it gives when every sample is read at once.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
from polars.testing import assert_frame_equal

from pipelines.reports.data import Zone
from pipelines.reports.series import period_series
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from schemas.tables import ROPES

HOIST = load_hoist(EXAMPLE_HOIST)
START = dt.datetime(2026, 3, 2, 0, 20, tzinfo=dt.UTC)


def _record() -> pl.DataFrame:
    rng = np.random.default_rng(3)
    n = int(3.5 * 3600 * 10)
    time = pl.datetime_range(
        START, START + (n - 1) * dt.timedelta(milliseconds=100), "100ms", eager=True
    )
    keep = np.ones(n, dtype=bool)
    keep[20_000:26_000] = False  # a 10-minute gap
    trip = np.where((np.arange(n) // 3000) % 3 == 1, np.arange(n) // 9000, -1)
    tensions = {
        f"tension{i}_n": np.round(50_000 + rng.normal(0, 300, n), 0)  # rounded: ties
        for i in ROPES
    }
    tensions["tension2_n"][70_000] = 90_000.0  # a spike
    tensions["tension3_n"][40_000:40_050] = np.nan  # a missing pressure inside a trip
    load = sum(tensions.values())
    frame = pl.DataFrame(
        {
            "time_utc": time,
            "trip_id": pl.Series(trip).set(pl.Series(trip < 0), None),
            "phase": np.where(trip >= 0, "run", "standstill"),
            "depth_m": rng.uniform(0, 600, n),
            "acceleration_up_m_s2": np.zeros(n),
            **tensions,
            "load_raw_n": load * 1.03,
            "load_n": load,
            "load_lo_n": load - 2000.0,
            "load_hi_n": load + 2000.0,
        }
    )
    return frame.filter(pl.Series(keep))


def test_chunked_series_equal_the_whole_period() -> None:
    frame = _record()
    trips = pl.DataFrame({"trip_id": [0, 1, 2, 3], "payload_kg": [1000.0, None, 3000.0, 0.0]})
    end = START + dt.timedelta(hours=4)
    kwargs = {"hoist": HOIST, "trips": trips, "zone": Zone("Asia/Shanghai")}
    whole = period_series(frame.lazy(), start_utc=START, end_utc=end, chunk=None, **kwargs)
    chunked = period_series(
        frame.lazy(), start_utc=START, end_utc=end, chunk=dt.timedelta(hours=1), **kwargs
    )
    assert chunked.samples == whole.samples == frame.height
    assert (chunked.first_utc, chunked.last_utc) == (whole.first_utc, whole.last_utc)
    assert chunked.lines.keys() == whole.lines.keys()
    assert len(whole.lines) >= 10
    for name, (t, y) in whole.lines.items():
        np.testing.assert_array_equal(chunked.lines[name][0], t, err_msg=name)
        np.testing.assert_array_equal(chunked.lines[name][1], y, err_msg=name)
    assert chunked.extremes == whole.extremes
    assert whole.band is not None
    assert chunked.band is not None
    for got, want in zip(chunked.band, whole.band, strict=True):
        np.testing.assert_array_equal(got, want)
    assert_frame_equal(chunked.worst_rope, whole.worst_rope)
    assert whole.worst_rope.height >= 3
