"""Pressure loss of oil in a pipe branch (paper eq 6 and 12-14).

Scalar kernels (numba; the simulation's integrators and the compensation call them)
    :func:`laminar_resistance` -- Hagen-Poiseuille R = 128 mu l / (pi d^4), eq 6.
    :func:`darcy_friction_factor_at` -- lambda of eq 12: 64/Re laminar, a linear bridge
    over 2000 < Re < 4000, turbulent by Colebrook (Clamond's solution) or Blasius.
    :func:`pipe_loss_pa` -- the signed loss along the pipe and at its fittings, eq 12-14.

Vectorised
    :func:`reynolds_number`, :func:`darcy_friction_factor`, :func:`pipe_pressure_loss`.
    :func:`globe_valve_k` -- Crane TP-410 K of a fully open globe valve (``fluids``).

The hoist's sensor branch (contract 1a) applies them: :mod:`physics.sensor_branch`.

Sign: a loss is positive in the direction of flow (pressure falls along the flow), so
the signed loss has the sign of the velocity and is 0 at rest.
"""

from __future__ import annotations

import math

import fluids
import numpy as np
from numba import njit

__all__ = [
    "BLASIUS",
    "COLEBROOK",
    "RE_LAMINAR",
    "RE_TURBULENT",
    "clamond_friction_factor",
    "darcy_friction_factor",
    "darcy_friction_factor_at",
    "globe_valve_k",
    "laminar_resistance",
    "pipe_loss_pa",
    "pipe_pressure_loss",
    "reynolds_number",
]

#: Upper Reynolds number of the laminar law lambda = 64/Re [-].
RE_LAMINAR = 2000.0
#: Lower Reynolds number of the fully turbulent correlation [-].
RE_TURBULENT = 4000.0
#: ``method`` of the turbulent friction factor: Colebrook-White, solved by Clamond (2009).
COLEBROOK = 0
#: ``method``: Blasius' smooth-pipe law 0.3164 Re^-0.25 (Re < 1e5; the simulations).
BLASIUS = 1


@njit(cache=True, nogil=True)
def laminar_resistance(mu_pa_s: float, length_m: float, bore_m: float) -> float:
    """Hagen-Poiseuille resistance of a round pipe (paper eq 6) [Pa s/m3].

    .. math:: R = \\frac{128 \\mu l}{\\pi d^4}, \\qquad \\Delta p = R q

    ``mu_pa_s`` dynamic viscosity [Pa s], ``length_m`` and ``bore_m`` [m].

    Paper eq 6 writes the friction force on the oil column, ``f = 128 mu l a^2 u /
    (pi d^4)``; dividing by the area ``a`` and writing ``q = a u`` gives the pressure
    drop ``R q``. Valid for laminar flow, Re below about 2000.

    >>> round(laminar_resistance(0.0414, 1.0, 0.006) / 1e9, 4)  # paper 2.2 pipe
    1.3015
    """
    return 128.0 * mu_pa_s * length_m / (math.pi * bore_m**4)


@njit(cache=True, nogil=True)
def clamond_friction_factor(re: float, relative_roughness: float) -> float:
    """Darcy friction factor of Colebrook-White, solved to machine precision [-].

    Clamond's (2009) two-step iteration, the arithmetic of ``fluids.friction.Clamond``
    (Re >= ~4000; ``relative_roughness`` = epsilon / D).

    >>> round(clamond_friction_factor(1e5, 1e-4), 5)
    0.01851

    References
    ----------
    Clamond, D. (2009), Efficient resolution of the Colebrook equation, Ind. Eng.
    Chem. Res. 48(7), 3665-3671, doi:10.1021/ie801626g.
    """
    x1 = relative_roughness * re * 0.1239681863354175460160858261654858382699
    x2 = math.log(re) - 0.7793974884556819406441139701653776731705
    f = x2 - 0.2
    x1f = x1 + f
    x1f1 = 1.0 + x1f
    e = (math.log(x1f) - 0.2) / x1f1
    f = f - (x1f1 + 0.5 * e) * e * x1f / (x1f1 + e * (1.0 + (1.0 / 3.0) * e))
    x1f = x1 + f
    x1f1 = 1.0 + x1f
    e = (math.log(x1f) + f - x2) / x1f1
    b = x1f1 + e * (1.0 + 1.0 / 3.0 * e)
    f = b / (b * f - (x1f1 + 0.5 * e) * e * x1f)
    return 1.325474527619599502640416597148504422899 * (f * f)


