"""From logged sensor pressures to compensated rope tensions (paper sections 4-5).

For each cylinder i of a hoist, per sample:

1. sensor calibration: p_i = (reading_i - offset_i) / gain_i (hoist ``[[sensors]]``);
2. single-sample spikes removed (3-point median) and a zero-phase low-pass, per
   gap-free segment;
3. piston motion (:mod:`transforms.piston_motion`): the chambers, pipes and manifold
   are one closed oil volume, so the *sum* of the four displacements follows the
   common pressure, A sum dx_i = V dp / beta (NOTES.md) -- with a 5 kPa pressure noise
   a micrometre-class sensor of the sum. Where x_i is logged (to a 0.1 mm step), its
   smoothed, played record says *which* pistons move: the oil's motion is shared out
   to the pistons seen moving, the part within the seals' presliding range equally
   (elastic), so a piston that sticks through a payload change is not moved out and
   back (issue 13). The friction state is driven by the increments of a play
   (deadband) operator on that estimate, so residual noise does not move it; the
   branch flow uses the Savitzky-Golay velocity of the same estimate;
4. chamber pressure: the sensor sits after the globe valve and the first branch part,
   so p_chamber = p_sensor - (p_sensor - p_chamber)(v, T) (paper eq 12-14, contract 1a);
5. seal friction F_i: LuGre (paper eq 15, which the paper calls "Leuven") driven by v_i,
   with parameters linear in chamber pressure (eq 17 form); with
   ``presliding_hysteresis`` in the hoist's model, the Maxwell-slip elements (the
   Leuven / GMS idea) replace the single bristle. The state is carried through
   standstill, so the friction left by the last motion is kept, not zeroed;
6. tension T_i = p_chamber,i A_bore + F_i (paper eq 2, F positive while the rod moves
   out), and the uncompensated T_raw,i = p_sensor,i A_bore (the paper's "before");
7. a 95 % band for each tension and the load (:mod:`transforms.uncertainty`): the
   friction range the estimate cannot resolve (motion only the oil saw), the friction
   law's uncertainty and the sensor noise.

Which corrections apply follows the hoist's ``[model] effects``: ``seal_friction``,
``presliding_hysteresis``, ``pipe_laminar_loss`` / ``local_loss`` (both are in the branch
loss), ``viscosity_temperature`` (viscosity from the logged oil temperature instead of
the reference temperature).

The friction state is sequential over the whole record, so :func:`compensate` takes a
collected frame of one hoist, sorted by time, and returns a ``ROPE_TENSIONS`` frame.
:func:`compensate_window` does the same for one block of a longer record, resuming the
sequential kernels from the state the previous block left (:class:`CompensationCarry`)
with the record's statistics (:class:`CompensationContext`): :mod:`transforms.blocks`.
"""

from __future__ import annotations

import datetime as dt
import itertools
import os
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
import polars as pl
from numba import njit

from physics.branch_loss import sensor_branch, sensor_minus_chamber_at
from physics.closed_volume import COMMON_MODE_STATE_SIZE, common_mode_displacement
from physics.friction_law import friction_law_at, law_array, stribeck_g
from physics.lugre import lugre_force, lugre_z_step
from physics.maxwell_slip import maxwell_slip_elements, maxwell_slip_step
from physics.oil import kinematic_viscosity
from physics.tension import rope_tension_n
from physics.trip_rule import LABEL_STATE_SIZE, trip_label_columns
from schemas.hoist import HoistDescription
from schemas.tables import ROPE_TENSIONS, ROPES
from transforms.filtering import (
    PLAY_STATE_SIZE,
    _play_kernel,
    box_smooth_into,
    despike_median3,
    first_difference_sigma,
    fresh_state,
    lowpass,
    lowpass_work_size,
    segment_ids,
)
from transforms.kinematics import smoothed_derivative
from transforms.piston_motion import share_out_common_motion, share_state
from transforms.uncertainty import load_band, rope_band

__all__ = [
    "CompensationCarry",
    "CompensationContext",
    "CompensationSettings",
    "compensate",
    "compensate_window",
    "compensation_context",
    "compensation_margins_s",
    "context_sample",
    "context_stride",
    "displacement_noise_sigma",
    "logger_rate_hz",
    "second_difference_sigma",
]

_OUTPUT_SCHEMA = pl.Schema(pl.from_arrow(ROPE_TENSIONS.empty_table()).schema)


