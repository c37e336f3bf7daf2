"""The conveyance's motion (physics.conveyance) and the logger's rate-homogeneous
segments (physics.trip_rule.segment_ids), on analytic trips."""

from __future__ import annotations

import numpy as np
import pytest

from physics.conveyance import conveyance_speed, smoothed_derivative
from physics.trip_rule import segment_ids, trip_label_codes
from schemas.hoist import EXAMPLE_HOIST, load_hoist

HOIST = load_hoist(EXAMPLE_HOIST)
ACCEL = 0.7  # m/s2


def _times(rates_hz: tuple[float, ...], span_s: float, *, seed: int = 0) -> np.ndarray:
    """Sample times: ``span_s`` seconds at each rate in turn, ms-rounded with jitter."""
    rng = np.random.default_rng(seed)
    parts, start = [], 0.0
    for rate in rates_hz:
        n = round(span_s * rate)
        parts.append(start + np.arange(n) / rate)
        start += n / rate
    t = np.concatenate(parts)
    return np.round(t + rng.uniform(-1e-3, 1e-3, t.size), 3)


def _trapezoid(t: np.ndarray, start: float = 5.0, top: float = 8.0, run_s: float = 20.0):
    """Speed [m/s] and depth [m] of a trip down from the pithead at rest: accelerate at
    ``ACCEL`` to ``top``, run ``run_s``, decelerate at ``ACCEL`` to rest."""
    ramp = top / ACCEL
    u = t - start
    speed = np.clip(np.minimum(ACCEL * u, top), 0.0, None)
    down = u - ramp - run_s
    speed = np.where(down > 0, np.clip(top - ACCEL * down, 0.0, None), speed)
    # exact depth: integrate the piecewise-linear speed on a fine grid
    fine = np.linspace(t[0], t[-1], 200_001)
    fine_speed = np.clip(np.minimum(ACCEL * (fine - start), top), 0.0, None)
    fd = fine - start - ramp - run_s
    fine_speed = np.where(fd > 0, np.clip(top - ACCEL * fd, 0.0, None), fine_speed)
    depth_fine = np.concatenate(
        [[0.0], np.cumsum(0.5 * (fine_speed[1:] + fine_speed[:-1]) * np.diff(fine))]
    )
    return speed, np.interp(t, fine, depth_fine)


@pytest.mark.parametrize("rates", [(50.0, 100.0), (50.0, 10.0), (100.0, 50.0)])
def test_rate_change_starts_a_segment_and_the_acceleration_is_the_true_one(rates):
    """A constant acceleration logged at one rate, then another: one segment per rate,
    and the acceleration from the speed is the true one in both (it was scaled by the
    rate ratio, or zero where each 10 Hz step counted as a gap)."""
    t = _times(rates, 4.0)
    seg = segment_ids(t, nominal_dt_s=float(np.median(np.diff(t))))
    change = round(4.0 * rates[0]) + 1  # the first sample after a step of the new rate
    assert np.unique(seg).tolist() == [0, 1]
    assert (seg[:change] == 0).all()
    assert (seg[change:] == 1).all()
    speed = 1.0 + ACCEL * t  # constant acceleration
    accel = smoothed_derivative(
        speed, seg, dt_s=float(np.median(np.diff(t))), window_s=0.5, time_s=t
    )
    # exact up to the timestamps' 1 ms jitter (2 % of a 50 Hz step, over a 0.5 s window)
    np.testing.assert_allclose(accel, ACCEL, rtol=0.03)
    assert abs(np.median(accel[:change]) - ACCEL) < 1e-3
    assert abs(np.median(accel[change:]) - ACCEL) < 1e-3


def test_constant_rate_segments_are_the_gaps_alone():
    """Jitter and isolated dropped samples change no rate: the segments are those of the
    gap rule alone (a spacing above 3 x nominal)."""
    t = _times((50.0,), 60.0, seed=1)
    keep = np.ones(t.size, bool)
    keep[np.random.default_rng(2).choice(t.size, 60, replace=False)] = False  # dropouts
    keep[1000:1010] = False  # one gap of 0.22 s
    t = t[keep]
    expected = np.concatenate([[0], np.cumsum(np.diff(t) > 0.06)])
    np.testing.assert_array_equal(segment_ids(t, nominal_dt_s=0.02), expected)


