"""LuGre's drift in the stick-slip solution: what shakes a seal loose (issue 13).

A seal of LuGre's single bristle (paper eq 15; ``seal_friction`` without
``presliding_hysteresis``) relaxes along any back-and-forth path, not only along a
slide: eq 15's -sigma_0 |dx| F / g (:func:`physics.lugre.lugre_drift`). A ringing
conveyance moves the pistons back and forth through the oil and shakes their seals
loose; the validation README's ringing hoist and ropeload's own LuGre simulation both
show it. Maxwell-slip seals hold their force under small oscillations (no drift).

What the drift needs is the pistons' *real* travel, and a quasi-static solution turns
the sensors' noise into micrometres of motion that would drain every seal. So the
travel is read from the sensors' mean pressure (the oil's motion, V / beta A per
pascal, eq 5), low-passed just above the conveyance's fastest bounce
(:func:`drift_cutoff_hz`) and passed through a play of :data:`DRIFT_SIGMAS` x its noise
(:func:`drift_pressure`); the travel the play hides at each turn of its output is
counted back (:func:`played_travel`). A ringing at rest spends as much travel below
the play's half-width as above it; that part is found by demodulating the mean
pressure at the conveyance's bounce frequency, where the noise is a quarter of the
play's (:func:`ringing_travel`). :func:`transforms.stick_slip.stick_slip` shares the
travel out by each piston's compliance and applies it before each sample's elastic
step.
The ropes' identification (:mod:`transforms.rope_identification`) runs the same
solution on 0.2 s means, each with the travel of the full-rate samples it stands for
(:func:`drift_travel`).

What it leaves out: each piston's own motion beside its share of the oil's. LuGre's
eq 15 drifts along that too, and at a reversal its bristle's force falls up to twice as
fast as sigma_0 (the validation days' stop windows show it: 1.2 kN over 24 um, 1.35
sigma_0). On validation days 101-104 every pithead arrival after an up trip keeps more
friction than the truth's (the load 0.05-0.6 % high on average, most after trips that
paused at the middle empty; with the truth's rope constants just as much), where pistons
stick while another slides millimetres. Tried (session 33) and not kept: the drift
along each piston's own solved x through a play as wide as the pressure's play in oil
travel (5.8 um), in place of the shared travel: worst window 0.80 / 0.67 / 0.79 /
0.96 -> 1.52 / 1.43 / 0.83 / 1.86 %, 35 windows worse than raw on day 104. The sensors'
noise moves a sliding piston by 25 N / a k, 20 um at the pithead and 270 um at the
bottom, as far as the real reversals, so no play tells them apart; it drained the seals.
A play of each piston's own noise (3 x the pressure play's width through its last
compliance: 2.5 um while it sticks, 80 um sliding at the pithead) drained them more:
day 104 (ringing) 0.74 % worst, none worse than raw, coverage 97 %, but days 101-103
2.8-3.9 %: the noise standing in for a ringing, not a model of it. Counted only where
the oil's played travel moves (not at rest): 101-103 still 1.6-2.3 %; only while the
piston sticks (its presliding, the play restarted after each slide): 1.9-2.4 %, day
104 0.83 %.
"""

from __future__ import annotations

import numpy as np
import polars as pl
from numba import njit

from physics.rope_spring import bounce_frequency_hz
from physics.tension import tail_rope_mass_kg
from physics.trip_rule import segment_ids
from schemas.hoist import G_STANDARD, HoistDescription
from transforms.alarm_events import reading_step
from transforms.filtering import despiked_lowpass, play_step, pressure_cutoff_at
from transforms.lowpass import lowpass

__all__ = [
    "DRIFT_CUTOFF_FACTOR",
    "DRIFT_SIGMAS",
    "PLAYED_TRAVEL_STATE_SIZE",
    "RINGING_BANDWIDTH_HZ",
    "RINGING_BESIDE",
    "RINGING_PEAK",
    "RINGING_SIGMAS",
    "drift_cutoff_hz",
    "drift_play_pa",
    "drift_pressure",
    "drift_travel",
    "played_travel",
    "played_travels",
    "played_travels_into",
    "ringing_travel",
    "seal_elements",
    "seals_drift",
]

