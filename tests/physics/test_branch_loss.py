"""Tests for physics.branch_loss (paper eq 12-14, contract section 1a)."""

from __future__ import annotations

import math

import fluids
import numpy as np
import polars as pl
import pytest

from physics.branch_loss import (
    darcy_friction_factor,
    globe_valve_k,
    pipe_pressure_loss,
    reynolds_number,
)
from physics.oil import kinematic_viscosity
from physics.sensor_branch import sensor_minus_chamber_expr, sensor_minus_chamber_pa
from schemas.hoist import EXAMPLE_HOIST, load_hoist

HOIST = load_hoist(EXAMPLE_HOIST)


def test_laminar_friction_factor_exact():
    re = np.array([1.0, 100.0, 1999.0])
    np.testing.assert_allclose(darcy_friction_factor(re), 64.0 / re, rtol=1e-15)


def test_turbulent_friction_factor_matches_fluids():
    rng = np.random.default_rng(3)
    re = 10.0 ** rng.uniform(np.log10(4000), 7.9, 50)
    for ed in (0.0, 1.5e-4, 1e-3):
        ref = np.array([fluids.friction_factor(r, eD=ed) for r in re])
        np.testing.assert_allclose(darcy_friction_factor(re, ed), ref, rtol=2e-4)


def test_transition_is_continuous():
    re = np.array([2000.0 - 1e-6, 2000.0 + 1e-6, 4000.0 - 1e-6, 4000.0])
    f = darcy_friction_factor(re, 1e-4)
    assert f[0] == pytest.approx(f[1], rel=1e-6)
    assert f[2] == pytest.approx(f[3], rel=1e-6)


def test_laminar_pipe_loss_is_hagen_poiseuille():
    # paper eq 6: f = 128 mu l a^2 u / (pi d^4) -> dp = 128 mu l Q / (pi d^4)
    d, length, nu, rho = 0.006, 1.0, 46e-6, 900.0
    q = np.array([-2e-6, 1e-6, 3e-6])  # m3/s, Re < 20
    v = q / (math.pi * d**2 / 4)
    dp = pipe_pressure_loss(v, d, length, nu, rho)
    np.testing.assert_allclose(dp, 128 * nu * rho * length * q / (math.pi * d**4), rtol=1e-12)


def test_turbulent_loss_and_local_loss_and_sign():
    d, length, nu, rho, rough = 0.01, 2.0, 1e-6, 1000.0, 1.5e-6
    v = 3.0  # Re 30000
    lam = fluids.friction_factor(v * d / nu, eD=rough / d)
    expected = (lam * length / d + 5.0) * rho * v**2 / 2
    dp = pipe_pressure_loss(
        np.array([v, -v, 0.0]), d, length, nu, rho, roughness_m=rough, k_local=5.0
    )
    assert dp[0] == pytest.approx(expected, rel=2e-4)
    assert dp[1] == pytest.approx(-expected, rel=2e-4)  # loss opposes flow
    assert dp[2] == 0.0


def test_reynolds_number():
    assert float(reynolds_number(-2.0, 0.01, 1e-6)) == pytest.approx(20000.0)


def test_globe_valve_k_crane():
    # Crane TP-410: K = 340 f_T; fluids' f_T for 10 mm clean steel
    assert globe_valve_k(0.01) == pytest.approx(340 * fluids.ft_Crane(0.01), rel=1e-12)
    # the example hoist's K = 9.0 is Crane-consistent within 10 % for its 10 mm bore
    k = globe_valve_k(HOIST.piping.bore_m)
    assert HOIST.piping.valve_loss_coefficient == pytest.approx(k, rel=0.10)


def test_sensor_branch_sign_and_magnitude():
    v = np.array([0.005, -0.005, 0.0])
    dp = sensor_minus_chamber_pa(v, HOIST)
    assert dp[0] < 0 < dp[1]  # out of the chamber: sensor low; in: high
    assert dp[2] == 0.0
    # independent: laminar pipe + local K, 100 mm bore / 10 mm pipe -> u = 100 v
    u = 0.005 * (0.1 / 0.01) ** 2
    nu = float(kinematic_viscosity(40.0, HOIST.oil))
    rho, d, length = 900.0, 0.01, 0.8
    re = u * d / nu
    assert re < 2000
    expected = (64 / re * length / d + 9.0 + 0.5) * rho * u**2 / 2
    assert -dp[0] == pytest.approx(expected, rel=1e-9)


def test_sensor_branch_has_only_the_declared_losses():
    """Contract 4: a hoist's ``[model] effects`` say which losses its branch has. The
    described valve is no loss without ``local_loss`` and the pipe none without
    ``pipe_laminar_loss`` (as in the device simulation): each part alone is its own
    analytic term, Hagen-Poiseuille (eq 6) and K rho u|u| / 2 (eq 13)."""
    v = np.array([0.005])
    u = 0.005 * (0.1 / 0.01) ** 2
    nu = float(kinematic_viscosity(40.0, HOIST.oil))
    rho, d, length = 900.0, 0.01, 0.8
    pipe_only = HOIST.with_effects(["pipe_laminar_loss"])
    valve_only = HOIST.with_effects(["local_loss"])
    neither = HOIST.with_effects(["seal_friction"])
    poiseuille = 32 * nu * rho * length * u / d**2
    assert -sensor_minus_chamber_pa(v, pipe_only)[0] == pytest.approx(poiseuille, rel=1e-9)
    local = (9.0 + 0.5) * rho * u**2 / 2
    assert -sensor_minus_chamber_pa(v, valve_only)[0] == pytest.approx(local, rel=1e-9)
    assert sensor_minus_chamber_pa(v, neither)[0] == 0.0


def test_sensor_branch_viscosity_temperature():
    cold, warm = sensor_minus_chamber_pa(np.array([0.002, 0.002]), HOIST, np.array([10.0, 60.0]))
    assert cold < warm < 0  # colder oil, larger (laminar) loss


def test_sensor_branch_polars_expression():
    df = pl.DataFrame({"v": [0.004, -0.001, None], "t": [20.0, 50.0, 30.0]})
    out = df.select(sensor_minus_chamber_expr(pl.col("v"), HOIST, pl.col("t")).alias("dp"))
    ref = sensor_minus_chamber_pa(np.array([0.004, -0.001]), HOIST, np.array([20.0, 50.0]))
    np.testing.assert_allclose(out["dp"].to_numpy()[:2], ref)
    assert out["dp"][2] is None
    lazy = df.lazy().with_columns(sensor_minus_chamber_expr(pl.col("v"), HOIST).alias("dp"))
    assert lazy.collect()["dp"].dtype == pl.Float64


def test_vectorised_losses_broadcast_and_accept_empty_input():
    """A scalar velocity with one viscosity per sample, empty arrays and an empty
    frame give what elementwise calls give (review of the physics move)."""
    nu = np.array([46e-6, 30e-6])
    both = pipe_pressure_loss(1.0, 0.01, 1.0, nu, 900.0)
    one = [float(pipe_pressure_loss(1.0, 0.01, 1.0, n, 900.0)) for n in nu]
    np.testing.assert_allclose(both, one, rtol=1e-15)
    assert pipe_pressure_loss(np.array([]), 0.01, 1.0, np.array([]), 900.0).shape == (0,)
    assert float(darcy_friction_factor(0.0)) == np.inf  # no ZeroDivisionError
    empty = pl.DataFrame({"v": []}, schema={"v": pl.Float64})
    out = empty.select(sensor_minus_chamber_expr(pl.col("v"), HOIST).alias("dp"))
    assert out.height == 0
