"""sims.replay: trips segmented from a synthetic log and replayed against known truth."""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest

from sims.discovery.cases import hidden_case
from sims.replay import estimate_noise_sigma, plan_replay, replay_fitted, replay_frame


@pytest.fixture(scope="module")
def null_case():
    return hidden_case(None, trips=3, seed=1)


def test_noise_estimate_white_noise():
    rng = np.random.default_rng(0)
    p = 5e6 + np.linspace(0, 2e5, 30000)[:, None] + rng.normal(0, 3e3, (30000, 4))
    assert estimate_noise_sigma(p, np.zeros(30000, bool)) == pytest.approx(3e3, rel=0.05)


def test_plan_recovers_trip_inputs(null_case):
    plan, info = null_case
    trips = info["day"].info["trips"]
    assert len(plan.trips) == len(trips) == plan.trips_found
    assert plan.noise_sigma_pa == pytest.approx(5e3, rel=0.1)
    for tr, truth in zip(plan.trips, trips, strict=True):
        assert tr.direction == truth["direction"]
        assert tr.start_depth_m == pytest.approx(truth["start_depth_m"], abs=0.05)
        assert tr.end_depth_m == pytest.approx(truth["end_depth_m"], abs=0.05)
        assert tr.oil_temp_c == pytest.approx(truth["oil_temp_c"], abs=0.05)
        # motion starts 5 s loading + 5 s rest after the trip's start
        assert tr.motion_start_s == pytest.approx(truth["start_s"] + 10.0, abs=0.01)


def test_replay_of_the_true_model_leaves_the_noise(null_case):
    plan, info = null_case
    result = replay_fitted(plan, passes=3)
    assert result.ok
    truth_pay = [t["payload_kg"] for t in info["day"].info["trips"]]
    np.testing.assert_allclose(result.payload_kg, truth_pay, atol=30.0)
    resid = np.concatenate([r[np.isfinite(r)] for r in result.residuals(plan)])
    assert np.sqrt(np.mean(resid**2)) < 1.15 * plan.noise_sigma_pa
    frame = replay_frame(plan, result)
    assert {"time_utc", "trip_id", "phase", "p1_pa", "p_sim4_pa"} <= set(frame.columns)


def test_replay_without_a_true_effect_shows_a_gap(null_case):
    plan, _ = null_case
    effects = [e for e in plan.hoist.model.effects if e != "conveyance_inertia"]
    result = replay_fitted(plan, effects=effects, passes=2)
    resid = np.concatenate([r[np.isfinite(r)] for r in result.residuals(plan)])
    assert np.sqrt(np.mean(resid**2)) > 10 * plan.noise_sigma_pa


def test_a_logger_gap_after_a_stop_does_not_lose_the_loading(null_case):
    """Rows missing from 1 s to 6 s after a stop (where the level before the next
    loading is read) move the reading to the nearest logged samples: the next trip's
    level before loading, its payload and its fit are as without the gap."""
    plan, info = null_case
    sensors = info["day"].sensors
    t0 = sensors["time_utc"][0]
    stop = plan.t_ref + dt.timedelta(seconds=plan.trips[0].motion_end_s)
    gapped = sensors.filter(
        (pl.col("time_utc") < stop + dt.timedelta(seconds=1))
        | (pl.col("time_utc") > stop + dt.timedelta(seconds=6))
    )
    assert gapped.height < sensors.height
    assert gapped["time_utc"][0] == t0
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=20.0)
    truth = info["day"].info["trips"][1]
    # the level before loading: the standstill pressure at the previous payload
    assert gap_plan.trips[1].p_before_pa == pytest.approx(plan.trips[1].p_before_pa, abs=5e3)
    result = replay_fitted(gap_plan, passes=3)
    assert result.payload_before_kg[1] == pytest.approx(truth["payload_before_kg"], abs=30.0)
    resid = np.concatenate([r[np.isfinite(r)] for r in result.residuals(gap_plan)])
    assert np.sqrt(np.mean(resid**2)) < 1.15 * gap_plan.noise_sigma_pa
