"""Dynamic seal friction, LuGre (paper eq 15, which the paper calls "Leuven").

Functions (numba scalar kernels, then the vectorised one)
    :func:`lugre_z_rate` -- dz/dt, eq 15 first line (the ODE form, for integrators).
    :func:`lugre_force_at` -- F = sigma0 z + sigma1 dz/dt + Kv v, eq 15 second line.
    :func:`lugre_z_step` -- exact exponential solution of the first line over a step.
    :func:`lugre_drift` -- the first line's drift term alone along a travelled path
    (:func:`lugre_drift_exponent`, its exponent sigma_0 s / g).
    :func:`lugre_force` -- the second line over a step, from z before/after it.
    :func:`lugre_friction` -- the two over a sampled velocity record.

Errata: the paper (section 4.2) calls eq 15 the "Leuven" model, but eq 15 as printed is
the LuGre model of Canudas de Wit et al. (1995). The Leuven model (Swevers et al. 2000)
adds a hysteresis force with non-local memory for presliding; ropeload provides that
part with Maxwell-slip elements, :mod:`physics.maxwell_slip`.

Units SI: velocity [m/s], force [N], bristle deflection [m]; sign convention of
:mod:`physics.friction_law`.

References
----------
Canudas de Wit, C., Olsson, H., Astrom, K. J., Lischinsky, P. (1995), A new model for
control of systems with friction, IEEE TAC 40(3), 419-425, doi:10.1109/9.376053.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from physics._samples import per_sample
from physics.friction_law import stribeck_g

__all__ = [
    "lugre_drift",
    "lugre_drift_exponent",
    "lugre_force",
    "lugre_force_at",
    "lugre_friction",
    "lugre_z_rate",
    "lugre_z_step",
]


@njit(cache=True, nogil=True, inline="always")
def lugre_z_rate(z: float, v: float, sigma0: float, g: float) -> float:
    r"""Bristle deflection rate of LuGre (paper eq 15, first line) [m/s].

    .. math:: \frac{dz}{dt} = v - \frac{\sigma_0 |v|}{g(v)} z

    ``z`` [m], ``v`` [m/s], ``sigma0`` [N/m], ``g`` the Stribeck function [N] > 0
    (:func:`physics.friction_law.stribeck_g`). For an integrator of the ODE; over a
    sampled record :func:`lugre_z_step` solves it exactly.

    >>> lugre_z_rate(1e-5, 0.01, 1e5, 1.0)   # at the steady state g / sigma0: 0
    0.0
    """
    return v - sigma0 * abs(v) * z / g


@njit(cache=True, nogil=True, inline="always")
def lugre_force_at(
    z: float, z_rate: float, v: float, sigma0: float, sigma1: float, kv: float
) -> float:
    r"""LuGre friction force (paper eq 15, second line) [N].

    .. math:: F = \sigma_0 z + \sigma_1 \frac{dz}{dt} + \sigma_2 v, \qquad \sigma_2 = K_v

    ``z`` [m], ``z_rate`` [m/s], ``v`` [m/s], ``sigma0`` [N/m], ``sigma1`` and ``kv``
    [N s/m].

    >>> lugre_force_at(1e-5, 0.0, 0.0, 1e5, 316.0, 0.4)
    1.0
    """
    return sigma0 * z + sigma1 * z_rate + kv * v


@njit(cache=True, nogil=True)
def lugre_z_step(z: float, v: float, dt: float, sigma0: float, g: float) -> float:
    r"""Exact exponential update of the LuGre bristle deflection z over one step.

    LuGre (paper eq 15; Canudas de Wit et al. 1995 eq 2):

    .. math::
        \frac{dz}{dt} = v - \frac{\sigma_0 |v|}{g(v)} z

    With v (hence g) held constant over the step the equation is linear in z, so

    .. math::
        z_{new} = z_{ss} + (z - z_{ss}) e^{-\sigma_0 |v| \Delta t / g},\qquad
        z_{ss} = \frac{g \operatorname{sgn}(v)}{\sigma_0}

    is exact and unconditionally stable for any stiffness sigma0 and step dt (z relaxes
    monotonically towards z_ss and never overshoots).

    Parameters
    ----------
    z : float
        Bristle deflection at the start of the step [m].
    v : float
        Sliding velocity, constant over the step [m/s].
    dt : float
        Step length [s]; dt <= 0 leaves z unchanged.
    sigma0 : float
        Bristle stiffness [N/m], > 0.
    g : float
        Stribeck function g(v) [N] (:func:`physics.friction_law.stribeck_g`).

    Returns
    -------
    float
        Bristle deflection at the end of the step [m]. At v = 0 (or a NaN v) z is held
        (stiction carried over); with g <= 0 (no friction) the bristles relax to 0.

    Examples
    --------
    >>> z = lugre_z_step(0.0, 0.1, 1.0, 1e5, 1.0)   # long step: steady state g/sigma0
    >>> round(z * 1e5, 12)
    1.0
    >>> lugre_z_step(3e-6, 0.0, 1.0, 1e5, 1.0)       # standstill: held
    3e-06
    """
    if v == 0.0 or v != v or dt <= 0.0:
        return z
    if g <= 0.0:
        return 0.0
    z_ss = g / sigma0 if v > 0.0 else -g / sigma0
    rate = sigma0 * abs(v) * dt / g
    if rate > 745.0:  # exp underflows to 0: already at the steady state
        return z_ss
    return z_ss + (z - z_ss) * math.exp(-rate)


@njit(cache=True, nogil=True, inline="always")
def lugre_drift(force_n: float, path_m: float, sigma0: float, g: float) -> float:
    r"""The bristles' force after LuGre's drift along a travelled path [N].

    Eq 15's first line per unit of travel, :math:`dz = dx - \sigma_0 |dx| z / g`, is an
    elastic part (dz = dx: reversible, the force follows the piston back and forth) and
    a drift toward 0 proportional to the path |dx| whatever its direction. Along a path
    s at a fixed g the drift alone gives

    .. math:: F' = F \, e^{-\sigma_0 s / g}

    It is why an oscillation with no net travel shakes a seal loose (the bristles relax
    by e over each presliding length g / sigma_0 travelled): a step that adds
    ``sigma0 dx`` (the elastic part) after this one integrates eq 15 to first order in
    the step. ``force_n`` = sigma_0 z [N], ``path_m`` >= 0 [m], ``sigma0`` [N/m],
    ``g`` the Stribeck function [N] > 0 (:func:`physics.friction_law.stribeck_g`).

    >>> round(lugre_drift(1000.0, 25e-6, 4e7, 1000.0), 3)   # one presliding length
    367.879
    >>> lugre_drift(1000.0, 0.0, 4e7, 1000.0)
    1000.0
    """
    return force_n * math.exp(-lugre_drift_exponent(path_m, sigma0, g))


@njit(cache=True, nogil=True, inline="always")
def lugre_drift_exponent(path_m: float, sigma0: float, g: float) -> float:
    r"""The exponent :math:`R = \sigma_0 s / g` by which LuGre's drift along a path s
    relaxes the bristles' force, :math:`F' = F e^{-R}` (:func:`lugre_drift`): the path in
    presliding lengths g / sigma_0. Any error of the force relaxes by the same factor
    (the drift is linear in F at a fixed g), which
    :func:`transforms.stop_continuity.drift_gains` uses.

    >>> lugre_drift_exponent(25e-6, 4e7, 1000.0)   # one presliding length
    1.0
    """
    return sigma0 * path_m / g


@njit(cache=True, nogil=True)
def lugre_force(
    z: float, z_new: float, v: float, dt: float, sigma0: float, sigma1: float, kv: float
) -> float:
    r"""LuGre friction force at the end of a step (paper eq 15, second line) [N].

    :func:`lugre_force_at` with z = z_new and dz/dt the mean over the step,
    (z_new - z)/dt, which is exact in the integral sense for the exponential update of
    :func:`lugre_z_step`. ``z``, ``z_new``
    [m], ``v`` [m/s], ``dt`` [s] (dt <= 0 drops the damping term), ``sigma0`` [N/m],
    ``sigma1`` [N s/m], ``kv`` [N s/m].

    >>> lugre_force(0.0, 1e-5, 0.0, 1e-3, 1e5, 0.0, 0.4)
    1.0
    """
    return lugre_force_at(z_new, (z_new - z) / dt if dt > 0.0 else 0.0, v, sigma0, sigma1, kv)


@njit(cache=True, nogil=True)
def _lugre_record(v, dt, fc, fs, vs, kv, sigma0, sigma1, z0, force, z_out):  # pragma: no cover
    z = z0
    for i in range(v.shape[0]):
        z_before = z
        if v[i] != v[i]:  # NaN velocity (logger gap): state held, no force
            force[i] = np.nan
            z_out[i] = z
            continue
        z = lugre_z_step(z, v[i], dt[i], sigma0, stribeck_g(v[i], fc[i], fs[i], vs[i]))
        force[i] = lugre_force(z_before, z, v[i], dt[i], sigma0, sigma1, kv[i])
        z_out[i] = z


def lugre_friction(
    v: np.ndarray,
    dt: np.ndarray | float,
    fc: np.ndarray | float,
    fs: np.ndarray | float,
    vs: np.ndarray | float,
    kv: np.ndarray | float,
    sigma0: float,
    sigma1: float,
    z0: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    r"""LuGre friction force driven by a sampled velocity record (paper eq 15).

    Sample i: ``v[i]`` is the velocity held over the interval of length ``dt[i]``
    that ends at sample i (``dt[i] = t[i] - t[i-1]``; ``dt[0]`` is the step from the
    initial state ``z0``). ``z[i]`` is the bristle deflection at the end of that
    interval (:func:`lugre_z_step`) and ``F[i]`` the force of :func:`lugre_force`,
    ``sigma0 z[i] + sigma1 (z[i] - z[i-1]) / dt[i] + kv[i] v[i]``.

    Parameters
    ----------
    v : numpy.ndarray
        Piston velocity [m/s], positive rod out.
    dt : numpy.ndarray or float
        Step lengths [s].
    fc, fs, vs, kv : numpy.ndarray or float
        Per-sample Coulomb [N], static [N] friction, Stribeck speed [m/s], viscous
        coefficient [N s/m] (e.g. from :func:`physics.friction_law.friction_parameters`).
    sigma0 : float
        Bristle stiffness [N/m]; any value (kN/mm to tens of kN/mm included) is stable.
    sigma1 : float
        Bristle damping [N s/m].
    z0 : float
        Initial deflection [m].

    Returns
    -------
    friction_n, z_m : numpy.ndarray
        Friction force [N] and bristle deflection [m] per sample.

    Notes
    -----
    A NaN velocity (a gap in the record) gives NaN force and holds z, so the state
    is not poisoned. At standstill (v = 0) z is held, so the friction carried over from
    the last motion persists (sigma0 z) instead of dropping to zero. With v constant for
    long enough the force converges to the Stribeck curve, eq 16.

    Examples
    --------
    >>> f, z = lugre_friction(np.array([0.01, 0.01, 0.0]), 1.0, 1.0, 1.5, 0.001, 0.4,
    ...                       1e5, 316.0)
    >>> [round(float(x), 6) for x in f]
    [1.00716, 1.004, 1.0]
    """
    v_arr = np.ascontiguousarray(v, dtype=np.float64)
    n = v_arr.shape[0]
    force, z = np.empty(n), np.empty(n)
    _lugre_record(
        v_arr,
        per_sample(dt, n, "dt"),
        per_sample(fc, n, "fc"),
        per_sample(fs, n, "fs"),
        per_sample(vs, n, "vs"),
        per_sample(kv, n, "kv"),
        float(sigma0),
        float(sigma1),
        float(z0),
        force,
        z,
    )
    return force, z
