"""Hydraulic oil properties: viscosity vs temperature, and effective bulk modulus.

Viscosity
    :func:`walther_coefficients` -- ASTM D341 (Walther) A, B from two reference points.
    :func:`kinematic_viscosity_walther` -- nu(T) from A, B (vectorised).
    :func:`kinematic_viscosity` -- nu(T) for a hoist's ``[oil]`` section.
    :func:`dynamic_viscosity` -- mu = rho nu.

Compressibility
    :func:`effective_bulk_modulus` -- oil with entrained (undissolved) air,
    polytropic air (isothermal by default).

``fluids``/``chemicals`` have neither relation (see ../shared/notes/stack.md), hence
this module. SI throughout: temperatures in degC where the name says ``_c``, viscosity
[m2/s] and [Pa s], pressure [Pa].
"""

from __future__ import annotations

import numpy as np
from numba import njit

from schemas.hoist import Oil

__all__ = [
    "ATMOSPHERIC_PRESSURE_PA",
    "dynamic_viscosity",
    "effective_bulk_modulus",
    "kinematic_viscosity",
    "kinematic_viscosity_walther",
    "walther_coefficients",
]

#: Standard atmosphere [Pa]; reference pressure of the entrained-air fraction.
ATMOSPHERIC_PRESSURE_PA = 101_325.0

_KELVIN = 273.15
_CST = 1e-6  # m2/s per mm2/s (cSt)


def walther_coefficients(
    nu1_m2_s: float, t1_c: float, nu2_m2_s: float, t2_c: float
) -> tuple[float, float]:
    r"""Walther / ASTM D341 constants A, B from two (viscosity, temperature) points.

    .. math::
        \log_{10}\log_{10}(\nu + 0.7) = A - B \log_{10} T

    with nu in cSt (mm2/s) and T in K.

    Parameters
    ----------
    nu1_m2_s, nu2_m2_s : float
        Kinematic viscosities at the two temperatures [m2/s].
    t1_c, t2_c : float
        The two temperatures [degC], distinct (usually 40 and 100 degC).

    Returns
    -------
    A, B : float
        Walther constants [-] (B > 0 for viscosity falling with temperature).

    Notes
    -----
    ASTM D341 adds small correction terms to Z = nu + 0.7 below 2 cSt; they are
    omitted, so use for nu >= 2 cSt (mineral hydraulic oils up to ~100 degC).

    Examples
    --------
    >>> a, b = walther_coefficients(46e-6, 40.0, 6.8e-6, 100.0)
    >>> round(a, 4), round(b, 4)
    (9.418, 3.6844)

    References
    ----------
    ASTM D341-20, Standard Practice for Viscosity-Temperature Equations and Charts for
    Liquid Petroleum or Hydrocarbon Products, eq 1-2. Walther, C. (1931),
    Erdoel und Teer 7, 382-384.
    """
    if t1_c == t2_c:
        raise ValueError("walther_coefficients: the two temperatures must differ")
    w1 = np.log10(np.log10(nu1_m2_s / _CST + 0.7))
    w2 = np.log10(np.log10(nu2_m2_s / _CST + 0.7))
    l1 = np.log10(t1_c + _KELVIN)
    l2 = np.log10(t2_c + _KELVIN)
    b = (w1 - w2) / (l2 - l1)
    return float(w1 + b * l1), float(b)


def kinematic_viscosity_walther(t_c: np.ndarray | float, a: float, b: float) -> np.ndarray:
    r"""Kinematic viscosity from Walther constants, ASTM D341.

    .. math::
        \nu = 10^{10^{A - B \log_{10} T}} - 0.7 \quad [\mathrm{cSt}]

    Parameters
    ----------
    t_c : array_like
        Oil temperature [degC].
    a, b : float
        Walther constants from :func:`walther_coefficients`.

    Returns
    -------
    numpy.ndarray
        Kinematic viscosity [m2/s].

    >>> a, b = walther_coefficients(46e-6, 40.0, 6.8e-6, 100.0)
    >>> round(float(kinematic_viscosity_walther(40.0, a, b)) * 1e6, 9)
    46.0
    """
    t_k = np.asarray(t_c, dtype=np.float64) + _KELVIN
    return (10.0 ** (10.0 ** (a - b * np.log10(t_k))) - 0.7) * _CST


def kinematic_viscosity(t_c: np.ndarray | float, oil: Oil) -> np.ndarray:
    """Kinematic viscosity [m2/s] of a hoist's oil at ``t_c`` [degC] (ASTM D341).

    Uses the oil's 40 and 100 degC reference viscosities; see
    :func:`walther_coefficients`.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> oil = load_hoist(EXAMPLE_HOIST).oil
    >>> round(float(kinematic_viscosity(100.0, oil)) * 1e6, 9)
    6.8
    """
    a, b = walther_coefficients(
        oil.kinematic_viscosity_40c_m2_s, 40.0, oil.kinematic_viscosity_100c_m2_s, 100.0
    )
    return kinematic_viscosity_walther(t_c, a, b)


