"""Pass 1 of the replay planning: the record read, and every motion's timing.

:func:`read_record` reads a landed sample frame of one hoist into arrays (times in s after
its first sample) with what :func:`discovery.planning.plan_replay` needs of the whole
record: the motions, the quiet standstill and the pressure noise, the common-mode
pressure (gaps interpolated, 1-s mean), the depths at the standstills. For each motion,
:func:`trip_timing` finds its start and stop, top speed, depths (completed by the
winder profile when the record cuts it), the loading ramp before it and the pressure
levels around it; :func:`trailing_ramp_start` a load change after the last stop;
:func:`window_end` where a trip's window ends.
"""

from __future__ import annotations

import datetime as dt
import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
import polars as pl
from scipy import ndimage

from discovery.segmentation import (
    CUT_WORDS,
    complete_cut_trip,
    estimate_noise_sigma,
    loading_ramp,
    median_in,
    motion_times,
    plateau_median,
    record_trips,
    time_span,
)
from physics.conveyance import conveyance_speed
from physics.trip_rule import STANDSTILL_SPEED_M_S, TRIP_BRIDGE_S, segment_ids
from schemas.hoist import HoistDescription
from sims.logged_motion import knot_spacing_s
from sims.replay_plan import loading_threshold_pa

__all__ = [
    "RAMP_LEAD_S",
    "RAMP_MARGIN_S",
    "RecordArrays",
    "read_record",
    "trailing_ramp_start",
    "trip_timing",
    "window_end",
]

RAMP_MARGIN_S = 2.0  # scored samples start this long after a loading ramp ends

#: A trip's window ends this long before the next loading ramp as the pressure shows it
#: (:func:`window_end`). The load leads the pressure (the seals take part of it first,
#: the ropes ring), and the replay's refit moves each ramp's start earlier
#: (:func:`sims.replay.replay_fitted`), but never before the previous trip's window
#: ends: on validation day 104, windows ending at the ramp held 47 of 66 fitted ramp
#: starts back, most by 0.2-0.6 s, a few by 1-4 s, and the shorter, later ramp rang the
#: ropes twice as hard as the record shows.
RAMP_LEAD_S = 2.0


@dataclass(frozen=True)
class RecordArrays:
    """One hoist's record as arrays (times ``t`` in s after ``t_ref``) and what is read
    off it: the motions (index ranges of the trips replayed; ``trip_ids`` their ids by
    the trip rule; ``short_trips``: first, last and id of the trips too short to
    replay), the quiet standstill, the pressure noise, the common-mode pressure
    (``pc``; gaps interpolated: ``pc_filled``; its 1-s mean: ``pcs``), the depths at the
    standstills between the motions and the pressure change that counts as a loading
    ramp."""

    t_ref: dt.datetime
    t: np.ndarray
    p: np.ndarray
    depth: np.ndarray
    speed: np.ndarray
    temp: np.ndarray
    motions: list[tuple[int, int]]
    quiet: np.ndarray
    sigma: float
    pc: np.ndarray
    pc_filled: np.ndarray
    pcs: np.ndarray
    stops: list[float]
    ramp_threshold: float
    trip_ids: list[int]
    short_trips: list[tuple[int, int, int]]
    #: the logged piston positions (samples, n) [m]; None unless every one is logged
    x: np.ndarray | None = None

    @functools.cached_property
    def knot_s(self) -> float:
        """Knot spacing of the logged motion for this record's speed
        (:func:`sims.logged_motion.knot_spacing_s`)."""
        return knot_spacing_s(self.t, self.speed)

    @property
    def end_t(self) -> float:
        return float(self.t[-1])


