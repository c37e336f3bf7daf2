"""Physical quantities written as ``"value unit"`` strings, converted to SI.

The hoist description (contract section 2) states every dimensioned number with its
unit, e.g. ``mass = "8.2 t"`` or ``bore = "100 mm"``. This module parses such strings
and converts them to SI, refusing a unit of the wrong dimension ("8.2 m" for a mass).

Only the units that occur on hoists, rigs and oils are known; an unknown unit is an
error, never a guess.
"""

from __future__ import annotations

import re

__all__ = ["DIMENSIONS", "QuantityError", "parse_quantity", "unit_factor"]


class QuantityError(ValueError):
    """A quantity string that cannot be read or has a unit of the wrong dimension."""


# unit -> (dimension, factor to SI). Offsets (degC) are handled separately.
_UNITS: dict[str, tuple[str, float]] = {
    # length [m]
    "m": ("length", 1.0),
    "mm": ("length", 1e-3),
    "um": ("length", 1e-6),
    "cm": ("length", 1e-2),
    "km": ("length", 1e3),
    # mass [kg]
    "kg": ("mass", 1.0),
    "t": ("mass", 1e3),
    "g": ("mass", 1e-3),
    # force [N]
    "N": ("force", 1.0),
    "kN": ("force", 1e3),
    "MN": ("force", 1e6),
    # pressure [Pa]
    "Pa": ("pressure", 1.0),
    "kPa": ("pressure", 1e3),
    "MPa": ("pressure", 1e6),
    "GPa": ("pressure", 1e9),
    "bar": ("pressure", 1e5),
    # linear density [kg/m]
    "kg/m": ("linear_density", 1.0),
    # density [kg/m3]
    "kg/m3": ("density", 1.0),
    "g/cm3": ("density", 1e3),
    # velocity [m/s]
    "m/s": ("velocity", 1.0),
    "mm/s": ("velocity", 1e-3),
    # acceleration [m/s2]
    "m/s2": ("acceleration", 1.0),
    # volume [m3]
    "m3": ("volume", 1.0),
    "L": ("volume", 1e-3),
    "mL": ("volume", 1e-6),
    # volume flow [m3/s]
    "m3/s": ("flow", 1.0),
    "L/min": ("flow", 1e-3 / 60.0),
    # dynamic viscosity [Pa s]
    "Pa*s": ("dynamic_viscosity", 1.0),
    "mPa*s": ("dynamic_viscosity", 1e-3),
    # kinematic viscosity [m2/s]
    "m2/s": ("kinematic_viscosity", 1.0),
    "mm2/s": ("kinematic_viscosity", 1e-6),
    "cSt": ("kinematic_viscosity", 1e-6),
    # stiffness [N/m]
    "N/m": ("stiffness", 1.0),
    "kN/mm": ("stiffness", 1e6),
    "N/mm": ("stiffness", 1e3),
    # damping [N s/m]
    "N*s/m": ("damping", 1.0),
    "kN*s/m": ("damping", 1e3),
    # time [s]
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "min": ("time", 60.0),
    "h": ("time", 3600.0),
    # frequency [Hz]
    "Hz": ("frequency", 1.0),
    # temperature [degC] (kept in degC: column names say so)
    "degC": ("temperature", 1.0),
}

#: The dimensions a quantity can have, with their SI unit.
DIMENSIONS: dict[str, str] = {
    "length": "m",
    "mass": "kg",
    "force": "N",
    "pressure": "Pa",
    "linear_density": "kg/m",
    "density": "kg/m3",
    "velocity": "m/s",
    "acceleration": "m/s2",
    "volume": "m3",
    "flow": "m3/s",
    "dynamic_viscosity": "Pa*s",
    "kinematic_viscosity": "m2/s",
    "stiffness": "N/m",
    "damping": "N*s/m",
    "time": "s",
    "frequency": "Hz",
    "temperature": "degC",
}

_ALIASES = {
    "m³": "m3",
    "µm": "um",
    "μm": "um",
    "l": "L",
    "mm²/s": "mm2/s",
    "m²/s": "m2/s",
    "°C": "degC",
    "C": "degC",
    "Pa.s": "Pa*s",
    "Pa s": "Pa*s",
    "mPa.s": "mPa*s",
    "mPa s": "mPa*s",
    "N.s/m": "N*s/m",
    "N s/m": "N*s/m",
    "m/s²": "m/s2",
    "m/s^2": "m/s2",
    "kg/m^3": "kg/m3",
    "kg/m³": "kg/m3",
    "m^3": "m3",
    "m^2/s": "m2/s",
    "mm^2/s": "mm2/s",
    "l/min": "L/min",
}

_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def unit_factor(unit: str, dimension: str) -> float:
    """Factor that converts a value in ``unit`` to the SI unit of ``dimension``.

    >>> unit_factor("MPa", "pressure")
    1000000.0
    """
    unit = _ALIASES.get(unit, unit)
    if unit not in _UNITS:
        known = sorted(u for u, (d, _) in _UNITS.items() if d == dimension)
        raise QuantityError(f"unknown unit {unit!r} for a {dimension}; use one of {known}")
    found_dimension, factor = _UNITS[unit]
    if found_dimension != dimension:
        known = sorted(u for u, (d, _) in _UNITS.items() if d == dimension)
        raise QuantityError(
            f"unit {unit!r} is a {found_dimension}, expected a {dimension} (one of {known})"
        )
    return factor


def parse_quantity(text: str | float | int, dimension: str) -> float:
    """Parse ``"value unit"`` into SI units of ``dimension``.

    A bare number is accepted only for dimensionless quantities (``dimension ==
    "dimensionless"``); everything else must name its unit.

    >>> parse_quantity("8.2 t", "mass")
    8200.0
    >>> parse_quantity("100 mm", "length")
    0.1
    """
    if dimension not in DIMENSIONS and dimension != "dimensionless":
        raise ValueError(f"unknown dimension {dimension!r}")
    if isinstance(text, bool):
        raise QuantityError(f"expected a {dimension}, got a boolean")
    if isinstance(text, int | float):
        if dimension == "dimensionless":
            return float(text)
        raise QuantityError(
            f'{text!r} has no unit; write it as "{text} {DIMENSIONS[dimension]}" (a {dimension})'
        )
    if not isinstance(text, str):
        raise QuantityError(f"expected a quantity string like '1.0 {DIMENSIONS.get(dimension)}'")
    match = _QUANTITY.match(text)
    if match is None:
        raise QuantityError(f"cannot read {text!r} as 'value unit'")
    value, unit = float(match.group(1)), match.group(2)
    if dimension == "dimensionless":
        if unit:
            raise QuantityError(f"{text!r} should be a plain number")
        return value
    if not unit:
        raise QuantityError(
            f"{text!r} has no unit; expected a {dimension} "
            f"such as '{value} {DIMENSIONS[dimension]}'"
        )
    return value * unit_factor(unit, dimension)
