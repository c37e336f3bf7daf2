"""The device simulation's integrator: ROS2 at a fixed step around the compiled model.

:func:`_run` is the compiled ROS2 integration (two-stage, L-stable Rosenbrock-W, Verwer
et al. 1999, the shared :func:`sims.hydraulics.ros2_matrix` /
:func:`~sims.hydraulics.ros2_step` with :func:`sims.device_model.rhs` as their
``rhs(y, args, out)``; finite-difference Jacobian every ``jacobian_every`` steps,
friction memory frozen over a step and committed with the accepted increment; see
:mod:`sims.device` for the scheme and its tolerances); :func:`integrate` checks the step
grid and the friction memory, runs it and turns the record into a
:class:`~sims.device.SimulationResult`.

Where the device is still at rest and its forcing constant, the state is held instead
of stepped (:data:`QUIET_FRACTION`, :func:`_quiet_steps`).

:func:`_run` allocates; its step loop :func:`_loop` (with the ROS2 functions numba
inlines into it), :func:`_commit` and the model's kernels are compiled without numba's
reference-counted runtime (``_nrt=False``), so no reference count is taken on the ~20
arrays a step passes around. Measured (``benchmarks/bench_sims.py``, 2-core machine;
back to back, 3-4 runs each): the old loop with ROS2 written inline (396f33d) ~316x
real time, the shared-ROS2 loop unpacking the model's arguments from a tuple at each
right-hand-side call ~275x, this ~396x; on the way, ``rhs`` unpacking them itself ~295x
and its kernels without reference counts ~375x. The two solves of a step were then ~45 %
of it; over the LU factors' nonzeros (:func:`sims.hydraulics.lu_solve`, session 46) the
benchmark ran 401-430x against 303-313x, back to back on a slower machine.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numba import njit

from sims.device_model import constant_until, friction_step, oil_volume, rhs
from sims.device_params import BETA, CYL0, PER, XMAX, Setup, T
from sims.device_results import SimulationResult, device_state, result_frame
from sims.effects import ResolvedEffects
from sims.hydraulics import lu_storage, ros2_matrix, ros2_step_refreshing
from sims.trips import TripProfile

#: A device at rest is not stepped: where the forcing (the winder's motion, the payload,
#: the ropes' source offsets) stays constant until ``t_end`` and every state's rate at
#: ``t``, extrapolated over ``t_end - t``, stays within this fraction of its absolute
#: tolerance (10 Pa, 0.01 um), the state is held until ``t_end`` (:func:`_quiet_steps`).
#: That is a first-order estimate of what the hold leaves out, not a bound: the states
#: drive each other and a difference carries on after the hold (the golden outputs of
#: ``tests/test_outputs_unchanged.py`` moved by up to 2.8e-6 m/s in the pistons'
#: velocities and 7e-8 m in their displacements). The held state's friction memory does
#: not move (no displacement). Measured on validation
#: trial_002's 12 planned trips (15 simulated, 1632 s): 31 % of the steps are held; one
#: replay on one thread 1.34 -> 1.0-1.1 s (1.87 s before the profile's segment was
#: found by bisection), its sensor pressures within 0.06 Pa of every step taken (0.52 Pa
#: when a logged rest's 0.1 s segments were held one by one).
QUIET_FRACTION = 0.1

#: A step with an older Jacobian is retaken with a fresh one when its error ratio
#: exceeds this many times that of the last step with a fresh one (and 1): the fixed
#: step may exceed the tolerance everywhere; a jump above that says the Jacobian went
#: stale. Measured on a throttled valve (the day-103 hoist description, K = 2e4, a
#: 600 m trip simulated here): sensor pressures 1.4 kPa RMS from a 0.5 ms reference
#: with 3 (193 steps retaken), 72 kPa with 10, 1.4 kPa with a Jacobian every step; on
#: an open valve (K = 500) 46 of 49150 steps retaken.
_REFRESH_GROWTH = 3.0


@njit(cache=True, _nrt=False)
def _quiet_steps(y, f0, args, atol, dt, steps_left, quiet_fraction):  # pragma: no cover
    """How many steps from ``y`` (rates ``f0``) the state may be held (0: step it; no
    hold when ``quiet_fraction`` is 0).

    Held only to where :func:`sims.device_model.constant_until` says the forcing changes
    (or the run ends), and only when every state's rate extrapolated over that whole
    span stays within ``quiet_fraction`` (:data:`QUIET_FRACTION`) of its tolerance: the
    span is skipped in one piece, so what it leaves out is counted once, not per piece.
    A state moving within one step is told first, before the forcing's knots are read."""
    if quiet_fraction <= 0.0:
        return 0
    rate = 0.0  # the largest rate, in tolerances per second
    for i in range(1, y.shape[0]):
        r = abs(f0[i]) / atol[i]
        if not r < math.inf:  # a NaN or infinite rate: never held
            return 0
        rate = max(rate, r)
    if not rate * dt <= quiet_fraction:
        return 0
    t = y[T]
    t_end = constant_until(t, args[2], args[3], args[4], args[5])
    span = t_end - t
    if not span >= dt:
        return 0
    m = steps_left
    if span < m * dt:
        m = int(span / dt)
    if not rate * m * dt <= quiet_fraction:
        return 0
    return m


