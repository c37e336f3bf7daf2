"""The load's continuity from a trip to its stop (transforms/stop_continuity.py).

Small records made here with analytic answers: a steady run whose load is known, a stop
whose solved friction is off by a known amount; the update must make the load at rest
the run's plus the tail ropes' change (paper eq 3-4), share it by the ropes' stiffness,
hold it while the seals stick, let it go as a piston slides or the payload changes, and
give the same in two parts as in one.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from physics.tension import tail_rope_mass_kg
from physics.trip_rule import PHASES
from schemas.hoist import EXAMPLE_HOIST, G_STANDARD, load_hoist
from transforms.compensation_record import CompensationSettings, compensation_margins_s
from transforms.stop_continuity import (
    PAYLOAD_SHARE,
    SETTLE_S,
    SPAN_S,
    ContinuityInputs,
    apply_stop_continuity,
    continuity_state,
    rest_window,
)

HOIST = load_hoist(EXAMPLE_HOIST)
RATE = 50.0
STILL, RUN, ACCEL, DECEL = (
    PHASES.index(p) for p in ("standstill", "run", "accelerate", "decelerate")
)
FRACTIONS = np.array([0.24, 0.25, 0.25, 0.26])


def _trip(
    run_s: float = 20.0,
    rest_s: float = 40.0,
    run_depth: tuple[float, float] = (400.0, 100.0),
    stop_depth: float = 0.0,
) -> dict[str, np.ndarray]:
    """A stop, a trip up (accelerate 2 s, run, decelerate 2 s) and a stop at the pithead;
    the sensors' load in the run 150 kN, at rest the run's plus the tail ropes' change
    as read by the sensors with the seals' 500 N, which the solution takes 900 N too
    high from the stop's first sample on."""
    parts = [(STILL, 5.0), (ACCEL, 2.0), (RUN, run_s), (DECEL, 2.0), (STILL, rest_s)]
    phase = np.concatenate([np.full(int(s * RATE), p, dtype=np.int8) for p, s in parts])
    n = phase.size
    t = np.arange(n) / RATE
    depth = np.full(n, run_depth[0])
    run = phase == RUN
    depth[run] = np.linspace(*run_depth, run.sum())
    after = np.flatnonzero(run)[-1] + 1
    depth[after:] = stop_depth
    arrival = n - int(rest_s * RATE)  # the stop's first sample
    run_mid = float(np.mean(depth[run]))
    tail_kg = tail_rope_mass_kg(HOIST, stop_depth) - tail_rope_mass_kg(HOIST, run_mid)
    tail_n = G_STANDARD * float(tail_kg)
    # the true seals hold 500 N summed in the run and at rest; the sensors read the rest
    p_load = np.full(n, 150e3)
    p_load[after:] = 150e3 + tail_n
    friction = [np.full(n, 50.0 * (i + 1)) for i in range(4)]  # the run's: 500 N summed
    for i, f in enumerate(friction):  # solved 900 N too high summed at rest
        f[arrival:] = 50.0 * (i + 1) + 900.0 * FRACTIONS[i] + 225.0 * (1 if i % 2 else -1)
    x = tuple(np.zeros(n) for _ in range(4))
    return {"t": t, "phase": phase, "depth": depth, "p": p_load, "f": friction, "x": x,
            "tail": tail_n, "arrival": arrival}  # fmt: skip


def _inputs(case: dict, presliding_m: float = 50e-6) -> ContinuityInputs:
    return ContinuityInputs(
        case["t"], case["phase"], case["depth"], case["p"], case["x"], FRACTIONS,
        presliding_m, 1.0 / RATE,
    )  # fmt: skip


def _run(case: dict, frictions: list, parts: tuple[int, ...] = ()) -> np.ndarray:
    state = continuity_state(len(frictions))
    edges = [0, *parts, case["t"].size]
    for lo, hi in itertools.pairwise(edges):
        apply_stop_continuity(_inputs(case), frictions, lo, hi, state, HOIST)
    return state


def _load(case: dict, friction: tuple[np.ndarray, ...]) -> np.ndarray:
    return case["p"] + sum(friction)


def test_the_stop_takes_the_runs_load_plus_the_tail_ropes() -> None:
    case = _trip()
    estimate = tuple(f.copy() for f in case["f"])
    _run(case, [estimate])
    arrival = case["arrival"]
    run_load = 150e3 + 500.0
    # the seals were solved 900 N too high summed: the update takes it out at rest
    np.testing.assert_allclose(_load(case, estimate)[arrival:], run_load + case["tail"], atol=1e-6)
    # shared by the ropes' stiffness: each seal moved by its fraction of the shift
    for i, f in enumerate(estimate):
        np.testing.assert_allclose(f[arrival:] - case["f"][i][arrival:], -900.0 * FRACTIONS[i])
    # nothing before the arrival moves
    for f, before in zip(estimate, case["f"], strict=True):
        np.testing.assert_array_equal(f[:arrival], before[:arrival])


