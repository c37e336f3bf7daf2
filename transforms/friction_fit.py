"""Fitting seal-friction parameters: Stribeck curves per pressure, lines in pressure.

Straight lines (paper eq 17 form)
    :mod:`transforms.friction_lines`, re-exported here: :func:`fit_line` (weighted least
    squares a + b p), :func:`fit_table1` and :func:`compare_with_eq17` (paper Table 1
    against the printed eq 17, :data:`EQ17`).

Stribeck curve at one pressure (paper eq 16/18)
    :func:`fit_stribeck` -- Fc, Fs, vs, Kv by ``scipy.optimize.least_squares`` with
    1-sigma uncertainties from the Jacobian.

Calibration
    :func:`fit_friction_law` -- per-pressure Stribeck fits -> weighted lines in
    pressure -> a :class:`~schemas.hoist.FrictionLaw` and the line fits (residuals).

No file reads here: callers pass frames and arrays in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from physics.friction_law import stribeck_friction
from schemas.hoist import FrictionLaw
from transforms.friction_lines import (
    EQ17,
    TABLE1_COLUMNS,
    LinearFit,
    compare_with_eq17,
    fit_line,
    fit_table1,
)

# the lines are part of this module's interface (transforms.friction_lines defines them)
__all__ = [
    "EQ17",
    "TABLE1_COLUMNS",
    "LinearFit",
    "StribeckFit",
    "compare_with_eq17",
    "fit_friction_law",
    "fit_line",
    "fit_stribeck",
    "fit_table1",
]


@dataclass(frozen=True)
class StribeckFit:
    """Stribeck-curve parameters at one pressure with 1-sigma uncertainties.

    ``fc``, ``fs`` [force unit of the data], ``vs`` [speed unit], ``kv`` [force /
    speed]; ``sigma`` the matching standard errors (fc, fs, vs, kv); ``residuals``
    per point; ``rms`` the residual RMS; ``success`` and ``message`` from the solver.
    """

    fc: float
    fs: float
    vs: float
    kv: float
    sigma: tuple[float, float, float, float]
    residuals: np.ndarray
    rms: float
    success: bool
    message: str


def _initial_guess(speed: np.ndarray, force: np.ndarray) -> np.ndarray:
    order = np.argsort(speed)
    s, f = speed[order], force[order]
    upper = slice(s.size // 2, None)
    kv0, fc0 = np.polyfit(s[upper], f[upper], 1) if s.size >= 4 else (0.0, np.median(f))
    kv0, fc0 = max(kv0, 0.0), max(fc0, 1e-3)
    fs0 = max(float(np.max(f[: max(s.size // 5, 1)])), fc0 * 1.01)
    vs0 = float(np.median(s[: max(s.size // 3, 1)]))
    return np.array([fc0, fs0, max(vs0, 1e-3), kv0])


def fit_stribeck(v: np.ndarray, friction: np.ndarray) -> StribeckFit:
    r"""Fit the Stribeck curve (paper eq 16/18) to steady (velocity, friction) points.

    .. math::
        F(v) = \left[F_c + (F_s - F_c) e^{-(v/v_s)^2}\right]\operatorname{sgn}(v)
        + K_v v

    Points of both directions are used together (friction is taken as odd in v).
    Data are scaled by max|v| and max|F| for conditioning; ``least_squares``
    (trust-region reflective, bounds Fc, Fs, Kv >= 0, vs > 0). Covariance
    s^2 (J^T J)^-1 at the solution, s^2 the residual variance with 4 parameters.

    Parameters
    ----------
    v : numpy.ndarray
        Steady sliding velocities (both signs, no zeros) [any speed unit, e.g. m/s].
    friction : numpy.ndarray
        Friction force at each velocity [any force unit, e.g. N].

    Returns
    -------
    StribeckFit

    Notes
    -----
    vs is only identifiable if there are points around and below vs (the curve's
    drop); without them its uncertainty is large, which the fit reports.
    """
    v = np.asarray(v, dtype=np.float64)
    f = np.asarray(friction, dtype=np.float64)
    keep = (v != 0.0) & np.isfinite(v) & np.isfinite(f)
    v, f = v[keep], f[keep]
    if v.size < 5:
        raise ValueError(f"fit_stribeck: need at least 5 points with v != 0, got {v.size}")
    v_scale = float(np.max(np.abs(v)))
    f_scale = float(np.max(np.abs(f)))
    vn, fn = v / v_scale, f / f_scale
    x0 = _initial_guess(np.abs(vn), fn * np.sign(vn))

    def residual(params: np.ndarray) -> np.ndarray:
        fc, fs, vs, kv = params
        return stribeck_friction(vn, fc, fs, vs, kv) - fn

    result = optimize.least_squares(
        residual,
        x0,
        bounds=([0.0, 0.0, 1e-9, 0.0], [np.inf, np.inf, np.inf, np.inf]),
        x_scale="jac",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
    )
    dof = max(v.size - 4, 1)
    s2 = float(np.sum(result.fun**2)) / dof
    jac = result.jac
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
        sig = np.sqrt(np.abs(np.diag(cov)))
    except np.linalg.LinAlgError:
        sig = np.full(4, np.inf)
    scale = np.array([f_scale, f_scale, v_scale, f_scale / v_scale])
    fc, fs, vs, kv = (result.x * scale).tolist()
    sigma = tuple((sig * scale).tolist())
    residuals = result.fun * f_scale
    return StribeckFit(
        fc=fc,
        fs=fs,
        vs=vs,
        kv=kv,
        sigma=sigma,  # type: ignore[arg-type]
        residuals=residuals,
        rms=float(np.sqrt(np.mean(residuals**2))),
        success=bool(result.success),
        message=str(result.message),
    )


def fit_friction_law(
    p_pa: Sequence[float] | np.ndarray,
    fits: Sequence[StribeckFit],
    *,
    bristle_stiffness_n_m: float,
    bristle_damping_n_s_m: float,
    presliding_elements: int,
) -> tuple[FrictionLaw, dict[str, LinearFit]]:
    """Weighted straight lines in pressure through per-pressure Stribeck fits (eq 17).

    Each of Fc, Fs, vs, Kv is fitted as a + b p by :func:`fit_line` with weights
    1/sigma^2 from the per-pressure fits (uncertainties rescaled by the scatter about
    the line, so an over-optimistic Jacobian sigma cannot hide misfit).

    Parameters
    ----------
    p_pa : sequence of float
        Chamber pressure of each fit [Pa].
    fits : sequence of StribeckFit
        Per-pressure fits in SI (N, m/s, N s/m).
    bristle_stiffness_n_m, bristle_damping_n_s_m, presliding_elements
        Passed through into the :class:`FrictionLaw` (not fitted here).

    Returns
    -------
    law : FrictionLaw
        SI intercepts and slopes per Pa.
    lines : dict of str to LinearFit
        Keys ``coulomb_n``, ``static_n``, ``stribeck_speed_m_s``, ``viscous_n_s_m``,
        with residuals per pressure.
    """
    p = np.asarray(p_pa, dtype=np.float64)
    if p.size != len(fits):
        raise ValueError("fit_friction_law: one pressure per fit")
    lines: dict[str, LinearFit] = {}
    for k, name in enumerate(("coulomb_n", "static_n", "stribeck_speed_m_s", "viscous_n_s_m")):
        values = np.array([(f.fc, f.fs, f.vs, f.kv)[k] for f in fits])
        sigma = np.array([f.sigma[k] for f in fits])
        usable = np.isfinite(sigma) & (sigma > 0)
        lines[name] = fit_line(p, values, sigma if usable.all() else None)
    law = FrictionLaw(
        coulomb_n=(lines["coulomb_n"].intercept, lines["coulomb_n"].slope),
        static_n=(lines["static_n"].intercept, lines["static_n"].slope),
        stribeck_speed_m_s=(
            lines["stribeck_speed_m_s"].intercept,
            lines["stribeck_speed_m_s"].slope,
        ),
        viscous_n_s_m=(lines["viscous_n_s_m"].intercept, lines["viscous_n_s_m"].slope),
        bristle_stiffness_n_m=bristle_stiffness_n_m,
        bristle_damping_n_s_m=bristle_damping_n_s_m,
        presliding_elements=presliding_elements,
    )
    return law, lines
