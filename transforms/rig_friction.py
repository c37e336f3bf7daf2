"""Seal friction from friction-rig recordings: force balance, steady steps, Stribeck fits.

The friction test of paper section 4.2.1 drives the tested cylinder at controlled
speeds against a set back-pressure at oil pressures 2..12 MPa. At a steady speed the
LuGre state (paper eq 15) is at rest (dz/dt = 0), so the measured friction is the
steady-state Stribeck curve (eq 16/18)::

    F(v) = [Fc + (Fs - Fc) exp(-(v/vs)^2)] sgn(v) + Kv v

These are the steps from rig samples (contract 3) to that curve per pressure level, the
analogue of paper Table 1; the lines in pressure (eq 17) are
:func:`transforms.friction_fit.fit_friction_law`.

    :func:`seal_friction_samples` -- piston velocity and acceleration from displacement
    (Savitzky-Golay derivatives) and the seal friction per sample: the piston force
    balance (eq 1) solved for friction,
    ``F = p_rodless A_bore - p_rod (A_bore - A_rod) - m a``.
    :func:`steady_steps` -- per ``/rig/step``: the steady part (acceleration and
    bristle transient dropped), its mean speed and mean friction.
    :func:`fit_pressure_levels` -- a Stribeck fit per pressure level with 1-sigma
    uncertainties: the analogue of Table 1.

Everything is SI (Pa, m, m/s, N, N s/m). No file reads here: ``pipelines.calibrate``
reads the rig lake and passes the samples in.
"""

from __future__ import annotations

import math

import numpy as np
import polars as pl
from scipy.ndimage import uniform_filter1d
from scipy.signal import savgol_filter

from physics.tension import annulus_area_m2, bore_area_m2
from physics.white_noise import MAD_TO_SIGMA
from transforms.friction_fit import StribeckFit, fit_stribeck

__all__ = ["fit_pressure_levels", "seal_friction_samples", "steady_steps"]


def _odd(n: float) -> int:
    """An odd Savitzky-Golay window of about ``n`` samples, at least 5."""
    k = max(round(n), 5)
    return k if k % 2 else k + 1


