"""The pistons' stick-slip on rope springs and the ropes' identification (issue 13).

Analytic cases of :func:`transforms.stick_slip.stick_slip` (the answers solve the
physics' linear equations here, not with the kernel's Newton iteration):

- every seal sticks through a small pressure rise: each piston takes a quarter of the
  oil's compression and its bristles the force sigma_0 dx;
- one piston's seal is near its capacity when the load falls: it slides and ends at
  its capacity, the three others stick with the friction their ropes leave them;
- seals of Maxwell-slip elements (``presliding_hysteresis``) through a rise and a fall
  back: the virgin curve, then Masing's rule (the return branch is the virgin curve
  doubled in both axes);
- blocks with the state carried give the whole record, bit for bit;
- the rope constants identified from a record of ropeload's device simulation (its
  Maxwell-slip seals, ringing ropes, a 0.1 mm logger step) with one rope 4 % stiffer;
- a worn groove: a length offset growing with depth, the same solution as the offset
  at a fixed depth; on the device simulation's worn hoist the declared wear is the one
  whose solution matches the logged x.
"""

from __future__ import annotations

import datetime as dt
import itertools
import json

import numpy as np
import polars as pl
import pytest

from physics.friction_law import friction_law_at, law_array
from physics.oil import effective_bulk_modulus_at
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from transforms import compensation_block, rope_identification
from transforms.compensation import CompensationSettings, compensate
from transforms.rope_identification import SPLITS, identify_from_means, record_means
from transforms.stick_slip import stick_slip, stick_slip_mismatch, stick_slip_state
from transforms.stick_slip_band import (
    BAND_SOURCES,
    MAX_ALTERNATIVES,
    MAX_SOLUTIONS,
    MEMBER_STIFFNESS_LIMITS,
    RINGING_MEMBERS,
    RopeSprings,
    band_solutions,
    prior_rope_springs,
)

HOIST = load_hoist(EXAMPLE_HOIST)
AREA = HOIST.cylinders.bore_area_m2
SIGMA0 = float(HOIST.friction_law.bristle_stiffness_n_m)
DEPTH = 300.0
K_ROPE = HOIST.ropes.head_rope_axial_stiffness_n / (HOIST.shaft.headframe_height_m + DEPTH)
EQUAL = RopeSprings((1.0,) * 4, (0.0,) * 4, 0.0, 0)


def _beta(p: float) -> float:
    oil = HOIST.oil
    return effective_bulk_modulus_at(p, oil.bulk_modulus_pa, oil.air_fraction, 1e5, 1.0)


def _static_n(p: float) -> float:
    return friction_law_at(p, law_array(HOIST.friction_law))[1]


def _oil_volume(p: np.ndarray) -> float:
    """The oil's compression, summed step by step at each step's pressure (eq 5) [m]."""
    steps = itertools.pairwise(p)
    return sum(HOIST.oil_volume_m3 / (_beta(b) * AREA) * (b - a) for a, b in steps)


def _run(p: np.ndarray, springs: RopeSprings, *, dt_s: float = 0.01):
    n = p.size
    return stick_slip(
        (p,) * 4, (np.zeros(n),) * 4, np.full(n, DEPTH), np.zeros(n, int), HOIST, springs,
        dt_s=dt_s,
    )  # fmt: skip


def test_every_seal_sticks_through_a_small_rise():
    p0, dp = 4.0e6, 2.0e4
    p = np.r_[np.full(10, p0), np.linspace(p0, p0 + dp, 200)[1:]]
    x, f = _run(p, EQUAL)
    volume = sum(
        HOIST.oil_volume_m3 / (_beta(b) * AREA) * (b - a) for a, b in itertools.pairwise(p)
    )
    for i in range(4):
        assert x[i][-1] == pytest.approx(volume / 4, rel=1e-9)
        assert f[i][-1] == pytest.approx(SIGMA0 * volume / 4, rel=1e-9)
        assert abs(f[i][-1]) < _static_n(p[-1])  # it did stick


def test_a_sensor_not_logged_takes_the_others_mean_and_the_seals_go_on():
    """The small rise of the test above with sensor 4 silent over its middle third: the
    chambers share the oil, so its pressure is the others' (equal here) and every seal
    follows as with four sensors, not held until the sensor returns (the first wave
    held all four for the gap, then caught up in one step)."""
    p0, dp = 4.0e6, 2.0e4
    p = np.r_[np.full(10, p0), np.linspace(p0, p0 + dp, 200)[1:]]
    n = p.size
    silent = p.copy()
    silent[70:140] = np.nan
    args = (np.full(n, DEPTH), np.zeros(n, int), HOIST, EQUAL)
    _, whole = stick_slip((p,) * 4, (np.zeros(n),) * 4, *args, dt_s=0.01)
    _, gap = stick_slip((p, p, p, silent), (np.zeros(n),) * 4, *args, dt_s=0.01)
    for i in range(4):
        np.testing.assert_allclose(gap[i], whole[i], rtol=1e-12)  # a mean of 3, not 4
    assert whole[0][139] - whole[0][70] > 0.3 * whole[0][-1]  # they moved in the gap


def test_a_sensor_leaving_or_rejoining_the_mean_puts_no_step_in_the_oil():
    """A rising load, sensor 4 reading 40 kPa above the others (a differential the oil's
    flow may make) and silent at the record's first sample and from sample 200 on: the
    pistons' displacements still sum to the oil's compression (eq 5, A sum dx = V dp /
    beta) at every sample, whole or in two blocks split where it leaves (the mean of
    four and of three differ by 10 kPa: taken as the oil's change, that step displaced
    the pistons, and a split there gave another answer, 48 N of friction)."""
    n = 400
    p = np.linspace(4.0e6, 4.02e6, n)
    p4 = p + 4e4
    p4[0] = np.nan
    p4[200:] = np.nan
    pressures, logged = (p, p, p, p4), (np.zeros(n),) * 4
    args = (np.full(n, DEPTH), np.zeros(n, int), HOIST, EQUAL)
    x, whole = stick_slip(pressures, logged, *args, dt_s=0.01)
    total = sum(x)
    for t in (1, 100, 199, 200, 300, n - 1):
        assert total[t] == pytest.approx(_oil_volume(p[: t + 1]), rel=1e-9, abs=1e-15)
    state = stick_slip_state(4)
    halves = [
        stick_slip(tuple(q[part] for q in pressures), tuple(v[part] for v in logged),
                   np.full(200, DEPTH), np.zeros(200, int), HOIST, EQUAL, dt_s=0.01,
                   state=state)[1]
        for part in (slice(0, 200), slice(200, n))
    ]  # fmt: skip
    for i in range(4):
        np.testing.assert_array_equal(np.r_[halves[0][i], halves[1][i]], whole[i])


