"""The single-cylinder test rig's design, its programs and its recordings (data only).

:class:`RigDesign` (geometry, oil, lines, valves; defaults from paper 3.1 and 4.2.1),
:class:`RigProgram` (a piecewise-constant program, one row per step),
:class:`RigRecording` (a simulated run and its truth) and :func:`default_friction_law`.
Public through :mod:`sims.rig`, which describes the model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import polars as pl

from physics.branch_loss import laminar_resistance
from physics.friction_law import friction_parameters, stribeck_friction
from physics.tension import annulus_area_m2, bore_area_m2
from schemas.hoist import EXAMPLE_HOIST, FrictionLaw, load_hoist

#: Paper 3.1: steady pressure loss at 20 L/min, 0.36 MPa at every load pressure.
PAPER_LOSS_PA = 0.36e6


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
        return bore_area_m2(self.bore_m)

    @property
    def annulus_area_m2(self) -> float:
        return annulus_area_m2(self.bore_m, self.rod_m)

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