def read_record(samples: pl.DataFrame, hoist: HoistDescription) -> RecordArrays:
    """The record's arrays, motions, noise and common-mode pressure; raises ValueError
    for missing columns or a record without a trip."""
    n = hoist.ropes_n
    pcols = [f"p{i}_pa" for i in range(1, n + 1)]
    need = {"time_utc", "depth_m", "speed_m_s", *pcols}
    missing = need - set(samples.columns)
    if missing:
        raise ValueError(f"samples: missing columns {sorted(missing)}")
    unlogged = [
        name
        for column, name in (("depth_m", "depth"), ("speed_m_s", "speed"))
        if samples[column].null_count() == samples.height
    ]
    if "depth" in unlogged:  # optional in the logs (contract 1a), needed here
        raise ValueError(
            f"the record has no {' and no '.join(unlogged)} logged: the replay follows "
            "the conveyance's encoder depth (and its speed, else the depth's derivative)"
        )
    frame = samples.sort("time_utc").unique("time_utc", keep="first", maintain_order=True)
    t_ref = frame["time_utc"][0]
    t = (frame["time_utc"].dt.epoch("us").to_numpy() - int(t_ref.timestamp() * 1e6)) / 1e6
    p = frame.select(pcols).to_numpy().astype(float)
    depth = frame["depth_m"].to_numpy().astype(float)
    # where the speed is missing, the depth's derivative (isolated holes interpolated)
    steps = np.diff(t)
    speed = conveyance_speed(
        t, frame["speed_m_s"].to_numpy().astype(float), depth, segment_ids(t),
        dt_s=float(np.median(steps)) if steps.size else 1.0,
    )  # fmt: skip
    temp = (
        frame["oil_temp_c"].to_numpy().astype(float)
        if "oil_temp_c" in frame.columns
        else np.full(t.size, np.nan)
    )
    xcols = [f"x{i}_m" for i in range(1, n + 1)]
    x = (
        frame.select(xcols).cast(pl.Float64).to_numpy()
        if set(xcols) <= set(frame.columns)
        else None
    )
    motions, trip_ids, short_trips = record_trips(t, speed, depth, hoist)
    if not motions:
        raise ValueError("samples: no trip (no encoder motion of at least 3 s) in the record")
    # noise from quiet standstill: >= 25 s after a stop (the rope bounce has decayed)
    quiet = np.ones(t.size, dtype=bool)
    for a_i, b_i in motions:
        quiet[time_span(t, t[a_i] - 1.0, t[b_i] + 25.0)] = False
    if quiet.sum() < 50:
        quiet = np.abs(np.nan_to_num(speed)) < STANDSTILL_SPEED_M_S
    sigma = estimate_noise_sigma(p, ~quiet)
    if not sigma > 0.0:  # every gap is set against it: no scale, no comparison
        raise ValueError(
            "samples: the pressure noise cannot be estimated (no pressure logged at "
            "standstill, or its readings never vary)"
        )
    pc = np.nanmean(p, axis=1)
    rate = 1.0 / max(float(np.median(np.diff(t))), 1e-6)
    # 1-s moving average of the common-mode pressure (O(n); a median over a day at 100 Hz
    # costs tens of seconds); spikes are rare and the ramp fit below is robust to them
    # missing values (dropped samples) interpolated in time, not filled with a constant
    known = np.isfinite(pc)
    pc_filled = np.interp(t, t[known], pc[known]) if known.any() else np.zeros_like(pc)
    pcs = ndimage.uniform_filter1d(pc_filled, size=max(3, int(rate) | 1))
    ramp_threshold = loading_threshold_pa(sigma)
    stops = _stop_depths(t, depth, motions, hoist.shaft.depth_m)
    return RecordArrays(
        t_ref, t, p, depth, speed, temp, motions, quiet, sigma, pc, pc_filled, pcs, stops,
        ramp_threshold, trip_ids, short_trips, x,
    )  # fmt: skip


def _stop_depths(
    t: np.ndarray, depth: np.ndarray, motions: list[tuple[int, int]], shaft: float
) -> list[float]:
    """Standstill depths between motions: shared by the trip before and after (chaining);
    NaN where the record holds no standstill (it starts or ends while moving). A
    standstill that a logger gap interrupts has a depth on each side of it
    (:func:`trip_timing`)."""
    bounds = (
        [(-np.inf, t[motions[0][0]])]
        + [(t[motions[k][1]], t[motions[k + 1][0]]) for k in range(len(motions) - 1)]
        + [(t[motions[-1][1]], np.inf)]
    )
    return [_stop_depth(t, depth, lo, hi, shaft) for lo, hi in bounds]


