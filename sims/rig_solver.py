"""The rig's integrator and :func:`simulate_rig` (public through :mod:`sims.rig`).

ROS2 (the shared :func:`sims.hydraulics.ros2_matrix` / :func:`~sims.hydraulics.ros2_step`:
two-stage, second-order, L-stable Rosenbrock-W) at a fixed step with a finite-difference
Jacobian every step, compiled with numba, around :func:`sims.rig_model.rhs` on the state
extended by time and the servo reference; a step is split at a segment start inside it,
and the state floors (vacuum, closed valves) are applied after each step. Until issue 17
this was a first-order linearly implicit (Rosenbrock-)Euler step.
"""

from __future__ import annotations

import time

import numpy as np
import polars as pl
from numba import njit

from physics.friction_law import law_array
from schemas.hoist import FrictionLaw
from sims.hydraulics import lu_storage, ros2_matrix, ros2_step
from sims.rig_design import RigDesign, RigProgram, RigRecording
from sims.rig_model import N_STATE, P_FLOOR, PORT_PRESSURE, rhs

#: Absolute tolerances of the extended state (t, x, v, z, p_A, p_B, p_L, y_A, y_B, x_ref)
#: [s, m, m/s, m, Pa, Pa, Pa, -, -, m]: they set the finite-difference steps,
#: 1e-7 max(|y|, 1e3 atol) (the first-order step's scales before issue 17), and weigh
#: the error estimate reported as ``meta["error_ratio_max"]`` (with rtol 1e-6).
_ATOL = np.array([1e-9, 1e-9, 1e-9, 1e-12, 1e-3, 1e-3, 1e-3, 1e-9, 1e-9, 1e-9])
_RTOL = 1e-6
_NY = N_STATE + 2  # the extended state: time, the model state, the servo reference x_ref
_XREF = N_STATE + 1


@njit(cache=True)
def _step_rhs(y, args, out):  # pragma: no cover - compiled
    """:func:`sims.rig_model.rhs` on the extended state, as the ROS2 ``rhs``.

    ``args = (c, law, prog, ctrl, seg, aux)``: ``prog`` the program rows (t_start, v_set,
    mode_a, mode_b, set_a, set_b, q_pump), ``ctrl`` = (segment k, previous segment's
    velocity setpoint, coupled, ramp_s); ``seg`` scratch for the model's segment values;
    ``aux`` receives the seal friction and the commanded velocity. The velocity ramp and
    the pump start ramp are evaluated at the state's time ``y[0]``; the servo reference
    ``x_ref`` integrates the commanded velocity, and follows the rod while a port is
    pressure-regulated.
    """
    c, law, prog, ctrl, seg, aux = args
    k = int(ctrl[0])
    t = y[0]
    ramp_s = ctrl[3]
    frac = min(max((t - prog[k, 0]) / ramp_s, 0.0), 1.0) if ramp_s > 0 else 1.0
    v_cmd = ctrl[1] + (prog[k, 1] - ctrl[1]) * frac
    pressure = prog[k, 2] == PORT_PRESSURE or prog[k, 3] == PORT_PRESSURE
    for i in range(4):
        seg[i] = prog[k, 2 + i]
    seg[4] = prog[k, 6] * min(t / 0.02, 1.0)
    seg[5] = v_cmd
    seg[6] = y[1] if pressure else y[_XREF]
    seg[7] = ctrl[2]
    aux[0] = rhs(y[1:_XREF], out[1:_XREF], c, law, seg)
    aux[1] = v_cmd
    out[0] = 1.0
    out[_XREF] = y[2] if pressure else v_cmd


@njit(cache=True)
def _to_segment(t, prog, ctrl, dt):  # pragma: no cover - compiled
    """Advance ``ctrl``'s segment to the one running at ``t`` (a start within 1e-6 dt
    after ``t`` counts as reached)."""
    k = int(ctrl[0])
    while k + 1 < prog.shape[0] and t >= prog[k + 1, 0] - 1e-6 * dt:
        ctrl[1] = prog[k, 1]
        k += 1
    ctrl[0] = k


