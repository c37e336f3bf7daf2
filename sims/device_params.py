"""The device simulation's parameter vector and state layout, and their set-up in Python.

:func:`build_par` packs a hoist description and its resolved effects into the flat
``par`` vector the compiled kernels of :mod:`sims.device_model` read (slot indices are
module constants, which numba reads as literals); :class:`Setup` bundles it with the
forcing (profile segments, payload knots, load sources) one run of
:mod:`sims.device_solver` integrates. The model itself is described in :mod:`sims.device`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from physics.maxwell_slip import maxwell_slip_elements
from physics.oil import (
    ATMOSPHERIC_PRESSURE_PA,
    effective_bulk_modulus,
    kinematic_viscosity_walther,
    walther_coefficients,
)
from schemas.hoist import G_STANDARD, HoistDescription
from sims.effects import ResolvedEffects

# ---- parameter vector layout (numba reads these module constants as literals) --------
A, VMID, MP, XMAX, KSTOP, CSTOP, BETA, VM, RHO, MU = range(10)
INERT, L1, L2, DLOSS, K1, K2, LAM_ON, LOC_ON, FRIC_ON, PRE_ON = range(10, 20)
FC0, FC1, FS0, FS1, VS0, VS1, KV0, KV1, SIG0, SIG1 = range(20, 30)
MINERT, MCONV, INERTIA_ON, TAIL_ON, TAIL_KG_M, SHAFT, LOOP, G = range(30, 38)
EA, LBASE, ZETA, RDRUM, FIXED, INERT1, CROPE, VPIPES = range(38, 46)
#: each head rope's stiffness factor on EA (KF0 + i, i < 8: the schema's most head ropes)
KF0 = 46
NPAR = KF0 + 8

# state layout: [t, eta, deta/dt, p_manifold, (p, x, v, q) per cylinder]
T, ETA, ETAD, PM = range(4)
CYL0 = 4
PER = 4

_STIFF_OIL_FACTOR = 1000.0
_K_STOP_N_M = 1e9


@dataclass(frozen=True)
class Setup:
    par: np.ndarray
    groove: np.ndarray
    seg: np.ndarray
    pay: np.ndarray
    src_t: np.ndarray
    src_s: np.ndarray
    ms_k: np.ndarray
    ms_w: np.ndarray
    sensor_gain: np.ndarray
    sensor_offset: np.ndarray
    oil_temp_c: float


def build_par(
    hoist: HoistDescription,
    eff: ResolvedEffects,
    *,
    oil_temp_c: float,
    p_static_pa: float,
    fixed_body: bool = False,
    rope_damping_n_s_m: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(par, groove offsets, (Maxwell-slip stiffnesses, weights))`` of one run."""
    prm = eff.parameters
    par = np.zeros(NPAR)
    _pack_hydraulics(par, hoist, eff, oil_temp_c=oil_temp_c, p_static_pa=p_static_pa)
    _pack_mechanics(par, hoist, eff, fixed_body=fixed_body, rope_damping_n_s_m=rope_damping_n_s_m)
    groove = (
        np.array(prm["groove_wear"]["groove_radius_deviation_m"], dtype=float)
        if eff.on("groove_wear")
        else np.zeros(hoist.ropes_n)
    )
    if eff.on("presliding_hysteresis"):
        ms_k, ms_w = maxwell_slip_elements(
            int(prm["presliding_hysteresis"]["elements"]),
            float(prm["presliding_hysteresis"]["stiffness_n_m"]),
        )
    else:
        ms_k, ms_w = np.ones(1), np.ones(1)
    return par, groove, (ms_k, ms_w)


