"""Tests for physics.oil: ASTM D341 viscosity and entrained-air bulk modulus."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.oil import (
    dynamic_viscosity,
    effective_bulk_modulus,
    kinematic_viscosity,
    kinematic_viscosity_walther,
    walther_coefficients,
)
from schemas.hoist import EXAMPLE_HOIST, load_hoist


def test_walther_reproduces_reference_points():
    oil = load_hoist(EXAMPLE_HOIST).oil
    nu = kinematic_viscosity(np.array([40.0, 100.0]), oil)
    np.testing.assert_allclose(nu, [46e-6, 6.8e-6], rtol=1e-12)


def test_walther_is_straight_line_in_double_log_coordinates():
    a, b = walther_coefficients(46e-6, 40.0, 6.8e-6, 100.0)
    t_c = np.array([0.0, 20.0, 60.0, 80.0])
    nu_cst = kinematic_viscosity_walther(t_c, a, b) * 1e6
    w = np.log10(np.log10(nu_cst + 0.7))
    slope = np.diff(w) / np.diff(np.log10(t_c + 273.15))
    np.testing.assert_allclose(slope, -b, rtol=1e-10)


def test_walther_vg46_published_datasheet_value():
    # Shell Tellus S2 M 46 datasheet: 46 cSt at 40 degC, 6.8 at 100 degC, 580 at 0 degC
    a, b = walther_coefficients(46e-6, 40.0, 6.8e-6, 100.0)
    assert float(kinematic_viscosity_walther(0.0, a, b)) * 1e6 == pytest.approx(580, rel=0.03)
    assert np.all(np.diff(kinematic_viscosity_walther(np.linspace(0, 100, 11), a, b)) < 0)


def test_walther_rejects_equal_temperatures():
    with pytest.raises(ValueError, match="differ"):
        walther_coefficients(46e-6, 40.0, 6.8e-6, 40.0)


def test_dynamic_viscosity_paper_section_2_2():
    # paper: 900 kg/m3, 46 mm2/s, 0.0414 kg/(m s)
    assert float(dynamic_viscosity(46e-6, 900.0)) == pytest.approx(0.0414)


def test_bulk_modulus_limits():
    p = np.array([1e5, 1e6, 1e7, 1e9])
    np.testing.assert_allclose(effective_bulk_modulus(p, 1.5e9, 0.0), 1.5e9)
    be = effective_bulk_modulus(p, 1.5e9, 0.01)
    assert np.all(np.diff(be) > 0)  # air compresses away with pressure
    assert be[-1] == pytest.approx(1.5e9, rel=0.01)
    assert be[0] < 0.1 * 1.5e9  # at ~1 atm 1 % air dominates


def test_bulk_modulus_matches_numerical_mixture_compressibility():
    beta_l, x0, p0, n = 1.5e9, 0.02, 101_325.0, 1.4

    def volume(p):  # air polytropic, liquid of constant (small) compressibility
        liquid = (1 - x0) * (1 - (p - p0) / beta_l)
        return liquid + x0 * (p0 / p) ** (1 / n)

    for p in (0.5e6, 2e6, 8e6):
        h = p * 1e-6
        dv_dp = (volume(p + h) - volume(p - h)) / (2 * h)
        beta_numeric = -volume(p) / dv_dp
        beta = effective_bulk_modulus(p, beta_l, x0, polytropic_index=n)
        # the formula neglects the liquid's own volume change (< (p - p0)/beta_l)
        assert float(beta) == pytest.approx(beta_numeric, rel=2 * (p - p0) / beta_l + 1e-6)


def test_bulk_modulus_rejects_bad_fraction():
    with pytest.raises(ValueError):
        effective_bulk_modulus(1e6, 1.5e9, 1.0)
    assert math.isfinite(float(effective_bulk_modulus(1e6, 1.5e9, 0.19)))


def test_effective_bulk_modulus_scalar_kernel_is_the_array_formula():
    """The numba scalar form used inside kernels gives the array function's values,
    written out here from Merritt's formula."""
    from physics.oil import ATMOSPHERIC_PRESSURE_PA, effective_bulk_modulus_at

    p = np.linspace(1e5, 1e7, 101)
    for x0, n in [(0.0, 1.0), (0.01, 1.0), (0.02, 1.4)]:
        r = (ATMOSPHERIC_PRESSURE_PA / p) ** (1.0 / n)
        formula = ((1.0 - x0) + x0 * r) / ((1.0 - x0) / 1.5e9 + x0 * r / (n * p))
        array = effective_bulk_modulus(p, 1.5e9, x0, polytropic_index=n)
        scalar = [effective_bulk_modulus_at(v, 1.5e9, x0, ATMOSPHERIC_PRESSURE_PA, n) for v in p]
        np.testing.assert_allclose(array, formula, rtol=1e-15)
        np.testing.assert_array_equal(scalar, array)