@njit(cache=True, nogil=True)
def _turbulent(re: float, relative_roughness: float, method: int) -> float:
    if method == BLASIUS:
        return 0.3164 * re**-0.25
    return clamond_friction_factor(re, relative_roughness)


@njit(cache=True, nogil=True, error_model="numpy")
def darcy_friction_factor_at(re: float, relative_roughness: float, method: int) -> float:
    r"""Darcy friction factor lambda of paper eq 12, laminar to turbulent [-].

    .. math::
        \lambda = \begin{cases}
        64/Re & Re \le 2000 \\
        \text{linear in } Re \text{ between the two} & 2000 < Re < 4000 \\
        \lambda_{turbulent}(Re, \epsilon/D) & Re \ge 4000
        \end{cases}

    ``method`` :data:`COLEBROOK` (:func:`clamond_friction_factor`) or :data:`BLASIUS`.
    64/Re is exact for fully developed laminar flow; the transitional band is not
    predictable and is bridged linearly for continuity (an implicit integrator's Newton
    iterations need a loss continuous in the flow).

    >>> darcy_friction_factor_at(1000.0, 0.0, COLEBROOK)
    0.064
    >>> round(darcy_friction_factor_at(1e4, 0.0, BLASIUS), 5)
    0.03164
    """
    if re <= RE_LAMINAR:
        return 64.0 / re
    if re >= RE_TURBULENT:
        return _turbulent(re, relative_roughness, method)
    weight = (re - RE_LAMINAR) / (RE_TURBULENT - RE_LAMINAR)
    start = _turbulent(RE_TURBULENT, relative_roughness, method)
    return (1.0 - weight) * (64.0 / RE_LAMINAR) + weight * start


@njit(cache=True, nogil=True, error_model="numpy")
def pipe_loss_pa(
    u_m_s: float,
    bore_m: float,
    length_m: float,
    nu_m2_s: float,
    rho_kg_m3: float,
    k_local: float,
    relative_roughness: float,
    method: int,
) -> float:
    r"""Signed pressure loss along a pipe with local losses, paper eq 12-14 [Pa].

    .. math::
        \Delta p = \left(\lambda \frac{l}{d} + \xi\right)\frac{\rho u |u|}{2}

    (eq 12 along the pipe, eq 13 local, eq 14 their sum), lambda from
    :func:`darcy_friction_factor_at`. In laminar flow the along-pipe part is written as
    the Hagen-Poiseuille drop of eq 6, 32 mu l u / d^2 (= R q), linear and smooth
    through u = 0.

    Parameters
    ----------
    u_m_s : float
        Mean oil velocity in the pipe [m/s], signed; NaN gives NaN.
    bore_m, length_m : float
        Pipe inner diameter and length [m] (length 0: local loss only).
    nu_m2_s : float
        Kinematic viscosity [m2/s].
    rho_kg_m3 : float
        Oil density [kg/m3].
    k_local : float
        Sum of local loss coefficients xi (valves, fittings) referred to u [-].
    relative_roughness : float
        epsilon / d [-].
    method : int
        Turbulent friction factor, :data:`COLEBROOK` or :data:`BLASIUS`.

    Notes
    -----
    Loss coefficients of valves (e.g. Crane's K) are stated for turbulent flow; in
    laminar flow the real local loss is larger (the 2-K/3-K methods in ``fluids``), so
    xi rho u^2/2 underestimates it there.

    >>> round(pipe_loss_pa(1.0, 0.01, 1.0, 46e-6, 900.0, 0.0, 0.0, COLEBROOK), 3)  # Re 217
    13248.0
    """
    if u_m_s == 0.0 or u_m_s != u_m_s:  # at rest 0 (not -0.0); unknown (NaN) stays NaN
        return u_m_s - u_m_s if u_m_s != u_m_s else 0.0
    dynamic = 0.5 * rho_kg_m3 * u_m_s * abs(u_m_s)
    re = abs(u_m_s) * bore_m / nu_m2_s
    if re <= RE_LAMINAR:
        along = 32.0 * nu_m2_s * rho_kg_m3 * length_m * u_m_s / (bore_m * bore_m)
    else:
        along = darcy_friction_factor_at(re, relative_roughness, method) * length_m / bore_m
        along *= dynamic
    return along + k_local * dynamic


