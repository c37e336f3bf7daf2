"""Dense linear algebra and the stiff integrator shared by the ropeload sims.

Contents
--------
Dense linear algebra (njit, small systems)
    :func:`lu_storage`, :func:`lu_factor`, :func:`lu_solve` -- LU with partial pivoting,
    in place, the solve over the factors' nonzeros.
Stiff fixed-step integrator (njit), the one home of ROS2 in the sims
    :data:`ROS2_GAMMA`; :func:`ros2_matrix` (build and factor ``W``) and
    :func:`ros2_step` (one step, its error ratio) -- the two-stage, second-order,
    L-stable Rosenbrock-W method ROS2 of Verwer et al. (1999) with a finite-difference
    Jacobian and an embedded first-order error estimate; :func:`ros2_integrate`, a plain
    fixed-step loop over them. The device (:mod:`sims.device_solver`), the rig
    (:mod:`sims.rig_solver`) and the two-cylinder model call these two functions, each
    with its model as an njit ``rhs(y, args, out)`` (the device's
    :func:`sims.device_model.rhs` itself, the rig's a wrapper) and its own per-step work
    (friction memory, end stops, segment lookup, state floors, recording) around them.
    Both are compiled with ``inline="always"``: numba inlines them into the caller, so
    the call to ``rhs`` is resolved statically and the caller stays cacheable (a
    function passed as an argument to a non-inlined call is a dynamic global to numba's
    cache). They allocate nothing and copy arrays with loops rather than ``a[:] = b``
    (which numba may compile to a temporary copy), so a caller compiled without numba's
    reference-counted runtime can inline them: the device's step loop is
    (``_nrt=False``, see :mod:`sims.device_solver`).

The problem solved is the initial value problem

.. math::

    \\frac{dy}{dt} = f(t, y), \\qquad y(t_0) = y_0

with ``t`` carried as state component 0 (``f[0] = 1``), so stage 2 sees the forcing at
``t + h``. The Jacobian's t column is left zero: forcing may be piecewise (trip
segments, load steps) and a finite difference across a kink would poison W, while
ROS2, a W-method, keeps its order for any J. One step of ROS2 is

.. math::

    W &= I - \\gamma h J, \\qquad \\gamma = 1 + 1/\\sqrt{2}, \\\\
    W k_1 &= f(y_n), \\\\
    W k_2 &= f(y_n + h k_1) - 2 k_1, \\\\
    y_{n+1} &= y_n + \\tfrac{3}{2} h k_1 + \\tfrac{1}{2} h k_2 .

ROS2 is second order for *any* matrix J (a W-method), so a Jacobian that is a
finite-difference approximation, or refreshed only every few steps, costs accuracy in
no order, only in the constant; it is L-stable, so stiff modes (oil compressibility at
GPa in litres, seal bristles of 1e7 N/m, stroke-end stops) are damped rather than
resolved. The embedded first-order solution ``y_n + h k_1`` gives the local error
estimate ``err = h (k_1 + k_2) / 2``, reported per step as the weighted RMS norm
``sqrt(mean((err / (atol + rtol |y|))**2))`` with a per-state ``atol`` (Pa beside m).

References
----------
J. G. Verwer, E. J. Spee, J. G. Blom, W. Hundsdorfer, "A second-order Rosenbrock
method applied to photochemical dispersion problems", SIAM J. Sci. Comput. 20(4),
1456-1480 (1999), doi:10.1137/S1064827597326651.
E. Hairer, G. Wanner, *Solving Ordinary Differential Equations II*, 2nd ed.,
Springer (1996), section IV.7 (Rosenbrock and W-methods).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "ROS2_GAMMA",
    "lu_factor",
    "lu_solve",
    "lu_storage",
    "ros2_integrate",
    "ros2_matrix",
    "ros2_step",
    "ros2_step_refreshing",
]

#: ROS2 stage parameter gamma = 1 + 1/sqrt(2) (L-stable choice, Verwer et al. 1999).
ROS2_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)


@njit(cache=True)
def lu_storage(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Empty arrays for the LU factors of an ``n x n`` matrix, as :func:`lu_factor` fills
    them and :func:`lu_solve` reads them: ``(a, piv, col, val, row_start)`` -- the dense
    factors and pivots, and their nonzeros row by row (strict L, then strict U)."""
    return (
        np.empty((n, n)),
        np.empty(n, dtype=np.int64),
        np.empty(n * n, dtype=np.int64),
        np.empty(n * n),
        np.empty(2 * n + 2, dtype=np.int64),
    )


