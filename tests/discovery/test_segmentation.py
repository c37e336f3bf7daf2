"""Discovery's trips (discovery.segmentation.record_trips) where the log lacks speed."""

from __future__ import annotations

import numpy as np

from discovery.segmentation import record_trips
from schemas.hoist import EXAMPLE_HOIST, load_hoist

HOIST = load_hoist(EXAMPLE_HOIST)


def _record(trips: int = 3, rate_hz: float = 50.0):
    """Trips down and up in turn (0.7 m/s2 to 8 m/s, 30 s at speed), 20 s apart at rest:
    times [s], speed [m/s, down > 0] and depth [m]."""
    a, top, run = 0.7, 8.0, 30.0
    t_trip = 2 * top / a + run
    t = np.arange(0.0, trips * (t_trip + 20.0) + 20.0, 1.0 / rate_hz)
    speed = np.zeros(t.size)
    for k in range(trips):
        u = t - (20.0 + k * (t_trip + 20.0))
        v = np.clip(np.minimum(np.minimum(a * u, top), a * (t_trip - u)), 0.0, None)
        speed += v if k % 2 == 0 else -v
    depth = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) / rate_hz)])
    return t, speed, depth


def test_isolated_missing_speed_does_not_split_a_trip():
    t, speed, depth = _record()
    whole = record_trips(t, speed, depth, HOIST)
    holed = speed.copy()
    holed[np.arange(250, t.size, 5000)] = np.nan  # one missing value every 100 s
    assert np.isnan(holed).sum() >= 3
    assert record_trips(t, holed, depth, HOIST) == whole
    assert len(whole[0]) == 3


def test_trips_without_speed_are_found_from_depth():
    t, speed, depth = _record()
    motions, ids, short = record_trips(t, np.full(t.size, np.nan), depth, HOIST)
    expected, expected_ids, _ = record_trips(t, speed, depth, HOIST)
    assert ids == expected_ids == [0, 1, 2]
    assert short == []
    # the motions' ends within a quarter of the derivative's 0.5 s window
    for (a, b), (a0, b0) in zip(motions, expected, strict=True):
        assert abs(t[a] - t[a0]) <= 0.15
        assert abs(t[b] - t[b0]) <= 0.15
