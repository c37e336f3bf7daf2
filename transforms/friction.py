"""Piston-seal friction of the rope-attachment cylinders (paper section 4.2).

Models, all in SI (velocity [m/s], force [N], bristle deflection [m]):

Steady state
    :func:`stribeck_friction` -- the Stribeck curve, paper eq 16/18 (vectorised numpy).
    :func:`friction_parameters` -- Fc, Fs, vs, Kv at a chamber pressure from a
    :class:`~schemas.hoist.FrictionLaw` (paper eq 17 form).

Dynamic, LuGre (paper eq 15)
    :func:`stribeck_g` -- g(v), the Stribeck function (scalar, numba).
    :func:`lugre_z_step` -- exact exponential update of the bristle state z (scalar, numba).
    :func:`lugre_force` -- friction force from z before/after a step (scalar, numba).
    :func:`lugre_friction` -- whole-array LuGre friction driven by a velocity record.

Presliding hysteresis with non-local memory, Maxwell-slip (the "Leuven" idea)
    :func:`maxwell_slip_step` -- one displacement increment of N elasto-slip elements
    (scalar, numba).
    :func:`maxwell_slip_elements` -- element stiffnesses and weights from the total
    presliding stiffness.
    :func:`maxwell_slip_friction` -- whole-array Maxwell-slip friction with
    Stribeck-scaled capacities (the C -> infinity limit of Generalized Maxwell-Slip).

Sign convention (contract section 1a): velocity is the piston (rod) velocity, positive
while the rope pulls the rod out; friction is positive while the rod moves out, i.e. it
opposes the motion, and rope tension is ``T = p_chamber * A_bore + F_friction``.

The scalar kernels are ``numba.njit(cache=True)`` functions so that simulation code can
call them from inside its own njit integrators.

Errata: the paper (section 4.2) calls eq 15 the "Leuven" model, but eq 15 as printed is
the LuGre model of Canudas de Wit et al. (1995). The Leuven model (Swevers et al. 2000)
adds a hysteresis force with non-local memory for presliding; here that part is
provided by the Maxwell-slip functions.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from schemas.hoist import FrictionLaw

__all__ = [
    "STRIBECK_SPEED_FLOOR_M_S",
    "friction_parameters",
    "lugre_force",
    "lugre_friction",
    "lugre_z_step",
    "maxwell_slip_elements",
    "maxwell_slip_friction",
    "maxwell_slip_step",
    "stribeck_friction",
    "stribeck_g",
]

#: Lower bound applied to the Stribeck speed by :func:`friction_parameters` [m/s].
#: A linear law with a negative slope (eq 17: vs = 8.35 - 0.397 p mm/s) turns negative
#: above ~21 MPa; the floor keeps exp(-(v/vs)^2) defined.
STRIBECK_SPEED_FLOOR_M_S = 1e-6


# ---------------------------------------------------------------------------------------
# Steady state
# ---------------------------------------------------------------------------------------
def friction_parameters(
    p_pa: np.ndarray | float, law: FrictionLaw
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r"""Stribeck parameters at chamber pressure ``p_pa`` from a linear law (paper eq 17).

    .. math::
        F_c = a_c + b_c p,\quad F_s = a_s + b_s p,\quad
        v_s = a_v + b_v p,\quad K_v = a_k + b_k p

    Parameters
    ----------
    p_pa : array_like
        Chamber pressure [Pa].
    law : FrictionLaw
        SI intercepts and slopes (forces [N] and [N/Pa], speed [m/s] and [m/(s Pa)],
        viscous coefficient [N s/m] and [N s/(m Pa)]).

    Returns
    -------
    fc, fs, vs, kv : numpy.ndarray
        Coulomb friction [N], maximum static friction [N], Stribeck speed [m/s],
        viscous coefficient [N s/m], each shaped like ``p_pa``.

    Notes
    -----
    Outside the calibrated range (2-12 MPa in the paper) a straight line can go
    unphysical; forces and the viscous coefficient are clipped at 0 and the Stribeck
    speed at :data:`STRIBECK_SPEED_FLOOR_M_S`. ``fs >= fc`` is not enforced.

    Examples
    --------
    >>> law = FrictionLaw((10.0, 1e-6), (20.0, 1e-6), (1e-3, 0.0), (5.0, 0.0), 1e7, 1e3, 4)
    >>> [float(a) for a in friction_parameters(2e6, law)]
    [12.0, 22.0, 0.001, 5.0]
    """
    p = np.asarray(p_pa, dtype=np.float64)
    coefficients = np.array(
        [law.coulomb_n, law.static_n, law.stribeck_speed_m_s, law.viscous_n_s_m],
        dtype=np.float64,
    )
    floors = np.array([0.0, 0.0, STRIBECK_SPEED_FLOOR_M_S, 0.0])
    if p.ndim == 0:
        values = np.maximum(coefficients[:, 0] + coefficients[:, 1] * float(p), floors)
        return tuple(np.float64(x) for x in values)  # type: ignore[return-value]
    flat = np.ascontiguousarray(p.ravel())
    out = np.empty((4, flat.size))
    _linear_laws(flat, coefficients, floors, out)
    fc, fs, vs, kv = (row.reshape(p.shape) for row in out)
    return fc, fs, vs, kv


@njit(inline="always")
def _linear_law(coefficients, floors, k, p):  # pragma: no cover - numba
    """max(a_k + b_k p, floor_k): eq 17 line k at one pressure."""
    value = coefficients[k, 0] + coefficients[k, 1] * p
    return value if value > floors[k] else floors[k]


@njit(cache=True, nogil=True)
def _linear_laws(p, coefficients, floors, out):  # pragma: no cover - numba
    """out[k, i] = max(a_k + b_k p[i], floor_k): the four eq 17 lines in one pass."""
    for i in range(p.shape[0]):
        for k in range(4):
            out[k, i] = _linear_law(coefficients, floors, k, p[i])


def stribeck_friction(
    v_m_s: np.ndarray | float,
    fc: np.ndarray | float,
    fs: np.ndarray | float,
    vs: np.ndarray | float,
    kv: np.ndarray | float,
) -> np.ndarray:
    r"""Steady-state friction force, the Stribeck curve (paper eq 16 and 18).

    .. math::
        F(v) = \left[F_c + (F_s - F_c) e^{-(v/v_s)^2}\right]\operatorname{sgn}(v) + K_v v

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
        Friction force [N]; 0 at v = 0 (the steady state is undefined at rest: use
        :func:`lugre_friction` or :func:`maxwell_slip_friction` for standstill).

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
    v = np.asarray(v_m_s, dtype=np.float64)
    ratio = v / np.asarray(vs, dtype=np.float64)
    g = fc + (np.asarray(fs) - fc) * np.exp(-ratio * ratio)
    return g * np.sign(v) + kv * v


