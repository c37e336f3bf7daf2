"""The single-cylinder test rig of paper sections 3.1 and 4.2.1, and its MCAP recordings.

One lumped model serves both experiments of the paper:

* **Pressure-loss test (section 3.1, Fig. 4-5).** The loading cylinder (Fig. 4 item 8),
  fed by the pump (rated 12 MPa, 20 L/min) through the directional valve, pushes the
  tested cylinder's rod in; the tested rodless chamber expels its oil through its branch
  (directional valve + hose) to the overflow valve (item 10) that sets the load pressure.
  The rodless chamber then reads the load pressure plus the branch loss (eq 12-14) plus
  the valve's flow override: a loss that depends on flow only, not on the load
  (:func:`pressure_loss_test`). A relief valve's opening lag makes the start overshoot.
* **Friction test (section 4.2.1, Fig. 15).** The tested cylinder alone, driven at a
  controlled velocity by a flow servo into one chamber, while the pressure-control
  (back-pressure) valve on the other chamber's outlet holds the oil pressure at the
  setpoint, 2..12 MPa, in both directions (:func:`friction_test_program`,
  :func:`simulate_rig`). Friction is what the pressures do not explain (contract 3):
  ``F = p_rodless A_bore - p_rod (A_bore - A_rod) - m a``.

Model (SI; x positive rod out, the rodless chamber growing):

.. math::
    m \\dot v = p_A A_b - p_B A_a - F_{LuGre}(v, z, p_A) - p_L A_L \\\\
    \\dot p_A = \\frac{\\beta}{V_A(x)}(Q_A - A_b v), \\quad
    \\dot p_B = \\frac{\\beta}{V_B(x)}(Q_B + A_a v), \\quad
    \\dot p_L = \\frac{\\beta}{V_L(x)}(Q_{pump} - Q_{relief} + A_L v)

with LuGre (paper eq 15) for the seal, its parameters linear in the rodless pressure
p_A (eq 17 form, a :class:`~schemas.hoist.FrictionLaw`), and an overflow valve per
outlet whose opening y lags its static characteristic by a first-order time constant:
``Q = Q_rated y``, ``tau dy/dt = (p_port - p_set)/dp_override - y``. Branch lines are
resistive: ``p_chamber - p_port = R_lam Q + R_loc Q|Q|`` (eq 6/12 laminar, eq 13 local).

Integrator: linearly implicit (Rosenbrock-Euler / W-method) fixed step with a
finite-difference Jacobian every step, L-stable: a bulk modulus of 1.5 GPa on a
0.2 L dead volume (hydraulic stiffness ~5e8 N/m) and a bristle stiffness of 2.5e7 N/m
stay stable at any step; accuracy of transients is first order in dt, steady states
are exact. Compiled with numba: ~0.27 M steps/s on one core, ~70x real time at the
default 0.25 ms step.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl
from mcap.writer import Writer
from numba import njit

from physics.branch_loss import laminar_resistance
from physics.friction_law import (
    friction_law_at,
    friction_parameters,
    law_array,
    stribeck_friction,
    stribeck_g,
)
from physics.lugre import lugre_force_at, lugre_z_rate
from schemas.hoist import EXAMPLE_HOIST, FrictionLaw, load_hoist
from schemas.rig_topics import schema_bytes

__all__ = [
    "PAPER_LOSS_PA",
    "PORT_FLOW",
    "PORT_PRESSURE",
    "PORT_RELIEF",
    "PORT_TANK",
    "LossTestResult",
    "RigDesign",
    "RigProgram",
    "RigRecording",
    "RigSensors",
    "default_friction_law",
    "friction_test_program",
    "pressure_loss_test",
    "simulate_rig",
    "small_friction_test_program",
    "write_rig_mcap",
]

#: Paper 3.1: steady pressure loss at 20 L/min, 0.36 MPa at every load pressure.
PAPER_LOSS_PA = 0.36e6

# Port modes of the program (per segment, per chamber port).
PORT_FLOW = 0  # flow servo into the chamber (velocity control)
PORT_RELIEF = 1  # outlet through the branch to an overflow / back-pressure valve
PORT_TANK = 2  # open to tank (p = 0 gauge)
PORT_PRESSURE = 3  # pressure-regulated supply through the branch (setting = its pressure)

_N = 8  # state: x, v, z, pA, pB, pL, yA, yB
_P_FLOOR = -0.09e6  # gauge pressure floor (vacuum): cavitation is not modelled


@dataclass(frozen=True)
class RigDesign:
    """Geometry, oil, lines and valves of the rig (SI). Defaults: paper 3.1 and 4.2.1.

    The branch line (``line_*``) and the overflow valve override are tuned so that the
    steady loss at the paper's 20 L/min pump flow is 0.36 MPa (section 3.1); the valve
    time constant so that the start overshoot at 11 MPa is close to the paper's
    0.5 MPa (11.86 MPa peak). Oil: ISO VG 46 at 40 degC (paper 2.2: 900 kg/m3,
    46 mm2/s), bulk modulus 1.5 GPa (not given in the paper; NOTES.md).
    """

    bore_m: float = 0.100
    rod_m: float = 0.060
    stroke_m: float = 1.000
    moving_mass_kg: float = 25.0
    dead_volume_m3: float = 0.2e-3
    bulk_modulus_pa: float = 1.5e9
    density_kg_m3: float = 900.0
    kinematic_viscosity_m2_s: float = 46e-6
    line_bore_m: float = 0.010
    line_length_m: float = 3.0
    line_k_local: float = 18.09
    relief_rated_flow_m3_s: float = 20e-3 / 60.0
    relief_override_pa: float = 0.30e6
    relief_time_constant_s: float = 0.072
    loading_bore_m: float = 0.125
    loading_volume_m3: float = 1.0e-3
    loading_mass_kg: float = 15.0
    pump_rated_pressure_pa: float = 12e6
    pump_relief_override_pa: float = 0.3e6
    servo_position_gain_1_s: float = 20.0
    oil: str = "ISO VG 46"
    rig_id: str = "friction-rig-1"

    @property
    def bore_area_m2(self) -> float:
        return math.pi * self.bore_m**2 / 4.0

    @property
    def annulus_area_m2(self) -> float:
        return math.pi * (self.bore_m**2 - self.rod_m**2) / 4.0

    @property
    def loading_area_m2(self) -> float:
        return math.pi * self.loading_bore_m**2 / 4.0

    def line_coefficients(self) -> tuple[float, float]:
        """(R_lam [Pa s/m3], R_loc [Pa s2/m6]) of the branch, eq 6/12 and eq 13.

        Laminar along the hose (Hagen-Poiseuille, 128 mu l / (pi d^4)); the local term
        ``K rho / (2 A^2)`` lumps the directional valve and fittings.
        """
        mu = self.kinematic_viscosity_m2_s * self.density_kg_m3
        area = math.pi * self.line_bore_m**2 / 4.0
        r_lam = laminar_resistance(mu, self.line_length_m, self.line_bore_m)
        r_loc = self.line_k_local * self.density_kg_m3 / (2.0 * area**2)
        return r_lam, r_loc

    def steady_loss_pa(self, flow_m3_s: float) -> float:
        """Branch loss plus valve override at a steady outflow [Pa] (what 3.1 measures)."""
        r_lam, r_loc = self.line_coefficients()
        q = abs(flow_m3_s)
        return r_lam * q + r_loc * q * q + self.relief_override_pa * q / self.relief_rated_flow_m3_s


def default_friction_law() -> FrictionLaw:
    """The example hoist's seal friction (OLS fit of paper Table 1, MPa reading) for a
    100 mm bore: the rig's cylinder is the same 100 x 60 mm (paper 3.1)."""
    hoist = load_hoist(EXAMPLE_HOIST)
    return hoist.friction.law(hoist.cylinders.bore_area_m2)