#: Half-width of the play on the mean pressure that drives LuGre's drift, in standard
#: deviations of that mean's noise: the smallest whole number at which the noise alone
#: (5 kPa white per sensor) drains the seals by < 3 % in 10 min at rest, at 50 or
#: 100 Hz, with the validation hoist's oil and bristles (3 drains 4-12 %; measured
#: apart, session 14). tests/transforms/test_seal_drift.py checks < 5 % on the example
#: hoist, and that a ringing of 20 kPa still shakes the seals loose.
DRIFT_SIGMAS = 4.0
#: The drift's mean pressure is low-passed at this factor on the conveyance's fastest
#: bounce (the pistons' real back-and-forth; faster is the sensors' noise).
DRIFT_CUTOFF_FACTOR = 1.5
#: Bandwidth of the ringing's demodulation at the conveyance's bounce frequency [Hz]
#: (:func:`ringing_travel`): a ringing of damping ratio 0.03 decays at 0.15-0.5 /s on
#: the validation hoist, well inside it; the noise passed is 0.25 / 4 of the play's.
RINGING_BANDWIDTH_HZ = 0.25
#: A ringing below the play counts where its demodulated amplitude exceeds this many
#: RMS of the amplitude that the noise alone gives (Rayleigh: exceeded by the noise
#: alone with probability exp(-9) ~ 1e-4).
RINGING_SIGMAS = 3.0
#: ... and where it is a line: this many times the amplitude at the frequencies
#: :data:`RINGING_BESIDE` x f_b (a ringing of damping ratio 0.03 leaves < 0.12 of its
#: amplitude there, through the demodulation's low-pass; a ramp's or a step's spectrum
#: is about flat).
RINGING_PEAK = 2.0
RINGING_BESIDE = (0.6, 1.6)


def seals_drift(effects: set[str] | frozenset[str]) -> bool:
    """Whether the hoist's seals drift: LuGre's single bristle (``seal_friction`` without
    ``presliding_hysteresis``, whose Maxwell-slip elements hold their force under small
    oscillations).

    >>> seals_drift({"seal_friction"}), seals_drift({"seal_friction", "presliding_hysteresis"})
    (True, False)
    """
    return "seal_friction" in effects and "presliding_hysteresis" not in effects


def seal_elements(effects: set[str] | frozenset[str], hoist: HoistDescription) -> int:
    """Maxwell-slip elements per seal: the friction law's ``presliding_elements`` with
    ``presliding_hysteresis`` among the effects, else 1 (one bristle: elasto-plastic,
    or LuGre's, which drifts, :func:`seals_drift`).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> seal_elements({"presliding_hysteresis"}, hoist), seal_elements({"seal_friction"}, hoist)
    (4, 1)
    """
    if "presliding_hysteresis" in effects:
        return hoist.friction_law.presliding_elements
    return 1


def drift_cutoff_hz(hoist: HoistDescription, pressure_cutoff_hz: float) -> float:
    """Cut-off of the drift's mean pressure [Hz]: :data:`DRIFT_CUTOFF_FACTOR` x the
    conveyance's fastest bounce (:func:`physics.rope_spring.bounce_frequency_hz`: the
    pithead, conveyance empty, the tail ropes hanging the whole shaft), at most the
    sensors' own cut-off.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> round(drift_cutoff_hz(load_hoist(EXAMPLE_HOIST), 10.0), 2)
    3.97
    """
    fastest = bounce_frequency_hz(
        hoist.ropes.head_rope_axial_stiffness_n, hoist.conveyance.head_ropes,
        hoist.shaft.headframe_height_m,
        hoist.conveyance.mass_kg + float(tail_rope_mass_kg(hoist, 0.0)),
    )  # fmt: skip
    return min(DRIFT_CUTOFF_FACTOR * fastest, pressure_cutoff_hz)


