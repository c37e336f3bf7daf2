"""The load's continuity from a trip to its stop: the seals' friction at arrival, updated.

The payload does not change while the conveyance travels. Over a trip's steady run
(phase ``run`` of :mod:`physics.trip_rule`: full speed, no acceleration) every piston
slides one way and its seal holds the friction law's capacity, which the stick-slip
solution (:mod:`transforms.stick_slip`) knows; at the arrival the deceleration and the
stop turn the pistons back into their presliding, where what each seal keeps depends on
the path in micrometres, on the ringing that shakes it and on a law the record does not
pin down. On the independent simulator's validation days the estimate over the run
phases is within 0.18 % of the true load, at the pithead's arrivals after up trips it
holds 190-670 N more friction than the truth's (``benchmarks/diagnose_stop_continuity.py``;
the windows worse than raw on day 104 are those).

The run phase so predicts the load at rest (paper eq 3-4, :func:`physics.tension.
expected_load_n` at a = 0):

.. math:: \\hat L_{stop} = \\bar L_{run} + g\\,(m_t(z_{stop}) - m_t(\\bar z_{run}))

with :math:`m_t(z)` the tail ropes below the conveyance (:func:`physics.tension.
tail_rope_mass_kg`), and :func:`apply_stop_continuity` sets each solution's seals at the
arrival so that its load over the first seconds at rest (:data:`SETTLE_S` after the
stop, for :data:`SPAN_S`, ending where the raw load moves by :data:`PAYLOAD_SHARE`: a
payload change begins) equals its own run phase's prediction. The run's mean is an
independent, better observation of the same state (the constraint is exact but for the
run phase's own error), so the update takes it whole: a Kalman gain of 1 on the common
mode, applied to each band member alike, so the band at the stop becomes the spread of
the members' run phases (an ensemble's update; the members stand for the law, the
bristles and the ropes, whose errors the run phase carries too).

Where the update goes: the sum of the seals' friction. A common stretch of the ropes
moves each sticking seal by its rope's stiffness (:math:`\\Delta F_i = a_i k \\Delta s`),
so rope i takes :math:`a_i / \\sum a` of the shift (the stiffness factors of
:class:`transforms.stick_slip_band.RopeSprings`). It holds while the seals stick: whole
up to the rest window's end, then each piston's share fades as the estimate's piston
moves beyond the reach of its ringing in the window, linearly to nothing over one
presliding range F_s / sigma_0 (a seal that has slid holds the law's capacity, which the
estimate knows); a payload change (the raw load's 2 s mean leaving its value at rest by
:data:`PAYLOAD_SHARE`) ends it, as does the next steady run. A new arrival replaces it.

Where it applies: ropes identified from the record's logged x
(:mod:`transforms.rope_identification`). With the ropes' prior instead (no x) the runs
themselves are 0.25-0.53 % off the truth on the validation days (the ropes' unknown
differences decide which seals slide in a run), so the run predicts no better than the
stop: measured with the update, the median stop error went 0.36 / 0.27 / 0.25 / 0.09 ->
0.64 / 0.56 / 0.54 / 0.25 % (days 101-104); it is not applied there.

Measured (``benchmarks/eval_compensation.py --sims 0``, days 101-104, session 42):
worst stop window 0.80 / 0.67 / 0.79 / 0.97 -> 0.80 / 0.67 / 0.40 / 0.97 %, median
0.18 / 0.13 / 0.15 / 0.22 -> 0.17 / 0.12 / 0.08 / 0.19 %, worst rope 1.13 / 1.04 / 1.84 /
1.18 -> 1.13 / 1.04 / 0.99 / 1.18 %, windows worse than raw by 0.2 points 0 / 1 / 0 / 4 ->
none, band coverage 97 / 98 / 95 / 90 -> 98 / 100 / 97 / 97 % at a median half-width of
0.92 / 0.89 / 0.84 / 0.55 -> 0.98 / 0.90 / 0.89 / 0.76 % (the runs' spread of the law's
capacity, all seals sliding one way, is wider than the stops' was); ropeload's own sims
worst 0.55 / 0.54 -> 0.42 / 0.51 %, median 0.30 / 0.33 -> 0.21 / 0.20 %. Tried and not
kept: the shift carried past payload changes at rest, fading only with each piston's
travel: the windows after a payload change at the bottom of days 101 and 102 went worse
than raw (one each) and day 104's worst to 1.09 %; so a payload change ends it. A gain
below 1 from the members: the innovation d_0 (the run's prediction less the load at
rest) taken as far as it exceeds what the members' own innovations span, s^2 (per
source the largest |d_m - d_0| / 1.96, in quadrature): per arrival, the positive-part
James-Stein share max(0, 1 - s^2 / d_0^2), left windows worse than raw 0 / 1 / 0 / 2
(median 0.16 / 0.11 / 0.15 / 0.15 %) and the own sims as they were; pooled over the
record's arrivals (the model error's variance by the method of moments), nothing moved:
the law's capacity members span the innovations (a capacity 20 % off moves a run, every
seal sliding one way, more than a stop), while on the validation days the runs are
right and the stops are not.

What it costs where the stop was right and the run is not: on ropeload's own
simulation with LuGre seals (``--sims-lugre 2``: seals shaken loose at rest, so the
estimate's stops are exact) the median went 0.01 -> 0.15 % and the band's median
half-width 0.63 -> 1.05 % (the runs' spread); on validation day 101 with x logged to
0.5 mm (the ropes identified less well: its down runs 0.25 % high) or decimated to
10 Hz, the median 0.13 -> 0.23 % and 0.16 -> 0.26 %, the worst windows unchanged, none
worse than raw.

What it leaves out: the branch loss beyond the sensor while oil flows in the run phase
(the run's pistons creep at millimetres a minute: negligible at the contract's valves);
a trip with less than :data:`MIN_RUN_S` of steady run predicts nothing (the stop keeps
the estimate as solved: a record that starts in a deceleration); the update acts at
arrivals only, not at payload changes at rest (the worst windows, after payload changes
at the bottom, are unchanged).

The pass is sequential and resumable (:func:`continuity_state`): a block carries the trip's
run sums, the active shift and how far each piston has moved since its arrival, so a
record compensated block by block gives the same update as read whole. The rest window
looks :data:`SETTLE_S` + :data:`SPAN_S` past an arrival, beyond the blocks' resume margin
(1 s, :func:`transforms.compensation_record.compensation_margins_s`): a block solves the
stick-slip estimate and its members that much past its first stage
(``BlockCompensation.spring_hi``), inside the halo it reads (30 s or more).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from physics.tension import tail_rope_mass_kg
from physics.trip_rule import PHASES, TRIP_BRIDGE_S
from schemas.hoist import G_STANDARD, HoistDescription

__all__ = [
    "MIN_RUN_S",
    "PAYLOAD_SHARE",
    "SETTLE_S",
    "SPAN_S",
    "ContinuityInputs",
    "apply_stop_continuity",
    "continuity_state",
    "rest_window",
]

#: The rest window starts this long after the stop [s]: the deceleration's jerk has
#: passed and the ringing (a conveyance bouncing on its ropes) decays.
SETTLE_S = 2.0
#: ... and lasts at most this long [s]: several periods of the slowest bounce (0.8 Hz at
#: the bottom of the validation hoist), so the ringing averages out of the mean.
SPAN_S = 10.0
#: ... ending where the raw load's 2 s centred mean moves by this share of its value at
#: the window's start: a payload change begins (a ringing's 2 s means stay within it).
PAYLOAD_SHARE = 0.005
#: A trip predicts its stop's load from at least this much steady run [s].
MIN_RUN_S = 2.0
_RUN = PHASES.index("run")
_STANDSTILL = PHASES.index("standstill")
# state: [ran, continues, was moving, run samples, run sum of P, run sum of depth,
# active, last time, fade from (time), the raw load at rest], each piston's x at rest,
# its ringing's reach and its travel beyond, then the run sums of F per solution and the
# shifts
_HEAD = 10
_PISTONS = 4
_PER_PISTON = 3


def continuity_state(solutions: int) -> np.ndarray:
    """A fresh state of :func:`apply_stop_continuity` for ``solutions`` solutions (the
    estimate and its band's members) of four pistons."""
    return np.zeros(_HEAD + _PER_PISTON * _PISTONS + solutions * (1 + _PISTONS))


@dataclass(frozen=True)
class ContinuityInputs:
    """What :func:`apply_stop_continuity` reads over a block and its look-ahead.

    ``time_s`` [s]; ``phase`` the trip rule's phase codes (:func:`physics.trip_rule.
    trip_label_codes`); ``depth_m``; ``pressure_load_n`` the sensors' pressures times
    the piston area summed over the four (unknown ones as the others' mean);
    ``x_m`` the estimate's piston displacements; ``fractions`` each rope's share of a
    common shift (:math:`a_i / \\sum a`); ``presliding_m`` one seal's presliding range
    F_s / sigma_0 [m]; ``dt_s`` the logger's nominal step [s]."""

    time_s: np.ndarray
    phase: np.ndarray
    depth_m: np.ndarray
    pressure_load_n: np.ndarray
    x_m: tuple[np.ndarray, ...]
    fractions: np.ndarray
    presliding_m: float
    dt_s: float


def rest_window(time_s: np.ndarray, phase: np.ndarray, load_n: np.ndarray, at: int) -> slice:
    """The samples of the rest window after an arrival at sample ``at``: from
    :data:`SETTLE_S` after it for :data:`SPAN_S`, while the conveyance stands still, no
    logger gap exceeds :data:`~physics.trip_rule.TRIP_BRIDGE_S`, and the 2 s centred
    mean of ``load_n`` (the raw load) stays within :data:`PAYLOAD_SHARE` of its value at
    the window's start. Empty where less than 1 s remains.

    >>> t = np.arange(0.0, 20.0, 0.5)
    >>> load = np.where(t < 9.0, 1e5, 0.9e5)   # a payload change at 9 s
    >>> w = rest_window(t, np.full(t.size, 4), load, 0)
    >>> float(t[w.start]), float(t[w.stop - 1])
    (2.0, 7.5)
    """
    n = time_s.size
    t0 = time_s[at]
    lo = int(np.searchsorted(time_s, t0 + SETTLE_S, side="left"))
    hi = int(np.searchsorted(time_s, t0 + SETTLE_S + SPAN_S, side="left"))
    hi = min(hi, n)
    if lo >= hi:
        return slice(lo, lo)
    still = phase[lo:hi] == _STANDSTILL
    gaps = np.diff(time_s[at:hi]) > TRIP_BRIDGE_S
    cut = hi
    if not still.all():
        cut = lo + int(np.argmin(still))
    if gaps.any():
        cut = min(cut, at + 1 + int(np.argmax(gaps)))
    if cut <= lo:
        return slice(lo, lo)
    # the raw load's 2 s centred mean against its value at the window's start
    centred = centred_mean(time_s, load_n, lo, cut)
    reference = centred[0]
    if not np.isfinite(reference):
        return slice(lo, lo)
    moved = ~(np.abs(centred - reference) <= PAYLOAD_SHARE * abs(reference))
    if moved.any():
        cut = lo + int(np.argmax(moved))
    if cut <= lo or time_s[cut - 1] - time_s[lo] < 1.0:
        return slice(lo, lo)
    return slice(lo, cut)


def centred_mean(time_s: np.ndarray, values: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """The 2 s centred mean of ``values`` (its known ones) at the samples [lo, hi), from
    the samples either side as far as they go; NaN where none is known.

    >>> t = np.arange(6.0)
    >>> centred_mean(t, np.array([0.0, 3.0, np.nan, 6.0, 9.0, 12.0]), 1, 4).tolist()
    [1.5, 4.5, 7.5]
    """
    n = time_s.size
    w_lo = int(np.searchsorted(time_s, time_s[lo] - 1.0, side="left")) if hi > lo else lo
    w_hi = (
        min(n, int(np.searchsorted(time_s, time_s[hi - 1] + 1.0, side="right"))) if hi > lo else lo
    )
    part = values[w_lo:w_hi]
    known = np.isfinite(part)
    sums = np.concatenate(([0.0], np.cumsum(np.where(known, part, 0.0))))
    counts = np.concatenate(([0], np.cumsum(known)))
    times = time_s[w_lo:w_hi]
    left = np.searchsorted(times, time_s[lo:hi] - 1.0, side="left")
    right = np.searchsorted(times, time_s[lo:hi] + 1.0, side="right")
    with np.errstate(invalid="ignore", divide="ignore"):
        return (sums[right] - sums[left]) / (counts[right] - counts[left])


def apply_stop_continuity(
    inputs: ContinuityInputs,
    frictions: list[tuple[np.ndarray, ...]],
    lo: int,
    hi: int,
    state: np.ndarray,
    hoist: HoistDescription,
) -> None:
    """Shift each solution's seal frictions over [lo, hi) in place (module docstring).

    ``frictions``: per solution (the estimate first, then its band's members) the four
    pistons' friction over the block and its look-ahead [N] (NaN where unsolved);
    ``state``: :func:`continuity_state`, carried from the previous part (its ``[1]``
    unused: a logger gap longer than :data:`~physics.trip_rule.TRIP_BRIDGE_S` ends a trip
    whatever the segments).
    """
    t, phase = inputs.time_s, inputs.phase
    solutions = len(frictions)
    base = _HEAD + _PER_PISTON * _PISTONS
    room = (state.size - base) // (1 + _PISTONS)
    if solutions > room:
        raise ValueError(f"{solutions} solutions: the state holds {room}")
    run_f = state[base : base + solutions]
    shift = state[base + room :].reshape(room, _PISTONS)[:solutions]
    pistons = state[_HEAD:base].reshape(_PER_PISTON, _PISTONS)  # x at rest, reach, travel
    if hi <= lo:
        return
    moving = phase[lo:hi] != _STANDSTILL
    gap_before = np.empty(hi - lo, dtype=bool)
    gap_before[0] = state[0] != 0.0 and t[lo] - state[7] > TRIP_BRIDGE_S
    gap_before[1:] = np.diff(t[lo:hi]) > TRIP_BRIDGE_S
    change = np.flatnonzero((moving[1:] != moving[:-1]) | gap_before[1:]) + 1
    bounds = np.concatenate(([0], change, [hi - lo])) + lo
    was_moving = bool(state[2] != 0.0) if state[0] != 0.0 else None
    for a, b in itertools.pairwise(bounds.tolist()):
        now_moving = bool(moving[a - lo])
        if gap_before[a - lo]:  # a logger gap: nothing known across it
            state[3:6] = 0.0
            run_f[:] = 0.0
            was_moving = None
        if now_moving:
            if was_moving is not True:  # a departure: a new trip's run
                state[3:6] = 0.0
                run_f[:] = 0.0
            run = np.flatnonzero(phase[a:b] == _RUN) + a
            if state[6] != 0.0:  # until the steady run at the latest: every seal slid
                _apply(inputs, frictions, shift, pistons, state, a, int(run[0]) if run.size else b)
                state[6] = 0.0 if run.size else state[6]
            if run.size:
                p = inputs.pressure_load_n[run]
                f_sums = [sum(f[run] for f in solution) for solution in frictions]
                known = np.isfinite(p) & np.isfinite(inputs.depth_m[run])
                for f_sum in f_sums:
                    known &= np.isfinite(f_sum)
                state[3] += known.sum()
                state[4] += p[known].sum()
                state[5] += inputs.depth_m[run][known].sum()
                for s, f_sum in enumerate(f_sums):
                    run_f[s] += f_sum[known].sum()
        else:
            if was_moving is True:  # an arrival: the run predicts the stop
                state[6] = 0.0
                window = _update(inputs, frictions, state, run_f, shift, a, hoist)
                if window is not None:  # each piston's x at rest and its ringing there
                    state[6], state[8] = 1.0, inputs.time_s[window.stop - 1]
                    state[9] = float(np.nanmean(inputs.pressure_load_n[window]))
                    for i, x in enumerate(inputs.x_m):
                        at_rest = x[window]
                        centre = float(np.nanmean(at_rest)) if np.isfinite(at_rest).any() else 0.0
                        pistons[0, i] = centre
                        pistons[1, i] = float(np.nanmax(np.abs(at_rest - centre), initial=0.0))
                        pistons[2, i] = 0.0
                state[3:6] = 0.0
                run_f[:] = 0.0
            if state[6] != 0.0:
                _apply(inputs, frictions, shift, pistons, state, a, b)
        was_moving = now_moving
    state[0] = 1.0
    state[2] = 1.0 if was_moving else 0.0
    state[7] = t[hi - 1]


def _update(
    inputs: ContinuityInputs,
    frictions: list[tuple[np.ndarray, ...]],
    state: np.ndarray,
    run_f: np.ndarray,
    shift: np.ndarray,
    at: int,
    hoist: HoistDescription,
) -> slice | None:
    """Each solution's shift at an arrival at sample ``at``, and the rest window it was
    set on (None: nothing predicts the stop's load)."""
    t = inputs.time_s
    count = state[3]
    if count < 2 or count * inputs.dt_s < MIN_RUN_S:
        return None
    window = rest_window(t, inputs.phase, inputs.pressure_load_n, at)
    if window.stop <= window.start:
        return None
    p = inputs.pressure_load_n[window]
    depth = inputs.depth_m[window]
    f_sums = [sum(f[window] for f in solution) for solution in frictions]
    known = np.isfinite(p) & np.isfinite(depth)
    for f_sum in f_sums:
        known &= np.isfinite(f_sum)
    if known.sum() < 2:
        return None
    tail = tail_rope_mass_kg(hoist, float(depth[known].mean())) - tail_rope_mass_kg(
        hoist, state[5] / count
    )
    p_rest = p[known].mean()
    for s, f_sum in enumerate(f_sums):
        predicted = (state[4] + run_f[s]) / count + G_STANDARD * float(tail)
        shift[s] = (predicted - p_rest - f_sum[known].mean()) * inputs.fractions
    return window


def _apply(
    inputs: ContinuityInputs,
    frictions: list[tuple[np.ndarray, ...]],
    shift: np.ndarray,
    pistons: np.ndarray,
    state: np.ndarray,
    a: int,
    b: int,
) -> None:
    """Add the active shift over [a, b): whole up to the rest window's end, then each
    piston's fading with its travel beyond its ringing at rest (``pistons``: x at rest,
    the ringing's reach and the travel so far, carried); ended (``state[6]`` = 0) where
    the raw load's 2 s centred mean leaves its value at rest by :data:`PAYLOAD_SHARE`
    (a payload change: its transient takes every seal through its presliding range,
    which wipes what the seals held out, the Maxwell-slip model's wiping-out)."""
    if b <= a:
        return
    fading = inputs.time_s[a:b] > state[8]
    if fading.any():
        first = a + int(np.argmax(fading))
        centred = centred_mean(inputs.time_s, inputs.pressure_load_n, first, b)
        changed = np.abs(centred - state[9]) > PAYLOAD_SHARE * abs(state[9])
        if changed.any():
            b = first + int(np.argmax(changed))
            state[6] = 0.0
            fading = fading[: b - a]
    reach = inputs.presliding_m
    for i, x in enumerate(inputs.x_m):
        beyond = np.abs(x[a:b] - pistons[0, i]) - pistons[1, i]
        beyond = np.where(fading & np.isfinite(beyond), np.maximum(beyond, 0.0), 0.0)
        travel = np.maximum.accumulate(np.concatenate(([pistons[2, i]], beyond)))[1:]
        pistons[2, i] = travel[-1] if travel.size else pistons[2, i]
        weight = np.clip(1.0 - travel / reach, 0.0, 1.0) if reach > 0 else np.ones(b - a)
        for s, solution in enumerate(frictions):
            if shift[s, i] != 0.0:
                solution[i][a:b] += shift[s, i] * weight
