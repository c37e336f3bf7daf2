"""From logged sensor pressures to compensated rope tensions (paper sections 4-5).

For each cylinder i of a hoist, per sample:

1. sensor calibration: p_i = (reading_i - offset_i) / gain_i (hoist ``[[sensors]]``);
2. single-sample spikes removed (3-point median) and a zero-phase low-pass, per
   gap-free segment;
3. piston motion: the common mode (all four pistons together) from the pressure,
   because the chambers, pipes and manifold are one closed oil volume and a change dp
   of the common pressure moves every piston by V dp / (n A beta) (NOTES.md) -- with a
   5 kPa pressure noise that is a nanometre-class displacement sensor, against the
   ~0.05 mm noise of a displacement transducer and common-mode motions of a few tenths
   of a millimetre per trip; plus, where x_i is logged, the differential part
   x_i - mean(x), low-passed. The friction state is driven by the increments of a play
   (deadband) operator on that estimate, so residual noise does not move it and a
   smoothed derivative's overshoot at a stop cannot flip it; the branch flow uses the
   Savitzky-Golay velocity of the same estimate;
4. chamber pressure: the sensor sits after the globe valve and the first branch part,
   so p_chamber = p_sensor - (p_sensor - p_chamber)(v, T) (paper eq 12-14, contract 1a);
5. seal friction F_i: LuGre (paper eq 15, which the paper calls "Leuven") driven by v_i,
   with parameters linear in chamber pressure (eq 17 form); with
   ``presliding_hysteresis`` in the hoist's model, the Maxwell-slip elements (the
   Leuven / GMS idea) replace the single bristle. The state is carried through
   standstill, so the friction left by the last motion is kept, not zeroed;
6. tension T_i = p_chamber,i A_bore + F_i (paper eq 2, F positive while the rod moves
   out), and the uncompensated T_raw,i = p_sensor,i A_bore (the paper's "before").

Which corrections apply follows the hoist's ``[model] effects``: ``seal_friction``,
``presliding_hysteresis``, ``pipe_laminar_loss`` / ``local_loss`` (both are in the branch
loss), ``viscosity_temperature`` (viscosity from the logged oil temperature instead of
the reference temperature).

The friction state is sequential over the whole record, so :func:`compensate` takes a
collected frame of one hoist, sorted by time, and returns a ``ROPE_TENSIONS`` frame.
"""

from __future__ import annotations

import itertools
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import polars as pl
from numba import njit

from schemas.hoist import HoistDescription
from schemas.tables import ROPE_TENSIONS, ROPES
from transforms.filtering import (
    box_smooth,
    despike_median3,
    lowpass_columns,
    play_operator,
    with_segment_id,
)
from transforms.friction import (
    friction_parameters,
    lugre_friction,
    maxwell_slip_elements,
    maxwell_slip_friction,
)
from transforms.kinematics import (
    with_acceleration,
    with_piston_velocity,
    with_position,
    with_trip_phases,
)
from transforms.oil import effective_bulk_modulus, kinematic_viscosity
from transforms.pressure_loss import sensor_minus_chamber_pa

__all__ = [
    "CompensationSettings",
    "common_mode_displacement",
    "compensate",
    "displacement_noise_sigma",
]

_OUTPUT_SCHEMA = pl.Schema(pl.from_arrow(ROPE_TENSIONS.empty_table()).schema)


