"""Presliding hysteresis of the seal: Maxwell-slip elements (the "Leuven" idea).

Functions
    :func:`maxwell_slip_step` -- one displacement increment of N elasto-slip elements
    with Stribeck-scaled capacities (numba).
    :func:`maxwell_slip_elements` -- element stiffnesses and weights from the total
    presliding stiffness.
    :func:`maxwell_slip_virgin` -- element deflections that hold a given force after a
    monotone motion from rest (numba).
    :func:`maxwell_slip_friction` -- the step over a sampled velocity record, plus the
    viscous term (the C -> infinity limit of Generalized Maxwell-Slip).

Not printed in the paper: its eq 15 is LuGre (:mod:`physics.lugre`, see the erratum
there); the Leuven model it names adds this hysteresis with non-local memory.

References
----------
Lampaert, V., Swevers, J., Al-Bender, F. (2002), Modification of the Leuven integrated
friction model structure, IEEE TAC 47(4), 683-687, doi:10.1109/9.995050.
Al-Bender, F., Lampaert, V., Swevers, J. (2005), The generalized Maxwell-slip model,
IEEE TAC 50(11), 1883-1887, doi:10.1109/TAC.2005.858676.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics._samples import per_sample
from physics.friction_law import stribeck_g

__all__ = [
    "maxwell_slip_elements",
    "maxwell_slip_friction",
    "maxwell_slip_step",
    "maxwell_slip_virgin",
]


@njit(cache=True, nogil=True, inline="always")
def maxwell_slip_step(
    deltas: np.ndarray, dx: float, stiffness: np.ndarray, weights: np.ndarray, g: float
) -> float:
    r"""Advance N Maxwell-slip elements by a displacement increment; return their force.

    Element j is a massless spring of stiffness k_j whose end slides once its force
    reaches the capacity w_j = alpha_j g (Lampaert et al. 2002; g the Stribeck function
    of the sliding velocity, :func:`physics.friction_law.stribeck_g`):

    .. math::
        \delta_j \leftarrow \operatorname{clip}(\delta_j + \Delta x,
        -\alpha_j g/k_j, \alpha_j g/k_j),\qquad F = \sum_j k_j \delta_j

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
    weights : numpy.ndarray
        Element weights alpha_j [-] (sum 1).
    g : float
        Stribeck function at the step's velocity [N], >= 0 (at rest g = Fs).

    Returns
    -------
    float
        Total hysteresis force [N], bounded by g (the viscous term is not included).

    Examples
    --------
    >>> d = np.zeros(2)
    >>> maxwell_slip_step(d, 1e-6, np.array([1e6, 1e6]), np.array([0.2, 0.8]), 2.5)
    1.5
    >>> maxwell_slip_step(d, 1e-6, np.array([1e6, 1e6]), np.array([0.2, 0.8]), 2.5)
    2.5
    """
    total = 0.0
    for j in range(deltas.shape[0]):
        limit = weights[j] * g / stiffness[j]
        d = deltas[j] + dx
        if d > limit:
            d = limit
        elif d < -limit:
            d = -limit
        deltas[j] = d
        total += stiffness[j] * d
    return total


@njit(cache=True, nogil=True)
def maxwell_slip_virgin(
    force_n: float, deltas: np.ndarray, stiffness: np.ndarray, weights: np.ndarray, g: float
) -> float:
    r"""Set the elements' deflections to hold ``force_n`` on the virgin curve; return it.

    The state a monotone motion from rest leaves at that force (Lampaert et al. 2002:
    the virgin curve F(u) = sum_j k_j min(|u|, alpha_j g / k_j) sgn u): every element
    moved by the same u, those whose capacity it passed saturated. A force beyond the
    capacity g is taken as g. Where nothing tells the elements' history (a record's
    start) it is the state with the fewest turning points.

    Parameters
    ----------
    force_n : float
        The force to hold [N].
    deltas : numpy.ndarray
        Element deflections [m]; written.
    stiffness, weights : numpy.ndarray
        k_j [N/m] and alpha_j [-] (:func:`maxwell_slip_elements`).
    g : float
        The capacity [N], >= 0.

    Returns
    -------
    float
        The force the elements hold, sum k_j delta_j [N] (``force_n`` within +-g).

    >>> d = np.zeros(2)
    >>> maxwell_slip_virgin(2.0, d, np.array([1e6, 1e6]), np.array([0.2, 0.8]), 2.5)
    2.0
    >>> d.tolist()   # u = 1.25 um: the first element (limit 0.5 um) has slipped
    [5e-07, 1.5e-06]
    """
    remaining = min(abs(force_n), g)
    u = 0.0
    while remaining > 0.0:
        slope = 0.0
        nxt = np.inf
        for j in range(deltas.shape[0]):
            limit = weights[j] * g / stiffness[j]
            if limit > u:
                slope += stiffness[j]
                nxt = min(nxt, limit)
        if slope == 0.0:
            break
        if slope * (nxt - u) >= remaining:
            u += remaining / slope
            break
        remaining -= slope * (nxt - u)
        u = nxt
    sign = 1.0 if force_n >= 0.0 else -1.0
    total = 0.0
    for j in range(deltas.shape[0]):
        deltas[j] = sign * min(u, weights[j] * g / stiffness[j])
        total += stiffness[j] * deltas[j]
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
def _maxwell_slip_record(
    v, dt, fc, fs, vs, kv, stiffness, weights, deltas, force_out
):  # pragma: no cover - numba
    for i in range(v.shape[0]):
        if v[i] != v[i]:  # NaN velocity: hold the elements, no force
            force_out[i] = np.nan
            continue
        # at standstill g(0) = Fs exactly: no exp needed
        g = fs[i] if v[i] == 0.0 else stribeck_g(v[i], fc[i], fs[i], vs[i])
        force_out[i] = maxwell_slip_step(deltas, v[i] * dt[i], stiffness, weights, g) + kv[i] * v[i]


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

    Per sample i (the timing convention of :func:`physics.lugre.lugre_friction`), the
    displacement increment ``v[i] dt[i]`` is applied to the elements
    (:func:`maxwell_slip_step`) with capacities ``w_j = alpha_j g(v[i])``, and the
    viscous term is added:

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

    >>> k, w = maxwell_slip_elements(4, 1e6)
    >>> f, _ = maxwell_slip_friction(np.array([1e-3, 1e-3, 0.0]), 1.0, 1.0, 1.5, 0.01, 0.0, k, w)
    >>> [round(float(x), 6) for x in f]   # saturated at g(1 mm/s), then held at rest
    [1.495025, 1.495025, 1.495025]
    """
    v_arr = np.ascontiguousarray(v, dtype=np.float64)
    n = v_arr.shape[0]
    k = np.ascontiguousarray(stiffness, dtype=np.float64)
    w = np.ascontiguousarray(weights, dtype=np.float64)
    if k.shape != w.shape or k.ndim != 1:
        raise ValueError("stiffness and weights must be 1-d arrays of the same length")
    deltas = np.zeros_like(k) if deltas0 is None else np.array(deltas0, dtype=np.float64)
    force = np.empty(n)
    _maxwell_slip_record(
        v_arr,
        per_sample(dt, n, "dt"),
        per_sample(fc, n, "fc"),
        per_sample(fs, n, "fs"),
        per_sample(vs, n, "vs"),
        per_sample(kv, n, "kv"),
        k,
        w,
        deltas,
        force,
    )
    return force, deltas