def test_the_mismatch_of_a_population_is_each_ones_mean_square_off_the_logged_x():
    """Every seal sticks through a small rise (the test above: each piston takes a quarter
    of the oil's compression); piston 2 has no logged x, piston 3 half of it, piston 4's
    is 20 um off on its last 100 samples: the true ropes' mismatch is (20 um)^2 x 100 / n
    over the three pistons with an x. A stiffer rope 2 is further off, as stick_slip's x
    says."""
    p0, dp = 4.0e6, 2.0e4
    p = np.r_[np.full(10, p0), np.linspace(p0, p0 + dp, 200)[1:]]
    n = p.size
    share = np.r_[0.0, np.cumsum([_oil_volume(p[k : k + 2]) for k in range(n - 1)])] / 4
    logged = [share.copy() for _ in range(4)]
    logged[1][:] = np.nan
    logged[2][n // 2 :] = np.nan
    logged[3][-100:] += 20e-6
    ropes = np.array([[1.0] * 4, [1.0, 1.04, 1.0, 1.0]])
    depth, segment = np.full(n, DEPTH), np.zeros(n, int)
    got = stick_slip_mismatch(
        (p,) * 4, tuple(logged), depth, segment, HOIST, ropes, np.zeros((2, 4)), dt_s=0.01
    )
    assert got[0] == pytest.approx((20e-6) ** 2 * 100 / n / 3, rel=1e-6)
    x, _ = stick_slip(
        (p,) * 4, tuple(logged), depth, segment, HOIST,
        RopeSprings(tuple(ropes[1]), (0.0,) * 4, 0.0, 0), dt_s=0.01,
    )  # fmt: skip
    pistons = [np.nanmean((x[i] - logged[i]) ** 2) for i in (0, 2, 3)]
    assert got[1] == pytest.approx(np.mean(pistons), rel=1e-12)
    assert got[1] > got[0]


def test_inputs_of_another_length_are_refused():
    p = np.full(20, 4e6)
    depth, segment = np.full(20, DEPTH), np.zeros(20, int)
    short = (np.zeros(20),) * 2 + (np.zeros(19),) * 2
    ropes = np.ones((1, 4)), np.zeros((1, 4))
    with pytest.raises(ValueError, match=r"x_logged\[2\] has \(19,\) samples"):
        stick_slip_mismatch((p,) * 4, short, depth, segment, HOIST, *ropes, dt_s=0.01)
    with pytest.raises(ValueError, match="3 logged x for 4 pressures"):
        stick_slip((p,) * 4, (np.zeros(20),) * 3, depth, segment, HOIST, EQUAL, dt_s=0.01)


def _virgin_n(u: float, capacity: float, elements: int = 4) -> float:
    """The virgin curve of ``elements`` Maxwell-slip elements of the example hoist's
    bristle stiffness in all (Lampaert et al. 2002; equal weights, k_j proportional to
    1/j: physics.maxwell_slip.maxwell_slip_elements' documented choice), written out."""
    k = SIGMA0 * (1.0 / np.arange(1, elements + 1)) / sum(1.0 / np.arange(1, elements + 1))
    return float(np.sum(np.minimum(k * abs(u), capacity / elements)) * np.sign(u))


def _returned_n(u: float, capacity_there: float, capacity_back: float) -> float:
    """The elements of :func:`_virgin_n` taken to u and back to 0: each element's
    deflection min(u, L_j there) less u, held within its limit L_j back (the capacity
    follows the pressure: a slipping element's limit moves with it)."""
    k = SIGMA0 * (1.0 / np.arange(1, 5)) / sum(1.0 / np.arange(1, 5))
    there = np.minimum(u, capacity_there / 4 / k)
    return float(np.sum(k * np.maximum(there - u, -capacity_back / 4 / k)))


def test_maxwell_slip_seals_follow_the_virgin_curve_then_masing():
    """Equal ropes: every piston takes a quarter of the oil's compression whatever its
    seal (eq 5). A rise takes the four elements of each seal up their virgin curve, past
    the two stiffest elements' slip; the fall back to the start's pressure returns each
    piston to 0, its friction on Masing's branch (F_a - 2 F_virgin(x_a / 2) at one
    capacity; here each element's limit follows the pressure's), not 0. One bristle
    slides at the top and comes back to min(sigma_0 x_a, F_s) - sigma_0 x_a."""
    p0 = 4.0e6
    capacity = _static_n(p0)
    limit_1 = capacity / 4 / (SIGMA0 / sum(1.0 / np.arange(1, 5)))  # stiffest element's
    dp = 2.5 * limit_1 * 4 * AREA * _beta(p0) / HOIST.oil_volume_m3  # x_a ~ 2.5 x limit_1
    rise = np.linspace(p0, p0 + dp, 400)
    p = np.r_[np.full(10, p0), rise[1:], rise[::-1][1:], np.full(10, p0)]
    n = p.size
    top = 10 + rise.size - 2

    def run(elements: int):
        return stick_slip(
            (p,) * 4, (np.zeros(n),) * 4, np.full(n, DEPTH), np.zeros(n, int), HOIST, EQUAL,
            dt_s=1.0, presliding_elements=elements,
        )  # fmt: skip

    x, f = run(4)
    x_a = _oil_volume(p[: top + 1]) / 4
    # the limits are j x limit_1 (k_j proportional to 1/j, equal weights): past two
    assert 2 * limit_1 < x_a < 3 * limit_1
    at_top = _static_n(p[top])  # the capacity grows with the pressure (eq 17)
    for i in range(4):
        assert x[i][top] == pytest.approx(x_a, rel=1e-9)
        assert f[i][top] == pytest.approx(_virgin_n(x_a, at_top), rel=1e-5)
        assert x[i][-1] == pytest.approx(0.0, abs=1e-12)
        assert f[i][-1] == pytest.approx(_returned_n(x_a, at_top, capacity), rel=1e-5)
        assert f[i][-1] < -0.2 * capacity  # the elements remember the rise
    # at one capacity throughout that is Masing's rule, F_a - 2 F_virgin(x_a / 2)
    masing = _virgin_n(x_a, capacity) - 2.0 * _virgin_n(x_a / 2.0, capacity)
    assert _returned_n(x_a, capacity, capacity) == pytest.approx(masing, rel=1e-12)
    _, f_one = run(1)
    one = min(SIGMA0 * x_a, at_top) - SIGMA0 * x_a
    assert f_one[0][-1] == pytest.approx(one, rel=1e-4)
    assert abs(f_one[0][-1] - f[0][-1]) > 0.03 * capacity  # the elements are not one (5 %)


def test_maxwell_slip_seals_do_not_drift():
    n = 10
    args = ((np.full(n, 4e6),) * 4, (np.zeros(n),) * 4, np.full(n, 300.0), np.zeros(n, int))
    with pytest.raises(ValueError, match="do not drift"):
        stick_slip(*args, HOIST, EQUAL, dt_s=0.01, drift_pressure_pa=np.zeros(n),
                   presliding_elements=4)  # fmt: skip
    with pytest.raises(ValueError, match="state has"):
        stick_slip(*args, HOIST, EQUAL, dt_s=0.01, state=stick_slip_state(4),
                   presliding_elements=4)  # fmt: skip


def test_the_seal_nearest_its_capacity_slides_and_the_others_stick():
    """Rope 1 is longer: at the start its seal carries 3/4 k c less than the mean (0 by
    the start's convention: 90 % of its capacity below), the others 1/4 k c more. A slow
    fall of the load slides seal 1 down, held at its capacity -F_s(p) as p falls; 2-4
    stick. Unknowns after the fall: the common stretch ds, the sticking pistons' dx_s
    and the sliding one's dx_1, from

        ropes 2-4: k (ds - dx_s) = A dp + sigma_0 dx_s    (eq 2, sticking bristles)
        rope 1:    k (ds - dx_1) = A dp - F_s(p_end) - F_1(0)    (at its capacity)
        oil:       A (dx_1 + 3 dx_s) = V / beta dp    (eq 5)
    """
    p0, dp = 4.0e6, -3.0e5
    offset = 0.9 * _static_n(p0) / (0.75 * K_ROPE)
    springs = RopeSprings((1.0,) * 4, (offset, 0.0, 0.0, 0.0), 0.0, 0)
    p = np.r_[np.full(10, p0), np.linspace(p0, p0 + dp, 20_000)[1:], np.full(50, p0 + dp)]
    x, f = _run(p, springs, dt_s=0.05)
    start = [f[i][0] for i in range(4)]
    assert start[0] == pytest.approx(-0.9 * _static_n(p0), rel=1e-9)
    assert start[1] == pytest.approx(0.3 * _static_n(p0), rel=1e-9)
    capacity = _static_n(p[-1])
    a = np.array([[K_ROPE, -(K_ROPE + SIGMA0), 0.0], [K_ROPE, 0.0, -K_ROPE], [0.0, 3.0, 1.0]])
    b = np.array([AREA * dp, AREA * dp - capacity - start[0], _oil_volume(p)])
    _, dx_s, dx_1 = np.linalg.solve(a, b)
    # the slide ends at the capacity at the slide's last, slow speed (Stribeck: ~F_s)
    assert f[0][-1] == pytest.approx(-capacity, rel=1e-3)
    assert x[0][-1] == pytest.approx(dx_1, rel=5e-3)
    for i in (1, 2, 3):
        assert x[i][-1] == pytest.approx(dx_s, rel=5e-3)
        assert f[i][-1] == pytest.approx(start[i] + SIGMA0 * dx_s, rel=5e-3)
        assert abs(f[i][-1]) < 0.9 * capacity  # stuck
    assert abs(dx_1) > 10 * abs(dx_s)  # the slider took the oil


def _from_start(p: np.ndarray, springs: RopeSprings, start: float):
    n = p.size
    return stick_slip(
        (p,) * 4, (np.zeros(n),) * 4, np.full(n, DEPTH), np.zeros(n, int), HOIST, springs,
        dt_s=0.05, start_at_capacity=start,
    )  # fmt: skip


def test_the_start_members_take_the_seals_as_far_as_the_ropes_let():
    """Nothing tells the seals' friction where a record starts. Rope 1 is longer (its
    seal carries 0.9 F_s less than the mean, the others 0.3 F_s more, as above): taking
    the common stretch as far up as the ropes let puts seals 2-4 at +F_s and seal 1 at
    -0.2 F_s; as far down, seal 1 at -F_s and 2-4 at +0.2 F_s. Nothing moves while the
    pressure stands. Where a rope's offset asks more than its seal holds, the estimate
    still starts with the seals' friction summing to 0."""
    p0 = 4.0e6
    offset = 0.9 * _static_n(p0) / (0.75 * K_ROPE)
    springs = RopeSprings((1.0,) * 4, (offset, 0.0, 0.0, 0.0), 0.0, 0)
    p = np.full(20, p0)
    expected = {1.0: (-0.2, 1.0, 1.0, 1.0), -1.0: (-1.0, 0.2, 0.2, 0.2), 0.0: (-0.9, 0.3, 0.3, 0.3)}
    for start, shares in expected.items():
        x, f = _from_start(p, springs, start)
        for i in range(4):
            assert f[i] == pytest.approx(np.full(20, shares[i] * _static_n(p0)), rel=1e-9)
            assert x[i] == pytest.approx(np.zeros(20), abs=1e-12)
    with pytest.raises(ValueError, match="start_at_capacity"):
        _from_start(p, springs, 0.5)
    # ropes that already leave seal 1 beyond its capacity down (1.5 F_s below the mean):
    # the estimate's seals still sum to 0 where it starts (seal 1 at -F_s, the others
    # F_s / 3 each: the load the sensors show), and the down member starts there too
    far = RopeSprings((1.0,) * 4, (2.0 * _static_n(p0) / K_ROPE, 0.0, 0.0, 0.0), 0.0, 0)
    _, down = _from_start(p, far, -1.0)
    _, estimate = _from_start(p, far, 0.0)
    assert [f[0] for f in estimate] == pytest.approx(
        [-_static_n(p0)] + [_static_n(p0) / 3] * 3, rel=1e-12
    )
    for i in range(4):
        assert down[i] == pytest.approx(estimate[i], rel=1e-12, abs=1e-9)


def test_pistons_not_logged_start_where_their_ropes_hold_them():
    """No logged x: each piston starts where its rope holds its chamber, every seal at 0,
    their mean x at 0. Ropes 5 % stiffer and softer (a prior's sigma point): at x = 0 the
    stiffer ropes' seals would start 5 % of p A = 1.6 kN up, the softer ones' as far
    down. Equal ropes whose lengths differ by +-0.8 F_s / k: at x = 0 their seals would
    start at -+0.8 F_s; from 0, a rise of 0.4 MPa (each piston out by V dp / (4 beta A)
    = 0.08 mm, more than one capacity of bristle travel, 0.05 mm, less than the 1.8
    capacities from -0.8 F_s) slides every seal out to +F_s(p), the most the seals hold
    together."""
    p0, dp = 4.0e6, 0.4e6
    rest = np.full(20, p0)
    p = np.r_[rest, np.linspace(p0, p0 + dp, 400)[1:], np.full(20, p0 + dp)]
    travel = abs(_oil_volume(p)) / 4
    assert _static_n(p[-1]) / SIGMA0 < travel < 1.8 * _static_n(p0) / SIGMA0

    def solve(pressure, springs):
        n = pressure.size
        return stick_slip(
            (pressure,) * 4, (np.full(n, np.nan),) * 4, np.full(n, DEPTH), np.zeros(n, int),
            HOIST, springs, dt_s=0.05,
        )  # fmt: skip

    apart = RopeSprings((1.05, 0.95, 1.05, 0.95), (0.0,) * 4, 0.0, 0)
    x, f = solve(rest, apart)
    assert [fi[0] for fi in f] == pytest.approx([0.0] * 4, abs=1e-6)
    factors = apart.stiffness_factors
    stretch = [xi[0] + p0 * AREA / (a * K_ROPE) for xi, a in zip(x, factors, strict=True)]
    assert stretch == pytest.approx([stretch[0]] * 4, rel=1e-12)  # one common stretch
    assert np.mean([xi[0] for xi in x]) == pytest.approx(0.0, abs=1e-12)
    c = 0.8 * _static_n(p0) / K_ROPE
    longer = RopeSprings((1.0,) * 4, (c, -c, c, -c), 0.0, 0)
    x, f = solve(p, longer)
    assert [fi[0] for fi in f] == pytest.approx([0.0] * 4, abs=1e-6)
    assert [xi[0] for xi in x] == pytest.approx([-c, c, -c, c], rel=1e-9)
    assert [fi[-1] for fi in f] == pytest.approx([_static_n(p[-1])] * 4, rel=1e-3)


def test_a_slide_forgets_the_start():
    """Equal ropes: the start members put every seal at -F_s or +F_s, the estimate at 0.
    A fall of 1 MPa moves each piston by V dp / (4 beta A) = 0.2 mm, more than two
    capacities of bristle travel (2 F_s / sigma_0 = 0.14 mm): every seal slides down,
    and the three solutions end at the same -F_s(p)."""
    p0, dp = 4.0e6, -1.0e6
    p = np.r_[np.full(20, p0), np.linspace(p0, p0 + dp, 2000)[1:], np.full(20, p0 + dp)]
    assert abs(_oil_volume(p)) / 4 > 2 * _static_n(p0) / SIGMA0
    ends = []
    for start in (-1.0, 0.0, 1.0):
        _, f = _from_start(p, EQUAL, start)
        assert [fi[0] for fi in f] == pytest.approx([start * _static_n(p0)] * 4, abs=1e-9)
        ends += [fi[-1] for fi in f]
    capacity = _static_n(p[-1])
    assert ends == pytest.approx([-capacity] * 12, rel=1e-3)  # slid down, at capacity
    assert max(ends) - min(ends) < 1e-6 * capacity  # the start forgotten


@pytest.mark.parametrize(("splits", "identified"), [(4, 4), (4, 3), (4, 2), (4, 1), (2, 2), (2, 1)])
def test_the_ropes_members_hold_95_percent(splits, identified):
    """The band's rope members (:func:`band_solutions`): a constant identified on
    ``splits`` equal parts of a record, each part's error normal with ``splits`` x the
    whole's variance, the whole their mean, and ``identified`` of the parts giving
    ropes. The members and the whole hold the true value in >= 95 % of 5 000 records
    (:func:`parts_reach`: Student's t is exact for the RMS and for two parts; the
    largest deviation widens it for more; one part alone is mirrored)."""
    rng = np.random.default_rng(7)
    # a length offset [m], truth 0; the whole's standard deviation 1 mm
    parts = rng.normal(0.0, 1e-3 * np.sqrt(splits), size=(5_000, splits))
    inside = 0
    for draw in parts:
        whole = float(draw.mean())
        seen = tuple(((1.0,), (float(q),)) for q in draw[:identified])
        springs = RopeSprings((1.0,), (whole,), 0.0, 0, seen, parts=splits)
        members = [ropes.length_offsets_m[0] for _, _, ropes, *_ in band_solutions(springs, 0.1)]
        inside += min(members) <= 0.0 <= max(members)
    assert 0.94 < inside / len(parts) < 0.99  # 95 % less three standard errors of the draws


def test_the_ropes_members_stay_within_their_limits():
    """A part's deviation taken t x as far would make a rope slack: the members'
    stiffness factors stop at MEMBER_STIFFNESS_LIMITS; alternatives without two parts
    at least are refused."""
    part = ((1.0, 0.92), (0.0, 1e-3))
    springs = RopeSprings((1.0, 1.0), (0.0, 0.0), 0.0, 0, (part,), parts=2)
    factors = [r.stiffness_factors[1] for _, _, r, *_ in band_solutions(springs, 0.1)[5:]]
    assert factors == [MEMBER_STIFFNESS_LIMITS[0], MEMBER_STIFFNESS_LIMITS[1]]
    with pytest.raises(ValueError, match="two parts"):
        RopeSprings((1.0, 1.0), (0.0, 0.0), 0.0, 0, (part,))
    with pytest.raises(ValueError, match="alternatives of 2 parts"):
        RopeSprings((1.0, 1.0), (0.0, 0.0), 0.0, 0, (part,) * 3, parts=2)


@pytest.mark.parametrize(
    ("drift", "start", "elements"),
    [
        ("none", 0.0, 1),
        ("pressure", 0.0, 1),
        ("travel", 0.0, 1),
        ("pressure", 1.0, 1),
        ("none", 0.0, 4),
        ("none", -1.0, 4),
    ],
)
def test_blocks_give_the_whole_record(drift, start, elements):
    """Also where the depth is unknown across a block's edge (the last known is kept),
    with the seals' drift (its play's output, heading and the pistons' compliance
    carried: a ringing on the pressure makes the play turn across the edges; or the
    travel given, its part at unknown pressures carried), and where a block's edge
    falls inside the unknown pressures that start a new segment; also for a band member
    that starts the record with the seals up, and for seals of four Maxwell-slip
    elements (each element's deflection carried)."""
    n_all = 3000
    p = 4.0e6 + 3.0e5 * np.sin(np.linspace(0, 6 * np.pi, n_all))
    p += 2.0e4 * np.sin(np.linspace(0, 300 * np.pi, n_all))
    p[1500:1510] = np.nan
    segment = (np.arange(n_all) >= 1500).astype(int)
    depth = np.linspace(100.0, 500.0, n_all)
    depth[990:1010] = np.nan
    depth[2195:2205] = np.nan
    springs = RopeSprings((1.0, 1.03, 0.98, 1.01), (0.0, 2e-3, -1e-3, 0.5e-3), 0.0, 0)
    travel = np.abs(np.diff(np.nan_to_num(p), prepend=p[0]))

    def run(lo: int, hi: int, state: np.ndarray | None = None):
        n = hi - lo
        return stick_slip(
            (p[lo:hi],) * 4, (np.zeros(n),) * 4, depth[lo:hi], segment[lo:hi], HOIST, springs,
            dt_s=0.01, state=state, drift_pressure_pa=p[lo:hi] if drift == "pressure" else None,
            drift_half_width_pa=5e3, start_at_capacity=start,
            drift_travel_pa=travel[lo:hi] if drift == "travel" else None,
            presliding_elements=elements,
        )  # fmt: skip

    whole_x, whole_f = run(0, n_all)
    state = stick_slip_state(4, elements)
    parts = []
    for lo, hi in ((0, 1000), (1000, 1505), (1505, 2200), (2200, n_all)):
        state[1] = 1.0 if lo and segment[lo] == segment[lo - 1] else 0.0
        parts.append(run(lo, hi, state))
    for i in range(4):
        assert np.array_equal(np.concatenate([part[1][i] for part in parts]), whole_f[i])
        assert np.array_equal(np.concatenate([part[0][i] for part in parts]), whole_x[i])


def test_a_record_without_a_first_depth_starts_at_its_first_known_one():
    """The ropes' stiffness k = EA / (headframe + depth) needs the depth: where the
    record's first samples have none, the start takes the first known one (it took the
    headframe alone, ropes ~7 x too stiff at 300 m, and a sigma point's seals started
    ~1 kN apart: a payload change then slid two of them). Blocks keep the last known
    depth also from a block whose pressures were all unknown."""
    n = 300
    p = np.full(n, 4.0e6)
    p[100:150] = np.linspace(4.0e6, 4.4e6, 50)
    p[150:] = 4.4e6
    apart = RopeSprings((1.0433, 0.9567, 1.0433, 0.9567), (0.0,) * 4, 0.0, 0)

    def solve(pressure, depth, lo=0, hi=n, state=None):
        return stick_slip(
            (pressure[lo:hi],) * 4, (np.full(hi - lo, np.nan),) * 4, depth[lo:hi],
            np.zeros(hi - lo, int), HOIST, apart, dt_s=0.01, state=state,
        )  # fmt: skip

    known = np.full(n, DEPTH)
    late = known.copy()
    late[:5] = np.nan
    for want, got in zip(solve(p, known), solve(p, late), strict=True):
        for i in range(4):
            assert np.array_equal(want[i], got[i])
    # pressures unknown over a first block whose depth is known, the next block's
    # first depths unknown: the blocks give the whole record
    first = p.copy()
    first[:40] = np.nan
    depth = known.copy()
    depth[40:60] = np.nan
    whole = solve(first, depth)
    state = stick_slip_state(4)
    parts = [solve(first, depth, lo, hi, state) for lo, hi in ((0, 30), (30, n))]
    for k in range(2):
        for i in range(4):
            assert np.array_equal(np.concatenate([part[k][i] for part in parts]), whole[k][i])


def test_a_held_stretch_of_unknown_pressure_is_one_step_over_its_whole_time():
    """Pressures unknown for 2 s while the load rises and the ropes shorten: the first
    sample after it solves the stretch's motion over its 2 s (a speed of dx / 2 s, not
    dx / 0.01 s, which dropped the Stribeck capacity toward F_c and clipped the sliding
    seals by ~600 N for 2 s), and from the next sample on the solution is the one of
    the record solved sample by sample."""
    n = 600
    p = np.linspace(4.0e6, 4.6e6, n)
    depth = np.linspace(300.0, 50.0, n)
    springs = RopeSprings((1.0, 1.03, 0.98, 1.01), (0.0,) * 4, 0.0, 0)

    def solve(pressure):
        _, f = stick_slip(
            (pressure,) * 4, (np.zeros(n),) * 4, depth, np.zeros(n, int), HOIST, springs,
            dt_s=0.01,
        )  # fmt: skip
        return np.array(f)

    whole = solve(p)
    held = p.copy()
    held[200:400] = np.nan
    gapped = solve(held)
    assert gapped[:, 401:] == pytest.approx(whole[:, 401:], rel=1e-3, abs=1.0)


def test_a_rope_beyond_its_seal_at_the_start_is_balanced_there():
    """At the pithead, equal ropes, piston 4 logged 2.5 mm out: its rope asks 2.75 kN
    less than the others', beyond its seal's capacity. The start puts seal 4 at -F_s,
    the others at F_s / 3 (their sum 0) and piston 4 where its rope holds it at that
    (2.2 mm: moved 0.3 mm, within the logger's and the offsets' uncertainty); nothing
    moves while the pressure stands. Left at its logged x it slid in the next sample,
    pushed the other seals up and left their sum at 1.45 kN."""
    n, p0 = 50, 4.0e6
    p = np.full(n, p0)
    logged = tuple(np.full(n, v) for v in (0.0, 0.0, 0.0, 2.5e-3))
    springs = RopeSprings((1.0,) * 4, (0.0,) * 4, 0.0, 0)
    x, f = stick_slip((p,) * 4, logged, np.zeros(n), np.zeros(n, int), HOIST, springs, dt_s=0.01)
    fs = _static_n(p0)
    for i, share in enumerate((1 / 3, 1 / 3, 1 / 3, -1.0)):
        assert f[i] == pytest.approx(np.full(n, share * fs), rel=1e-9)
    k_top = HOIST.ropes.head_rope_axial_stiffness_n / HOIST.shaft.headframe_height_m
    assert x[3] == pytest.approx(np.full(n, 4 / 3 * fs / k_top), rel=1e-9)
    for i in range(3):
        assert x[i] == pytest.approx(np.zeros(n), abs=1e-12)


def test_a_given_travel_is_carried_over_unknown_pressures():
    """The drift's travel given at samples of unknown pressure acts at the next known
    one: the same as giving it there. A negative or NaN travel is refused."""
    n = 40
    p = np.linspace(4.0e6, 4.05e6, n)
    p[10:15] = np.nan
    args = ((p,) * 4, (np.zeros(n),) * 4, np.full(n, 300.0), np.zeros(n, int), HOIST, EQUAL)
    spread = np.zeros(n)
    spread[10:15] = 2e3
    spread[20] = 1e3
    at_once = np.zeros(n)
    at_once[15] = 10e3
    at_once[20] = 1e3
    one = stick_slip(*args, dt_s=0.01, drift_travel_pa=spread)[1]
    other = stick_slip(*args, dt_s=0.01, drift_travel_pa=at_once)[1]
    none = stick_slip(*args, dt_s=0.01, drift_travel_pa=np.zeros(n))[1]
    for a, b, c in zip(one, other, none, strict=True):
        np.testing.assert_array_equal(a, b)
        assert abs(a[-1]) < abs(c[-1])  # the travel drained the seals
    for bad in (-1.0, np.nan):
        travel = np.zeros(n)
        travel[3] = bad
        with pytest.raises(ValueError, match="finite and >= 0"):
            stick_slip(*args, dt_s=0.01, drift_travel_pa=travel)


def test_the_drift_pressure_must_fit_the_record():
    n = 10
    args = ((np.full(n, 4e6),) * 4, (np.zeros(n),) * 4, np.full(n, 300.0), np.zeros(n, int))
    with pytest.raises(ValueError, match="drift_pressure_pa has"):
        stick_slip(*args, HOIST, EQUAL, dt_s=0.01, drift_pressure_pa=np.zeros(n - 1))
    with pytest.raises(ValueError, match="must be >= 0"):
        stick_slip(*args, HOIST, EQUAL, dt_s=0.01, drift_pressure_pa=np.zeros(n),
                   drift_half_width_pa=-1.0)  # fmt: skip


@pytest.fixture(scope="module")
def stiff_rope_day() -> tuple[pl.DataFrame, tuple[float, ...]]:
    from sims.field_day import generate_field_day

    factors = (1.0, 1.04, 1.0, 1.0)
    hoist = HOIST.model_copy(
        update={"ropes": HOIST.ropes.model_copy(update={"head_rope_stiffness_factors": factors})}
    )
    day = generate_field_day(hoist, date="2026-03-02", seed=5, trips=8, hours=1.0)
    # a logger's 0.1 mm step on the simulation's noisy x
    step = 1e-4
    logged = day.sensors.with_columns(
        (pl.col(f"x{i}_m") / step).round() * step for i in range(1, 5)
    )
    return logged.sort("time_utc"), factors


def test_the_identification_finds_the_stiffer_rope(stiff_rope_day):
    """ropeload's device simulation (the example hoist's Maxwell-slip seals, ropes that
    ring, x logged to a 0.1 mm step): rope 2 is 4 % stiffer than the others, the lengths
    are equal."""
    samples, factors = stiff_rope_day
    springs = identify_from_means(record_means(samples, samples["time_utc"][0]), HOIST)
    assert springs is not None
    ratios = np.array(springs.stiffness_factors) / springs.stiffness_factors[0]
    # 1.038 for rope 2 with the seals' own four Maxwell-slip elements in the model
    # (1.057 with one elasto-plastic bristle for them); a wrong basin takes ropes 3, 4
    # as 8 % softer
    assert ratios == pytest.approx(np.array(factors), abs=0.01)
    assert int(np.argmax(ratios)) == 1
    assert springs.mismatch_m < 0.1e-3
    # each quarter of the record identified again (the band's members take these
    # ropes): a quarter holds two trips, so its ropes are less certain (rope 2
    # 1.012-1.033) than the whole record's
    assert len(springs.alternatives) == SPLITS
    quarters = [a[1] / a[0] for a, _ in springs.alternatives]
    assert abs(ratios[1] - factors[1]) < min(abs(q - factors[1]) for q in quarters)
    rope_2 = [ratios[1], *quarters]
    assert max(rope_2) - min(rope_2) < 0.08
    # the whole record was searched on one thread beside its quarters; alone, with the
    # default threads (the members split over the cores on a long record): the same
    # ropes to the last bit
    alone = rope_identification._identify(
        record_means(samples, samples["time_utc"][0]), HOIST, parts=False
    )
    assert (alone.stiffness_factors, alone.length_offsets_m, alone.mismatch_m) == (
        springs.stiffness_factors,
        springs.length_offsets_m,
        springs.mismatch_m,
    )


def test_the_search_stops_losing_trials_without_changing_its_answer(stiff_rope_day, monkeypatch):
    """Each trial of the global search is solved only until it has lost to the member it
    would replace (rope_identification._Parents mirrors scipy's deferred selection):
    the same ropes, to the last bit, as every trial solved whole; and most trials stop."""
    samples, _ = stiff_rope_day
    means = record_means(samples, samples["time_utc"][0])
    stopped = []
    mismatch = rope_identification.stick_slip_mismatch

    def counting(*args, bounds=None, **kwargs):
        energies = mismatch(*args, bounds=bounds, **kwargs)
        if bounds is not None and np.isfinite(bounds).any() and len(stopped) < 4:
            whole = mismatch(*args, **kwargs)  # a few generations solved whole too
            assert (energies <= whole).all()
            stopped.append(float(np.mean(energies < whole)))
        return energies

    monkeypatch.setattr(rope_identification, "stick_slip_mismatch", counting)
    bounded = rope_identification._identify(means, HOIST, parts=False)
    monkeypatch.setattr(
        rope_identification._Parents, "limits", lambda self, members: np.full(members, np.inf)
    )
    whole = rope_identification._identify(means, HOIST, parts=False)
    assert (bounded.stiffness_factors, bounded.length_offsets_m, bounded.mismatch_m) == (
        whole.stiffness_factors,
        whole.length_offsets_m,
        whole.mismatch_m,
    )
    assert len(stopped) == 4
    assert np.mean(stopped) > 0.3  # trials stopped before their end


def test_a_bounded_mismatch_is_whole_within_its_bound_and_a_lower_bound_beyond():
    """stick_slip_mismatch's bounds: a candidate within its bound gets its mismatch to
    the last bit; one beyond it stops with a value between the bound and its mismatch."""
    n = 3000
    t = np.arange(n) * 0.2
    p = 4.0e6 + 3.0e5 * np.sin(2 * np.pi * t / 200.0)
    rng = np.random.default_rng(8)
    truth = RopeSprings((1.0, 1.03, 0.98, 1.01), (0.0, 2e-3, -1e-3, 0.5e-3), 0.0, 0)
    depth, segment = np.full(n, DEPTH), np.zeros(n, int)
    x, _ = stick_slip((p,) * 4, (np.zeros(n),) * 4, depth, segment, HOIST, truth, dt_s=0.2)
    logged = tuple(np.round((xi + rng.normal(0, 2e-5, n)) / 1e-4) * 1e-4 for xi in x)
    logged[2][100:300] = np.nan
    a = 1.0 + rng.normal(0, 0.03, (40, 4))
    c = rng.normal(0, 2e-3, (40, 4))
    args = ((p,) * 4, logged, depth, segment, HOIST, a, c)
    whole = stick_slip_mismatch(*args, dt_s=0.2)
    bounds = np.median(whole) * rng.uniform(0.5, 1.5, 40)
    bounded = stick_slip_mismatch(*args, dt_s=0.2, bounds=bounds)
    within = whole <= bounds
    assert 5 < within.sum() < 35
    assert np.array_equal(bounded[within], whole[within])
    assert (bounded[~within] > bounds[~within]).all()
    assert (bounded[~within] <= whole[~within]).all()
    assert (bounded[~within] < whole[~within]).any()  # some stopped early


def _means_at_rest() -> pl.DataFrame:
    """The identification's means of a minute at rest (50 Hz, nothing moves)."""
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    n = 3000
    frame = pl.DataFrame(
        {
            "time_utc": [start + dt.timedelta(seconds=k / 50) for k in range(n)],
            **{f"p{i}_pa": np.full(n, 4e6) for i in range(1, 5)},
            **{f"x{i}_m": np.full(n, 1e-3) for i in range(1, 5)},
            "depth_m": np.zeros(n),
            "oil_temp_c": np.full(n, 40.0),
        }
    )
    return record_means(frame, start)


def test_no_motion_no_identification():
    assert identify_from_means(_means_at_rest(), HOIST) is None


def test_identified_ropes_are_remembered_in_the_data_root(stiff_rope_day, tmp_path, monkeypatch):
    """What another process (a re-run, a flow's task, the sanity check) reads instead of
    identifying again; a file that does not read as ropes is identified again."""
    memory = dict(rope_identification._IDENTIFIED)  # this test's own, altered below
    monkeypatch.setattr(rope_identification, "_IDENTIFIED", memory)
    samples, _ = stiff_rope_day
    means = record_means(samples, samples["time_utc"][0])
    cache = tmp_path / "cache" / "rope_springs"
    springs = identify_from_means(means, HOIST, cache_dir=cache)
    (file,) = cache.glob("*.json")
    assert len(file.stem) == 64  # a SHA-256, nothing from the data
    assert set(file.stem) <= set("0123456789abcdef")
    payload = json.loads(file.read_text())
    assert payload["stiffness_factors"] == list(springs.stiffness_factors)
    assert len(payload["alternatives"]) == len(springs.alternatives)
    payload["stiffness_factors"][1] = 1.5  # proof that the file is what is read
    file.write_text(json.dumps(payload))
    memory.clear()
    read = identify_from_means(means, HOIST, cache_dir=cache)
    assert read.stiffness_factors[1] == 1.5
    # the band's law uncertainty does not identify ropes: a description stating another
    # reads the same file
    memory.clear()
    friction = HOIST.friction.model_copy(update={"relative_uncertainty": 0.2})
    restated = HOIST.model_copy(update={"friction": friction})
    assert identify_from_means(means, restated, cache_dir=cache).stiffness_factors[1] == 1.5
    memory.clear()
    assert read.alternatives == springs.alternatives
    assert read.parts == springs.parts == SPLITS
    # a replay's (whole record only): the remembered ropes, alternatives and all ...
    assert identify_from_means(means, HOIST, cache_dir=cache, alternatives=False) == read
    assert list(cache.glob("*.json")) == [file]
    # ... else the whole record's search alone, the same ropes, remembered apart
    memory.clear()
    alone = tmp_path / "alone"
    whole = identify_from_means(means, HOIST, cache_dir=alone, alternatives=False)
    assert whole.stiffness_factors == springs.stiffness_factors
    assert whole.alternatives == ()
    (other,) = alone.glob("*.json")
    assert other.name != file.name


def test_a_search_polished_from_nearby_ropes_ends_in_the_global_searchs_valley(
    stiff_rope_day, tmp_path, monkeypatch
):
    """Discovery's re-read (the same record, a nearby description): the polish alone,
    started from ropes within the basin (rope 2 1.02 for the truth's 1.04, the others
    0.5 % and 0.3 mm off), ends in the global search's valley, where a stiffer rope 2
    trades against its length offset (1.0295 and 0.79 mm against 1.0378 and 1.32 mm,
    the mismatch 1.5 % higher), the odd rope the same; remembered apart from the global
    search's answer, under its start."""
    monkeypatch.setattr(rope_identification, "_IDENTIFIED", {})
    samples, factors = stiff_rope_day
    means = record_means(samples, samples["time_utc"][0])
    searched = identify_from_means(means, HOIST, alternatives=False)
    near = RopeSprings((1.0, 1.02, 1.005, 0.995), (0.0, 3e-4, -3e-4, 2e-4), 0.0, 0)
    cache = tmp_path / "cache"
    polished = identify_from_means(means, HOIST, cache_dir=cache, alternatives=False, start=near)
    assert polished is not None
    assert polished.mismatch_m < 1.03 * searched.mismatch_m
    assert polished.mismatch_m < 0.1e-3
    ratios = np.array(polished.stiffness_factors) / polished.stiffness_factors[0]
    assert ratios == pytest.approx(np.array(factors), abs=0.015)
    assert int(np.argmax(ratios)) == 1
    # it left its start along the valley, short of the global search's end
    moved = np.subtract(polished.stiffness_factors, near.stiffness_factors)
    assert moved[1] > 0.005
    assert polished.stiffness_factors[1] < searched.stiffness_factors[1] - 0.004
    # another start is another answer's key; the same start reads the file
    assert len(list(cache.glob("*.json"))) == 1
    other = RopeSprings((1.0, 1.03, 1.0, 1.0), (0.0,) * 4, 0.0, 0)
    identify_from_means(means, HOIST, cache_dir=cache, alternatives=False, start=other)
    assert len(list(cache.glob("*.json"))) == 2
    rope_identification._IDENTIFIED.clear()
    again = identify_from_means(means, HOIST, cache_dir=cache, alternatives=False, start=near)
    assert again == polished


def test_a_cached_file_that_does_not_read_is_identified_again(tmp_path, monkeypatch):
    monkeypatch.setattr(rope_identification, "_IDENTIFIED", {})
    means = _means_at_rest()
    assert identify_from_means(means, HOIST, cache_dir=tmp_path) is None  # at rest
    (file,) = tmp_path.glob("*.json")
    assert json.loads(file.read_text()) is None
    file.write_text('{"stiffness_factors": [1.0')  # cut short
    rope_identification._IDENTIFIED.clear()
    assert identify_from_means(means, HOIST, cache_dir=tmp_path) is None
    assert json.loads(file.read_text()) is None  # replaced
    three_ropes = {"stiffness_factors": [1.0, 1.0, 1.0], "length_offsets_m": [0.0, 0.0, 0.0],
                   "mismatch_m": 1e-4, "samples": 100, "alternatives": [], "parts": 0}  # fmt: skip
    four = {**three_ropes, "stiffness_factors": [1.0] * 4, "length_offsets_m": [0.0] * 4}
    part = [[1.0] * 4, [0.0] * 4]
    for bad in (
        three_ropes,  # not this hoist's four ropes
        {**four, "alternatives": [part], "parts": 1},  # a spread needs two parts
        {**four, "alternatives": [part] * 3, "parts": 2},  # more alternatives than parts
        {**four, "alternatives": [part] * 5, "parts": 5},  # more parts than SPLITS
    ):
        file.write_text(json.dumps(bad))
        rope_identification._IDENTIFIED.clear()
        assert identify_from_means(means, HOIST, cache_dir=tmp_path) is None
        assert json.loads(file.read_text()) is None
    assert not list(tmp_path.glob(".*.tmp"))


def test_band_solutions_fit_the_carried_state():
    """One carried state row per solution (transforms.compensation_record): more
    alternatives than the rows hold is an error, not a member silently left out."""
    ropes = ((1.0,) * 4, (0.0,) * 4)
    most = RopeSprings(*ropes, 1e-4, 100, (ropes,) * MAX_ALTERNATIVES)
    solutions = band_solutions(most, 0.1, ringing=True)
    assert len(solutions) == 5 + MAX_ALTERNATIVES + len(RINGING_MEMBERS) <= MAX_SOLUTIONS
    assert solutions[0] == (1.0, 1.0, most, 0.0, 1.0, "estimate")  # the estimate first
    # every member stands for one of the sources the band combines
    assert {m.source for m in solutions[1:]} == set(BAND_SOURCES) - {"stiffness"}
    # ropes no record identified: the prior's six sigma points fill the rows
    prior = band_solutions(prior_rope_springs((1.0,) * 4, 0.05), 0.1, ringing=True)
    assert len(prior) == MAX_SOLUTIONS
    assert {m.source for m in prior[1:]} == set(BAND_SOURCES) - {"ropes"}
    with pytest.raises(ValueError, match="MAX_ALTERNATIVES"):
        band_solutions(RopeSprings(*ropes, 1e-4, 100, (ropes,) * (MAX_ALTERNATIVES + 1)), 0.1)


def test_ringing_drains_the_seals_and_more_ringing_drains_them_further():
    """A ringing member's travel is the estimate's ringing x its factor: until the
    ringing starts it solves as the estimate, bit for bit (the compensation copies it
    there: tests/transforms/test_blocks.py); where the hoist rings at rest, more ringing
    drains the seals further (LuGre's drift takes each seal's friction toward 0)."""
    n = 2000
    p = np.r_[np.linspace(4.0e6, 4.3e6, 500), np.full(n - 500, 4.3e6)]
    springs = RopeSprings((1.0, 1.03, 0.98, 1.01), (0.0, 2e-3, -1e-3, 0.5e-3), 0.0, 0)

    def run(ringing: np.ndarray):
        return stick_slip(
            (p,) * 4, (np.zeros(n),) * 4, np.full(n, DEPTH), np.zeros(n, int), HOIST, springs,
            dt_s=0.01, drift_pressure_pa=p, drift_half_width_pa=5e3, drift_ringing_pa=ringing,
        )  # fmt: skip

    _, estimate = run(np.zeros(n))
    rings = np.where(np.arange(n) >= 1000, 50.0, 0.0)
    _, once = run(rings)
    _, twice = run(rings * max(RINGING_MEMBERS))
    for f_estimate, f_once, f_twice in zip(estimate, once, twice, strict=True):
        assert np.array_equal(f_once[:1000], f_estimate[:1000])
        assert abs(f_estimate[999]) > 100.0  # the ramp left the seal loaded
        assert (np.abs(f_twice[1001:]) < np.abs(f_once[1001:])).all()
        assert (np.abs(f_once[1001:]) < abs(f_estimate[999])).all()


def _worn(deviations_m: tuple[float, ...]):
    """The example hoist with ``groove_wear`` declared and these groove deviations."""
    drum = HOIST.drum.model_copy(update={"groove_radius_deviation_m": list(deviations_m)})
    worn = HOIST.model_copy(update={"drum": drum})
    return worn.with_effects(sorted({*worn.model.effects, "groove_wear"}))


def test_a_worn_groove_is_a_length_offset_that_grows_with_depth():
    """Rope i pays out z (1 + dr_i / R) (physics.rope_spring.groove_payout_m): at a fixed
    depth z a worn groove is the length offset z dr_i / R, the same solution as ropes
    with those offsets and no wear; on the way down the offset grows and the pistons
    take it up (the worn rope's piston draws in, the others let out)."""
    deviations = (0.0, 0.0, 2e-4, -1e-4)
    worn = _worn(deviations)
    n = 600
    p = np.linspace(4.0e6, 4.3e6, n)
    depth = np.full(n, DEPTH)
    args = ((p,) * 4, (np.zeros(n),) * 4, depth, np.zeros(n, int))
    x_worn, f_worn = stick_slip(*args, worn, EQUAL, dt_s=0.01)
    offsets = tuple(DEPTH * d / HOIST.drum.radius_m for d in deviations)
    as_offsets = RopeSprings((1.0,) * 4, offsets, 0.0, 0)
    x_off, f_off = stick_slip(*args, HOIST, as_offsets, dt_s=0.01)
    np.testing.assert_allclose(np.array(f_worn), np.array(f_off), rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.array(x_worn), np.array(x_off), rtol=0, atol=1e-12)
    # undeclared, the same deviations change nothing
    plain = HOIST.model_copy(update={"drum": worn.drum})
    x_plain, _ = stick_slip(*args, plain, EQUAL, dt_s=0.01)
    x_equal, _ = stick_slip(*args, HOIST, EQUAL, dt_s=0.01)
    np.testing.assert_array_equal(np.array(x_plain), np.array(x_equal))
    # 600 m down at a constant load: rope 3's groove pays out 86 mm more; its rope would
    # slacken by k x 86 mm, far beyond what its seal holds: the piston draws in
    down = np.linspace(0.0, 600.0, 6000)
    moving = ((np.full(6000, 4e6),) * 4, (np.zeros(6000),) * 4, down, np.zeros(6000, int))
    x_down, _ = stick_slip(*moving, worn, EQUAL, dt_s=0.01)
    travel = np.array([x[-1] - x[0] for x in x_down])
    assert travel[2] < -0.02
    assert travel[3] > 0.0  # the narrower groove's rope tightens: its piston lets out
    assert travel[2] == min(travel)


def test_the_device_simulations_worn_groove_is_the_one_the_solution_holds():
    """ropeload's device simulation (its own equations: consistency, not accuracy) of a
    hoist whose rope 3 runs in a groove 0.1 mm wider, x logged to a 0.1 mm step: the
    described ropes' stick-slip x matches the logged x best with the deviation as
    declared (0.3 mm RMS over 0.2 s means), ten times better than without the wear; the
    identification, on its finer strides for a worn groove (rope_identification.
    WORN_GROOVE_COARSE_S), finds the ropes alike (the simulation's), and without the
    wear declared finds none (the logged x is then shared out)."""
    from sims.field_day import generate_field_day

    day = generate_field_day(_worn((0.0, 0.0, 1e-4, 0.0)), date="2026-03-02", seed=5,
                             trips=2, hours=0.25)  # fmt: skip
    samples = day.sensors.with_columns(
        (pl.col(f"x{i}_m") / 1e-4).round() * 1e-4 for i in range(1, 5)
    ).sort("time_utc")
    means = record_means(samples, samples["time_utc"][0])
    inputs = (
        tuple(means[f"p{i}_pa"].to_numpy() for i in range(1, 5)),
        tuple(means[f"x{i}_m"].to_numpy() for i in range(1, 5)),
        means["depth_m"].to_numpy(),
        np.zeros(means.height, dtype=np.int64),
    )
    rms = {
        share: float(np.sqrt(stick_slip_mismatch(
            *inputs, _worn((0.0, 0.0, share * 1e-4, 0.0)), np.ones((1, 4)), np.zeros((1, 4)),
            dt_s=0.2, presliding_elements=4,
        )[0]))
        for share in (0.0, 0.8, 1.0, 1.2)
    }  # fmt: skip
    assert min(rms, key=rms.get) == 1.0
    assert rms[1.0] < 0.5e-3
    assert rms[0.0] > 10 * rms[1.0]
    worn = identify_from_means(means, _worn((0.0, 0.0, 1e-4, 0.0)))
    assert worn is not None
    assert worn.stiffness_factors == pytest.approx((1.0,) * 4, abs=0.01)
    assert worn.mismatch_m < 0.1e-3
    assert identify_from_means(means, HOIST) is None


def test_the_members_take_the_friction_laws_uncertainty_the_hoist_states(
    stiff_rope_day, monkeypatch
):
    """On identified ropes the band is the spread of the stick-slip solution's members,
    the law's capacity +-1.96 sigma among them (transforms.stick_slip_band.band_members):
    the members are made with the sigma the description states (on ropes identified
    from the record), a description stating 20 % gives a wider load band than one
    stating 2 %, at every sample where the seals hold friction, and the settings' sigma
    over the description's gives the same band to the last bit as a description
    stating it."""
    samples, _ = stiff_rope_day
    part = samples.head(len(samples) // 4)  # two trips: ropes identified, members run
    made = []

    def recording(springs, sigma, **kwargs):
        made.append((np.isfinite(springs.mismatch_m), sigma))
        return band_solutions(springs, sigma, **kwargs)

    monkeypatch.setattr(compensation_block, "band_solutions", recording)

    def stating(sigma: float):
        friction = HOIST.friction.model_copy(update={"relative_uncertainty": sigma})
        return HOIST.model_copy(update={"friction": friction})

    def band(hoist, sigma=None):
        out = compensate(part, hoist, settings=CompensationSettings(friction_relative_sigma=sigma))
        return (out["load_hi_n"] - out["load_lo_n"]).to_numpy()

    narrow, wide = band(stating(0.02)), band(stating(0.2))
    assert made == [(True, 0.02), (True, 0.2)]  # identified ropes, the stated sigma
    held = np.isfinite(narrow) & np.isfinite(wide)
    assert held.mean() > 0.9
    assert np.all(wide[held] >= narrow[held])
    assert np.median(wide[held] - narrow[held]) > 100.0  # N, of a load band ~1 kN wide
    np.testing.assert_array_equal(band(stating(0.02), sigma=0.2), wide)