def dynamic_viscosity(nu_m2_s: np.ndarray | float, rho_kg_m3: np.ndarray | float) -> np.ndarray:
    r"""Dynamic viscosity mu = rho nu [Pa s].

    Parameters: ``nu_m2_s`` kinematic viscosity [m2/s], ``rho_kg_m3`` density [kg/m3].

    >>> round(float(dynamic_viscosity(46e-6, 900.0)), 6)   # paper section 2.2: 0.0414
    0.0414
    """
    return np.asarray(nu_m2_s, dtype=np.float64) * np.asarray(rho_kg_m3, dtype=np.float64)


def effective_bulk_modulus(
    p_pa: np.ndarray | float,
    bulk_modulus_oil_pa: float,
    air_fraction: float,
    *,
    p_ref_pa: float = ATMOSPHERIC_PRESSURE_PA,
    polytropic_index: float = 1.0,
) -> np.ndarray:
    r"""Effective bulk modulus of oil with entrained (undissolved) air.

    A volume V0 at ``p_ref_pa`` holds air fraction x0; the air follows
    p V_a^n = const, the liquid has constant bulk modulus beta_l. With
    r = (p_ref / p)^(1/n) the air volume is x0 V0 r and

    .. math::
        \beta_e = \frac{(1 - x_0) + x_0 r}
                       {\dfrac{1 - x_0}{\beta_l} + \dfrac{x_0 r}{n p}}

    Parameters
    ----------
    p_pa : array_like
        Absolute oil pressure [Pa], > 0.
    bulk_modulus_oil_pa : float
        Bulk modulus of the air-free oil [Pa] (mineral oil ~1.4-1.7 GPa).
    air_fraction : float
        Entrained air volume fraction x0 at ``p_ref_pa`` [-], 0 <= x0 < 1.
    p_ref_pa : float
        Pressure at which ``air_fraction`` is stated [Pa], default 1 atm.
    polytropic_index : float
        n: 1 isothermal (slow processes, the default), 1.4 adiabatic (fast).

    Returns
    -------
    numpy.ndarray
        Effective (secant-free, tangent) bulk modulus [Pa].

    Notes
    -----
    The liquid's own volume change is neglected against its volume (beta_l >> p), and
    air dissolving into the oil with pressure (Henry's law) is not modelled, so the
    result is a lower bound at high pressure. With x0 = 0 it is beta_l; as
    p -> infinity it tends to beta_l.

    Examples
    --------
    >>> round(float(effective_bulk_modulus(5e6, 1.5e9, 0.0)) / 1e9, 6)
    1.5
    >>> round(float(effective_bulk_modulus(5e6, 1.5e9, 0.01)) / 1e9, 3)
    1.414

    References
    ----------
    Merritt, H. E. (1967), Hydraulic Control Systems, Wiley, section 2.5.
    Gholizadeh, H., Burton, R., Schoenau, G. (2011), Fluid bulk modulus: a literature
    survey, Int. J. Fluid Power 12(3), 5-13, doi:10.1080/14399776.2011.10781033.
    """
    if not 0.0 <= air_fraction < 1.0:
        raise ValueError(f"air_fraction: must be in [0, 1), got {air_fraction}")
    p = np.asarray(p_pa, dtype=np.float64)
    out = np.empty(p.shape)
    _effective_bulk_modulus_kernel(
        np.ascontiguousarray(p).reshape(-1),
        float(bulk_modulus_oil_pa),
        float(air_fraction),
        float(p_ref_pa),
        float(polytropic_index),
        out.reshape(-1),
    )
    return out if out.ndim else out[()]


@njit(cache=True, nogil=True)
def effective_bulk_modulus_at(
    p: float, beta_l: float, x0: float, p_ref: float, n: float
) -> float:  # pragma: no cover - numba
    """:func:`effective_bulk_modulus` at one pressure (Merritt 1967 section 2.5), for
    numba kernels; arguments unchecked, in the order of that function."""
    r = (p_ref / p) ** (1.0 / n)
    return ((1.0 - x0) + x0 * r) / ((1.0 - x0) / beta_l + x0 * r / (n * p))


@njit(cache=True, nogil=True)
def _effective_bulk_modulus_kernel(p, beta_l, x0, p_ref, n, out):  # pragma: no cover - numba
    for i in range(p.shape[0]):
        out[i] = effective_bulk_modulus_at(p[i], beta_l, x0, p_ref, n)
