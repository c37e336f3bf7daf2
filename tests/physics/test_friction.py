"""Tests for physics.friction_law, .lugre and .maxwell_slip: Stribeck, LuGre, Maxwell-slip.

The LuGre cases reproduce Canudas de Wit, Olsson, Astrom, Lischinsky (1995), "A new
model for control of systems with friction", IEEE TAC 40(3) 419-425, with the
paper's parameters: sigma0 = 1e5 N/m, sigma1 = sqrt(1e5) N s/m, sigma2 = 0.4 N s/m,
Fc = 1 N, Fs = 1.5 N, vs = 0.001 m/s, m = 1 kg. Independent truths: the analytic
steady state (eq 16), the analytic presliding curve of LuGre under monotone loading,
and scipy's Radau solution of the continuous LuGre ODE.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from numba import njit
from scipy.integrate import solve_ivp

from physics.friction_law import (
    STRIBECK_SPEED_FLOOR_M_S,
    friction_parameters,
    stribeck_friction,
    stribeck_g,
)
from physics.lugre import lugre_force, lugre_friction, lugre_z_step
from physics.maxwell_slip import maxwell_slip_elements, maxwell_slip_friction, maxwell_slip_step
from schemas.hoist import EXAMPLE_HOIST, FrictionLaw, load_hoist

SIGMA0 = 1e5
SIGMA1 = math.sqrt(1e5)
SIGMA2 = 0.4
FC, FS, VS = 1.0, 1.5, 0.001
MASS = 1.0


def _eq16(v: np.ndarray) -> np.ndarray:
    # written out independently of the module
    return (FC + (FS - FC) * np.exp(-((v / VS) ** 2))) * np.sign(v) + SIGMA2 * v


# --- steady state, parameters -----------------------------------------------------------
def test_stribeck_friction_limits():
    v = np.array([-1.0, -1e-3, 1e-9, 1e-3, 1.0])
    f = stribeck_friction(v, FC, FS, VS, SIGMA2)
    np.testing.assert_allclose(f, _eq16(v), rtol=1e-14)
    assert stribeck_friction(0.0, FC, FS, VS, SIGMA2) == 0.0
    assert stribeck_friction(1e-12, FC, FS, VS, 0.0) == pytest.approx(FS)  # breakaway
    assert stribeck_friction(1.0, FC, FS, VS, 0.0) == pytest.approx(FC)  # Coulomb


def test_stribeck_g_scalar():
    assert stribeck_g(0.0, FC, FS, VS) == FS
    assert stribeck_g(VS, FC, FS, VS) == pytest.approx(FC + (FS - FC) / math.e)
    assert stribeck_g(-VS, FC, FS, VS) == stribeck_g(VS, FC, FS, VS)


def test_friction_parameters_from_example_hoist():
    hoist = load_hoist(EXAMPLE_HOIST)
    area = math.pi * 0.1**2 / 4  # 100 mm bore
    fc, fs, vs, kv = friction_parameters(np.array([5e6]), hoist.friction_law)
    # TOML: coulomb = [0.0292, 0.0259] MPa per MPa, stribeck = [8.034, -0.3657] mm/s
    assert fc[0] == pytest.approx((0.0292 + 0.0259 * 5) * 1e6 * area, rel=1e-12)
    assert fs[0] == pytest.approx((0.1276 + 0.0253 * 5) * 1e6 * area, rel=1e-12)
    assert vs[0] == pytest.approx((8.034 - 0.3657 * 5) * 1e-3, rel=1e-12)
    assert kv[0] == pytest.approx((0.00121 + 0.000066 * 5) * 1e6 * area / 1e-3, rel=1e-12)


def test_friction_parameters_clipped():
    law = FrictionLaw((-10.0, 1e-6), (-5.0, 0.0), (1e-3, -1e-9), (-1.0, 0.0), 1e7, 0.0, 4)
    fc, fs, vs, kv = friction_parameters(np.array([0.0, 30e6]), law)
    assert fc.tolist() == [0.0, 20.0]
    assert fs.tolist() == [0.0, 0.0]
    assert vs[1] == STRIBECK_SPEED_FLOOR_M_S
    assert kv.tolist() == [0.0, 0.0]


# --- LuGre scalar kernels ---------------------------------------------------------------
def test_lugre_z_step_is_exact_solution():
    # dz/dt = v - sigma0 |v| z / g with constant v: closed form, checked by Radau
    v, g, z0, dt = -2e-4, 1.3, 4e-6, 3e-4
    sol = solve_ivp(
        lambda t, z: v - SIGMA0 * abs(v) * z / g,
        (0, dt),
        [z0],
        method="Radau",
        rtol=1e-12,
        atol=1e-16,
    )
    assert lugre_z_step(z0, v, dt, SIGMA0, g) == pytest.approx(sol.y[0, -1], rel=1e-8)


@pytest.mark.parametrize("sigma0", [1e6, 1e7, 5e7])  # 1 to 50 kN/mm
def test_lugre_z_step_unconditionally_stable(sigma0):
    g = 1200.0
    z = 0.0
    for v in (0.2, -0.2, 0.05, 0.0, -1e-4):
        z = lugre_z_step(z, v, 0.1, sigma0, g)  # sigma0 |v| dt / g from 17 to 8e5
        assert abs(z) <= g / sigma0 * (1 + 1e-12)
    # forward Euler with the same step would blow up: |1 - sigma0 |v| dt / g| >> 1
    assert abs(1 - sigma0 * 0.2 * 0.1 / g) > 2


def test_lugre_force_terms():
    assert lugre_force(1e-6, 2e-6, 0.5, 1e-3, 1e5, 10.0, 0.4) == pytest.approx(
        0.2 + 10.0 * 1e-3 + 0.2
    )


# --- Canudas de Wit 1995, (a) steady state ---------------------------------------------
@pytest.mark.parametrize("v", [-0.1, -2e-3, -5e-4, 1e-4, 1e-3, 3e-3, 0.05])
def test_lugre_steady_state_equals_eq16(v):
    n = 20_000
    f, z = lugre_friction(np.full(n, v), 1e-2, FC, FS, VS, SIGMA2, SIGMA0, SIGMA1)
    assert f[-1] == pytest.approx(_eq16(np.array(v)), rel=1e-9)
    assert z[-1] == pytest.approx(np.sign(v) * stribeck_g(v, FC, FS, VS) / SIGMA0, rel=1e-9)


# --- standstill holds the friction --------------------------------------------------------
def test_lugre_standstill_holds_friction():
    v = np.concatenate([np.full(5000, 2e-3), np.zeros(5000)])
    f, z = lugre_friction(v, 1e-3, FC, FS, VS, SIGMA2, SIGMA0, SIGMA1)
    held = stribeck_g(2e-3, FC, FS, VS)  # sigma0 z at the end of the motion
    assert f[4999] == pytest.approx(held + SIGMA2 * 2e-3, rel=1e-9)
    np.testing.assert_allclose(f[5000:], held, rtol=1e-12)
    assert np.all(z[5000:] == z[4999])


def test_nan_velocity_holds_state():
    v = np.array([2e-3] * 3000 + [np.nan] * 3 + [0.0] * 2)
    f, _z = lugre_friction(v, 1e-3, FC, FS, VS, SIGMA2, SIGMA0, SIGMA1)
    assert np.isnan(f[3000:3003]).all()
    assert f[-1] == pytest.approx(stribeck_g(2e-3, FC, FS, VS), rel=1e-9)
    k, w = maxwell_slip_elements(3, 1e6)
    fm, _ = maxwell_slip_friction(v, 1e-3, FC, FS, VS, SIGMA2, k, w)
    assert np.isnan(fm[3000])
    assert np.isfinite(fm[-1])


def test_lugre_per_sample_parameters_and_shapes():
    n = 100
    fc = np.linspace(1.0, 2.0, n)
    f, _ = lugre_friction(np.full(n, 0.5), np.full(n, 1.0), fc, fc, VS, 0.0, SIGMA0, 0.0)
    np.testing.assert_allclose(f, fc, rtol=1e-12)
    with pytest.raises(ValueError, match="fc"):
        lugre_friction(np.zeros(3), 1.0, np.zeros(2), 1.0, 1.0, 0.0, 1.0, 0.0)


# --- (b) frictional lag: hysteresis in F vs v, widening with frequency -----------------
def _loop_area(omega: float) -> tuple[float, np.ndarray, np.ndarray]:
    dt = 1e-5
    period = 2 * math.pi / omega
    t = np.arange(1, round(3 * period / dt) + 1) * dt
    v = 1e-3 * (np.sin(omega * (t - dt / 2)) + 1.5)  # mid-interval velocity
    f, _ = lugre_friction(v, dt, FC, FS, VS, SIGMA2, SIGMA0, SIGMA1)
    last = t > 2 * period  # one period after the transient
    fv, vv = f[last], v[last]
    area = abs(float(np.sum(0.5 * (fv[1:] + fv[:-1]) * np.diff(vv))))
    return area, vv, fv


def test_lugre_frictional_lag_loop_widens_with_frequency():
    areas = [_loop_area(w)[0] for w in (1.0, 10.0, 25.0)]
    assert areas[0] < areas[1] < areas[2]
    assert areas[0] < 0.1 * areas[2]  # slow: close to the steady-state curve
    _, v, f = _loop_area(25.0)
    accelerating = np.gradient(v) > 0
    # at the same velocity friction is higher while accelerating (lag), eq. Fig 3 of the paper
    probe = np.abs(v - 1.5e-3) < 2e-5
    assert f[probe & accelerating].mean() > f[probe & ~accelerating].mean()


def test_lugre_matches_radau_solution_of_continuous_model():
    omega, dt, t_end = 10.0, 2e-5, 1.0

    def vel(t):
        return 1e-3 * (np.sin(omega * t) + 0.5)  # crosses zero: both directions

    def rhs(t, y):
        v = vel(t)
        g = FC + (FS - FC) * math.exp(-((v / VS) ** 2))
        return [v - SIGMA0 * abs(v) * y[0] / g]

    t = np.arange(1, round(t_end / dt) + 1) * dt
    sol = solve_ivp(rhs, (0, t_end), [0.0], method="Radau", t_eval=t, rtol=1e-9, atol=1e-13)
    _, z = lugre_friction(vel(t - dt / 2), dt, FC, FS, VS, SIGMA2, SIGMA0, SIGMA1)
    scale = FS / SIGMA0
    assert np.max(np.abs(z - sol.y[0])) < 2e-3 * scale


# --- (c) presliding and (d) stick-slip: a mass driven through the njit kernels ----------
@njit(cache=True)
def _simulate_mass(n, dt, mass, k_spring, pull_speed, f_ext_ramp, f_ext_time):
    x = 0.0
    v = 0.0
    z = 0.0
    xs = np.empty(n)
    vs_out = np.empty(n)
    fs_out = np.empty(n)
    for i in range(n):
        t = (i + 1) * dt
        g = stribeck_g(v, FC, FS, VS)
        z_new = lugre_z_step(z, v, dt, SIGMA0, g)
        friction = lugre_force(z, z_new, v, dt, SIGMA0, SIGMA1, SIGMA2)
        z = z_new
        if k_spring > 0.0:
            f_ext = k_spring * (pull_speed * t - x)
        else:
            f_ext = f_ext_ramp * min(t / f_ext_time, 1.0)
        v += (f_ext - friction) / mass * dt
        x += v * dt
        xs[i] = x
        vs_out[i] = v
        fs_out[i] = f_ext
    return xs, vs_out, fs_out


def test_lugre_presliding_spring_like_without_drift():
    force = 0.5  # N, below Fs = 1.5 N and Fc = 1 N
    dt = 1e-5
    x, v, _ = _simulate_mass(int(5.0 / dt), dt, MASS, 0.0, 0.0, force, 1.0)
    # monotone loading at v << vs: dz/dx = 1 - sigma0 z / Fs, so with sigma0 z = F:
    x_expected = -(FS / SIGMA0) * math.log(1 - force / FS)
    i2, i5 = int(2.0 / dt) - 1, -1
    assert x[i5] == pytest.approx(x_expected, rel=0.01)
    assert x[i5] == pytest.approx(force / SIGMA0, rel=0.25)  # ~F/sigma0: spring-like
    assert abs(x[i5] - x[i2]) < 1e-4 * x_expected  # no drift
    assert np.max(np.abs(v[i2:])) < 1e-7


def test_lugre_stick_slip_cycles():
    dt, t_end = 1e-5, 30.0
    x, v, f_spring = _simulate_mass(int(t_end / dt), dt, MASS, 2.0, 0.1, 0.0, 1.0)
    t = np.arange(1, x.size + 1) * dt
    stuck = np.abs(v) < 1e-3
    late = t > 2.0
    # stick-slip: the mass stops again and again, and slips faster than the pull
    slip_starts = np.flatnonzero(stuck[:-1] & ~stuck[1:] & late[1:])
    assert len(slip_starts) >= 3
    assert v.max() > 0.2
    assert stuck[late].mean() > 0.2
    # it breaks away when the spring force reaches about Fs (LuGre shows a small
    # rate-dependent overshoot), not at Fc
    breakaway = f_spring[slip_starts]
    assert np.all(breakaway > FC + 0.3)
    np.testing.assert_allclose(breakaway, FS, rtol=0.05)
    # independent truth: continuous LuGre + mass + spring by Radau; same cycle period

    def rhs(tt, y):
        xx, vv, zz = y
        g = FC + (FS - FC) * math.exp(-((vv / VS) ** 2))
        dz = vv - SIGMA0 * abs(vv) * zz / g
        fr = SIGMA0 * zz + SIGMA1 * dz + SIGMA2 * vv
        return [vv, (2.0 * (0.1 * tt - xx) - fr) / MASS, dz]

    sol = solve_ivp(
        rhs, (0, t_end), [0, 0, 0], method="Radau", rtol=1e-8, atol=1e-11, max_step=0.01
    )
    v_ref = sol.y[1]
    stuck_ref = np.abs(v_ref) < 1e-3
    ref_starts = sol.t[1:][stuck_ref[:-1] & ~stuck_ref[1:] & (sol.t[1:] > 2.0)]
    period = np.diff(t[slip_starts]).mean()
    period_ref = np.diff(ref_starts).mean()
    assert period == pytest.approx(period_ref, rel=0.02)


# --- Maxwell-slip -------------------------------------------------------------------------
K_ELEM, W_ELEM = maxwell_slip_elements(4, 2.5e7)
G_SLIDING = 1200.0  # N
CAP = W_ELEM * G_SLIDING  # N


def _virgin(x: np.ndarray) -> np.ndarray:
    return np.sum(np.minimum(K_ELEM[None, :] * x[:, None], CAP[None, :]), axis=1)


def _drive(path: np.ndarray) -> np.ndarray:
    deltas = np.zeros(K_ELEM.size)
    out = np.empty(path.size)
    prev = 0.0
    for i, xi in enumerate(path):
        out[i] = maxwell_slip_step(deltas, xi - prev, K_ELEM, W_ELEM, G_SLIDING)
        prev = xi
    return out


def _ramp(*points: float, n: int = 400) -> np.ndarray:
    return np.concatenate(
        [np.linspace(a, b, n, endpoint=False) for a, b in itertools.pairwise(points)]
        + [np.array([points[-1]])]
    )


def test_maxwell_slip_elements():
    k, w = maxwell_slip_elements(4, 2.5e7)
    assert k.sum() == pytest.approx(2.5e7)
    assert w.sum() == pytest.approx(1.0)
    limits = w / k
    np.testing.assert_allclose(np.diff(limits), limits[0])  # equally spaced break-aways
    with pytest.raises(ValueError):
        maxwell_slip_elements(0, 1.0)


def test_maxwell_slip_virgin_curve_and_masing_branch():
    x_max = 1.2 * np.max(CAP / K_ELEM) / 2  # reversal inside the presliding range
    up = np.linspace(0, x_max, 300)
    f_up = _drive(up)
    np.testing.assert_allclose(f_up, _virgin(up), rtol=1e-12, atol=1e-9)
    assert f_up[1] / up[1] == pytest.approx(2.5e7)  # initial stiffness
    path = np.concatenate([up, np.linspace(x_max, -x_max, 600)[1:]])
    f = _drive(path)
    down = path[300:]
    # Masing rule: the descending branch is the virgin curve doubled in both axes
    np.testing.assert_allclose(f[300:], f_up[-1] - 2 * _virgin((x_max - down) / 2), atol=1e-9)


def test_maxwell_slip_nested_loops_close_and_wipe_out():
    a, b, c = 40e-6, 10e-6, 25e-6
    major = _ramp(0, a, -a, a)
    with_minor = _ramp(0, a, -a, b, -b / 2, b, a)  # minor loop b -> -b/2 -> b
    f_major = _drive(major)
    f_minor = _drive(with_minor)
    # the inner loop closes: back at b the force is what it was at the first b
    i_first = 800 + 400 - 1  # end of -a -> b segment is index 3*400
    i_back = 3 * 400 + 2 * 400
    assert with_minor[1200] == pytest.approx(b)
    assert with_minor[i_back] == pytest.approx(b)
    assert f_minor[i_back] == pytest.approx(f_minor[1200], abs=1e-9)
    del i_first
    # wiping-out: after closing, the path continues on the major ascending branch
    x_probe = c
    f_on_major = np.interp(x_probe, major[800:], f_major[800:])
    tail = slice(i_back, None)
    f_after = np.interp(x_probe, with_minor[tail], f_minor[tail])
    assert f_after == pytest.approx(f_on_major, abs=1e-9)
    assert f_minor[-1] == pytest.approx(f_major[-1], abs=1e-9)


def test_maxwell_slip_force_bounded():
    rng = np.random.default_rng(7)
    path = np.cumsum(rng.normal(0, 20e-6, 5000))
    f = _drive(path)
    assert np.all(np.abs(f) <= CAP.sum() + 1e-9)
    assert np.max(np.abs(f)) == pytest.approx(CAP.sum())  # saturates when sliding


def test_maxwell_slip_friction_sliding_standstill_and_stribeck():
    k, w = maxwell_slip_elements(4, 1e7)
    fc, fs, vs, kv = 800.0, 1200.0, 5e-3, 2e4
    v = np.concatenate([np.full(2000, 0.02), np.zeros(500), np.full(2000, -0.002)])
    f, deltas = maxwell_slip_friction(v, 1e-3, fc, fs, vs, kv, k, w)
    # sliding: the Stribeck curve, eq 16
    assert f[1999] == pytest.approx(stribeck_friction(0.02, fc, fs, vs, kv), rel=1e-9)
    assert f[-1] == pytest.approx(stribeck_friction(-0.002, fc, fs, vs, kv), rel=1e-9)
    # standstill: friction held at the last sliding element force (g, without viscous)
    np.testing.assert_allclose(f[2000:2500], stribeck_g(0.02, fc, fs, vs), rtol=1e-12)
    assert deltas.shape == (4,)