def drift_pressure(
    pressures: tuple[np.ndarray, ...],
    segment_id: np.ndarray,
    hoist: HoistDescription,
    *,
    sample_rate_hz: float,
    pressure_sigma_pa: float,
    pressure_cutoff_hz: float,
    work: np.ndarray | None = None,
    reading_step_pa: float = 0.0,
) -> tuple[np.ndarray, float]:
    """The mean pressure that drives the seals' drift in
    :func:`transforms.stick_slip.stick_slip`, and the half-width of the play on it [Pa].

    The mean of the sensors logged at each sample (already low-passed at
    ``pressure_cutoff_hz``), low-passed
    again at :func:`drift_cutoff_hz`; the play's half-width is :data:`DRIFT_SIGMAS` x
    that mean's noise, ``pressure_sigma_pa`` white per sensor through the two filters
    (:func:`drift_play_pa`, with the loggers' ``reading_step_pa``).
    ``work``: scratch of :func:`transforms.lowpass.lowpass_work_size` samples at that
    cut-off.
    """
    cutoff = drift_cutoff_hz(hoist, pressure_cutoff_hz)
    mean = np.zeros(np.shape(pressures[0]))
    count = np.zeros(np.shape(pressures[0]))
    for p in pressures:  # a sensor not logged at a sample: the others' mean
        known = ~np.isnan(p)
        mean += np.where(known, p, 0.0)
        count += known
    with np.errstate(invalid="ignore"):
        mean /= count  # none logged: NaN
    lowpass(mean, segment_id, sample_rate_hz=sample_rate_hz, cutoff_hz=cutoff, out=mean, work=work)
    share = min(1.0, 2.0 * cutoff / sample_rate_hz)
    return mean, drift_play_pa(pressure_sigma_pa, reading_step_pa, share, len(pressures))


def drift_play_pa(sigma_pa: float, step_pa: float, share: float, sensors: int) -> float:
    """Half-width of the drift's play on the sensors' mean pressure [Pa]:
    :data:`DRIFT_SIGMAS` x the mean's noise (``sigma_pa`` white per sensor with a
    logger's rounding to ``step_pa``, q^2 / 12, passed in the filters' ``share`` of the
    band), and at least half a step. The mean of readings each rounded to q is within
    q / 2 of the mean pressure, so at rest its flips between steps span up to q: a
    play of half-width q / 2 never takes them for the oil's motion. A logger rounding to
    25 kPa (five times the noise) flipped the mean past the white-noise play at rest,
    drained every seal and left the stop windows 3-5 % off (validation days rounded,
    session 40); where the readings keep the noise (a step of a kilopascal) the white
    noise decides, as before.

    >>> round(drift_play_pa(5e3, 0.0, 0.16, 4)), round(drift_play_pa(5e3, 25e3, 0.16, 4))
    (4000, 12500)
    """
    noise = np.sqrt(sigma_pa**2 + step_pa**2 / 12.0) * np.sqrt(share / sensors)
    return float(max(DRIFT_SIGMAS * noise, 0.5 * step_pa))


