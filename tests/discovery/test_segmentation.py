"""Discovery's trips (discovery.segmentation.record_trips) where the log lacks speed."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from discovery.segmentation import record_trips
from schemas.hoist import EXAMPLE_HOIST, load_hoist

HOIST = load_hoist(EXAMPLE_HOIST)


A, TOP, RUN = 0.7, 8.0, 30.0  # m/s2, m/s, s
T_TRIP = 2 * TOP / A + RUN  # s from rest to rest


def _record(trips: int = 3, rate_hz: float = 50.0):
    """Trips down and up in turn (0.7 m/s2 to 8 m/s, 30 s at speed), 20 s apart at rest:
    times [s], speed [m/s, down > 0] and depth [m]."""
    a, top, t_trip = A, TOP, T_TRIP
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
    # the trip rule (|v| >= 0.02 m/s) by hand: trip k leaves rest at 20 + k (T_TRIP + 20) s
    # and reaches 0.02 m/s 0.02 / A = 0.029 s later, and leaves it as long before it
    # stops; the first and last samples within one 50 Hz step of those times
    for k, (first, last) in enumerate(whole[0]):
        start = 20.0 + k * (T_TRIP + 20.0)
        assert abs(t[first] - (start + 0.02 / A)) <= 0.02
        assert abs(t[last] - (start + T_TRIP - 0.02 / A)) <= 0.02


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
    # by hand: the speed from the depth is its least-squares slope over the centred window
    # w = 0.5 s; u0 from leaving rest, the depth A/2 u^2 for u > 0 gives, with R = w/2 + u0,
    # v(u0) = 12 / w^3 x A/2 (R^4 / 4 - u0 R^3 / 3), which reaches 0.02 m/s at u0 = -0.042 s;
    # by symmetry the trip ends 0.042 s after it stops. The first and last samples at or
    # inside those times, within one 50 Hz step.
    w = 0.5

    def slope(u0: float) -> float:
        r = w / 2 + u0
        return 12 / w**3 * A / 2 * (r**4 / 4 - u0 * r**3 / 3) - 0.02

    lead = -brentq(slope, -w / 2, 0.0)
    assert lead == pytest.approx(0.042, abs=1e-3)
    for k, (a, b) in enumerate(motions):
        start = 20.0 + k * (T_TRIP + 20.0)
        assert 0.0 <= t[a] - (start - lead) <= 0.02
        assert 0.0 <= (start + T_TRIP + lead) - t[b] <= 0.02
