"""Effect switches and parameters of the device simulation, by contract name (section 4).

One registry, :data:`EFFECT_REGISTRY`, maps every name of
:data:`schemas.effects.EFFECT_NAMES` to an :class:`EffectSpec`: what the effect is, and
its parameters (name, unit, description, and how the default is read from a hoist
description). :func:`resolve_effects` turns a caller's choice into a
:class:`ResolvedEffects` the simulation uses::

    resolve_effects(hoist, effects={"seal_friction", "sensor_offset"},
                    parameters={"sensor_offset": {"sensor": 2, "offset_pa": 5e4}})

``effects=None`` takes the hoist's ``[model] effects``. An unknown effect or parameter
name raises :class:`ValueError` listing the valid ones. A parameter given for an effect
that is switched off also raises (it would be silently ignored otherwise).

Per-sensor effects accept either the whole list (``offsets_pa`` / ``gains``, one value
per sensor) or one sensor's value (``{"sensor": k, "offset_pa": x}`` /
``{"sensor": k, "gain": g}``, k = 1..n); the others keep the hoist's calibration.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from schemas.effects import EFFECT_DESCRIPTIONS, EFFECT_NAMES
from schemas.hoist import HoistDescription

__all__ = [
    "EFFECT_REGISTRY",
    "EffectParameter",
    "EffectSpec",
    "ResolvedEffects",
    "parameters_json",
    "resolve_effects",
]


@dataclass(frozen=True)
class EffectParameter:
    """One parameter of an effect: name, SI unit, meaning, default from the hoist."""

    name: str
    unit: str
    description: str
    default: Callable[[HoistDescription], Any]


@dataclass(frozen=True)
class EffectSpec:
    """A named effect (contract section 4) and its parameters."""

    name: str
    description: str
    parameters: tuple[EffectParameter, ...]

    def defaults(self, hoist: HoistDescription) -> dict[str, Any]:
        """The parameter values this hoist description implies."""
        return {p.name: p.default(hoist) for p in self.parameters}


def _law(attr: str) -> Callable[[HoistDescription], Any]:
    return lambda h: getattr(h.friction_law, attr)


_P = EffectParameter

#: Every contract effect with its parameters; defaults come from the hoist description.
EFFECT_REGISTRY: dict[str, EffectSpec] = {
    spec.name: spec
    for spec in (
        EffectSpec(
            "tail_rope_weight",
            EFFECT_DESCRIPTIONS["tail_rope_weight"],
            (
                _P(
                    "mass_per_length_kg_m",
                    "kg/m",
                    "mass per metre of one tail rope",
                    lambda h: h.ropes.tail_rope_mass_per_length_kg_m,
                ),
                _P("tail_ropes", "-", "number of tail ropes", lambda h: h.conveyance.tail_ropes),
            ),
        ),
        EffectSpec(
            "conveyance_inertia",
            EFFECT_DESCRIPTIONS["conveyance_inertia"],
            (
                _P(
                    "mass_kg",
                    "kg",
                    "empty conveyance mass accelerated by the hoist (payload and hanging tail "
                    "rope are added)",
                    lambda h: h.conveyance.mass_kg,
                ),
            ),
        ),
        EffectSpec(
            "seal_friction",
            EFFECT_DESCRIPTIONS["seal_friction"],
            (
                _P("coulomb_n", "N, N/Pa", "Fc = a + b p (eq 17)", _law("coulomb_n")),
                _P("static_n", "N, N/Pa", "Fs = a + b p (eq 17)", _law("static_n")),
                _P(
                    "stribeck_speed_m_s",
                    "m/s, m/(s Pa)",
                    "vs = a + b p (eq 17)",
                    _law("stribeck_speed_m_s"),
                ),
                _P(
                    "viscous_n_s_m",
                    "N s/m, N s/(m Pa)",
                    "Kv = a + b p (eq 17)",
                    _law("viscous_n_s_m"),
                ),
                _P(
                    "bristle_stiffness_n_m",
                    "N/m",
                    "LuGre sigma0 (eq 15)",
                    _law("bristle_stiffness_n_m"),
                ),
                _P(
                    "bristle_damping_n_s_m",
                    "N s/m",
                    "LuGre sigma1 (eq 15)",
                    _law("bristle_damping_n_s_m"),
                ),
            ),
        ),
        EffectSpec(
            "presliding_hysteresis",
            EFFECT_DESCRIPTIONS["presliding_hysteresis"],
            (
                _P(
                    "stiffness_n_m",
                    "N/m",
                    "total presliding stiffness of the Maxwell-slip elements",
                    _law("bristle_stiffness_n_m"),
                ),
                _P("elements", "-", "number of Maxwell-slip elements", _law("presliding_elements")),
            ),
        ),
        EffectSpec(
            "pipe_laminar_loss",
            EFFECT_DESCRIPTIONS["pipe_laminar_loss"],
            (
                _P(
                    "length_chamber_to_sensor_m",
                    "m",
                    "branch pipe length, chamber to sensor tee",
                    lambda h: h.piping.length_chamber_to_sensor_m,
                ),
                _P(
                    "length_sensor_to_manifold_m",
                    "m",
                    "branch pipe length, sensor tee to manifold",
                    lambda h: h.piping.length_sensor_to_manifold_m,
                ),
                _P("bore_m", "m", "branch pipe bore", lambda h: h.piping.bore_m),
            ),
        ),
        EffectSpec(
            "local_loss",
            EFFECT_DESCRIPTIONS["local_loss"],
            (
                _P(
                    "valve_loss_coefficient",
                    "-",
                    "globe valve K (chamber side of the sensor)",
                    lambda h: h.piping.valve_loss_coefficient,
                ),
                _P(
                    "fittings_chamber_to_sensor",
                    "-",
                    "fittings K between chamber and sensor",
                    lambda h: h.piping.fittings_loss_coefficient_chamber_to_sensor,
                ),
                _P(
                    "fittings_sensor_to_manifold",
                    "-",
                    "fittings K between sensor and manifold",
                    lambda h: h.piping.fittings_loss_coefficient_sensor_to_manifold,
                ),
            ),
        ),
        EffectSpec(
            "oil_compressibility",
            EFFECT_DESCRIPTIONS["oil_compressibility"],
            (
                _P(
                    "bulk_modulus_pa",
                    "Pa",
                    "bulk modulus of the air-free oil",
                    lambda h: h.oil.bulk_modulus_pa,
                ),
                _P("air_fraction", "-", "entrained air at 1 atm", lambda h: h.oil.air_fraction),
            ),
        ),
        EffectSpec(
            "viscosity_temperature",
            EFFECT_DESCRIPTIONS["viscosity_temperature"],
            (
                _P(
                    "kinematic_viscosity_40c_m2_s",
                    "m2/s",
                    "ASTM D341 reference point at 40 degC",
                    lambda h: h.oil.kinematic_viscosity_40c_m2_s,
                ),
                _P(
                    "kinematic_viscosity_100c_m2_s",
                    "m2/s",
                    "ASTM D341 reference point at 100 degC (sets the slope)",
                    lambda h: h.oil.kinematic_viscosity_100c_m2_s,
                ),
            ),
        ),
        EffectSpec(
            "sensor_offset",
            EFFECT_DESCRIPTIONS["sensor_offset"],
            (
                _P(
                    "offsets_pa",
                    "Pa",
                    "zero error per sensor, reading = gain p + offset",
                    lambda h: [s.offset_pa for s in sorted(h.sensors, key=lambda s: s.cylinder)],
                ),
            ),
        ),
        EffectSpec(
            "sensor_gain",
            EFFECT_DESCRIPTIONS["sensor_gain"],
            (
                _P(
                    "gains",
                    "-",
                    "span factor per sensor, reading = gain p + offset",
                    lambda h: [s.gain for s in sorted(h.sensors, key=lambda s: s.cylinder)],
                ),
            ),
        ),
        EffectSpec(
            "groove_wear",
            EFFECT_DESCRIPTIONS["groove_wear"],
            (
                _P(
                    "groove_radius_deviation_m",
                    "m",
                    "drum groove radius minus nominal, per rope",
                    lambda h: list(h.drum.groove_radius_deviation_m),
                ),
            ),
        ),
    )
}

assert tuple(EFFECT_REGISTRY) == EFFECT_NAMES


@dataclass(frozen=True)
class ResolvedEffects:
    """Effects switched on and the parameters of every effect (defaults filled in).

    ``parameters`` holds all effects' parameters, also of effects that are off, so a
    caller can see what would be used; only ``enabled`` ones act.
    """

    enabled: frozenset[str]
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)

    def on(self, name: str) -> bool:
        """Is effect ``name`` switched on?"""
        if name not in EFFECT_REGISTRY:
            raise ValueError(_unknown(name))
        return name in self.enabled


def _unknown(name: str) -> str:
    return f"unknown effect name {name!r}; valid names: {', '.join(EFFECT_NAMES)}"


def _per_sensor(
    name: str, spec_key: str, one_key: str, given: Mapping[str, Any], current: list[float]
) -> list[float]:
    values = list(current)
    if spec_key in given:
        values = [float(v) for v in given[spec_key]]
        if len(values) != len(current):
            raise ValueError(f"{name}.{spec_key}: need {len(current)} values, got {len(values)}")
    if "sensor" in given or one_key in given:
        if "sensor" not in given or one_key not in given:
            raise ValueError(f"{name}: give both 'sensor' (1..{len(values)}) and {one_key!r}")
        k = int(given["sensor"])
        if not 1 <= k <= len(values):
            raise ValueError(f"{name}.sensor: must be 1..{len(values)}, got {k}")
        values[k - 1] = float(given[one_key])
    return values


def resolve_effects(
    hoist: HoistDescription,
    effects: Iterable[str] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
) -> ResolvedEffects:
    """Validate effect names and parameters, fill defaults from the hoist description.

    Parameters
    ----------
    hoist : HoistDescription
        Supplies defaults and, with ``effects=None``, the ``[model] effects`` list.
    effects : iterable of str, optional
        Effect names of contract section 4 to switch on.
    parameters : mapping, optional
        ``{effect: {parameter: value}}`` overriding defaults (see module docstring).

    Raises
    ------
    ValueError
        Unknown effect or parameter name (the message lists the valid ones), a
        parameter for an effect that is off, or a malformed per-sensor override.
    """
    if isinstance(effects, str):
        raise ValueError("effects: give a collection of names, not one string")
    names = list(hoist.model.effects if effects is None else effects)
    for name in names:
        if name not in EFFECT_REGISTRY:
            raise ValueError(_unknown(name))
    enabled = frozenset(names)
    resolved = {name: spec.defaults(hoist) for name, spec in EFFECT_REGISTRY.items()}
    for name, given in (parameters or {}).items():
        if name not in EFFECT_REGISTRY:
            raise ValueError(_unknown(name))
        if name not in enabled:
            raise ValueError(f"parameters given for effect {name!r}, which is not switched on")
        spec = EFFECT_REGISTRY[name]
        if name == "sensor_offset":
            allowed = {"offsets_pa", "sensor", "offset_pa"}
        elif name == "sensor_gain":
            allowed = {"gains", "sensor", "gain"}
        else:
            allowed = {p.name for p in spec.parameters}
        for key in given:
            if key not in allowed:
                raise ValueError(
                    f"unknown parameter {key!r} of effect {name!r}; "
                    f"valid: {', '.join(sorted(allowed))}"
                )
        if name == "sensor_offset":
            resolved[name]["offsets_pa"] = _per_sensor(
                name, "offsets_pa", "offset_pa", given, resolved[name]["offsets_pa"]
            )
        elif name == "sensor_gain":
            resolved[name]["gains"] = _per_sensor(
                name, "gains", "gain", given, resolved[name]["gains"]
            )
        else:
            resolved[name].update(given)
    return ResolvedEffects(enabled=enabled, parameters=resolved)


def parameters_json(value: Any, *, significant_digits: int | None = None) -> Any:
    """Effect parameters as JSON-ready values: dict keys as str, arrays and tuples as
    lists, numpy scalars as Python numbers; floats rounded to ``significant_digits``
    when given (reports), exact otherwise (truth records)."""
    if isinstance(value, dict):
        return {
            str(k): parameters_json(v, significant_digits=significant_digits)
            for k, v in value.items()
        }
    if isinstance(value, list | tuple | np.ndarray):
        return [parameters_json(v, significant_digits=significant_digits) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and significant_digits is not None:
        return float(f"{value:.{significant_digits}g}")
    return value