@dataclass(frozen=True)
class CompensationSettings:
    """Signal-processing choices of :func:`compensate` (documented defaults).

    Attributes
    ----------
    sample_rate_hz : float
        Nominal logger rate [Hz]; spacing above ``gap_factor`` / rate starts a segment.
    pressure_cutoff_hz : float
        Zero-phase low-pass on the pressures [Hz] (4th-order Butterworth, filtfilt).
    spike_sigmas : float
        A sample further than this many noise sigmas from the median of itself and its
        neighbours is a spike (:func:`transforms.filtering.despike_median3`).
    velocity_window_s : float
        Savitzky-Golay window for the piston velocity [s].
    acceleration_window_s : float
        Savitzky-Golay window for the conveyance acceleration [s].
    differential_cutoff_hz : float
        Half-power frequency of the Gaussian smoothing of the differential part of the
        logged displacement (x_i minus the mean of the four) [Hz]. Differential motion
        (ropes stretching differently, groove wear) is slow; the transducer's noise is not.
    differential_bridge_s : float
        Logger gaps up to this long [s] are bridged for the differential displacement
        (pistons do not jump while the logger drops samples); longer gaps restart it.
    displacement_deadband_m : float
        Half-width of the play operator on the estimated piston displacement [m]: the
        residual noise of the estimate, well inside the seal's presliding range.
    """

    sample_rate_hz: float = 100.0
    gap_factor: float = 3.0
    pressure_cutoff_hz: float = 10.0
    spike_sigmas: float = 6.0
    velocity_window_s: float = 0.2
    acceleration_window_s: float = 0.5
    differential_cutoff_hz: float = 0.1
    differential_bridge_s: float = 120.0
    displacement_deadband_m: float = 5e-6


def _rope_cols(template: str) -> list[str]:
    return [template.format(i=i) for i in ROPES]


def common_mode_displacement(
    p_mean_pa: np.ndarray, segment_id: np.ndarray, hoist: HoistDescription
) -> np.ndarray:
    r"""Piston displacement implied by oil compression when x is not logged [m].

    The four chambers, pipes and manifold are one closed oil volume V, so a change of
    the common pressure dp moves every piston by the same amount (NOTES.md):

    .. math::
        n A_{bore}\, dx = \frac{V}{\beta_e(p)}\, dp

    with beta_e the effective bulk modulus (entrained air included,
    :func:`transforms.oil.effective_bulk_modulus`). A rising load squeezes oil out of
    the chambers, so x grows (rod out) while p rises. Differential piston motion is not
    observable this way and is taken as zero. Integrated per segment from 0.
    """
    p = np.asarray(p_mean_pa, dtype=np.float64)
    beta = effective_bulk_modulus(
        np.maximum(np.nan_to_num(p, nan=1e6), 1e5),
        hoist.oil.bulk_modulus_pa,
        hoist.oil.air_fraction,
    )
    compliance = hoist.oil_volume_m3 / (hoist.ropes_n * hoist.cylinders.bore_area_m2 * beta)
    dp = np.r_[0.0, np.diff(p)]
    starts = np.r_[True, segment_id[1:] != segment_id[:-1]]
    dp[starts | ~np.isfinite(dp)] = 0.0
    dx = compliance * dp
    x = np.cumsum(dx)
    # restart the integral at every segment start
    offsets = np.maximum.accumulate(np.where(starts, np.arange(x.size), 0))
    return x - x[offsets] + dx[offsets]