@njit(cache=True, _nrt=False)
def _record(y, args, rec, scratch, kr, n):  # pragma: no cover
    """Record state, aux and oil volume at record ``kr``: aux from :func:`rhs` at ``y``,
    its friction column the one ``aux`` held before (the committed step's, or in a held
    span the zero-increment friction of the loop's last :func:`rhs` call)."""
    par, aux = args[0], args[13]
    rec_y, rec_aux, rec_vol = rec[0], rec[1], rec[2]
    work, committed = scratch[1], scratch[4]
    for i in range(n):
        committed[i] = aux[i, 0]
    rhs(y, args, work[3])
    for i in range(y.shape[0]):
        rec_y[kr, i] = y[i]
    for i in range(n):
        aux[i, 0] = committed[i]
        for c in range(4):
            rec_aux[kr, i, c] = aux[i, c]
    rec_vol[kr] = oil_volume(y, par, n)


@njit(cache=True, _nrt=False)
def _commit(y, par, z, deltas, x_start, dt, ms_k, ms_w, cap, aux, stop_hits):  # pragma: no cover
    """Commit the friction memory with the accepted displacement increments, count the
    end-stop contacts; True when a chamber pressure fell below zero gauge."""
    cavitation = False
    for i in range(x_start.shape[0]):
        b = CYL0 + PER * i
        ff, z_new = friction_step(
            y[b], y[b + 1] - x_start[i], dt, par, z[i], deltas[i], ms_k, ms_w, cap, True
        )
        z[i] = z_new
        aux[i, 0] = ff
        x_start[i] = y[b + 1]
        if abs(y[b + 1]) > par[XMAX]:
            stop_hits[i] += 1
        if y[b] < 0.0:
            cavitation = True
    return cavitation


