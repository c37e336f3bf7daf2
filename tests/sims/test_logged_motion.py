"""sims.logged_motion: the logged motion as a replay input, the rope bounce a record shows.

Analytic motions and synthetic pressure records with known damping; and replays of
ropeload's own simulated days whose ropes ring or do not, described either way.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from discovery.cases import scenario_hoist
from discovery.planning import plan_replay
from discovery.rope_damping import with_rope_damping
from sims.field_day import generate_field_day
from sims.logged_motion import (
    KNOT_ACCELERATION_SIGMA,
    KNOT_MAX_S,
    knot_spacing_s,
    motion_knots,
    profile_from_knots,
    rope_damping_from_record,
)
from sims.replay import replay_fitted


def _trapezoid(t: np.ndarray, a: float = 0.8, vmax: float = 9.7, t0: float = 5.0):
    """Speed and depth of a 0 -> 600 m trip: accelerate at ``a`` to ``vmax``, run,
    decelerate at ``a`` (analytic)."""
    ta = vmax / a
    run = (600.0 - vmax * ta) / vmax
    tt = np.clip(t - t0, 0.0, None)
    t_end = 2 * ta + run
    v = np.where(
        tt < ta, a * tt, np.where(tt < ta + run, vmax, np.maximum(vmax - a * (tt - ta - run), 0.0))
    )
    d_acc = 0.5 * a * np.minimum(tt, ta) ** 2
    d_run = vmax * np.clip(tt - ta, 0.0, run)
    td = np.clip(tt - ta - run, 0.0, ta)
    d_dec = vmax * td - 0.5 * a * td**2
    return np.where(tt > t_end, 0.0, v), d_acc + d_run + d_dec, t0 + t_end


def test_knots_of_a_quantised_logged_trip_follow_the_analytic_depth():
    t = np.arange(0.0, 90.0, 0.02)  # 50 Hz
    rng = np.random.default_rng(1)
    t_log = t + rng.uniform(-2e-3, 2e-3, t.size)  # logger jitter
    v, _d, t_end = _trapezoid(t_log)
    v_logged = np.round(v, 3)  # 1 mm/s resolution
    knots = motion_knots(t_log, v_logged, 4.0, t_end + 1.0, 0.0, 600.0)
    assert knots is not None
    tk, vk, dk = knots
    assert vk[0] == 0.0
    assert vk[-1] == 0.0
    assert dk[-1] == pytest.approx(600.0, abs=1e-9)  # scaled to the logged travel
    prof = profile_from_knots(
        tk, vk, dk, start_s=1.0, duration_s=t_end + 5.0, payload_time_s=np.array([0.0]),
        payload_kg=np.array([100.0]), oil_temp_c=None, direction="down",
    )  # fmt: skip
    tq = np.linspace(2.0, t_end + 4.0, 3000)
    v_true, d_true, _ = _trapezoid(tq)
    # depth within 2 cm, speed within 0.05 m/s (the 0.1 s knots round the corners)
    assert np.max(np.abs(prof.depth(tq - 1.0) - d_true)) < 0.02
    assert np.max(np.abs(prof.speed(tq - 1.0) - v_true)) < 0.05
    # the acceleration is the logged one (0.8 m/s2), not a description's
    mid_acc = prof.acceleration(np.array([8.0, 10.0]) - 1.0)
    np.testing.assert_allclose(mid_acc, 0.8, atol=0.02)
    assert prof.speed(np.array([t_end + 3.0 - 1.0]))[0] == 0.0


def test_knots_need_logged_samples():
    t = np.arange(0.0, 10.0, 0.1)
    assert motion_knots(t, np.full(t.size, np.nan), 1.0, 9.0, 0.0, 10.0) is None


def _record(zeta: float | None, f_hz: float = 1.5, seed: int = 0):
    """Common-mode pressure at 50 Hz: a step at each of 6 stops, followed (zeta given)
    by a ring of 40 kPa decaying at ``zeta``; white noise of 2.5 kPa."""
    rate = 50.0
    t = np.arange(0.0, 600.0, 1 / rate)
    rng = np.random.default_rng(seed)
    p = 5e6 + rng.normal(0.0, 2.5e3, t.size)
    stops = [60.0 + 90.0 * k for k in range(6)]
    w = 2 * np.pi * f_hz
    for k, ts in enumerate(stops):
        after = t >= ts
        p[after] += 2e5 * (-1) ** k
        if zeta is not None:
            tau = t[after] - ts
            wd = w * np.sqrt(1 - zeta**2)
            p[after] += 4e4 * np.exp(-zeta * w * tau) * np.cos(wd * tau)
    quiet = np.ones(t.size, bool)
    for ts in stops:
        quiet[(t > ts - 30.0) & (t < ts + 25.0)] = False
    return t, p, stops, quiet


@pytest.mark.parametrize("zeta", [0.02, 0.05])
def test_damping_read_off_a_ringing_record(zeta):
    t, p, stops, quiet = _record(zeta)
    got, how = rope_damping_from_record(t, p, stops, quiet)
    assert got == pytest.approx(zeta, rel=0.25), how
    assert "seen after 6 of 6 stops" in how


def test_a_record_without_ringing_reads_as_critically_damped():
    t, p, stops, quiet = _record(None)
    got, how = rope_damping_from_record(t, p, stops, quiet)
    assert got == 1.0
    assert "no rope bounce above the noise after 6 of 6 stops" in how


def test_a_logger_gap_after_a_stop_is_not_read_as_ringing():
    """Rows missing from 6 s after each stop of a record without ringing, the pressure
    200 kPa higher after the gap (a trip happened in it): each stretch between gaps is
    filtered on its own. Filtered across the gaps, the pressure's jumps rang the band
    filter inside the stops' 3-7 s windows, the ropes read as ringing and the
    description's light damping was kept (the replay then rang where the record does
    not: validation day 102 with a 5-minute gap)."""
    t, p, stops, quiet = _record(None)
    keep = np.ones(t.size, bool)
    for k, ts in enumerate(stops):
        keep &= ~((t >= ts + 6.0) & (t < ts + 40.0))
        p[t >= ts + 40.0] += 2e5 * (-1) ** k
    got, how = rope_damping_from_record(t[keep], p[keep], stops, quiet[keep])
    assert got == 1.0, how
    assert "no rope bounce above the noise after 6 of 6 stops" in how


def test_a_record_too_slow_for_the_bounce_reads_no_damping():
    t, p, stops, quiet = _record(0.02)
    got, how = rope_damping_from_record(t[::10], p[::10], stops, quiet[::10])  # 5 Hz
    assert got is None
    assert "too slow" in how


def _with_damping(hoist, zeta: float):
    return hoist.model_copy(
        update={"ropes": hoist.ropes.model_copy(update={"head_rope_damping_ratio": zeta})}
    )


@pytest.fixture(scope="module")
def stiff_and_ringing_days():
    """Two simulated days of the same hoist: ropes critically damped (no ringing) and
    damped at 0.02 (ringing), 3 trips at 20 Hz each."""
    base = scenario_hoist("plain")
    days = {}
    for zeta in (1.0, 0.02):
        days[zeta] = generate_field_day(
            _with_damping(base, zeta), date="2026-03-02", seed=4, trips=3,
            hours=3 * 150.0 / 3600, sample_rate_hz=20.0, loading_s=5.0, rest_after_s=20.0,
        )  # fmt: skip
    return base, days


def _gap(plan) -> float:
    return replay_fitted(plan, passes=3).rms_gap_pa(plan)


def test_a_hoist_that_does_not_ring_replays_to_the_noise_described_as_ringing(
    stiff_and_ringing_days,
):
    base, days = stiff_and_ringing_days
    described = _with_damping(base, 0.02)
    plan = plan_replay(days[1.0].sensors, described, settle_s=20.0)
    assert plan.hoist.ropes.head_rope_damping_ratio >= 0.3
    assert any("replaces the description's 0.02" in note for note in plan.notes)
    assert _gap(plan) < 1.2 * plan.noise_sigma_pa
    # the description's ringing ropes, as the replay had them before: far from the noise
    as_described = dataclasses.replace(plan, hoist=described)
    assert _gap(as_described) > 2.0 * plan.noise_sigma_pa


def test_a_ringing_hoist_keeps_or_finds_its_damping(stiff_and_ringing_days):
    base, days = stiff_and_ringing_days
    kept = plan_replay(days[0.02].sensors, _with_damping(base, 0.02), settle_s=20.0)
    assert kept.hoist.ropes.head_rope_damping_ratio == 0.02
    assert "consistent with the description's 0.02" in kept.rope_bounce
    assert _gap(kept) < 1.2 * kept.noise_sigma_pa
    # described as barely ringing: the record says otherwise, the read damping is used
    found = plan_replay(days[0.02].sensors, _with_damping(base, 0.3), settle_s=20.0)
    assert found.hoist.ropes.head_rope_damping_ratio == pytest.approx(0.02, rel=0.3)
    assert _gap(found) < 1.5 * found.noise_sigma_pa


def test_a_ringing_read_where_none_is_loses_to_the_ropes_critically_damped(
    stiff_and_ringing_days,
):
    """A ringing read off a record whose ropes do not ring (a logger rounding coarsely
    flips between its steps after the stops, which the band reads as one: 0.008 on a
    validation trial rounded to 50 kPa, whose every trip then replayed 30-60 kPa off):
    the ropes critically damped are replayed beside it and the gap decides."""
    base, days = stiff_and_ringing_days
    described = _with_damping(base, 0.02)
    plan = plan_replay(days[1.0].sensors, described, settle_s=20.0)
    before = dataclasses.replace(plan, hoist=described, rope_bounce="read", notes=())
    chosen = with_rope_damping(before, 0.008)
    assert chosen.hoist.ropes.head_rope_damping_ratio == 1.0, chosen.rope_bounce
    assert "0.008: " in chosen.rope_bounce  # the read one was replayed and lost
    assert _gap(chosen) < 1.2 * plan.noise_sigma_pa


def test_a_read_damping_near_the_described_one_is_used_when_it_replays_closer(
    stiff_and_ringing_days,
):
    """Ropes ringing at 0.02 described as 0.035 (within a factor 2, which once passed
    for agreement unreplayed): the ratio read from the record replays the first trips
    closer and replaces the description's."""
    base, days = stiff_and_ringing_days
    plan = plan_replay(days[0.02].sensors, _with_damping(base, 0.035), settle_s=20.0)
    assert plan.hoist.ropes.head_rope_damping_ratio == pytest.approx(0.02, rel=0.3)
    assert "replaces the description's 0.035" in plan.rope_bounce, plan.rope_bounce
    assert _gap(plan) < 1.2 * plan.noise_sigma_pa


