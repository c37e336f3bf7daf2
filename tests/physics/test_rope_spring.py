"""A piston between its rope spring and a seal of Maxwell-slip elements
(physics.rope_spring.elements_on_rope_step) and the elements' virgin state
(physics.maxwell_slip.maxwell_slip_virgin).

The answers: the force balance the step must solve (the elements' force after the
step, by physics.maxwell_slip.maxwell_slip_step, plus K dx equals the demand), its
derivative by finite differences, the one-element case's closed form
(physics.rope_spring.seal_on_rope_step, whose doctest holds its numbers) and the
virgin curve reached by a monotone motion from rest.
"""

from __future__ import annotations

import numpy as np
import pytest

from physics.maxwell_slip import maxwell_slip_elements, maxwell_slip_step, maxwell_slip_virgin
from physics.rope_spring import elements_on_rope_step, seal_on_rope_step


def _draw(rng: np.random.Generator, elements: int):
    """Elements, their deflections (some beyond a capacity that has fallen since),
    rope stiffness, capacity and demand, of the example hoist's order of magnitude."""
    stiffness = rng.uniform(1e6, 3e7, elements)
    weights = rng.dirichlet(np.ones(elements))
    capacity = rng.uniform(0.0, 2000.0)
    limits = weights * capacity / stiffness
    deltas = rng.uniform(-1.3, 1.3, elements) * limits
    return stiffness, weights, deltas, rng.uniform(1e4, 1e6), capacity, rng.uniform(-5e3, 5e3)


@pytest.mark.parametrize("elements", [1, 2, 4, 7])
def test_the_step_balances_the_demand(elements):
    rng = np.random.default_rng(17 + elements)
    checked = 0
    for _ in range(500):
        stiffness, weights, deltas, rope, capacity, demand = _draw(rng, elements)
        limits = weights * capacity / stiffness
        dx, slope, _, _ = elements_on_rope_step(demand, deltas, stiffness, limits, rope)
        after = deltas.copy()
        force = maxwell_slip_step(after, dx, stiffness, weights, capacity)
        assert force + rope * dx == pytest.approx(demand, abs=1e-9 * max(1.0, abs(demand)))
        assert abs(force) <= capacity * (1 + 1e-12)
        # d dx / d demand, where a small change of the demand stays on one segment
        h = 1e-3
        up = elements_on_rope_step(demand + h, deltas, stiffness, limits, rope)[0]
        down = elements_on_rope_step(demand - h, deltas, stiffness, limits, rope)[0]
        if abs((up - dx) - (dx - down)) < 1e-6 * abs(up - down):
            assert slope == pytest.approx((up - down) / (2 * h), rel=1e-5)
            checked += 1
    assert checked > 400


def test_one_element_is_the_elasto_plastic_seal():
    rng = np.random.default_rng(3)
    for _ in range(1000):
        stiffness, _, deltas, rope, capacity, demand = _draw(rng, 1)
        friction = stiffness[0] * deltas[0]
        dx, friction_after, slope, _, _ = seal_on_rope_step(
            demand, friction, stiffness[0], rope, capacity
        )
        dx_e, slope_e, _, _ = elements_on_rope_step(
            demand, deltas, stiffness, capacity / stiffness, rope
        )
        assert dx_e == pytest.approx(dx, rel=1e-9, abs=1e-15)
        assert slope_e == pytest.approx(slope, rel=1e-9)
        force = maxwell_slip_step(deltas, dx_e, stiffness, np.ones(1), capacity)
        assert force == pytest.approx(friction_after, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("force", [-1500.0, -300.0, 0.0, 700.0, 1999.0, 2600.0])
def test_the_virgin_state_is_a_monotone_motion_from_rest(force):
    stiffness, weights = maxwell_slip_elements(4, 2.5e7)
    capacity = 2000.0
    deltas = np.zeros(4)
    held = maxwell_slip_virgin(force, deltas, stiffness, weights, capacity)
    assert held == pytest.approx(np.clip(force, -capacity, capacity), rel=1e-12, abs=1e-9)
    # the same elements moved from rest by the same u, one step at a time
    u = deltas[np.argmax(weights * capacity / stiffness)]
    moved = np.zeros(4)
    for step in np.full(100, u / 100):
        maxwell_slip_step(moved, step, stiffness, weights, capacity)
    assert moved == pytest.approx(deltas, rel=1e-9, abs=1e-15)


@pytest.mark.parametrize("elements", [1, 2, 4])
def test_the_step_is_linear_on_its_piece_and_bends_at_its_ends(elements):
    """Within [lo, hi] the step follows its slope (the balance by maxwell_slip_step
    holds there); just beyond a finite end the slope differs (the piece ends where an
    element or the seal changes between sticking and slipping)."""
    rng = np.random.default_rng(41 + elements)
    bent = 0
    for _ in range(300):
        stiffness, weights, deltas, rope, capacity, demand = _draw(rng, elements)
        limits = weights * capacity / stiffness
        dx, slope, lo, hi = elements_on_rope_step(demand, deltas, stiffness, limits, rope)
        assert lo <= demand <= hi
        if elements == 1:
            one = seal_on_rope_step(demand, stiffness[0] * deltas[0], stiffness[0], rope, capacity)
            if abs(deltas[0]) < limits[0]:  # the bristle within its capacity: the same
                assert one[3:] == pytest.approx((lo, hi), rel=1e-9, abs=1e-9)
        for end in (lo, hi):
            if not np.isfinite(end):
                continue
            inside = demand + 0.999 * (end - demand)
            moved = elements_on_rope_step(inside, deltas, stiffness, limits, rope)[0]
            assert moved == pytest.approx(dx + slope * (inside - demand), rel=1e-9, abs=1e-15)
            after = deltas.copy()
            force = maxwell_slip_step(after, moved, stiffness, weights, capacity)
            assert force + rope * moved == pytest.approx(inside, abs=1e-9 * max(1.0, abs(inside)))
            beyond = end + 0.05 * (end - demand) + np.sign(end - demand) * 1.0
            past = elements_on_rope_step(beyond, deltas, stiffness, limits, rope)[0]
            if abs(past - (dx + slope * (beyond - demand))) > 1e-9 * abs(past - dx):
                bent += 1
    assert bent > 100
