"""Vectorised event detection of the alarms: run lengths, debounce, one row per event.

A condition must hold ``min_duration`` before an alarm starts (the reported start is
where it began); once started, the alarm lasts while the condition holds with a
hysteresis band, and events of the same rule and rope closer than ``merge_gap_s``
merge. Numpy run lengths over the samples; Python loops only over detected events.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl

from physics.conveyance import quantum_of_turns
from transforms.alarm_rules import ALARM_RULES, alarm_id

__all__ = [
    "EventContext",
    "column",
    "debounced",
    "event_rows",
    "flatline_runs",
    "frozen_runs",
    "merge_events",
    "reading_step",
    "runs",
    "step_of_changes",
    "threshold_events",
    "unchanged",
]


def runs(mask: np.ndarray, breaks: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """First and last (inclusive) index of every run of True in ``mask``; ``breaks[i]``
    True ends a run between samples i and i + 1 (a logger gap).

    >>> runs(np.array([True, True, False, True, True, True]), np.array([0, 0, 0, 1, 0], bool))
    (array([0, 3, 4]), array([1, 3, 5]))
    """
    if breaks is None or mask.size < 2:
        edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
        return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    joined = mask[:-1] & mask[1:] & ~breaks  # sample i and i + 1 in one run
    starts = np.flatnonzero(mask & ~np.concatenate(([False], joined)))
    ends = np.flatnonzero(mask & ~np.concatenate((joined, [False])))
    return starts, ends


def merge_events(
    t_s: np.ndarray, starts: np.ndarray, ends: np.ndarray, merge_gap_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Merge events (sorted) whose gap is at most ``merge_gap_s``."""
    if starts.size == 0:
        return starts, ends
    new = np.concatenate(([True], t_s[starts[1:]] - t_s[ends[:-1]] > merge_gap_s))
    last = np.concatenate((new[1:], [True]))
    return starts[new], ends[last]