def reynolds_number(
    v_m_s: np.ndarray | float, d_m: float, nu_m2_s: np.ndarray | float
) -> np.ndarray:
    r"""Pipe Reynolds number Re = |v| d / nu [-].

    ``v_m_s`` mean velocity [m/s], ``d_m`` inner diameter [m], ``nu_m2_s`` kinematic
    viscosity [m2/s].

    >>> float(reynolds_number(-1.0, 0.01, 46e-6)) > 217
    True
    """
    return np.abs(np.asarray(v_m_s, dtype=np.float64)) * d_m / np.asarray(nu_m2_s)


@njit(cache=True, nogil=True, error_model="numpy")
def _friction_factors(re, relative_roughness, method, out):  # pragma: no cover - numba
    for i in range(re.shape[0]):
        out[i] = darcy_friction_factor_at(re[i], relative_roughness, method)


def darcy_friction_factor(
    re: np.ndarray | float, relative_roughness: float = 0.0, method: int = COLEBROOK
) -> np.ndarray:
    """:func:`darcy_friction_factor_at` over an array of Reynolds numbers (> 0) [-].

    >>> float(darcy_friction_factor(1000.0))
    0.064
    >>> round(float(darcy_friction_factor(1e5, 1e-4)), 5)
    0.01851
    """
    re_arr = np.asarray(re, dtype=np.float64)
    out = np.empty(re_arr.size)
    _friction_factors(np.ascontiguousarray(re_arr.ravel()), float(relative_roughness), method, out)
    return out.reshape(re_arr.shape)


@njit(cache=True, nogil=True, error_model="numpy")
def _pipe_losses(u, bore, length, nu, rho, k_local, rr, method, out):  # pragma: no cover
    per_sample = nu.shape[0] > 1
    for i in range(u.shape[0]):
        nu_i = nu[i] if per_sample else nu[0]
        out[i] = pipe_loss_pa(u[i], bore, length, nu_i, rho, k_local, rr, method)


def pipe_pressure_loss(
    v_m_s: np.ndarray | float,
    d_m: float,
    length_m: float,
    nu_m2_s: np.ndarray | float,
    rho_kg_m3: float,
    *,
    roughness_m: float = 0.0,
    k_local: float = 0.0,
    method: int = COLEBROOK,
) -> np.ndarray:
    """:func:`pipe_loss_pa` over an array of velocities ``v_m_s`` [m/s] (eq 12-14) [Pa].

    ``nu_m2_s`` a scalar or one value per velocity; ``roughness_m`` absolute [m].

    >>> dp = pipe_pressure_loss(1.0, 0.01, 1.0, 46e-6, 900.0)   # Re 217: laminar
    >>> round(float(dp), 3)   # 32 mu l v / d^2 = 32 * 0.0414 / 1e-4
    13248.0
    """
    v, nu = np.broadcast_arrays(
        np.asarray(v_m_s, dtype=np.float64), np.asarray(nu_m2_s, dtype=np.float64)
    )
    flat, nu_flat = np.ascontiguousarray(v.ravel()), np.ascontiguousarray(nu.ravel())
    out = np.empty(flat.size)
    if flat.size:
        _pipe_losses(
            flat, d_m, length_m, nu_flat, rho_kg_m3, k_local, roughness_m / d_m, method, out
        )
    return out.reshape(v.shape)


def globe_valve_k(d_m: float) -> float:
    """Loss coefficient K of a fully open globe valve of bore ``d_m`` [m] (Crane TP-410).

    K = 340 f_T with f_T Crane's fully turbulent friction factor for clean commercial
    steel of that size, via ``fluids.K_globe_valve_Crane`` [-].

    >>> round(globe_valve_k(0.01), 2)
    9.88

    References
    ----------
    Crane Co. (2009), Flow of Fluids Through Valves, Fittings, and Pipe, TP-410, A-27.
    """
    return float(fluids.K_globe_valve_Crane(d_m, d_m))