@njit(cache=True, _nrt=False)
def lu_factor(lu: tuple) -> bool:
    """LU-factorise the square matrix ``lu[0]`` in place with partial pivoting (pivots in
    ``lu[1]``) and list the factors' nonzeros row by row for :func:`lu_solve`.

    ``lu``: the arrays of :func:`lu_storage`, the matrix in the first. Returns False when
    a pivot is exactly zero (singular matrix; the nonzeros are then not listed).

    The list: row ``r`` of strict L holds ``col[row_start[r]:row_start[r + 1]]`` and
    ``val`` alike; row ``r`` of strict U the same from ``row_start[n + 1 + r]`` to
    ``row_start[n + 2 + r]``. The device's iteration matrix (20 states, four cylinders
    coupled through the manifold and the conveyance) keeps 133-174 of its 380
    off-diagonal entries nonzero through its LU (the example hoist's full-shaft trip at
    1 ms: L 54-71, U 75-103, a mean of 167 over its 8684 fresh factorisations, 174 in
    half of them; 133, 58 in L and 75 in U, where it starts at rest), so a solve that
    skips the zeros does under half of a dense one's multiplications; the device
    simulation's step took ~13 % less time (an 89 s trip at 2 ms, 15 runs each, best
    78-80 against 90-92 ms). The zeros are exact, so the solution equals the dense one
    (the same products in the same order) where the right-hand side is finite, bit for
    bit but for the sign of an exact zero: a skipped ``-0.0 * b[c]`` leaves an
    ``s = -0.0`` where the dense solve's ``s - (-0.0)`` makes it ``+0.0``.
    """
    a, piv, col, val, start = lu
    n = a.shape[0]
    for k in range(n):
        best = k
        big = abs(a[k, k])
        for r in range(k + 1, n):
            if abs(a[r, k]) > big:
                big = abs(a[r, k])
                best = r
        piv[k] = best
        if big == 0.0:
            return False
        if best != k:
            for c in range(n):
                tmp = a[k, c]
                a[k, c] = a[best, c]
                a[best, c] = tmp
        inv = 1.0 / a[k, k]
        for r in range(k + 1, n):
            a[r, k] *= inv
            f = a[r, k]
            if f != 0.0:
                for c in range(k + 1, n):
                    a[r, c] -= f * a[k, c]
    m = 0
    for r in range(n):  # strict L, row by row
        start[r] = m
        for c in range(r):
            if a[r, c] != 0.0:
                col[m] = c
                val[m] = a[r, c]
                m += 1
    start[n] = m
    for r in range(n):  # strict U, row by row
        start[n + 1 + r] = m
        for c in range(r + 1, n):
            if a[r, c] != 0.0:
                col[m] = c
                val[m] = a[r, c]
                m += 1
    start[2 * n + 1] = m
    return True


@njit(cache=True, _nrt=False, inline="always")
def lu_solve(lu: tuple, b: np.ndarray) -> None:
    """Solve ``A x = b`` in place in ``b`` with the factors from :func:`lu_factor`
    (their nonzeros only; the diagonal of U from the dense factors)."""
    a, piv, col, val, start = lu
    n = a.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for r in range(n):
        s = b[r]
        for j in range(start[r], start[r + 1]):
            s -= val[j] * b[col[j]]
        b[r] = s
    for r in range(n - 1, -1, -1):
        s = b[r]
        for j in range(start[n + 1 + r], start[n + 2 + r]):
            s -= val[j] * b[col[j]]
        b[r] = s / a[r, r]


