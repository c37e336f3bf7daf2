"""Steady seal friction: the Stribeck curve (paper eq 16/18) and its pressure law (eq 17).

Functions
    :func:`friction_law_at` -- Fc, Fs, vs, Kv at one chamber pressure (eq 17; numba).
    :func:`friction_parameters` -- the same over an array of pressures.
    :func:`law_array` -- a :class:`~schemas.hoist.FrictionLaw` as the kernels' array.
    :func:`stribeck_g` -- the Stribeck bracket g(v) (eq 15 third line, eq 16; numba).
    :func:`stribeck_friction` -- the steady-state curve F(v) (eq 16/18), vectorised.

Sign convention (contract 1a): v is the piston (rod) velocity, positive while the rope
pulls the rod out; friction is positive while the rod moves out (it opposes the motion),
and rope tension is ``T = p_chamber A_bore + F`` (eq 2, :mod:`physics.tension`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from schemas.hoist import FrictionLaw

__all__ = [
    "STRIBECK_SPEED_FLOOR_M_S",
    "friction_law_at",
    "friction_parameters",
    "law_array",
    "stribeck_friction",
    "stribeck_g",
]

#: Lower bound applied to the Stribeck speed of the eq 17 law [m/s]. A linear law with a
#: negative slope (eq 17: vs = 8.35 - 0.397 p mm/s) turns negative above ~21 MPa; the
#: floor keeps exp(-(v/vs)^2) defined.
STRIBECK_SPEED_FLOOR_M_S = 1e-6


def law_array(law: FrictionLaw) -> np.ndarray:
    """The eq 17 law as the kernels take it: ``[a_c, b_c, a_s, b_s, a_v, b_v, a_k, b_k]``.

    Intercepts and slopes of Fc [N, N/Pa], Fs [N, N/Pa], vs [m/s, m/(s Pa)] and
    Kv [N s/m, N s/(m Pa)].

    >>> law_array(FrictionLaw((10.0, 1e-6), (20.0, 1e-6), (1e-3, 0.0), (5.0, 0.0), 1e7, 1e3, 4))
    array([1.e+01, 1.e-06, 2.e+01, 1.e-06, 1.e-03, 0.e+00, 5.e+00, 0.e+00])
    """
    lines = (law.coulomb_n, law.static_n, law.stribeck_speed_m_s, law.viscous_n_s_m)
    return np.array([value for line in lines for value in line], dtype=np.float64)


@njit(cache=True, nogil=True, inline="always")
def friction_law_at(p_pa: float, law: np.ndarray) -> tuple[float, float, float, float]:
    r"""Stribeck parameters at chamber pressure ``p_pa`` from a linear law (paper eq 17).

    .. math::
        F_c = a_c + b_c p,\quad F_s = a_s + b_s p,\quad
        v_s = a_v + b_v p,\quad K_v = a_k + b_k p

    Parameters
    ----------
    p_pa : float
        Chamber pressure [Pa].
    law : numpy.ndarray
        :func:`law_array` of the law (8 intercepts and slopes, SI).

    Returns
    -------
    fc, fs, vs, kv : float
        Coulomb friction [N], maximum static friction [N], Stribeck speed [m/s],
        viscous coefficient [N s/m].

    Notes
    -----
    Outside the calibrated range (2-12 MPa in the paper) a straight line can go
    unphysical; forces and the viscous coefficient are clipped at 0 and the Stribeck
    speed at :data:`STRIBECK_SPEED_FLOOR_M_S` (a NaN line value gives the floor).
    ``fs >= fc`` is not enforced. The paper prints eq 17 in N and mm/s against MPa;
    :data:`transforms.friction_fit.EQ17` holds it in SI.

    >>> law = law_array(FrictionLaw((10.0, 1e-6), (20.0, 1e-6), (1e-3, 0.0), (5.0, 0.0),
    ...                             1e7, 1e3, 4))
    >>> [float(a) for a in friction_law_at(2e6, law)]
    [12.0, 22.0, 0.001, 5.0]
    """
    fc = law[0] + law[1] * p_pa
    fs = law[2] + law[3] * p_pa
    vs = law[4] + law[5] * p_pa
    kv = law[6] + law[7] * p_pa
    return (
        fc if fc > 0.0 else 0.0,
        fs if fs > 0.0 else 0.0,
        vs if vs > STRIBECK_SPEED_FLOOR_M_S else STRIBECK_SPEED_FLOOR_M_S,
        kv if kv > 0.0 else 0.0,
    )


@njit(cache=True, nogil=True)
def _friction_laws(p, law, out):  # pragma: no cover - numba
    for i in range(p.shape[0]):
        fc, fs, vs, kv = friction_law_at(p[i], law)
        out[0, i], out[1, i], out[2, i], out[3, i] = fc, fs, vs, kv


def friction_parameters(
    p_pa: np.ndarray | float, law: FrictionLaw
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`friction_law_at` over an array of chamber pressures ``p_pa`` [Pa].

    Returns fc [N], fs [N], vs [m/s], kv [N s/m], each shaped like ``p_pa``.

    >>> law = FrictionLaw((10.0, 1e-6), (20.0, 1e-6), (1e-3, 0.0), (5.0, 0.0), 1e7, 1e3, 4)
    >>> [float(a) for a in friction_parameters(2e6, law)]
    [12.0, 22.0, 0.001, 5.0]
    """
    p = np.asarray(p_pa, dtype=np.float64)
    flat = np.ascontiguousarray(p.ravel())
    out = np.empty((4, flat.size))
    _friction_laws(flat, law_array(law), out)
    if p.ndim == 0:
        return tuple(np.float64(row[0]) for row in out)  # type: ignore[return-value]
    fc, fs, vs, kv = (row.reshape(p.shape) for row in out)
    return fc, fs, vs, kv


