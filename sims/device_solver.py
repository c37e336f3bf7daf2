"""The device simulation's integrator: ROS2 at a fixed step around the compiled model.

:func:`_run` is the compiled ROS2 loop (two-stage, L-stable Rosenbrock-W, Verwer et al.
1999; finite-difference Jacobian every ``jacobian_every`` steps, friction memory frozen
over a step and committed with the accepted increment; see :mod:`sims.device` for the
scheme and its tolerances); :func:`_integrate` checks the step grid and the friction
memory, runs it and turns the record into a :class:`~sims.device.SimulationResult`.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numba import njit

from sims.device_model import _friction, _oil_volume, _rhs
from sims.device_params import _BETA, _CYL0, _PER, _T, _XMAX, _Setup
from sims.device_results import SimulationResult, _final_state, _frame
from sims.effects import ResolvedEffects
from sims.hydraulics import ROS2_GAMMA, lu_factor, lu_solve
from sims.trips import TripProfile


@njit(cache=True)
def _run(
    y0,
    par,
    groove,
    seg,
    pay,
    src_t,
    src_s,
    ms_k,
    ms_w,
    z0,
    deltas0,
    dt,
    n_steps,
    record_every,
    jacobian_every,
    atol,
    rtol,
):  # pragma: no cover - compiled
    """Integrate ``n_steps`` ROS2 steps of :func:`sims.device_model._rhs` from ``y0``.

    Returns the recorded states, aux values and oil volumes (every ``record_every``
    steps; NaN rows after a failure), the largest error ratio and where, the status code
    (0 ok, 1 singular iteration matrix, 2 non-finite, 3 cavitation), the failing step,
    the end-stop hit counts and the final state with its friction memory.

    Longer than 80 lines on purpose: it is the one compiled loop of the run (Jacobian
    refresh, the two ROS2 stages, the error norm, the friction commit and the recording
    share some twenty arrays and the state); kept whole so numba compiles it as one loop
    without passing that state through calls, and so the arithmetic stays as validated.
    Most of its length is the 16-argument ``_rhs`` calls written one argument a line.
    """
    n_state = y0.shape[0]
    n = groove.shape[0]
    n_el = ms_k.shape[0]
    n_rec = n_steps // record_every + 1
    rec_y = np.full((n_rec, n_state), np.nan)
    rec_aux = np.full((n_rec, n, 4), np.nan)
    rec_vol = np.full(n_rec, np.nan)
    y = y0.copy()
    z = z0.copy()  # friction memory carried in (zero from static equilibrium)
    deltas = deltas0.copy()
    x_start = np.empty(n)
    for i in range(n):
        x_start[i] = y[_CYL0 + _PER * i + 1]
    cap = np.empty(2 * max(n_el, 1))
    aux = np.zeros((n, 4))
    f0 = np.empty(n_state)
    f1 = np.empty(n_state)
    k1 = np.empty(n_state)
    k2 = np.empty(n_state)
    yt = np.empty(n_state)
    w = np.empty((n_state, n_state))
    piv = np.empty(n_state, dtype=np.int64)
    err_max = 0.0
    err_at = np.zeros(2, dtype=np.int64)  # step and state index of the largest error
    stop_hits = np.zeros(n, dtype=np.int64)
    # record the initial state
    _rhs(y, par, groove, seg, pay, src_t, src_s, ms_k, ms_w, z, deltas, x_start, dt, cap, f0, aux)
    rec_y[0] = y
    rec_aux[0] = aux
    rec_vol[0] = _oil_volume(y, par, n)
    code = 0  # 0 ok, 1 singular, 2 non-finite, 3 cavitation
    fail_step = -1
    for step in range(n_steps):
        _rhs(
            y, par, groove, seg, pay, src_t, src_s, ms_k, ms_w, z, deltas, x_start, dt, cap, f0, aux
        )
        if step % jacobian_every == 0:
            # column of t left zero: the forcing (profile, payload, load sources) is
            # piecewise and an FD across a kink would poison W; any J is admissible
            # for the W-method ROS2, which keeps its order.
            for r in range(n_state):
                w[r, _T] = 0.0
            w[_T, _T] = 1.0
            for j in range(1, n_state):
                delta = 1e-7 * max(abs(y[j]), 1e3 * atol[j])
                yt[:] = y
                yt[j] += delta
                _rhs(
                    yt,
                    par,
                    groove,
                    seg,
                    pay,
                    src_t,
                    src_s,
                    ms_k,
                    ms_w,
                    z,
                    deltas,
                    x_start,
                    dt,
                    cap,
                    f1,
                    aux,
                )
                for r in range(n_state):
                    w[r, j] = -ROS2_GAMMA * dt * (f1[r] - f0[r]) / delta
                w[j, j] += 1.0
            if not lu_factor(w, piv):
                code = 1
                fail_step = step
                break
        k1[:] = f0
        lu_solve(w, piv, k1)
        for r in range(n_state):
            yt[r] = y[r] + dt * k1[r]
        _rhs(
            yt,
            par,
            groove,
            seg,
            pay,
            src_t,
            src_s,
            ms_k,
            ms_w,
            z,
            deltas,
            x_start,
            dt,
            cap,
            f1,
            aux,
        )
        for r in range(n_state):
            k2[r] = f1[r] - 2.0 * k1[r]
        lu_solve(w, piv, k2)
        acc = 0.0
        worst = 0
        worst_e = 0.0
        for r in range(n_state):
            y_new = y[r] + 1.5 * dt * k1[r] + 0.5 * dt * k2[r]
            e = 0.5 * dt * (k1[r] + k2[r]) / (atol[r] + rtol * abs(y_new))
            acc += e * e
            if abs(e) > worst_e:
                worst_e = abs(e)
                worst = r
            y[r] = y_new
        err = math.sqrt(acc / n_state)
        if not math.isfinite(err):
            code = 2
            fail_step = step
            break
        if err > err_max:
            err_max = err
            err_at[0] = step
            err_at[1] = worst
        # commit the friction memory with the accepted displacement increments
        for i in range(n):
            b = _CYL0 + _PER * i
            ff, z_new = _friction(
                y[b], y[b + 1] - x_start[i], dt, par, z[i], deltas[i], ms_k, ms_w, cap, True
            )
            z[i] = z_new
            aux[i, 0] = ff
            x_start[i] = y[b + 1]
            if abs(y[b + 1]) > par[_XMAX]:
                stop_hits[i] += 1
            if y[b] < 0.0:
                code = 3
                fail_step = step
        if code != 0:
            break
        if (step + 1) % record_every == 0:
            committed = aux[:, 0].copy()
            _rhs(
                y,
                par,
                groove,
                seg,
                pay,
                src_t,
                src_s,
                ms_k,
                ms_w,
                z,
                deltas,
                x_start,
                dt,
                cap,
                f1,
                aux,
            )
            aux[:, 0] = committed
            kr = (step + 1) // record_every
            rec_y[kr] = y
            rec_aux[kr] = aux
            rec_vol[kr] = _oil_volume(y, par, n)
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
    setup: _Setup, z0: np.ndarray | None, deltas0: np.ndarray | None
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


def _integrate(
    setup: _Setup,
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
) -> SimulationResult:
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
        setup.par,
        setup.groove,
        setup.seg,
        setup.pay,
        setup.src_t,
        setup.src_s,
        setup.ms_k,
        setup.ms_w,
        np.ascontiguousarray(z0),
        np.ascontiguousarray(deltas0),
        dt_s,
        n_steps,
        record_every,
        jacobian_every,
        atol,
        rtol,
    )
    wall = time.perf_counter() - wall0
    good = np.isfinite(rec_vol)
    frame = _frame(setup, rec_y[good], rec_aux[good], rec_vol[good], profile)
    message, solver = _report(
        code=code,
        fail_step=fail_step,
        n_steps=n_steps,
        t0_s=y0[_T],
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
        final_state = _final_state(y_end, z_end, deltas_end, float(setup.par[_BETA]), eff, profile)
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
        "wall_s": wall_s,
    }
    return message, solver