@dataclass(frozen=True)
class RigProgram:
    """A piecewise-constant rig program: one row per step (segment).

    Arrays of equal length: ``t_start_s`` (ascending, first 0), ``duration_s``,
    ``step`` (the ``/rig/step`` number), ``pressure_setpoint_pa``,
    ``velocity_setpoint_m_s`` (ramped over ``ramp_s`` from the previous step's value),
    ``mode_a``/``mode_b`` (port modes: 0 flow servo, 1 relief, 2 tank),
    ``setting_a_pa``/``setting_b_pa`` (overflow valve set pressures), ``pump_flow_m3_s``
    (loading-cylinder pump, 0 when the loading cylinder is uncoupled) and
    ``steady`` (True where the speed is settled: the calibration window, for truth).
    """

    t_start_s: np.ndarray
    duration_s: np.ndarray
    step: np.ndarray
    pressure_setpoint_pa: np.ndarray
    velocity_setpoint_m_s: np.ndarray
    mode_a: np.ndarray
    mode_b: np.ndarray
    setting_a_pa: np.ndarray
    setting_b_pa: np.ndarray
    pump_flow_m3_s: np.ndarray
    ramp_s: float = 0.05
    loading_coupled: bool = False
    x0_m: float = 0.0
    p0_a_pa: float = 0.0
    p0_b_pa: float = 0.0
    settle_s: np.ndarray | None = None

    @property
    def total_s(self) -> float:
        return float(self.t_start_s[-1] + self.duration_s[-1])


