"""Tests for physics.tension: eq 2 and the masses of paper Table 2 (eq 3-4)."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from physics.tension import expected_load_n, rope_tension_n, tail_rope_length_m, tail_rope_mass_kg
from schemas.hoist import EXAMPLE_HOIST, G_STANDARD, load_hoist

HOIST = load_hoist(EXAMPLE_HOIST)


@pytest.mark.parametrize(
    ("position", "tail_length_m", "tail_mass_t", "total_mass_t"),
    [("pithead", 620, 7.688, 15.888), ("middle", 300, 3.72, 11.92), ("bottom", 20, 0.248, 8.448)],
)
def test_example_positions_reproduce_table2_masses(
    position, tail_length_m, tail_mass_t, total_mass_t
):
    """Table 2's tail-rope lengths, masses and total loads follow from the positions."""
    depth = HOIST.shaft.positions_m[position]
    assert tail_rope_length_m(HOIST, depth) == pytest.approx(tail_length_m)
    assert tail_rope_mass_kg(HOIST, depth) == pytest.approx(tail_mass_t * 1e3)
    assert expected_load_n(HOIST, depth) == pytest.approx(total_mass_t * 1e3 * G_STANDARD)


def test_expected_load_is_one_function_for_floats_arrays_and_expressions():
    """(m_c + m_p + m_t(z))(g + a) with a payload and an upward acceleration, the same
    from a float, an array and a polars expression."""
    depth, payload, accel = 320.0, 9000.0, 0.75
    by_hand = (
        8200.0 + payload + 2 * 6.2 * (620.0 - depth + 0.0 + HOIST.shaft.tail_rope_loop_m)
    ) * (G_STANDARD + accel)
    assert expected_load_n(HOIST, depth, payload, accel) == pytest.approx(by_hand, rel=1e-12)
    arrays = expected_load_n(HOIST, np.array([depth]), np.array([payload]), np.array([accel]))
    assert arrays[0] == pytest.approx(by_hand, rel=1e-12)
    frame = pl.DataFrame({"d": [depth], "m": [payload], "a": [accel]})
    expr = expected_load_n(HOIST, pl.col("d"), pl.col("m"), pl.col("a"))
    assert frame.select(expr).item() == pytest.approx(by_hand, rel=1e-12)


def test_rope_tension_adds_friction_to_the_chamber_force():
    """Eq 2: 5 MPa on a 100 mm bore is 39.27 kN; friction adds with its sign."""
    area = np.pi * 0.1**2 / 4
    assert rope_tension_n(5e6, area, 0.0) == pytest.approx(39_269.9, abs=0.1)
    assert rope_tension_n(5e6, area, -250.0) == pytest.approx(39_269.9 - 250.0, abs=0.1)