# ---------------------------------------------------------------------------------------
# LuGre, scalar building blocks
# ---------------------------------------------------------------------------------------
@njit(cache=True)
def stribeck_g(v: float, fc: float, fs: float, vs: float) -> float:
    r"""Stribeck function g(v) of LuGre (paper eq 15, third line) [N].

    .. math:: g(v) = F_c + (F_s - F_c) e^{-(v/v_s)^2}

    ``v`` [m/s], ``fc``/``fs`` [N], ``vs`` [m/s] > 0. Numba scalar kernel.

    >>> round(stribeck_g(0.0, 1.0, 1.5, 0.001), 12), round(stribeck_g(1.0, 1.0, 1.5, 0.001), 12)
    (1.5, 1.0)
    """
    r = v / vs
    return fc + (fs - fc) * math.exp(-r * r)


@njit(cache=True)
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
        Stribeck function g(v) [N] (force units, so sigma0 z is a force).

    Returns
    -------
    float
        Bristle deflection at the end of the step [m]. At v = 0 z is held (stiction
        carried over); with g <= 0 (no friction) the bristles relax to 0.

    Examples
    --------
    >>> z = lugre_z_step(0.0, 0.1, 1.0, 1e5, 1.0)   # long step: steady state g/sigma0
    >>> round(z * 1e5, 12)
    1.0
    >>> lugre_z_step(3e-6, 0.0, 1.0, 1e5, 1.0)       # standstill: held
    3e-06
    """
    if v == 0.0 or dt <= 0.0:
        return z
    if g <= 0.0:
        return 0.0
    z_ss = g / sigma0 if v > 0.0 else -g / sigma0
    rate = sigma0 * abs(v) * dt / g
    if rate > 745.0:  # exp underflows to 0: already at the steady state
        return z_ss
    return z_ss + (z - z_ss) * math.exp(-rate)


@njit(cache=True)
def lugre_force(
    z: float, z_new: float, v: float, dt: float, sigma0: float, sigma1: float, kv: float
) -> float:
    r"""LuGre friction force at the end of a step (paper eq 15, second line) [N].

    .. math::
        F = \sigma_0 z_{new} + \sigma_1 \frac{z_{new} - z}{\Delta t} + \sigma_2 v,
        \qquad \sigma_2 = K_v

    dz/dt is taken as the mean over the step, (z_new - z)/dt, which is exact in the
    integral sense for the exponential update of :func:`lugre_z_step`. ``z``, ``z_new``
    [m], ``v`` [m/s], ``dt`` [s] (dt <= 0 drops the damping term), ``sigma0`` [N/m],
    ``sigma1`` [N s/m], ``kv`` [N s/m].

    >>> lugre_force(0.0, 1e-5, 0.0, 1e-3, 1e5, 0.0, 0.4)
    1.0
    """
    f = sigma0 * z_new + kv * v
    if dt > 0.0:
        f += sigma1 * (z_new - z) / dt
    return f


@njit(cache=True, nogil=True, parallel=True)
def _lugre_decay_target(v, dt, fc, fs, vs, sigma0, decay, target):  # pragma: no cover
    """Per sample, independent of z: the exact update's decay and steady state."""
    for i in prange(v.shape[0]):
        vi = v[i]
        if vi == 0.0 or vi != vi or dt[i] <= 0.0:  # standstill, NaN or no step: hold z
            decay[i] = 1.0
            target[i] = 0.0
            continue
        r = vi / vs[i]
        g = fc[i] + (fs[i] - fc[i]) * math.exp(-r * r)
        if g <= 0.0:  # no friction: the bristles relax at once
            decay[i] = 0.0
            target[i] = 0.0
            continue
        rate = sigma0 * abs(vi) * dt[i] / g
        decay[i] = math.exp(-rate) if rate < 745.0 else 0.0
        target[i] = g / sigma0 if vi > 0.0 else -g / sigma0


