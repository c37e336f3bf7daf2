"""The trip rule: phase, direction and trip of each sample, and the shaft position.

Not an equation of the paper; the rule every step that speaks of trips uses (the
compensation's labels, the reconciliation's stints, :func:`transforms.kinematics.with_trip_phases`,
the replay's trips in :mod:`discovery.segmentation`, so ``sanity_checks.trip_id`` names
the trip ``trip_summary.trip_id`` does).

Functions
    :func:`trip_label_codes` -- phase, direction and trip id per sample as integer codes,
    resumable block by block (numba kernel).
    :func:`position_codes` -- the nearest named shaft position within the window.
    :func:`trip_label_columns` -- both as the string / Int64 columns of the tables.
    :func:`segment_ids` -- the logger's gap-free segments (a new segment after each gap),
    the rule's ``segment`` input.

Rules, first match wins (|v| the speed, a_t = a sgn(v) the tangential acceleration):

==============  ===================================================================
standstill      |v| < ``standstill_speed_m_s`` (default :data:`STANDSTILL_SPEED_M_S`)
accelerate      a_t >  ``acceleration_fraction`` (0.3) x the winder's acceleration
decelerate      a_t < -``acceleration_fraction`` x the winder's deceleration
creep           |v| <= ``creep_factor`` (1.5) x the winder's creep speed
run             otherwise
==============  ===================================================================

``direction`` is down for speed > 0 and up for speed < 0 (none at standstill). A trip is
a maximal run of non-standstill samples, numbered from 0 in time order (a direction
reversal without a stop stays one trip). A logger gap (a new segment) inside a motion
continues the trip when the motion has the same direction on both sides and the gap is
at most :data:`TRIP_BRIDGE_S`, or the depth advanced across it, in that direction, at a
mean speed between :data:`TRIP_BRIDGE_SPEED_FRACTION` x the slower speed and the faster
speed / that fraction; otherwise the motion after the gap is a new trip.
"""

from __future__ import annotations

import numpy as np
import polars as pl
from numba import njit

from schemas.hoist import HoistDescription

__all__ = [
    "DIRECTIONS",
    "LABEL_STATE_SIZE",
    "PHASES",
    "RATE_RATIO",
    "RATE_RUN",
    "STANDSTILL_SPEED_M_S",
    "TRIP_BRIDGE_S",
    "TRIP_BRIDGE_SPEED_FRACTION",
    "named_codes",
    "ordered_positions",
    "position_codes",
    "segment_ids",
    "trip_label_codes",
    "trip_label_columns",
]

#: Trip phase labels; a phase code is an index into it.
PHASES = ("accelerate", "run", "decelerate", "creep", "standstill")
#: Below this |speed| the conveyance stands still [m/s] (the phase ``standstill``).
STANDSTILL_SPEED_M_S = 0.02
#: Direction labels; a direction code is an index into it.
DIRECTIONS = ("down", "up")
#: A logger gap of at most this many seconds inside a motion does not end the trip [s] ...
TRIP_BRIDGE_S = 2.0
#: ... as does a longer gap over which the depth advanced, in the direction of motion,
#: at a mean speed between this fraction of the slower speed either side of it and the
#: faster speed over this fraction: the conveyance kept moving, so no stop (and no
#: unseen round trip) can have hidden in the gap.
TRIP_BRIDGE_SPEED_FRACTION = 0.5
#: Length of :func:`trip_label_codes`' state.
LABEL_STATE_SIZE = 7

_ACCELERATE, _RUN, _DECELERATE, _CREEP, _STANDSTILL = (
    PHASES.index(name) for name in ("accelerate", "run", "decelerate", "creep", "standstill")
)


