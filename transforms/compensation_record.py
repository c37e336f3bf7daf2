"""What a record gives the compensation before and between its blocks.

:class:`CompensationSettings` (the signal-processing choices), the record's statistics
(:class:`CompensationContext`, read once from a sparse sample of the whole record) and
the sequential state carried from one block to the next (:class:`CompensationCarry`),
with the block margins they imply (:func:`compensation_margins_s`). The compensation
itself: :mod:`transforms.compensation`.
"""

from __future__ import annotations

import datetime as dt
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl
from numba import njit

from physics.closed_volume import COMMON_MODE_STATE_SIZE
from physics.conveyance import quantum_of_turns, reading_turns
from physics.trip_rule import LABEL_STATE_SIZE, STANDSTILL_SPEED_M_S, segment_ids
from physics.white_noise import difference_noise_sigma
from schemas.hoist import HoistDescription
from schemas.tables import ROPES
from transforms.alarm_events import flatline_runs, frozen_runs, step_of_changes
from transforms.alarm_rules import rule_thresholds
from transforms.filtering import (
    PLAY_STATE_SIZE,
    despike_median3,
    fresh_state,
    sampled_differences,
)
from transforms.piston_motion import share_state
from transforms.rope_identification import (
    IDENTIFY_SPAN,
    identify_from_means,
    pistons_moved,
    record_means,
)
from transforms.seal_drift import (
    PLAYED_TRAVEL_STATE_SIZE,
    RINGING_BANDWIDTH_HZ,
    drift_travel,
    seals_drift,
)
from transforms.stick_slip import stick_slip_state
from transforms.stick_slip_band import MAX_SOLUTIONS, RopeSprings, prior_rope_springs
from transforms.stop_continuity import LOOK_AHEAD_S, continuity_state

__all__ = [
    "CONTEXT_ROWS",
    "DEFAULT_FRICTION_RELATIVE_SIGMA",
    "ROPE_STATE_BASE",
    "CompensationCarry",
    "CompensationContext",
    "CompensationSettings",
    "at_rest",
    "calibrated",
    "compensation_context",
    "compensation_margins_s",
    "context_sample",
    "context_stride",
    "departure_from_median",
    "depth_turns",
    "disagreeing_as_unknown",
    "displacement_noise_sigma",
    "flatlined_samples",
    "float_column",
    "identification_means",
    "logger_rate_hz",
    "mean_horizontal",
    "rope_cols",
    "without_flatlined",
]

_LOG = logging.getLogger(__name__)

#: The friction law's relative standard uncertainty where neither the settings nor the
#: hoist's description state one: a law given without its calibration's uncertainty,
#: taken as about twice a rig's (paper Table 1's Coulomb line 4.7 %,
#: :func:`transforms.friction_lines.law_relative_sigma`). On the independent simulator's
#: validation days, whose descriptions state none, the band at 10 % held 97-100 % of
#: the stop windows (``benchmarks/eval_compensation.py``).
DEFAULT_FRICTION_RELATIVE_SIGMA = 0.10

