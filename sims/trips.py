"""Hoist trip profiles: the input of the device simulation.

A :class:`TripProfile` is the conveyance's commanded motion as constant-acceleration
segments (depth, speed, acceleration piecewise; speed positive downwards, as in the
field logs), plus the payload as a piecewise-linear function of time and the oil
temperature. :func:`trip` builds one trip the way a Koepe winder runs it:

    rest -> accelerate -> run at max speed -> decelerate to creep speed -> creep over
    the creep distance -> stop (at the deceleration) -> rest

with the winder's ``[winder]`` limits (a short trip that never reaches full speed gets
a triangular profile). :func:`day_schedule` strings trips into a working day with
loading and unloading at the stops, and :func:`hold` is a conveyance at rest (load
changes only), for static checks. :func:`fit_cut_trip` completes a trip a record cuts
(logging starts or stops while the conveyance moves): the winder trip whose motion best
matches the logged encoder depth, with the unseen end (or start) depth fitted.

The profile and the single trip live in :mod:`sims.trip_profile`, the fit of cut trips
in :mod:`sims.trip_fit`; this module is their public face and builds the day.
"""

from __future__ import annotations

import numpy as np

from schemas.hoist import HoistDescription
from sims.trip_fit import CutTripFit, fit_cut_trip
from sims.trip_profile import TripProfile, hold, trip

__all__ = ["CutTripFit", "TripProfile", "day_schedule", "fit_cut_trip", "hold", "trip"]


def day_schedule(
    hoist: HoistDescription,
    *,
    round_trips: int = 20,
    start_time_s: float = 6 * 3600.0,
    dwell_s: float = 60.0,
    loading_s: float = 20.0,
    payload_kg: float | None = None,
    loaded_at: str = "bottom",
    oil_temp_c: float | tuple[float, float] | None = None,
) -> list[TripProfile]:
    """A working day: ``round_trips`` x (down trip, up trip) between pithead and bottom.

    Each trip profile starts with the conveyance at rest; the load change at a stop is
    part of the trip that leaves it (``loading_s`` ramp at the start). With
    ``loaded_at="bottom"`` (ore hoisting) the up trip leaves loaded and the down trip
    empty; ``"pithead"`` the reverse. ``oil_temp_c`` is one value or a (morning,
    afternoon) pair warmed linearly over the day. ``start_time_s`` of each profile is its
    start on the day's clock.
    """
    if round_trips < 1:
        raise ValueError("round_trips must be at least 1")
    if loaded_at not in ("bottom", "pithead"):
        raise ValueError("loaded_at must be 'bottom' or 'pithead'")
    payload = hoist.conveyance.rated_payload_kg if payload_kg is None else payload_kg
    top = hoist.shaft.positions_m.get("pithead", 0.0)
    bottom = hoist.shaft.positions_m.get("bottom", hoist.shaft.depth_m)
    trips_out: list[TripProfile] = []
    clock = start_time_s
    n = 2 * round_trips
    for k in range(n):
        down = k % 2 == 0
        loaded = (not down) if loaded_at == "bottom" else down
        before = 0.0 if loaded else payload  # the load at the previous stop
        after = payload if loaded else 0.0
        if isinstance(oil_temp_c, tuple):
            temp = oil_temp_c[0] + (oil_temp_c[1] - oil_temp_c[0]) * k / max(n - 1, 1)
        else:
            temp = oil_temp_c
        base = trip(
            hoist,
            start_depth_m=top if down else bottom,
            end_depth_m=bottom if down else top,
            rest_before_s=loading_s + 5.0,
            rest_after_s=dwell_s,
            oil_temp_c=temp,
            start_time_s=clock,
        )
        profile = TripProfile(
            segment_start_s=base.segment_start_s,
            segment_depth_m=base.segment_depth_m,
            segment_speed_m_s=base.segment_speed_m_s,
            segment_acceleration_m_s2=base.segment_acceleration_m_s2,
            duration_s=base.duration_s,
            payload_time_s=np.array([0.0, loading_s]),
            payload_kg=np.array([before, after]),
            oil_temp_c=temp,
            start_time_s=clock,
            direction=base.direction,
        )
        trips_out.append(profile)
        clock += profile.duration_s
    return trips_out
