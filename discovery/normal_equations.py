"""Least squares with per-trip normal equations, so a trip bootstrap costs no refit.

The fits of discovery (re-tuning, candidate scoring, Gauss-Newton steps) are linear
least squares ``x b = target`` over the flat scored entries (:mod:`discovery.layout`).
Their normal equations are kept per trip (:class:`NormalEquations`), so a resample of the trips
with weights ``w`` is solved from ``sum_k w_k X_k^T X_k`` without touching the entries
again (:func:`solve_normal`); columns are scaled to unit RMS and re-tuned coordinates carry a
Gaussian prior (ridge).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["NormalEquations", "normal_equations", "solve_normal"]


@dataclass(frozen=True)
class NormalEquations:
    gram: np.ndarray  # (m, p, p) per trip
    rhs: np.ndarray  # (m, p)
    tt: np.ndarray  # (m,)
    scale: np.ndarray  # (p,) column scales
    penalty: np.ndarray  # (p,) ridge on the scaled coefficients (Gaussian prior)


def normal_equations(
    x: np.ndarray,
    target: np.ndarray,
    trip: np.ndarray,
    m: int,
    penalty: np.ndarray | None = None,
) -> NormalEquations:
    """Per-trip normal equations of ``x b = target`` with columns scaled to unit RMS.

    ``penalty`` (per column, in target units squared per coefficient unit squared:
    sigma^2 / prior_sd^2) is the Gaussian prior of re-tuned coordinates.
    """
    scale = np.sqrt(np.mean(x**2, axis=0)) if x.size else np.zeros(0)
    scale = np.where(scale > 0, scale, 1.0)
    xs = x / scale
    p = xs.shape[1]
    gram = np.zeros((m, p, p))
    rhs = np.zeros((m, p))
    tt = np.zeros(m)
    for k in range(m):
        sel = trip == k
        xk, tk = xs[sel], target[sel]
        gram[k] = xk.T @ xk
        rhs[k] = xk.T @ tk
        tt[k] = tk @ tk
    pen = np.zeros(p) if penalty is None else np.asarray(penalty, float) / scale**2
    return NormalEquations(gram, rhs, tt, scale, pen)


def solve_normal(ne: NormalEquations, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Weighted (per trip) ridge solution: data RSS and coefficients (column units)."""
    g = np.tensordot(w, ne.gram, axes=1)
    b = w @ ne.rhs
    tt = float(w @ ne.tt)
    p = g.shape[0]
    if p == 0:
        return tt, np.zeros(0)
    lam = 1e-9 * max(np.trace(g) / p, 1e-30)
    beta = np.linalg.solve(g + np.diag(ne.penalty * w.sum() / w.size) + lam * np.eye(p), b)
    rss = tt - 2.0 * float(b @ beta) + float(beta @ g @ beta)
    return max(rss, 1e-30), beta / ne.scale