#: Length of the rope kernel's state before its Maxwell-slip elements
#: (:func:`transforms.compensation_kernels.rope_kernel`).
ROPE_STATE_BASE = 4


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
    friction_relative_sigma : float or None
        Relative standard uncertainty (1 sigma) of the hoist's calibrated friction law,
        for the 95 % band (:mod:`transforms.uncertainty`). None (the default): what the
        hoist's description states (``[friction] relative_uncertainty``, which
        ``ropeload calibrate`` writes from its fit,
        :func:`transforms.friction_lines.law_relative_sigma`), else
        :data:`DEFAULT_FRICTION_RELATIVE_SIGMA`; :meth:`friction_sigma` resolves it.
    pressure_sigma_pa : float
        White noise of a raw pressure reading [Pa] (1 sigma), for the band.
    rope_springs : bool
        Identify the head ropes from the record and solve each piston's stick-slip on
        its rope spring (:mod:`transforms.stick_slip`) where the logged x allow it; False:
        always share out the oil's motion by the logged x (:mod:`transforms.piston_motion`).
    rope_stiffness_sigma : float
        Where nothing identifies the head ropes (no logged x, or one that shows no
        piston motion: a record at rest) and the description states no
        stiffness factors of its own (``[ropes] head_rope_stiffness_factors``, then
        taken as known), their relative stiffness spread about the nominal EA (1 sigma):
        the stick-slip solution runs on the sigma points of that spread and takes their
        mean (:func:`transforms.stick_slip_band.prior_rope_springs`); 0: the share-out
        of :mod:`transforms.piston_motion` instead. The default 0.05 is the
        identification's search range, 0.9-1.1
        (:data:`transforms.rope_identification.STIFFNESS_BOUNDS`), as two standard
        deviations: real ropes of one hoist differ by several percent.
    band_member_step_s : float
        0 (the default): the stick-slip band's members run at the sensors' rate, each
        costing what the estimate costs. > 0: they run on means of this many seconds
        where the pressures hold still (:mod:`transforms.band_members`; 0.1 s made the
        compute 1.5x faster, its CPU 2.3x less, the band the same to tens of newtons at
        most samples but moved by up to ~0.3 % of the load at single stops: a
        backfill's choice; session 33 on the validation days 101-104: the load band's
        edges at the stop windows moved by a median 0.02 % of the load, at most 0.31 %,
        0.88 % at one sample of a deceleration, and the coverage went 97 / 98 / 95 /
        90 % -> 98 / 98 / 94 / 90 % at the same median half-widths).
        A whole fraction of the blocks' resume margin (:func:`compensation_margins_s`,
        1 s by default: 0.1, 0.2, 0.25, 0.5 or 1 s), so that the windows start where a
        block's first stage does.
    stop_continuity : bool
        True (the default): at each arrival the stick-slip solution's seals are set so
        that the load at rest continues the trip's steady run, the tail ropes' change
        added (:mod:`transforms.stop_continuity`); False: the solution as it is.
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
    friction_relative_sigma: float | None = None
    pressure_sigma_pa: float = 5e3
    rope_springs: bool = True
    rope_stiffness_sigma: float = 0.05
    band_member_step_s: float = 0.0
    stop_continuity: bool = True

    def __post_init__(self) -> None:
        if not 0.0 <= self.rope_stiffness_sigma < 0.5:
            raise ValueError(
                f"rope_stiffness_sigma {self.rope_stiffness_sigma}: a relative spread in "
                "[0, 0.5) (0: the share-out without x)"
            )
        sigma = self.friction_relative_sigma
        if sigma is not None and not 0.0 <= sigma < 0.5:
            raise ValueError(f"friction_relative_sigma {sigma}: a relative uncertainty in [0, 0.5)")
        step = self.band_member_step_s
        if step == 0:
            return
        resume_s = compensation_margins_s(self)[0]
        if not (0 < step <= resume_s and abs(resume_s / step - round(resume_s / step)) < 1e-9):
            raise ValueError(
                f"band_member_step_s {step} s: 0, or a whole fraction of the resume margin "
                f"{resume_s:g} s (e.g. 0.1, 0.2, 0.25, 0.5)"
            )

    def friction_sigma(self, hoist: HoistDescription) -> float:
        """The friction law's relative standard uncertainty the band takes for ``hoist``:
        :attr:`friction_relative_sigma` if given, else the description's
        ``[friction] relative_uncertainty``, else :data:`DEFAULT_FRICTION_RELATIVE_SIGMA`.

        >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
        >>> hoist = load_hoist(EXAMPLE_HOIST)
        >>> CompensationSettings().friction_sigma(hoist) == hoist.friction.relative_uncertainty
        True
        >>> CompensationSettings(friction_relative_sigma=0.2).friction_sigma(hoist)
        0.2
        """
        if self.friction_relative_sigma is not None:
            return self.friction_relative_sigma
        stated = hoist.friction.relative_uncertainty
        return DEFAULT_FRICTION_RELATIVE_SIGMA if stated is None else stated


