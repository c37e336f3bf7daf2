"""Evaluate the discovery workflow on many seeded synthetic trials (issue 8).

Not a unit test: a script. Each trial generates a short field day of the example hoist
(:func:`sims.discovery.cases.hidden_case`; the pipe, valve and viscosity effects in the
scenarios with differential branch flow that excite them, see
:mod:`sims.discovery.cases`) with one effect hidden from the model (at
several sensor-noise levels, so the effect's RMS spans ~1-20 x the noise), with no
effect hidden (null trials), or with two hidden (two-effect trials), and runs
:func:`sims.discovery.discover_effects`. Prints the confusion matrix (truth x first
answer), top-1 accuracy where the effect's RMS >= 2 x the noise, the false-alarm rate
on null trials, the median gap reduction (excess over noise) when the right effect was
added, the two-effect recovery rate, and the wall time of one hoist-day analysed
(``--day``).

    .venv/bin/python benchmarks/eval_discovery.py [--seeds 3] [--day]
"""

from __future__ import annotations

import argparse
import time
from collections import Counter, defaultdict

import numpy as np

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.discovery import discover_effects
from sims.discovery.cases import EXTRA, hidden_case
from sims.field_day import generate_field_day
from sims.noise import NoiseModel
from sims.replay import plan_replay

EFFECTS = [
    "tail_rope_weight",
    "conveyance_inertia",
    "seal_friction",
    "presliding_hysteresis",
    "oil_compressibility",
    "sensor_offset",
    "sensor_gain",
    "pipe_laminar_loss",
    "local_loss",
    "viscosity_temperature",
    "groove_wear",
]
NOISE_PA = (5e3, 15e3)
#: Null trials in every scenario: the plain hoist and the one with drum-groove wear.
NULL_SCENARIOS = ("plain", "differential", "orifice")


def trial(hidden: list[str], seed: int, noise_pa: float, scenario: str | None = None):
    """One seeded trial: the scenario that excites the (first) hidden effect
    (:data:`sims.discovery.cases.SCENARIO_FOR`) unless ``scenario`` is given."""
    plan, _ = hidden_case(
        hidden,
        seed=seed,
        # local_loss needs trips at winding speeds that go up and down (4, 10, 4 m/s)
        trips=3 if "local_loss" in hidden else 2,
        noise=NoiseModel(pressure_sigma_pa=noise_pa),
        scenario=scenario,
    )
    return plan, discover_effects(plan, bootstrap=50, max_iterations=2 if len(hidden) > 1 else 1)


def excess(gap: float, noise: float) -> float:
    return float(np.sqrt(max(gap**2 - noise**2, 0.0)))


def hoist_day() -> None:
    base = load_hoist(EXAMPLE_HOIST)
    t0 = time.perf_counter()
    day = generate_field_day(
        base,
        date="2026-03-02",
        seed=11,
        trips=120,
        hours=24.0,
        sample_rate_hz=100.0,
        effects=[*base.model.effects, "sensor_offset"],
        parameters={"sensor_offset": EXTRA["sensor_offset"]},
    )
    t1 = time.perf_counter()
    plan = plan_replay(day.sensors, base)
    result = discover_effects(plan)
    t2 = time.perf_counter()
    f = result.findings[0]
    print(
        f"hoist-day: {day.sensors.height} samples at 100 Hz, 120 trips "
        f"(generated in {t1 - t0:.0f} s); discovery on {len(plan.trips)} trips in "
        f"{t2 - t1:.1f} s -> {[x.effect for x in result.findings]}, gap "
        f"{f.gap_before_pa:.0f} -> {f.gap_after_pa:.0f} Pa "
        f"({'OK' if t2 - t1 < 120 else 'OVER'} the 2-minute target)"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--day", action="store_true", help="also time one hoist-day")
    args = ap.parse_args()
    confusion: dict[str, Counter] = defaultdict(Counter)
    strong_hits = strong_n = 0
    reductions: list[float] = []
    nulls = alarms = 0
    two_hits = two_n = 0
    pair_answers: list[str] = []
    t_start = time.perf_counter()
    for seed in range(args.seeds):
        for noise in NOISE_PA:
            for scenario in NULL_SCENARIOS:
                plan, res = trial([], 100 + seed, noise, scenario)
                nulls += 1
                answer = res.findings[0].effect
                alarms += answer != "none"
                confusion["none"][answer] += 1
            for effect in EFFECTS:
                plan, res = trial([effect], 200 + seed, noise)
                f = res.findings[0]
                confusion[effect][f.effect] += 1
                sigma = plan.noise_sigma_pa
                if excess(f.gap_before_pa, sigma) >= 2 * sigma:
                    strong_n += 1
                    strong_hits += f.effect == effect
                if f.effect == effect:
                    reductions.append(
                        1 - excess(f.gap_after_pa, sigma) / excess(f.gap_before_pa, sigma)
                    )
        for pair in (["tail_rope_weight", "sensor_offset"], ["conveyance_inertia", "sensor_gain"]):
            plan, res = trial(pair, 300 + seed, 5e3)
            two_n += 1
            two_hits += set(res.effects_found) == set(pair)
            pair_answers.append(
                f"  seed {seed}: {' + '.join(pair)} -> " + ", ".join(f.effect for f in res.findings)
            )
    names = ["none", *EFFECTS]
    answers = sorted({a for c in confusion.values() for a in c})
    short = {a: a[:8] for a in answers}
    print("confusion matrix (rows truth, columns first answer)")
    print(f"{'':24s}" + "".join(f"{short[a]:>9s}" for a in answers))
    for t in names:
        print(f"{t:24s}" + "".join(f"{confusion[t][a]:9d}" for a in answers))
    print(
        f"top-1 accuracy where effect RMS >= 2 x noise: {strong_hits}/{strong_n} = "
        f"{strong_hits / max(strong_n, 1):.0%} (target >= 95 %)"
    )
    print(
        f"false alarms on null trials: {alarms}/{nulls} = {alarms / max(nulls, 1):.0%} "
        "(target <= 5 %)"
    )
    print(
        f"median gap reduction (excess over noise) when the right effect was added: "
        f"{np.median(reductions):.0%} (target >= 80 %)"
        if reductions
        else "no hits"
    )
    print(f"two-effect trials, both found: {two_hits}/{two_n}")
    print("\n".join(pair_answers))
    print(f"trials wall time: {time.perf_counter() - t_start:.0f} s")
    if args.day:
        hoist_day()


if __name__ == "__main__":
    main()
