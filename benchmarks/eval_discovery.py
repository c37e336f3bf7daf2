"""Evaluate the discovery workflow on many seeded synthetic trials (issue 8).

Not a unit test: a script. Each trial generates a short field day of the example hoist
(:func:`discovery.cases.hidden_case`; the pipe, valve and viscosity effects in the
scenarios with differential branch flow that excite them, see
:mod:`discovery.cases`) with one effect hidden from the model (at
several sensor-noise levels, so the effect's RMS spans ~1-20 x the noise), with no
effect hidden (null trials), or with two hidden (two-effect trials), and runs
:func:`discovery.discover_effects`. Prints the confusion matrix (truth x first
answer), top-1 accuracy where the effect's RMS >= 2 x the noise, the false-alarm rate
on null trials, the median gap reduction (excess over noise) when the right effect was
added, top-1 split by the hidden effect's own RMS over the noise and the median share of
its variance removed (issue 14's two figures, the effect's RMS as :func:`effect_rms_pa`
measures it), the two-effect recovery rate, and the wall time of one hoist-day analysed
(``--day``).

    .venv/bin/python benchmarks/eval_discovery.py [--seeds 3] [--day]

``--trials [DIR]`` (issue 14) evaluates instead the hidden-effect records of an
independent simulator, ``../shared/validation/trials/`` by default (evaluation data:
nothing in ropeload is, or may be, tuned to them; see its README). ``answers.json`` there
is the key. Each ``trial_NNN/`` goes the way a mine's record goes: ``trial_NNN.csv.gz``
is decompressed into a temporary folder and ingested with its ``hoist.toml``
(:func:`pipelines.ingest.ingest_paths`, as ``ropeload ingest --hoist``) into a data root
of its own (trials share dates), then the whole record is analysed by
:func:`pipelines.discover.discover_period` -- what ``ropeload discover --hoist hoist.toml
--json out.json`` calls -- and the report JSON it wrote (contract 5) is read back. A
crash is caught per trial, counted and named on one line; it never stops the run.
Prints one line per trial, the confusion matrix (hidden x answered effect, with
``none``, ``ambiguous`` and ``crash`` columns), top-1 accuracy by effect size
(``rms_over_noise`` >= 5, 2-5, < 2), false alarms on ``none`` records, the median share
of the hidden effect's variance removed by the added effect, the replay gap on ``none``
records against the noise, seconds per record, and the issue-14 targets.

``--parts N`` cuts each record into N consecutive records of equal row counts
(``record_parts.split_record``), each ingested into its own data root and analysed
alone: exports that start and end wherever the cut falls, mid-trip or mid-stop, more
records of the kind the targets are judged on (shorter, so an effect shows on fewer
trips; the key's ``effect_rms_pa``, by which the variance removed is measured, is the
whole record's).

``--variant NAME`` writes each record as another logger would have
(``record_variants.VARIANTS``: no x, no oil temperature, 10 Hz, pressures on a 10 kPa
step, a frozen sensor, an outage, repeated rows...) before it is ingested; the key is the
record's own (only what was logged changed).

    uv run python benchmarks/eval_discovery.py --trials [DIR] [--only trial_003,...] [--keep DIR]
                                               [--parts N] [--variant NAME]
"""

from __future__ import annotations

import argparse
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
from eval_trials import DEFAULT_TRIALS, EFFECTS, run_trials  # the sibling scripts
from record_variants import VARIANTS

from discovery import discover_effects
from discovery.cases import EXTRA, hidden_case
from discovery.planning import plan_replay
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.field_day import generate_field_day
from sims.noise import NoiseModel
from sims.replay import replay, replay_fitted
from sims.replay_plan import ReplayPlan

NOISE_PA = (5e3, 15e3)
#: Null trials in every scenario: the plain hoist and the one with drum-groove wear.
NULL_SCENARIOS = ("plain", "differential", "orifice")


def trial(hidden: list[str], seed: int, noise_pa: float, scenario: str | None = None):
    """One seeded trial: the scenario that excites the (first) hidden effect
    (:data:`discovery.cases.SCENARIO_FOR`) unless ``scenario`` is given. Returns the
    plan, the result and the case's truth (:func:`discovery.cases.hidden_case`)."""
    plan, info = hidden_case(
        hidden,
        seed=seed,
        # local_loss needs trips at winding speeds that go up and down (4, 10, 4 m/s)
        trips=3 if "local_loss" in hidden else 2,
        noise=NoiseModel(pressure_sigma_pa=noise_pa),
        scenario=scenario,
    )
    result = discover_effects(plan, bootstrap=50, max_iterations=2 if len(hidden) > 1 else 1)
    return plan, result, info