@dataclass
class RigRecording:
    """A simulated rig run: the true states on the output grid, the program, the truth.

    ``frame`` columns: ``time_s, step, pressure_setpoint_pa, velocity_setpoint_m_s,
    x_m, v_m_s, a_m_s2, p_rodless_pa, p_rod_pa, p_loading_pa, friction_n, z_m,
    oil_temp_c`` (true values, no sensor noise). ``friction_law`` is the TRUE law used;
    :meth:`true_step_parameters` gives the true Fc, Fs, vs, Kv per step.
    """

    frame: pl.DataFrame
    program: RigProgram
    design: RigDesign
    friction_law: FrictionLaw | None
    dt_s: float
    wall_s: float = 0.0
    meta: dict = field(default_factory=dict)

    def true_step_parameters(self) -> pl.DataFrame:
        """True Fc, Fs, vs, Kv [N, N, m/s, N s/m] per step at the step's mean rodless
        pressure over its settled window, with the steady-state friction there
        (eq 16) and the simulated mean friction for comparison."""
        if self.friction_law is None:
            raise ValueError("recording was simulated without seal friction")
        prog = self.program
        rows = []
        t = self.frame["time_s"].to_numpy()
        pa = self.frame["p_rodless_pa"].to_numpy()
        fr = self.frame["friction_n"].to_numpy()
        settle = prog.settle_s if prog.settle_s is not None else np.zeros_like(prog.t_start_s)
        for k in range(prog.step.size):
            t0 = prog.t_start_s[k] + prog.ramp_s + settle[k]
            t1 = prog.t_start_s[k] + prog.duration_s[k]
            window = (t >= t0) & (t < t1)
            if not window.any() or prog.velocity_setpoint_m_s[k] == 0:
                continue
            p = float(pa[window].mean())
            fc, fs, vs, kv = (float(a) for a in friction_parameters(p, self.friction_law))
            v = float(prog.velocity_setpoint_m_s[k])
            rows.append(
                {
                    "step": int(prog.step[k]),
                    "pressure_setpoint_pa": float(prog.pressure_setpoint_pa[k]),
                    "velocity_setpoint_m_s": v,
                    "p_rodless_mean_pa": p,
                    "coulomb_n": fc,
                    "static_n": fs,
                    "stribeck_speed_m_s": vs,
                    "viscous_n_s_m": kv,
                    "friction_steady_n": float(stribeck_friction(v, fc, fs, vs, kv)),
                    "friction_simulated_n": float(fr[window].mean()),
                }
            )
        return pl.DataFrame(rows)


# ---------------------------------------------------------------------------------------
# numba core
# ---------------------------------------------------------------------------------------
@njit(cache=True)
def _line_flow(dp, r_lam, r_loc):  # pragma: no cover - compiled
    # flow through the branch for a pressure difference: R_lam q + R_loc q|q| = dp
    a = abs(dp)
    q = 2.0 * a / (r_lam + math.sqrt(r_lam * r_lam + 4.0 * r_loc * a))
    return q if dp >= 0.0 else -q