def displacement_noise_sigma(x: np.ndarray) -> float:
    """Robust white-noise sigma of a sampled signal from its second differences [unit of x].

    For white noise of variance s^2, the second difference has variance 6 s^2; the
    median absolute deviation (x 1.4826) makes the estimate ignore real motion and steps.
    """
    d2 = np.diff(np.asarray(x, dtype=np.float64), 2)
    d2 = d2[:: max(1, d2.size // 200_000)]  # the median of 200 k of them is plenty
    d2 = d2[np.isfinite(d2)]
    if d2.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def _median_padded_smooth(x: np.ndarray, sigma_samples: float, edge_samples: int) -> np.ndarray:
    """Near-Gaussian smoothing whose ends are pinned to the median of the nearest samples.

    The kernel (:func:`transforms.filtering.box_smooth`) has only positive weights, so
    a monotone input gives a monotone output: a step in piston position never comes
    out with an overshoot and a return, which a history-dependent friction state would
    take for a reversal (a Butterworth filter rings). Padding both ends with the median
    of the nearest ``edge_samples`` samples keeps the ends from being pinned to one
    noisy raw sample.
    """
    finite = np.isfinite(x)
    if not finite.any():
        return np.zeros_like(x)
    if not finite.all():
        idx = np.arange(x.size)
        x = np.interp(idx, idx[finite], x[finite])
    pad = int(4 * sigma_samples) + 1
    padded = np.r_[
        np.full(pad, np.median(x[:edge_samples])), x, np.full(pad, np.median(x[-edge_samples:]))
    ]
    return box_smooth(padded, sigma_samples=sigma_samples)[pad:-pad]


def _differential_displacement(
    frame: pl.DataFrame, x_cols: list[str], settings: CompensationSettings
) -> list[np.ndarray]:
    """x_i - mean_j x_j per rope: smoothed, then a play operator of 3 sigma of its noise.

    The differential motion is slow and positions are continuous across a short logger
    dropout, so segments here are split only at gaps longer than
    ``settings.differential_bridge_s``. The smoother is a Gaussian of standard deviation
    s = 0.1325 / f_c seconds (half-power frequency f_c); it leaves
    sigma / sqrt(2 sqrt(pi) s f_s) of the transducer's white noise, and a play of
    half-width 3 times that keeps the slow wander of the filtered noise from moving the
    friction state.
    """
    time_s = frame["time_utc"].dt.epoch("us").to_numpy().astype(np.float64) * 1e-6
    long_gap = np.r_[False, np.diff(time_s) > settings.differential_bridge_s]
    segment = np.cumsum(long_gap)
    bounds = np.r_[0, np.flatnonzero(long_gap), time_s.size]
    mean = frame.select(pl.mean_horizontal(x_cols)).to_series().to_numpy()
    sigma_samples = 0.1325 / settings.differential_cutoff_hz * settings.sample_rate_hz
    edge = max(int(settings.sample_rate_hz / settings.differential_cutoff_hz), 1)
    shrink = 1.0 / np.sqrt(2.0 * np.sqrt(np.pi) * sigma_samples)
    result = []
    for column in x_cols:
        raw = frame[column].to_numpy().astype(np.float64) - mean
        sigma = displacement_noise_sigma(raw)
        smooth = np.zeros_like(raw)
        for a, b in itertools.pairwise(bounds):
            smooth[a:b] = _median_padded_smooth(raw[a:b], sigma_samples, min(edge, b - a))
        result.append(play_operator(smooth, segment, half_width=3.0 * sigma * shrink))
    return result


def _increment_velocity(x: np.ndarray, dt: np.ndarray, segment_id: np.ndarray) -> np.ndarray:
    """(x[i] - x[i-1]) / dt[i], 0 at segment starts: the friction state sees exact steps."""
    v = np.empty_like(x)
    _increment_kernel(np.ascontiguousarray(x), dt, np.ascontiguousarray(segment_id), v)
    return v


@njit(cache=True, nogil=True)
def _increment_kernel(x, dt, segment_id, v):  # pragma: no cover - numba
    v[0] = 0.0
    for i in range(1, x.shape[0]):
        step = (x[i] - x[i - 1]) / dt[i]
        v[i] = step if segment_id[i] == segment_id[i - 1] and np.isfinite(step) else 0.0


def _viscosity(t_oil_c: np.ndarray | None, hoist: HoistDescription) -> np.ndarray | float:
    """Kinematic viscosity [m2/s] per sample (ASTM D341), or at the reference temperature.

    Walther's relation is smooth in T, so it is evaluated on a 0.01 degC-fine grid over
    the logged range and interpolated: exact to ~1e-7 relative, 20x cheaper per sample.
    """
    if t_oil_c is None:
        return float(kinematic_viscosity(hoist.oil.reference_temperature_c, hoist.oil))
    low, high = float(np.min(t_oil_c)), float(np.max(t_oil_c))
    grid = np.linspace(low, high, max(int((high - low) / 0.01) + 2, 2))
    return np.interp(t_oil_c, grid, kinematic_viscosity(grid, hoist.oil))


def _despiked(frame: pl.DataFrame, columns: list[str], *, n_sigmas: float) -> pl.DataFrame:
    """Single-sample spikes removed from ``columns``, per gap-free segment."""
    segment = frame["segment_id"].to_numpy()
    cleaned = [
        pl.Series(c, despike_median3(frame[c].to_numpy(), segment, n_sigmas=n_sigmas)[0])
        .fill_nan(None)
        .alias(c)
        for c in columns
    ]
    return frame.with_columns(cleaned)


def _step_lengths(time_s: np.ndarray, segment_id: np.ndarray, nominal_dt_s: float) -> np.ndarray:
    """dt[i] = t[i] - t[i-1]; a segment's first sample gets the nominal step."""
    dt = np.empty_like(time_s)
    dt[0] = nominal_dt_s
    dt[1:] = np.diff(time_s)
    starts = np.r_[True, segment_id[1:] != segment_id[:-1]]
    dt[starts] = nominal_dt_s
    return dt


def _seal_friction(
    v: np.ndarray,
    dt: np.ndarray,
    p_chamber_pa: np.ndarray,
    hoist: HoistDescription,
    *,
    presliding: bool,
) -> np.ndarray:
    law = hoist.friction_law
    fc, fs, vs, kv = friction_parameters(p_chamber_pa, law)
    v = np.where(np.isfinite(v), v, 0.0)  # no velocity information: hold the state
    if presliding:
        stiffness, weights = maxwell_slip_elements(
            law.presliding_elements, law.bristle_stiffness_n_m
        )
        force, _ = maxwell_slip_friction(v, dt, fc, fs, vs, kv, stiffness, weights)
    else:
        force, _ = lugre_friction(
            v, dt, fc, fs, vs, kv, law.bristle_stiffness_n_m, law.bristle_damping_n_s_m
        )
    return force


def compensate(
    samples: pl.DataFrame | pl.LazyFrame,
    hoist: HoistDescription,
    *,
    settings: CompensationSettings | None = None,
    effects: set[str] | None = None,
) -> pl.DataFrame:
    """Compensated rope tensions for one hoist's samples (a ``FIELD_SAMPLES`` frame).

    Parameters
    ----------
    samples : polars.DataFrame or LazyFrame
        Landed samples of one hoist (columns of ``schemas.tables.FIELD_SAMPLES``).
    hoist : HoistDescription
        Geometry, oil, sensors, friction law and ``[model] effects``.
    settings : CompensationSettings, optional
        Filtering and differentiation choices.
    effects : set of str, optional
        Effects to compensate; default ``hoist.model.effects``.

    Returns
    -------
    polars.DataFrame
        One row per sample with the columns of ``schemas.tables.ROPE_TENSIONS``.
    """
    settings = settings or CompensationSettings()
    effects = set(hoist.model.effects if effects is None else effects)
    dt_nominal = 1.0 / settings.sample_rate_hz
    frame = samples.lazy().sort("time_utc").collect()
    if frame.height == 0:
        return pl.DataFrame(schema=_OUTPUT_SCHEMA)

    p_cols, x_cols = _rope_cols("p{i}_pa"), _rope_cols("x{i}_m")
    calibration = [
        ((pl.col(f"p{s.cylinder}_pa") - s.offset_pa) / s.gain).alias(f"p{s.cylinder}_pa")
        for s in hoist.sensors
    ]
    frame = (
        frame.with_columns(calibration)
        .pipe(
            with_segment_id,
            "time_utc",
            gap_factor=settings.gap_factor,
            nominal_dt_s=dt_nominal,
        )
        .pipe(_despiked, [*p_cols, *x_cols], n_sigmas=settings.spike_sigmas)
        .pipe(
            lowpass_columns,
            p_cols,
            sample_rate_hz=settings.sample_rate_hz,
            cutoff_hz=settings.pressure_cutoff_hz,
        )
        .with_columns(pl.col("speed_m_s").fill_null(0.0).alias("_speed"))
        .pipe(
            with_acceleration,
            dt_s=dt_nominal,
            speed_col="_speed",
            window_s=settings.acceleration_window_s,
        )
        .pipe(with_trip_phases, hoist, speed_col="_speed")
        .pipe(with_position, hoist)
    )

    has_x = all(frame[c].null_count() < frame.height for c in x_cols)
    segment = frame["segment_id"].to_numpy()
    p_mean = frame.select(pl.mean_horizontal(p_cols)).to_series().to_numpy()
    x_common = common_mode_displacement(p_mean, segment, hoist)
    if has_x:
        differential = _differential_displacement(frame, x_cols, settings)
        estimates = {f"x{i}_m": x_common + differential[k] for k, i in enumerate(ROPES)}
    else:
        estimates = {f"x{i}_m": x_common for i in ROPES}
    played = {
        name: play_operator(values, segment, half_width=settings.displacement_deadband_m)
        for name, values in estimates.items()
    }
    motion = frame.select("segment_id").with_columns(
        pl.Series(name, values) for name, values in played.items()
    )
    motion = with_piston_velocity(
        motion,
        x_cols,
        bore_area_m2=hoist.cylinders.bore_area_m2,
        dt_s=dt_nominal,
        window_s=settings.velocity_window_s,
    )
    flow_velocities = [motion[f"v{i}_m_s"].to_numpy().astype(np.float64) for i in ROPES]

    time_s = frame["time_utc"].dt.epoch("us").to_numpy().astype(np.float64) * 1e-6
    dt = _step_lengths(time_s, segment, dt_nominal)
    area = hoist.cylinders.bore_area_m2
    t_oil = None
    if "viscosity_temperature" in effects and frame["oil_temp_c"].null_count() < frame.height:
        t_oil = (
            frame["oil_temp_c"]
            .fill_null(strategy="forward")
            .fill_null(strategy="backward")
            .to_numpy()
        )
    nu = _viscosity(t_oil, hoist)
    with_branch_loss = bool({"pipe_laminar_loss", "local_loss"} & effects)
    with_friction = "seal_friction" in effects
    presliding = "presliding_hysteresis" in effects

    def rope(i: int, v_flow: np.ndarray) -> dict[str, np.ndarray]:
        p_sensor = frame[f"p{i}_pa"].to_numpy().astype(np.float64)
        v_known = np.where(np.isfinite(v_flow), v_flow, 0.0)
        v = _increment_velocity(played[f"x{i}_m"], dt, segment)
        if with_branch_loss:
            # the oil is still for most of a day: evaluate the loss where it flows only
            flowing = v_known != 0.0
            loss = np.zeros_like(p_sensor)
            loss[flowing] = sensor_minus_chamber_pa(
                v_known[flowing], hoist, nu_m2_s=nu if np.ndim(nu) == 0 else nu[flowing]
            )
            p_chamber = p_sensor - loss
        else:
            p_chamber = p_sensor.copy()
        if with_friction:
            p_for_law = np.where(np.isfinite(p_chamber), p_chamber, 0.0)
            friction = _seal_friction(v, dt, p_for_law, hoist, presliding=presliding)
        else:
            friction = np.zeros_like(p_chamber)
        return {
            f"p_chamber{i}_pa": p_chamber,
            f"friction{i}_n": friction,
            f"tension_raw{i}_n": p_sensor * area,
            f"tension{i}_n": p_chamber * area + friction,
        }

    # The ropes are independent and the numba kernels and large numpy operations
    # release the GIL, so the four run side by side.
    with ThreadPoolExecutor(max_workers=min(len(ROPES), os.cpu_count() or 1)) as pool:
        per_rope = list(pool.map(rope, ROPES, flow_velocities))
    columns = {name: values for part in per_rope for name, values in part.items()}

    result = frame.with_columns(
        pl.Series(name, values, dtype=pl.Float64) for name, values in columns.items()
    ).with_columns(
        (-pl.col("acceleration_m_s2")).alias("acceleration_up_m_s2"),
        pl.sum_horizontal(_rope_cols("tension_raw{i}_n")).alias("load_raw_n"),
        pl.sum_horizontal(_rope_cols("tension{i}_n")).alias("load_n"),
    )
    return result.select(pl.col(name).cast(dtype) for name, dtype in _OUTPUT_SCHEMA.items())