def _derivatives(
    t_all: np.ndarray, x_all: np.ndarray, block: np.ndarray, *, smooth_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Savitzky-Golay velocity and acceleration of ``x_all`` per contiguous ``block``.

    Quadratic fits over windows of ``smooth_s`` (velocity) and ``2 smooth_s``
    (acceleration); NaN in blocks shorter than 11 samples or with non-finite x.
    """
    velocity = np.full(t_all.size, np.nan)
    acceleration = np.full(t_all.size, np.nan)
    bounds = np.flatnonzero(np.diff(block)) + 1
    for lo, hi in zip(np.r_[0, bounds], np.r_[bounds, t_all.size], strict=True):
        t, x = t_all[lo:hi], x_all[lo:hi]
        if t.size < 11 or not np.isfinite(x).all():
            continue
        dt_s = float(np.median(np.diff(t)))
        w1 = min(_odd(smooth_s / dt_s), t.size - (1 - t.size % 2))
        w2 = min(_odd(2 * smooth_s / dt_s), t.size - (1 - t.size % 2))
        velocity[lo:hi] = savgol_filter(x, w1, 2, deriv=1, delta=dt_s, mode="interp")
        acceleration[lo:hi] = savgol_filter(x, w2, 2, deriv=2, delta=dt_s, mode="interp")
    return velocity, acceleration


def seal_friction_samples(
    samples: pl.DataFrame,
    *,
    bore_m: float,
    rod_m: float,
    moving_mass_kg: float,
    smooth_s: float = 0.05,
    max_gap_s: float = 0.5,
) -> pl.DataFrame:
    r"""Piston velocity, acceleration and seal friction per rig sample (contract 3).

    The piston force balance (paper eq 1) solved for the seal friction:

    .. math::
        F = p_{rodless} A_{bore} - p_{rod} (A_{bore} - A_{rod}) - m \ddot x

    Velocity and acceleration are Savitzky-Golay derivatives of ``x_m`` (quadratic,
    windows ``smooth_s`` and ``2 smooth_s``), computed per contiguous block (a gap
    longer than ``max_gap_s`` starts a new block: another recording). The sign
    convention is that of :mod:`physics.friction_law`: friction is positive while the
    rod moves out (v > 0), opposing the motion.

    Parameters
    ----------
    samples : polars.DataFrame
        ``rig_samples`` rows (schema :data:`schemas.tables.RIG_SAMPLES`), any order.
    bore_m, rod_m : float
        Piston and rod diameters [m].
    moving_mass_kg : float
        Piston, rod and attached mass [kg].
    smooth_s : float
        Derivative window [s].
    max_gap_s : float
        Longest time gap inside one recording [s].

    Returns
    -------
    polars.DataFrame
        The samples sorted by time plus ``t_s`` (from the first sample), ``block``,
        ``segment`` (a new one at each step change or gap), ``v_m_s``, ``a_m_s2`` and
        ``friction_n``.

    Raises
    ------
    ValueError
        ``samples`` is empty.
    """
    if samples.height == 0:
        raise ValueError("no rig samples")
    area_bore = bore_area_m2(bore_m)
    area_annulus = annulus_area_m2(bore_m, rod_m)
    frame = samples.sort("time_utc").with_columns(
        t_s=(pl.col("time_utc") - pl.col("time_utc").first()).dt.total_microseconds() / 1e6
    )
    gap = (pl.col("t_s").diff() > max_gap_s).fill_null(False)
    changed = pl.col("step").ne_missing(pl.col("step").shift()).fill_null(False)
    frame = frame.with_columns(
        block=gap.cum_sum().cast(pl.Int64),
        segment=(gap | changed).cum_sum().cast(pl.Int64),
        x_filled=pl.col("x_m").interpolate().forward_fill().backward_fill(),
    )
    velocity, acceleration = _derivatives(
        frame["t_s"].to_numpy(), frame["x_filled"].to_numpy(), frame["block"].to_numpy(),
        smooth_s=smooth_s,
    )  # fmt: skip
    return (
        frame.drop("x_filled")
        .with_columns(
            v_m_s=pl.Series(velocity),
            a_m_s2=pl.Series(acceleration),
        )
        .with_columns(
            friction_n=pl.col("p_rodless_pa") * area_bore
            - pl.col("p_rod_pa") * area_annulus
            - moving_mass_kg * pl.col("a_m_s2")
        )
    )


_STEP_SCHEMA = {
    "segment": pl.Int64,
    "step": pl.Int32,
    "pressure_setpoint_pa": pl.Float64,
    "velocity_setpoint_m_s": pl.Float64,
    "steady_start_s": pl.Float64,
    "steady_end_s": pl.Float64,
    "samples": pl.Int64,
    "p_rodless_pa": pl.Float64,
    "velocity_m_s": pl.Float64,
    "friction_n": pl.Float64,
    "friction_sem_n": pl.Float64,
}


def _steady_start(
    v: np.ndarray, force: np.ndarray, window: int, velocity_tol: float, force_tol: float
) -> int:
    """First index from which speed and friction stay at their end-of-step values."""
    tail = slice(3 * v.size // 4, None)
    v_end = float(np.median(v[tail]))
    f_end = float(np.mean(force[tail]))
    f_smooth = uniform_filter1d(force, window, mode="nearest")
    # the median of |d|, not the MAD about d's median of physics.white_noise.
    # difference_noise_sigma: that moved the 2 MPa Coulomb fit of
    # tests/pipelines/test_calibrate.py by 19 % (session 38, not examined further)
    noise = float(np.median(np.abs(np.diff(force)))) / (0.6745 * math.sqrt(2.0))
    band = max(5.0 * noise / math.sqrt(window), force_tol * abs(f_end))
    v_noise = MAD_TO_SIGMA * float(np.median(np.abs(v[tail] - v_end)))
    v_band = max(velocity_tol * abs(v_end), 5.0 * v_noise)
    unsettled = (np.abs(v - v_end) > v_band) | (np.abs(f_smooth - f_end) > band)
    bad = np.flatnonzero(unsettled)
    return int(bad[-1]) + 1 if bad.size else 0


#: A moving step whose measured speed is below this fraction of its setpoint (or the
#: other way) stalled: static friction held the piston, there is no sliding friction to
#: read (kept, its speed of ~1e-15 m/s forced the Stribeck fit through -F_s at zero).
STALLED_FRACTION = 0.2


def steady_steps(
    frame: pl.DataFrame,
    *,
    smooth_s: float = 0.05,
    velocity_tol: float = 0.05,
    force_tol: float = 0.01,
    min_steady_s: float = 0.1,
) -> pl.DataFrame:
    """Mean speed and friction over the steady part of each moving step (paper 4.2.1).

    A step (segment of :func:`seal_friction_samples`) with a non-zero velocity setpoint
    starts with the speed ramp and the bristle transient of the LuGre state (eq 15: z
    relaxes over a travel of about F/sigma0). Its steady part is where, from some sample
    on to the end of the step, the smoothed speed stays within ``velocity_tol`` of the
    end-of-step speed (median of the last quarter; or within 5 robust standard
    deviations of the speed there, whichever is wider) and the ``smooth_s`` running mean
    of the friction within max(5 standard errors, ``force_tol`` relative) of the
    end-of-step friction (mean of the last quarter). What is left of the transient
    biases the step mean far less than the band: it decays exponentially with travel.
    The last ``smooth_s`` of a step is left out (the derivative windows there reach
    into the next step's speed ramp). Steps with less than ``min_steady_s`` of steady
    data are dropped, and so are steps that stalled (a speed below
    :data:`STALLED_FRACTION` of the setpoint, or against it). The step's speed is the
    least-squares slope of x over the steady part
    (the derivative averaged without the Savitzky-Golay edge effects); its friction
    the mean of ``friction_n`` there, with its standard error.

    Returns one row per kept step: ``segment, step, pressure_setpoint_pa,
    velocity_setpoint_m_s, steady_start_s, steady_end_s, samples, p_rodless_pa,
    velocity_m_s, friction_n, friction_sem_n``.
    """
    rows = []
    moving = frame.filter(
        pl.col("velocity_setpoint_m_s").is_not_null()
        & (pl.col("velocity_setpoint_m_s") != 0)
        & pl.col("v_m_s").is_not_nan()
        & pl.col("x_m").is_not_null()
    )
    for whole in moving.partition_by("segment", maintain_order=True):
        # the derivative windows reach into the next step's ramp: trim one window
        part = whole.filter(pl.col("t_s") <= pl.col("t_s").max() - smooth_s)
        t = part["t_s"].to_numpy()
        if t.size < 20 or t[-1] - t[0] < min_steady_s:
            continue
        dt_s = float(np.median(np.diff(t)))
        window = max(round(smooth_s / dt_s), 3)
        force = part["friction_n"].to_numpy()
        start = _steady_start(part["v_m_s"].to_numpy(), force, window, velocity_tol, force_tol)
        keep = slice(start, None)
        if t.size - start < 10 or t[-1] - t[start] < min_steady_s:
            continue
        tk, xk, fk = t[keep], part["x_m"].to_numpy()[keep], force[keep]
        slope = float(np.polyfit(tk - tk.mean(), xk, 1)[0])
        first = part.row(0, named=True)
        setpoint = float(first["velocity_setpoint_m_s"])
        if not slope * setpoint >= (STALLED_FRACTION * setpoint) ** 2:
            continue  # the piston did not follow its setpoint: stuck, not sliding
        rows.append(
            {
                "segment": int(first["segment"]),
                "step": first["step"],
                "pressure_setpoint_pa": first["pressure_setpoint_pa"],
                "velocity_setpoint_m_s": first["velocity_setpoint_m_s"],
                "steady_start_s": float(tk[0]),
                "steady_end_s": float(tk[-1]),
                "samples": int(tk.size),
                "p_rodless_pa": float(part["p_rodless_pa"].to_numpy()[keep].mean()),
                "velocity_m_s": slope,
                "friction_n": float(fk.mean()),
                "friction_sem_n": float(fk.std(ddof=1) / math.sqrt(fk.size)),
            }
        )
    return pl.DataFrame(rows, schema=_STEP_SCHEMA)


_LEVEL_SCHEMA = {
    "pressure_setpoint_pa": pl.Float64,
    "p_rodless_pa": pl.Float64,
    "steps": pl.Int64,
    "coulomb_n": pl.Float64,
    "coulomb_sigma_n": pl.Float64,
    "static_n": pl.Float64,
    "static_sigma_n": pl.Float64,
    "stribeck_speed_m_s": pl.Float64,
    "stribeck_speed_sigma_m_s": pl.Float64,
    "viscous_n_s_m": pl.Float64,
    "viscous_sigma_n_s_m": pl.Float64,
    "rms_n": pl.Float64,
    "converged": pl.Boolean,
}


def fit_pressure_levels(
    steps: pl.DataFrame, *, level_resolution_pa: float = 1e4, min_points: int = 5
) -> tuple[pl.DataFrame, list[StribeckFit]]:
    """Stribeck fit (eq 16/18) per pressure level, both directions together.

    Steps are grouped by their pressure setpoint (rounded to ``level_resolution_pa``);
    each level's fit is assigned to the mean measured rodless pressure of its steps,
    the pressure the eq-17 lines are functions of. Levels with fewer than
    ``min_points`` steps are skipped. This is the analogue of paper Table 1, in SI with
    1-sigma uncertainties (:func:`transforms.friction_fit.fit_stribeck`).

    Returns the per-pressure frame (ascending pressure; columns ``pressure_setpoint_pa,
    p_rodless_pa, steps``, each parameter with its ``*_sigma_*``, ``rms_n``,
    ``converged``) and the fits in the same order.
    """
    levels = (
        steps.with_columns(level=(pl.col("pressure_setpoint_pa") / level_resolution_pa).round(0))
        .filter(pl.col("level").is_not_null())
        .sort("level", "segment")
    )
    rows, fits = [], []
    for part in levels.partition_by("level", maintain_order=True):
        if part.height < min_points:
            continue
        fit = fit_stribeck(part["velocity_m_s"].to_numpy(), part["friction_n"].to_numpy())
        fits.append(fit)
        rows.append(
            {
                "pressure_setpoint_pa": float(part["pressure_setpoint_pa"].mean()),  # type: ignore[arg-type]
                "p_rodless_pa": float(part["p_rodless_pa"].mean()),  # type: ignore[arg-type]
                "steps": part.height,
                "coulomb_n": fit.fc,
                "coulomb_sigma_n": fit.sigma[0],
                "static_n": fit.fs,
                "static_sigma_n": fit.sigma[1],
                "stribeck_speed_m_s": fit.vs,
                "stribeck_speed_sigma_m_s": fit.sigma[2],
                "viscous_n_s_m": fit.kv,
                "viscous_sigma_n_s_m": fit.sigma[3],
                "rms_n": fit.rms,
                "converged": fit.success,
            }
        )
    return pl.DataFrame(rows, schema=_LEVEL_SCHEMA), fits
