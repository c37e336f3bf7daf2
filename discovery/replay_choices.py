"""What a replay reads off the record before any effect is tried.

A hoist description leaves out what a mine does not know and the replay needs: how the
head ropes ring (:mod:`discovery.rope_damping`), how their stiffnesses differ
(:mod:`discovery.rope_stiffness`), and whether the winder's profile or the encoder's
logged speed drives the trips closer. Each is chosen by the replay gap of the first
trips (:func:`sims.replay.first_trips_gap`), in this order:

1. the damping, with equal ropes and the logged speed (the winder profile when the
   caller asks for it);
2. the stiffness spread, with that damping (or the ropes' factors as the compensation
   identified them from the logged x, when the caller gives them);
3. the damping again, with the spread (a spread left out inflates every damping
   candidate's gap: on validation day 102 it chose 0.3, with the spread 1.0, and the
   replay gap on 12 trips fell from 15.6 to 9.7 kPa);
4. the motion: the logged speed when it replays the first trips closer than the winder
   profile by 10 %, else the profile. A jerk-limited winder (the validation days) is
   followed by its logged speed, a simulated one with steps in acceleration (ropeload's
   own field days) by its profile: the knots of the logged speed round its corners, and
   ringing ropes answer.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from discovery.rope_damping import with_rope_damping
from discovery.rope_stiffness import (
    IdentifiedFactors,
    with_rope_stiffness,
    with_stiffness_factors,
)
from sims.replay import CLOSER_SHARE, first_trips_gaps
from sims.replay_plan import ReplayPlan

__all__ = ["choose_motion", "read_ropes"]


def read_ropes(
    plan: ReplayPlan,
    zeta_read: float | None,
    slides_m: np.ndarray | None,
    identified: IdentifiedFactors = None,
) -> ReplayPlan:
    """The plan with the ropes' damping and stiffness spread the record supports (steps 1-3
    of the module docstring); ``zeta_read``, ``slides_m`` and ``identified`` as
    :func:`~discovery.rope_damping.with_rope_damping` and
    :func:`~discovery.rope_stiffness.with_rope_stiffness` take them."""
    damped = with_rope_damping(plan, zeta_read)
    spread = with_rope_stiffness(damped, slides_m, identified)
    factors = spread.hoist.ropes.head_rope_stiffness_factors
    if factors is None or factors == plan.hoist.ropes.head_rope_stiffness_factors:
        return spread
    again = with_rope_damping(
        dataclasses.replace(
            plan,
            hoist=with_stiffness_factors(plan.hoist, factors),
            rope_offsets_m=spread.rope_offsets_m,
        ),
        zeta_read,
    )
    return dataclasses.replace(again, notes=(*again.notes, *spread.notes[len(damped.notes) :]))


def choose_motion(logged: ReplayPlan, winder: ReplayPlan) -> ReplayPlan:
    """Of two plans of the same trips, driven by the logged speed and by the winder
    profile, the logged one when its first trips replay closer by 10 %, else the winder
    one (``logged``'s hoist for both), with a note of the two gaps."""
    # the winder plan replays the ropes the logged one read (stiffness, damping, offsets)
    winder = dataclasses.replace(
        winder,
        hoist=logged.hoist,
        rope_bounce=logged.rope_bounce,
        rope_offsets_m=logged.rope_offsets_m,
    )
    if not logged.trips or all(tr.motion_knots is None for tr in logged.trips):
        return dataclasses.replace(winder, notes=logged.notes)
    gaps = first_trips_gaps([(logged, None), (winder, None)])
    closer = gaps[0] < CLOSER_SHARE * gaps[1]
    chosen, name = (logged, "logged speed") if closer else (winder, "winder profile")
    note = (
        f"motion: the {name} drives the trips (replay gap on the first 3 trips: logged "
        f"speed {gaps[0] / 1e3:.1f} kPa, winder profile {gaps[1] / 1e3:.1f} kPa)"
    )
    return dataclasses.replace(chosen, notes=(*logged.notes, note))