@dataclass(frozen=True)
class CompensationSettings:
    """Signal-processing choices of :func:`compensate` (documented defaults).

    Attributes
    ----------
    sample_rate_hz : float or None
        Nominal logger rate [Hz]; spacing above ``gap_factor`` / rate starts a segment.
        None (the default): the record's own rate, :func:`logger_rate_hz`.
    pressure_cutoff_hz : float
        Zero-phase low-pass on the pressures [Hz] (4th-order Butterworth, filtfilt);
        at most 0.4 x the sample rate (below Nyquist) for slow loggers.
    spike_sigmas : float
        A sample further than this many noise sigmas from the median of itself and its
        neighbours is a spike (:func:`transforms.filtering.despike_median3`).
    velocity_window_s : float
        Savitzky-Golay window for the piston velocity [s].
    acceleration_window_s : float
        Savitzky-Golay window for the conveyance acceleration [s].
    differential_cutoff_hz : float
        Half-power frequency of the Gaussian smoothing of each logged displacement [Hz],
        which says which pistons move (:mod:`transforms.piston_motion`); the oil gives
        the fast motion of their sum. The transducer's noise and step are not slow.
    differential_bridge_s : float
        Logger gaps up to this long [s] are bridged for the differential displacement
        (pistons do not jump while the logger drops samples); longer gaps restart it.
    displacement_deadband_m : float
        Half-width of the play operator on the estimated piston displacement [m]: the
        residual noise of the estimate, well inside the seal's presliding range.
    friction_relative_sigma : float
        Relative standard uncertainty of the hoist's calibrated friction law, for the
        95 % band (:mod:`transforms.uncertainty`).
    pressure_sigma_pa : float
        White noise of a raw pressure reading [Pa] (1 sigma), for the band.
    """

    sample_rate_hz: float | None = None
    gap_factor: float = 3.0
    pressure_cutoff_hz: float = 10.0
    spike_sigmas: float = 6.0
    velocity_window_s: float = 0.2
    acceleration_window_s: float = 0.5
    differential_cutoff_hz: float = 0.1
    differential_bridge_s: float = 120.0
    displacement_deadband_m: float = 5e-6
    friction_relative_sigma: float = 0.10
    pressure_sigma_pa: float = 5e3


def _rope_cols(template: str) -> list[str]:
    return [template.format(i=i) for i in ROPES]


