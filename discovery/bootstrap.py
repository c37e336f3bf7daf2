"""Stability of the winner: trips resampled with replacement (Efron 1979).

Each resample is a vector of per-trip weights (multinomial, as many draws as trips);
its fits come from the per-trip normal equations (:mod:`discovery.normal_equations`)
without touching the entries. The winner of a resample is the candidate with the
largest positive BIC difference at the resample's effective sample count, or none;
the winner's share of the resamples is the reported confidence.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from discovery.normal_equations import NormalEquations, solve_normal
from schemas.effects import NO_EFFECT

__all__ = ["bootstrap_shares", "trip_weights"]


def trip_weights(seed: int, m: int, bootstrap: int) -> np.ndarray:
    """(bootstrap, m) per-trip weights of the resamples (seeded)."""
    rng = np.random.default_rng(seed)
    return rng.multinomial(m, np.full(m, 1.0 / m), size=bootstrap).astype(float)


def bootstrap_shares(
    ne0: NormalEquations,
    scores: dict[str, dict[str, Any]],
    weights: np.ndarray,
    trip: np.ndarray,
    n_eff: float,
    n_entries: int,
) -> dict[str, float]:
    """Share of the resamples each candidate (and ``none``) wins.

    ``ne0`` is re-tuning alone, ``scores[c]["ne"]`` candidate c's normal equations and
    ``scores[c]["k"]`` its number of coordinates; ``trip`` the trip of each entry.
    """
    m = weights.shape[1]
    bootstrap = weights.shape[0]
    wins = {c: 0 for c in scores}
    wins[NO_EFFECT] = 0
    for w in weights:
        r0b, _ = solve_normal(ne0, w)
        nb = n_eff * float(w @ np.bincount(trip, minlength=m)) / n_entries
        best_b, best_v = NO_EFFECT, 0.0
        for c, sc in scores.items():
            rb, _ = solve_normal(sc["ne"], w)
            v = nb * np.log(r0b / rb) - sc["k"] * np.log(max(nb, 2.0))
            if v > best_v:
                best_b, best_v = c, v
        wins[best_b] += 1
    return {c: wins[c] / bootstrap for c in wins}