@njit(cache=True)
def _rhs(y, out, c, law, seg):  # pragma: no cover - compiled
    # c: constants; seg: current segment values; law: physics.friction_law.law_array
    x, v, z, pa, pb, pl_, ya, yb = y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7]
    ab, aa, al, m, stroke, v_dead, beta = c[0], c[1], c[2], c[3], c[4], c[5], c[6]
    r_lam, r_loc, q_rated, dp_ov, tau_v = c[7], c[8], c[9], c[10], c[11]
    sigma0, sigma1, has_friction = c[12], c[13], c[14]
    v_load0, pump_crack, pump_ov, k_pos = c[15], c[16], c[17], c[18]
    mode_a, mode_b, set_a, set_b, q_pump, v_cmd, x_ref, coupled = (
        seg[0],
        seg[1],
        seg[2],
        seg[3],
        seg[4],
        seg[5],
        seg[6],
        seg[7],
    )
    # --- seal friction, LuGre (eq 15) with eq 17 parameters at p_A
    if has_friction > 0.5:
        fc, fs, vs, kv = friction_law_at(pa, law)
        zdot = lugre_z_rate(z, v, sigma0, stribeck_g(v, fc, fs, vs))
        friction = lugre_force_at(z, zdot, v, sigma0, sigma1, kv)
    else:
        zdot = -z * 1e3
        friction = 0.0
    # --- chamber volumes (x = 0 mid-stroke)
    half = 0.5 * stroke
    va = v_dead + ab * (half + x)
    vb = v_dead + aa * (half - x)
    # --- port A flow into the chamber
    dya = -ya / tau_v
    if mode_a == PORT_FLOW:
        qa = ab * (v_cmd + k_pos * (x_ref - x))
    elif mode_a == PORT_RELIEF:
        qv = q_rated * max(ya, 0.0) * min(max(pa / 0.2e6, 0.0), 1.0)
        p_port = pa - (r_lam * qv + r_loc * qv * qv)
        dya = ((p_port - set_a) / dp_ov - ya) / tau_v
        if ya <= 0.0 and dya < 0.0:
            dya = 0.0
        qa = -qv
    elif mode_a == PORT_PRESSURE:
        qa = _line_flow(set_a - pa, r_lam, r_loc)
    else:
        qa = 0.0
    dya_out = dya
    dyb = -yb / tau_v
    if mode_b == PORT_FLOW:
        qb = aa * (-v_cmd - k_pos * (x_ref - x))
    elif mode_b == PORT_RELIEF:
        qv = q_rated * max(yb, 0.0) * min(max(pb / 0.2e6, 0.0), 1.0)
        p_port = pb - (r_lam * qv + r_loc * qv * qv)
        dyb = ((p_port - set_b) / dp_ov - yb) / tau_v
        if yb <= 0.0 and dyb < 0.0:
            dyb = 0.0
        qb = -qv
    elif mode_b == PORT_PRESSURE:
        qb = _line_flow(set_b - pb, r_lam, r_loc)
    else:
        qb = 0.0
    # --- loading cylinder (paper Fig. 4 item 8), pushing the rod in (x decreasing)
    if coupled > 0.5:
        vl = v_load0 + al * (half - x)
        q_rel = max(pl_ - pump_crack, 0.0) * max(q_pump, 1e-6) / pump_ov
        dpl = beta / vl * (q_pump - q_rel + al * v)
        f_load = pl_ * al
    else:
        dpl = -pl_ * 1e3
        f_load = 0.0
    out[0] = v
    out[1] = (pa * ab - pb * aa - friction - f_load) / m
    out[2] = zdot
    out[3] = 0.0 if mode_a == PORT_TANK else beta / va * (qa - ab * v)
    out[4] = 0.0 if mode_b == PORT_TANK else beta / vb * (qb + aa * v)
    out[5] = dpl
    out[6] = dya_out
    out[7] = dyb
    return friction