@njit(cache=True, nogil=True)
def stribeck_g(v: float, fc: float, fs: float, vs: float) -> float:
    r"""Stribeck function g(v) (paper eq 15 third line; the bracket of eq 16) [N].

    .. math:: g(v) = F_c + (F_s - F_c) e^{-(v/v_s)^2}

    ``v`` [m/s], ``fc``/``fs`` [N], ``vs`` [m/s] > 0. Numba scalar kernel.

    >>> round(stribeck_g(0.0, 1.0, 1.5, 0.001), 12), round(stribeck_g(1.0, 1.0, 1.5, 0.001), 12)
    (1.5, 1.0)
    """
    r = v / vs
    return fc + (fs - fc) * math.exp(-r * r)


@njit(cache=True, nogil=True)
def _stribeck_curve(v, fc, fs, vs, kv, out):  # pragma: no cover - numba
    for i in range(v.shape[0]):
        vi = v[i]
        sign = 1.0 if vi > 0.0 else (-1.0 if vi < 0.0 else (0.0 if vi == 0.0 else vi))
        out[i] = stribeck_g(vi, fc[i], fs[i], vs[i]) * sign + kv[i] * vi


def stribeck_friction(
    v_m_s: np.ndarray | float,
    fc: np.ndarray | float,
    fs: np.ndarray | float,
    vs: np.ndarray | float,
    kv: np.ndarray | float,
) -> np.ndarray:
    r"""Steady-state friction force, the Stribeck curve (paper eq 16 and 18).

    .. math::
        F(v) = g(v) \operatorname{sgn}(v) + K_v v
             = \left[F_c + (F_s - F_c) e^{-(v/v_s)^2}\right]\operatorname{sgn}(v) + K_v v

    with g from :func:`stribeck_g`.

    Parameters
    ----------
    v_m_s : array_like
        Sliding (piston) velocity [m/s].
    fc, fs : array_like
        Coulomb and maximum static friction [N].
    vs : array_like
        Stribeck speed [m/s], > 0.
    kv : array_like
        Viscous coefficient [N s/m].

    Returns
    -------
    numpy.ndarray
        Friction force [N], broadcast shape of the inputs; 0 at v = 0 (the steady state
        is undefined at rest: :func:`physics.lugre.lugre_friction` or
        :func:`physics.maxwell_slip.maxwell_slip_friction` hold it at standstill).

    Notes
    -----
    It is the v = const. steady state of eq 15 (dz/dt = 0 gives z = g(v) sgn(v)/sigma0).
    The paper prints the exponent as -|v/vs|^2 in eq 16 and -(v/vs)^2 in eq 18; both
    are the same.

    Examples
    --------
    >>> round(float(stribeck_friction(0.001, 1.0, 1.5, 0.001, 0.4)), 6)
    1.18434

    References
    ----------
    Song et al., hydraulic connection device, eq 16/18. Canudas de Wit, C., Olsson, H.,
    Astrom, K. J., Lischinsky, P. (1995), IEEE TAC 40(3), 419-425,
    doi:10.1109/9.376053, eq 6-7.
    """
    inputs = (v_m_s, fc, fs, vs, kv)
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in inputs))
    shape = arrays[0].shape
    flat = [np.ascontiguousarray(a.ravel()) for a in arrays]
    out = np.empty(flat[0].size)
    _stribeck_curve(*flat, out)
    return out.reshape(shape)
