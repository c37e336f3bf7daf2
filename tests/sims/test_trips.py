"""Hoist trip profiles."""

from __future__ import annotations

import numpy as np
import pytest

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.trips import day_schedule, fit_cut_trip, hold, trip


@pytest.fixture(scope="module")
def hoist():
    return load_hoist(EXAMPLE_HOIST)


def test_full_shaft_trip(hoist):
    p = trip(hoist, start_depth_m=0.0, end_depth_m=620.0, rest_before_s=2, rest_after_s=2)
    t = np.linspace(0, p.duration_s, 20001)
    v = p.speed(t)
    assert p.depth(p.duration_s) == pytest.approx(620.0)
    assert v.max() == pytest.approx(10.0)
    assert np.all(v >= -1e-12)
    assert np.abs(p.acceleration(t)).max() == pytest.approx(0.75)
    # by hand: accel 13.33 s, run 48.17 s, decel 12.67 s, creep 10 s, stop 0.67 s, rests 4 s
    assert p.duration_s == pytest.approx(88.83, abs=0.01)
    # creep: the last 5 m before the stop distance at 0.5 m/s
    near = (p.depth(t) > 620 - 5.0) & (p.depth(t) < 620 - 0.2)
    assert np.allclose(v[near], 0.5)
    assert p.direction == "down"


def test_up_trip_and_short_trip(hoist):
    up = trip(hoist, start_depth_m=600.0, end_depth_m=0.0, payload_kg=6000.0)
    assert up.depth(up.duration_s) == pytest.approx(0.0, abs=1e-9)
    assert up.speed(np.linspace(0, up.duration_s, 1000)).min() == pytest.approx(-10.0)
    assert up.payload(10.0) == 6000.0
    short = trip(hoist, start_depth_m=100.0, end_depth_m=103.0)
    assert short.depth(short.duration_s) == pytest.approx(103.0)
    assert short.speed(np.linspace(0, short.duration_s, 1000)).max() < 10.0


def test_trip_outside_shaft_raises(hoist):
    with pytest.raises(ValueError, match="outside the shaft"):
        trip(hoist, start_depth_m=0.0, end_depth_m=700.0)


def test_day_schedule_alternates_and_loads_at_bottom(hoist):
    day = day_schedule(hoist, round_trips=2, oil_temp_c=(30.0, 45.0))
    assert [p.direction for p in day] == ["down", "up", "down", "up"]
    assert day[1].payload(0.0) == 0.0
    assert day[1].payload(30.0) == 6000.0
    assert day[2].payload(0.0) == 6000.0
    assert day[2].payload(30.0) == 0.0
    starts = [p.start_time_s for p in day]
    assert np.all(np.diff(starts) > 60.0)
    assert day[0].oil_temp_c == 30.0
    assert day[-1].oil_temp_c == 45.0


def test_hold_is_at_rest():
    p = hold(depth_m=320.0, duration_s=10.0, payload_time_s=[1, 3], payload_kg=[0, 100])
    assert p.speed(5.0) == 0.0
    assert p.depth(5.0) == 320.0
    assert p.payload(2.0) == pytest.approx(50.0)


# ------------------------------------------------------------ trips a record cuts


def _logged(profile, t0_s: float, lo: float, hi: float, rate_hz: float = 20.0):
    """Encoder depth of ``profile`` (started at ``t0_s`` on the record's clock) logged
    from ``lo`` to ``hi`` with 1 cm of noise."""
    t = np.arange(lo, hi, 1.0 / rate_hz)
    rng = np.random.default_rng(5)
    return t, profile.depth(t - t0_s) + rng.normal(0.0, 0.01, t.size)


def test_a_record_ending_mid_trip_is_completed_from_its_logged_depth(hoist):
    # down 0 -> 600 m, motion from 5 s; the record ends while decelerating (at 80 s)
    full = trip(hoist, start_depth_m=0.0, end_depth_m=600.0, rest_before_s=0, rest_after_s=0)
    t, d = _logged(full, 5.0, 5.0, 80.0)
    fit = fit_cut_trip(hoist, t, d, start_depth_m=0.0, motion_start_s=5.0)
    assert fit.end_depth_m == pytest.approx(600.0, abs=0.2)  # the deceleration decides it
    assert fit.motion_end_s == pytest.approx(5.0 + full.duration_s, abs=0.1)
    assert fit.rms_m < 0.02
    # cut at full speed: every far enough stop fits; the named position wins, and the
    # profile over the logged part is the true one whatever the stop
    t, d = _logged(full, 5.0, 5.0, 40.0)
    fit = fit_cut_trip(hoist, t, d, start_depth_m=0.0, motion_start_s=5.0)
    assert fit.end_depth_m in hoist.shaft.positions_m.values()
    assert fit.rms_m < 0.02
    # up, cut while accelerating: the winder's full speed, not the speed reached so far
    up = trip(hoist, start_depth_m=600.0, end_depth_m=0.0, rest_before_s=0, rest_after_s=0)
    t, d = _logged(up, 0.0, 0.0, 10.0)
    fit = fit_cut_trip(hoist, t, d, start_depth_m=600.0, motion_start_s=0.0,
                       max_speeds_m_s=(None, 7.5))  # fmt: skip
    assert fit.max_speed_m_s is None
    assert fit.end_depth_m < 600.0 - 30.0


def test_a_record_starting_mid_trip_is_completed_back_to_its_start(hoist):
    full = trip(hoist, start_depth_m=320.0, end_depth_m=0.0, rest_before_s=0, rest_after_s=0)
    # the record starts 5 s into the motion (which began at -5 s on its clock), while
    # the conveyance still accelerates: that decides where it started
    t, d = _logged(full, -5.0, 0.0, full.duration_s - 5.0)
    fit = fit_cut_trip(hoist, t, d, end_depth_m=0.0, motion_end_s=full.duration_s - 5.0)
    assert fit.start_depth_m == pytest.approx(320.0, abs=0.5)
    assert fit.motion_start_s == pytest.approx(-5.0, abs=0.1)
    assert fit.end_depth_m == 0.0


def test_a_cut_trip_that_cannot_be_completed_says_why(hoist):
    t = np.linspace(0.0, 10.0, 100)
    with pytest.raises(ValueError, match="not both"):
        fit_cut_trip(hoist, t, t, start_depth_m=0.0, motion_start_s=0.0, end_depth_m=1.0,
                     motion_end_s=9.0)  # fmt: skip
    with pytest.raises(ValueError, match="no encoder depth"):
        fit_cut_trip(hoist, t, np.full(t.size, np.nan), start_depth_m=0.0, motion_start_s=0.0)
    with pytest.raises(ValueError, match="no net motion"):
        fit_cut_trip(hoist, t, np.full(t.size, 100.0), start_depth_m=100.0, motion_start_s=0.0)