@njit(cache=True, _nrt=False)
def _loop(
    y, args, rec, scratch, n_steps, record_every, jacobian_every, atol, rtol, quiet_fraction
):  # pragma: no cover
    """The ROS2 steps of :func:`_run`, in the arrays it allocated: ``y`` advanced in
    place, ``args`` the model's (its friction memory committed in place), ``rec`` =
    (rec_y, rec_aux, rec_vol, err_at, stop_hits) filled, ``scratch`` = (f0, work, the
    iteration matrix's factors (:func:`sims.hydraulics.lu_storage`), y_before,
    committed). Returns (largest error ratio, status code, failing step).

    Compiled without numba's reference-counted runtime (``_nrt=False``, as the model's
    kernels, :mod:`sims.device_model`): it allocates nothing, copies are loops, and
    no reference count is taken on the arrays it borrows from :func:`_run` or the views
    it makes of them (the inlined ROS2 functions' ``args`` and work rows included).

    Where :func:`_quiet_steps` says the device is still (``quiet_fraction`` > 0), the
    state is held over the span instead of stepped (its records filled by
    :func:`_record`, the held steps counted in ``err_at[3]``, a piston held against its
    end stop counted there); the iteration matrix factored before the hold serves after
    it (the same state and forcing), and a run held from its start factors one first.
    """
    par, groove, _, _, _, _, ms_k, ms_w, z, deltas, x_start, dt, cap, aux = args
    err_at, stop_hits = rec[3], rec[4]
    f0, work, lu, y_before = scratch[0], scratch[1], scratch[2], scratch[3]
    n = groove.shape[0]
    err_max = 0.0
    code = 0  # 0 ok, 1 singular, 2 non-finite, 3 cavitation
    fail_step = -1
    err_fresh = 0.0  # error ratio of the last step taken with a fresh Jacobian
    t0 = y[T]
    step = 0
    factored = False
    while step < n_steps:
        rhs(y, args, f0)
        held = _quiet_steps(y, f0, args, atol, dt, n_steps - step, quiet_fraction)
        if held > 0:  # at rest: the state held, its records filled
            err_at[3] += held
            for i in range(n):  # a piston held against its end stop is counted there
                if abs(y[CYL0 + PER * i + 1]) > par[XMAX]:
                    stop_hits[i] += held
            for _ in range(held):
                step += 1
                y[T] = t0 + step * dt
                if step % record_every == 0:
                    _record(y, args, rec, scratch, step // record_every, n)
            continue
        # a run held from its start has no iteration matrix yet; after a hold, the one
        # before it is at the same state and forcing
        fresh = step % jacobian_every == 0 or not factored
        if fresh and not ros2_matrix(rhs, args, y, f0, dt, atol, lu, work):
            code = 1
            break
        factored = True
        err, worst, retaken = ros2_step_refreshing(
            rhs, args, y, f0, dt, atol, rtol, lu, work, y_before, fresh,
            _REFRESH_GROWTH * max(err_fresh, 1.0),
        )  # fmt: skip
        if retaken < 0:
            code = 1
            break
        err_at[2] += retaken
        if fresh or retaken:
            err_fresh = err
        if not math.isfinite(err):
            code = 2
            break
        if err > err_max:
            err_max, err_at[0], err_at[1] = err, step, worst
        if _commit(y, par, z, deltas, x_start, dt, ms_k, ms_w, cap, aux, stop_hits):
            code = 3
            break
        step += 1
        if step % record_every == 0:
            _record(y, args, rec, scratch, step // record_every, n)
    if code != 0:
        fail_step = step
    return err_max, code, fail_step


@njit(cache=True, nogil=True)
def _run(
    y0,
    model,
    z0,
    deltas0,
    dt,
    n_steps,
    record_every,
    jacobian_every,
    atol,
    rtol,
    quiet_fraction,
):  # pragma: no cover
    """Integrate ``n_steps`` ROS2 steps of :func:`sims.device_model.rhs` from ``y0``
    (held where the device is still, ``quiet_fraction`` > 0: :func:`_loop`); ``model``
    is the tuple (par, groove, seg, pay, src_t, src_s, ms_k, ms_w) of a
    :class:`~sims.device_params.Setup`, ``z0``, ``deltas0`` the friction memory.

    Returns the recorded states, aux values and oil volumes (every ``record_every``
    steps; NaN rows after a failure), the largest error ratio and where, the status code
    (0 ok, 1 singular iteration matrix, 2 non-finite, 3 cavitation), the failing step,
    the end-stop hit counts and the final state with its friction memory.

    Allocates the records, the model's ``args`` (the ``rhs(y, args, out)`` tuple:
    ``model``, z, deltas, x_start, dt, cap, aux) and the scratch, records the initial
    state and leaves the steps to :func:`_loop`: :func:`sims.hydraulics.ros2_matrix`
    (every ``jacobian_every`` steps) and :func:`sims.hydraulics.ros2_step`; the friction
    memory is frozen over a step and committed with the accepted increment
    (:func:`_commit`). A step taken with an older Jacobian whose error ratio exceeds
    :data:`_REFRESH_GROWTH` times that of the last fresh one is taken again with a fresh
    one (:func:`sims.hydraulics.ros2_step_refreshing`; on a validation day's throttled
    valve, ``K = 2e4`` at 2 ms, a 10-step-old one let the replayed pressures fall into
    cavitation).
    ``err_at`` holds the largest error's step and state, the steps retaken with a fresh
    Jacobian and the steps held.
    """
    par, groove, ms_k = model[0], model[1], model[6]
    n_state = y0.shape[0]
    n = groove.shape[0]
    n_rec = n_steps // record_every + 1
    rec_y = np.full((n_rec, n_state), np.nan)
    rec_aux = np.full((n_rec, n, 4), np.nan)
    rec_vol = np.full(n_rec, np.nan)
    y = y0.copy()
    z = z0.copy()  # friction memory carried in (zero from static equilibrium)
    deltas = deltas0.copy()
    x_start = y[CYL0 + 1 :: PER].copy()
    cap = np.empty(2 * max(ms_k.shape[0], 1))
    aux = np.zeros((n, 4))
    args = (*model, z, deltas, x_start, dt, cap, aux)
    f0 = np.empty(n_state)
    rhs(y, args, f0)  # record the initial state
    rec_y[0], rec_aux[0], rec_vol[0] = y, aux, oil_volume(y, par, n)
    # step and state index of the largest error, steps retaken with a fresh Jacobian,
    # steps held at rest
    err_at = np.zeros(4, dtype=np.int64)
    stop_hits = np.zeros(n, dtype=np.int64)
    rec = (rec_y, rec_aux, rec_vol, err_at, stop_hits)
    work = np.empty((4, n_state))
    scratch = (f0, work, lu_storage(n_state), np.empty(n_state), np.empty(n))
    err_max, code, fail_step = _loop(
        y, args, rec, scratch, n_steps, record_every, jacobian_every, atol, rtol, quiet_fraction
    )
    return rec_y, rec_aux, rec_vol, err_max, err_at, code, fail_step, stop_hits, y, z, deltas


def _atol(n: int) -> np.ndarray:
    head = [1e-6, 1e-6, 1e-5, 100.0]
    return np.array(head + [100.0, 1e-7, 1e-5, 1e-9] * n)


def _step_counts(
    duration_s: float, dt_s: float, output_rate_hz: float, jacobian_every: int
) -> tuple[int, int]:
    """``(record_every, n_steps)`` of a run; ValueError for an unusable step grid."""
    if not dt_s > 0 or not output_rate_hz > 0:
        raise ValueError("dt_s and output_rate_hz must be positive")
    record_every = round(1.0 / (output_rate_hz * dt_s))
    if record_every < 1 or not math.isclose(
        record_every * dt_s * output_rate_hz, 1.0, rel_tol=1e-9
    ):
        raise ValueError(
            f"the output interval 1/output_rate_hz = {1 / output_rate_hz:g} s must be a whole "
            f"multiple of dt_s = {dt_s:g} s"
        )
    if jacobian_every < 1:
        raise ValueError("jacobian_every must be at least 1")
    n_steps = record_every * math.ceil(duration_s * output_rate_hz - 1e-9)
    return record_every, n_steps


def _friction_memory(
    setup: Setup, z0: np.ndarray | None, deltas0: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """The starting LuGre z and Maxwell-slip deflections (zero unless carried in)."""
    n = setup.groove.shape[0]
    n_el = max(setup.ms_k.shape[0], 1)
    z0 = np.zeros(n) if z0 is None else np.array(z0, dtype=float)
    deltas0 = np.zeros((n, n_el)) if deltas0 is None else np.array(deltas0, dtype=float)
    if z0.shape != (n,) or deltas0.shape != (n, n_el):
        raise ValueError(
            f"friction memory: need z of shape ({n},) and Maxwell-slip deflections of shape "
            f"({n}, {n_el}), got {z0.shape} and {deltas0.shape}"
        )
    return z0, deltas0


def integrate(
    setup: Setup,
    y0: np.ndarray,
    *,
    duration_s: float,
    dt_s: float,
    output_rate_hz: float,
    jacobian_every: int,
    eff: ResolvedEffects,
    profile: TripProfile | None,
    rtol: float = 1e-4,
    z0: np.ndarray | None = None,
    deltas0: np.ndarray | None = None,
    hold_at_rest: bool = True,
) -> SimulationResult:
    """Run :func:`_run` on ``setup`` from ``y0`` for ``duration_s`` (the arguments of
    :func:`sims.device.simulate`; ``hold_at_rest`` False steps every ``dt_s``) and turn
    its records into a :class:`~sims.device.SimulationResult`."""
    record_every, n_steps = _step_counts(duration_s, dt_s, output_rate_hz, jacobian_every)
    n = setup.groove.shape[0]
    z0, deltas0 = _friction_memory(setup, z0, deltas0)
    atol = _atol(n)
    wall0 = time.perf_counter()
    (
        rec_y,
        rec_aux,
        rec_vol,
        err_max,
        err_at,
        code,
        fail_step,
        stop_hits,
        y_end,
        z_end,
        deltas_end,
    ) = _run(
        y0,
        (
            setup.par,
            setup.groove,
            setup.seg,
            setup.pay,
            setup.src_t,
            setup.src_s,
            setup.ms_k,
            setup.ms_w,
        ),
        np.ascontiguousarray(z0),
        np.ascontiguousarray(deltas0),
        dt_s,
        n_steps,
        record_every,
        jacobian_every,
        atol,
        rtol,
        QUIET_FRACTION if hold_at_rest else 0.0,
    )
    wall = time.perf_counter() - wall0
    good = np.isfinite(rec_vol)
    frame = result_frame(setup, rec_y[good], rec_aux[good], rec_vol[good], profile)
    message, solver = _report(
        code=code,
        fail_step=fail_step,
        n_steps=n_steps,
        t0_s=y0[T],
        dt_s=dt_s,
        stop_hits=stop_hits,
        err_max=err_max,
        err_at=err_at,
        jacobian_every=jacobian_every,
        atol=atol,
        rtol=rtol,
        wall_s=wall,
    )
    final_state = None
    if code == 0:
        final_state = device_state(y_end, z_end, deltas_end, float(setup.par[BETA]), eff, profile)
    return SimulationResult(
        status="success" if code == 0 else "failed",
        message=message,
        frame=frame,
        effects=eff,
        solver=solver,
        final_state=final_state,
    )


def _report(
    *,
    code: int,
    fail_step: int,
    n_steps: int,
    t0_s: float,
    dt_s: float,
    stop_hits: np.ndarray,
    err_max: float,
    err_at: np.ndarray,
    jacobian_every: int,
    atol: np.ndarray,
    rtol: float,
    wall_s: float,
) -> tuple[str, dict[str, Any]]:
    """The run's message (failure reason, steps, end-stop contacts, accuracy) and the
    solver record of :attr:`~sims.device.SimulationResult.solver`."""
    n = stop_hits.shape[0]
    t_fail = t0_s + (fail_step + 1) * dt_s
    reasons = {
        1: f"iteration matrix singular at t = {t_fail:.4f} s",
        2: f"state went non-finite at t = {t_fail:.4f} s (step {dt_s:g} s too large?)",
        3: f"chamber pressure fell below zero gauge at t = {t_fail:.4f} s (cavitation is "
        "not modelled; slack rope?)",
    }
    notes = [f"ROS2 fixed step {dt_s:g} s, {n_steps if code == 0 else fail_step + 1} steps"]
    if err_at[3]:
        notes[0] += f" ({err_at[3]} of them held at rest)"
    hits = [str(i + 1) for i in range(n) if stop_hits[i] > 0]
    if hits:
        notes.append(f"pistons {', '.join(hits)} reached the stroke end stops")
    state_names = ["t", "eta", "deta/dt", "p_manifold"] + [
        f"{name}{i + 1}" for i in range(n) for name in ("p", "x", "v", "q")
    ]
    err_where = f"t = {t0_s + (err_at[0] + 1) * dt_s:.3f} s, state {state_names[err_at[1]]}"
    if err_max > 1.0:
        notes.append(
            f"local error estimate up to {err_max:.3g} x tolerance at {err_where} (fixed "
            "step, not adapted; reduce dt_s where that matters)"
        )
    message = "; ".join(([reasons[code]] if code else []) + notes)
    solver = {
        "method": "ROS2 (Verwer et al. 1999), L-stable Rosenbrock-W, FD Jacobian",
        "dt_s": dt_s,
        "jacobian_every": jacobian_every,
        "atol": atol,
        "rtol": rtol,
        "steps": n_steps if code == 0 else fail_step + 1,
        "error_ratio_max": float(err_max),
        "error_ratio_max_at": err_where,
        "steps_retaken_fresh_jacobian": int(err_at[2]),
        "steps_held_at_rest": int(err_at[3]),
        "wall_s": wall_s,
    }
    return message, solver
