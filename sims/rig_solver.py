"""The rig's integrator and :func:`simulate_rig` (public through :mod:`sims.rig`).

A linearly implicit (Rosenbrock-Euler / W-method) fixed step with a finite-difference
Jacobian every step, compiled with numba, around :func:`sims.rig_model._rhs`.
"""

from __future__ import annotations

import time

import numpy as np
import polars as pl
from numba import njit

from physics.friction_law import law_array
from schemas.hoist import FrictionLaw
from sims.hydraulics import lu_factor, lu_solve
from sims.rig_design import RigDesign, RigProgram, RigRecording
from sims.rig_model import _N, _P_FLOOR, PORT_PRESSURE, _rhs


@njit(cache=True)
def _integrate(  # pragma: no cover - compiled
    y0,
    c,
    law,
    t_start,
    v_set,
    mode_a,
    mode_b,
    set_a,
    set_b,
    q_pump,
    coupled,
    ramp_s,
    dt,
    n_steps,
    every,
    out,
):
    """Integrate ``n_steps`` fixed steps from ``y0`` through the program's segments,
    writing every ``every``-th state to ``out``; returns the rows written.

    Longer than 80 lines on purpose: the compiled step loop (segment and ramp lookup,
    the finite-difference Jacobian, the linearly implicit solve and the state floors)
    stays one numba function so the scratch arrays live across steps without calls.
    """
    y = y0.copy()
    f0 = np.empty(_N)
    f1 = np.empty(_N)
    yp = np.empty(_N)
    jac = np.empty((_N, _N))
    piv = np.empty(_N, dtype=np.int64)
    seg = np.empty(8)
    scale = np.array([1e-6, 1e-6, 1e-9, 1.0, 1.0, 1.0, 1e-6, 1e-6])
    k = 0
    n_seg = t_start.shape[0]
    x_ref = y0[0]
    v_prev_seg = 0.0
    row = 0
    for n in range(n_steps):
        t = n * dt
        while k + 1 < n_seg and t >= t_start[k + 1]:
            v_prev_seg = v_set[k]
            k += 1
        frac = min((t - t_start[k]) / ramp_s, 1.0) if ramp_s > 0 else 1.0
        v_cmd = v_prev_seg + (v_set[k] - v_prev_seg) * frac
        seg[0] = mode_a[k]
        seg[1] = mode_b[k]
        seg[2] = set_a[k]
        seg[3] = set_b[k]
        pump_ramp = min(t / 0.02, 1.0)
        seg[4] = q_pump[k] * pump_ramp
        seg[5] = v_cmd
        seg[6] = x_ref
        seg[7] = coupled
        friction = _rhs(y, f0, c, law, seg)
        if n % every == 0 and row < out.shape[0]:
            out[row, 0] = t
            for i in range(_N):
                out[row, 1 + i] = y[i]
            out[row, 9] = f0[1]
            out[row, 10] = friction
            out[row, 11] = k
            out[row, 12] = v_cmd
            row += 1
        # finite-difference Jacobian
        for j in range(_N):
            h = 1e-7 * max(abs(y[j]), scale[j]) + 1e-12
            for i in range(_N):
                yp[i] = y[i]
            yp[j] = y[j] + h
            _rhs(yp, f1, c, law, seg)
            for i in range(_N):
                jac[i, j] = -dt * (f1[i] - f0[i]) / h
            jac[j, j] += 1.0
        for i in range(_N):
            f1[i] = dt * f0[i]
        if not lu_factor(jac, piv):  # (I - dt J) dy = dt f, LU with partial pivoting
            raise ZeroDivisionError("rig step: singular Jacobian")
        lu_solve(jac, piv, f1)
        for i in range(_N):
            y[i] += f1[i]
        if y[3] < _P_FLOOR:
            y[3] = _P_FLOOR
        if y[4] < _P_FLOOR:
            y[4] = _P_FLOOR
        if y[6] < 0.0:
            y[6] = 0.0
        if y[7] < 0.0:
            y[7] = 0.0
        if mode_a[k] == PORT_PRESSURE or mode_b[k] == PORT_PRESSURE:
            x_ref = y[0]
        else:
            x_ref += v_cmd * dt
    return row


