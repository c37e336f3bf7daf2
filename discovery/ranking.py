"""Scoring and ranking the candidates: BIC with the effective sample count.

A candidate's score is the BIC difference against re-tuning alone (Schwarz 1978, Ann.
Stat. 6(2) 461-464), ``N_eff ln(RSS_0 / RSS_c) - k_c ln N_eff``, with ``N_eff = N / tau``
and tau the residual's integrated autocorrelation time (:func:`autocorrelation_time`;
1 for white noise). :func:`rank_candidates` orders the candidates by score with what each
explains and its bootstrap share; :func:`separating_excitation` says what would separate two.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from discovery.layout import EntryLayout
from discovery.library import EffectLibrary

__all__ = ["autocorrelation_time", "rank_candidates", "score_bic", "separating_excitation"]


def autocorrelation_time(resid: np.ndarray, layout: EntryLayout, max_lag: int = 40) -> float:
    """Integrated autocorrelation time 1 + 2 sum(rho_l), summed to the first rho < 0.05."""
    num = np.zeros(max_lag + 1)
    den = 0.0
    for k in np.unique(layout.trip):
        for i in np.unique(layout.sensor):
            sel = (layout.trip == k) & (layout.sensor == i)
            x = resid[sel]
            if x.size <= max_lag + 2:
                continue
            x = x - x.mean()
            den += float(x @ x)
            for lag in range(1, max_lag + 1):
                num[lag] += float(x[:-lag] @ x[lag:])
    if den <= 0:
        return 1.0
    rho = num / den
    tau = 1.0
    for lag in range(1, max_lag + 1):
        if rho[lag] < 0.05:
            break
        tau += 2.0 * rho[lag]
    return float(tau)


def score_bic(scores: dict[str, dict[str, Any]], rss0: float, n_eff: float) -> None:
    """Set each candidate's ``dbic`` (BIC difference against re-tuning only)."""
    for sc in scores.values():
        sc["dbic"] = n_eff * np.log(rss0 / sc["rss"]) - sc["k"] * np.log(n_eff)


def rank_candidates(
    scores: dict[str, dict[str, Any]], rss0: float, n_entries: int, share: dict[str, float]
) -> list[dict[str, Any]]:
    """The scored candidates, best score first: ``effect``, ``score`` (BIC difference),
    ``explained_pa`` (RMS of the residual it explains), ``bootstrap_share``."""
    return sorted(
        (
            {
                "effect": c,
                "score": round(float(sc["dbic"]), 1),
                "explained_pa": round(float(np.sqrt(max(rss0 - sc["rss"], 0.0) / n_entries)), 1),
                "bootstrap_share": share[c],
            }
            for c, sc in scores.items()
        ),
        key=lambda d: -d["score"],
    )


def separating_excitation(lib: EffectLibrary, a: str, b: str) -> str:
    return f"to separate {a} from {b}: for {a}, {lib[a].excitation}; for {b}, {lib[b].excitation}"
