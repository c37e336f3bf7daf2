r"""A head rope as a spring on its piston, and a seal that sticks or slides against it.

Quasi-static (the piston's 25 kg against ropes of 10^5-10^6 N/m: eq 1 with
m_p x'' -> 0, i.e. eq 2), rope i pulls its piston with

.. math::
    T_i = a_i\, k(z)\, (s - x_i - c_i), \qquad k(z) = \frac{EA}{h + z}

with EA the hoist description's nominal axial stiffness, h + z the hanging length
(headframe plus depth; :mod:`sims.device` uses the same spring), s the conveyance's
common stretch coordinate, x_i the piston displacement (rod out positive), and two
constants of each rope that the mine does not know: a_i its stiffness relative to the
nominal EA and c_i its length offset (real ropes differ by several percent and by up
to ~10 mm, ``../shared/validation/README.md``). With ``groove_wear`` (contract 4:
unequal drum groove radii) rope i pays out z (1 + dr_i / R) for the drum's z, so its
offset grows with depth, c_i + z dr_i / R (:func:`groove_payout_m`; :mod:`sims.device`
the same, its lengths equal at the pithead).

The seal is elasto-plastic: bristles of stiffness sigma_0 (the hoist's
``bristle_stiffness``) whose force is capped by the eq 17 capacity g(v) (the Stribeck
function, :func:`physics.friction_law.stribeck_g`). It is LuGre (paper eq 15) without
LuGre's drift: under a small back-and-forth motion LuGre's bristle deflection creeps
to 0, so the sensor noise that a quasi-static solution turns into micrometres of
piston motion would drain every seal (a LuGre version of this step did: the stop
frictions of validation day 101 came out near 0 instead of +-2 kN). The drift is
applied apart, along the oil's real motion only (:func:`physics.lugre.lugre_drift`,
:mod:`transforms.seal_drift`). Dupont et al.
(2002) introduced elasto-plastic models for that reason; this is their limit with the
elastic range up to the capacity, the one-element Maxwell-slip model
(:func:`physics.maxwell_slip.maxwell_slip_step`) driven by a force.

    :func:`head_rope_stiffness_n_m` -- k(z) (numba).
    :func:`groove_payout_m` -- a worn groove's extra payout z dr_i / R (numba).
    :func:`bounce_frequency_hz` -- the conveyance's bounce on its ropes.
    :func:`seal_on_rope_step` -- one quasi-static step of a piston between its rope and
    its seal (numba).
    :func:`elements_on_rope_step` -- the same with the seal's Maxwell-slip elements
    (``presliding_hysteresis``, numba).

References
----------
Dupont, P., Hayward, V., Armstrong, B., Altpeter, F. (2002), Single state elastoplastic
friction models, IEEE TAC 47(5), 787-792, doi:10.1109/TAC.2002.1000274.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from numba import njit

#: A float, or an array of them (elementwise).
ArrayOrFloat = TypeVar("ArrayOrFloat", float, np.ndarray)

__all__ = [
    "bounce_frequency_hz",
    "elements_on_rope_step",
    "groove_payout_m",
    "head_rope_stiffness_n_m",
    "seal_on_rope_step",
]


@njit(cache=True, nogil=True, inline="always")
def groove_payout_m(depth_m: float, relative_deviation: float) -> float:
    r"""A rope's length beyond the drum's payout where its groove's radius deviates [m].

    .. math:: o_i = z \, \frac{\Delta r_i}{R}

    The drum turns through z / R for the conveyance's depth z below the pithead, and a
    rope in a groove of radius R + dr_i pays out (R + dr_i) z / R: the ropes' lengths
    drift apart with travel (contract 4, ``groove_wear``; equal at the pithead), and the
    pistons take up the difference. Added to the rope's length offset c_i.

    ``relative_deviation``: dr_i / R (``[drum] groove_radius_deviation`` over
    ``radius``).

    >>> round(groove_payout_m(600.0, 0.5e-3 / 2.0), 6)  # 0.5 mm on a 2 m drum, 600 m down
    0.15
    """
    return depth_m * relative_deviation


@njit(cache=True, nogil=True, inline="always")
def head_rope_stiffness_n_m(axial_stiffness_n: float, hanging_m: float) -> float:
    """Spring rate k = EA / L of a head rope hanging ``hanging_m`` [N/m].

    >>> head_rope_stiffness_n_m(60e6, 650.0)  # the validation hoist at the bottom
    92307.69230769231
    """
    return axial_stiffness_n / hanging_m


def bounce_frequency_hz(
    axial_stiffness_n: float, ropes: int, hanging_m: ArrayOrFloat, mass_kg: ArrayOrFloat
) -> ArrayOrFloat:
    r"""Natural frequency of the conveyance bouncing on its head ropes [Hz].

    One mass on ``ropes`` parallel massless springs (paper section 2.1 neglects the
    ropes' mass; :func:`head_rope_stiffness_n_m`):
    :math:`f = \frac{1}{2\pi}\sqrt{n\,EA / (L\,M)}`. The highest is at the pithead
    (shortest ropes) with the conveyance empty. Elementwise on arrays.

    >>> round(bounce_frequency_hz(60e6, 4, 50.0, 8200.0 + 2 * 6.2 * 620.0), 2)
    2.77
    """
    k = head_rope_stiffness_n_m(axial_stiffness_n, hanging_m)
    frequency = np.sqrt(ropes * k / mass_kg) / (2.0 * np.pi)
    return float(frequency) if np.ndim(frequency) == 0 else frequency


@njit(cache=True, nogil=True, inline="always")
def seal_on_rope_step(
    demand_n: float, friction_n: float, sigma0_n_m: float, stiffness_n_m: float, capacity_n: float
) -> tuple[float, float, float, float, float]:
    r"""A piston's quasi-static step between its rope spring and its elasto-plastic seal.

    The rope's pull beyond the chamber's force, ``demand`` D = a k (s - x - c) - p A
    (eq 2 with T from the rope spring, before the piston moves), is taken by the seal
    and by what resists the piston's step dx (``stiffness`` K: the rope's a k, plus
    damping / dt of the viscous friction and the branch loss, implicit):

    .. math::
        F' + K\, dx = D, \qquad F' = \operatorname{clip}(F + \sigma_0\, dx, -g, g)

    Sticking (|F'| < g) the seal's bristles and the rope share the demand as springs in
    series with the piston; at the capacity the seal slides and the rope takes the rest.

    Parameters
    ----------
    demand_n : float
        D [N].
    friction_n : float
        The bristles' force F before the step [N].
    sigma0_n_m : float
        Bristle stiffness [N/m].
    stiffness_n_m : float
        K [N/m], > 0.
    capacity_n : float
        g >= 0, the Stribeck function at the piston's speed [N].

    Returns
    -------
    dx, friction, slope : float
        The piston's displacement [m], the bristles' force after it [N], and d dx / d D
        [m/N] (what a Newton solve of the closed oil volume needs).
    lo, hi : float
        The demands [N] between which dx, the force and the slope are linear in D with
        that slope (the piece of D this one is on: sticking, or sliding either way; the
        sliding pieces are unbounded): a Newton step that stays within it lands on the
        root of a sum of such steps, with no evaluation after it.

    Examples
    --------
    A demand of 300 N on bristles at 0 with capacity 1000 N sticks: bristles (2e5 N/m)
    and rope (1e5 N/m) share it by stiffness, up to a demand of 1500 N; 3000 N slides
    the seal, which holds its capacity.

    >>> seal_on_rope_step(300.0, 0.0, 2e5, 1e5, 1000.0)
    (0.001, 200.0, 3.3333333333333333e-06, -1500.0, 1500.0)
    >>> seal_on_rope_step(3000.0, 0.0, 2e5, 1e5, 1000.0)
    (0.02, 1000.0, 1e-05, 1500.0, inf)
    """
    dx = (demand_n - friction_n) / (sigma0_n_m + stiffness_n_m)
    force = friction_n + sigma0_n_m * dx
    # the demands at which the sticking bristles reach the capacity either way
    reach = (sigma0_n_m + stiffness_n_m) / sigma0_n_m
    lo = friction_n + (-capacity_n - friction_n) * reach
    hi = friction_n + (capacity_n - friction_n) * reach
    if force > capacity_n:
        slide = 1.0 / stiffness_n_m
        return (demand_n - capacity_n) * slide, capacity_n, slide, hi, np.inf
    if force < -capacity_n:
        slide = 1.0 / stiffness_n_m
        return (demand_n + capacity_n) * slide, -capacity_n, slide, -np.inf, lo
    return dx, force, 1.0 / (sigma0_n_m + stiffness_n_m), lo, hi


@njit(cache=True, nogil=True, inline="always")
def elements_on_rope_step(
    demand_n: float,
    deltas: np.ndarray,
    stiffness: np.ndarray,
    limits: np.ndarray,
    stiffness_n_m: float,
) -> tuple[float, float, float, float]:
    r"""A piston's quasi-static step between its rope spring and a seal of Maxwell-slip
    elements (:func:`physics.maxwell_slip.maxwell_slip_step`, ``presliding_hysteresis``).

    As :func:`seal_on_rope_step`, the demand D is taken by the seal and by what resists
    the step (K), the seal now N elasto-slip elements of stiffness k_j whose deflection
    is held within the limit L_j = alpha_j g / k_j (alpha_j the element's weight, g the
    capacity at the piston's speed):

    .. math::
        \sum_j k_j \operatorname{clip}(\delta_j + dx, -L_j, L_j) + K\, dx = D

    The left side is continuous, piecewise linear and increasing in dx: walked from
    dx = 0 over the elements' break points toward D, exact. One element (k_1 =
    sigma_0, L_1 = g / sigma_0) is :func:`seal_on_rope_step`.

    Parameters
    ----------
    demand_n : float
        D [N].
    deltas : numpy.ndarray
        The elements' deflections before the step [m] (not changed: the step is taken
        with ``maxwell_slip_step(deltas, dx, stiffness, weights, g)``).
    stiffness : numpy.ndarray
        k_j [N/m] (:func:`physics.maxwell_slip.maxwell_slip_elements`).
    limits : numpy.ndarray
        L_j = alpha_j g / k_j [m], >= 0.
    stiffness_n_m : float
        K [N/m], > 0.

    Returns
    -------
    dx, slope : float
        The piston's displacement [m] and d dx / d D [m/N].
    lo, hi : float
        The demands [N] between which dx is linear in D with that slope (the segment of
        the walk D falls on, the last unbounded; the first either way goes on past the
        elements' force before the step where the slope is the same on the other
        side), as :func:`seal_on_rope_step`'s.

    Examples
    --------
    The examples of :func:`seal_on_rope_step` with two elements (1.5e5 and 0.5e5 N/m,
    capacities 500 N each, together the one bristle of 2e5 N/m): 300 N sticks both, as
    there; 1200 N slips the stiffer element at 3.33 mm (1000 N taken), and the softer
    and the rope share the remaining 200 N: 4.67 mm, the seal holding 733 N. That
    segment runs from a demand of 1000 N to 2000 N, where the softer slips too (10 mm).

    >>> k = np.array([1.5e5, 0.5e5])
    >>> limits = 500.0 / k
    >>> elements_on_rope_step(300.0, np.zeros(2), k, limits, 1e5)[:2]
    (0.001, 3.3333333333333333e-06)
    >>> dx, slope, lo, hi = elements_on_rope_step(1200.0, np.zeros(2), k, limits, 1e5)
    >>> round(dx * 1e3, 4), round(1.0 / slope), round(lo, 6), round(hi, 6)
    (4.6667, 150000, 1000.0, 2000.0)
    """
    h0 = 0.0
    for j in range(deltas.shape[0]):
        h0 += stiffness[j] * min(max(deltas[j], -limits[j]), limits[j])
    way = 1.0 if demand_n >= h0 else -1.0
    target = way * (demand_n - h0)  # walked in the mirrored coordinate w = way dx >= 0
    w = 0.0
    gained = 0.0
    first = True
    back_slope, back = stiffness_n_m, np.inf  # the first segment the other way from h0
    while True:
        slope = stiffness_n_m
        nxt = np.inf
        for j in range(deltas.shape[0]):
            e = way * deltas[j]
            enters, leaves = -limits[j] - e, limits[j] - e  # elastic in between
            if enters <= w < leaves:
                slope += stiffness[j]
            if w < enters < nxt:
                nxt = enters
            if w < leaves < nxt:
                nxt = leaves
            if first:  # mirrored: the element enters at -leaves and leaves at -enters
                if -leaves <= 0.0 < -enters:
                    back_slope += stiffness[j]
                if 0.0 < -leaves < back:
                    back = -leaves
                if 0.0 < -enters < back:
                    back = -enters
        if nxt == np.inf or gained + slope * (nxt - w) >= target:
            end = gained + slope * (nxt - w) if nxt < np.inf else np.inf
            # the first segment goes on past h0 where the slope is the same there
            start = -back_slope * back if first and back_slope == slope else gained
            lo, hi = (h0 + start, h0 + end) if way > 0.0 else (h0 - end, h0 - start)
            return way * (w + (target - gained) / slope), 1.0 / slope, lo, hi
        gained += slope * (nxt - w)
        w = nxt
        first = False
