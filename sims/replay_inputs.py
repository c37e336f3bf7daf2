"""The inputs of a replayed trip: its winder profile, its payloads, the sensor calibration.

:func:`replay_profile`
    The winder profile of one trip of a :class:`~sims.replay_plan.ReplayPlan`, with its
    loading ramp, times relative to the simulation's start.
:func:`payload_from_pressure`
    The payload the model needs for a static sensor reading (``W = n A p``, the model's
    sensor calibration undone, the conveyance and the hanging tail rope taken off).
:func:`replay_inputs`
    Payloads before and after loading and the loading ramps of every planned trip, the
    defaults of :func:`sims.replay.replay` filled in.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from physics.tension import tail_rope_length_m
from schemas.hoist import G_STANDARD, HoistDescription
from sims.effects import resolve_effects
from sims.replay_plan import ReplayPlan
from sims.trips import TripProfile, trip

__all__ = [
    "payload_from_pressure",
    "replay_inputs",
    "replay_profile",
    "sensor_gain_offset",
    "static_payloads_kg",
]


def replay_profile(
    hoist: HoistDescription,
    d0: float,
    d1: float,
    rest_before_s: float,
    duration_s: float,
    vmax: float | None,
    oil_temp_c: float,
    ramp: tuple[float, float],
    payload_before: float,
    payload_after: float | None = None,
) -> TripProfile:
    """The winder profile of one replayed trip, times relative to the simulation start.

    From ``d0`` to ``d1`` [m] after ``rest_before_s``, lasting ``duration_s`` (a trip the
    record cuts at its end shorter than the profile), at top speed ``vmax`` (None: the
    winder's); the payload changes from ``payload_before`` to ``payload_after`` (default
    unchanged) over the loading ``ramp`` (start, end) [s].
    """
    base = trip(
        hoist,
        start_depth_m=d0,
        end_depth_m=d1,
        rest_before_s=max(rest_before_s, 0.0),
        rest_after_s=0.0,
        max_speed_m_s=vmax,
        oil_temp_c=oil_temp_c,
    )
    rest_after = max(duration_s - base.duration_s, 0.5)
    prof = trip(
        hoist,
        start_depth_m=d0,
        end_depth_m=d1,
        rest_before_s=max(rest_before_s, 0.0),
        rest_after_s=rest_after,
        max_speed_m_s=vmax,
        oil_temp_c=oil_temp_c,
    )
    after = payload_before if payload_after is None else payload_after
    return dataclasses.replace(
        prof,
        # a trip the record cuts at its end is simulated up to the end of the record
        duration_s=min(prof.duration_s, max(duration_s, 1e-3)),
        payload_time_s=np.array([ramp[0], max(ramp[1], ramp[0] + 1e-3)]),
        payload_kg=np.array([payload_before, after]),
    )


def sensor_gain_offset(
    hoist: HoistDescription, effects: Iterable[str], parameters: Mapping[str, Any] | None
) -> tuple[np.ndarray, np.ndarray]:
    """(gains, offsets [Pa]) of the model's sensor calibration per sensor: the
    ``sensor_gain`` / ``sensor_offset`` effects' parameters, or 1 and 0 without them."""
    eff = resolve_effects(hoist, effects, parameters)
    n = hoist.ropes_n
    gain = (
        np.asarray(eff.parameters["sensor_gain"]["gains"], float)
        if eff.on("sensor_gain")
        else np.ones(n)
    )
    off = (
        np.asarray(eff.parameters["sensor_offset"]["offsets_pa"], float)
        if eff.on("sensor_offset")
        else np.zeros(n)
    )
    return gain, off


def payload_from_pressure(
    hoist: HoistDescription,
    effects: Iterable[str],
    parameters: Mapping[str, Any] | None,
    readings_pa: float,
    depth_m: float,
) -> float:
    """Payload [kg] the model needs for the mean sensor reading ``readings_pa`` at rest.

    ``W = n A p`` with ``p = (reading - offset) / gain`` (the model's sensor
    calibration), minus the conveyance and (with ``tail_rope_weight``) the hanging tail
    rope at ``depth_m``; seal friction held at rest is ignored (see
    :func:`sims.replay.replay_fitted`).
    """
    eff = resolve_effects(hoist, effects, parameters)
    gain, off = sensor_gain_offset(hoist, effects, parameters)
    p = (readings_pa - off.mean()) / gain.mean()
    tail = 0.0
    if eff.on("tail_rope_weight"):
        prm = eff.parameters["tail_rope_weight"]
        tail = prm["tail_ropes"] * prm["mass_per_length_kg_m"] * tail_rope_length_m(hoist, depth_m)
    area = hoist.cylinders.bore_area_m2
    return max(p * hoist.ropes_n * area / G_STANDARD - hoist.conveyance.mass_kg - tail, 0.0)


def static_payloads_kg(
    plan: ReplayPlan, effects: Iterable[str], parameters: Mapping[str, Any] | None
) -> np.ndarray:
    """Each trip's payload after and before its loading [kg], (trips, 2), from its levels
    at rest (``p_after_pa``, ``p_before_pa``) where they were read
    (``levels_depth_m``; :func:`payload_from_pressure`)."""
    hoist = plan.hoist
    return np.array(
        [
            [
                payload_from_pressure(hoist, effects, parameters, level, tr.levels_depth_m)
                for level in (tr.p_after_pa, tr.p_before_pa)
            ]
            for tr in plan.trips
        ],
        dtype=float,
    ).reshape(-1, 2)


def replay_inputs(
    plan: ReplayPlan,
    names: frozenset[str],
    prm: dict[str, dict[str, Any]],
    payload_kg: Sequence[float] | np.ndarray | None,
    payload_before_kg: Sequence[float] | np.ndarray | None,
    ramps_s: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(payload after, payload before, loading ramps) per trip, the defaults of
    :func:`sims.replay.replay` filled in: payloads from the static pressures, the plan's ramps."""
    if payload_kg is None or payload_before_kg is None:
        static = static_payloads_kg(plan, names, prm)
        payload_kg = static[:, 0] if payload_kg is None else payload_kg
        payload_before_kg = static[:, 1] if payload_before_kg is None else payload_before_kg
    if ramps_s is None:
        ramps_s = np.array([[tr.ramp_start_s, tr.ramp_end_s] for tr in plan.trips])
    ramps = np.asarray(ramps_s, dtype=float).reshape(-1, 2)
    pay = np.asarray(payload_kg, dtype=float)
    pay_before = np.asarray(payload_before_kg, dtype=float).copy()
    return pay, pay_before, ramps