def rope_cols(template: str) -> list[str]:
    """``template`` formatted with each rope number, e.g. ``p{i}_pa`` -> p1_pa ... p4_pa."""
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

    :func:`physics.white_noise.difference_noise_sigma` of (at most ~200 k of) its second
    differences: the median absolute deviation ignores real motion and steps.
    """
    x = np.asarray(x, dtype=np.float64)
    # every step-th second difference (the median of 200 k of them is plenty), as
    # np.diff(x, 2)[::step] without differencing the whole record
    step = max(1, (x.size - 2) // 200_000)
    at = np.arange(0, max(x.size - 2, 0), step)
    return difference_noise_sigma((x[at + 2] - x[at + 1]) - (x[at + 1] - x[at]), 2)


def float_column(series: pl.Series, *, fill: float = np.nan, scale: float = 1.0) -> np.ndarray:
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
        (:func:`physics.white_noise.difference_noise_sigma`), for the despiking.
    displacement_sigma_m : tuple of float
        White-noise sigma of each rope's logged displacement from second differences
        [m] (:func:`~physics.white_noise.difference_noise_sigma` of second differences),
        for the differential's play band.
    typical_pressure_pa : float
        Median of the ropes' mean calibrated pressure [Pa] (the presliding range's F_s).
    has_x : bool
        Every rope's displacement is logged somewhere in the record.
    depth_sigma_m : float
        The logged depth's white noise [m] (:func:`physics.white_noise.
        difference_noise_sigma` of the second differences of the sample's consecutive
        triplets), the standstill of a speed taken from it.
    depth_quantum_m : float
        The depth's reading step [m] (:func:`physics.conveyance.reading_quantum_m` of
        every row's changes; 0: a continuous reading): one step is no motion.
    sensor_departures : tuple of float
        Each sensor's signed median departure from the others at the record's rests
        (:func:`sensor_departures`; 0 where the rests show none beyond their noise, and
        for an offset sensor). Empty: none.
    offset_sensors : tuple of bool
        Each sensor whose reading departs from the others' at the record's rests, in
        its median there, by more than the ``sensor_disagreement`` limit
        (:func:`offset_sensors`): a sensor off by a constant (a bad calibration), not a
        pressure anywhere in the record. Empty: none.
    pressure_step_pa : float
        The largest reading step of the calibrated pressures [Pa]
        (:func:`transforms.alarm_events.step_of_changes` of the sample's pairs): a
        logger's rounding, which the seals' drift play and the band's sensor part take in
        (:func:`transforms.seal_drift.drift_play_pa`).
    rope_springs : RopeSprings or None
        The head ropes' constants identified from the record
        (:mod:`transforms.rope_identification`), or where nothing identifies them (no
        logged x, or one that shows no piston motion) the ropes the description states
        (``head_rope_stiffness_factors``, four) or else their prior
        (:func:`transforms.stick_slip_band.prior_rope_springs`, ``rope_stiffness_sigma``);
        None: a logged x that shows motion but no constants fit it to 0.5 mm, or
        ``CompensationSettings(rope_springs=False)``, or nothing identifies them, no
        ropes are stated and ``rope_stiffness_sigma=0``: the pistons' motion is shared
        out by the logged x (:mod:`transforms.piston_motion`).
    """

    sample_rate_hz: float
    spike_sigma: dict[str, float]
    displacement_sigma_m: tuple[float, ...]
    typical_pressure_pa: float
    has_x: bool
    rope_springs: RopeSprings | None = None
    depth_sigma_m: float = 0.0
    depth_quantum_m: float = 0.0
    pressure_step_pa: float = 0.0
    offset_sensors: tuple[bool, ...] = ()
    sensor_departures: tuple[float, ...] = ()


def depth_turns(frame: pl.DataFrame) -> tuple[np.ndarray, np.ndarray] | None:
    """The reversals of every row's logged depth (:func:`physics.conveyance.
    reading_turns`; ``frame`` sorted by time, a block of the record or all of it), None
    without a depth column: ``compensation_context``'s ``depth_turns``."""
    if "depth_m" not in frame.columns:
        return None
    return reading_turns(np.diff(float_column(frame["depth_m"])))


def calibrated(frame: pl.DataFrame, column: str, hoist: HoistDescription) -> np.ndarray:
    """A column as a new float64 array; a pressure with its sensor's calibration
    applied, p = (reading - offset) / gain (hoist ``[[sensors]]``), in place."""
    values = float_column(frame[column])
    for sensor in hoist.sensors:
        if column == f"p{sensor.cylinder}_pa":
            sensor.calibrated(values, out=values)
    return values


def departure_from_median(pressures: Sequence[np.ndarray], floor_pa: float = 0.0) -> np.ndarray:
    """(sensors, samples): each sensor's pressure less the median of the sensors logged
    at the sample, over that median (NaN where the sensor, or every sensor, is unknown,
    and where the median is below ``floor_pa``).

    >>> departure_from_median([np.array([4.0e6]), np.array([4.0e6]), np.array([5.0e6])])
    array([[0.  ],
           [0.  ],
           [0.25]])
    """
    columns = tuple(np.ascontiguousarray(p, dtype=np.float64) for p in pressures)
    out = np.empty((len(columns), columns[0].shape[0]))
    _departure_kernel(columns, float(floor_pa), out)
    return out


