"""The named physical effects of contract section 4.

One name per effect that the simulation can switch on and the discovery workflow can
report. A hoist's ``[model] effects`` list and the discrepancy report use exactly these
names; ``none`` is reserved for "nothing is missing" in the report only.
"""

from __future__ import annotations

from typing import Literal, get_args

__all__ = [
    "EFFECT_DESCRIPTIONS",
    "EFFECT_NAMES",
    "NO_EFFECT",
    "READ_WITH_THE_ROPES",
    "EffectName",
]

EffectName = Literal[
    "tail_rope_weight",
    "conveyance_inertia",
    "seal_friction",
    "presliding_hysteresis",
    "pipe_laminar_loss",
    "local_loss",
    "oil_compressibility",
    "viscosity_temperature",
    "sensor_offset",
    "sensor_gain",
    "groove_wear",
]

#: Every effect name, in contract order.
EFFECT_NAMES: tuple[str, ...] = get_args(EffectName)

#: What the discrepancy report says when no effect is missing.
NO_EFFECT = "none"

#: One line per effect: what it is and the parameter(s) that discovery estimates.
EFFECT_DESCRIPTIONS: dict[str, str] = {
    "tail_rope_weight": "weight of the hanging tail ropes, changing with depth [kg/m]",
    "conveyance_inertia": "conveyance mass times hoist acceleration [kg]",
    "seal_friction": "piston-seal friction, Coulomb + Stribeck + viscous, pressure dependent "
    "(paper eq 16-17)",
    "presliding_hysteresis": "history-dependent friction at standstill (Maxwell-slip elements) "
    "[N/m, count]",
    "pipe_laminar_loss": "pressure drop along the connecting pipes, proportional to flow "
    "(paper eq 6, 12) [m, m]",
    "local_loss": "valve and fitting losses, proportional to flow squared (paper eq 13) [-]",
    "oil_compressibility": "finite bulk modulus: lag and ringing between cylinders "
    "(paper eq 5, 8) [Pa]",
    "viscosity_temperature": "oil viscosity falling with temperature (ASTM D341) [-]",
    "sensor_offset": "constant zero error on one pressure sensor [Pa]",
    "sensor_gain": "span error on one pressure sensor [-]",
    "groove_wear": "unequal drum groove radii: rope lengths drift apart with travel [m]",
}

assert set(EFFECT_DESCRIPTIONS) == set(EFFECT_NAMES)

#: The effects whose parameters the ropes' identification reads off a hoist's
#: description (``pipelines.identified_ropes.described_by_parameters``): the branch
#: losses and the oil turn the sensors' pressures into the chambers' and tie the
#: pistons together, the sensors' calibrations read the pressures, the grooves pay the
#: ropes out. Ropes identified without such an effect have taken part of it.
READ_WITH_THE_ROPES: frozenset[str] = frozenset(
    {
        "pipe_laminar_loss",
        "local_loss",
        "viscosity_temperature",
        "oil_compressibility",
        "groove_wear",
        "sensor_offset",
        "sensor_gain",
    }
)