def debounced(
    t_s: np.ndarray,
    trigger: np.ndarray,
    hold: np.ndarray,
    *,
    min_duration_s: float,
    merge_gap_s: float,
    dt_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Events of a Schmitt trigger with a minimum on-time.

    An event starts where a run of ``trigger`` lasting ``min_duration_s`` begins and
    ends with the run of ``hold`` (the released condition, ``trigger`` implies it) that
    contains it; events closer than ``merge_gap_s`` merge. A run does not continue
    through a logger gap longer than ``merge_gap_s``: nothing is known in it (the gap
    is the dropout rule's), and the events on either side stay apart.
    """
    hold = hold | trigger
    breaks = np.diff(t_s) > merge_gap_s
    ts, te = runs(trigger, breaks)
    keep = (t_s[te] - t_s[ts] + dt_s) >= min_duration_s - 1e-9
    ts = ts[keep]
    if ts.size == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty
    hs, he = runs(hold, breaks)
    which = np.searchsorted(hs, ts, side="right") - 1
    held, first = np.unique(which, return_index=True)
    return merge_events(t_s, ts[first], he[held], merge_gap_s)


def threshold_events(
    t_s: np.ndarray,
    value: np.ndarray,
    threshold: np.ndarray | float,
    *,
    above: bool,
    hysteresis_fraction: float,
    min_duration_s: float,
    merge_gap_s: float,
    dt_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Events where ``value`` is above (or below) ``threshold``, with hysteresis."""
    finite = np.isfinite(value)
    band = np.abs(threshold) * hysteresis_fraction
    with np.errstate(invalid="ignore"):
        if above:
            trigger, hold = value > threshold, value > threshold - band
        else:
            trigger, hold = value < threshold, value < threshold + band
    return debounced(
        t_s,
        trigger & finite,
        hold & finite,
        min_duration_s=min_duration_s,
        merge_gap_s=merge_gap_s,
        dt_s=dt_s,
    )


@dataclass(frozen=True)
class EventContext:
    """Where the events are: the alarm rows' site, hoist and run, and the sample times."""

    site: str
    hoist: str
    run_id: str
    time: np.ndarray  # datetime64[us], UTC
    t_s: np.ndarray


def event_rows(
    ctx: EventContext,
    rule: str,
    rope: int | None,
    starts: np.ndarray,
    ends: np.ndarray,
    *,
    peak_of: np.ndarray | None,
    peak_max: bool,
    threshold: np.ndarray | float,
    message: str,
    peak_values: np.ndarray | None = None,
    report: np.ndarray | None = None,
) -> list[dict[str, object]]:
    """Alarm rows for detected events (loop over events, not samples).

    The peak is where ``peak_of`` is largest (``peak_max``) or smallest; its value is
    read from ``report`` (default ``peak_of``). Without ``peak_of`` the peak is the start
    and ``peak_values`` gives one value per event.
    """
    rows = []
    thresholds = np.broadcast_to(np.asarray(threshold, dtype=float), ctx.t_s.shape)
    for k, (s, e) in enumerate(zip(starts.tolist(), ends.tolist(), strict=True)):
        if peak_of is not None:
            segment = peak_of[s : e + 1]
            offset = int(np.nanargmax(segment) if peak_max else np.nanargmin(segment))
            peak_index = s + offset
            peak_value = float((peak_of if report is None else report)[peak_index])
        else:
            peak_index = s
            peak_value = float(peak_values[k]) if peak_values is not None else float("nan")
        start = ctx.time[s].astype("datetime64[us]").item().replace(tzinfo=dt.UTC)
        rule_info = ALARM_RULES[rule]
        rows.append(
            {
                "alarm_id": alarm_id(ctx.site, ctx.hoist, rule, rope, start),
                "run_id": ctx.run_id,
                "site": ctx.site,
                "hoist": ctx.hoist,
                "rule": rule,
                "rope": rope,
                "start_utc": start,
                "end_utc": ctx.time[e].astype("datetime64[us]").item().replace(tzinfo=dt.UTC),
                "peak_time_utc": ctx.time[peak_index]
                .astype("datetime64[us]")
                .item()
                .replace(tzinfo=dt.UTC),
                "peak_value": peak_value,
                "threshold": float(thresholds[peak_index]),
                "unit": rule_info.unit,
                "message": f"{message} [{rule_info.citation}]",
            }
        )
    return rows


def column(frame: pl.DataFrame, name: str) -> np.ndarray:
    """A column as float64 with NaN for null; all NaN when the frame lacks it."""
    if name not in frame.columns:
        return np.full(frame.height, np.nan)
    return frame.get_column(name).cast(pl.Float64).fill_null(np.nan).to_numpy()


def unchanged(x: np.ndarray) -> np.ndarray:
    """True where a sample repeats the previous one exactly (flat-line evidence)."""
    same = np.zeros(x.shape, dtype=bool)
    same[1:] = x[1:] == x[:-1]
    return same


def reading_step(x: np.ndarray) -> float:
    """The smallest change between consecutive finite readings of ``x`` that at least
    three changes share (to a thousandth of a pascal), else the smallest change (0 where
    none changes): a logger's reading step where it rounds (its quantum), the file's
    resolution or less where it does not. One reading off the grid (a garbage line, a
    restart) makes changes of its own, at most twice each: it does not set the step.

    >>> reading_step(np.array([0.0, 50.0, 50.0, 100.0, np.nan, 0.0])), reading_step(np.ones(3))
    (50.0, 0.0)
    >>> reading_step(np.array([0.0, 50, 0, 50, 0, 50, 51.2, 50, 0]))
    50.0
    """
    return step_of_changes(np.diff(np.asarray(x, dtype=float)))


def step_of_changes(changes: np.ndarray) -> float:
    """:func:`reading_step` of the changes between consecutive readings (any subset of
    them, e.g. a record's sampled pairs): the rule the depth's reading step follows
    (:func:`physics.conveyance.quantum_of_turns`, on its reversals), on the changes."""
    change = np.abs(np.asarray(changes, dtype=float))
    change = np.round(change[np.isfinite(change) & (change > 0.0)], 3)
    change = change[change > 0.0]
    if not change.size:
        return 0.0
    values, counts = np.unique(change, return_counts=True)
    shared = quantum_of_turns(values, counts)
    return shared if shared > 0.0 else float(values[0])


def flatline_runs(
    pressures: Sequence[np.ndarray], t_s: np.ndarray, duration_s: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per sensor, the first and last index (inclusive) of each stretch over which it
    repeats one reading for at least ``duration_s`` while another sensor's reading
    moves by more than the first could miss: the ``sensor_flatline`` rule
    (:mod:`transforms.alarm_rules`). A stretch starts at the sample its repeats copy.
    A sensor with kilopascals of noise never repeats a reading for seconds while the
    oil it shares with the others moves: it stopped, and its reading is not a pressure
    (the compensation takes it as not logged,
    :func:`transforms.compensation_record.flatlined_samples`).

    What the others must show: a logger that rounds to a step q (:func:`reading_step`)
    holds one reading while the pressure stays within a step, and the others' readings
    flip between neighbouring steps meanwhile (a 50 kPa step over 5 kPa of noise at
    rest: every sensor "repeated" for minutes while another flipped, and the rule once
    took all four for stuck, their tensions null over 7 % of the record). So another
    sensor j must span more than 2 q_k + q_j over the stretch: the pressure then moved
    by more than q_k (j's span less its own step; the second q_k a margin for its
    noise) and a working sensor k would have changed its reading. Where nothing rounds
    (q of a pascal or less) that is any change. And at least half the other sensors
    that change over the stretch must show it (one of one or two, two of three): a
    faulty sensor's own jump (a stuck one coming back) does not make the others,
    flipping their rounded readings at rest, stuck too; one that holds its reading
    over the stretch (stuck as well, or rounded at rest) says nothing either way, so
    three sensors stuck while the fourth follows the oil are all three taken.

    A stretch of the record known in part (a block's window) is a stretch of the whole
    when the part reaches ``duration_s`` past the sample asked about either side and the
    others move that far within it (not when they, frozen too or rounded, moved only
    before the part; the steps are read on the part, which holds the whole's where the
    sensors change within it, and a sensor changing nowhere in it takes the median of
    the others'). The steps are read only where some stretch lasts ``duration_s``.

    >>> t = np.arange(6.0)
    >>> stuck, live = np.array([1.0, 2, 2, 2, 2, 3]), np.array([5.0, 7, 9, 11, 13, 15])
    >>> flatline_runs([stuck, live], t, 3.0)[0]
    (array([1]), array([4]))
    >>> flip = np.array([5.0, 6, 5, 6, 5, 6])  # one step back and forth: not the oil
    >>> flatline_runs([stuck, flip], t, 3.0)[0]
    (array([], dtype=int64), array([], dtype=int64))
    """
    stretches = []
    for p in pressures:
        starts, ends = runs(unchanged(p) & np.isfinite(p))
        starts = np.maximum(starts - 1, 0)
        stretches.append((starts, ends, t_s[ends] - t_s[starts] >= duration_s))
    if not any(long.any() for _, _, long in stretches):  # the usual case: no step read
        return [(s[:0], e[:0]) for s, e, _ in stretches]
    steps = [reading_step(p) for p in pressures]
    # a sensor that changes nowhere in the arrays given (stuck through a block's whole
    # window) has the others' step, as its logger rounds them alike: read on the whole
    # record it had its own from before it stuck, and the block must decide as the whole
    given = [q for q in steps if q > 0.0]
    steps = [q if q > 0.0 or not given else float(np.median(given)) for q in steps]
    out = []
    for k, (starts, ends, long) in enumerate(stretches):
        keep = np.zeros(starts.size, dtype=bool)
        for r in np.flatnonzero(long):
            stretch = slice(starts[r], ends[r] + 1)
            changing = moved = 0
            for j, other in enumerate(pressures):
                seen = other[stretch]
                seen = seen[np.isfinite(seen)]
                spread = np.ptp(seen) if seen.size else 0.0
                if j == k or spread == 0.0:  # one held too (stuck, or rounded at rest)
                    continue  # says nothing either way
                changing += 1
                moved += bool(spread > 2.0 * steps[k] + steps[j])
            keep[r] = moved >= max(1, (changing + 1) // 2)
        out.append((starts[keep], ends[keep]))
    return out


def frozen_runs(
    pressures: Sequence[np.ndarray],
    t_s: np.ndarray,
    depth_m: np.ndarray,
    duration_s: float,
    travel_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """First and last index (inclusive) of each stretch over which every sensor repeats
    its reading for at least ``duration_s`` while the conveyance's depth changes by
    more than ``travel_m``: the ``sensor_stuck`` rule (:mod:`transforms.alarm_rules`), a
    logger whose pressures froze. A stretch starts at the sample its repeats copy.

    >>> t, depth = np.arange(6.0), np.array([0.0, 1, 2, 3, 4, 5])
    >>> frozen_runs([np.array([1.0, 2, 2, 2, 2, 3])] * 2, t, depth, 3.0, 2.0)
    (array([1]), array([4]))
    """
    frozen = np.logical_and.reduce([unchanged(p) for p in pressures])
    starts, ends = runs(frozen)
    starts = np.maximum(starts - 1, 0)
    with np.errstate(invalid="ignore"):
        travelled = np.abs(depth_m[ends] - depth_m[starts])
    keep = (t_s[ends] - t_s[starts] >= duration_s) & (travelled > travel_m)
    return starts[keep], ends[keep]