@njit(cache=True, nogil=True)
def _departure_kernel(arrays, floor_pa, out):  # pragma: no cover - numba
    """Per sample: the median of the non-NaN values (insertion-sorted, the middle one or
    two), then each value's departure from it over it (NaN where the value is NaN or the
    median is below ``floor_pa`` or unknown)."""
    m = len(arrays)
    values = np.empty(m)
    for i in range(out.shape[1]):
        count = 0
        for k in range(m):
            v = arrays[k][i]
            if not np.isnan(v):
                j = count
                while j > 0 and values[j - 1] > v:
                    values[j] = values[j - 1]
                    j -= 1
                values[j] = v
                count += 1
        median = 0.5 * (values[(count - 1) // 2] + values[count // 2]) if count else np.nan
        for k in range(m):
            if count and median >= floor_pa:
                out[k, i] = (arrays[k][i] - median) / median
            else:
                out[k, i] = np.nan


def disagreeing_as_unknown(
    pressures: Sequence[np.ndarray],
    rest: np.ndarray,
    limit: float,
    spread: int = 0,
    floor_pa: float = 0.0,
) -> tuple[np.ndarray, ...]:
    """``pressures`` with NaN (unknown) where, at ``rest``, a sensor departs from the
    median of the four (at least ``floor_pa``) by more than ``limit`` (a fraction), and
    ``spread`` samples
    either side (the low-pass filter's reach: a filtered step climbs to the limit
    through smaller departures, which would still move the seals): the pipes equalise
    the chambers at rest (contract 1a), so that is the sensor, not the oil, and the
    stick-slip solution takes the others' mean for it (:func:`transforms.stick_slip.
    stick_slip`) instead of moving every seal to explain it. The arrays themselves
    where no sensor does (the ordinary case: results unchanged to the bit).
    The alarm of the same condition is ``sensor_disagreement``
    (:mod:`transforms.alarm_rules`).

    >>> step = np.full(7, 4e6)
    >>> step[3] = 5e6
    >>> out = disagreeing_as_unknown([np.full(7, 4e6)] * 3 + [step], np.ones(7, bool), 0.05, 1)
    >>> np.isnan(out[3]).astype(int), out[0] is not None
    (array([0, 0, 1, 1, 1, 0, 0]), True)
    """
    with np.errstate(invalid="ignore"):
        off = (np.abs(departure_from_median(pressures, floor_pa)) > limit) & rest
    if not off.any():
        return tuple(pressures)
    if spread > 0:  # any off sample within `spread` of each sample
        counts = np.cumsum(np.pad(off, ((0, 0), (spread + 1, spread))), axis=1)
        off = counts[:, 2 * spread + 1 :] > counts[:, : -(2 * spread + 1)]
    return tuple(np.where(o, np.nan, p) for p, o in zip(pressures, off, strict=True))


#: Rests a sensor's median departure is read over (:func:`offset_sensors`), at least.
OFFSET_LEAST_SAMPLES = 30


def offset_sensors(
    pressures: Sequence[np.ndarray], rest: np.ndarray, limit: float, floor_pa: float = 0.0
) -> tuple[bool, ...]:
    """Each sensor whose departure from the median of the four (:func:`departure_from_
    median`, at least ``floor_pa``) at ``rest`` exceeds ``limit`` (a fraction) in its
    median over those samples (at least :data:`OFFSET_LEAST_SAMPLES` of them): the pipes
    equalise the chambers at rest (contract 1a), so a sensor that reads apart at most of
    the record's rests is off by a constant, and not a pressure while the oil flows
    either. :func:`disagreeing_as_unknown` leaves it out at rest only; a sensor 0.3 MPa
    off for a day (validation day 101, session 41) then moved every seal on every trip:
    54 of 115 stop windows worse than raw, none within the band. None where more than
    half the sensors would be: the others could not carry them.

    >>> p = [np.full(40, 4e6)] * 3 + [np.full(40, 4.3e6)]
    >>> offset_sensors(p, np.ones(40, bool), 0.05), offset_sensors(p, np.zeros(40, bool), 0.05)
    ((False, False, False, True), (False, False, False, False))
    """
    if np.count_nonzero(rest) < OFFSET_LEAST_SAMPLES:
        return tuple(False for _ in pressures)
    departures = departure_from_median([np.asarray(p)[rest] for p in pressures], floor_pa)
    found = []
    for departure in departures:
        known = np.abs(departure[np.isfinite(departure)])
        found.append(bool(known.size >= OFFSET_LEAST_SAMPLES and np.median(known) > limit))
    if sum(found) > len(found) // 2:
        return tuple(False for _ in found)
    return tuple(found)


def sensor_departures(
    pressures: Sequence[np.ndarray], rest: np.ndarray, floor_pa: float = 0.0
) -> tuple[float, ...]:
    """Each sensor's signed median departure from the median of the four at ``rest``
    (:func:`departure_from_median`, a fraction), where it stands beyond four standard
    errors of that median (1.2533 x 1.4826 MAD / n^0.5); else 0. The pipes equalise the
    chambers at rest (contract 1a): a sensor that reads apart at the rests, by less than
    the disagreement alarm's limit, has a gain or offset of its own, which its rope's
    tension carries everywhere (validation day 101 with sensor 3 reading 2 % low: the
    load 0.5 % low at most windows, 5 % of them within a band that did not know).

    >>> rng = np.random.default_rng(1)
    >>> p = [4e6 + rng.normal(0.0, 5e3, 400) for _ in range(4)]
    >>> p[2] = p[2] * 0.98
    >>> [round(d, 2) for d in sensor_departures(p, np.ones(400, bool))]
    [0.0, 0.0, -0.02, 0.0]
    """
    found = []
    departures = departure_from_median([np.asarray(p)[rest] for p in pressures], floor_pa)
    for departure in departures:
        known = departure[np.isfinite(departure)]
        if known.size < OFFSET_LEAST_SAMPLES:
            found.append(0.0)
            continue
        median = float(np.median(known))
        spread = 1.4826 * float(np.median(np.abs(known - median)))
        standard_error = 1.2533 * spread / np.sqrt(known.size)
        found.append(median if abs(median) > 4.0 * standard_error else 0.0)
    return tuple(found)


def flatlined_samples(
    frame: pl.DataFrame, time_s: np.ndarray, hoist: HoistDescription
) -> dict[str, np.ndarray]:
    """The samples of each logged pressure (``p{i}_pa``) in a stuck stretch, for the
    columns that have any: one reading repeated for the hoist's ``[alarms]
    flatline_duration`` while another sensor moves (:func:`transforms.alarm_events.
    flatline_runs`), or every sensor's while the conveyance travels (a frozen logger,
    :func:`~transforms.alarm_events.frozen_runs`). Not pressures: the compensation
    takes them as not logged, as a dropout (the rope's tension and the load are null
    there; the ``sensor_flatline`` / ``sensor_stuck`` alarm names it), where the stuck
    reading would otherwise enter the rope's tension and the load with an ordinary
    band. The other sensors' mean carries the oil meanwhile
    (:func:`transforms.stick_slip.stick_slip`). Block by block as whole where the
    others move within the flat-line duration of each sample (the blocks' halo reaches
    past it, :func:`compensation_margins_s`); not where they move only farther away
    (:mod:`transforms.blocks`)."""
    columns = [c for c in rope_cols("p{i}_pa") if c in frame.columns]
    readings = [float_column(frame[c]) for c in columns]
    duration_s = hoist.alarms.flatline_duration_s
    stretches = flatline_runs(readings, time_s, duration_s)
    if len(columns) == len(ROPES) and "depth_m" in frame.columns:
        frozen = frozen_runs(
            readings, time_s, float_column(frame["depth_m"]), duration_s,
            hoist.shaft.position_window_m,
        )  # fmt: skip
        stretches = [
            (np.concatenate([s, frozen[0]]), np.concatenate([e, frozen[1]])) for s, e in stretches
        ]
    out = {}
    for column, (starts, ends) in zip(columns, stretches, strict=True):
        if starts.size:
            edges = np.zeros(frame.height + 1, dtype=np.int64)
            np.add.at(edges, starts, 1)
            np.add.at(edges, ends + 1, -1)
            out[column] = np.cumsum(edges[:-1]) > 0
    return out


def without_flatlined(frame: pl.DataFrame, hoist: HoistDescription) -> pl.DataFrame:
    """``frame`` (time-sorted samples) with each logged pressure null over its stuck
    stretches (:func:`flatlined_samples`): what the compensation takes as not logged,
    for the stages that read the pressures beside it (the ropes' identification, the
    sanity check's and discovery's replays, which compared a sensor stuck for an hour
    with the oil's pressure and failed every trip of its record)."""
    if frame.height == 0 or "time_utc" not in frame.columns:
        return frame
    seconds = float_column(frame["time_utc"].dt.cast_time_unit("us").to_physical(), scale=1e-6)
    flat = flatlined_samples(frame, seconds, hoist)
    if not flat:
        return frame
    return frame.with_columns(
        pl.when(pl.Series(mask)).then(None).otherwise(pl.col(c)).alias(c)
        for c, mask in flat.items()
    )


def at_rest(frame: pl.DataFrame) -> np.ndarray:
    """Where the conveyance stands still (|``speed_m_s``| below
    :data:`physics.trip_rule.STANDSTILL_SPEED_M_S`); an unknown speed is not at rest
    (the ringing it would let count, :func:`transforms.seal_drift.ringing_travel`, is
    left out rather than guessed)."""
    speed = float_column(frame["speed_m_s"], fill=np.inf)
    return np.abs(speed) < STANDSTILL_SPEED_M_S


def despiked_span(span: pl.DataFrame, settings: CompensationSettings) -> pl.DataFrame:
    """``span`` (time-sorted samples) with each logged pressure despiked as the
    compensation despikes it (:func:`transforms.filtering.despike_median3`,
    ``settings.spike_sigmas`` x the span's own noise, per gap-free segment): one sample
    of 50 MPa in a 0.2 s mean of :func:`~transforms.rope_identification.record_means`
    moved that mean by 4.5 MPa, and the ropes of the whole record were not identified
    (validation day 101 with four such samples: worst load error 0.80 -> 2.16 %, band
    coverage 97 -> 72 %). The x are left as logged: their 0.1 mm step gives a noise
    estimate of 0, which despiked every toggle and moved the identified ropes. A
    pressure's noise is taken as its logger's rounding, q / sqrt 12, at least: one
    quieter than its step (a 1 kPa logger at rest) reads as no noise too."""
    if span.height < 3:
        return span
    seconds = float_column(span["time_utc"].dt.cast_time_unit("us").to_physical(), scale=1e-6)
    segment = segment_ids(seconds, gap_factor=settings.gap_factor)
    columns = [c for c in rope_cols("p{i}_pa") if c in span.columns and span[c].dtype.is_float()]

    def despiked(values: np.ndarray) -> np.ndarray:
        changes = sampled_differences(values)
        sigma = max(difference_noise_sigma(changes, 1), step_of_changes(changes) / np.sqrt(12.0))
        return despike_median3(values, segment, n_sigmas=settings.spike_sigmas, sigma=sigma)[0]

    return span.with_columns(
        pl.Series(c, despiked(float_column(span[c])), dtype=span[c].dtype).fill_nan(None)
        for c in columns
    )


def identification_means(
    samples: pl.DataFrame, start: dt.datetime, hoist: HoistDescription,
    settings: CompensationSettings,
) -> pl.DataFrame:  # fmt: skip
    """:func:`transforms.rope_identification.record_means` of the record that starts at
    ``start`` (its time-sorted samples, at least its first
    :data:`~transforms.rope_identification.IDENTIFY_SPAN`), with each mean's played
    travel of the seals' drift (``drift_travel_pa``,
    :func:`transforms.seal_drift.drift_travel`) when the hoist declares seals that drift.
    The pressures despiked (:func:`despiked_span`), a stuck stretch left out
    (:func:`without_flatlined`), and a sensor off the others at the span's rests
    (:func:`offset_sensors`) left out whole: the model takes the others' mean for it.
    The same means whether the record is read whole or block by block."""
    span = without_flatlined(samples.filter(pl.col("time_utc") < start + IDENTIFY_SPAN), hoist)
    span = despiked_span(span, settings)
    if "speed_m_s" in span.columns and span.height:
        columns = [c for c in rope_cols("p{i}_pa") if c in span.columns]
        limits = rule_thresholds(hoist)
        rests = np.flatnonzero(at_rest(span))  # about 200 k of them decide it
        rests = span[rests[:: max(1, rests.size // 200_000)]]
        off = offset_sensors(
            [calibrated(rests, c, hoist) for c in columns], np.ones(rests.height, bool),
            limits.disagreement_fraction, limits.disagreement_floor_pa,
        )  # fmt: skip
        if any(off):  # as the compensation: the others carry
            span = span.with_columns(
                pl.lit(None, dtype=span[c].dtype).alias(c)
                for c, o in zip(columns, off, strict=True)
                if o
            )
    logged = [
        c for c in rope_cols("x{i}_m") if c in span.columns and span[c].fill_nan(None).count()
    ]
    if seals_drift(set(hoist.model.effects)) and span.height > 1 and logged:
        epoch = span["time_utc"].dt.cast_time_unit("us").to_physical()
        travel = drift_travel(
            tuple(calibrated(span, column, hoist) for column in rope_cols("p{i}_pa")),
            float_column(epoch, scale=1e-6), float_column(span["depth_m"]), at_rest(span),
            hoist, sample_rate_hz=settings.sample_rate_hz,
            pressure_sigma_pa=settings.pressure_sigma_pa,
            pressure_cutoff_hz=settings.pressure_cutoff_hz,
            spike_sigmas=settings.spike_sigmas, gap_factor=settings.gap_factor,
        )  # fmt: skip
        span = span.with_columns(pl.Series("drift_travel_pa", travel))
    return record_means(span, start)


def compensation_context(
    sample: pl.DataFrame,
    hoist: HoistDescription,
    settings: CompensationSettings,
    stride: int,
    *,
    means: pl.DataFrame | None = None,
    cache_dir: Path | None = None,
    depth_turns: tuple[np.ndarray, np.ndarray] | None = None,
) -> CompensationContext:
    """:class:`CompensationContext` from a :func:`context_sample` of the record and, to
    identify the ropes, its :func:`identification_means` (the
    ropes remembered in ``cache_dir``, :func:`~transforms.rope_identification.
    identify_from_means`); ``depth_turns`` the depth's reversals over every row
    (:func:`physics.conveyance.reading_turns`, the parts' concatenated), else those of
    the sample's pairs, which on a long record catch too few of an encoder's toggles."""
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
    p_cols, x_cols = rope_cols("p{i}_pa"), rope_cols("x{i}_m")
    pressures, steps = [], []
    for column in (*p_cols, *x_cols):
        values = (
            calibrated(sample, column, hoist)
            if column in sample.columns
            else np.full(row.size, np.nan)
        )
        spike_sigma[column] = difference_noise_sigma(values[pair + 1] - values[pair], 1)
        if column in p_cols:
            pressures.append(values[first])
            steps.append(step_of_changes(values[pair + 1] - values[pair]))
    displacement_sigma, logged = [], []
    has_x = True
    for column in x_cols:
        x = float_column(sample[column]) if column in sample.columns else np.full(row.size, np.nan)
        has_x = has_x and bool(np.isfinite(x).any())
        logged.append(x)
        d2 = (x[triple + 2] - x[triple + 1]) - (x[triple + 1] - x[triple])
        displacement_sigma.append(difference_noise_sigma(d2, 2))
    depth = (
        float_column(sample["depth_m"])
        if "depth_m" in sample.columns
        else np.full(row.size, np.nan)
    )
    depth_d2 = (depth[triple + 2] - depth[triple + 1]) - (depth[triple + 1] - depth[triple])
    mean = mean_horizontal(pressures) if pressures and row.size else np.empty(0)
    typical = float(np.nanmedian(mean)) if np.isfinite(mean).any() else 0.0
    limits = rule_thresholds(hoist)
    off: tuple[bool, ...] = ()
    apart: tuple[float, ...] = ()
    if "speed_m_s" in sample.columns and row.size:
        rest = at_rest(sample)[first]
        fraction, floor_pa = limits.disagreement_fraction, limits.disagreement_floor_pa
        off = offset_sensors(pressures, rest, fraction, floor_pa)
        apart = sensor_departures(pressures, rest, floor_pa)
        if any(off):  # an offset sensor's rope takes the others' reading
            apart = tuple(0.0 if o else d for d, o in zip(apart, off, strict=True))
    identify = settings.rope_springs and has_x and means is not None
    springs = identify_from_means(means, hoist, cache_dir=cache_dir) if identify else None
    # nothing identified the ropes: no logged x, or one that shows no piston motion (a
    # record at rest: x within 5 logger steps), where the share-out of
    # transforms.piston_motion would read equal shares of every slide from it and turn
    # seals the wrong way at a payload change at rest (issue 13: 23-24 stop windows
    # worse than raw on the validation days). A logged x that shows motion the
    # identification could not match still decides the pistons' shares (the share-out):
    # the measured motion, which the rope springs may not hold (a groove's wear pays the
    # ropes out at different rates, the pistons slide apart on every trip). Measured on
    # validation days 101-104 with the identification made to fail, x kept (session 38,
    # not kept as the rule): the share-out's stop windows 2.1-2.5 % worst, 4-6 worse
    # than raw, its band holding 65-82 % of them at 4.2-4.7 % half-width; the prior's
    # (ignoring x) 0.8-3.5 %, 0-2, 98-100 % at 0.6-1.8 %; but those days' grooves are
    # alike and their ropes identify.
    # motion on the sample's triplets' medians over the whole record (a single-sample
    # spike at rest, which the despiking removes, is no motion), or on the
    # identification's 0.2 s means of its first IDENTIFY_SPAN (what it saw)
    # (the gate at least 8 x the transducer's measured noise there: a median of three
    # keeps most of it, and a day's 66 000 triplets of 0.12 mm noise spanned 0.5 mm)
    moved = has_x and any(
        pistons_moved((_triplet_medians(x, triple),), least_m=max(0.5e-3, 8.0 * sigma))
        for x, sigma in zip(logged, displacement_sigma, strict=True)
    )
    if has_x and not moved and means is not None:
        moved = pistons_moved(tuple(float_column(means[c]) for c in x_cols if c in means.columns))
    unidentified = springs is None and settings.rope_springs and not moved
    stated = hoist.ropes.head_rope_stiffness_factors
    if stated is not None and len(stated) != len(ROPES):
        stated = None  # not the compensation's four ropes: the share-out
    if unidentified and stated is not None:
        # the description states its ropes: the stick-slip solution on them
        springs = RopeSprings(tuple(stated), (0.0,) * len(stated), float("nan"), 0)
    elif (
        unidentified
        and settings.rope_stiffness_sigma
        and hoist.ropes.head_rope_stiffness_factors is None
        and hoist.ropes_n == len(ROPES)
    ):
        # the stick-slip solution on the ropes' prior spread
        springs = prior_rope_springs((1.0,) * len(ROPES), settings.rope_stiffness_sigma)
    if identify and (springs is None or unidentified):
        _LOG.warning(
            "the logged x did not identify the head ropes; the compensation runs on %s",
            "the pistons' share-out of the logged x"
            if springs is None
            else "the described ropes"
            if stated is not None
            else "their prior spread (a wider band)",
        )
    return CompensationContext(
        sample_rate_hz=rate_hz,
        spike_sigma=spike_sigma,
        displacement_sigma_m=tuple(displacement_sigma),
        depth_sigma_m=difference_noise_sigma(depth_d2, 2),
        depth_quantum_m=quantum_of_turns(
            *(reading_turns(depth[pair + 1] - depth[pair]) if depth_turns is None else depth_turns)
        ),
        typical_pressure_pa=typical,
        has_x=has_x,
        rope_springs=springs,
        offset_sensors=off if any(off) else (),
        sensor_departures=apart if any(apart) else (),
        pressure_step_pa=max(steps, default=0.0),
    )


def _triplet_medians(x: np.ndarray, triple: np.ndarray) -> np.ndarray:
    """The median of each of the sample's consecutive triplets of ``x`` (rows ``triple``,
    +1, +2) over their finite values, as :func:`numpy.nanmedian` gives it (the mean of
    two, the one alone; NaN where none is finite); ``x`` itself where the sample has no
    triplet. Sorted along the triplet (NaN last) instead of ``nanmedian``'s masked
    arrays: 0.5 s less a 2 h, 50 Hz record.

    >>> x = np.array([3.0, 1.0, 2.0, np.nan, 5.0, np.nan, np.nan, 7.0])
    >>> _triplet_medians(x, np.array([0, 1, 2, 3, 5])).tolist()
    [2.0, 1.5, 3.5, 5.0, 7.0]
    """
    if triple.size == 0:
        return x
    ordered = np.sort(np.stack([x[triple], x[triple + 1], x[triple + 2]]), axis=0)
    known = np.isfinite(ordered).sum(axis=0)
    return np.where(
        known == 3,
        ordered[1],
        np.where(known == 2, (ordered[0] + ordered[1]) / 2.0, ordered[0]),
    )


@dataclass
class CompensationCarry:
    """The sequential state of :func:`compensate_window` from one block to the next.

    Each array is a resumable kernel's state (:func:`transforms.filtering.fresh_state`).
    The filters before them are not causal, so a block is compensated on a window with a
    margin either side (:func:`compensation_margins_s`); the kernels that feed a second
    filter (the oil's common mode, the pistons' share-out, the play operators) resume
    ``resume_s`` before the block's start, the friction and trip labels at its start.
    ``estimate`` is the stick-slip estimate's :func:`~transforms.stick_slip.
    stick_slip_state`; ``springs`` holds one row per solution of
    :func:`~transforms.stick_slip_band.band_solutions`, in its order: its band members at the
    sensors' rate (row 0 unused), or with ``band_member_step_s`` every solution on the
    means of :mod:`transforms.band_members` (rows past the record's solutions unused);
    ``drift_play`` the play whose travel drives the means' drift
    (:func:`transforms.seal_drift.played_travels_into`); ``continuity`` the load's
    continuity from a trip to its stop (:func:`transforms.stop_continuity.
    continuity_state`: the trip's run so far, the shift at its last arrival).
    """

    common: np.ndarray
    differential: list[np.ndarray]
    share: np.ndarray
    played: list[np.ndarray]
    rope: list[np.ndarray]
    labels: np.ndarray
    springs: np.ndarray
    estimate: np.ndarray
    drift_play: np.ndarray
    continuity: np.ndarray

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
            springs=np.stack([stick_slip_state(len(ROPES), elements)] * MAX_SOLUTIONS),
            estimate=stick_slip_state(len(ROPES), elements),
            drift_play=np.zeros(PLAYED_TRAVEL_STATE_SIZE),
            continuity=continuity_state(MAX_SOLUTIONS + 1),
        )


def compensation_margins_s(
    settings: CompensationSettings, hoist: HoistDescription | None = None
) -> tuple[float, float]:
    """(resume, halo) [s] of block processing (:func:`compensate_window`).

    ``resume``: the first-stage kernels restart this long before a block, so the piston
    velocity filter (``velocity_window_s``) has exact input at the block's edges.
    ``halo``: samples this far beyond (resume + block + resume) are read so that the
    zero-phase filters have forgotten the window's edges: 10 periods of the pressure
    low-pass and of the ringing's demodulation (:func:`transforms.seal_drift.
    ringing_travel`), the differential smoother's 4 sigma plus its median-padded edge,
    twice each Savitzky-Golay window, and at least 30 s; with ``hoist``, its
    ``[alarms] flatline_duration`` on top: a stuck sensor's stretch is told in a window
    as in the whole record only where the window reaches the duration past the sample
    either side (:func:`transforms.alarm_events.flatline_runs`), and the filters read
    the pressures that far beyond the first stage
    (:func:`flatlined_samples`). After the block, :func:`compensation_look_ahead_s`
    more.
    """
    resume = max(1.0, 2.0 * settings.velocity_window_s)
    smoother_s = 4.0 * 0.1325 / settings.differential_cutoff_hz
    halo = max(
        30.0,
        10.0 / settings.pressure_cutoff_hz,
        2.0 * (smoother_s + 1.0 / settings.differential_cutoff_hz),
        2.0 * settings.acceleration_window_s,
        2.0 * settings.velocity_window_s,
        10.0 / RINGING_BANDWIDTH_HZ,
    )
    if hoist is not None:
        halo += hoist.alarms.flatline_duration_s
    return resume, halo


def compensation_look_ahead_s(settings: CompensationSettings) -> float:
    """How much more than the halo (:func:`compensation_margins_s`) a block reads after
    its end [s]: with ``settings.stop_continuity`` the stick-slip solutions are solved
    :data:`transforms.stop_continuity.LOOK_AHEAD_S` past the first stage, where the next
    trip's run predicts a stop's load (:func:`transforms.stop_continuity.backward_shift`),
    and the filters still have their halo beyond; else 0.

    >>> compensation_look_ahead_s(CompensationSettings(stop_continuity=False))
    0.0
    """
    return LOOK_AHEAD_S if settings.stop_continuity else 0.0


def mean_horizontal(arrays: list[np.ndarray]) -> np.ndarray:
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
