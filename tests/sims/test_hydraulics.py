"""sims.hydraulics: the ROS2 step with an old iteration matrix, against a stiff ODE whose
stiffness grows while it is integrated (as a throttled valve's resistance grows with
the flow).

dy/dt = F(t) - a y |y| with F stepping from 0 to F1 at t = 0.05 s: at rest the Jacobian
-2 a |y| is zero, at the new equilibrium y1 = sqrt(F1 / a) it is -2 sqrt(a F1), so a
W built at rest is the explicit-Euler-like W = I, unstable once 2 sqrt(a F1) dt > 2.
The exact equilibrium is known; the solution must settle there.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sims.hydraulics import lu_factor, lu_solve, lu_storage, ros2_matrix, ros2_step_refreshing

A = 1e4  # [1/m]: dy/dt = F - A y|y|
F1 = 100.0  # [m/s2] after the step: y1 = 0.1, Jacobian -2 sqrt(A F1) = -2000 1/s
DT = 2e-3  # 2000 x 2e-3 = 4 > 2: explicit-like W is unstable at y1


@njit(cache=True)
def _rhs(y, args, out):  # pragma: no cover - compiled
    out[0] = 1.0
    forcing = args[0] if y[0] >= 0.05 else 0.0
    out[1] = forcing - A * y[1] * abs(y[1])


@njit(cache=True)
def _integrate(n_steps, jacobian_every, refresh_above):  # pragma: no cover - compiled
    y = np.zeros(2)
    args = (F1,)
    atol = np.array([1e-6, 1e-6])
    f0 = np.empty(2)
    work = np.empty((4, 2))
    lu = lu_storage(2)
    y_before = np.empty(2)
    retakes = 0
    for step in range(n_steps):
        _rhs(y, args, f0)
        fresh = step % jacobian_every == 0
        if fresh:
            ros2_matrix(_rhs, args, y, f0, DT, atol, lu, work)
        _, _, retaken = ros2_step_refreshing(
            _rhs, args, y, f0, DT, atol, 1e-4, lu, work, y_before, fresh, refresh_above
        )
        retakes += retaken
    return y[1], retakes


def test_a_fresh_matrix_every_step_settles_at_the_equilibrium():
    y, retakes = _integrate(500, 1, 10.0)
    assert math.isclose(y, math.sqrt(F1 / A), rel_tol=1e-9)
    assert retakes == 0


def test_an_old_matrix_fails_without_the_refresh():
    """The W of the state at rest, kept for 1000 steps, does not reach the equilibrium:
    the case the refresh is for (the test of the test)."""
    y, retakes = _integrate(40, 1000, math.inf)  # 15 steps after the forcing step
    assert retakes == 0
    assert abs(y - math.sqrt(F1 / A)) > 1.0  # oscillating away (measured: -6.1)
    y, retakes = _integrate(40, 1000, 10.0)
    assert math.isclose(y, math.sqrt(F1 / A), rel_tol=1e-6)


def test_an_old_matrix_is_rebuilt_when_its_step_fails():
    y, retakes = _integrate(500, 1000, 10.0)
    assert math.isclose(y, math.sqrt(F1 / A), rel_tol=1e-9)
    assert 0 < retakes <= 5  # rebuilt where the stiffness grew, not every step (2)


@njit(cache=True)
def _factor_and_solve(a, b):  # pragma: no cover - compiled
    lu = lu_storage(a.shape[0])
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            lu[0][i, j] = a[i, j]
    x = b.copy()
    if not lu_factor(lu):
        return False, x, 0
    lu_solve(lu, x)
    return True, x, lu[4][2 * a.shape[0] + 1]


def test_the_solve_over_the_factors_nonzeros_is_numpys_solution():
    """A matrix with the device's kind of structure (blocks coupled through a few
    shared states, zeros elsewhere) and rows that need pivoting: the solution is
    LAPACK's (numpy.linalg.solve), and only nonzeros are listed."""
    rng = np.random.default_rng(7)
    n = 12
    a = np.zeros((n, n))
    for k in range(3):  # three 3x3 blocks after three shared states
        s = slice(3 + 3 * k, 6 + 3 * k)
        a[s, s] = rng.normal(size=(3, 3))
        a[s, 0] = rng.normal(size=3)
        a[0, s] = rng.normal(size=3)
    a[:3, :3] = rng.normal(size=(3, 3))
    a[9:, 1:3] = rng.normal(size=(3, 2))
    b = rng.normal(size=n)
    ok, x, listed = _factor_and_solve(a, b)
    assert ok
    np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-10, atol=1e-12)
    assert 0 < listed < n * (n - 1)  # zeros stay out of the list


def test_a_singular_matrix_is_refused():
    a = np.array([[1.0, 2.0], [2.0, 4.0]])
    ok, _, _ = _factor_and_solve(a, np.ones(2))
    assert not ok
