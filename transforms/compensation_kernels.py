"""The per-sample arithmetic of the compensation: smoothing, viscosity, the rope kernel.

:func:`rope_kernel` runs the physics kernels (:mod:`physics`) over one rope's samples
in one pass; :func:`differential_smooth` smooths a logged displacement for the
share-out of the oil's motion; :func:`viscosity` gives the oil's viscosity per sample;
:func:`load_kernel` sums the ropes. Called by :mod:`transforms.compensation_block`.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
from numba import njit

from physics.friction_law import friction_law_at, stribeck_g
from physics.lugre import lugre_drift, lugre_force, lugre_z_step
from physics.maxwell_slip import maxwell_slip_step
from physics.oil import kinematic_viscosity
from physics.sensor_branch import sensor_minus_chamber_at
from physics.tension import rope_tension_n
from schemas.hoist import HoistDescription
from transforms.compensation_record import CompensationSettings
from transforms.filtering import box_smooth_into, segment_ids

__all__ = [
    "Buffer",
    "differential_smooth",
    "load_kernel",
    "long_segments",
    "rope_kernel",
    "smoothed_noise",
    "viscosity",
]

#: ``buffer(name, size)``: a work array of that size, reused by name (per thread).
Buffer = Callable[[str, int], np.ndarray]


def _fresh(name: str, size: int) -> np.ndarray:
    """A new float64 array (the default of the ``buffer`` arguments below)."""
    return np.empty(size)


def _median_padded_smooth(
    x: np.ndarray,
    sigma_samples: float,
    edge_samples: int,
    *,
    out: np.ndarray | None = None,
    buffer: Buffer = _fresh,
) -> np.ndarray:
    """Near-Gaussian smoothing whose ends are pinned to the median of the nearest samples.

    The kernel (:func:`transforms.filtering.box_smooth`) has only positive weights, so
    a monotone input gives a monotone output: a step in piston position never comes
    out with an overshoot and a return, which a history-dependent friction state would
    take for a reversal (a Butterworth filter rings). Padding both ends with the median
    of the nearest ``edge_samples`` samples keeps the ends from being pinned to one
    noisy raw sample. Written into ``out`` when given; the padded work arrays come from
    ``buffer(name, size)`` (reused arrays in the per-rope loop).
    """
    if out is None:
        out = np.empty_like(x)
    finite = np.isfinite(x)
    if not finite.any():
        out[:] = 0.0
        return out
    if not finite.all():
        idx = np.arange(x.size)
        x = np.interp(idx, idx[finite], x[finite])
    pad = int(4 * sigma_samples) + 1
    size = x.size + 2 * pad
    current, other = buffer("smooth_a", size), buffer("smooth_b", size)
    current[:pad] = np.median(x[:edge_samples])
    current[pad : pad + x.size] = x
    current[pad + x.size :] = np.median(x[-edge_samples:])
    smoothed = box_smooth_into(current, other, sigma_samples=sigma_samples)
    out[:] = smoothed[pad : pad + x.size]
    return out


def differential_smooth(
    x: np.ndarray,
    bounds: np.ndarray,
    settings: CompensationSettings,
    *,
    buffer: Buffer = _fresh,
) -> np.ndarray:
    """One rope's logged displacement, Gaussian-smoothed per long segment.

    The differential motion is slow and positions are continuous across a short logger
    dropout, so segments here are split only at gaps longer than
    ``settings.differential_bridge_s`` (``bounds``). The smoother is a Gaussian of
    standard deviation s = 0.1325 / f_c seconds (half-power frequency f_c); it leaves
    sigma / sqrt(2 sqrt(pi) s f_s) of the transducer's white noise (:func:`smoothed_noise`),
    and the caller's play operator of half-width 3 times that keeps the slow wander of the
    filtered noise from moving the friction state. The result is ``buffer("work_b", n)``.
    """
    sigma_samples = _smoothing_sigma_samples(settings)
    edge = max(int(settings.sample_rate_hz / settings.differential_cutoff_hz), 1)
    smooth = buffer("work_b", x.size)
    for a, b in itertools.pairwise(bounds):
        _median_padded_smooth(
            x[a:b], sigma_samples, min(edge, b - a), out=smooth[a:b], buffer=buffer
        )
    return smooth


def _smoothing_sigma_samples(settings: CompensationSettings) -> float:
    """Standard deviation of the differential smoother [samples]."""
    return 0.1325 / settings.differential_cutoff_hz * settings.sample_rate_hz


def smoothed_noise(settings: CompensationSettings) -> float:
    """Share of white noise the differential smoother leaves, 1 / sqrt(2 sqrt(pi) s f_s)."""
    return 1.0 / np.sqrt(2.0 * np.sqrt(np.pi) * _smoothing_sigma_samples(settings))


def long_segments(time_s: np.ndarray, bridge_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Segment id per sample and segment bounds [0, ..., n], split only at gaps > bridge_s."""
    segment = segment_ids(time_s, gap_factor=1.0, nominal_dt_s=bridge_s, rate_changes=False)
    starts = np.flatnonzero(segment[1:] != segment[:-1]) + 1
    return segment, np.r_[0, starts, time_s.size]


