"""Sharing the oil's common motion among the pistons (transforms.piston_motion), issue 13.

Cases with analytic answers: the sum of the increments is the oil's (conservation), a
payload change at rest that one piston takes while three stick gives the three no motion
at all (no reversal, which would flip their friction), an oscillation inside the seals'
presliding range is shared equally, and with nothing seen moving the split is equal.
"""

from __future__ import annotations

import numpy as np
import pytest

from transforms.piston_motion import share_out_common_motion


def _smooth_step(n: int, at: int, width: int, height: float) -> np.ndarray:
    """A monotone ramp of ``height`` over ``width`` samples centred on ``at``."""
    t = np.arange(n, dtype=float)
    return height * np.clip((t - at + width / 2) / width, 0.0, 1.0)


def test_one_piston_slides_three_stick_through_a_payload_change_at_rest():
    n = 2000
    # the oil: the sum of the displacements steps by 1.8 mm within 0.2 s (10 samples)
    total = _smooth_step(n, 1000, 10, 1.8e-3)
    common = total / 4
    # the logged record, smoothed: piston 1's step spread over +-5 s, the others still
    logged = (_smooth_step(n, 1000, 500, 1.8e-3), np.zeros(n), np.zeros(n), np.zeros(n))
    x, _ = share_out_common_motion(common, logged, np.zeros(n, dtype=np.int64))
    # conservation: the increments add up to the oil's at every sample
    np.testing.assert_allclose(sum(x), total, atol=1e-12)
    # the three sticking pistons get under a micrometre (the weights' floor), against
    # the 0.45 mm each of an equal split
    for k in (1, 2, 3):
        assert np.max(np.abs(x[k])) < 1e-6
    # piston 1 takes the step when the oil moves, not before (monotone, no lead)
    assert np.all(np.diff(x[0]) >= -1e-15)
    assert x[0][990] == pytest.approx(0.0, abs=1e-6)
    assert x[0][-1] == pytest.approx(1.8e-3, rel=1e-6)


def test_the_first_wave_split_would_reverse_the_sticking_pistons():
    """The estimate this replaces (equal split of the sum + smoothed difference) moves a
    sticking piston out and back: the failure the issue measured."""
    n = 2000
    total = _smooth_step(n, 1000, 10, 1.8e-3)
    smooth1 = _smooth_step(n, 1000, 500, 1.8e-3)
    mean_logged = smooth1 / 4
    piston2 = total / 4 + (0.0 - mean_logged)  # common + differential of a still piston
    assert piston2.max() > 0.2e-3  # it appears to go out > 0.2 mm and come back
    assert piston2[-1] == pytest.approx(0.0, abs=1e-12)


def test_an_oscillation_inside_the_presliding_range_is_shared_equally():
    n = 3000
    t = np.arange(n) / 50.0
    total = 0.1e-3 * np.sin(2 * np.pi * 1.0 * t) * np.exp(-t / 20.0)  # ringing of the sum
    logged = (_smooth_step(n, 1500, 500, 1e-3), np.zeros(n), np.zeros(n), np.zeros(n))
    x, _ = share_out_common_motion(
        total / 4, logged, np.zeros(n, dtype=np.int64), elastic_half_width_m=0.2e-3
    )
    # the elastic part goes a quarter to each piston (to two micrometres of a 1 mm drift: the
    # weights' floor leaks a little); piston 1's logged drift is not the oil's (the sum
    # did not move), so the oil overrules it
    assert np.std(total / 4) > 5e-6
    for k in range(4):
        np.testing.assert_allclose(x[k], total / 4, atol=2e-6)


def test_nothing_seen_moving_splits_the_sum_equally_and_gaps_restart():
    n = 400
    total = np.linspace(0.0, 1e-3, n)
    segment = np.repeat([0, 1], n // 2)
    still = np.full(n, 2e-3)
    x, _ = share_out_common_motion(total / 4, (still, still, still, still), segment)
    first, second = slice(0, n // 2), slice(n // 2, n)
    for k in range(4):
        np.testing.assert_allclose(x[k][first] - 2e-3, (total[first] - total[0]) / 4, atol=1e-12)
        # a new segment restarts at the logged position
        assert x[k][n // 2] == pytest.approx(2e-3)
        np.testing.assert_allclose(
            x[k][second] - 2e-3, (total[second] - total[n // 2]) / 4, atol=1e-12
        )


def test_pistons_exchanging_oil_keep_their_logged_motion():
    """Rope equalisation on a trip: one piston in, one out, the sum unchanged."""
    n = 1000
    move = _smooth_step(n, 500, 400, 1e-3)
    logged = (move, -move, np.zeros(n), np.zeros(n))
    x, _ = share_out_common_motion(np.zeros(n), logged, np.zeros(n, dtype=np.int64))
    np.testing.assert_allclose(x[0], move, atol=1e-12)
    np.testing.assert_allclose(x[1], -move, atol=1e-12)
    np.testing.assert_allclose(x[2], 0.0, atol=1e-12)


def test_blind_motion_is_unknown_until_seen_sliding_and_counts_ringing():
    n = 3000
    t = np.arange(n) / 50.0
    ringing = np.where(t > 40.0, 40e-6 * np.sin(2 * np.pi * (t - 40.0)), 0.0)
    # piston 1 is seen sliding 1 mm (more than the reset) from 5 s to 15 s with the oil
    move = _smooth_step(n, 500, 500, 1e-3)
    total = move + ringing
    logged = (move, np.zeros(n), np.zeros(n), np.zeros(n))
    _, blind = share_out_common_motion(
        total / 4,
        logged,
        np.zeros(n, dtype=np.int64),
        elastic_half_width_m=0.2e-3,
        seen_reset_m=0.1e-3,
    )
    # the sticking pistons were never seen sliding: their friction state is unknown
    for k in (1, 2, 3):
        assert np.isinf(blind[k]).all()
    # piston 1: known once it has slid, then its blind path grows only with the ringing
    assert np.isinf(blind[0][0])
    assert blind[0][1900] == 0.0
    # 20 s at 1 Hz of +-10 um (a quarter of the sum's 40 um): 40 swings of 20 um less
    # the 4 um the 2 um dead band takes from each: 0.64 mm of path
    assert blind[0][-1] == pytest.approx(0.64e-3, rel=0.05)