def ringing_travel(
    mean_pa: np.ndarray,
    segment_id: np.ndarray,
    depth_m: np.ndarray,
    at_rest: np.ndarray,
    hoist: HoistDescription,
    *,
    sample_rate_hz: float,
    pressure_cutoff_hz: float,
    half_width_pa: float,
    hidden_below_pa: float | None = None,
) -> np.ndarray:
    """Per sample, the travel of a ringing at rest that the drift's play hides [Pa]:
    4 A f_b per second where the ringing's amplitude A is below the play's half-width w
    (above it the play counts it whole) and above the noise. ``hidden_below_pa``: count
    it below this amplitude instead (a play of another width that hides it, e.g. the
    shared-out x's deadband as the oil's pressure, :meth:`transforms.compensation_block.
    BlockCompensation.ringing_drift`).

    A conveyance at rest rings at its bounce frequency f_b (:func:`physics.rope_spring.
    bounce_frequency_hz`: the ropes' hanging length from ``depth_m``, the last known
    of the given samples where NaN, the pithead before any; the mass hanging on them
    n A p / g, at least the empty conveyance's),
    and a damped ringing spends as much travel below w as above it (4 w / (2 pi zeta)
    of it, 85 kPa at zeta = 0.03 and w = 4 kPa): a LuGre seal drains along all of it.
    A is the mean pressure's deviation from its :data:`RINGING_BANDWIDTH_HZ` low-pass,
    demodulated at f_b (I/Q, low-passed at the same bandwidth), where the noise is
    (bandwidth / drift cut-off)^(1/2) of the play's; it counts above
    :data:`RINGING_SIGMAS` x the noise's amplitude RMS and where it stands
    :data:`RINGING_PEAK` x above the amplitude beside f_b. Motion (``at_rest`` False)
    has its travel from the play: the trips' own pressure changes would pass for
    ringing here.

    ``mean_pa``, ``half_width_pa``: :func:`drift_pressure`'s mean and play half-width,
    ``pressure_cutoff_hz`` the sensors' cut-off it was given. NaN pressures count
    nothing (the filters bridge them).
    """
    mean = np.asarray(mean_pa, dtype=np.float64)
    n = mean.shape[0]
    for name, values in (("segment_id", segment_id), ("depth_m", depth_m), ("at_rest", at_rest)):
        if np.shape(values) != (n,):
            raise ValueError(f"{name} has {np.shape(values)} samples, mean_pa {n}")
    out = np.zeros(n)
    if not np.any(at_rest):
        return out
    known = np.isfinite(mean)
    ropes = hoist.conveyance.head_ropes
    hanging_mass = np.maximum(
        ropes * hoist.cylinders.bore_area_m2 * np.nan_to_num(mean) / G_STANDARD,
        hoist.conveyance.mass_kg,
    )
    depth = pl.Series(np.asarray(depth_m, dtype=np.float64)).fill_nan(None)
    depth = depth.fill_null(strategy="forward").fill_null(0.0).to_numpy()
    hanging = hoist.shaft.headframe_height_m + np.maximum(depth, 0.0)
    bounce = bounce_frequency_hz(
        hoist.ropes.head_rope_axial_stiffness_n, ropes, hanging, hanging_mass
    )
    phase = 2.0 * np.pi * np.cumsum(bounce) / sample_rate_hz
    rate, band = sample_rate_hz, RINGING_BANDWIDTH_HZ
    swing = mean - lowpass(mean.copy(), segment_id, sample_rate_hz=rate, cutoff_hz=band)
    swing = np.where(known, swing, 0.0)

    def amplitude_at(factor: float) -> np.ndarray:  # I/Q demodulation at factor x f_b
        i = lowpass(swing * np.cos(factor * phase), segment_id, sample_rate_hz=rate,
                    cutoff_hz=band)  # fmt: skip
        q = lowpass(swing * np.sin(factor * phase), segment_id, sample_rate_hz=rate,
                    cutoff_hz=band)  # fmt: skip
        return 2.0 * np.hypot(i, q)

    amplitude = amplitude_at(1.0)
    # a ringing is a line at f_b; a payload change's ramp, or a stop's, is broadband.
    # (At the pithead 1.6 f_b is above the drift's cut-off: 0.6 f_b then guards alone.)
    beside = np.max([amplitude_at(factor) for factor in RINGING_BESIDE], axis=0)
    # the mean's white noise (w / DRIFT_SIGMAS) up to the drift's cut-off: its
    # amplitude at f_b has an RMS of 2 sigma (band / cut-off)^(1/2)
    cutoff = drift_cutoff_hz(hoist, pressure_cutoff_hz)
    noise = 2.0 * half_width_pa / DRIFT_SIGMAS * np.sqrt(band / cutoff)
    below = half_width_pa if hidden_below_pa is None else hidden_below_pa
    counted = at_rest & known & (amplitude > RINGING_SIGMAS * noise) & (amplitude < below)
    counted &= amplitude > RINGING_PEAK * beside
    out[counted] = 4.0 * amplitude[counted] * bounce[counted] / rate
    return out


@njit(cache=True, nogil=True, inline="always")
def played_travel(
    p: float, played: float, heading: float, half_width: float
) -> tuple[float, float, float]:  # pragma: no cover - numba
    """One sample of the play on the drift's pressure (:func:`transforms.filtering.
    play_operator`): (the input's travel it passes [Pa], its new output, its heading).
    At a turn of the output the input travelled 2 w more than the output: counted.
    A NaN output (a segment's start) starts at p; a NaN p holds it."""
    if not np.isfinite(played):
        return 0.0, p, 0.0
    output = play_step(p, played, half_width)  # transforms.filtering's, one home
    step = output - played
    if step == 0.0:
        return 0.0, played, heading
    travel = abs(step) + (2.0 * half_width if heading * step < 0.0 else 0.0)
    return travel, output, 1.0 if step > 0.0 else -1.0