def _pack_hydraulics(
    par: np.ndarray,
    hoist: HoistDescription,
    eff: ResolvedEffects,
    *,
    oil_temp_c: float,
    p_static_pa: float,
) -> None:
    """Cylinder, oil (bulk modulus, viscosity) and branch-line slots of ``par``."""
    prm = eff.parameters
    cyl, piping, oil = hoist.cylinders, hoist.piping, hoist.oil
    par[A] = cyl.bore_area_m2
    par[VMID] = cyl.chamber_volume_mid_m3
    par[MP] = cyl.piston_mass_kg
    par[XMAX] = cyl.stroke_m / 2.0
    par[KSTOP] = _K_STOP_N_M
    par[CSTOP] = 2.0 * math.sqrt(_K_STOP_N_M * cyl.piston_mass_kg)
    comp = prm["oil_compressibility"]
    beta = float(comp["bulk_modulus_pa"])
    if comp["air_fraction"] > 0.0:
        beta = float(
            effective_bulk_modulus(
                p_static_pa + ATMOSPHERIC_PRESSURE_PA, beta, float(comp["air_fraction"])
            )
        )
    if not eff.on("oil_compressibility"):
        beta *= _STIFF_OIL_FACTOR
    par[BETA] = beta
    par[VM] = piping.manifold_volume_m3
    if par[VM] <= 0.0:
        raise ValueError("piping.manifold_volume must be positive for the device simulation")
    par[RHO] = oil.density_kg_m3
    visc = prm["viscosity_temperature"]
    if eff.on("viscosity_temperature"):
        a, b = walther_coefficients(
            visc["kinematic_viscosity_40c_m2_s"], 40.0, visc["kinematic_viscosity_100c_m2_s"], 100.0
        )
        nu = float(kinematic_viscosity_walther(oil_temp_c, a, b))
    else:
        a, b = walther_coefficients(
            oil.kinematic_viscosity_40c_m2_s, 40.0, oil.kinematic_viscosity_100c_m2_s, 100.0
        )
        nu = float(kinematic_viscosity_walther(oil.reference_temperature_c, a, b))
    par[MU] = nu * oil.density_kg_m3
    l1, l2 = piping.length_chamber_to_sensor_m, piping.length_sensor_to_manifold_m
    par[INERT] = oil.density_kg_m3 * (l1 + l2) / piping.area_m2
    par[INERT1] = oil.density_kg_m3 * l1 / piping.area_m2
    par[VPIPES] = hoist.ropes_n * piping.branch_volume_m3
    lam = prm["pipe_laminar_loss"]
    par[L1] = lam["length_chamber_to_sensor_m"]
    par[L2] = lam["length_sensor_to_manifold_m"]
    par[DLOSS] = lam["bore_m"]
    loc = prm["local_loss"]
    par[K1] = loc["valve_loss_coefficient"] + loc["fittings_chamber_to_sensor"]
    par[K2] = loc["fittings_sensor_to_manifold"]
    par[LAM_ON] = float(eff.on("pipe_laminar_loss"))
    par[LOC_ON] = float(eff.on("local_loss"))


def _pack_mechanics(
    par: np.ndarray,
    hoist: HoistDescription,
    eff: ResolvedEffects,
    *,
    fixed_body: bool,
    rope_damping_n_s_m: float,
) -> None:
    """Seal friction, conveyance, tail rope and head rope slots of ``par``."""
    prm = eff.parameters
    par[FRIC_ON] = float(eff.on("seal_friction"))
    par[PRE_ON] = float(eff.on("presliding_hysteresis"))
    if eff.on("presliding_hysteresis") and not eff.on("seal_friction"):
        raise ValueError(
            "effect 'presliding_hysteresis' needs 'seal_friction' (its element capacities "
            "are the seal's Stribeck friction g(v))"
        )
    fr = prm["seal_friction"]
    par[FC0], par[FC1] = fr["coulomb_n"]
    par[FS0], par[FS1] = fr["static_n"]
    par[VS0], par[VS1] = fr["stribeck_speed_m_s"]
    par[KV0], par[KV1] = fr["viscous_n_s_m"]
    par[SIG0] = fr["bristle_stiffness_n_m"]
    par[SIG1] = fr["bristle_damping_n_s_m"]
    par[MINERT] = prm["conveyance_inertia"]["mass_kg"]
    par[MCONV] = hoist.conveyance.mass_kg
    par[INERTIA_ON] = float(eff.on("conveyance_inertia"))
    tail = prm["tail_rope_weight"]
    par[TAIL_ON] = float(eff.on("tail_rope_weight"))
    par[TAIL_KG_M] = tail["tail_ropes"] * tail["mass_per_length_kg_m"]
    par[SHAFT] = hoist.shaft.depth_m
    par[LOOP] = hoist.shaft.tail_rope_loop_m
    par[G] = G_STANDARD
    par[EA] = hoist.ropes.head_rope_axial_stiffness_n
    factors = hoist.ropes.head_rope_stiffness_factors
    n = hoist.ropes_n
    par[KF0 : KF0 + n] = 1.0 if factors is None else np.asarray(factors, dtype=float)
    par[LBASE] = hoist.shaft.headframe_height_m
    par[ZETA] = hoist.ropes.head_rope_damping_ratio
    par[RDRUM] = hoist.drum.radius_m
    par[FIXED] = float(fixed_body)
    par[CROPE] = rope_damping_n_s_m


def sensor_calibration(eff: ResolvedEffects, n: int) -> tuple[np.ndarray, np.ndarray]:
    gain = (
        np.array(eff.parameters["sensor_gain"]["gains"], dtype=float)
        if eff.on("sensor_gain")
        else np.ones(n)
    )
    offset = (
        np.array(eff.parameters["sensor_offset"]["offsets_pa"], dtype=float)
        if eff.on("sensor_offset")
        else np.zeros(n)
    )
    return gain, offset
