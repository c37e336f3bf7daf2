"""Synthetic cases for the discovery tests: a field day with one effect the model lacks."""

from __future__ import annotations

from typing import Any

from schemas.hoist import EXAMPLE_HOIST, HoistDescription, load_hoist
from sims.field_day import generate_field_day
from sims.noise import NoiseModel
from sims.replay import ReplayPlan, plan_replay

#: Effects added to the example hoist's data (not in its model) with their truth.
EXTRA: dict[str, dict[str, Any]] = {
    "sensor_offset": {"sensor": 2, "offset_pa": 2.0e4},
    "sensor_gain": {"sensor": 3, "gain": 1.01},
    "groove_wear": {"groove_radius_deviation_m": [0.0, 0.0, 4e-4, 0.0]},
}
#: Effects that need another one (dropped from model and data together).
COUPLED = {"seal_friction": "presliding_hysteresis", "pipe_laminar_loss": "viscosity_temperature"}


def hoist_with(hoist: HoistDescription, effects: list[str]) -> HoistDescription:
    return hoist.model_copy(update={"model": hoist.model.model_copy(update={"effects": effects})})


def hidden_case(
    hidden: str | None, *, trips: int = 2, seed: int = 3, noise: NoiseModel | None = None
) -> tuple[ReplayPlan, dict[str, Any]]:
    """Data with every example-model effect plus ``hidden``; the model omits ``hidden``."""
    base = load_hoist(EXAMPLE_HOIST)
    truth = list(base.model.effects)
    params: dict[str, Any] = {}
    if hidden in EXTRA:
        truth.append(hidden)
        params[hidden] = EXTRA[hidden]
    model = [e for e in base.model.effects if e != hidden]
    if hidden in COUPLED:
        truth.remove(COUPLED[hidden])
        model.remove(COUPLED[hidden])
    day = generate_field_day(
        base,
        date="2026-03-02",
        seed=seed,
        trips=trips,
        hours=trips * 150 / 3600,
        sample_rate_hz=20.0,
        loading_s=5.0,
        rest_after_s=20.0,
        effects=truth,
        parameters=params or None,
        noise=noise,
    )
    plan = plan_replay(day.sensors, hoist_with(base, model), settle_s=20.0)
    return plan, {"truth_effects": truth, "parameters": params, "day": day}