@njit(cache=True)
def _solve(a, b):  # pragma: no cover - compiled
    # Gaussian elimination with partial pivoting, in place; returns b (the solution).
    n = b.shape[0]
    for k in range(n):
        piv = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                big = abs(a[i, k])
                piv = i
        if piv != k:
            for j in range(n):
                a[k, j], a[piv, j] = a[piv, j], a[k, j]
            b[k], b[piv] = b[piv], b[k]
        inv = 1.0 / a[k, k]
        for i in range(k + 1, n):
            f = a[i, k] * inv
            if f != 0.0:
                for j in range(k, n):
                    a[i, j] -= f * a[k, j]
                b[i] -= f * b[k]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= a[i, j] * b[j]
        b[i] = s / a[i, i]
    return b


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
    y = y0.copy()
    f0 = np.empty(_N)
    f1 = np.empty(_N)
    yp = np.empty(_N)
    jac = np.empty((_N, _N))
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
        dy = _solve(jac, f1)
        for i in range(_N):
            y[i] += dy[i]
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
        From :func:`friction_test_program` or built by :func:`pressure_loss_test`.
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
    import time

    design = design or RigDesign()
    every = round(1.0 / (output_rate_hz * dt_s))
    if every < 1 or abs(every * dt_s * output_rate_hz - 1.0) > 1e-9:
        raise ValueError(f"dt_s={dt_s} must divide the output period 1/{output_rate_hz} s")
    n_steps = round(program.total_s / dt_s)
    r_lam, r_loc = design.line_coefficients()
    has_friction = friction_law is not None
    sigma0 = friction_law.bristle_stiffness_n_m if has_friction else 1.0
    sigma1 = friction_law.bristle_damping_n_s_m if has_friction else 0.0
    mass = design.moving_mass_kg + (design.loading_mass_kg if program.loading_coupled else 0.0)
    c = np.array(
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
    seg = out[:, 11].astype(np.int64)
    t = out[:, 0]
    temp = oil_temp_c[0] + (oil_temp_c[1] - oil_temp_c[0]) * t / max(program.total_s, 1e-9)
    frame = pl.DataFrame(
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
    return RigRecording(
        frame=frame,
        program=program,
        design=design,
        friction_law=friction_law,
        dt_s=dt_s,
        wall_s=wall,
        meta={"steps": n_steps, "sim_s_per_wall_s": program.total_s / max(wall, 1e-9)},
    )


# ---------------------------------------------------------------------------------------
# Programs
# ---------------------------------------------------------------------------------------
def _program(rows: list[dict], **kwargs) -> RigProgram:
    t = np.cumsum([0.0] + [r["duration_s"] for r in rows[:-1]])
    cols = {
        key: np.array([r[key] for r in rows])
        for key in (
            "duration_s",
            "step",
            "pressure_setpoint_pa",
            "velocity_setpoint_m_s",
            "mode_a",
            "mode_b",
            "setting_a_pa",
            "setting_b_pa",
            "pump_flow_m3_s",
        )
    }
    settle = np.array([r.get("settle_s", 0.0) for r in rows])
    return RigProgram(t_start_s=t, settle_s=settle, **cols, **kwargs)


@dataclass(frozen=True)
class LossTestResult:
    """One run of the paper 3.1 pressure-loss test (rodless chamber pressure trace)."""

    load_pressure_pa: float
    pump_flow_m3_s: float
    time_s: np.ndarray
    p_rodless_pa: np.ndarray
    steady_pa: float
    peak_pa: float
    peak_time_s: float

    @property
    def loss_pa(self) -> float:
        """Steady rodless pressure minus the load (overflow valve) pressure [Pa]."""
        return self.steady_pa - self.load_pressure_pa

    @property
    def overshoot_pa(self) -> float:
        """Start-up peak above the steady pressure [Pa]."""
        return self.peak_pa - self.steady_pa


def pressure_loss_test(
    load_pressure_pa: float,
    *,
    pump_flow_m3_s: float = 20e-3 / 60.0,
    duration_s: float = 1.0,
    design: RigDesign | None = None,
    friction_law: FrictionLaw | None = None,
    dt_s: float = 2e-5,
) -> LossTestResult:
    """Paper 3.1 (Fig. 5): rodless chamber pressure when the loading cylinder starts.

    At t = 0 the directional valve opens: the pump (``pump_flow_m3_s``, relief at the
    rated 12 MPa) drives the loading cylinder, which pushes the tested rod in from near
    full extension; the expelled oil passes the branch to the overflow valve set at
    ``load_pressure_pa``. The steady pressure is taken as the mean over the last
    quarter of the run.

    Paper: 0.36 MPa loss at every load 1..11 MPa at 20 L/min; at 11 MPa a peak of
    11.86 MPa within 0.2 s, steady 11.36 MPa after 0.3 s.
    """
    design = design or RigDesign()
    law = friction_law if friction_law is not None else default_friction_law()
    row = {
        "duration_s": duration_s,
        "step": 0,
        "pressure_setpoint_pa": load_pressure_pa,
        "velocity_setpoint_m_s": 0.0,
        "mode_a": PORT_RELIEF,
        "mode_b": PORT_TANK,
        "setting_a_pa": load_pressure_pa,
        "setting_b_pa": 0.0,
        "pump_flow_m3_s": pump_flow_m3_s,
    }
    program = _program([row], ramp_s=0.0, loading_coupled=True, x0_m=0.0)
    rec = simulate_rig(program, design=design, friction_law=law, dt_s=dt_s, output_rate_hz=1e4)
    t = rec.frame["time_s"].to_numpy()
    p = rec.frame["p_rodless_pa"].to_numpy()
    steady = float(p[t >= 0.75 * duration_s].mean())
    i = int(np.argmax(p))
    return LossTestResult(
        load_pressure_pa=load_pressure_pa,
        pump_flow_m3_s=pump_flow_m3_s,
        time_s=t,
        p_rodless_pa=p,
        steady_pa=steady,
        peak_pa=float(p[i]),
        peak_time_s=float(t[i]),
    )


def _valve_settings(v: float, p: float, law: FrictionLaw, design: RigDesign) -> tuple[float, float]:
    """Back-pressure valve settings (A, B) that hold the rodless chamber at ``p`` at
    steady speed ``v``: rod out, outlet B; rod in, outlet A (4.2.1)."""
    fc, fs, vs, kv = (float(a) for a in friction_parameters(p, law))
    ab, aa = design.bore_area_m2, design.annulus_area_m2
    if v > 0:
        f = float(stribeck_friction(v, fc, fs, vs, kv))
        return 0.0, (p * ab - f) / aa - design.steady_loss_pa(aa * v)
    return p - design.steady_loss_pa(ab * v), 0.0


def friction_test_program(
    *,
    pressures_pa: tuple[float, ...] = (2e6, 4e6, 6e6, 8e6, 10e6, 12e6),
    speeds_m_s: tuple[float, ...] = (
        0.5e-3,
        1e-3,
        2e-3,
        3e-3,
        4e-3,
        5e-3,
        6e-3,
        8e-3,
        12e-3,
        20e-3,
        35e-3,
        60e-3,
    ),
    steady_s: float = 1.0,
    settle_lengths: float = 6.0,
    dwell_s: float = 0.5,
    design: RigDesign | None = None,
    friction_law: FrictionLaw | None = None,
) -> RigProgram:
    """Paper 4.2.1 friction test: speed sweeps out and in at each oil pressure.

    For each pressure: a dwell (valves set, piston held), a sweep rod out through
    ``speeds_m_s`` ascending, a dwell, the same sweep rod in, so the piston travels
    out and back over the same stroke. Each speed step lasts ``ramp`` + settle +
    ``steady_s``, the settle time being ``settle_lengths`` LuGre memory lengths
    (Fs / sigma0) at that speed, so the bristles reach the steady state (eq 16) before
    the measuring window. Speeds span 0.5..60 mm/s, around the Stribeck speed (paper
    Table 1: 3.4..7.8 mm/s).

    The back-pressure valve of each step is set (as the operator adjusts it, 4.2.1:
    "when the adjustment is completed, the backpressure remains a constant") so that
    the rodless chamber sits at the pressure setpoint at steady speed: rod out, the
    rod-side outlet valve at (p A_b - F(v)) / A_a minus its branch and override loss;
    rod in, the rodless outlet valve at p minus the loss.
    """
    design = design or RigDesign()
    law = friction_law if friction_law is not None else default_friction_law()
    ab, aa = design.bore_area_m2, design.annulus_area_m2
    ramp = 0.05
    rows: list[dict] = []
    step = 0
    travel = sum(v * (steady_s + ramp) for v in speeds_m_s)
    if travel > 0.9 * design.stroke_m:
        raise ValueError(f"program travel {travel:.3f} m exceeds 90 % of the stroke")
    for p in pressures_pa:
        fs = float(friction_parameters(p, law)[1])
        for direction in (1.0, -1.0):
            mode_a = PORT_FLOW if direction > 0 else PORT_RELIEF
            mode_b = PORT_RELIEF if direction > 0 else PORT_FLOW
            # dwell: the supply pressurises the rodless chamber to the setpoint while
            # the rod-side servo port is closed (the piston settles where forces balance)
            rows.append(
                {
                    "duration_s": dwell_s,
                    "step": step,
                    "pressure_setpoint_pa": p,
                    "velocity_setpoint_m_s": 0.0,
                    "mode_a": PORT_PRESSURE,
                    "mode_b": PORT_FLOW,
                    "setting_a_pa": p,
                    "setting_b_pa": 0.0,
                    "pump_flow_m3_s": 0.0,
                }
            )
            step += 1
            for speed in speeds_m_s:
                v = direction * speed
                set_a, set_b = _valve_settings(v, p, law, design)
                settle = settle_lengths * fs / law.bristle_stiffness_n_m / speed
                rows.append(
                    {
                        "duration_s": ramp + settle + steady_s,
                        "step": step,
                        "pressure_setpoint_pa": p,
                        "velocity_setpoint_m_s": v,
                        "mode_a": mode_a,
                        "mode_b": mode_b,
                        "setting_a_pa": set_a,
                        "setting_b_pa": set_b,
                        "pump_flow_m3_s": 0.0,
                        "settle_s": settle,
                    }
                )
                step += 1
    # start mid-stroke shifted back by half the out-sweep, chambers at the first setpoint
    p0 = pressures_pa[0]
    x0 = -0.5 * travel
    return _program(
        rows,
        ramp_s=ramp,
        loading_coupled=False,
        x0_m=x0,
        p0_a_pa=p0,
        p0_b_pa=p0 * ab / aa,
    )


def small_friction_test_program(
    *, design: RigDesign | None = None, friction_law: FrictionLaw | None = None
) -> RigProgram:
    """A short friction test for demos and tests: 2, 7, 12 MPa, nine speeds 1..50 mm/s
    (five of them within 1-2x the Stribeck speed), 0.6 s steady windows: ~50 s of
    recording, a ~2 MB MCAP file."""
    return friction_test_program(
        pressures_pa=(2e6, 7e6, 12e6),
        speeds_m_s=(1e-3, 2e-3, 3e-3, 4e-3, 6e-3, 8e-3, 12e-3, 25e-3, 50e-3),
        steady_s=0.6,
        dwell_s=0.3,
        design=design,
        friction_law=friction_law,
    )


# ---------------------------------------------------------------------------------------
# MCAP recording (contract section 3)
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RigSensors:
    """Rig sensor noise and rates (SI). Pressure transmitters 0.05 % of 40 MPa, an LVDT
    with 1 um noise, a Pt100 at 0.05 degC; log-time jitter of the acquisition."""

    pressure_sigma_pa: float = 2e3
    displacement_sigma_m: float = 1e-6
    temperature_sigma_c: float = 0.05
    pressure_rate_hz: float = 1000.0
    displacement_rate_hz: float = 500.0
    temperature_rate_hz: float = 1.0
    jitter_sigma_s: float = 20e-6


def _jittered(t_s: np.ndarray, start_ns: int, sigma_s: float, rng: np.random.Generator):
    nominal = start_ns + np.round(t_s * 1e9).astype(np.int64)
    if sigma_s <= 0 or t_s.size < 2:
        return nominal, nominal
    bound = 0.4 * float(np.min(np.diff(t_s))) * 1e9
    jitter = np.minimum(np.abs(rng.normal(0.0, sigma_s * 1e9, t_s.size)), bound)  # delay
    return nominal + np.round(jitter).astype(np.int64), nominal


def write_rig_mcap(
    path: str | Path,
    recording: RigRecording,
    *,
    start_time_ns: int = 1_772_409_600_000_000_000,  # 2026-03-02 00:00:00 UTC
    seed: int = 0,
    sensors: RigSensors | None = None,
    truncate_fraction: float | None = None,
    unknown_topic: bool = False,
    schema_encodings: dict[str, str] | None = None,
) -> Path:
    """Write a simulated rig run as one MCAP recording per contract section 3.

    Topics (message encoding ``json``, schema encoding ``jsonschema``, schemas from
    :mod:`schemas.rig_topics`): ``/rig/info`` once; ``/rig/pressure`` (``p_rodless_mpa``,
    ``p_rod_mpa``, 0.0001 MPa resolution) at ~1 kHz; ``/rig/displacement`` (``x_mm``,
    0.001 mm) at ~500 Hz; ``/rig/temperature`` (``oil_temp_c``) at ~1 Hz; ``/rig/step``
    at every step change. Log time is ns since the Unix epoch, each sample's nominal
    time plus Gaussian acquisition jitter (``publish_time`` is the nominal time);
    messages are written in log-time order.

    The displacement is the rig's x (positive rod out), offset so that mid-stroke is
    500 mm. Friction is recoverable as p_rodless A_bore - p_rod (A_bore - A_rod) - m a,
    with m = ``moving_mass_kg`` of ``/rig/info``.

    Awkward variants for ingest tests:

    * ``truncate_fraction`` -- keep only that fraction of the file's bytes (the rig
      stopped mid-write: no summary, no footer, a cut chunk).
    * ``unknown_topic`` -- add ``/rig/pump_status`` (``pump_on``, ``motor_current_a``)
      at 10 Hz, a topic the contract does not know.
    * ``schema_encodings`` -- e.g. ``{"/rig/temperature": "protobuf"}``: register that
      topic's schema with another schema encoding.
    """
    sensors = sensors or RigSensors()
    rng = np.random.default_rng(seed)
    path = Path(path)
    design = recording.design
    frame = recording.frame
    t = frame["time_s"].to_numpy()
    out_rate = 1.0 / float(np.median(np.diff(t)))
    encodings = dict(schema_encodings or {})
    messages: list[tuple[int, int, int, bytes]] = []  # (log, publish, channel, data)

    def every(rate_hz: float) -> np.ndarray:
        stride = max(round(out_rate / rate_hz), 1)
        return np.arange(0, t.size, stride)

    # pressure
    idx = every(sensors.pressure_rate_hz)
    log, pub = _jittered(t[idx], start_time_ns, sensors.jitter_sigma_s, rng)
    pa = frame["p_rodless_pa"].to_numpy()[idx] + rng.normal(0, sensors.pressure_sigma_pa, idx.size)
    pb = frame["p_rod_pa"].to_numpy()[idx] + rng.normal(0, sensors.pressure_sigma_pa, idx.size)
    pressure = [
        (int(a), int(b), 1, b'{"p_rodless_mpa":%.4f,"p_rod_mpa":%.4f}' % (u, w))
        for a, b, u, w in zip(log, pub, pa / 1e6, pb / 1e6, strict=True)
    ]
    # displacement
    idx = every(sensors.displacement_rate_hz)
    log, pub = _jittered(t[idx], start_time_ns, sensors.jitter_sigma_s, rng)
    x_mm = (frame["x_m"].to_numpy()[idx] + 0.5 * design.stroke_m) * 1e3
    x_mm = x_mm + rng.normal(0, sensors.displacement_sigma_m * 1e3, idx.size)
    displacement = [
        (int(a), int(b), 2, b'{"x_mm":%.3f}' % u) for a, b, u in zip(log, pub, x_mm, strict=True)
    ]
    # temperature
    idx = every(sensors.temperature_rate_hz)
    log, pub = _jittered(t[idx], start_time_ns, sensors.jitter_sigma_s, rng)
    temp = frame["oil_temp_c"].to_numpy()[idx] + rng.normal(
        0, sensors.temperature_sigma_c, idx.size
    )
    temperature = [
        (int(a), int(b), 3, b'{"oil_temp_c":%.2f}' % u)
        for a, b, u in zip(log, pub, temp, strict=True)
    ]
    # steps, at each program step start
    prog = recording.program
    steps = []
    for k in range(prog.step.size):
        ns = start_time_ns + round(float(prog.t_start_s[k]) * 1e9)
        body = {
            "step": int(prog.step[k]),
            "pressure_setpoint_mpa": round(float(prog.pressure_setpoint_pa[k]) / 1e6, 6),
            "velocity_setpoint_mm_s": round(float(prog.velocity_setpoint_m_s[k]) * 1e3, 6),
        }
        steps.append((ns, ns, 4, json.dumps(body).encode()))
    info = {
        "rig_id": design.rig_id,
        "bore_mm": design.bore_m * 1e3,
        "rod_mm": design.rod_m * 1e3,
        "stroke_mm": design.stroke_m * 1e3,
        "moving_mass_kg": design.moving_mass_kg,
        "oil": design.oil,
    }
    messages = [(start_time_ns, start_time_ns, 0, json.dumps(info).encode())]
    messages += steps + pressure + displacement + temperature
    if unknown_topic:
        idx = every(10.0)
        log, pub = _jittered(t[idx], start_time_ns, sensors.jitter_sigma_s, rng)
        current = 12.0 + rng.normal(0, 0.2, idx.size)
        messages += [
            (int(a), int(b), 5, b'{"pump_on":true,"motor_current_a":%.2f}' % u)
            for a, b, u in zip(log, pub, current, strict=True)
        ]
    messages.sort(key=lambda m: (m[0], m[2]))

    topics = ["/rig/info", "/rig/pressure", "/rig/displacement", "/rig/temperature", "/rig/step"]
    with path.open("wb") as handle:
        writer = Writer(handle)
        writer.start(profile="", library="ropeload-sims")
        channel_ids = {}
        for order, topic in enumerate(topics):
            schema_id = writer.register_schema(
                name=topic, encoding=encodings.get(topic, "jsonschema"), data=schema_bytes(topic)
            )
            channel_ids[order] = writer.register_channel(
                topic=topic, message_encoding="json", schema_id=schema_id
            )
        # channel order in `messages`: 0 info, 1 pressure, 2 displacement, 3 temperature,
        # 4 step, 5 unknown
        remap = dict(channel_ids)
        if unknown_topic:
            schema = {
                "title": "vendor.PumpStatus",
                "type": "object",
                "properties": {
                    "pump_on": {"type": "boolean"},
                    "motor_current_a": {"type": "number"},
                },
            }
            schema_id = writer.register_schema(
                name="/rig/pump_status",
                encoding=encodings.get("/rig/pump_status", "jsonschema"),
                data=json.dumps(schema).encode(),
            )
            remap[5] = writer.register_channel(
                topic="/rig/pump_status", message_encoding="json", schema_id=schema_id
            )
        sequence = dict.fromkeys(remap, 0)
        for log_time, publish_time, channel, data in messages:
            writer.add_message(
                remap[channel], log_time, data, publish_time, sequence=sequence[channel]
            )
            sequence[channel] += 1
        writer.finish()
    if truncate_fraction is not None:
        if not 0 < truncate_fraction < 1:
            raise ValueError("truncate_fraction: must be in (0, 1)")
        size = path.stat().st_size
        with path.open("r+b") as handle:
            handle.truncate(int(size * truncate_fraction))
    return path