@njit(cache=True, nogil=True)
def _affine_recurrence(decay, target, z0, z_out):  # pragma: no cover - numba
    """z[i] = decay[i] z[i-1] + (1 - decay[i]) target[i]: the only sequential part."""
    z = z0
    for i in range(decay.shape[0]):
        z = target[i] + (z - target[i]) * decay[i]
        z_out[i] = z


@njit(cache=True, nogil=True, parallel=True)
def _lugre_forces(v, dt, kv, z, z0, sigma0, sigma1, force):  # pragma: no cover - numba
    for i in prange(v.shape[0]):
        if v[i] != v[i]:  # NaN velocity (logger gap): state held, no force
            force[i] = np.nan
            continue
        z_before = z0 if i == 0 else z[i - 1]
        f = sigma0 * z[i] + kv[i] * v[i]
        if dt[i] > 0.0:
            f += sigma1 * (z[i] - z_before) / dt[i]
        force[i] = f


def _per_sample(value: np.ndarray | float, n: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name}: expected a scalar or shape ({n},), got {arr.shape}")
    return np.ascontiguousarray(arr)


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
    interval, updated exactly by :func:`lugre_z_step`, and
    ``F[i] = sigma0 z[i] + sigma1 (z[i] - z[i-1]) / dt[i] + kv[i] v[i]``.

    Parameters
    ----------
    v : numpy.ndarray
        Piston velocity [m/s], positive rod out.
    dt : numpy.ndarray or float
        Step lengths [s].
    fc, fs, vs, kv : numpy.ndarray or float
        Per-sample Coulomb [N], static [N] friction, Stribeck speed [m/s], viscous
        coefficient [N s/m] (e.g. from :func:`friction_parameters`).
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
    the last motion persists (sigma0 z) instead of dropping to zero. With v constant for long
    enough the force converges to the Stribeck curve, eq 16.

    Examples
    --------
    >>> f, z = lugre_friction(np.array([0.01, 0.01, 0.0]), 1.0, 1.0, 1.5, 0.001, 0.4,
    ...                       1e5, 316.0)
    >>> [round(float(x), 6) for x in f]
    [1.00716, 1.004, 1.0]
    """
    v_arr = np.ascontiguousarray(v, dtype=np.float64)
    n = v_arr.shape[0]
    dt_arr = _per_sample(dt, n, "dt")
    decay, target, z, force = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    # The exact update's decay and steady state do not depend on z: computed in
    # parallel; only the affine recurrence z <- target + (z - target) decay is sequential.
    _lugre_decay_target(
        v_arr,
        dt_arr,
        _per_sample(fc, n, "fc"),
        _per_sample(fs, n, "fs"),
        _per_sample(vs, n, "vs"),
        float(sigma0),
        decay,
        target,
    )
    _affine_recurrence(decay, target, float(z0), z)
    _lugre_forces(
        v_arr, dt_arr, _per_sample(kv, n, "kv"), z, float(z0), float(sigma0), float(sigma1), force
    )
    return force, z


# ---------------------------------------------------------------------------------------
# Maxwell-slip
# ---------------------------------------------------------------------------------------
@njit(cache=True)
def maxwell_slip_step(
    deltas: np.ndarray, dx: float, stiffness: np.ndarray, capacity: np.ndarray
) -> float:
    r"""Advance N Maxwell-slip elements by a displacement increment; return total force.

    Each element j is a massless spring of stiffness k_j whose end slides once its
    force reaches the capacity w_j (Lampaert et al. 2002):

    .. math::
        \delta_j \leftarrow \operatorname{clip}(\delta_j + \Delta x,
        -w_j/k_j, w_j/k_j),\qquad F = \sum_j k_j \delta_j

    The elements together give rate-independent hysteresis with non-local memory:
    nested reversal points, closing inner loops and the wiping-out property.

    Parameters
    ----------
    deltas : numpy.ndarray
        Element spring deflections [m]; updated in place.
    dx : float
        Displacement increment of the moving body [m].
    stiffness : numpy.ndarray
        Element stiffnesses k_j [N/m], > 0.
    capacity : numpy.ndarray
        Element saturation (slip) forces w_j [N], >= 0.

    Returns
    -------
    float
        Total friction force [N], bounded by sum(capacity).

    Examples
    --------
    >>> d = np.zeros(2)
    >>> maxwell_slip_step(d, 1e-6, np.array([1e6, 1e6]), np.array([0.5, 2.0]))
    1.5
    >>> maxwell_slip_step(d, 1e-6, np.array([1e6, 1e6]), np.array([0.5, 2.0]))
    2.5
    """
    total = 0.0
    for j in range(deltas.shape[0]):
        limit = capacity[j] / stiffness[j]
        d = deltas[j] + dx
        if d > limit:
            d = limit
        elif d < -limit:
            d = -limit
        deltas[j] = d
        total += stiffness[j] * d
    return total


def maxwell_slip_elements(n: int, stiffness_n_m: float) -> tuple[np.ndarray, np.ndarray]:
    r"""Element stiffnesses and weights for an n-element Maxwell-slip model.

    Equal weights alpha_j = 1/n (capacities w_j = alpha_j g) and stiffnesses
    k_j proportional to 1/j summing to ``stiffness_n_m``, so the break-away
    displacements w_j/k_j are equally spaced, j/n * delta_max with
    delta_max = g H_n / K (H_n the n-th harmonic number): the virgin curve
    F(x) = sum_j min(k_j x, w_j) is a piecewise-linear approximation of a parabola-like
    presliding curve with initial slope K that saturates at g.

    Parameters
    ----------
    n : int
        Number of elements, >= 1.
    stiffness_n_m : float
        Total presliding (initial) stiffness K = sum k_j [N/m].

    Returns
    -------
    stiffness, weights : numpy.ndarray
        k_j [N/m] and alpha_j [-] (sum 1).

    >>> k, w = maxwell_slip_elements(2, 3e6)
    >>> k.tolist(), w.tolist()
    ([2000000.0, 1000000.0], [0.5, 0.5])
    """
    if n < 1:
        raise ValueError(f"n: need at least one element, got {n}")
    if not stiffness_n_m > 0:
        raise ValueError(f"stiffness_n_m: must be positive, got {stiffness_n_m}")
    inv = 1.0 / np.arange(1, n + 1, dtype=np.float64)
    return stiffness_n_m * inv / inv.sum(), np.full(n, 1.0 / n)


@njit(cache=True, nogil=True)
def _maxwell_slip_kernel(
    v, dt, fc, fs, vs, kv, stiffness, weights, deltas, force_out
):  # pragma: no cover
    capacity = np.empty(weights.shape[0])
    for i in range(v.shape[0]):
        if v[i] != v[i]:  # NaN velocity: hold the elements, no force
            force_out[i] = np.nan
            continue
        # at standstill g(0) = Fs exactly: no exp needed
        g = fs[i] if v[i] == 0.0 else stribeck_g(v[i], fc[i], fs[i], vs[i])
        for j in range(weights.shape[0]):
            capacity[j] = weights[j] * g
        force_out[i] = maxwell_slip_step(deltas, v[i] * dt[i], stiffness, capacity) + kv[i] * v[i]


def maxwell_slip_friction(
    v: np.ndarray,
    dt: np.ndarray | float,
    fc: np.ndarray | float,
    fs: np.ndarray | float,
    vs: np.ndarray | float,
    kv: np.ndarray | float,
    stiffness: np.ndarray,
    weights: np.ndarray,
    deltas0: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    r"""Maxwell-slip friction with Stribeck-scaled capacities driven by a velocity record.

    Per sample i (same timing convention as :func:`lugre_friction`), the displacement
    increment ``v[i] dt[i]`` is applied to the elements (:func:`maxwell_slip_step`) with
    capacities ``w_j = alpha_j g(v[i])``, and the viscous term is added:

    .. math::
        F = \sum_j k_j \delta_j + K_v v

    This is the Generalized Maxwell-Slip model (Al-Bender et al. 2005) in the limit of
    an infinite attraction parameter C (a slipping element's force equals alpha_j g(v)
    at once). In sliding the total force follows the Stribeck curve (eq 16); in
    presliding it shows hysteresis with non-local memory; at standstill the element
    deflections, and hence the friction, are held.

    Parameters
    ----------
    v : numpy.ndarray
        Piston velocity [m/s].
    dt : numpy.ndarray or float
        Step lengths [s].
    fc, fs, vs, kv : numpy.ndarray or float
        Per-sample Stribeck parameters [N], [N], [m/s], [N s/m].
    stiffness, weights : numpy.ndarray
        Element stiffnesses [N/m] and weights [-] (see :func:`maxwell_slip_elements`).
    deltas0 : numpy.ndarray, optional
        Initial element deflections [m] (default all 0: virgin state).

    Returns
    -------
    friction_n, deltas_m : numpy.ndarray
        Friction force per sample [N] and the final element deflections [m].

    References
    ----------
    Lampaert, V., Swevers, J., Al-Bender, F. (2002), Modification of the Leuven
    integrated friction model structure, IEEE TAC 47(4), 683-687,
    doi:10.1109/9.995050. Al-Bender, F., Lampaert, V., Swevers, J. (2005), The
    generalized Maxwell-slip model, IEEE TAC 50(11), 1883-1887,
    doi:10.1109/TAC.2005.858676.
    """
    v_arr = np.ascontiguousarray(v, dtype=np.float64)
    n = v_arr.shape[0]
    k = np.ascontiguousarray(stiffness, dtype=np.float64)
    w = np.ascontiguousarray(weights, dtype=np.float64)
    if k.shape != w.shape or k.ndim != 1:
        raise ValueError("stiffness and weights must be 1-d arrays of the same length")
    deltas = np.zeros_like(k) if deltas0 is None else np.array(deltas0, dtype=np.float64)
    force = np.empty(n)
    _maxwell_slip_kernel(
        v_arr,
        _per_sample(dt, n, "dt"),
        _per_sample(fc, n, "fc"),
        _per_sample(fs, n, "fs"),
        _per_sample(vs, n, "vs"),
        _per_sample(kv, n, "kv"),
        k,
        w,
        deltas,
        force,
    )
    return force, deltas
