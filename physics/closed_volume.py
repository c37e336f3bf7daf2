"""The closed oil volume of the connection device (paper eq 5, NOTES.md).

The four chambers, pipes and manifold hold one closed volume of oil V. Continuity
(eq 5, dV = V / beta dp) with the effective bulk modulus of oil with entrained air
(:func:`physics.oil.effective_bulk_modulus_at`) says how far the pistons move together
when the common pressure changes: :func:`common_mode_displacement`, resumable block by
block.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.oil import (
    ATMOSPHERIC_PRESSURE_PA,
    effective_bulk_modulus,
    effective_bulk_modulus_at,
)
from schemas.hoist import HoistDescription

__all__ = ["COMMON_MODE_STATE_SIZE", "common_mode_displacement", "common_mode_per_pa"]


def common_mode_displacement(
    p_mean_pa: np.ndarray,
    segment_id: np.ndarray,
    hoist: HoistDescription,
    *,
    state: np.ndarray | None = None,
) -> np.ndarray:
    r"""Piston displacement implied by oil compression when x is not logged [m].

    The four chambers, pipes and manifold are one closed oil volume V, so a change of
    the common pressure dp moves every piston by the same amount (NOTES.md):

    .. math::
        n A_{bore}\, dx = \frac{V}{\beta_e(p)}\, dp

    with beta_e the effective bulk modulus (entrained air included,
    :func:`physics.oil.effective_bulk_modulus`). A rising load squeezes oil out of
    the chambers, so x grows (rod out) while p rises. Differential piston motion is not
    observable this way and is taken as zero. Integrated per segment from 0.
    ``state``: carried from the previous block of the same record (None: the first).
    """
    p = np.ascontiguousarray(p_mean_pa, dtype=np.float64)
    x = np.empty_like(p)
    if p.size:
        _common_mode_kernel(
            p,
            np.ascontiguousarray(segment_id, dtype=np.int64),
            *_common_mode_constants(hoist),
            x,
            np.zeros(COMMON_MODE_STATE_SIZE) if state is None else state,
        )
    return x


def common_mode_per_pa(p_pa: np.ndarray | float, hoist: HoistDescription) -> np.ndarray:
    r"""Each piston's common motion per pascal of the common pressure [m/Pa]: eq 5's
    :math:`V / (\beta_e(p)\, n A_{bore})` at ``p_pa`` (at least 1 bar, 10 bar where
    unknown, as :func:`common_mode_displacement` takes it).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> f"{float(common_mode_per_pa(4e6, load_hoist(EXAMPLE_HOIST))):.3g}"
    '1.91e-10'
    """
    volume, n_area, oil = _common_mode_constants(hoist)
    p = np.fmax(np.nan_to_num(np.asarray(p_pa, dtype=np.float64), nan=1e6), 1e5)
    beta = effective_bulk_modulus(p, oil[0], oil[1], p_ref_pa=oil[2])
    return volume / (n_area * beta)


def _common_mode_constants(hoist: HoistDescription) -> tuple[float, float, np.ndarray]:
    """Oil volume [m3], n A_bore [m2] and (beta_liquid, air fraction, p_ref) of the hoist."""
    return (
        float(hoist.oil_volume_m3),
        hoist.ropes_n * hoist.cylinders.bore_area_m2,
        np.array([hoist.oil.bulk_modulus_pa, hoist.oil.air_fraction, ATMOSPHERIC_PRESSURE_PA]),
    )


#: Length of the resumable state of :func:`common_mode_displacement`.
COMMON_MODE_STATE_SIZE = 6


@njit(cache=True, nogil=True)
def _common_mode_kernel(p, segment_id, volume, n_area, oil, x, state):  # pragma: no cover - numba
    """n A dx = V / beta_e(p) dp integrated per segment from 0 (:func:`common_mode_displacement`).

    beta_e at max(p, 1 bar), 10 bar where p is unknown (NaN), isothermal
    (:func:`physics.oil.effective_bulk_modulus_at`; ``oil`` = liquid bulk modulus,
    air fraction, reference pressure). The arithmetic of the array version: a running
    sum over the whole record, minus its value at the segment's start. ``state`` =
    [ran, continues segment, running sum, its value and dx at the segment's start,
    last p] (all 0 before the first call).
    """
    ran = state[0] != 0.0
    resume = ran and state[1] != 0.0
    total, total_at_start, dx_at_start, p_last = state[2], state[3], state[4], state[5]
    for i in range(p.shape[0]):
        p_beta = p[i]
        if np.isnan(p_beta):
            p_beta = 1e6
        elif np.isinf(p_beta):
            p_beta = 1.7976931348623157e308 if p_beta > 0 else -1.7976931348623157e308
        beta = effective_bulk_modulus_at(max(p_beta, 1e5), oil[0], oil[1], oil[2], 1.0)
        start = (i == 0 and not resume) or (i > 0 and segment_id[i] != segment_id[i - 1])
        dp = 0.0
        if not start:
            dp = p[i] - (p[i - 1] if i > 0 else p_last)
            if not np.isfinite(dp):
                dp = 0.0
        dx = volume / (n_area * beta) * dp
        total = dx if (i == 0 and not ran) else total + dx
        if start:
            total_at_start = total
            dx_at_start = dx
        x[i] = total - total_at_start + dx_at_start
    if p.shape[0]:
        state[0] = 1.0
        state[2], state[3], state[4], state[5] = total, total_at_start, dx_at_start, p[-1]