@njit(cache=True, inline="always")
def ros2_matrix(rhs, args, y, f0, dt, atol, lu, work):  # pragma: no cover - compiled
    """Build the ROS2 iteration matrix ``W = I - gamma dt J`` at ``y`` and LU-factor it.

    ``J`` is the forward-difference Jacobian of ``rhs`` at ``y`` (``f0 = rhs(y)`` given),
    step ``1e-7 max(|y_j|, 1e3 atol_j, 1e-12)`` in state ``j``; its t column (state 0) is
    left zero (see the module docstring).

    Parameters
    ----------
    rhs : njit function ``rhs(y, args, out)`` writing dy/dt into ``out``, ``out[0] = 1``
    args : anything ``rhs`` takes (a tuple of arrays and floats), passed through
    y, f0 : the state (``y[0]`` time) and ``rhs`` there
    dt : step [s]
    atol : per-state absolute tolerance, sets the difference steps
    lu : output, the LU factors of ``W`` (the arrays of :func:`lu_storage`)
    work : (4, n) scratch (rows 2 and 3 are overwritten)

    Returns
    -------
    ok : False when ``W`` is singular (a zero pivot).
    """
    n = y.shape[0]
    w = lu[0]
    ytmp = work[2]
    f1 = work[3]
    for i in range(n):
        w[i, 0] = 0.0  # t column: forcing may be piecewise (see the module docstring)
    w[0, 0] = 1.0
    for j in range(1, n):
        delta = 1e-7 * max(abs(y[j]), atol[j] * 1e3, 1e-12)
        for i in range(n):
            ytmp[i] = y[i]
        ytmp[j] += delta
        rhs(ytmp, args, f1)
        for i in range(n):
            w[i, j] = -ROS2_GAMMA * dt * (f1[i] - f0[i]) / delta
        w[j, j] += 1.0
    return lu_factor(lu)


@njit(cache=True, inline="always")
def ros2_step(rhs, args, y, f0, dt, atol, rtol, lu, work):  # pragma: no cover - compiled
    """Advance ``y`` in place by one ROS2 step of ``dt``; return the error ratio.

    Solves ``W k1 = f(y)``, ``W k2 = f(y + dt k1) - 2 k1`` with the factors of
    :func:`ros2_matrix` (possibly from an earlier step: a W-method keeps its order for
    any ``W``) and sets ``y <- y + 3/2 dt k1 + 1/2 dt k2``.

    Parameters
    ----------
    rhs, args : as for :func:`ros2_matrix`
    y : (n,) state, ``y[0]`` time, updated in place; f0 : ``rhs`` at the incoming ``y``
    dt : step [s]
    atol, rtol : per-state absolute and scalar relative tolerance of the error estimate
    lu : the factors from :func:`ros2_matrix`
    work : (4, n) scratch; on return rows 0 and 1 hold ``k1`` and ``k2``

    Returns
    -------
    err : weighted RMS norm of the embedded error estimate ``dt (k1 + k2) / 2``,
        ``sqrt(mean((err_i / (atol_i + rtol |y_new_i|))**2))`` (below 1: within the
        tolerances; not finite when the state went non-finite)
    worst : the state index with the largest weighted error
    """
    n = y.shape[0]
    k1 = work[0]
    k2 = work[1]
    ytmp = work[2]
    f1 = work[3]
    for i in range(n):
        k1[i] = f0[i]
    lu_solve(lu, k1)
    for i in range(n):
        ytmp[i] = y[i] + dt * k1[i]
    rhs(ytmp, args, f1)
    for i in range(n):
        k2[i] = f1[i] - 2.0 * k1[i]
    lu_solve(lu, k2)
    acc = 0.0
    worst = 0
    worst_e = 0.0
    for i in range(n):
        y_new = y[i] + 1.5 * dt * k1[i] + 0.5 * dt * k2[i]
        e = 0.5 * dt * (k1[i] + k2[i]) / (atol[i] + rtol * abs(y_new))
        acc += e * e
        if abs(e) > worst_e:
            worst_e = abs(e)
            worst = i
        y[i] = y_new
    return math.sqrt(acc / n), worst


