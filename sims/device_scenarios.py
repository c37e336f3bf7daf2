"""The paper's section 3.2 scenario: four balancing cylinders driven by load sources.

:func:`paper_scenario_3_2` (public as :func:`sims.device.paper_scenario_3_2`) runs the
device model of :mod:`sims.device` with fixed cylinder bodies, each rod pulled through a
spring-damper by a load source following :data:`SCENARIO_3_2_LOAD_N`.
"""

from __future__ import annotations

import numpy as np

from schemas.hoist import EXAMPLE_HOIST, Cylinders, HoistDescription, Piping, load_hoist
from sims.device_params import CYL0, EA, LBASE, PER, PM, Setup, build_par
from sims.device_results import SimulationResult
from sims.device_solver import integrate
from sims.effects import resolve_effects

#: Load-source knots of the section 3.2 scenario (Figure 10): time [s] and load per
#: cylinder [N]. Ramps from about 2000 N to about 5000 N over 0-3 s with different
#: slopes, then a sudden change (10 ms) to more than 6000 N, cylinder 2 largest and 1
#: smallest (section 3.2.2 (5)).
SCENARIO_3_2_TIME_S = np.array([0.0, 3.0, 3.01, 6.0])
SCENARIO_3_2_LOAD_N = np.array(
    [
        [2100.0, 1900.0, 2000.0, 2200.0],
        [5500.0, 4500.0, 4100.0, 6000.0],
        [6200.0, 7500.0, 6900.0, 6600.0],
        [6200.0, 7500.0, 6900.0, 6600.0],
    ]
)


def paper_scenario_3_2(
    *,
    pipe_characteristics: bool = True,
    seal_friction: bool = False,
    rope_stiffness_n_m: float = 5.0e4,
    rope_damping_n_s_m: float = 2.0e3,
    stop_valve_loss_coefficient: float = 10.0,
    duration_s: float = 6.0,
    dt_s: float = 1e-4,
    output_rate_hz: float = 1000.0,
) -> SimulationResult:
    """The four-cylinder scenario of paper section 3.2 (Figures 9-14).

    Four balancing cylinders (the paper 2.2 cylinder: 80 mm bore, 800 mm long) with
    fixed bodies; each rod is pulled through a spring-damper ("rope", paper Fig. 9
    item 6) by a load source (item 2) that would produce the load
    :data:`SCENARIO_3_2_LOAD_N` if the piston stood still (rope end displaced by
    ``-load / k``). The branches are the paper 2.2 pipe (6 mm, 1 m: 0.3 m to the sensor,
    0.7 m on) with a stop valve (``stop_valve_loss_coefficient``, open) on each bypass
    tube, into a 0.1 L manifold; VG 46 oil at 40 degC, 1.5 GPa.

    ``pipe_characteristics=False`` is the paper's case (2), "the characteristic of oil
    tube is not considered": no losses along the pipes nor at the valves (inertia and
    compressibility stay). With ``pipe_characteristics=True`` (case 3) the four
    pressures are equalised by the connection after each load change, with a pressure
    shock after the sudden change at 3 s that decays. At rest the pistons sit at
    ``(load_i - mean load) / k``: the spread of loads is taken up by piston travel.

    Solver as :func:`~sims.device.simulate` (ROS2), default step 0.1 ms, output 1 kHz.
    """
    hoist = _scenario_hoist(stop_valve_loss_coefficient)
    cylinders = hoist.cylinders
    effects = {"oil_compressibility"}
    if pipe_characteristics:
        effects |= {"pipe_laminar_loss", "local_loss"}
    if seal_friction:
        effects.add("seal_friction")
    eff = resolve_effects(hoist, effects)
    n = 4
    area = cylinders.bore_area_m2
    loads = SCENARIO_3_2_LOAD_N
    p0 = float(loads[0].mean() / area)
    par, _groove, (ms_k, ms_w) = build_par(
        hoist,
        eff,
        oil_temp_c=40.0,
        p_static_pa=p0,
        fixed_body=True,
        rope_damping_n_s_m=rope_damping_n_s_m,
    )
    par[EA] = rope_stiffness_n_m  # k = EA / (L_base + depth) with L_base = 1 m, depth 0
    par[LBASE] = 1.0
    setup = Setup(
        par=par,
        groove=np.zeros(n),
        seg=np.array([[0.0, 0.0, 0.0, 0.0]]),
        pay=np.array([[0.0, 0.0]]),
        src_t=SCENARIO_3_2_TIME_S.astype(float),
        src_s=np.ascontiguousarray(-loads / rope_stiffness_n_m),
        ms_k=np.ascontiguousarray(ms_k),
        ms_w=np.ascontiguousarray(ms_w),
        sensor_gain=np.ones(n),
        sensor_offset=np.zeros(n),
        oil_temp_c=40.0,
    )
    return integrate(
        setup,
        _scenario_start(p0, rope_stiffness_n_m),
        duration_s=duration_s,
        dt_s=dt_s,
        output_rate_hz=output_rate_hz,
        jacobian_every=1,
        eff=eff,
        profile=None,
    )


def _scenario_hoist(stop_valve_loss_coefficient: float) -> HoistDescription:
    """The example hoist with the paper 2.2 cylinders and pipes (section 3.2 rig)."""
    base = load_hoist(EXAMPLE_HOIST)
    cylinders = Cylinders(
        bore="80 mm", rod="45 mm", stroke="800 mm", dead_volume="0.05 L", piston_mass="5 kg"
    )
    piping = Piping(
        bore="6 mm",
        length_chamber_to_sensor="0.3 m",
        length_sensor_to_manifold="0.7 m",
        valve_loss_coefficient=stop_valve_loss_coefficient,
        fittings_loss_coefficient_chamber_to_sensor=0.0,
        fittings_loss_coefficient_sensor_to_manifold=0.0,
        manifold_volume="0.1 L",
    )
    # the copy derives its friction law for the new bore (HoistDescription.model_copy)
    return base.model_copy(update={"cylinders": cylinders, "piping": piping})


def _scenario_start(p0: float, rope_stiffness_n_m: float) -> np.ndarray:
    """The scenario's start: pressures at the mean initial load, each piston at
    ``(load_i - mean load) / k``, everything at rest."""
    n = 4
    loads = SCENARIO_3_2_LOAD_N
    y0 = np.zeros(CYL0 + PER * n)
    y0[PM] = p0
    for i in range(n):
        b = CYL0 + PER * i
        y0[b] = p0
        y0[b + 1] = (loads[0, i] - loads[0].mean()) / rope_stiffness_n_m
    return y0
