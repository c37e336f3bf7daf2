"""Tests for physics.trip_rule: trips, phases and positions on a hand-made record."""

from __future__ import annotations

import numpy as np

from physics.trip_rule import PHASES, position_codes, trip_label_codes
from schemas.hoist import EXAMPLE_HOIST, load_hoist

HOIST = load_hoist(EXAMPLE_HOIST)


def _record(gap_after_s: float | None = None, gap_s: float = 0.0, rate_hz: float = 10.0):
    """Down 0 -> 300 m at 10 m/s (1 m/s2), 20 s at rest, up again; optional logger gap."""
    t = np.arange(0.0, 100.0, 1.0 / rate_hz)
    v = np.interp(t, [0, 5, 15, 35, 45, 50, 60, 80, 90, 100], [0, 0, 10, 10, 0, 0, -10, -10, 0, 0])
    a = np.gradient(v, t)
    depth = np.cumsum(v) / rate_hz
    segment = np.zeros(t.size, dtype=np.int64)
    if gap_after_s is not None:
        keep = (t < gap_after_s) | (t >= gap_after_s + gap_s)
        segment = np.cumsum(~keep)[keep]
        t, v, a, depth = t[keep], v[keep], a[keep], depth[keep]
    return t, v, a, segment, depth


def test_two_trips_their_directions_and_phases():
    t, v, a, segment, depth = _record()
    phase, direction, trip = trip_label_codes(t, v, a, segment, depth, HOIST)
    assert sorted(set(trip.tolist())) == [-1, 0, 1]
    assert set(direction[trip == 0].tolist()) == {0}  # down
    assert set(direction[trip == 1].tolist()) == {1}  # up
    assert np.all(trip[np.abs(v) < 0.02] == -1)
    names = [PHASES[c] for c in phase]
    assert names[int(10.0 * 10)] == "accelerate"  # 10 s: 1 m/s2 against a 0.3 x threshold
    assert names[int(25.0 * 10)] == "run"
    assert names[int(40.0 * 10)] == "decelerate"
    assert names[int(47.0 * 10)] == "standstill"


def test_a_short_gap_inside_a_motion_continues_the_trip_a_long_one_does_not_unless_it_moved():
    t, v, a, segment, depth = _record(gap_after_s=25.0, gap_s=1.0)
    assert sorted(set(trip_label_codes(t, v, a, segment, depth, HOIST)[2].tolist())) == [-1, 0, 1]
    # 5 s missing mid-run: bridged because the depth advanced at the running speed
    t, v, a, segment, depth = _record(gap_after_s=25.0, gap_s=5.0)
    assert sorted(set(trip_label_codes(t, v, a, segment, depth, HOIST)[2].tolist())) == [-1, 0, 1]
    # the same gap with the depth unknown: a new trip after it
    trips = trip_label_codes(t, v, a, segment, np.full(t.size, np.nan), HOIST)[2]
    assert sorted(set(trips.tolist())) == [-1, 0, 1, 2]


def test_resumed_in_blocks_equals_one_pass():
    t, v, a, segment, depth = _record()
    whole = trip_label_codes(t, v, a, segment, depth, HOIST)
    state = np.zeros(7)
    cut = 333  # inside the first trip
    first = trip_label_codes(t[:cut], v[:cut], a[:cut], segment[:cut], depth[:cut], HOIST,
                             state=state)  # fmt: skip
    state[1] = 1.0  # the block continues the segment
    second = trip_label_codes(t[cut:], v[cut:], a[cut:], segment[cut:], depth[cut:], HOIST,
                              state=state)  # fmt: skip
    for w, f, s in zip(whole, first, second, strict=True):
        assert np.array_equal(w, np.concatenate([f, s]))


def test_positions_within_the_window_nearest_wins():
    positions = HOIST.shaft.positions_m
    window = HOIST.shaft.position_window_m
    depth = np.array(
        [positions["middle"] + 0.9 * window, positions["middle"] + 1.1 * window, np.nan]
    )
    assert position_codes(depth, HOIST).tolist() == [1, -1, -1]