@njit(cache=True, inline="always")
def ros2_step_refreshing(
    rhs, args, y, f0, dt, atol, rtol, lu, work, y_before, fresh, refresh_above
):  # pragma: no cover - compiled
    """:func:`ros2_step`, taken again with a fresh ``W`` when the old one fails it.

    A W-method keeps its order with any ``W`` but not its stability: when the Jacobian
    has grown since ``W`` was built (a throttled valve's resistance ``2 K |q|`` rises
    with the flow), a step with the old ``W`` can amplify the error instead of damping
    it, and the error ratio then grows from step to step. A step taken with an older
    ``W`` (``fresh`` False) whose error ratio exceeds ``refresh_above`` (or is not
    finite) is taken again from the same state with ``W`` rebuilt there
    (:func:`ros2_matrix`). The caller sets ``refresh_above`` from the error ratios its
    fresh steps have (a fixed step may exceed the tolerance everywhere; only a jump
    above that says the matrix went stale).

    Parameters as for :func:`ros2_step`, and ``y_before`` an (n,) scratch array,
    ``fresh`` whether ``W`` was built at this ``y``, ``refresh_above`` the error ratio
    above which an older ``W`` is rebuilt.

    Returns
    -------
    err, worst : as :func:`ros2_step`, of the step kept
    retaken : 0 taken once, 1 taken again with a fresh ``W``, -1 the rebuilt ``W`` is
        singular (``y`` is then the incoming state)
    """
    n = y.shape[0]
    for i in range(n):
        y_before[i] = y[i]
    err, worst = ros2_step(rhs, args, y, f0, dt, atol, rtol, lu, work)
    if fresh or err <= refresh_above:
        return err, worst, 0
    for i in range(n):
        y[i] = y_before[i]
    if not ros2_matrix(rhs, args, y, f0, dt, atol, lu, work):
        return err, worst, -1
    err, worst = ros2_step(rhs, args, y, f0, dt, atol, rtol, lu, work)
    return err, worst, 1


@njit
def ros2_integrate(rhs, y0, params, dt, n_steps, record_every, atol, rtol):
    """Integrate ``dy/dt = rhs(y, params, out)`` with ROS2 at a fixed step.

    Parameters
    ----------
    rhs : njit function ``rhs(y, params, out)`` writing dy/dt into ``out``; ``y[0]`` is
        time and ``out[0]`` must be 1.
    y0 : initial state, ``y0[0]`` the start time [s]
    params : parameters passed through to ``rhs`` (an array or a tuple)
    dt : step [s]
    n_steps : number of steps
    record_every : keep every ``record_every``-th state (the first is ``y0``)
    atol, rtol : per-state absolute tolerance array and relative tolerance, used only
        for the reported error estimate

    Returns
    -------
    states : (n_steps // record_every + 1, n) recorded states
    error_ratio_max : largest weighted RMS local error estimate over all steps
    ok : False when the state went non-finite or W was singular; ``states`` then ends
        with the last finite record and the rest is NaN.

    The Jacobian is refreshed by forward differences every step (these models are small):
    :func:`ros2_matrix` then :func:`ros2_step`.
    """
    n = y0.shape[0]
    n_rec = n_steps // record_every + 1
    states = np.full((n_rec, n), np.nan)
    y = y0.copy()
    states[0] = y
    f0 = np.empty(n)
    work = np.empty((4, n))
    lu = lu_storage(n)
    err_max = 0.0
    for step in range(n_steps):
        rhs(y, params, f0)
        if not ros2_matrix(rhs, params, y, f0, dt, atol, lu, work):
            return states, err_max, False
        err, _ = ros2_step(rhs, params, y, f0, dt, atol, rtol, lu, work)
        if not math.isfinite(err):
            return states, err_max, False
        err_max = max(err_max, err)
        if (step + 1) % record_every == 0:
            states[(step + 1) // record_every] = y
    return states, err_max, True
