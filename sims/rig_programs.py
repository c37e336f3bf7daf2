"""Rig programs: the paper 3.1 pressure-loss test and the 4.2.1 friction test.

Public through :mod:`sims.rig`: :func:`pressure_loss_test` (runs it, a
:class:`LossTestResult`), :func:`friction_test_program` and
:func:`small_friction_test_program` (programs for :func:`sims.rig.simulate_rig`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from physics.friction_law import friction_parameters, stribeck_friction
from schemas.hoist import FrictionLaw
from sims.rig_design import RigDesign, RigProgram, default_friction_law
from sims.rig_model import PORT_FLOW, PORT_PRESSURE, PORT_RELIEF, PORT_TANK
from sims.rig_solver import simulate_rig


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
        sweep = _pressure_rows(
            p,
            step,
            speeds_m_s=speeds_m_s,
            steady_s=steady_s,
            settle_lengths=settle_lengths,
            dwell_s=dwell_s,
            ramp=ramp,
            law=law,
            design=design,
        )
        rows += sweep
        step += len(sweep)
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


def _pressure_rows(
    p: float,
    first_step: int,
    *,
    speeds_m_s: tuple[float, ...],
    steady_s: float,
    settle_lengths: float,
    dwell_s: float,
    ramp: float,
    law: FrictionLaw,
    design: RigDesign,
) -> list[dict]:
    """The program rows at one oil pressure ``p``: a dwell and a sweep rod out, a dwell
    and the sweep rod in; steps numbered from ``first_step``."""
    rows: list[dict] = []
    step = first_step
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
    return rows


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