def test_a_read_damping_the_first_trips_cannot_tell_from_the_described_one_is_used(
    stiff_and_ringing_days,
):
    """Ropes ringing at 0.02 described as 0.0165 (within a factor 2, beyond the 20 % that
    passes for agreement unreplayed): the ratio read from the ringing's decay replays
    the first trips closer, by less than the 10 % a default needs to lose (22.9 against
    24.6 kPa), and is used: a measurement against a default."""
    base, days = stiff_and_ringing_days
    plan = plan_replay(days[0.02].sensors, _with_damping(base, 0.0165), settle_s=20.0)
    assert plan.hoist.ropes.head_rope_damping_ratio == pytest.approx(0.02, rel=0.1)
    assert "replaces the description's 0.0165" in plan.rope_bounce, plan.rope_bounce


def test_a_coarsely_quantised_speed_gets_knots_wide_enough_for_its_acceleration():
    """A constant 0.8 m/s2 logged at 50 Hz as a speed rounded to 0.01 m/s (with the
    encoder's 3 mm/s of noise that dithers it): at the default 0.1 s knots the
    acceleration between knots scatters by ~q / sqrt(6 r dt^3) = 0.018 m/s2 (a probe's
    record replayed a jagged inertia that a valve loss was named for); at the spacing
    knot_spacing_s chooses it stays within KNOT_ACCELERATION_SIGMA (0.005 m/s2), and a
    speed logged to 1 mm/s keeps the default."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 32.5, 0.02)  # 12.5 s at 0.8 m/s2, then 20 s at 10 m/s
    v_true = np.minimum(0.8 * t, 10.0)
    logged = np.round(v_true + rng.normal(0.0, 0.003, t.size), 2)
    spacing = knot_spacing_s(t, logged)
    assert spacing > 0.2

    def scatter(knot_s: float) -> float:
        knots = motion_knots(t, logged, 0.0, 12.4, 0.0, 62.5, at_rest_before=False,
                             at_rest_after=False, knot_s=knot_s)  # fmt: skip
        assert knots is not None
        centres, speed, _ = knots
        return float(np.std(np.diff(speed) / np.diff(centres)))

    assert scatter(0.1) > 2.5 * KNOT_ACCELERATION_SIGMA
    assert scatter(spacing) < 1.5 * KNOT_ACCELERATION_SIGMA
    fine = np.round(v_true + rng.normal(0.0, 0.003, t.size), 3)
    assert knot_spacing_s(t, fine) == 0.1
    # one value off the grid does not set the quantisation; the spacing has a ceiling
    assert knot_spacing_s(t, np.r_[logged[:-1], 0.1234]) == spacing
    assert knot_spacing_s(t, np.round(v_true, 1)) == KNOT_MAX_S


def test_knots_bridge_a_logger_gap_inside_the_trip_with_the_logged_depth():
    # a 30 s logger gap from the run into the deceleration (the trip rule bridges it:
    # the depth advanced at the running speed): a straight line between the speeds
    # either side misses the travel in it (on a validation trial ~100 m: the profile
    # ended short of the stop and the next trip's simulation could not start where the
    # conveyance was; a smaller miss is scaled over the whole trip)
    t = np.arange(0.0, 90.0, 0.02)
    t = t[(t < 45.0) | (t >= 75.0)]
    v, d, t_end = _trapezoid(t)
    after = t >= 75.0
    without = motion_knots(t, v, 4.0, t_end + 1.0, 0.0, 600.0)
    assert without is not None
    assert without[2][-1] < 550.0  # ~70 m short: more than 10 %, so not scaled
    knots = motion_knots(t, v, 4.0, t_end + 1.0, 0.0, 600.0, depth_m=d)
    assert knots is not None
    tk, vk, dk = knots
    assert dk[-1] == pytest.approx(600.0, abs=0.5)
    np.testing.assert_allclose(np.interp(t[after], tk, dk), d[after], atol=0.5)
    gap = (tk > 45.0) & (tk < 75.0)
    assert gap.sum() == 2  # a plateau in the gap
    assert (vk[gap] > 0.0).all()
    assert (vk[gap] < 12.0).all()  # at a plausible speed
    # as gently as the winder (0.8 m/s2): a step of the run's speed within 0.1 s of the
    # gap's edge made the replay's conveyance go slack and its chamber cavitate
    across = (tk > 44.0) & (tk < 76.0)
    assert np.abs(np.diff(vk[across]) / np.diff(tk[across])).max() < 1.0
    # the depth unknown at the last sample before the gap: the last known one serves
    holed = d.copy()
    holed[np.flatnonzero(t < 45.0)[-3:]] = np.nan
    knots = motion_knots(t, v, 4.0, t_end + 1.0, 0.0, 600.0, depth_m=holed)
    assert knots is not None
    assert knots[2][-1] == pytest.approx(600.0, abs=0.5)


def test_a_gap_from_the_run_into_the_creep_is_bridged_without_turning_back():
    """A 40 s gap from the 9.7 m/s run into a 0.5 m/s creep (the trip rule bridges it:
    1.8 m/s on average): one knot in the gap's middle went to -1.4 m/s to lose the
    ramps' travel; the plateau keeps going down and follows the logged depth."""
    t = np.arange(0.0, 140.0, 0.02)
    v = np.interp(t, [0, 5, 17, 60, 71.5, 130, 130.6, 140], [0, 0, 9.7, 9.7, 0.5, 0.5, 0, 0])
    d = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    keep = (t < 60.0) | (t >= 100.0)
    t, v, d = t[keep], v[keep], d[keep]
    knots = motion_knots(t, v, 4.0, 135.0, 0.0, float(d[-1]), depth_m=d)
    assert knots is not None
    tk, vk, dk = knots
    assert (vk >= 0.0).all()
    np.testing.assert_allclose(np.interp(t, tk, dk), d, atol=1.0)


def test_a_record_too_slow_for_the_bounce_lets_the_replay_choose_the_damping(
    stiff_and_ringing_days,
):
    """At 5 Hz the bounce cannot be read; the description's ringing 0.02 was kept and
    replayed every trip far from a hoist that does not ring. The replay gap decides."""
    base, days = stiff_and_ringing_days
    slow = days[1.0].sensors.gather_every(4)  # 20 Hz -> 5 Hz
    plan = plan_replay(slow, _with_damping(base, 0.02), settle_s=20.0)
    assert "too slow to see the rope bounce" in plan.rope_bounce, plan.rope_bounce
    assert plan.hoist.ropes.head_rope_damping_ratio >= 0.3, plan.rope_bounce
    assert _gap(plan) < 1.5 * plan.noise_sigma_pa
