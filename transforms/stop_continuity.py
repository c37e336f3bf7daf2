"""The load's continuity from a trip to its stop and from the stop to the next trip.

The payload does not change while the conveyance travels. Over a trip's steady run
(phase ``run`` of :mod:`physics.trip_rule`: full speed, no acceleration) every piston
slides one way and its seal holds the friction law's capacity, which the stick-slip
solution (:mod:`transforms.stick_slip`) knows; at a stop the pistons turn back into
their presliding, where what each seal keeps depends on the path in micrometres, on the
ringing that shakes it and on a law the record does not pin down. On the independent
simulator's validation days the estimate over the run phases is within 0.18 % of the
true load; at the pithead's arrivals after up trips it held 190-670 N more friction
than the truth's, after payload changes at the bottom 0.3-0.4 % of the load
(``benchmarks/diagnose_stop_continuity.py``).

A run so predicts the load at rest on either side of it (paper eq 3-4,
:func:`physics.tension.expected_load_n` at a = 0):

.. math:: \\hat L_{stop} = \\bar L_{run} + g\\,(m_t(z_{stop}) - m_t(\\bar z_{run}))

with :math:`m_t(z)` the tail ropes below the conveyance (:func:`physics.tension.
tail_rope_mass_kg`). :func:`apply_stop_continuity` sets each solution's seals

- at an arrival, so that its load over the first seconds at rest (:data:`SETTLE_S`
  after the stop, for :data:`SPAN_S`, ending where the raw load moves by
  :data:`PAYLOAD_SHARE`: a payload change begins) equals what the trip's whole steady
  run predicts; held while the seals stick (below), ended by a payload change;
- before a departure (:func:`backward_shift`), so that its load over the stop's last
  steady stretch (after its last payload change, at most :data:`BACK_S`) equals what
  the next trip's steady run predicts (its first :data:`NEXT_RUN_S`, within
  :data:`REACH_S` of the departure);
- where both reach (a stop without a payload change), to the mean of the two.

The runs' means are independent, better observations of the same state (the
constraint is exact but for the run's own error), so the update takes them whole: a
Kalman gain of 1 on the common mode, applied to each band member alike with its own
runs, so the band at the stop becomes the spread of the members' runs (an ensemble's
update; the members stand for the law, the bristles and the ropes, whose errors the
runs carry too).

Where the update goes: the sum of the seals' friction. A common stretch of the ropes
moves each sticking seal by its rope's stiffness (:math:`\\Delta F_i = a_i k \\Delta s`),
so rope i takes :math:`a_i / \\sum a` of the shift (the stiffness factors of
:class:`transforms.stick_slip_band.RopeSprings`). The arrival's holds whole up to the
rest window's end, then each piston's share fades as the estimate's piston moves beyond
the reach of its ringing in the window, linearly to nothing over one presliding range
F_s / sigma_0 (a seal that has slid holds the law's capacity, which the estimate knows);
a payload change (the raw load's 2 s mean leaving its value at rest by
:data:`PAYLOAD_SHARE`: its transient takes every seal through its presliding range)
ends it, as does the next steady run. The departure's holds over the stretch it was
set on.

Where it applies: ropes identified from the record's logged x
(:mod:`transforms.rope_identification`). With the ropes' prior instead (no x) the runs
themselves are 0.25-0.53 % off the truth on the validation days (the ropes' unknown
differences decide which seals slide in a run), so a run predicts no better than the
stop: with the arrival's update the median stop error went 0.36 / 0.27 / 0.25 / 0.09 ->
0.64 / 0.56 / 0.54 / 0.25 % (days 101-104); with both updates the worst windows went
3.50 / 2.37 / 1.50 / 0.82 -> 1.28 / 1.90 / 1.04 / 0.69 % but the medians to 0.38 / 0.37 /
0.36 / 0.28 % and the windows worse than raw 1 / 2 / 0 / 2 -> 1 / 4 / 2 / 10; it is not
applied there.

Measured (``benchmarks/eval_compensation.py``, session 42), days 101-104 before ->
arrivals only -> both: worst stop window 0.80 / 0.67 / 0.79 / 0.97 -> 0.80 / 0.67 /
0.40 / 0.97 -> 0.42 / 0.33 / 0.25 / 0.31 %, median 0.18 / 0.13 / 0.15 / 0.22 -> 0.17 /
0.12 / 0.08 / 0.19 -> 0.14 / 0.08 / 0.06 / 0.06 %, worst rope 1.13 / 1.04 / 1.84 / 1.18
-> 0.87 / 0.80 / 0.99 / 0.68 %, windows worse than raw by 0.2 points 0 / 1 / 0 / 4 ->
none -> none, band coverage 97 / 98 / 95 / 90 -> 100 / 100 / 97 / 100 % at a median
half-width of 0.92 / 0.89 / 0.84 / 0.55 -> 0.84 / 0.85 / 0.81 / 0.75 %. Own sims
(Maxwell-slip seals) worst 0.55 / 0.54 -> 0.42 / 0.47 %, median 0.30 / 0.33 -> 0.21 /
0.19 %, half-width 1.61 / 1.73 -> 1.22 / 1.30 %. The cost where the stop was right and
the runs are not: own sims with LuGre seals (shaken loose at rest: the estimate's
stops exact) median 0.01 -> 0.15 %, worst 0.52 / 0.60 -> 0.27 / 0.48 %, half-width 0.63
-> 0.84 %. The departure's run taken over its first 10 s only: day 104's windows after
a payload change at the bottom, where the ringing had shaken the seals loose (raw within
0.1 %), went 0.2-0.3 % high (4 worse than raw: the acceleration's ringing in the mean);
over the whole run as the arrival's is (up to 120 s), none.

Tried and not kept: the arrival's shift carried past payload changes at rest, fading
only with each piston's travel (days 101 and 102: a window after a payload change worse
than raw each, day 104's worst 1.09 %). A gain below 1 from the members, the innovation
d_0 (the run's prediction less the load at rest) taken as far as it exceeds what the
members' own innovations span, s^2 (per source the largest |d_m - d_0| / 1.96, in
quadrature): per arrival the positive-part James-Stein share max(0, 1 - s^2 / d_0^2)
left windows worse than raw 0 / 1 / 0 / 2; pooled over the record's arrivals (the
model error's variance by the method of moments) nothing moved: the law's capacity
members span the innovations (a capacity 20 % off moves a run, every seal sliding one
way, more than a stop), while on the validation days the runs are right and the stops
are not.

Where the seals drift (LuGre's single bristle, a hoist that rings:
:mod:`transforms.seal_drift`), the estimate's seals relax along the ringing's travel,
by exp(-R_i) with R_i = sigma_0 s_i / g each seal's drift exponent
(:func:`physics.lugre.lugre_drift`), and so does any error of their state. So each
shift relaxes with its seal (the estimate's exponents, ``relaxation``, from
:func:`transforms.stick_slip.stick_slip`): a seal takes exp(-R_i over the rest window)
of its share where the shift is set (:func:`drift_gains`: one the window's ringing
shakes loose ends it near the relaxed state the estimate relaxes to as well, so the
run's prediction corrects what is left of the estimate's error and no more), and the
arrival's share relaxes on with the seal's drift after its window. Maxwell-slip seals
do not drift: their shifts are held as before. Measured (session 64,
``benchmarks/eval_compensation.py``): validation day 104 (ringing) windows worse than
raw by more than 0.2 points 2 -> 0 (largest excess +0.210 -> +0.154), worst 0.33 ->
0.42 %, median 0.06 -> 0.09 % (the pithead's arrivals after up trips, where the
estimate keeps more friction than the truth, which its drift does not shed: the
:mod:`transforms.seal_drift` docstring's piston's own motion), band half-width 0.75 ->
0.60 %; days 101-103 within 0.02 points as before; own sims with LuGre seals median
0.15 / 0.16 -> 0.01 / 0.01 % (the estimate's exact stops back), worst 0.27 / 0.48 % as
before, half-width 0.84 / 0.82 -> 0.34 / 0.34 %; own Maxwell-slip sims unchanged.
The shares are the estimate's exponents for every band member alike (the members'
bristle stiffness differs by its factor).

Left out: the branch loss beyond the sensor while oil flows in a run (the
run's pistons creep at millimetres a minute: negligible at the contract's valves); a
trip with less than :data:`MIN_RUN_S` of steady run predicts nothing; a stop's stretch
between two payload changes keeps the solution as solved. A period that ends at rest
(``ropeload run --to`` inside a stop, or a record whose export ends there) gives its
last stop the arrival's update only; run again over the following data, that stop
takes the departure's too (the rows change: more data, a better estimate).

The pass is sequential and resumable (:func:`continuity_state`): a block carries the
trip's run sums, the arrival's shift with how far each piston has moved since, and the
departure's shift once found, so a record compensated block by block gives the same
update as read whole. It reads up to :data:`LOOK_AHEAD_S` past a block's first stage:
a block solves the stick-slip estimate and its members that far
(``BlockCompensation.spring_hi``) and reads that much more after its end
(:func:`transforms.compensation_record.compensation_look_ahead_s`), its filters' halo
beyond.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from physics.tension import tail_rope_mass_kg
from physics.trip_rule import PHASES, TRIP_BRIDGE_S
from schemas.hoist import G_STANDARD, HoistDescription

__all__ = [
    "BACK_S",
    "LOOK_AHEAD_S",
    "MIN_RUN_S",
    "MIN_WINDOW_S",
    "NEXT_RUN_S",
    "PAYLOAD_SHARE",
    "REACH_S",
    "SETTLE_S",
    "SPAN_S",
    "ContinuityInputs",
    "apply_stop_continuity",
    "backward_shift",
    "continuity_state",
    "drift_gains",
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
#: A trip predicts its stop's load from at least this much steady run [s] ...
MIN_RUN_S = 2.0
#: ... over a rest window at least this long [s]: longer than two periods of the
#: slowest bounce, or the ringing does not average out of its mean.
MIN_WINDOW_S = 3.0
#: The next trip's steady run predicts the load at rest up to this long before its
#: departure [s] (:func:`backward_shift`) ...
BACK_S = 90.0
#: ... from its first seconds of steady run, at most this many [s] ...
NEXT_RUN_S = 120.0
#: ... which start within this long of the departure [s] (the acceleration).
REACH_S = 30.0
#: How far past a block the continuity reads [s]: the stick-slip solutions are solved
#: this far past the block's first stage, and the block reads that much more after its
#: end (:func:`transforms.compensation_record.compensation_look_ahead_s`).
LOOK_AHEAD_S = BACK_S + REACH_S + NEXT_RUN_S
_RUN = PHASES.index("run")
_STANDSTILL = PHASES.index("standstill")
# state: [ran, continues, was moving, run samples, run sum of P, run sum of depth,
# active, last time, fade from (time), the raw load at rest, backward held, its
# departure's time, its first sample's time], each piston's x at rest, its ringing's
# reach, its travel beyond and its seal's drift exponent since the rest window, then per
# solution the run sum of F, the arrival's shifts and the departure's
_HEAD = 13
_PISTONS = 4
_PER_PISTON = 4
_PER_SOLUTION = 1 + 2 * _PISTONS


def continuity_state(solutions: int) -> np.ndarray:
    """A fresh state of :func:`apply_stop_continuity` for ``solutions`` solutions (the
    estimate and its band's members) of four pistons."""
    return np.zeros(_HEAD + _PER_PISTON * _PISTONS + solutions * _PER_SOLUTION)


@dataclass(frozen=True)
class ContinuityInputs:
    """What :func:`apply_stop_continuity` reads over a block and its look-ahead.

    ``time_s`` [s]; ``phase`` the trip rule's phase codes (:func:`physics.trip_rule.
    trip_label_codes`); ``depth_m``; ``pressure_load_n`` the sensors' pressures times
    the piston area summed over the four (unknown ones as the others' mean);
    ``x_m`` the estimate's piston displacements; ``fractions`` each rope's share of a
    common shift (:math:`a_i / \\sum a`); ``presliding_m`` one seal's presliding range
    F_s / sigma_0 [m]; ``dt_s`` the logger's nominal step [s]; ``capacity_n`` one
    seal's static friction F_s [N] (:func:`_update`: inf, no bound); ``relaxation``
    the estimate's drift exponent of each seal at each sample, shape (samples, 4)
    (:func:`transforms.stick_slip.stick_slip`'s ``relaxation_out``; None: no drift),
    by which the shifts relax (:func:`drift_gains`)."""

    time_s: np.ndarray
    phase: np.ndarray
    depth_m: np.ndarray
    pressure_load_n: np.ndarray
    x_m: tuple[np.ndarray, ...]
    fractions: np.ndarray
    presliding_m: float
    dt_s: float
    capacity_n: float = np.inf
    relaxation: np.ndarray | None = None


def rest_window(time_s: np.ndarray, phase: np.ndarray, load_n: np.ndarray, at: int) -> slice:
    """The samples of the rest window after an arrival at sample ``at``: from
    :data:`SETTLE_S` after it for :data:`SPAN_S`, while the conveyance stands still, no
    logger gap exceeds :data:`~physics.trip_rule.TRIP_BRIDGE_S`, and the 2 s centred
    mean of ``load_n`` (the raw load) stays within :data:`PAYLOAD_SHARE` of its value at
    the window's start. Empty where less than :data:`MIN_WINDOW_S` remains.

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
    # standing still from the arrival on: a move before the window (a stop shorter than
    # SETTLE_S) leaves it in another stop
    still = phase[at:hi] == _STANDSTILL
    gaps = np.diff(time_s[at:hi]) > TRIP_BRIDGE_S
    cut = hi
    if not still.all():
        cut = at + int(np.argmin(still))
    if gaps.any():
        cut = min(cut, at + 1 + int(np.argmax(gaps)))
    if cut <= lo:
        return slice(lo, lo)
    # the raw load's 2 s centred mean against its value at the window's start
    centred = centred_mean(time_s, load_n, lo, cut, phase)
    reference = centred[0]
    if not np.isfinite(reference):
        return slice(lo, lo)
    moved = ~(np.abs(centred - reference) <= PAYLOAD_SHARE * abs(reference))
    if moved.any():
        cut = lo + int(np.argmax(moved))
    if cut <= lo or time_s[cut - 1] - time_s[lo] < MIN_WINDOW_S:
        return slice(lo, lo)
    return slice(lo, cut)


def centred_mean(
    time_s: np.ndarray,
    values: np.ndarray,
    lo: int,
    hi: int,
    phase: np.ndarray | None = None,
) -> np.ndarray:
    """The 2 s centred mean of ``values`` (its known ones; with ``phase``, those at rest
    only) at the samples [lo, hi), from the samples either side as far as they go; NaN
    where none is known. At rest only: the load's watch for a payload change at rest
    does not read the swing of a departure a second away as one.

    >>> t = np.arange(6.0)
    >>> centred_mean(t, np.array([0.0, 3.0, np.nan, 6.0, 9.0, 12.0]), 1, 4).tolist()
    [1.5, 4.5, 7.5]
    >>> moving = np.array([_STANDSTILL] * 4 + [_RUN] * 2)
    >>> centred_mean(t, np.array([0.0, 3.0, np.nan, 6.0, 9.0, 12.0]), 1, 4, moving).tolist()
    [1.5, 4.5, 6.0]
    """
    n = time_s.size
    w_lo = int(np.searchsorted(time_s, time_s[lo] - 1.0, side="left")) if hi > lo else lo
    w_hi = (
        min(n, int(np.searchsorted(time_s, time_s[hi - 1] + 1.0, side="right"))) if hi > lo else lo
    )
    part = values[w_lo:w_hi]
    known = np.isfinite(part)
    if phase is not None:
        known &= phase[w_lo:w_hi] == _STANDSTILL
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
    pistons' friction over the block and its look-ahead [N] (NaN where unsolved; an
    array two solutions share is shifted once, by the first's shift);
    ``state``: :func:`continuity_state`, carried from the previous part (its ``[1]``
    unused: a logger gap longer than :data:`~physics.trip_rule.TRIP_BRIDGE_S` ends a trip
    whatever the segments).
    """
    t, phase = inputs.time_s, inputs.phase
    solutions = len(frictions)
    base = _HEAD + _PER_PISTON * _PISTONS
    room = (state.size - base) // _PER_SOLUTION
    if solutions > room:
        raise ValueError(f"{solutions} solutions: the state holds {room}")
    run_f = state[base : base + solutions]
    shifts = state[base + room : base + room * _PER_SOLUTION].reshape(2, room, _PISTONS)
    shift, back = shifts[0, :solutions], shifts[1, :solutions]
    # x at rest, reach, travel, drift exponent
    pistons = state[_HEAD:base].reshape(_PER_PISTON, _PISTONS)
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
                        pistons[3, i] = 0.0
                state[3:6] = 0.0
                run_f[:] = 0.0
            held = backward_shift(inputs, frictions, state, back, a, hoist, until=b)
            overlap = (a, a) if held is None else (max(a, held[0]), min(b, held[1]))
            forward_end = a
            if state[6] != 0.0:  # where both predict the stop, each takes half
                scale = np.ones(b - a)
                scale[overlap[0] - a : overlap[1] - a] = 0.5
                forward_end = _apply(inputs, frictions, shift, pistons, state, a, b, scale)
            if overlap[1] > overlap[0]:
                _add_backward(frictions, back, overlap, forward_end)
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
    set on (None: nothing predicts the stop's load). None too where the estimate's
    load at rest is further from the run's prediction than its four seals can hold
    between their extremes (2 x 4 x ``capacity_n``): the payload changed before the
    window (one done within SETTLE_S of the arrival, or while the conveyance crept in),
    which the window's own payload check, from its start on, cannot see."""
    t = inputs.time_s
    count = state[3]
    if count < 2 or count * inputs.dt_s < MIN_RUN_S:
        return None
    window = rest_window(t, inputs.phase, inputs.pressure_load_n, at)
    if window.stop <= window.start:
        return None
    rest = _means(inputs, frictions, np.arange(window.start, window.stop))
    if rest is None:
        return None
    loads, depth, _ = rest
    tail = tail_rope_mass_kg(hoist, depth) - tail_rope_mass_kg(hoist, state[5] / count)
    predicted = (state[4] + run_f[: len(frictions)]) / count + G_STANDARD * float(tail)
    if abs(predicted[0] - loads[0]) > 2.0 * _PISTONS * inputs.capacity_n:
        return None
    gains = drift_gains(inputs, window.start, window.stop)
    for s in range(len(frictions)):
        shift[s] = (predicted[s] - loads[s]) * inputs.fractions * gains
    return window


def backward_shift(
    inputs: ContinuityInputs,
    frictions: list[tuple[np.ndarray, ...]],
    state: np.ndarray,
    back: np.ndarray,
    at: int,
    hoist: HoistDescription,
    until: int | None = None,
) -> tuple[int, int] | None:
    """The departure's shifts for the stop holding sample ``at`` (into ``back``, per
    solution and piston) and the samples [first, departure) they hold on; None where no
    steady run follows within the look-ahead, or where the departure is more than
    :data:`BACK_S` after the sample before ``until`` (the end of the samples the caller
    shifts): its stretch cannot reach them, and its run may lie beyond the
    :data:`LOOK_AHEAD_S` past them that a block solves, so it is left to the call that
    reaches it rather than found from part of its run and held.

    The stop's last steady stretch (after its last payload change, at most
    :data:`BACK_S` before the departure) carries the load the next trip lifts: the first
    :data:`NEXT_RUN_S` of that trip's steady run, less the tail ropes' change, predict it
    as the previous run predicts the arrival's (:func:`apply_stop_continuity`). Its rest
    window: the :data:`SPAN_S` before the last second at rest, within the stretch (whose
    start is where the raw load's 2 s centred mean last left its value there by
    :data:`PAYLOAD_SHARE`). Held in ``state`` once found (the departure's and the
    stretch's first sample's times), so a stop that a block edge cuts takes the shifts
    the record read whole gives it."""
    t, phase = inputs.time_s, inputs.phase
    # a departure more than BACK_S past the samples shifted now is not theirs: the scan
    # stops there, not at the end of the block's look-ahead
    end = t.size if until is None else int(np.searchsorted(t, t[until - 1] + BACK_S, "right"))
    ahead = np.flatnonzero(phase[at:end] != _STANDSTILL)
    if ahead.size == 0:
        return None
    departure = at + int(ahead[0])
    if state[10] != 0.0 and state[11] == t[departure]:
        return int(np.searchsorted(t, state[12], side="left")), departure
    state[10] = 0.0
    if until is not None and (until <= at or t[until - 1] < t[departure] - BACK_S):
        return None  # the stretch starts after the samples shifted now
    # the stop's last steady stretch ends a second before the departure: a logger gap
    # there (before that second's first sample or in it) leaves nothing known across it
    last = int(np.searchsorted(t, t[departure] - 1.0, side="left"))
    if last == 0 or (np.diff(t[last - 1 : departure + 1]) > TRIP_BRIDGE_S).any():
        return None
    # the next steady run: within REACH_S, no stop or logger gap on the way
    reach = int(np.searchsorted(t, t[departure] + REACH_S, side="right"))
    runs = np.flatnonzero(phase[departure:reach] == _RUN)
    if runs.size == 0:
        return None
    first_run = departure + int(runs[0])
    end = int(np.searchsorted(t, t[first_run] + NEXT_RUN_S, side="left"))
    way = phase[departure:end]
    if (way == _STANDSTILL).any():
        end = departure + int(np.argmax(way == _STANDSTILL))
    if (np.diff(t[departure:end]) > TRIP_BRIDGE_S).any():
        return None
    run = np.flatnonzero(phase[first_run:end] == _RUN) + first_run
    run_means = _means(inputs, frictions, run)
    if run_means is None or run_means[2] * inputs.dt_s < MIN_RUN_S:
        return None
    # the stop's last steady stretch, back from its last second
    earliest = int(np.searchsorted(t, t[departure] - BACK_S, side="left"))
    # it starts after its last moving sample, or at the first sample after its last
    # logger gap (marked on the sample before the gap: the one after it is at rest)
    breaks = phase[earliest:last] != _STANDSTILL
    breaks[:-1] |= np.diff(t[earliest:last]) > TRIP_BRIDGE_S
    start = earliest
    if breaks.any():
        start = earliest + int(np.flatnonzero(breaks)[-1]) + 1
    if last - start < 2:
        return None
    centred = centred_mean(t, inputs.pressure_load_n, start, last, phase)
    reference = centred[-1]
    if not np.isfinite(reference):
        return None
    moved = ~(np.abs(centred - reference) <= PAYLOAD_SHARE * abs(reference))
    if moved.any():
        start += int(np.flatnonzero(moved)[-1]) + 1
    window_lo = max(start, int(np.searchsorted(t, t[departure] - 1.0 - SPAN_S, side="left")))
    if last - window_lo < 2 or t[last - 1] - t[window_lo] < MIN_WINDOW_S:
        return None
    rest_means = _means(inputs, frictions, np.arange(window_lo, last))
    if rest_means is None:
        return None
    (run_load, run_depth, _), (rest_load, rest_depth, _) = run_means, rest_means
    tail = tail_rope_mass_kg(hoist, rest_depth) - tail_rope_mass_kg(hoist, run_depth)
    predicted = run_load + G_STANDARD * float(tail)
    gains = drift_gains(inputs, window_lo, last)
    for s_ in range(len(frictions)):
        back[s_] = (predicted[s_] - rest_load[s_]) * inputs.fractions * gains
    state[10], state[11], state[12] = 1.0, t[departure], t[start]
    return start, departure


def _means(
    inputs: ContinuityInputs, frictions: list[tuple[np.ndarray, ...]], samples: np.ndarray
) -> tuple[np.ndarray, float, int] | None:
    """Each solution's mean load (the sensors' plus its seals') and the mean depth over
    the samples all of them know; None where fewer than two are known."""
    p = inputs.pressure_load_n[samples]
    depth = inputs.depth_m[samples]
    f_sums = [sum(f[samples] for f in solution) for solution in frictions]
    known = np.isfinite(p) & np.isfinite(depth)
    for f_sum in f_sums:
        known &= np.isfinite(f_sum)
    count = int(known.sum())
    if count < 2:
        return None
    p_mean = float(p[known].mean())
    loads = np.array([p_mean + float(f_sum[known].mean()) for f_sum in f_sums])
    return loads, float(depth[known].mean()), count


def drift_gains(inputs: ContinuityInputs, lo: int, hi: int) -> np.ndarray:
    """Each seal's share of a shift set on the rest window [lo, hi): exp(-R_i), R_i
    its drift exponent over the window (``inputs.relaxation``; 1 without).

    LuGre's drift relaxes a seal's friction, and any error of it, by exp(-R) along the
    path (:func:`physics.lugre.lugre_drift`): a seal the window's ringing shakes loose
    ends it near the relaxed state the estimate relaxes to as well, so the run's
    prediction there corrects what is left of the estimate's error, not all of it, and
    the run's own error would take its place (validation day 104, a ringing hoist:
    without this an arrival at the bottom and the stop after a payload change there
    0.2 points worse than raw, where the estimate alone was within 0.1 % of the truth).

    >>> import numpy as np
    >>> inputs = ContinuityInputs(np.arange(3.0), np.zeros(3, int), np.zeros(3),
    ...     np.zeros(3), (np.zeros(3),) * 4, np.full(4, 0.25), 1e-5, 1.0,
    ...     relaxation=np.array([[0.0, 0.5, 0.5], [0.0] * 3, [0.0] * 3, [0.0, 2.0, 0.0]]).T)
    >>> drift_gains(inputs, 1, 3).round(3).tolist()
    [0.368, 1.0, 1.0, 0.135]
    """
    if inputs.relaxation is None or hi <= lo:
        return np.ones(_PISTONS)
    exponents = np.nansum(inputs.relaxation[lo:hi], axis=0)
    return np.exp(-exponents)


def _add_backward(
    frictions: list[tuple[np.ndarray, ...]],
    back: np.ndarray,
    span: tuple[int, int],
    forward_end: int,
) -> None:
    """Add the departure's shifts over ``span``, half of them where the arrival's holds
    too (before ``forward_end``: the two predictions of the same load averaged)."""
    lo, hi = span
    weight = np.ones(hi - lo)
    weight[: max(0, min(forward_end, hi) - lo)] = 0.5
    for i in range(_PISTONS):
        for s in _owners(frictions, i):
            if back[s, i] != 0.0:
                frictions[s][i][lo:hi] += back[s, i] * weight


def _owners(frictions: list[tuple[np.ndarray, ...]], piston: int) -> list[int]:
    """The solutions whose array of ``piston`` no solution before them holds too: an
    array two solutions share is shifted once (by the first's shift)."""
    seen: set[int] = set()
    owners = []
    for s, solution in enumerate(frictions):
        if id(solution[piston]) not in seen:
            seen.add(id(solution[piston]))
            owners.append(s)
    return owners


def _apply(
    inputs: ContinuityInputs,
    frictions: list[tuple[np.ndarray, ...]],
    shift: np.ndarray,
    pistons: np.ndarray,
    state: np.ndarray,
    a: int,
    b: int,
    scale: np.ndarray | None = None,
) -> int:
    """Add the active shift over [a, b) (times ``scale`` there, if given) and return
    where it stopped (b, or a payload change's sample): as set (:func:`drift_gains`) up
    to the rest window's end, then each piston's fading with its travel beyond its
    ringing at rest
    (``pistons``: x at rest, the ringing's reach, the travel so far and the seal's drift
    exponent since the window, carried; that drift relaxes it too, exp(-R)); ended
    (``state[6]`` = 0) where
    the raw load's 2 s centred mean leaves its value at rest by :data:`PAYLOAD_SHARE`
    (a payload change: its transient takes every seal through its presliding range,
    which wipes what the seals held out, the Maxwell-slip model's wiping-out)."""
    if b <= a:
        return b
    fading = inputs.time_s[a:b] > state[8]
    if fading.any():
        first = a + int(np.argmax(fading))
        centred = centred_mean(inputs.time_s, inputs.pressure_load_n, first, b, inputs.phase)
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
        if inputs.relaxation is not None:  # the seal's drift since the window relaxes it
            drift = np.where(fading, np.nan_to_num(inputs.relaxation[a:b, i]), 0.0)
            exponent = pistons[3, i] + np.cumsum(drift)
            pistons[3, i] = exponent[-1] if exponent.size else pistons[3, i]
            weight = weight * np.exp(-exponent)
        if scale is not None:
            weight = weight * scale[: b - a]
        for s in _owners(frictions, i):
            if shift[s, i] != 0.0:
                frictions[s][i][a:b] += shift[s, i] * weight
    return b