def drift_travel(
    pressures: tuple[np.ndarray, ...],
    time_s: np.ndarray,
    depth_m: np.ndarray,
    at_rest: np.ndarray,
    hoist: HoistDescription,
    *,
    pressure_sigma_pa: float,
    pressure_cutoff_hz: float,
    spike_sigmas: float,
    gap_factor: float,
    sample_rate_hz: float | None = None,
) -> np.ndarray:
    """Per sample, the travel of the drift's played pressure since the sample before [Pa]:
    what :func:`transforms.stick_slip.stick_slip` drives the seals' drift with, for a
    record's full-rate samples (the ropes' identification sums it over each of its
    means, ``drift_travel_pa``: a 0.2 s mean hides a bounce of 0.8-2.7 Hz).

    ``pressures``: calibrated sensor pressures; despiked and low-passed here as the
    compensation does (:class:`transforms.compensation_record.CompensationSettings`'s
    ``spike_sigmas``, ``pressure_cutoff_hz`` as the logger's rate allows
    (:func:`transforms.filtering.pressure_cutoff_at`), gaps beyond ``gap_factor``
    steps; the rate ``sample_rate_hz``, else the median step's), then
    :func:`drift_pressure` and :func:`played_travel`, plus the ringing the play hides at
    rest (:func:`ringing_travel`).
    """
    t = np.asarray(time_s, dtype=np.float64)
    if t.size < 2:
        return np.zeros(t.size)
    rate = sample_rate_hz or 1.0 / float(np.median(np.diff(t)))
    if not 0.0 < rate < np.inf:
        raise ValueError(f"the samples' rate {rate} Hz is not a rate (repeated times?)")
    segment = segment_ids(t, gap_factor=gap_factor, nominal_dt_s=1.0 / rate)
    cutoff = pressure_cutoff_at(pressure_cutoff_hz, rate)  # as the compensation's set-up
    filtered = tuple(
        despiked_lowpass(np.array(p, dtype=np.float64), segment, sample_rate_hz=rate,
                         cutoff_hz=cutoff, spike_sigmas=spike_sigmas)
        for p in pressures
    )  # fmt: skip
    mean, half_width = drift_pressure(
        filtered, segment, hoist, sample_rate_hz=rate,
        pressure_sigma_pa=pressure_sigma_pa, pressure_cutoff_hz=cutoff,
        reading_step_pa=max((reading_step(p) for p in pressures), default=0.0),
    )  # fmt: skip
    ringing = ringing_travel(
        mean, segment, depth_m, at_rest, hoist, sample_rate_hz=rate, pressure_cutoff_hz=cutoff,
        half_width_pa=half_width,
    )  # fmt: skip
    return played_travels(mean, segment, half_width) + ringing


#: Size of :func:`played_travels_into`'s state: [ran, continues, output, heading]
#: (:func:`transforms.filtering.fresh_state`'s first two).
PLAYED_TRAVEL_STATE_SIZE = 4


@njit(cache=True, nogil=True)
def played_travels(
    p: np.ndarray, segment: np.ndarray, half_width: float
) -> np.ndarray:  # pragma: no cover - numba
    """:func:`played_travel` along a record: each sample's travel [Pa] (0 where p is NaN);
    a new segment restarts the play at its first known p, as in the stick-slip kernel.

    The input travels 3, 3 and 4; the play's first engagement hides 1 (w):

    >>> played_travels(np.array([0.0, 3.0, 0.0, 4.0]), np.zeros(4, np.int64), 1.0).tolist()
    [0.0, 2.0, 3.0, 4.0]
    """
    out = np.zeros(p.shape[0])
    played_travels_into(p, segment, half_width, np.zeros(PLAYED_TRAVEL_STATE_SIZE), out)
    return out


@njit(cache=True, nogil=True)
def played_travels_into(
    p: np.ndarray, segment: np.ndarray, half_width: float, state: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - numba
    """:func:`played_travels` into ``out``, resuming the play from ``state`` (size
    :data:`PLAYED_TRAVEL_STATE_SIZE`; its output and heading kept where ``state[1]`` says
    the samples continue the state's segment) and leaving its own there: a record read
    block by block plays as it does whole.

    >>> state, out = np.zeros(PLAYED_TRAVEL_STATE_SIZE), np.zeros(2)
    >>> played_travels_into(np.array([0.0, 3.0]), np.zeros(2, np.int64), 1.0, state, out)
    >>> state[1] = 1.0  # the next samples continue the segment
    >>> played_travels_into(np.array([0.0, 4.0]), np.zeros(2, np.int64), 1.0, state, out)
    >>> out.tolist()
    [3.0, 4.0]
    """
    resume = state[0] != 0.0 and state[1] != 0.0
    played = state[2] if resume else np.nan
    heading = state[3] if resume else 0.0
    for t in range(p.shape[0]):
        out[t] = 0.0
        if t > 0 and segment[t] != segment[t - 1]:
            played, heading = np.nan, 0.0
        if np.isfinite(p[t]):
            out[t], played, heading = played_travel(p[t], played, heading, half_width)
    if p.shape[0]:  # no samples: the state stays as it was
        state[0], state[2], state[3] = 1.0, played, heading