def trip_label_codes(
    time_s: np.ndarray,
    speed: np.ndarray,
    accel: np.ndarray,
    segment: np.ndarray,
    depth: np.ndarray,
    hoist: HoistDescription,
    *,
    standstill_speed_m_s: float = STANDSTILL_SPEED_M_S,
    acceleration_fraction: float = 0.3,
    creep_factor: float = 1.5,
    state: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integer codes of the module's rule: phase (index in :data:`PHASES`), direction
    (index in :data:`DIRECTIONS`, -1 at standstill) and trip id (-1 at standstill).

    ``time_s`` [s], ``speed`` [m/s] positive down (no NaN: fill before), ``accel``
    [m/s2] in the speed's sense, ``segment`` the logger's gap-free segment ids, ``depth``
    [m] (NaN where unknown: a longer gap then ends the trip). ``state``: carried from the
    previous block (:data:`LABEL_STATE_SIZE`; None for the record's first).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> t = np.arange(6.0)
    >>> v = np.array([0.0, 1.0, 1.0, 0.0, -1.0, 0.0])
    >>> phase, direction, trip = trip_label_codes(t, v, np.zeros(6), np.zeros(6, np.int64),
    ...                                           np.zeros(6), load_hoist(EXAMPLE_HOIST))
    >>> trip.tolist(), direction.tolist()
    ([-1, 0, 0, -1, 1, -1], [-1, 0, 0, -1, 1, -1])
    """
    winder = hoist.winder
    phase = np.empty(speed.size, dtype=np.int8)
    direction = np.empty(speed.size, dtype=np.int8)
    trip_id = np.empty(speed.size, dtype=np.int64)
    _label_kernel(
        np.ascontiguousarray(time_s, dtype=np.float64),
        np.ascontiguousarray(speed, dtype=np.float64),
        np.ascontiguousarray(accel, dtype=np.float64),
        np.ascontiguousarray(segment, dtype=np.int64),
        np.ascontiguousarray(depth, dtype=np.float64),
        TRIP_BRIDGE_S,
        TRIP_BRIDGE_SPEED_FRACTION,
        standstill_speed_m_s,
        creep_factor * winder.creep_speed_m_s,
        -acceleration_fraction * winder.deceleration_m_s2,
        acceleration_fraction * winder.acceleration_m_s2,
        phase,
        direction,
        trip_id,
        np.zeros(LABEL_STATE_SIZE) if state is None else state,
    )
    return phase, direction, trip_id


@njit(cache=True, nogil=True)
def _label_kernel(
    time_s,
    speed,
    accel,
    segment,
    depth,
    bridge_s,
    bridge_fraction,
    standstill,
    creep,
    decelerating,
    accelerating,
    phase,
    direction,
    trip_id,
    state,
):  # pragma: no cover - numba
    """The rules of :func:`trip_label_codes` (later rules override earlier ones), one pass.

    ``state`` = [ran, continues segment, last trip id, was moving, last speed, time,
    depth] (:data:`LABEL_STATE_SIZE`; all 0 before the first call).
    """
    ran = state[0] != 0.0
    resume = ran and state[1] != 0.0
    trips = int(state[2]) if ran else -1
    was_moving = ran and state[3] != 0.0
    for i in range(speed.shape[0]):
        v = speed[i]
        abs_v = abs(v)
        a_t = accel[i] * np.sign(v)
        moving = abs_v >= standstill
        code = _RUN
        if abs_v <= creep:
            code = _CREEP
        if a_t < decelerating:
            code = _DECELERATE
        if a_t > accelerating:
            code = _ACCELERATE
        if not moving:
            code = _STANDSTILL
        phase[i] = code
        direction[i] = -1
        if moving and v > 0:
            direction[i] = 0
        elif moving and v < 0:
            direction[i] = 1
        new_segment = not resume if i == 0 else segment[i] != segment[i - 1]
        if moving and ((i == 0 and not ran) or not was_moving):
            trips += 1
        elif moving and new_segment:
            # a logger gap inside a motion: the same trip if it kept moving the same way
            v_before = speed[i - 1] if i > 0 else state[4]
            gap = time_s[i] - (time_s[i - 1] if i > 0 else state[5])
            advance = (depth[i] - (depth[i - 1] if i > 0 else state[6])) * np.sign(v)
            slower = min(abs_v, abs(v_before))
            faster = max(abs_v, abs(v_before))
            kept_moving = (
                advance >= bridge_fraction * slower * gap
                and advance <= faster / bridge_fraction * gap
            )
            if not (np.sign(v) == np.sign(v_before) and (gap <= bridge_s or kept_moving)):
                trips += 1
        trip_id[i] = trips if moving else -1
        was_moving = moving
    n = speed.shape[0]
    if n:
        state[0] = 1.0
        state[2] = trips
        state[3] = 1.0 if was_moving else 0.0
        state[4], state[5], state[6] = speed[n - 1], time_s[n - 1], depth[n - 1]


#: Length of :func:`_label_kernel`'s state.


def ordered_positions(hoist: HoistDescription) -> list[tuple[str, float]]:
    """The hoist's named shaft positions (name, depth [m]) by depth."""
    return sorted(hoist.shaft.positions_m.items(), key=lambda item: item[1])


@njit(cache=True, nogil=True)
def _position_kernel(depth, positions, window, position):  # pragma: no cover - numba
    for i in range(depth.shape[0]):
        position[i] = -1
        if positions.shape[0] and not np.isnan(depth[i]):
            best = abs(depth[i] - positions[0])
            for k in range(1, positions.shape[0]):
                best = min(best, abs(depth[i] - positions[k]))
            for k in range(positions.shape[0]):
                dist = abs(depth[i] - positions[k])
                if dist == best and dist <= window:
                    position[i] = k


def position_codes(depth: np.ndarray, hoist: HoistDescription) -> np.ndarray:
    """Index in :func:`ordered_positions` of the nearest named position within the hoist's
    ``position_window`` of ``depth`` [m]; -1 elsewhere (and where depth is NaN).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> position_codes(np.array([1.0, 100.0, 318.0, 604.0]), load_hoist(EXAMPLE_HOIST)).tolist()
    [0, -1, 1, 2]
    """
    position = np.empty(np.size(depth), dtype=np.int8)
    _position_kernel(
        np.ascontiguousarray(depth, dtype=np.float64),
        np.array([d for _, d in ordered_positions(hoist)], dtype=np.float64),
        float(hoist.shaft.position_window_m),
        position,
    )
    return position


def named_codes(name: str, codes: np.ndarray, names: list[str] | tuple[str, ...]) -> pl.Series:
    """Integer codes as a String column of their names (-1: null).

    >>> named_codes("direction", np.array([0, -1, 1], dtype=np.int8), DIRECTIONS).to_list()
    ['down', None, 'up']
    """
    if codes.size == 0:
        return pl.Series(name, [], dtype=pl.String)
    if not names:
        return pl.Series(name, [None], dtype=pl.String).extend_constant(None, codes.size - 1)
    index = pl.Series(codes).cast(pl.UInt32, strict=False)  # -1 becomes a null index
    return pl.Series(name, list(names), dtype=pl.String).gather(index)


def trip_label_columns(
    time_s: np.ndarray,
    speed: np.ndarray,
    depth: np.ndarray,
    accel: np.ndarray,
    segment: np.ndarray,
    hoist: HoistDescription,
    state: np.ndarray | None = None,
) -> dict[str, pl.Series]:
    """``trip_id`` (Int64), ``phase``, ``direction`` and ``position`` (String) columns of
    :func:`trip_label_codes` and :func:`position_codes` (nulls where the code is -1)."""
    codes, direction, trip_id = trip_label_codes(
        time_s, speed, accel, segment, depth, hoist, state=state
    )
    position = position_codes(depth, hoist)
    names = [name for name, _ in ordered_positions(hoist)]
    return {
        "trip_id": pl.Series("trip_id", trip_id, dtype=pl.Int64).set(pl.Series(trip_id < 0), None),
        "phase": named_codes("phase", codes, list(PHASES)),
        "direction": named_codes("direction", direction, list(DIRECTIONS)),
        "position": named_codes("position", position, names),
    }


def segment_ids(
    t_s: np.ndarray,
    *,
    gap_factor: float = 3.0,
    nominal_dt_s: float | None = None,
    rate_changes: bool = True,
) -> np.ndarray:
    """Number contiguous segments: a new segment starts after each gap and where the
    logger's rate changes.

    A gap is a spacing above ``gap_factor`` times the spacing of the logger's rate at
    that point. That rate starts as ``nominal_dt_s``; where :data:`RATE_RUN` consecutive
    spacings agree with their mean within a factor :data:`RATE_RATIO` and that mean is
    off the current rate's spacing by more than that factor (a logger switched from
    50 Hz to 100 Hz, or to 10 Hz, mid-file), the rate changes to that mean and a new
    segment starts: each segment is rate-homogeneous, so a filter or a derivative of a
    segment can take one spacing (:func:`physics.conveyance.smoothed_derivative`), and
    the steps of a slower rate are not each taken for a gap. At a record's first sample
    the rate is adopted without a new segment. A constant-rate record (jitter, isolated
    dropouts) never changes rate: its segments are the gaps' alone.

    Parameters
    ----------
    t_s : numpy.ndarray
        Sample times [s], increasing.
    gap_factor : float
        A spacing above ``gap_factor * nominal_dt_s`` is a gap [-].
    nominal_dt_s : float, optional
        Nominal sample spacing [s]; default the median spacing.
    rate_changes : bool
        Whether a change of the logger's rate starts a segment (and sets the spacing
        gaps are measured in); False: every spacing above ``gap_factor *
        nominal_dt_s`` is a gap, whatever the rate (a bridge of so many seconds).

    Returns
    -------
    numpy.ndarray
        int64 segment id per sample, starting at 0.

    >>> segment_ids(np.array([0.0, 0.01, 0.02, 0.5, 0.51])).tolist()
    [0, 0, 0, 1, 1]
    >>> t = np.r_[np.arange(0.0, 0.2, 0.02), 0.2 + np.arange(0.0, 2.0, 0.1)]  # 50 -> 10 Hz
    >>> np.unique(segment_ids(t, nominal_dt_s=0.02), return_counts=True)[1].tolist()
    [11, 19]
    """
    t = np.ascontiguousarray(t_s, dtype=np.float64)
    if t.size < 2:
        return np.zeros(t.size, dtype=np.int64)
    nominal = float(np.median(np.diff(t))) if nominal_dt_s is None else nominal_dt_s
    out = np.empty(t.size, dtype=np.int64)
    _segment_kernel(t, gap_factor, nominal, RATE_RATIO, RATE_RUN if rate_changes else 0, out)
    return out


#: A logger's rate changes where :data:`RATE_RUN` consecutive spacings agree with their
#: mean within this factor and the mean is off the current rate's spacing by more [-] ...
RATE_RATIO = 1.5
#: ... over this many spacings (:func:`segment_ids`).
RATE_RUN = 10


@njit(cache=True, nogil=True)
def _segment_kernel(t, gap_factor, nominal, ratio, run, out):  # pragma: no cover - numba
    """out[i] = number of segment starts at samples j <= i: a step t[j] - t[j-1] above
    ``gap_factor`` x the current spacing h (a gap), or a change of h (a rate change,
    :func:`segment_ids`); a rate change right after a gap does not start another one.
    ``run`` 0: no rate changes."""
    count = 0
    out[0] = 0
    h = nominal
    n = t.shape[0]
    started = True  # a segment started at the previous sample
    for i in range(1, n):
        d = t[i] - t[i - 1]
        changed = False
        if run and (d > ratio * h or d * ratio < h) and i + run <= n:
            mean = (t[i + run - 1] - t[i - 1]) / run
            if mean > ratio * h or mean * ratio < h:
                agree = True
                for j in range(i, i + run):
                    step = t[j] - t[j - 1]
                    if step > ratio * mean or step * ratio < mean:
                        agree = False
                        break
                if agree:
                    h = mean
                    changed = True
        start = d > gap_factor * h or (changed and not started)
        if start:
            count += 1
        started = start
        out[i] = count
