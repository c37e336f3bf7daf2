"""Synthetic discovery cases: field days whose data contain an effect the model lacks.

Used by the discovery tests and by ``benchmarks/eval_discovery.py``. A case is a short
synthetic field day (:func:`sims.field_day.generate_field_day`) of the example hoist
(``schemas/hoists/paper_field_test.toml``) in one of three *scenarios*, with one or
more effects hidden from the hoist's model:

``plain``
    The example hoist as described: full-shaft trips, loading at the stops, oil at
    28-38 degC. All four pistons move together (common mode), so almost no oil flows
    in the branches: the pipe, valve and viscosity effects leave the sensors within the
    noise here. Everything else is seen.
``differential``
    The same hoist with *measured* drum-groove wear in its description and its model
    (radius deviations +0.3 / -0.3 / +0.3 / -0.3 mm): the ropes pay out different
    lengths, so the pistons drift apart during every trip at ~2 mm/s and oil flows
    between the cylinders in proportion to the winding speed (Re ~ 100, laminar). The
    oil warms from 0 to 30 degC over the analysed period (a cold start), so the laminar
    loss, which scales with the viscosity, changes by a factor ~3 between the trips.
    Excites ``pipe_laminar_loss`` and ``viscosity_temperature``.
``orifice``
    The ``differential`` hoist with a damping orifice (about 3 mm in the 10 mm line,
    K ~ 300) between each sensor tee and the manifold, in the description. The branch
    flow follows the winding speed (acceleration, full speed, creep), so the flow
    amplitude spans 0 .. max and the orifice's loss, quadratic in the flow, differs in
    shape from the laminar loss (linear in the flow, and scaled by the temperature).
    The trips alternate between 4 and 10 m/s full speed (:data:`MAX_SPEEDS_M_S`): on
    trips of one speed the branch flow is flat most of a trip and a re-tuned laminar
    loss with its viscosity slope mimics the orifice (the answer is ``none``); at
    different speeds the loss scales with the speed squared, not with the speed, and
    with three or more trips (two speeds, not monotonic in the oil temperature) the
    viscosity slope cannot absorb it. Excites ``local_loss``.

Why a separate scenario for ``local_loss``: with the example hoist's fittings
(K = 1.2 between tee and manifold; the globe valve's K = 9 sits between the chamber
and the tee, where the sensor does not see its drop), the local loss at the
groove-driven branch velocity (~0.3 m/s) is ~50 Pa, a hundredth of the sensor noise:
no trip of a Koepe hoist with equal ropes moves oil fast enough (the branch flow is
bounded by the winding speed x the groove deviation / drum radius, and the deviation by
the cylinder stroke) for the plain fittings' local loss to be seen. That is a finding,
not a defect of the discovery: its answer there is ``none``.

:data:`SCENARIO_FOR` maps each effect to the scenario that excites it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from discovery.planning import plan_replay
from schemas.hoist import EXAMPLE_HOIST, HoistDescription, load_hoist
from sims.field_day import FieldDay, generate_field_day
from sims.noise import NoiseModel
from sims.replay_plan import ReplayPlan

__all__ = [
    "COUPLED",
    "DIFFERENTIAL_GROOVE_M",
    "EXTRA",
    "MAX_SPEEDS_M_S",
    "ORIFICE_LOSS_COEFFICIENT",
    "SCENARIOS",
    "SCENARIO_FOR",
    "hidden_case",
    "scenario_hoist",
]

#: Effects added to the example hoist's data (not in its model) with their truth.
EXTRA: dict[str, dict[str, Any]] = {
    "sensor_offset": {"sensor": 2, "offset_pa": 2.0e4},
    "sensor_gain": {"sensor": 3, "gain": 1.01},
    "groove_wear": {"groove_radius_deviation_m": [0.0, 0.0, 4e-4, 0.0]},
}
#: Effects that need another one (dropped from model and data together).
COUPLED = {"seal_friction": "presliding_hysteresis", "pipe_laminar_loss": "viscosity_temperature"}

#: Measured groove radius deviations of the ``differential`` scenario's drum [m].
DIFFERENTIAL_GROOVE_M = (3e-4, -3e-4, 3e-4, -3e-4)
#: Loss coefficient of the ``orifice`` scenario's damping orifice (tee -> manifold).
ORIFICE_LOSS_COEFFICIENT = 1000.0

SCENARIOS = ("plain", "differential", "orifice")
#: The scenario that excites each effect (``plain`` when not listed).
SCENARIO_FOR: dict[str, str] = {
    "pipe_laminar_loss": "differential",
    "viscosity_temperature": "differential",
    "local_loss": "orifice",
}
#: Full (winding) speeds of the trips per scenario, cycled [m/s] (default the winder's).
#: The orifice's trips run at different speeds: the branch flow scales with the winding
#: speed, so its loss (quadratic in the flow) and the laminar loss (linear) separate;
#: the speeds are not monotonic in time, so the viscosity slope (the oil warms over the
#: period) cannot stand in for the speed dependence.
MAX_SPEEDS_M_S: dict[str, tuple[float, ...]] = {"orifice": (4.0, 10.0)}
#: Oil temperature at the start and end of the period per scenario [degC].
_OIL_TEMP_C = {"plain": (28.0, 38.0), "differential": (0.0, 30.0), "orifice": (0.0, 30.0)}


def scenario_hoist(scenario: str = "plain") -> HoistDescription:
    """The example hoist as the scenario describes it (module docstring)."""
    if scenario not in SCENARIOS:
        raise ValueError(f"scenario: unknown {scenario!r}; valid: {', '.join(SCENARIOS)}")
    base = load_hoist(EXAMPLE_HOIST)
    if scenario == "plain":
        return base
    drum = base.drum.model_copy(update={"groove_radius_deviation_m": list(DIFFERENTIAL_GROOVE_M)})
    update: dict[str, Any] = {"drum": drum}
    if scenario == "orifice":
        update["piping"] = base.piping.model_copy(
            update={"fittings_loss_coefficient_sensor_to_manifold": ORIFICE_LOSS_COEFFICIENT}
        )
    hoist = base.model_copy(update=update)
    return hoist.with_effects([*base.model.effects, "groove_wear"])


def hidden_case(
    hidden: str | Iterable[str] | None,
    *,
    trips: int = 2,
    seed: int = 3,
    noise: NoiseModel | None = None,
    scenario: str | None = None,
    oil_temp_c: tuple[float, float] | None = None,
    max_speeds_m_s: tuple[float, ...] | None = None,
    hidden_parameters: Mapping[str, Mapping[str, Any]] | None = None,
) -> tuple[ReplayPlan, dict[str, Any]]:
    """Data with every model effect of the scenario's hoist plus ``hidden``; the model
    omits ``hidden`` (one name, several, or None for the null case).
    ``hidden_parameters`` (``{effect: {parameter: value}}``) replace :data:`EXTRA`'s
    for the hidden effects it names.

    ``scenario`` defaults to :data:`SCENARIO_FOR` of the (first) hidden effect;
    ``max_speeds_m_s`` (cycled over the trips) to :data:`MAX_SPEEDS_M_S` of the scenario
    (the winder's full speed when not listed). Returns
    the replay plan (the hoist without the hidden effects) and ``{"truth_effects",
    "parameters", "day", "scenario", "hidden"}``.
    """
    names = [] if hidden is None else [hidden] if isinstance(hidden, str) else list(hidden)
    unused = set(hidden_parameters or {}) - {h for h in names if h in EXTRA}
    if unused:
        raise ValueError(
            f"hidden_parameters: {', '.join(sorted(unused))} not a hidden extra effect"
        )
    if scenario is None:
        scenario = next((SCENARIO_FOR[h] for h in names if h in SCENARIO_FOR), "plain")
    base = scenario_hoist(scenario)
    truth = list(base.model.effects)
    model = list(base.model.effects)
    params: dict[str, Any] = {}
    for h in names:
        if h in EXTRA and h not in truth:
            truth.append(h)
            params[h] = dict((hidden_parameters or {}).get(h, EXTRA[h]))
        elif h in model:
            model.remove(h)
        if h in COUPLED and COUPLED[h] in model:
            model.remove(COUPLED[h])
            truth.remove(COUPLED[h])
    if max_speeds_m_s is None:
        max_speeds_m_s = MAX_SPEEDS_M_S.get(scenario)
    # 150 s per trip at the full speed; slower trips get the longer period they need
    period_s = 150.0
    if max_speeds_m_s:
        run = base.shaft.depth_m / base.winder.max_speed_m_s
        period_s += max(base.shaft.depth_m / v - run for v in max_speeds_m_s)
    day: FieldDay = generate_field_day(
        base,
        date="2026-03-02",
        seed=seed,
        trips=trips,
        hours=trips * period_s / 3600,
        sample_rate_hz=20.0,
        loading_s=5.0,
        rest_after_s=20.0,
        effects=truth,
        parameters=params or None,
        noise=noise,
        oil_temp_c=_OIL_TEMP_C[scenario] if oil_temp_c is None else oil_temp_c,
        max_speeds_m_s=max_speeds_m_s,
    )
    plan = plan_replay(day.sensors, base.with_effects(model), settle_s=20.0)
    return plan, {
        "truth_effects": truth,
        "parameters": params,
        "day": day,
        "scenario": scenario,
        "hidden": names,
    }