def viscosity(t_oil_c: np.ndarray | None, hoist: HoistDescription) -> np.ndarray | float:
    """Kinematic viscosity [m2/s] per sample (ASTM D341), or at the reference temperature.

    Walther's relation is smooth in T, so it is evaluated on a grid of whole hundredths
    of a degree over the logged range and interpolated: exact to ~1e-7 relative, 20x
    cheaper per sample; the grid's nodes do not depend on the range, so a block of a
    day gets the values of the whole day.
    """
    if t_oil_c is None:
        return float(kinematic_viscosity(hoist.oil.reference_temperature_c, hoist.oil))
    low, high = float(np.min(t_oil_c)), float(np.max(t_oil_c))
    first, last = int(np.floor(low * 100.0)), int(np.ceil(high * 100.0))
    grid = np.arange(first, max(last, first + 1) + 1) / 100.0
    return np.interp(t_oil_c, grid, kinematic_viscosity(grid, hoist.oil))


@njit(cache=True, nogil=True, error_model="numpy")
def rope_kernel(
    x,
    time_s,
    gap_s,
    nominal_dt_s,
    p_sensor,
    with_loss,
    v_flow,
    nu,
    branch,
    law,
    mode,
    stiffness,
    weights,
    sigma0,
    sigma1,
    area,
    drift_m,
    p_chamber,
    friction,
    tension_raw,
    tension,
    state,
):  # pragma: no cover - numba
    """Increments, branch loss, seal friction and tensions of one rope in one pass.

    Velocity v = (x[i] - x[i-1]) / dt[i] (0 at a segment's start or where unknown). Step
    lengths and segment starts come from ``time_s``: a step above ``gap_s`` starts a
    segment and counts ``nominal_dt_s``. Per sample, the physics kernels:
    p_chamber = p_sensor - :func:`physics.sensor_branch.sensor_minus_chamber_at` of the
    branch flow ``v_flow`` if ``with_loss`` (``branch`` from
    :func:`~physics.sensor_branch.sensor_branch`); the eq 17 law at p_chamber
    (:func:`physics.friction_law.friction_law_at`); friction by Maxwell-slip
    (``mode`` 1, :func:`physics.maxwell_slip.maxwell_slip_step` plus Kv v) or LuGre
    (``mode`` 2, :func:`physics.lugre.lugre_z_step`, :func:`~physics.lugre.lugre_force`),
    given in ``friction`` on entry for ``mode`` 3, none for ``mode`` 0; tension by
    :func:`physics.tension.rope_tension_n` (eq 2). ``drift_m`` (``mode`` 2; one value per
    sample, or a single 0): the piston's travel that its x does not show, along which
    the bristles drift before the sample's step (:func:`physics.lugre.lugre_drift`: a
    ringing at rest within the x's deadband, :meth:`transforms.compensation_block.
    BlockCompensation.ringing_drift`).
    ``state`` = [ran, last x, last time, LuGre z, Maxwell-slip deflections...] carries
    the friction state from the previous block (:func:`transforms.filtering.fresh_state`,
    :data:`transforms.compensation_record.ROPE_STATE_BASE` + elements).
    One function over 80 lines on purpose: the
    per-sample loop of the run's hot path (5 M rope-samples/s) calls the physics kernels
    inline; its friction state stays in registers between samples.
    """
    n_el = weights.shape[0]
    ran = state[0] != 0.0
    deltas = np.zeros(n_el)
    z = 0.0
    if ran:
        z = state[3]
        for j in range(n_el):
            deltas[j] = state[4 + j]
    per_sample = nu.shape[0] > 1
    for i in range(x.shape[0]):
        # step length and segment start (the caller's segments)
        same_segment = False
        dt_i = nominal_dt_s
        x_before = x[i - 1] if i > 0 else state[1]
        if i > 0 or ran:
            dt_i = time_s[i] - (time_s[i - 1] if i > 0 else state[2])
            same_segment = not dt_i > gap_s
            if not same_segment:
                dt_i = nominal_dt_s
        pc = p_sensor[i]
        if with_loss and np.isfinite(v_flow[i]):  # an unknown flow: no loss taken
            pc -= sensor_minus_chamber_at(v_flow[i], nu[i] if per_sample else nu[0], branch)
        p_chamber[i] = pc
        f = 0.0
        if mode == 3:
            f = friction[i]  # given: the stick-slip solution's (transforms.stick_slip)
        elif mode != 0:
            v = 0.0
            if (i > 0 or ran) and x[i] != x_before:  # (a NaN differs too); else 0 / dt is 0
                step = (x[i] - x_before) / dt_i
                if same_segment and np.isfinite(step):
                    v = step
            fc, fs, vs, kv = friction_law_at(pc if np.isfinite(pc) else 0.0, law)
            if mode == 1:
                # at standstill g(0) = Fs exactly: no exp needed
                g = fs if v == 0.0 else stribeck_g(v, fc, fs, vs)
                f = maxwell_slip_step(deltas, v * dt_i, stiffness, weights, g) + kv * v
            else:
                if drift_m.shape[0] > 1 and drift_m[i] > 0.0:  # at rest: g = F_s
                    z = lugre_drift(z, drift_m[i], sigma0, stribeck_g(v, fc, fs, vs))
                z_before = z
                if v != 0.0 and dt_i > 0.0:
                    z = lugre_z_step(z, v, dt_i, sigma0, stribeck_g(v, fc, fs, vs))
                f = lugre_force(z_before, z, v, dt_i, sigma0, sigma1, kv)
        friction[i] = f
        tension_raw[i] = rope_tension_n(p_sensor[i], area, 0.0)
        tension[i] = rope_tension_n(pc, area, f)
    if x.shape[0]:
        state[0] = 1.0
        state[1] = x[x.shape[0] - 1]
        state[2] = time_s[x.shape[0] - 1]
        state[3] = z
        for j in range(n_el):
            state[4 + j] = deltas[j]


#: Length of :func:`_rope_kernel`'s state before its Maxwell-slip elements.
ROPE_STATE_BASE = 4


@njit(cache=True, nogil=True)
def load_kernel(raw, compensated, load_raw, load):  # pragma: no cover - numba
    """Row sums of the rope tensions (polars ``sum_horizontal``: in column order)."""
    for i in range(load.shape[0]):
        total_raw = raw[0][i]
        total = compensated[0][i]
        for k in range(1, len(raw)):
            total_raw += raw[k][i]
            total += compensated[k][i]
        load_raw[i] = total_raw
        load[i] = total
