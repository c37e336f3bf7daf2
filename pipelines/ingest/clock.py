"""A logger clock that steps back mid-file: its repeated stretch is quarantined, not merged.

A logger whose clock is set back (by hand, by a time server, a wrong daylight-saving
rule) goes on logging with times it already logged: ``t, t + dt, ...`` again, each
sample a millisecond or two off the first stream's by jitter. Landed, the two streams
interleave (only exactly equal times collide) and every later step of the pipeline
sees a hoist that jumps between two states 20 ms apart.

The rule, per file, on the UTC times in file order (after the daylight-saving
disambiguation of :mod:`.local_time`, so a repeated local hour is no step):

* the *latest time read* is the largest sample time of the file so far;
* a row whose time is earlier than that by more than :func:`tolerance_us` (rows swapped
  with a neighbour by jitter are not a step: they land, sorted) starts a **clock step
  back**;
* that row and every following row, until a time passes the latest time read before
  the step, are quarantined with one reason naming the step
  (:func:`clock_step_reason`: its size and the line or sample where it began). The
  first row past that time lands, and the file goes on as before.

A lone time ahead of both its neighbours, which go on one timeline, is no step at all
but a corrupted time (a year 2027 in a 2026 file): that row alone is quarantined
(:func:`time_ahead_reason`) and moves no clock; taken as the latest time read, it had
quarantined every later row of the file as a step back (:func:`lone_times_ahead`). Its
neighbours are judged within a batch: such a row last in its batch is taken as read.
So is a short stretch of such rows (:func:`stretches_ahead`: a wrong year on a few rows,
a time server's wrong hour for seconds), which lasted less than its lead: taken as the
latest times read, two rows a year ahead had quarantined the rest of their file.

The state (:class:`ClockState`) carries over batches of a file, and over a resume of a
growing CSV (the manifest keeps it: ``clock_latest_utc``, ``clock_step_line``,
``clock_step_s``).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

import numpy as np
import polars as pl

__all__ = [
    "CLOCK_STEP_TOLERANCE_S",
    "REASON_CLOCK_STEP_PREFIX",
    "ClockState",
    "clock_step_reason",
    "clock_steps",
    "lone_times_ahead",
    "steps_note",
    "stretches_ahead",
    "time_ahead_reason",
    "tolerance_us",
]

#: A time this much (or less) before the latest already read is jitter, not a step [s]:
#: ten samples at 50 Hz, far beyond a neighbour swapped by the logger's timing.
CLOCK_STEP_TOLERANCE_S = 0.2
#: ... or three nominal sample periods, where that is more (a slow logger).
_TOLERANCE_PERIODS = 3
REASON_CLOCK_STEP_PREFIX = "the logger clock stepped back"
_LOW = np.iinfo(np.int64).min
_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)


@dataclass
class ClockState:
    """Where a file's clock stood after the rows read so far.

    ``latest_us``: the latest sample time read (µs since the epoch, UTC), None before
    any. ``step_line``/``step_s``: the clock step back the rows read last are inside
    (its first line or sample, its size in seconds), None when not in one. ``steps``:
    the steps begun in this reading (line or sample, seconds), for the file's notes.
    """

    latest_us: int | None = None
    step_line: int | None = None
    step_s: float | None = None
    steps: list[tuple[int, float]] = field(default_factory=list)

    @property
    def latest_utc(self) -> dt.datetime | None:
        if self.latest_us is None:
            return None
        return _EPOCH + dt.timedelta(microseconds=self.latest_us)

    @classmethod
    def carried(
        cls, latest_utc: dt.datetime | None, step_line: int | None, step_s: float | None
    ) -> ClockState:
        """The state an earlier reading of the file's first part left (the manifest's)."""
        latest = None
        if latest_utc is not None:
            latest = (latest_utc - _EPOCH) // dt.timedelta(microseconds=1)
        in_step = latest is not None and step_line is not None and step_s is not None
        return cls(latest, step_line if in_step else None, step_s if in_step else None)


def tolerance_us(period_s: float | None) -> int:
    """How far before the latest time read a row may be without being a step [µs]:
    :data:`CLOCK_STEP_TOLERANCE_S`, or three nominal sample periods where more."""
    periods = _TOLERANCE_PERIODS * period_s if period_s and period_s > 0 else 0.0
    return round(max(CLOCK_STEP_TOLERANCE_S, periods) * 1e6)


def clock_step_reason(where: str, line: int, seconds: float) -> str:
    """The quarantine reason of every row of one step.

    >>> clock_step_reason("line", 45496, 29.981)
    'the logger clock stepped back 30.0 s at line 45496: time before the latest already read'
    """
    return (
        f"{REASON_CLOCK_STEP_PREFIX} {_size(seconds)} s at {where} {line}: "
        "time before the latest already read"
    )


def time_ahead_reason(seconds: float) -> str:
    """The quarantine reason of a lone time ahead of its neighbours (:func:`lone_times_ahead`).

    >>> time_ahead_reason(31536000.0)
    'time 31536000.0 s ahead of the rows around it, which go on one timeline'
    """
    return f"time {_size(seconds)} s ahead of the rows around it, which go on one timeline"


def lone_times_ahead(t: np.ndarray, valid: np.ndarray, tolerance: int) -> np.ndarray:
    """Rows whose time is more than ``tolerance`` ahead of both known neighbours while
    the row after it is not more than ``tolerance`` before the row before it (the two
    go on one timeline) [bool per row; ``t`` in µs, ``valid`` where known]. The first
    and the last row have one neighbour in the batch: never.

    >>> t = np.array([0, 20, 40, 9_000_000, 60, 80, 100]) * 1000
    >>> lone_times_ahead(t, np.ones(7, bool), 200_000).nonzero()[0].tolist()
    [3]
    >>> gap = np.array([0, 20, 40, 9_000_000, 9_000_020]) * 1000  # a logger's gap
    >>> bool(lone_times_ahead(gap, np.ones(5, bool), 200_000).any())
    False
    """
    ahead = np.zeros(t.size, np.bool_)
    if t.size < 3:
        return ahead
    prev, mid, nxt = t[:-2], t[1:-1], t[2:]
    known = valid[:-2] & valid[1:-1] & valid[2:]
    ahead[1:-1] = (
        known & (mid > prev + tolerance) & (mid > nxt + tolerance) & (nxt >= prev - tolerance)
    )
    return ahead


#: Rows stepping back that :func:`stretches_ahead` looks behind, per batch (each costs a
#: pass over the rows before it; a file whose rows are in no order has thousands).
_MAX_STRETCH_ENDS = 64


def stretches_ahead(t: np.ndarray, valid: np.ndarray, tolerance: int) -> np.ndarray:
    """Rows of a short stretch whose times run ahead of the rows before and after it,
    which go on one timeline: the lead of each such row's stretch [µs], 0 elsewhere.

    A stretch begins with a jump ahead of more than ``tolerance`` and ends with the
    first row back on the timeline before it (not more than ``tolerance`` before the
    row before the jump, and more than ``tolerance`` before the stretch's first time);
    it is short when it lasted (its last time less its first) less than its lead (a
    logger that wrote a wrong year on a few rows, a time server's wrong hour for
    seconds). A clock ahead for longer than its lead, then set back, is a step back
    (:func:`clock_steps`). One row is :func:`lone_times_ahead`'s; a stretch not ended
    within the batch is taken as read. ``t`` in µs, ``valid`` where known.

    >>> t = np.array([0, 20, 40, 9_000_000, 9_000_020, 60, 80]) * 1000
    >>> (stretches_ahead(t, np.ones(7, bool), 200_000) > 0).nonzero()[0].tolist()
    [3, 4]
    >>> late = np.array([0, 20, 40, 500, 3_000, 5_000, 60, 80]) * 1000  # ahead too long
    >>> bool(stretches_ahead(late, np.ones(8, bool), 200_000).any())
    False
    """
    lead = np.zeros(t.size, np.int64)
    known = np.flatnonzero(valid)
    times = t[known]
    backs = np.flatnonzero(times[1:] < times[:-1] - tolerance) + 1  # rows stepping back
    for r in backs[:_MAX_STRETCH_ENDS].tolist():  # a few per batch (rows in no order: many)
        before = np.flatnonzero(times[:r] <= times[r] + tolerance)
        if not before.size:  # the batch begins ahead: no timeline before to go on
            continue
        k = int(before[-1])  # the last row before the stretch: k + 1 .. r - 1 run ahead
        first, last = times[k + 1], times[r - 1]
        jump = int(first - times[k])
        if times[r] < times[k] - tolerance or jump <= tolerance or last - first >= jump:
            continue
        rows = known[k + 1 : r]
        if not lead[rows].any():
            lead[rows] = jump
    return lead


def _size(seconds: float) -> str:
    return f"{seconds:.1f}" if seconds >= 1 else f"{seconds:.3f}"


def steps_note(steps: list[tuple[int, float]], where: str) -> str:
    """The file's note on the clock steps back of a reading (``ClockState.steps``)."""
    shown = ", ".join(f"{_size(seconds)} s at {where} {line}" for line, seconds in steps[:5])
    more = f" and {len(steps) - 5} more" if len(steps) > 5 else ""
    return (
        f"the logger clock stepped back {len(steps)} time(s) ({shown}{more}): the rows "
        "until its time passed the latest already read are quarantined or counted as exact "
        "duplicates, not merged"
    )


def clock_steps(
    time_utc: pl.Series,
    rows: np.ndarray,
    state: ClockState,
    tolerance: int,
    where: str = "line",
) -> pl.Series | None:
    """The clock-step reason of each row, or a lone corrupted time's
    (:func:`lone_times_ahead`; null where none), None when no row has one.

    ``time_utc``: the rows' times in file order (null where unknown: such a row does
    not move the clock); ``rows``: their line (CSV) or sample index (TDMS), named in
    the reason as ``where``; ``state`` is read and advanced; ``tolerance`` in µs.
    """
    n = len(time_utc)
    if n == 0:
        return None
    valid = time_utc.is_not_null().to_numpy()
    t = time_utc.dt.epoch("us").fill_null(_LOW).to_numpy().astype(np.int64, copy=False)
    t = np.where(valid, t, _LOW)
    ahead = lone_times_ahead(t, valid, tolerance)
    lead = np.zeros(n, np.int64)
    if ahead.any():  # corrupted times: quarantined alone, they move no clock
        lead[ahead] = t[ahead] - t[np.flatnonzero(ahead) - 1]
        valid = valid & ~ahead
        t = np.where(ahead, _LOW, t)
    stretch = stretches_ahead(t, valid, tolerance)
    if stretch.any():  # a short stretch of them: likewise
        lead = np.where(stretch > 0, stretch, lead)
        ahead = ahead | (stretch > 0)
        valid = valid & ~ahead
        t = np.where(ahead, _LOW, t)
    if ahead.any():
        lone = [time_ahead_reason(int(lead[k]) / 1e6) for k in np.flatnonzero(ahead)]
    seed = _LOW if state.latest_us is None else state.latest_us
    running = np.maximum.accumulate(np.concatenate(([seed], t)))
    before = running[:-1]  # the latest time read before each row
    if running[-1] != _LOW:
        latest_end = int(running[-1])
    else:
        latest_end = None
    known = valid & (before != _LOW)
    onset_candidate = np.zeros(n, np.bool_)
    onset_candidate[known] = t[known] < before[known] - tolerance
    carried = state.step_line is not None
    if not carried and not onset_candidate.any():  # the common case: nothing stepped back
        state.latest_us = latest_end
        if not ahead.any():
            return None
        reasons = np.full(n, None, dtype=object)
        reasons[ahead] = np.array(lone, dtype=object)
        return pl.Series("clock_reason", reasons.tolist(), dtype=pl.String)
    # A plateau: rows with the same latest time before them. A step lasts from its
    # onset to the end of its plateau (the first row past that time starts the next).
    index = np.arange(n)
    new_plateau = np.ones(n, np.bool_)
    new_plateau[1:] = before[1:] != before[:-1]
    plateau_start = np.maximum.accumulate(np.where(new_plateau, index, 0))
    first_plateau = plateau_start == 0
    if carried:  # the first plateau is inside the carried step: no new onset there
        onset_candidate &= ~first_plateau
    count = np.cumsum(onset_candidate)
    in_plateau = count - (count - onset_candidate)[plateau_start]
    started = in_plateau > 0
    if carried:
        started |= first_plateau
    stepped = valid & started & (t <= before)
    onset = onset_candidate & (in_plateau == 1)
    onset_at = np.maximum.accumulate(np.where(onset, index, -1))
    names: dict[int, str] = {}  # onset row (-1: the carried step) -> its reason
    if carried and state.step_line is not None and state.step_s is not None:
        names[-1] = clock_step_reason(where, state.step_line, state.step_s)
    for k in np.flatnonzero(onset):
        seconds = (int(before[k]) - int(t[k])) / 1e6
        state.steps.append((int(rows[k]), seconds))
        names[int(k)] = clock_step_reason(where, int(rows[k]), seconds)
    step_of = np.where(first_plateau, -1, onset_at) if carried else onset_at
    keys, inverse = np.unique(step_of[stepped], return_inverse=True)
    reasons = np.full(n, None, dtype=object)
    reasons[stepped] = np.array([names[int(k)] for k in keys], dtype=object)[inverse]
    # where the rows read end: inside a step unless the last row passed its time
    last = n - 1
    ended = bool(valid[last] and t[last] > before[last])
    if started[last] and not ended:
        if not (carried and first_plateau[last]):
            k = int(onset_at[last])
            state.step_line, state.step_s = int(rows[k]), (int(before[k]) - int(t[k])) / 1e6
    else:
        state.step_line = state.step_s = None
    state.latest_us = latest_end
    if ahead.any():
        reasons[ahead] = np.array(lone, dtype=object)
    if not (stepped.any() or ahead.any()):
        return None
    return pl.Series("clock_reason", reasons.tolist(), dtype=pl.String)