def effect_rms_pa(plan: ReplayPlan, info: dict) -> float:
    """The hidden effect's own sensor change [Pa RMS] over the scored samples, as the
    validation key's ``effect_rms_pa`` measures it: the truth's effects replayed with
    payloads fitted, less the model's effects at those payloads and loading ramps."""
    truth = replay_fitted(plan, effects=info["truth_effects"], parameters=info["parameters"])
    without = replay(
        plan,
        effects=plan.hoist.model.effects,
        payload_kg=truth.payload_kg,
        payload_before_kg=truth.payload_before_kg,
        ramps_s=truth.ramps_s,
    )
    change = np.concatenate(
        [
            (a - b)[tr.valid]
            for tr, a, b in zip(plan.trips, truth.simulated, without.simulated, strict=True)
        ]
    )
    change = change[np.isfinite(change)]
    return float(np.sqrt(np.mean(change**2))) if change.size else float("nan")


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
    ap.add_argument(
        "--trials",
        type=Path,
        nargs="?",
        const=DEFAULT_TRIALS,
        default=None,
        metavar="DIR",
        help=f"evaluate the validation trials in DIR instead (default {DEFAULT_TRIALS})",
    )
    ap.add_argument(
        "--only", default=None, metavar="NAMES", help="with --trials: e.g. trial_003,trial_004"
    )
    ap.add_argument(
        "--keep", type=Path, default=None, metavar="DIR", help="with --trials: work in DIR, keep it"
    )
    ap.add_argument(
        "--parts",
        type=int,
        default=1,
        metavar="N",
        help="with --trials: cut each record into N consecutive records, each analysed alone",
    )
    ap.add_argument(
        "--variant",
        choices=sorted(VARIANTS),
        default="",
        help="with --trials: write each record as another logger would have first",
    )
    args = ap.parse_args()
    if args.trials is None and (args.variant or args.parts != 1 or args.only or args.keep):
        ap.error("--only, --keep, --parts and --variant go with --trials")
    if args.trials is not None:
        only = [n.strip() for n in args.only.split(",") if n.strip()] if args.only else None
        if args.parts < 1:
            ap.error(f"--parts {args.parts}: a whole number >= 1")
        run_trials(args.trials, only, args.keep, args.parts, args.variant)
        return
    seeded(args)


def seeded(args: argparse.Namespace) -> None:
    """The seeded synthetic trials (and ``--day``)."""
    confusion: dict[str, Counter] = defaultdict(Counter)
    strong_hits = strong_n = 0
    reductions: list[float] = []
    removed: list[float] = []
    own_share: list[float] = []
    by_size: dict[str, list[int]] = {"5x": [0, 0], "2-5x": [0, 0], "<2x": [0, 0]}
    nulls = alarms = 0
    two_hits = two_n = 0
    pair_answers: list[str] = []
    t_start = time.perf_counter()
    for seed in range(args.seeds):
        for noise in NOISE_PA:
            for scenario in NULL_SCENARIOS:
                plan, res, _ = trial([], 100 + seed, noise, scenario)
                nulls += 1
                answer = res.findings[0].effect
                alarms += answer != "none"
                confusion["none"][answer] += 1
            for effect in EFFECTS:
                plan, res, info = trial([effect], 200 + seed, noise)
                f = res.findings[0]
                confusion[effect][f.effect] += 1
                sigma = plan.noise_sigma_pa
                size = effect_rms_pa(plan, info)
                band = "5x" if size >= 5 * noise else "2-5x" if size >= 2 * noise else "<2x"
                by_size[band][0] += f.effect == effect
                by_size[band][1] += 1
                if f.effect == effect:
                    removed.append((f.gap_before_pa**2 - f.gap_after_pa**2) / size**2)
                    without = f.gap_without_effect_pa
                    without = f.gap_before_pa if without is None else without
                    own_share.append((without**2 - f.gap_after_pa**2) / size**2)
                if excess(f.gap_before_pa, sigma) >= 2 * sigma:
                    strong_n += 1
                    strong_hits += f.effect == effect
                if f.effect == effect:
                    reductions.append(
                        1 - excess(f.gap_after_pa, sigma) / excess(f.gap_before_pa, sigma)
                    )
        for pair in (["tail_rope_weight", "sensor_offset"], ["conveyance_inertia", "sensor_gain"]):
            plan, res, _ = trial(pair, 300 + seed, 5e3)
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
    print(
        "top-1 by the hidden effect's own RMS over the noise (as the validation key's "
        "rms_over_noise): "
        + ", ".join(f"{k} {h}/{n}" for k, (h, n) in by_size.items())
        + " (targets >= 90 % at >= 5x, >= 70 % at 2-5x)"
    )
    print(
        "median share of the hidden effect's variance removed by the added effect, "
        f"(gap_before^2 - gap_after^2) / effect_rms^2: {np.median(removed):.0%} over "
        f"{len(removed)} named (target >= 80 %); the added effect's own share, "
        f"(gap_without_effect^2 - gap_after^2) / effect_rms^2: {np.median(own_share):.0%}"
        if removed
        else "no hits"
    )
    print(f"two-effect trials, both found: {two_hits}/{two_n}")
    print("\n".join(pair_answers))
    print(f"trials wall time: {time.perf_counter() - t_start:.0f} s")
    if args.day:
        hoist_day()


if __name__ == "__main__":
    main()