def _stop_depth(t: np.ndarray, depth: np.ndarray, lo: float, hi: float, shaft: float) -> float:
    """The logged depth of the standstill between times ``lo`` and ``hi`` (its median,
    within the shaft); NaN where no depth is logged there."""
    d = median_in(t, depth, lo + 1.0, hi - 0.5)
    if not np.isfinite(d):  # a standstill shorter than 1.5 s at the record's edge
        d = median_in(t, depth, lo + 0.05, hi - 0.05)
    return float(np.clip(d, 0.0, shaft)) if np.isfinite(d) else float("nan")


def shortest_round_trip_s(hoist: HoistDescription) -> float:
    """The least time a trip between the two nearest named positions and back takes
    [s]: the winder's trapezoid each way, at full speed, without its creep (a lower
    bound). A logger gap at rest shorter than this cannot hide trips that leave the
    conveyance where it was (:func:`trip_timing`: ``gap_before``).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> round(shortest_round_trip_s(load_hoist(EXAMPLE_HOIST)), 1)  # 280 m each way
    82.7
    """
    depths = sorted(set(hoist.shaft.positions_m.values()) | {0.0})
    gaps = np.diff(depths)
    distance = float(gaps[gaps > 0].min()) if np.any(gaps > 0) else hoist.shaft.depth_m
    w = hoist.winder
    v, a, b = w.max_speed_m_s, w.acceleration_m_s2, w.deceleration_m_s2
    reach = 0.5 * v * v * (1.0 / a + 1.0 / b)  # the distance to reach full speed and stop
    if distance >= reach:
        one_way = distance / v + 0.5 * v * (1.0 / a + 1.0 / b)
    else:  # a triangle: the top speed reached halfway through (a = b) or so
        one_way = float(np.sqrt(2.0 * distance * (1.0 / a + 1.0 / b)))
    return 2.0 * one_way


#: A standstill's logged depth either side of a logger gap differing by more than this
#: [m] says the conveyance moved in the gap (:func:`trip_timing`).
STANDSTILL_DEPTH_M = 0.5


def _around_gaps(
    t: np.ndarray, depth: np.ndarray, lo: float, gaps: np.ndarray, hi: float, shaft: float
) -> tuple[float, float]:
    """The standstill's depth logged before its first logger gap and after its last
    (``gaps``: :func:`_gap_starts` of the standstill between times ``lo`` and ``hi``)."""
    pre = _stop_depth(t, depth, lo, float(t[gaps[0]]), shaft)
    return pre, _stop_depth(t, depth, float(t[gaps[-1] + 1]), hi, shaft)


def _moved(
    t: np.ndarray, depth: np.ndarray, lo: float, gaps: np.ndarray, hi: float, shaft: float
) -> bool:
    """Whether the standstill's logged stretches between times ``lo`` and ``hi``, apart by
    its logger ``gaps`` (:func:`_gap_starts`), say the conveyance moved in a gap: one
    stretch's depth differs from another's (two short gaps around a stretch logged at
    another level hide a trip each way, which neither gap alone could)."""
    edges = [lo, *(x for g in gaps for x in (float(t[g]), float(t[g + 1]))), hi]
    stretches = zip(edges[::2], edges[1::2], strict=True)
    depths = [_stop_depth(t, depth, a, b, shaft) for a, b in stretches]
    known = [d for d in depths if np.isfinite(d)]
    return bool(known) and max(known) - min(known) > STANDSTILL_DEPTH_M


def _ends_history(
    rec: RecordArrays, hoist: HoistDescription, lo: float, gaps: np.ndarray, hi: float
) -> bool:
    """Whether the logger ``gaps`` of the standstill between times ``lo`` and ``hi``
    end what is known of the seals' history: one could hide a round trip
    (:func:`shortest_round_trip_s`), or the conveyance stood at different levels around
    them (:func:`_moved`)."""
    t = rec.t
    return bool(
        np.max(t[gaps + 1] - t[gaps]) >= shortest_round_trip_s(hoist)
        or _moved(t, rec.depth, lo, gaps, hi, hoist.shaft.depth_m)
    )