@njit(cache=True)
def _floors(y, prog, k):  # pragma: no cover - compiled
    """State floors after a step: vacuum gauge pressure, closed valves; x_ref on the rod
    while a port is pressure-regulated."""
    y[4] = max(y[4], P_FLOOR)
    y[5] = max(y[5], P_FLOOR)
    y[7] = max(y[7], 0.0)
    y[8] = max(y[8], 0.0)
    if prog[k, 2] == PORT_PRESSURE or prog[k, 3] == PORT_PRESSURE:
        y[_XREF] = y[1]


@njit(cache=True)
def _integrate(y0, c, law, prog, ctrl, dt, n_steps, every, atol, out):  # pragma: no cover
    """Integrate ``n_steps`` ROS2 steps from the model state ``y0`` through the program
    rows ``prog``, writing every ``every``-th state to ``out``; returns the rows written
    and the largest error ratio.

    A step that a segment start falls inside is split there, so each (sub)step sees one
    segment's port modes and settings (second order across the switches too).
    """
    y = np.empty(_NY)
    y[1:_XREF] = y0
    y[_XREF] = y0[0]
    seg = np.empty(8)
    aux = np.zeros(2)
    args = (c, law, prog, ctrl, seg, aux)
    f0 = np.empty(_NY)
    work = np.empty((4, _NY))
    lu = lu_storage(_NY)
    err_max = 0.0
    row = 0
    for n in range(n_steps):
        y[0] = n * dt
        t_end = (n + 1) * dt
        _to_segment(y[0], prog, ctrl, dt)
        _step_rhs(y, args, f0)
        if n % every == 0 and row < out.shape[0]:
            out[row, 0] = y[0]
            out[row, 1 : 1 + N_STATE] = y[1:_XREF]
            out[row, 9], out[row, 10], out[row, 11], out[row, 12] = f0[2], aux[0], ctrl[0], aux[1]
            row += 1
        while True:
            k = int(ctrl[0])
            t_next = prog[k + 1, 0] if k + 1 < prog.shape[0] else t_end
            split = t_next < t_end - 1e-6 * dt
            h = (t_next if split else t_end) - y[0]
            if not ros2_matrix(_step_rhs, args, y, f0, h, atol, lu, work):
                raise ZeroDivisionError("rig step: singular iteration matrix")
            err, _ = ros2_step(_step_rhs, args, y, f0, h, atol, _RTOL, lu, work)
            err_max = max(err_max, err)
            _floors(y, prog, k)
            if not split:
                break
            y[0] = t_next
            _to_segment(t_next, prog, ctrl, dt)
            _step_rhs(y, args, f0)
    return row, err_max


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
        Fixed step of the ROS2 integrator [s]; must divide the output period. Stable at
        any step (L-stable), second order; 2.5e-4 s resolves the 1 kHz output.
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
    y0 = np.zeros(N_STATE)
    y0[0] = program.x0_m
    y0[3] = program.p0_a_pa
    y0[4] = program.p0_b_pa
    if has_friction:  # bristles relaxed
        y0[2] = 0.0
    out = np.empty((n_steps // every + 1, 13))
    start = time.perf_counter()
    prog = np.column_stack(
        [
            program.t_start_s,
            program.velocity_setpoint_m_s,
            program.mode_a,
            program.mode_b,
            program.setting_a_pa,
            program.setting_b_pa,
            program.pump_flow_m3_s,
        ]
    ).astype(np.float64)
    ctrl = np.array([0.0, 0.0, 1.0 if program.loading_coupled else 0.0, program.ramp_s])
    rows, err_max = _integrate(y0, c, law, prog, ctrl, dt_s, n_steps, every, _ATOL, out)
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
        meta={
            "steps": n_steps,
            "sim_s_per_wall_s": program.total_s / max(wall, 1e-9),
            "error_ratio_max": float(err_max),
        },
    )


def _constants(
    design: RigDesign, program: RigProgram, friction_law: FrictionLaw | None
) -> np.ndarray:
    """The constant vector ``c`` that :func:`sims.rig_model.rhs` reads."""
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