def simulate_rig(
    program: RigProgram,
    *,
    design: RigDesign | None = None,
    friction_law: FrictionLaw | None = None,
    dt_s: float = 2.5e-4,
    output_rate_hz: float = 1000.0,
    oil_temp_c: tuple[float, float] = (35.0, 38.0),
) -> RigRecording:
    """Run a rig program; return the true states on the output grid.

    Parameters
    ----------
    program : RigProgram
        From :func:`~sims.rig.friction_test_program` or built by
        :func:`~sims.rig.pressure_loss_test`.
    design : RigDesign, optional
        Default :class:`RigDesign()`.
    friction_law : FrictionLaw, optional
        Seal friction (LuGre, eq 15, parameters linear in the rodless pressure, eq 17);
        ``None`` for an ideal seal.
    dt_s : float
        Fixed step of the linearly implicit integrator [s]; must divide the output
        period. Stable at any step (L-stable); 2.5e-4 s resolves the 1 kHz output.
    output_rate_hz : float
        Rate of the returned frame [Hz].
    oil_temp_c : (float, float)
        Oil temperature at start and end [degC], linear drift (recorded only; the
        friction law has no temperature term).
    """
    design = design or RigDesign()
    every = round(1.0 / (output_rate_hz * dt_s))
    if every < 1 or abs(every * dt_s * output_rate_hz - 1.0) > 1e-9:
        raise ValueError(f"dt_s={dt_s} must divide the output period 1/{output_rate_hz} s")
    n_steps = round(program.total_s / dt_s)
    has_friction = friction_law is not None
    c = _constants(design, program, friction_law)
    law = law_array(friction_law) if has_friction else np.ones(8)
    y0 = np.zeros(_N)
    y0[0] = program.x0_m
    y0[3] = program.p0_a_pa
    y0[4] = program.p0_b_pa
    if has_friction:  # bristles relaxed
        y0[2] = 0.0
    out = np.empty((n_steps // every + 1, 13))
    start = time.perf_counter()
    rows = _integrate(
        y0,
        c,
        law,
        program.t_start_s.astype(np.float64),
        program.velocity_setpoint_m_s.astype(np.float64),
        program.mode_a.astype(np.int64),
        program.mode_b.astype(np.int64),
        program.setting_a_pa.astype(np.float64),
        program.setting_b_pa.astype(np.float64),
        program.pump_flow_m3_s.astype(np.float64),
        1.0 if program.loading_coupled else 0.0,
        program.ramp_s,
        dt_s,
        n_steps,
        every,
        out,
    )
    wall = time.perf_counter() - start
    out = out[:rows]
    if not np.all(np.isfinite(out)):
        raise FloatingPointError("rig simulation diverged (non-finite state)")
    frame = _frame(out, program, oil_temp_c)
    return RigRecording(
        frame=frame,
        program=program,
        design=design,
        friction_law=friction_law,
        dt_s=dt_s,
        wall_s=wall,
        meta={"steps": n_steps, "sim_s_per_wall_s": program.total_s / max(wall, 1e-9)},
    )


def _constants(
    design: RigDesign, program: RigProgram, friction_law: FrictionLaw | None
) -> np.ndarray:
    """The constant vector ``c`` that :func:`sims.rig_model._rhs` reads."""
    r_lam, r_loc = design.line_coefficients()
    has_friction = friction_law is not None
    sigma0 = friction_law.bristle_stiffness_n_m if has_friction else 1.0
    sigma1 = friction_law.bristle_damping_n_s_m if has_friction else 0.0
    mass = design.moving_mass_kg + (design.loading_mass_kg if program.loading_coupled else 0.0)
    return np.array(
        [
            design.bore_area_m2,
            design.annulus_area_m2,
            design.loading_area_m2,
            mass,
            design.stroke_m,
            design.dead_volume_m3,
            design.bulk_modulus_pa,
            r_lam,
            r_loc,
            design.relief_rated_flow_m3_s,
            design.relief_override_pa,
            design.relief_time_constant_s,
            sigma0,
            sigma1,
            1.0 if has_friction else 0.0,
            design.loading_volume_m3,
            design.pump_rated_pressure_pa,
            design.pump_relief_override_pa,
            design.servo_position_gain_1_s,
        ]
    )


def _frame(out: np.ndarray, program: RigProgram, oil_temp_c: tuple[float, float]) -> pl.DataFrame:
    """The recording's frame from the integrator's output rows."""
    seg = out[:, 11].astype(np.int64)
    t = out[:, 0]
    temp = oil_temp_c[0] + (oil_temp_c[1] - oil_temp_c[0]) * t / max(program.total_s, 1e-9)
    return pl.DataFrame(
        {
            "time_s": t,
            "step": program.step[seg].astype(np.int32),
            "pressure_setpoint_pa": program.pressure_setpoint_pa[seg],
            "velocity_setpoint_m_s": out[:, 12],
            "x_m": out[:, 1],
            "v_m_s": out[:, 2],
            "a_m_s2": out[:, 9],
            "p_rodless_pa": out[:, 4],
            "p_rod_pa": out[:, 5],
            "p_loading_pa": out[:, 6],
            "friction_n": out[:, 10],
            "z_m": out[:, 3],
            "oil_temp_c": temp,
        }
    )