def logger_rate_hz(time_s: np.ndarray, *, default_hz: float = 100.0) -> float:
    """A record's nominal sample rate [Hz]: 1 / the median positive time step.

    The median ignores logger gaps and jitter. Filters, windows and segmentation depend
    on it, so a 20 Hz log must not be treated as a 100 Hz one (every step would look like
    a gap). ``default_hz`` when the record has fewer than two distinct times.
    """
    # every stride-th time (200 k steps are plenty): a step then spans stride samples
    stride = max(1, len(time_s) // 200_000)
    steps = np.diff(np.asarray(time_s, dtype=np.float64)[::stride])
    steps = steps[steps > 0]
    if steps.size == 0:
        return default_hz
    return float(stride / np.median(steps))


def displacement_noise_sigma(x: np.ndarray) -> float:
    """Robust white-noise sigma of a sampled signal from its second differences [unit of x].

    For white noise of variance s^2, the second difference has variance 6 s^2; the
    median absolute deviation (x 1.4826) makes the estimate ignore real motion and steps.
    """
    x = np.asarray(x, dtype=np.float64)
    # every step-th second difference (the median of 200 k of them is plenty), as
    # np.diff(x, 2)[::step] without differencing the whole record
    step = max(1, (x.size - 2) // 200_000)
    at = np.arange(0, max(x.size - 2, 0), step)
    return second_difference_sigma((x[at + 2] - x[at + 1]) - (x[at + 1] - x[at]))


def second_difference_sigma(d2: np.ndarray) -> float:
    """White-noise sigma from second differences: 1.4826 MAD / sqrt 6 (non-finite ignored)."""
    d2 = np.asarray(d2, dtype=np.float64)
    d2 = d2[np.isfinite(d2)]
    if d2.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


Buffer = Callable[[str, int], np.ndarray]


def _float_column(series: pl.Series, *, fill: float = np.nan, scale: float = 1.0) -> np.ndarray:
    """A column as a new float64 array (null -> ``fill``), times ``scale`` if not 1.

    Copied chunk by chunk: a day read from Parquet comes as one chunk per row group, and
    ``to_numpy`` would first concatenate them into a polars array of its own.
    """
    out = np.empty(series.len())
    start = 0
    for chunk in series.get_chunks():
        part = chunk.to_numpy()  # a view of the chunk's buffer when it has no nulls
        stop = start + part.shape[0]
        if scale != 1.0:
            np.multiply(part, scale, out=out[start:stop])
        else:
            out[start:stop] = part
        if chunk.null_count():
            out[start:stop][chunk.is_null().to_numpy()] = fill
        start = stop
    return out


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


def _differential_smooth(
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
    sigma / sqrt(2 sqrt(pi) s f_s) of the transducer's white noise (:func:`_smoothed_noise`),
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


def _smoothed_noise(settings: CompensationSettings) -> float:
    """Share of white noise the differential smoother leaves, 1 / sqrt(2 sqrt(pi) s f_s)."""
    return 1.0 / np.sqrt(2.0 * np.sqrt(np.pi) * _smoothing_sigma_samples(settings))


def _long_segments(time_s: np.ndarray, bridge_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Segment id per sample and segment bounds [0, ..., n], split only at gaps > bridge_s."""
    segment = segment_ids(time_s, gap_factor=1.0, nominal_dt_s=bridge_s)
    starts = np.flatnonzero(segment[1:] != segment[:-1]) + 1
    return segment, np.r_[0, starts, time_s.size]


def _viscosity(t_oil_c: np.ndarray | None, hoist: HoistDescription) -> np.ndarray | float:
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
def _rope_kernel(
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
    p_chamber = p_sensor - :func:`physics.branch_loss.sensor_minus_chamber_at` of the
    branch flow ``v_flow`` if ``with_loss`` (``branch`` from
    :func:`~physics.branch_loss.sensor_branch`); the eq 17 law at p_chamber
    (:func:`physics.friction_law.friction_law_at`); friction by Maxwell-slip
    (``mode`` 1, :func:`physics.maxwell_slip.maxwell_slip_step` plus Kv v) or LuGre
    (``mode`` 2, :func:`physics.lugre.lugre_z_step`, :func:`~physics.lugre.lugre_force`),
    none for ``mode`` 0; tension by :func:`physics.tension.rope_tension_n` (eq 2).
    ``state`` = [ran, last x, last time, LuGre z, Maxwell-slip deflections...] carries
    the friction state from the previous block (:func:`transforms.filtering.fresh_state`,
    :data:`ROPE_STATE_BASE` + elements).
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
        if mode != 0:
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


#: Rows the record-wide statistics of :class:`CompensationContext` are read from (about).
CONTEXT_ROWS = 200_000


def context_stride(rows: int) -> int:
    """Every how many rows :func:`compensation_context` looks (row counts from 0)."""
    return max(1, rows // CONTEXT_ROWS)


def context_sample(
    samples: pl.DataFrame | pl.LazyFrame, stride: int, *, offset: int = 0
) -> pl.LazyFrame:
    """Rows i, i + 1, i + 2 of every i divisible by ``stride`` (time-sorted samples), with
    their row number ``_row`` (the first row is number ``offset``: a block of a longer
    record): what :func:`compensation_context` reads, about 3 / ``stride`` of the rows."""
    return (
        samples.lazy()
        .with_row_index("_row", offset=offset)
        .filter(pl.col("_row") % stride < 3)
        .with_columns(pl.col("_row").cast(pl.Int64))
    )


@dataclass(frozen=True)
class CompensationContext:
    """Record-wide statistics of :func:`compensate`, measured once for the whole record.

    A block of a day (issue 16) must be compensated with the day's statistics, not its
    own, to give the day's result; :func:`compensation_context` reads them from a sparse,
    evenly spread sample of the record (:func:`context_sample`).

    Attributes
    ----------
    sample_rate_hz : float
        The logger's rate [Hz] (1 / the median step between neighbouring samples), or
        ``settings.sample_rate_hz`` when set.
    spike_sigma : dict of str to float
        White-noise sigma of each calibrated pressure and logged displacement column
        (:func:`transforms.filtering.first_difference_sigma`), for the despiking.
    displacement_sigma_m : tuple of float
        White-noise sigma of each rope's logged displacement from second differences
        [m] (:func:`second_difference_sigma`), for the differential's play band.
    typical_pressure_pa : float
        Median of the ropes' mean calibrated pressure [Pa] (the presliding range's F_s).
    has_x : bool
        Every rope's displacement is logged somewhere in the record.
    """

    sample_rate_hz: float
    spike_sigma: dict[str, float]
    displacement_sigma_m: tuple[float, ...]
    typical_pressure_pa: float
    has_x: bool


def _calibrated(frame: pl.DataFrame, column: str, hoist: HoistDescription) -> np.ndarray:
    """A column as a new float64 array; a pressure with its sensor's calibration
    applied, p = (reading - offset) / gain (hoist ``[[sensors]]``), in place."""
    values = _float_column(frame[column])
    for sensor in hoist.sensors:
        if column == f"p{sensor.cylinder}_pa":
            np.subtract(values, sensor.offset_pa, out=values)
            np.divide(values, sensor.gain, out=values)
    return values


def compensation_context(
    sample: pl.DataFrame, hoist: HoistDescription, settings: CompensationSettings, stride: int
) -> CompensationContext:
    """:class:`CompensationContext` from a :func:`context_sample` of the record."""
    row = sample["_row"].to_numpy()
    first = row % stride == 0
    pair = np.flatnonzero(first[:-1] & (row[1:] == row[:-1] + 1))
    triple = pair[(pair + 2 < row.size)]
    triple = triple[row[np.minimum(triple + 2, row.size - 1)] == row[triple] + 2]
    epoch_us = sample["time_utc"].dt.cast_time_unit("us").to_physical().to_numpy()
    steps = (epoch_us[pair + 1] - epoch_us[pair]) * 1e-6
    steps = steps[steps > 0]
    rate_hz = settings.sample_rate_hz or (float(1.0 / np.median(steps)) if steps.size else 100.0)
    spike_sigma: dict[str, float] = {}
    p_cols, x_cols = _rope_cols("p{i}_pa"), _rope_cols("x{i}_m")
    pressures = []
    for column in (*p_cols, *x_cols):
        values = (
            _calibrated(sample, column, hoist)
            if column in sample.columns
            else np.full(row.size, np.nan)
        )
        spike_sigma[column] = first_difference_sigma(values[pair + 1] - values[pair])
        if column in p_cols:
            pressures.append(values[first])
    displacement_sigma = []
    has_x = True
    for column in x_cols:
        x = _float_column(sample[column]) if column in sample.columns else np.full(row.size, np.nan)
        has_x = has_x and bool(np.isfinite(x).any())
        d2 = (x[triple + 2] - x[triple + 1]) - (x[triple + 1] - x[triple])
        displacement_sigma.append(second_difference_sigma(d2))
    mean = _mean_horizontal(pressures) if pressures and row.size else np.empty(0)
    typical = float(np.nanmedian(mean)) if np.isfinite(mean).any() else 0.0
    return CompensationContext(
        sample_rate_hz=rate_hz,
        spike_sigma=spike_sigma,
        displacement_sigma_m=tuple(displacement_sigma),
        typical_pressure_pa=typical,
        has_x=has_x,
    )


@dataclass
class CompensationCarry:
    """The sequential state of :func:`compensate_window` from one block to the next.

    Each array is a resumable kernel's state (:func:`transforms.filtering.fresh_state`).
    The filters before them are not causal, so a block is compensated on a window with a
    margin either side (:func:`compensation_margins_s`); the kernels that feed a second
    filter (the oil's common mode, the pistons' share-out, the play operators) resume
    ``resume_s`` before the block's start, the friction and trip labels at its start.
    """

    common: np.ndarray
    differential: list[np.ndarray]
    share: np.ndarray
    played: list[np.ndarray]
    rope: list[np.ndarray]
    labels: np.ndarray

    @classmethod
    def fresh(cls, elements: int) -> CompensationCarry:
        ropes = range(len(ROPES))
        return cls(
            common=fresh_state(COMMON_MODE_STATE_SIZE),
            differential=[fresh_state(PLAY_STATE_SIZE) for _ in ropes],
            share=share_state(len(ROPES)),
            played=[fresh_state(PLAY_STATE_SIZE) for _ in ropes],
            rope=[fresh_state(ROPE_STATE_BASE + elements) for _ in ropes],
            labels=fresh_state(LABEL_STATE_SIZE),
        )


def compensation_margins_s(settings: CompensationSettings) -> tuple[float, float]:
    """(resume, halo) [s] of block processing (:func:`compensate_window`).

    ``resume``: the first-stage kernels restart this long before a block, so the piston
    velocity filter (``velocity_window_s``) has exact input at the block's edges.
    ``halo``: samples this far beyond (resume + block + resume) are read so that the
    zero-phase filters have forgotten the window's edges: 10 periods of the pressure
    low-pass, the differential smoother's 4 sigma plus its median-padded edge, twice
    each Savitzky-Golay window, and at least 30 s.
    """
    resume = max(1.0, 2.0 * settings.velocity_window_s)
    smoother_s = 4.0 * 0.1325 / settings.differential_cutoff_hz
    halo = max(
        30.0,
        10.0 / settings.pressure_cutoff_hz,
        2.0 * (smoother_s + 1.0 / settings.differential_cutoff_hz),
        2.0 * settings.acceleration_window_s,
        2.0 * settings.velocity_window_s,
    )
    return resume, halo


def _continues(segment: np.ndarray, at: int) -> float:
    """1.0 when sample ``at`` continues the gap-free segment of sample ``at - 1``."""
    return 1.0 if 0 < at < segment.size and segment[at] == segment[at - 1] else 0.0


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

    See Also
    --------
    compensate_window : the same on a block of a longer record, with its state carried
        (what ``ropeload run`` uses, :mod:`pipelines.blocks`).
    """
    settings = settings or CompensationSettings()
    frame = _input_frame(samples)
    if frame.height == 0:
        return pl.DataFrame(schema=_OUTPUT_SCHEMA)
    stride = context_stride(frame.height)
    context = compensation_context(context_sample(frame, stride).collect(), hoist, settings, stride)
    result, _ = compensate_window(frame, hoist, context=context, settings=settings, effects=effects)
    return result


def _input_frame(samples: pl.DataFrame | pl.LazyFrame) -> pl.DataFrame:
    """The columns :func:`compensate_window` reads, collected and sorted by time."""
    lazy = samples.lazy()
    available = set(lazy.collect_schema().names())
    # only the columns used below (a landed frame also carries e.g. long provenance
    # strings, which sorting would otherwise have to move)
    wanted = ["time_utc", "depth_m", "speed_m_s", "oil_temp_c", *_rope_cols("p{i}_pa")]
    wanted += _rope_cols("x{i}_m")
    frame = lazy.select(c for c in wanted if c in available).collect()
    if frame.height and not frame["time_utc"].is_sorted():
        frame = frame.sort("time_utc")
    return frame


def compensate_window(
    samples: pl.DataFrame | pl.LazyFrame,
    hoist: HoistDescription,
    *,
    context: CompensationContext,
    settings: CompensationSettings | None = None,
    effects: set[str] | None = None,
    carry: CompensationCarry | None = None,
    block_start_utc: dt.datetime | None = None,
    block_end_utc: dt.datetime | None = None,
) -> tuple[pl.DataFrame, CompensationCarry]:
    """Compensate the block ``block_start_utc <= t < block_end_utc`` of a longer record.

    ``samples`` hold the block and the margins of :func:`compensation_margins_s` either
    side (less at the record's ends); ``context`` the record's statistics; ``carry`` the
    state the previous block returned (None for the record's first block, which must
    then start at the samples' start). Returns the block's ``ROPE_TENSIONS`` rows and the
    state for the next block, which starts at ``block_end_utc``. Called on the whole
    record at once (no carry, no bounds) it is :func:`compensate`; block by block it
    gives the same rows (tests/transforms/test_blocks.py states the tolerance).
    """
    settings = settings or CompensationSettings()
    effects = set(hoist.model.effects if effects is None else effects)
    p_cols, x_cols = _rope_cols("p{i}_pa"), _rope_cols("x{i}_m")
    frame = _input_frame(samples)
    n = frame.height
    law = hoist.friction_law
    presliding = "presliding_hysteresis" in effects
    if presliding:
        stiffness, weights = maxwell_slip_elements(
            law.presliding_elements, law.bristle_stiffness_n_m
        )
    else:
        stiffness, weights = np.ones(1), np.ones(1)
    resuming = carry is not None  # a block after the record's first
    carry = carry or CompensationCarry.fresh(weights.shape[0])
    if n == 0:
        return pl.DataFrame(schema=_OUTPUT_SCHEMA), carry
    workers = min(len(ROPES), os.cpu_count() or 1)

    # epoch microseconds x 1e-6 (the arithmetic of .astype(float) * 1e-6), chunk by chunk
    epoch_us = frame["time_utc"].dt.cast_time_unit("us").to_physical()
    time_s = _float_column(epoch_us, scale=1e-6)
    rate_hz = context.sample_rate_hz
    settings = replace(
        settings,
        sample_rate_hz=rate_hz,
        pressure_cutoff_hz=min(settings.pressure_cutoff_hz, 0.4 * rate_hz),
    )
    resume_s, _ = compensation_margins_s(settings)
    epoch = epoch_us.to_numpy()

    def index(at: dt.datetime | None, shift_s: float, default: int) -> int:
        if at is None:
            return default
        micros = _epoch_us(at) + round(shift_s * 1e6)
        return int(np.searchsorted(epoch, micros, side="left"))

    core_lo, core_hi = index(block_start_utc, 0.0, 0), index(block_end_utc, 0.0, n)
    stage_lo = index(block_start_utc, -resume_s, 0) if resuming else 0
    handover = index(block_end_utc, -resume_s, n)
    stage_hi = index(block_end_utc, resume_s, n)
    dt_nominal = 1.0 / rate_hz
    segment = segment_ids(time_s, gap_factor=settings.gap_factor, nominal_dt_s=dt_nominal)
    nxt = CompensationCarry(
        common=carry.common,
        differential=list(carry.differential),
        share=carry.share,
        played=list(carry.played),
        rope=list(carry.rope),
        labels=carry.labels,
    )

    def staged(run: Callable[[int, int, np.ndarray], None], seg: np.ndarray, state: np.ndarray):
        """Run a first-stage kernel over [stage_lo, stage_hi) resuming ``state``; returns
        its state at the hand-over to the next block."""
        state = state.copy()
        state[1] = _continues(seg, stage_lo)
        run(stage_lo, handover, state)
        saved = state.copy()
        state[1] = _continues(seg, handover)
        run(handover, stage_hi, state)
        return saved

    # Work arrays are reused per thread: every fresh 70 MB array costs page faults, and
    # freeing one interrupts the other thread (TLB shootdown), which cost more than the
    # arithmetic of a rope.
    local = threading.local()

    def buffer(name: str, size: int) -> np.ndarray:
        arrays = local.__dict__.setdefault("arrays", {})
        if name not in arrays or arrays[name].size < size:
            arrays[name] = np.empty(size)
        return arrays[name][:size]

    cutoff = settings.pressure_cutoff_hz
    n_sigmas = settings.spike_sigmas

    def pressure(column: str) -> np.ndarray:
        """Calibrated, despiked and low-passed, all in one new array."""
        values = _calibrated(frame, column, hoist)
        sigma = context.spike_sigma.get(column)
        despike_median3(values, segment, n_sigmas=n_sigmas, out=values, sigma=sigma)
        return lowpass(
            values,
            segment,
            sample_rate_hz=rate_hz,
            cutoff_hz=cutoff,
            out=values,
            # the rope jobs reuse it on this thread
            work=buffer("work_a", lowpass_work_size(n, sample_rate_hz=rate_hz, cutoff_hz=cutoff)),
        )

    def displacement(column: str) -> np.ndarray:
        values = _float_column(frame[column]) if column in frame.columns else np.full(n, np.nan)
        sigma = context.spike_sigma.get(column)
        return despike_median3(values, segment, n_sigmas=n_sigmas, out=values, sigma=sigma)[0]

    def kinematics() -> tuple[np.ndarray, dict[str, pl.Series]]:
        """Conveyance acceleration, then the trip labels that depend on it."""
        speed = _float_column(frame["speed_m_s"], fill=0.0)
        accel = smoothed_derivative(
            speed, segment, dt_s=dt_nominal, window_s=settings.acceleration_window_s
        )
        depth = _float_column(frame["depth_m"])
        state = carry.labels.copy()
        state[1] = _continues(segment, core_lo)
        window = slice(core_lo, core_hi)
        labels = trip_label_columns(
            time_s[window], speed[window], depth[window], accel[window], segment[window],
            hoist, state,
        )  # fmt: skip
        nxt.labels = state
        return accel, labels

    has_x = context.has_x
    long_segment, long_bounds = _long_segments(time_s, settings.differential_bridge_s)

    t_oil = None
    if "viscosity_temperature" in effects and frame["oil_temp_c"].null_count() < n:
        temperature = frame["oil_temp_c"]
        if temperature.null_count():
            temperature = temperature.fill_null(strategy="forward").fill_null(strategy="backward")
        t_oil = _float_column(temperature)

    with_branch_loss = bool({"pipe_laminar_loss", "local_loss"} & effects)
    with_friction = "seal_friction" in effects
    law_lines = law_array(law)
    mode = 0 if not with_friction else (1 if presliding else 2)
    area = hoist.cylinders.bore_area_m2
    branch = sensor_branch(hoist)
    gap_s = settings.gap_factor * dt_nominal
    no_array = np.zeros(1)

    # the sensor's noise after the low-pass, as a force on the piston (the band)
    pressure_noise_n = (
        settings.pressure_sigma_pa
        * np.sqrt(min(1.0, 2.0 * settings.pressure_cutoff_hz / rate_hz))
        * hoist.cylinders.bore_area_m2
    )
    deadband = settings.displacement_deadband_m
    if deadband < 0:
        raise ValueError(f"displacement_deadband_m must be >= 0, got {deadband}")

    def smoothed_logged(k: int) -> np.ndarray | None:
        """Rope k's logged displacement, smoothed and played (None without a logged x)."""
        if not has_x:
            return None
        smooth = _differential_smooth(x_jobs[k].result(), long_bounds, settings, buffer=buffer)
        # the result is a per-thread work array: played into a copy of its own
        played = np.empty(n)
        half_width = 3.0 * context.displacement_sigma_m[k] * _smoothed_noise(settings)

        def run(lo: int, hi: int, state: np.ndarray) -> None:
            _play_kernel(smooth[lo:hi], long_segment[lo:hi], half_width, played[lo:hi], state)

        nxt.differential[k] = staged(run, long_segment, carry.differential[k])
        return played

    def piston_motion() -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """Each piston's displacement (the common mode shared out by the logged motion)
        and its blind motion since last seen sliding (:mod:`transforms.piston_motion`)."""
        logged = [job.result() for job in smooth_jobs]
        common = common_mode.result()
        if any(d is None for d in logged):
            never_seen = np.full(n, np.inf)  # pressure only: no piston is seen sliding
            # shared by the ropes: not overwritten
            return tuple(common for _ in ROPES), tuple(never_seen for _ in ROPES)
        blind = tuple(np.empty(n) for _ in ROPES)

        def run(lo: int, hi: int, state: np.ndarray) -> None:
            _, parts = share_out_common_motion(
                common[lo:hi],
                tuple(d[lo:hi] for d in logged),
                segment[lo:hi],
                overwrite_logged=True,  # the smoothed copies are this job's own
                elastic_half_width_m=len(ROPES) * presliding_range_m,
                # from any state, a seal saturates once it has moved 2 F_s / sigma_0
                seen_reset_m=2.0 * presliding_range_m,
                state=state,
            )
            for whole, part in zip(blind, parts, strict=True):
                whole[lo:hi] = part

        nxt.share = staged(run, segment, carry.share)
        return tuple(logged), blind

    # F_s / sigma_0 at the record's median pressure: one seal's presliding range
    presliding_range_m = 0.0
    if mode != 0 and law.bristle_stiffness_n_m > 0:
        p_typical = context.typical_pressure_pa
        static = friction_law_at(p_typical if np.isfinite(p_typical) else 0.0, law_lines)[1]
        presliding_range_m = static / float(law.bristle_stiffness_n_m)

    def rope(k: int) -> dict[str, np.ndarray]:
        """Tensions of rope k; its inputs are futures of the jobs queued before it."""
        i = ROPES[k]
        played = buffer("work_b", n)
        estimate = motion_share.result()[0][k]

        # transforms.filtering.play_operator (the estimate is not overwritten)
        def run_play(lo: int, hi: int, state: np.ndarray) -> None:
            _play_kernel(estimate[lo:hi], segment[lo:hi], deadband, played[lo:hi], state)

        nxt.played[k] = staged(run_play, segment, carry.played[k])
        p_sensor = np.ascontiguousarray(p_jobs[k].result())
        nu = nu_job.result()
        nu_arr = np.ascontiguousarray(np.atleast_1d(np.asarray(nu, dtype=np.float64)))
        out = {name: np.empty(n) for name in ("p_chamber", "tension_raw", "tension")}
        # this rope's despiked displacement is consumed (the differential is done): its
        # array takes the friction, one fresh day-long array fewer
        out["friction"] = x_jobs[k].result() if has_x else np.empty(n)
        v_flow = no_array
        if with_branch_loss:
            v_flow = np.zeros(n)
            v_flow[stage_lo:stage_hi] = smoothed_derivative(
                played[stage_lo:stage_hi],
                segment[stage_lo:stage_hi],
                dt_s=dt_nominal,
                window_s=settings.velocity_window_s,
                out=buffer("work_a", stage_hi - stage_lo),
            )
        window = slice(core_lo, core_hi)
        state = carry.rope[k].copy()
        _rope_kernel(
            played[window],
            time_s[window],
            gap_s,
            dt_nominal,
            p_sensor[window],
            with_branch_loss,
            v_flow[window] if v_flow.size == n else v_flow,
            nu_arr[window] if nu_arr.size == n else nu_arr,
            branch,
            law_lines,
            mode,
            stiffness,
            weights,
            float(law.bristle_stiffness_n_m),
            float(law.bristle_damping_n_s_m),
            area,
            out["p_chamber"][window],
            out["friction"][window],
            out["tension_raw"][window],
            out["tension"][window],
            state,
        )
        nxt.rope[k] = state
        estimates, blind = motion_share.result()
        # rope k's estimate is consumed (played above) and its blind motion is read
        # before each hi is written: they take the band, unless shared by the ropes
        own = estimates[k] is not estimates[(k + 1) % len(ROPES)]
        lo, hi = rope_band(
            out["tension"][window],
            out["friction"][window] if mode != 0 else np.zeros(core_hi - core_lo),
            out["p_chamber"][window],
            blind[k][window],
            static_law_n=tuple(law.static_n) if mode != 0 else (0.0, 0.0),
            bristle_stiffness_n_m=float(law.bristle_stiffness_n_m) if mode != 0 else 0.0,
            gaussian_sigma_n=(
                settings.friction_relative_sigma if mode != 0 else 0.0,
                pressure_noise_n,
            ),
            out=(estimates[k][window], blind[k][window]) if own else None,
        )
        return {
            f"p_chamber{i}_pa": out["p_chamber"][window],
            f"friction{i}_n": out["friction"][window],
            f"tension_raw{i}_n": out["tension_raw"][window],
            f"tension{i}_n": out["tension"][window],
            f"tension{i}_lo_n": lo,
            f"tension{i}_hi_n": hi,
        }

    # One pool for the whole computation; every job waits only for jobs queued before it
    # or for the common mode, which this thread computes. The trip labels go first: they
    # are the longest job that does not wait for the pressures, so they overlap the
    # pressure filters instead of running alone after the ropes. The ropes are queued
    # right away: each starts on its differential displacement while the common mode is
    # still being integrated. The numba kernels and large numpy operations release the
    # GIL, so the jobs run side by side.
    common_mode: Future[np.ndarray] = Future()
    with ThreadPoolExecutor(max_workers=workers) as pool:
        kinematics_job = pool.submit(kinematics)
        p_jobs = [pool.submit(pressure, c) for c in p_cols]
        x_jobs = [pool.submit(displacement, c) for c in x_cols]
        nu_job = pool.submit(_viscosity, t_oil, hoist)
        smooth_jobs = [pool.submit(smoothed_logged, k) for k in range(len(ROPES))]
        motion_share = pool.submit(piston_motion)
        rope_jobs = [pool.submit(rope, k) for k in range(len(ROPES))]
        try:
            # NaN stands for null from here on (the frame version filled NaN with null)
            pressures = [job.result() for job in p_jobs]
            p_mean = _mean_horizontal(pressures)
            common = np.empty(n)

            def run_common(lo: int, hi: int, state: np.ndarray) -> None:
                if hi > lo:
                    common[lo:hi] = common_mode_displacement(
                        p_mean[lo:hi], segment[lo:hi], hoist, state=state
                    )

            nxt.common = staged(run_common, segment, carry.common)
            common_mode.set_result(common)
        except BaseException as error:
            common_mode.set_exception(error)  # the rope jobs fail instead of waiting
            raise
        accel, labels = kinematics_job.result()
        per_rope = [job.result() for job in rope_jobs]
    window = slice(core_lo, core_hi)
    m = core_hi - core_lo
    columns = {name: values for part in per_rope for name, values in part.items()}
    # the mean pressure's array takes the raw load sum
    load_raw = p_mean[window]
    load = np.empty(m)
    _load_kernel(
        tuple(columns[c] for c in _rope_cols("tension_raw{i}_n")),
        tuple(columns[c] for c in _rope_cols("tension{i}_n")),
        load_raw,
        load,
    )

    load_lo, load_hi = load_band(
        load,
        [columns[c] for c in _rope_cols("tension{i}_lo_n")],
        [columns[c] for c in _rope_cols("tension{i}_hi_n")],
        [columns[c] for c in _rope_cols("tension{i}_n")],
        [columns[c] for c in _rope_cols("friction{i}_n")],
        gaussian_sigma_n=(settings.friction_relative_sigma if mode != 0 else 0.0, pressure_noise_n),
    )

    def nullable(name: str, values: np.ndarray, dtype: type = pl.Float64) -> pl.Series:
        series = pl.Series(name, values, dtype=dtype)
        return series.fill_nan(None) if np.isnan(values).any() else series

    rows = frame.slice(core_lo, m)
    accel_up = np.negative(accel[window])
    out: dict[str, pl.Series] = {
        "time_utc": rows["time_utc"],
        "depth_m": rows["depth_m"],
        "speed_m_s": rows["speed_m_s"],
        "acceleration_up_m_s2": nullable("acceleration_up_m_s2", accel_up),
        **labels,
        **{c: nullable(c, v[window]) for c, v in zip(p_cols, pressures, strict=True)},
        **{
            name: nullable(name, values, pl.Float32)  # the band (schemas.tables)
            if name.endswith(("_lo_n", "_hi_n"))
            else pl.Series(name, values, dtype=pl.Float64)
            for name, values in columns.items()
        },
        "load_raw_n": pl.Series("load_raw_n", load_raw, dtype=pl.Float64),
        "load_n": pl.Series("load_n", load, dtype=pl.Float64),
        "load_lo_n": nullable("load_lo_n", load_lo, pl.Float32),
        "load_hi_n": nullable("load_hi_n", load_hi, pl.Float32),
    }
    result = pl.DataFrame([out[name] for name in _OUTPUT_SCHEMA])
    if result.schema != _OUTPUT_SCHEMA:
        result = result.cast(dict(_OUTPUT_SCHEMA))
    return result, nxt


def _epoch_us(at: dt.datetime) -> int:
    """Microseconds since the epoch of a datetime (naive: UTC)."""
    at = at.replace(tzinfo=dt.UTC) if at.tzinfo is None else at
    delta = at - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
    return (delta.days * 86_400 + delta.seconds) * 1_000_000 + delta.microseconds


@njit(cache=True, nogil=True)
def _load_kernel(raw, compensated, load_raw, load):  # pragma: no cover - numba
    """Row sums of the rope tensions (polars ``sum_horizontal``: in column order)."""
    for i in range(load.shape[0]):
        total_raw = raw[0][i]
        total = compensated[0][i]
        for k in range(1, len(raw)):
            total_raw += raw[k][i]
            total += compensated[k][i]
        load_raw[i] = total_raw
        load[i] = total


def _mean_horizontal(arrays: list[np.ndarray]) -> np.ndarray:
    """polars ``mean_horizontal`` of NaN-for-null arrays (nulls ignored), as an array."""
    out = np.empty(arrays[0].shape[0]) if arrays else np.empty(0)
    if arrays:
        columns = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in arrays)
        _mean_horizontal_kernel(columns, out)
    return out


@njit(cache=True, nogil=True)
def _mean_horizontal_kernel(arrays, out):  # pragma: no cover - numba
    """Row mean of the non-NaN values (sum in column order / count), NaN if none."""
    for i in range(out.shape[0]):
        total = 0.0
        count = 0
        for k in range(len(arrays)):
            v = arrays[k][i]
            if not np.isnan(v):
                total += v
                count += 1
        out[i] = total / count if count else np.nan
