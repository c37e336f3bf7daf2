"""The fused per-rope kernel of transforms.compensation against the public functions it
fuses: step lengths and increments written out here, the branch loss
(``sensor_minus_chamber_pa``), the friction laws (``friction_parameters``) and the
friction models (``maxwell_slip_friction``, ``lugre_friction``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from transforms.compensation import ROPE_STATE_BASE, _rope_kernel
from transforms.friction import (
    STRIBECK_SPEED_FLOOR_M_S,
    friction_parameters,
    lugre_friction,
    maxwell_slip_elements,
    maxwell_slip_friction,
)
from transforms.kinematics import _savgol_derivative
from transforms.pressure_loss import RE_LAMINAR, _branch_constants, sensor_minus_chamber_pa


def _random_record(rng: np.random.Generator, n: int = 20_000):
    time_s = np.cumsum(np.where(rng.random(n) < 0.001, 5.0, 0.01))
    segment = np.cumsum(np.r_[0, np.diff(time_s) > 0.03])
    held = rng.random(n) < 0.5  # the friction state sees standstill too
    x = np.cumsum(np.where(held, 0.0, rng.normal(0.0, 2e-6, n)))
    p = 6e6 + rng.normal(0.0, 2e5, n)
    p[rng.random(n) < 0.001] = np.nan
    return time_s, segment, x, p


def _steps_and_increments(time_s, segment, x, nominal_dt_s):
    """dt[i] = t[i] - t[i-1] (the nominal step at a segment's start) and the velocity
    (x[i] - x[i-1]) / dt[i] (0 at a segment's start or where x is unknown)."""
    start = np.r_[True, segment[1:] != segment[:-1]]
    dt = np.where(start, nominal_dt_s, np.diff(time_s, prepend=time_s[0]))
    with np.errstate(invalid="ignore"):
        v = np.diff(x, prepend=x[0]) / dt
    v[start | ~np.isfinite(v)] = 0.0
    return dt, v


@pytest.mark.parametrize("presliding", [True, False])
def test_rope_kernel_matches_composed_functions(presliding: bool) -> None:
    hoist = load_hoist(EXAMPLE_HOIST)
    law = hoist.friction_law
    rng = np.random.default_rng(3)
    time_s, segment, x, p_sensor = _random_record(rng)
    n = x.size
    dt, v = _steps_and_increments(time_s, segment, x, 0.01)

    v_flow = rng.normal(0.0, 1e-3, n)
    v_flow[rng.random(n) < 0.3] = 0.0
    v_flow[rng.random(n) < 0.001] = np.nan
    nu = np.full(n, 46e-6) + rng.normal(0.0, 1e-7, n)
    area_ratio, d, length, _, k_local = _branch_constants(hoist)
    v_known = np.where(np.isfinite(v_flow), v_flow, 0.0)
    flowing = v_known != 0.0
    expected_loss = np.zeros(n)
    expected_loss[flowing] = sensor_minus_chamber_pa(v_known[flowing], hoist, nu_m2_s=nu[flowing])

    coefficients = np.array(
        [law.coulomb_n, law.static_n, law.stribeck_speed_m_s, law.viscous_n_s_m], dtype=float
    )
    floors = np.array([0.0, 0.0, STRIBECK_SPEED_FLOOR_M_S, 0.0])
    stiffness, weights = maxwell_slip_elements(law.presliding_elements, law.bristle_stiffness_n_m)
    branch = np.array(
        [area_ratio, d, length, hoist.oil.density_kg_m3, k_local, RE_LAMINAR], dtype=float
    )
    results = []
    for loss_mode in (0, 1):  # the loss given, or the laminar loss computed inline
        out = [np.empty(n) for _ in range(4)]
        assert _rope_kernel(
            x, time_s, 0.03, 0.01, p_sensor, loss_mode, expected_loss, v_flow, nu, branch,
            coefficients, floors, 1 if presliding else 2, stiffness, weights,
            law.bristle_stiffness_n_m, law.bristle_damping_n_s_m,
            hoist.cylinders.bore_area_m2, *out, np.zeros(ROPE_STATE_BASE + weights.size),
        )  # fmt: skip
        results.append(out)
    for given, inline in zip(*results, strict=True):
        np.testing.assert_allclose(inline, given, rtol=1e-12)
    p_chamber, friction, tension_raw, tension = results[0]
    np.testing.assert_array_equal(p_chamber, p_sensor - expected_loss)
    p_law = np.where(np.isfinite(p_chamber), p_chamber, 0.0)
    fc, fs, vs, kv = friction_parameters(p_law, law)
    if presliding:
        expected, _ = maxwell_slip_friction(v, dt, fc, fs, vs, kv, stiffness, weights)
    else:
        sigma0, sigma1 = law.bristle_stiffness_n_m, law.bristle_damping_n_s_m
        expected, _ = lugre_friction(v, dt, fc, fs, vs, kv, sigma0, sigma1)
    scale = np.max(np.abs(expected))
    np.testing.assert_allclose(friction, expected, rtol=1e-12, atol=1e-12 * scale)
    area = hoist.cylinders.bore_area_m2
    np.testing.assert_array_equal(tension_raw, p_sensor * area)
    np.testing.assert_allclose(tension, p_chamber * area + expected, rtol=1e-12)


def test_rope_kernel_reports_turbulence() -> None:
    hoist = load_hoist(EXAMPLE_HOIST)
    area_ratio, d, length, _, k_local = _branch_constants(hoist)
    v = np.array([0.0, 1e-3, 100.0])
    nu = np.array([46e-6])
    branch = np.array([area_ratio, d, length, 870.0, k_local, RE_LAMINAR])
    out = [np.empty(3) for _ in range(4)]
    ones = np.ones(1)
    assert not _rope_kernel(
        np.zeros(3), np.arange(3) * 0.01, 0.03, 0.01, np.full(3, 6e6), 1, ones, v, nu,
        branch, np.zeros((4, 2)), np.zeros(4), 0, ones, ones, 1.0, 1.0, 1.0, *out,
        np.zeros(ROPE_STATE_BASE + 1),
    )  # fmt: skip


@pytest.mark.parametrize("n_win", [5, 21, 51])
def test_direct_savgol_matches_scipy(n_win: int) -> None:
    rng = np.random.default_rng(n_win)
    y = np.cumsum(rng.normal(0.0, 1e-4, 10 * n_win + 7))
    expected = signal.savgol_filter(y, n_win, 2, deriv=1, delta=0.01, mode="interp")
    got = _savgol_derivative(y, n_win, 2, 0.01)
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-12 * np.max(np.abs(expected)))


def test_direct_savgol_of_a_flat_signal_is_exactly_zero() -> None:
    """A piston at rest has no velocity: not ~1e-14 of its position, which scipy's
    least-squares coefficients (odd only to ~1e-14) would give, and which would put a
    tiny flow, and a branch-loss evaluation, on every sample at standstill."""
    y = np.full(500, 0.0123)
    y[300:] = 0.0125  # a step between two rests
    got = _savgol_derivative(y, 21, 2, 0.01)
    # the interior (the first and last 10 samples are scipy's end-window polynomials)
    assert np.all(got[10:289] == 0.0)
    assert np.all(got[311:-10] == 0.0)
    assert np.all(got[290:310] > 0.0)