def test_each_member_continues_its_own_run() -> None:
    """A band member whose seals hold 300 N more in the run and 100 N more at rest ends
    300 N above the estimate at rest: the band there is the runs' spread."""
    case = _trip()
    estimate = tuple(f.copy() for f in case["f"])
    member = tuple(f + 75.0 for f in case["f"])
    for f in member:
        f[case["arrival"] :] -= 50.0
    _run(case, [estimate, member])
    at_rest = slice(case["arrival"], None)
    np.testing.assert_allclose((_load(case, member) - _load(case, estimate))[at_rest], 300.0)


def test_a_sliding_piston_lets_its_share_go_and_a_payload_change_ends_it() -> None:
    case = _trip(rest_s=60.0)
    arrival = case["arrival"]
    t = case["t"]
    # piston 2 slides 0.2 mm from 20 s after the arrival, over 2 s: past its presliding
    moving = (t >= t[arrival] + 20.0) & (t < t[arrival] + 22.0)
    x2 = np.cumsum(np.where(moving, 0.2e-3 / moving.sum(), 0.0))
    case["x"] = (case["x"][0], x2, case["x"][2], case["x"][3])
    # a payload change at rest 40 s after the arrival: the load drops 5 %
    change = t >= t[arrival] + 40.0
    case["p"] = np.where(change, case["p"] * 0.95, case["p"])
    estimate = tuple(f.copy() for f in case["f"])
    _run(case, [estimate])
    shift = [f - before for f, before in zip(estimate, case["f"], strict=True)]
    early = arrival + int(10 * RATE)
    assert shift[1][early] == pytest.approx(-900.0 * FRACTIONS[1])
    slid = int(np.flatnonzero(t >= t[arrival] + 23.0)[0])
    assert shift[1][slid] == 0.0  # slid 0.2 mm > 0.05 mm: its seal holds the law's force
    assert shift[0][slid] == pytest.approx(-900.0 * FRACTIONS[0])  # still sticking
    # half way through sliding its presliding range: half its share
    half = int(np.flatnonzero(x2 >= 25e-6)[0])
    assert shift[1][half] == pytest.approx(-900.0 * FRACTIONS[1] / 2, rel=0.05)
    # the payload change (its 2 s centred mean leaves by 0.5 %) ends every share
    ended = int(np.flatnonzero(change)[0])
    assert all(s[ended:].max() == 0.0 and s[ended:].min() == 0.0 for s in shift)
    assert shift[0][ended - int(1.5 * RATE)] != 0.0


def test_a_short_trip_predicts_nothing() -> None:
    case = _trip(run_s=1.0)  # under MIN_RUN_S of steady run
    estimate = tuple(f.copy() for f in case["f"])
    _run(case, [estimate])
    for f, before in zip(estimate, case["f"], strict=True):
        np.testing.assert_array_equal(f, before)


@pytest.mark.parametrize("split_s", [10.0, 28.5, 30.0, 33.0, 45.0])
def test_two_parts_give_what_one_gives(split_s: float) -> None:
    """Split in the run, at the arrival, inside the rest window and after it."""
    case = _trip()
    case["x"] = tuple(1e-6 * np.sin(case["t"] * (i + 1)) for i in range(4))
    whole = [tuple(f.copy() for f in case["f"]), tuple(f + 40.0 for f in case["f"])]
    parts = [tuple(f.copy() for f in case["f"]), tuple(f + 40.0 for f in case["f"])]
    _run(case, whole)
    _run(case, parts, (int(split_s * RATE),))
    for w, p in zip(whole, parts, strict=True):
        for fw, fp in zip(w, p, strict=True):
            # the run's sums in two parts: equal to the rounding of a sum's order
            np.testing.assert_allclose(fw, fp, rtol=1e-12, atol=1e-9)


def test_the_rest_window_ends_before_a_payload_change_and_at_a_departure() -> None:
    t = np.arange(0.0, 30.0, 1.0 / RATE)
    phase = np.full(t.size, STILL, dtype=np.int8)
    load = np.full(t.size, 1e5)
    window = rest_window(t, phase, load, 0)
    assert (t[window.start], t[window.stop - 1]) == pytest.approx((2.0, 11.98))
    ramp = np.where(t > 8.0, 1e5 - 2e4 * (t - 8.0), 1e5)  # unloading from 8 s
    window = rest_window(t, phase, ramp, 0)
    # the 2 s centred mean leaves by PAYLOAD_SHARE before the ramp has gone that far
    assert t[window.stop - 1] < 8.0
    assert t[window.stop - 1] > 8.0 - 1.0
    departing = np.where(t >= 6.0, RUN, STILL).astype(np.int8)
    window = rest_window(t, departing, load, 0)
    assert t[window.stop - 1] < 6.0
    assert PAYLOAD_SHARE * 1e5 < 2e4  # the ramp's first second exceeds it


def test_the_rest_windows_look_ahead_fits_in_the_blocks_halo() -> None:
    """The look-ahead is past the resume margin (module docstring): a block solves the
    stick-slip solution that far past its first stage, inside the halo it reads."""
    resume_s, halo_s = compensation_margins_s(CompensationSettings())
    assert SETTLE_S + SPAN_S > resume_s
    assert resume_s + SETTLE_S + SPAN_S < halo_s
