"""Rope tension and hoist load (paper eq 1-4 and Table 2).

Functions
    :func:`rope_tension_n` -- T = p_chamber A + F, eq 2 (eq 1 at the piston with its
    inertia neglected; numba).
    :func:`tail_rope_length_m`, :func:`tail_rope_mass_kg` -- the tail ropes hanging
    below the conveyance (Table 2).
    :func:`expected_load_n` -- what the head ropes carry, (m_c + m_p + m_t(z))(g + a),
    eq 3-4 with the masses of Table 2.

The last three take a float, a numpy array or a polars expression for the depth,
payload and acceleration (written with operators only), so the reconciliation's
expressions, the simulations and the alarms use one function each.

Sign and units: SI; tension positive in pull; acceleration positive upward;
friction positive while the rod moves out (contract 1a).
"""

from __future__ import annotations

import math

import numpy as np
import polars as pl
from numba import njit

from schemas.hoist import G_STANDARD, HoistDescription

__all__ = [
    "annulus_area_m2",
    "bore_area_m2",
    "expected_load_n",
    "rope_tension_n",
    "tail_rope_length_m",
    "tail_rope_mass_kg",
]

#: A float, one value per sample or a polars expression of them.
Quantity = float | np.ndarray | pl.Expr


@njit(cache=True, nogil=True, inline="always")
def rope_tension_n(p_chamber_pa: float, area_m2: float, friction_n: float) -> float:
    r"""Rope tension from the chamber pressure and the seal friction (paper eq 2) [N].

    .. math:: T = p_{chamber} A + F_f

    Eq 1, m_p (x'' - y'') = T - p A - F_f, with the piston's inertia neglected (its
    mass counts with the conveyance). ``p_chamber_pa`` [Pa], ``area_m2`` bore area
    [m2], ``friction_n`` [N], positive while the rod moves out.

    >>> rope_tension_n(5e6, 7.854e-3, 120.0)
    39390.0
    """
    return p_chamber_pa * area_m2 + friction_n


def bore_area_m2(bore_m: float) -> float:
    """Piston area on the rodless side, pi D^2 / 4 [m2] (paper eq 2's A).

    >>> round(bore_area_m2(0.1), 7)
    0.007854
    """
    return math.pi * bore_m**2 / 4.0


def annulus_area_m2(bore_m: float, rod_m: float) -> float:
    """Piston area on the rod side, pi (D^2 - d^2) / 4 [m2] (the friction rig's port B).

    >>> round(annulus_area_m2(0.1, 0.06), 7)
    0.0050265
    """
    return math.pi * (bore_m**2 - rod_m**2) / 4.0


def tail_rope_length_m(hoist: HoistDescription, depth_m: Quantity) -> Quantity:
    """Hanging tail-rope length below the conveyance at ``depth_m`` [m].

    Shaft depth - depth + the loop below the bottom (Table 2: 620 m at the pithead of a
    620 m shaft, 20 m at the bottom).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> tail_rope_length_m(hoist, 0.0) - tail_rope_length_m(hoist, 600.0)
    600.0
    """
    return hoist.shaft.depth_m - depth_m + hoist.shaft.tail_rope_loop_m


def tail_rope_mass_kg(hoist: HoistDescription, depth_m: Quantity) -> Quantity:
    """Mass of all tail ropes hanging below the conveyance at ``depth_m`` [kg] (Table 2).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> round(tail_rope_mass_kg(load_hoist(EXAMPLE_HOIST), 0.0))   # 2 x 6.2 kg/m x 620 m
    7688
    """
    per_length_kg_m = hoist.conveyance.tail_ropes * hoist.ropes.tail_rope_mass_per_length_kg_m
    return per_length_kg_m * tail_rope_length_m(hoist, depth_m)


def expected_load_n(
    hoist: HoistDescription,
    depth_m: Quantity,
    payload_kg: Quantity = 0.0,
    acceleration_up_m_s2: Quantity = 0.0,
) -> Quantity:
    r"""Load the head ropes carry together (paper eq 3-4, masses of Table 2) [N].

    .. math:: \sum_i T_i = (m_c + m_p + m_t(z)) (g + a)

    m_c the conveyance, m_p the payload, m_t(z) the tail ropes below the conveyance at
    depth z (:func:`tail_rope_mass_kg`), a the acceleration, positive upward. Float,
    array or polars expression arguments.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> round(expected_load_n(hoist, 0.0) / 1e3, 2)   # Table 2 pithead, empty: 155.81 kN
    155.81
    """
    moving_mass_kg = hoist.conveyance.mass_kg + payload_kg + tail_rope_mass_kg(hoist, depth_m)
    return moving_mass_kg * (G_STANDARD + acceleration_up_m_s2)
