"""Quantity strings -> SI."""

from __future__ import annotations

import pytest

from schemas.quantities import QuantityError, parse_quantity, unit_factor


@pytest.mark.parametrize(
    ("text", "dimension", "si"),
    [
        ("8.2 t", "mass", 8200.0),
        ("100 mm", "length", 0.1),
        ("1.5 um", "length", 1.5e-6),
        ("12 MPa", "pressure", 12e6),
        ("120 bar", "pressure", 12e6),
        ("350 kPa", "pressure", 3.5e5),
        ("1.5 GPa", "pressure", 1.5e9),
        ("46 mm2/s", "kinematic_viscosity", 46e-6),
        ("46 cSt", "kinematic_viscosity", 46e-6),
        ("20 L/min", "flow", 20e-3 / 60),
        ("2.5e7 N/m", "stiffness", 2.5e7),
        ("25 kN/mm", "stiffness", 2.5e7),
        ("0.0414 Pa*s", "dynamic_viscosity", 0.0414),
        ("41.4 mPa s", "dynamic_viscosity", 0.0414),
        ("6.2 kg/m", "linear_density", 6.2),
        ("-0.3 mm", "length", -3e-4),
        ("0.75 m/s^2", "acceleration", 0.75),
    ],
)
def test_parse_converts_to_si(text, dimension, si):
    assert parse_quantity(text, dimension) == pytest.approx(si, rel=1e-12)


def test_dimension_mismatch_is_refused():
    with pytest.raises(QuantityError, match="'MPa' is a pressure, expected a force"):
        parse_quantity("3 MPa", "force")


def test_unitless_number_refused_unless_dimensionless():
    with pytest.raises(QuantityError, match="has no unit"):
        parse_quantity(3.0, "pressure")
    assert parse_quantity(3, "dimensionless") == 3.0
    assert parse_quantity("0.5", "dimensionless") == 0.5


@pytest.mark.parametrize("text", ["", "MPa", "3..5 MPa", "three MPa"])
def test_unreadable_strings_are_refused(text):
    with pytest.raises(QuantityError):
        parse_quantity(text, "pressure")


def test_booleans_are_not_quantities():
    with pytest.raises(QuantityError, match="boolean"):
        parse_quantity(True, "dimensionless")


def test_unit_factor_round_trip():
    assert unit_factor("bar", "pressure") * 10 == unit_factor("MPa", "pressure")