def _gap_starts(t: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """Indices j in [lo, hi) after which the logger stopped for more than
    :data:`~physics.trip_rule.TRIP_BRIDGE_S` (t[j + 1] - t[j])."""
    if hi <= lo:
        return np.zeros(0, dtype=np.int64)
    return lo + np.flatnonzero(np.diff(t[lo : hi + 1]) > TRIP_BRIDGE_S)


def trip_timing(rec: RecordArrays, hoist: HoistDescription, k: int) -> dict[str, Any]:
    """Pass 1, motion ``k`` of the record: start / stop times and depths, top speed, the
    loading ramp before it and the pressure levels around it; ``cut`` and ``skip`` say
    whether the record cuts it and why it cannot be prepared."""
    t, pc, pcs, motions = rec.t, rec.pc, rec.pcs, rec.motions
    a_i, b_i = motions[k]
    prev_end = float(t[motions[k - 1][1]]) if k > 0 else float(t[0]) - 2.0
    next_start = float(t[motions[k + 1][0]]) if k + 1 < len(motions) else rec.end_t
    t_m, t_e, vmax_arg = motion_times(t, rec.speed, hoist.winder, a_i, b_i)
    d0, d1 = rec.stops[k], rec.stops[k + 1]
    # a logger gap in the standstill before (after) the motion: the depth, the levels and
    # the loading are those logged after (before) it; one long enough to hide trips
    # that came back to the same depth ends the seals' known history (gap_before)
    shaft = hoist.shaft.depth_m
    before = _gap_starts(t, motions[k - 1][1] if k > 0 else 0, a_i)
    after = _gap_starts(t, b_i, motions[k + 1][0] if k + 1 < len(motions) else t.size - 1)
    gap_before = False
    gap_after, ramp_before_gap = np.inf, np.inf
    if before.size and before[-1] + 1 < a_i:
        lo = float(t[motions[k - 1][1]]) if k > 0 else -np.inf
        resumed = float(t[before[-1] + 1])
        _, post = _around_gaps(t, rec.depth, lo, before, float(t[a_i]), shaft)
        gap_before = _ends_history(rec, hoist, lo, before, float(t[a_i]))
        d0 = post if np.isfinite(post) else d0  # where it stood when it left
        if gap_before:
            # it moved, or may have, in the gap: only what is logged after it is this
            # trip's standstill (a shorter gap may hide a loading: bridged)
            prev_end = resumed - 2.0
    if after.size and after[0] > b_i:
        # where it stopped, and its payload there, are what is logged before the gap
        # (the motion after the gap may start straight out of another)
        hi = float(t[motions[k + 1][0]]) if k + 1 < len(motions) else np.inf
        pre, _ = _around_gaps(t, rec.depth, float(t[b_i]), after, hi, shaft)
        d1 = pre if np.isfinite(pre) else d1
        next_start = min(next_start, float(t[after[0]]))
        # the trip is compared up to a gap that ends the known history (what is logged
        # after it may stand elsewhere or carry another payload; a shorter gap at the
        # same level is the same standstill, compared across)
        if _ends_history(rec, hoist, float(t[b_i]), after, hi):
            gap_after = float(t[after[0]])
        # and its window ends before a payload change logged before the gap, which the
        # next trip's loading ramp does not hold where its history restarts after the
        # gap (gap_before): as before the record's end (trailing_ramp_start)
        ramp_before_gap = _load_change(rec, t_e + 2.0, float(t[after[0]]))
    # a motion that runs into (or out of) a logger gap the trip rule did not bridge is
    # cut there as by the record's end (start): the standstill beyond the gap is not its
    if b_i + 1 < t.size and t[b_i + 1] - t[b_i] > TRIP_BRIDGE_S:
        d1 = float("nan")
    if a_i > 0 and t[a_i] - t[a_i - 1] > TRIP_BRIDGE_S:
        d0 = float("nan")
    cut, skip = "", ""
    unseen = False  # too little of the standstill before it logged to see its loading
    if not (np.isfinite(d0) and np.isfinite(d1)):
        # the record starts or ends while the conveyance moves (or the encoder depth
        # is missing at a stop): the winder profile fitted to the logged depth
        # completes the trip; both ends unknown: nothing anchors it
        cut = "start" if not np.isfinite(d0) else "end"
        try:
            t_m, t_e, d0, d1, vmax_arg = complete_cut_trip(
                hoist, t, rec.depth, a_i, b_i, d0, d1, t_m, t_e, vmax_arg
            )
        except ValueError as exc:
            skip = f"{CUT_WORDS[cut]}: {exc}"
    if cut == "start":
        # no loading seen: the simulation starts at rest shortly before the motion
        r0, r1 = t_m - 2.0, t_m - 1.5
        p_pre = p_post = float("nan")
    else:
        s_lo = max(prev_end + 2.0, float(t[0]))
        r0, r1, p_pre, p_post = loading_ramp(t, pc, pcs, s_lo, t_m - 0.3, rec.ramp_threshold)
        # the record holds less of the standstill before its first motion than it takes
        # to see a loading whole: the trip only loads the seals' state for the next one
        # (after a gap that ends the history the trip is a warm-up anyway)
        if k == 0 and t_m - s_lo < STANDSTILL_SEEN_S:
            unseen = True
    # the depth the levels are read at: the tail rope hanging below it weighs in them
    levels_depth = d0
    if not np.isfinite(p_post):
        # no standstill before the motion in the record: the payload does not change
        # during a trip, so the level after its stop (or, cut there too, while moving),
        # with the tail rope that hangs there (at the start's depth, a trip up from
        # mid-shaft had taken 2 x 6.2 kg/m x 320 m of tail rope for payload)
        p_post = plateau_median(t, pcs, t_e + 2.0, next_start - 0.3, 2.0, from_start=True)
        p_pre, levels_depth = float("nan"), d1  # both levels one, read where it stopped
        if not np.isfinite(p_post):
            p_post = median_in(t, pc, t[a_i], t[b_i])
            levels_depth = median_in(t, rec.depth, t[a_i], t[b_i])
        if not np.isfinite(p_post) and not skip:
            skip = "no pressure logged to infer the payload from"
    return {
        "t_m": t_m,
        "t_e": t_e,
        "vmax": vmax_arg,
        "r0": r0,
        "r1": r1,
        "p_pre": p_pre,
        "p_post": p_post,
        "levels_depth": levels_depth,
        "gap_before": gap_before,
        "gap_after": gap_after,
        "standstill_unseen": unseen,
        "ramp_before_gap": ramp_before_gap,
        "d0": d0,
        "d1": d1,
        "cut": cut,
        "skip": skip,
        "a_t": float(t[a_i]),
        "b_t": float(t[b_i]),
    }


def trailing_ramp_start(rec: RecordArrays, timing: list[dict[str, Any]], notes: list[str]) -> float:
    """Where a payload change after the last stop (loading for a trip the record does
    not hold) starts as the pressure shows it; inf without one. The last trip's window
    ends :data:`RAMP_LEAD_S` before it (:func:`window_end`), as before any other ramp."""
    if timing and not timing[-1]["cut"]:
        r0 = _load_change(rec, timing[-1]["t_e"] + 2.0, rec.end_t)
        if np.isfinite(r0):
            notes.append(
                f"the payload changes after the last stop (from {r0:.0f} s): "
                "the last trip's window ends there"
            )
            return r0
    return np.inf


#: The least standstill [s] a record must hold before its first motion for that trip
#: to be compared: the two plateaus
#: :func:`~discovery.segmentation.loading_ramp` reads either side of a loading (2 s and
#: 3 s) and 3 s of ramp between them. A record that starts less than this before the
#: motion may start within or just after a loading it does not show, whose seals the
#: replay's start from rest does not hold (a probe on a loading of 5 s that ends 5 s
#: before the motion: 3.1-4.7 x the noise on that trip for records starting 6 s down to
#: 1 s before the motion; 1.5-1.6 x from 11 s, the loading seen). A choice, not a
#: measured bound: a record starting on a longer standstill may still start just after
#: a loading (the seals' state there is then the start from rest's).
STANDSTILL_SEEN_S = 8.0
#: The last stretch of a standstill [s] whose common-mode pressure tells a payload change
#: the record's end or a logger gap cuts (:func:`_load_change`) ...
CUT_CHANGE_S = 0.5
#: ... a change that began at most this long before the cut [s] (one cut in its first
#: ~1.7 s is what the ramp's own reading misses), in a standstill at least this long [s]
#: (a review: without these bounds the settling after a stop on validation day 104, the
#: ringing hoist, read as a change at 147 of ~1800 cut positions, 0 of them with one,
#: and a trip whose window it shortened failed at 3.5 x the noise instead of 2.9 x)
CUT_CHANGE_RECENT_S, CUT_STANDSTILL_S = 3.0, 5.0


def _load_change(rec: RecordArrays, lo: float, hi: float) -> float:
    """Where a payload change in the standstill ``[lo, hi]`` starts as the pressure
    shows it (:func:`~discovery.segmentation.loading_ramp` without its fallback); inf
    without one.

    A change the standstill's end cuts early (its level after read over the last 3 s
    of a ramp that began less than ~1.7 s before the end) is taken where the last
    :data:`CUT_CHANGE_S` depart from the level before by more than half the ramp
    threshold: it starts after the last 1 s mean within 3 sigma of that level (a probe:
    a loading cut 1.4-1.6 s in failed the trip before at 3.8-4.1 x the noise)."""
    t, pc, pcs = rec.t, rec.pc, rec.pcs
    r0, _, p_a, p_b = loading_ramp(t, pc, pcs, lo, hi, rec.ramp_threshold, fallback=False)
    if np.isfinite(r0) and abs(p_b - p_a) > rec.ramp_threshold:
        return r0
    span = time_span(t, lo, hi)
    if span.stop - span.start < 5 or hi - lo < CUT_STANDSTILL_S or not np.isfinite(p_a):
        return np.inf
    last = median_in(t, pc, float(t[span.stop - 1]) - CUT_CHANGE_S, hi)
    if not (np.isfinite(last) and abs(last - p_a) > 0.5 * rec.ramp_threshold):
        return np.inf
    calm = np.flatnonzero(np.abs(pcs[span] - p_a) <= 3.0 * rec.sigma)
    start = float(t[span][calm[-1]]) if calm.size else lo
    # only a change that began just before the end: an older departure is the settling
    # after the stop (a ringing hoist's 20-25 kPa over its first 10 s) or a change below
    # the threshold, over which a standstill is compared as without the cut
    return start if hi - start <= CUT_CHANGE_RECENT_S else np.inf


def window_end(t_stop: float, next_ramp: float, settle_s: float, end_t: float) -> float:
    """Where the window of a trip that stopped at ``t_stop`` ends: ``settle_s`` after
    the stop, :data:`RAMP_LEAD_S` before the next loading ramp the pressure shows
    (``next_ramp``; inf without one), at the record's end ``end_t``; but never sooner
    than :data:`RAMP_LEAD_S` after the stop, nor after the ramp (a ramp that soon after
    the stop leaves the stop's own settling the lead).

    >>> window_end(100.0, 140.0, 30.0, 1e9), window_end(100.0, 125.0, 30.0, 1e9)
    (130.0, 123.0)
    >>> window_end(100.0, 103.0, 30.0, 1e9), window_end(100.0, 101.0, 30.0, 1e9)
    (102.0, 101.0)
    """
    cap = min(next_ramp, max(next_ramp - RAMP_LEAD_S, t_stop + RAMP_LEAD_S))
    return min(t_stop + settle_s, cap, end_t)