def test_speed_from_depth_matches_the_analytic_speed():
    """A trip logged without speed: its speed is the depth's derivative (depth increasing
    downwards, speed positive down), within 0.06 m/s of the analytic speed everywhere
    (the 0.5 s window rounds the corners of the trapezoid by a * w / 8 ~ 0.05 m/s) and
    within 0.01 m/s in the median, with 1 ms jitter, dropped samples and a depth logged
    to 1 cm; the trip rule finds the one trip."""
    t = _times((50.0,), 50.0, seed=3)
    t = np.delete(t, np.random.default_rng(4).choice(np.arange(10, t.size - 10), 40, replace=False))
    speed, depth = _trapezoid(t)
    depth = np.round(depth, 2)
    seg = segment_ids(t, nominal_dt_s=0.02)
    v = conveyance_speed(t, np.full(t.size, np.nan), depth, seg, dt_s=0.02)
    assert np.abs(v - speed).max() < 0.06
    assert np.median(np.abs(v - speed)) < 0.01
    moving = np.flatnonzero(speed > 0.0)
    still = (t < t[moving[0]] - 0.5) | (t > t[moving[-1]] + 0.5)
    assert np.abs(v[still]).max() < 1e-9  # standing still half a window away: still
    _, direction, trip = trip_label_codes(t, v, np.zeros(t.size), seg, depth, HOIST)
    assert set(trip.tolist()) == {-1, 0}
    assert set(direction[trip == 0].tolist()) == {0}  # down


def test_isolated_missing_speed_is_interpolated_and_nothing_else_changes():
    t = _times((50.0,), 50.0, seed=5)
    speed, _ = _trapezoid(t)
    logged = speed.copy()
    holes = np.arange(100, t.size, 500)
    logged[holes] = np.nan
    v = conveyance_speed(t, logged, np.full(t.size, np.nan), segment_ids(t), dt_s=0.02)
    keep = np.ones(t.size, bool)
    keep[holes] = False
    np.testing.assert_array_equal(v[keep], speed[keep])
    np.testing.assert_allclose(v[holes], speed[holes], atol=ACCEL * 0.05)


def test_neither_speed_nor_depth_stays_unknown():
    t = _times((50.0,), 5.0)
    nan = np.full(t.size, np.nan)
    assert np.isnan(conveyance_speed(t, nan, nan, segment_ids(t), dt_s=0.02)).all()


def _at_rest_trips(t: np.ndarray, depth: np.ndarray, nominal_dt_s: float) -> int:
    seg = segment_ids(t, nominal_dt_s=nominal_dt_s)
    v = conveyance_speed(t, np.full(t.size, np.nan), depth, seg, dt_s=nominal_dt_s)
    _, _, trip = trip_label_codes(t, v, np.zeros(t.size), seg, depth, HOIST)
    return int(np.unique(trip[trip >= 0]).size)


def test_a_noisy_depth_at_rest_makes_no_trip_at_a_slower_rate_or_between_gaps():
    """At rest, 1 cm of depth noise: no trip in a part logged at 10 Hz after 100 Hz (its
    derivative scatters ~3 x the 100 Hz one's), nor in a 0.3 s stretch between two logger
    gaps (shorter than the window: numpy.gradient's scatter)."""
    rng = np.random.default_rng(0)
    t = np.r_[np.arange(0.0, 120.0, 0.01), 120.0 + np.arange(0.0, 120.0, 0.1)]
    assert _at_rest_trips(t, 300.0 + rng.normal(0.0, 0.01, t.size), 0.01) == 0
    t = np.arange(0.0, 120.0, 0.01)
    keep = np.ones(t.size, bool)
    keep[6000:6100] = keep[6130:6230] = False
    t = t[keep]
    assert _at_rest_trips(t, 300.0 + rng.normal(0.0, 0.01, t.size), 0.01) == 0


def test_a_depth_read_to_the_centimetre_that_toggles_at_rest_makes_no_trip():
    """An encoder at rest on a count's edge: its depth toggles by 1 cm now and then
    (most differences 0, so no noise is measured); one count's step is no motion."""
    t = np.arange(0.0, 600.0, 0.01)
    depth = np.full(t.size, 300.0)
    rng = np.random.default_rng(0)
    for s in rng.integers(0, t.size - 200, 20):
        depth[s : s + rng.integers(5, 100)] += 0.01
    assert _at_rest_trips(t, depth, 0.01) == 0
