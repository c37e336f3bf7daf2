"""sims.replay: trips segmented from a synthetic log and replayed against known truth."""

from __future__ import annotations

import numpy as np
import pytest

from sims.discovery.cases import hidden_case
from sims.replay import estimate_noise_sigma, replay_fitted, replay_frame


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
