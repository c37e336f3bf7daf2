"""Discovery over a record, re-reading what the replay reads off it once an effect joins.

:func:`discovery.planning.plan_replay` reads the ropes' damping and stiffness spread and
the motion that drives the trips off the record, each chosen by the replay gap of the
first trips (:mod:`discovery.replay_choices`), with the model the hoist declares. When
the model lacks a large effect, those choices are made against the gap it leaves, not
the ropes': on an independent simulator's record whose model lacked the tail ropes'
weight (a 789 kPa gap), the effect was named and added, but the gap stayed at 88 kPa
against 5 kPa of noise, and the next iteration "explained" part of that with a groove
wear the record does not hold.

:func:`discover_in_record` runs one iteration at a time (an :class:`discovery.selection.
EffectSelector` with ``max_iterations=1``); after an iteration that adds an effect it
plans the record again with the grown model and its fitted parameters
(``plan_replay(parameters=...)``), so the ropes and the motion are read anew, and goes
on from that plan when its baseline gap is smaller than the one the effect left (the
added effect's ``gap_after_pa`` is then that gap: the effect with the ropes as the
record shows them), else from the plan before with the grown model: that search goes
on (:meth:`~discovery.selection.EffectSelector.fit_more`), its fitted state and its
candidates' columns reused as the iterations of one search reuse them; a search on the
new plan takes those columns over too (``fit(columns_from=...)``), but for the added
effect's and groove wear's, which it replays. The baselines
are compared before the next iteration runs: only the plan it goes on from is searched. A
new plan that cannot be made or simulated ends the search with a note; the findings so
far stand.
A first search whose two best candidates are a sensor's offset and its gain asks the
whole record's rests, where the four readings differ only by the sensors' errors
(:mod:`discovery.sensor_rests`); when they refute the one it ranked first, or it could
not tell the two apart (``ambiguous``), that one is left out and the search runs again
on the same plan (validation trial_010 with sensor 2 written 20 kPa low: the gain ranked
first by 142 in BIC on the replayed trips, its re-simulation not credited, ``none``;
the rests, the offset). Later iterations keep their answers.
The findings keep their order and numbering. The result's ``before`` is the first
plan's replay and its ``plan`` and ``after`` the last plan's (same trips and samples:
the planning of the trips does not read the model; the ropes' damping and spread and
the motion may differ, so "before" and "after" plots compare the replays as chosen).
The last effect added within ``max_iterations`` is not planned again.

The ropes' stiffnesses and length offsets the compensation identified from the logged x
(``identified_ropes``) were read with the model the hoist declares, whose branch losses
turn the sensors' pressures into the chambers' (contract 1a): a branch the model lacks
biases them. Given ``identify_ropes``, each new plan takes the ropes identified again
with the grown model and its fitted parameters (validation trial_001 hides a 7.77 m,
4.88 mm pipe where the description says 1 m, 6 mm: the ropes read without it are
0.9698 / 1.0285 / 1.0087 / 0.9931 of their mean, with it 0.9639 / 1.0340 / 1.0082 /
0.9939; described with that pipe, its ropes read with it, the record replays to
8.2 kPa, 13.1 kPa as described).

On a new plan whose baseline is closer, the added effect's coordinates, fitted on the
plan before, are refined with the ropes and motion read anew (Gauss-Newton steps,
payloads refitted: :func:`discovery.refit.refine_added`); the finding then reports them
and the gap they leave.

A winner the first search refuses, by its linear fit or by its re-simulation, is judged
on ropes read without it. When the ropes'
identification reads it (:data:`schemas.effects.READ_WITH_THE_ROPES`) and it is
decisive and stable (:func:`discovery.iteration._to_reread`), it is tried with the
record read again (:func:`_tried_reread`): planned at its fitted step and at twice it
while the gap shrinks (a signed term once the other way when its fitted way does not; a
term the description sizes at the description's own value when neither left a gap a
winner is credited with), the best refined, and credited by the rule any winner is
(:func:`discovery.iteration.credited_shrink`) on that plan's gap against the first.
Credited, it is the first finding and the search goes on from that plan; else the
refusal stands with a note.
A runner-up the ropes' identification reads, decisive and a contender on the
resamples (at least :data:`discovery.iteration.CONTENDER_SHARE` of them), is tried the
same way after a winner refused by its linear fit whose own re-read is not credited, or
in its place when the winner is not one the ropes read (validation day 103 with its
throttled valve taken out of the description and its K written as a mine unaware of
the throttling would, the default 500: the valve, the runner-up to a groove wear, read
again 15.2 -> 9.2 kPa at K = 1.7e4; with the stated K = 2e4 kept, its fitted way left
no gap a winner is credited with and the described value did, 15.2 -> 9.3 kPa).
(Validation trial_001, a pipe 2.2 x the noise: refused at 0.9 x the noise explained,
read again 13.1 -> 7.1 kPa; trial_009, a groove 3.8 x: its fit pointed the wrong way,
read again the other way 16.9 -> 14.0 kPa, and each half of it, cut at the middle
(the second starting at the bottom), 14.8 -> 10.9 and 12.7 -> 9.2 kPa, the groove's linear
fit credited and its re-simulation on ropes read without it refused (session 57; with
the replay's blocks counting a groove's payout from where each started, the whole
16.9 -> 12.0 kPa and both halves `none`); on the three records with nothing hidden the
winners tried left 11.3-12.5 kPa of 9.9-12.3, not credited.)
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
from collections.abc import Callable
from typing import Any

import numpy as np
import polars as pl

from discovery.iteration import credited_shrink
from discovery.library import EFFECT_LIBRARY
from discovery.planning import plan_replay
from discovery.refit import refine_added
from discovery.results import (
    AMBIGUOUS,
    DiscoveryResult,
    Finding,
    Params,
    RereadCandidate,
    merge_parameters,
)
from discovery.rope_stiffness import Identified, IdentifiedFactors
from discovery.selection import (
    BASE_PASSES,
    EffectSelector,
    baseline_gap_pa,
    fitted_baseline,
)
from discovery.sensor_rests import sensor_error_at_rest
from schemas.effects import NO_EFFECT
from schemas.hoist import HoistDescription
from sims.effects import parameters_json
from sims.replay_inputs import sensor_gain_offset

__all__ = ["discover_in_record"]


def discover_in_record(
    samples: pl.DataFrame,
    hoist: HoistDescription,
    *,
    max_trips: int = 12,
    max_iterations: int = 3,
    number_from: dt.datetime | None = None,
    identified_ropes: IdentifiedFactors = None,
    identify_ropes: Callable[[HoistDescription, Params], Identified] | None = None,
    **selector: Any,
) -> DiscoveryResult:
    """Discover the effects missing from ``hoist``'s model in the landed ``samples``,
    planning the record again after each effect added (module docstring).

    ``max_trips``, ``number_from`` and ``identified_ropes`` (the ropes as the
    compensation identified them; each plan weighs them against the stiffness spread
    it searches; a function returning them is called by each plan) go to
    :func:`~discovery.planning.plan_replay`, the ``selector`` keywords (``bootstrap``,
    ``detectable_x_noise``, ...) to
    :class:`~discovery.selection.EffectSelector`. ``identify_ropes(hoist, parameters)``:
    the ropes identified with ``hoist``'s ``[model] effects`` and those effects'
    ``parameters``, for the plans made once an effect joined (module docstring; None:
    each plan takes ``identified_ropes``).
    """
    fixed = {"effects", "parameters", "max_iterations", "base"} & set(selector)
    if fixed:
        raise TypeError(f"discover_in_record: {', '.join(sorted(fixed))} cannot be given")
    plan = plan_replay(
        samples,
        hoist,
        max_trips=max_trips,
        number_from=number_from,
        identified_ropes=identified_ropes,
    )
    search = EffectSelector(max_iterations=1, **selector).fit(plan)
    search, told, refuted = _told_at_rest(search, samples, plan, selector)
    first = result = search.result_
    findings = list(result.findings)
    replays, notes = result.replays, list(result.notes) + ([told] if told else [])
    if refuted and findings[-1].effect in SENSOR_PAIR:  # the rests told the pair apart
        findings[-1] = dataclasses.replace(findings[-1], message=f"{told}; {findings[-1].message}")
    replan = functools.partial(
        _planned_with, samples, hoist, identified_ropes, identify_ropes, max_trips,
        number_from, selector,
    )  # fmt: skip
    tried = None
    candidates = findings[-1].reread if identify_ropes is not None else ()
    candidates = tuple(c for c in candidates if c.effect != refuted)  # not what rests refute
    for refused in candidates:
        tried = _tried_reread(search, findings[-1], refused, result, replan, selector)
        notes.append(tried.note)
        if tried.finding is not None:
            break  # the first credited, in the ranking's order
    if tried is not None and tried.finding is not None:
        findings[-1] = tried.finding
        model, params = list(tried.model), tried.params
        result = dataclasses.replace(
            result,
            plan=tried.plan,
            effects_after=tuple(model),
            parameters_after=params,
            after=tried.base,
        )
        if len(findings) < max_iterations:
            try:
                search = EffectSelector(
                    effects=model, parameters=params, max_iterations=1, **selector
                ).fit(tried.plan, tried.base, columns_from=search)
            except (RuntimeError, ValueError) as exc:
                notes.append(f"the search with {', '.join(model)} failed, search ended: {exc}")
                max_iterations = len(findings)
            else:
                result = search.result_
                findings.append(
                    dataclasses.replace(result.findings[-1], iteration=len(findings) + 1)
                )
                replays += result.replays
                notes += result.notes
    while len(findings) < max_iterations and _added(findings[-1].effect):
        model = list(result.effects_after)
        params = {k: dict(v) for k, v in result.parameters_after.items() if k in model}
        try:
            again, base, gap = replan(model, params)
            closer = gap < findings[-1].gap_after_pa
            if closer:  # the added effect's coordinates refined with the ropes read anew
                added = findings[-1].effect
                base, gap, params = refine_added(
                    again, selector.get("library") or EFFECT_LIBRARY, added, model, params, base
                )
        except (RuntimeError, ValueError) as exc:
            notes.append(f"planning again with {', '.join(model)} failed, search ended: {exc}")
            break
        # what the search that goes on (on the plan before) had counted, said and found
        counted, said, found = 0, 0, 0
        try:
            if closer:  # a search on the new plan, the candidates' columns taken over
                search = EffectSelector(
                    effects=model, parameters=params, max_iterations=1, **selector
                ).fit(again, base, columns_from=search)
            else:  # the search goes on from the plan before with its columns
                counted, said = search.result_.replays, len(search.result_.notes)
                found = len(search.result_.findings)
                search.fit_more(1)
        except (RuntimeError, ValueError) as exc:
            notes.append(f"the search with {', '.join(model)} failed, search ended: {exc}")
            break
        if len(search.result_.findings) == found:
            break  # the search had ended (no candidate left)
        if closer:
            findings[-1] = dataclasses.replace(
                findings[-1],
                gap_after_pa=gap,
                parameters=parameters_json(
                    params.get(findings[-1].effect, {}), significant_digits=6
                ),
            )
            notes.append(f"planned again with {', '.join(model)}")
        result = search.result_
        findings.append(dataclasses.replace(result.findings[-1], iteration=len(findings) + 1))
        replays += result.replays - counted
        notes += result.notes[said:]
    return dataclasses.replace(
        result,
        findings=findings,
        effects_before=first.effects_before,
        before=first.before,
        replays=replays,
        notes=notes,
    )


def _added(effect: str) -> bool:
    return effect not in (NO_EFFECT, AMBIGUOUS)


#: The candidates the record's rests tell apart (:mod:`discovery.sensor_rests`).
SENSOR_PAIR = frozenset({"sensor_offset", "sensor_gain"})


def _told_at_rest(
    search: EffectSelector, samples: pl.DataFrame, plan: Any, selector: dict[str, Any]
) -> tuple[EffectSelector, str, str]:
    """A first search whose two best candidates are a sensor's offset and its gain
    (answered ``ambiguous`` between them, or either ranked first) asks the record's rests
    (:func:`discovery.sensor_rests.sensor_error_at_rest`, beyond the sensors' calibration
    the model has). (search, what the rests said, the candidate they refute or ""):
    searched again without the refuted one where that is the one it ranked first or it
    could not tell them apart (the columns and baseline taken over; a search that fails
    leaves the first, with a note), else ``search`` as it is; ("" for what was said
    where the rests were not asked)."""
    last = search.result_.findings[-1]
    ranked = [row["effect"] for row in last.ranking[:2]]
    undecided = last.effect == AMBIGUOUS and frozenset(last.ambiguous_between) == SENSOR_PAIR
    if not undecided and frozenset(ranked) != SENSOR_PAIR:
        return search, "", ""
    model = search.result_.effects_before  # the calibration before anything was added
    params = {k: v for k, v in search.result_.parameters_after.items() if k in model}
    gains, offsets = sensor_gain_offset(plan.hoist, model, params)
    verdict = sensor_error_at_rest(samples, plan.hoist.ropes_n, gains=gains, offsets_pa=offsets)
    if verdict.effect is None:
        return search, verdict.note(), ""
    refuted = next(iter(SENSOR_PAIR - {verdict.effect}))
    if not undecided and verdict.effect == ranked[0]:
        return search, verdict.note(), refuted
    names = selector.get("candidates") or search.library_.get_feature_names()
    kept = [name for name in names if name != refuted]
    told = EffectSelector(max_iterations=1, **{**selector, "candidates": kept})
    try:
        told.fit(plan, search.result_.before, columns_from=search)
    except (RuntimeError, ValueError) as exc:
        return search, f"{verdict.note()}; the search without {refuted} failed: {exc}", ""
    return told, verdict.note(), refuted


#: The multiples of a refused winner's (or a contender's) fitted step (its coordinates
#: from the description's, :class:`~discovery.effect_terms.EffectTerm`) at which
#: :func:`_tried_reread` reads the record again, the second while the first left a
#: smaller gap than the refusal's: ropes read without the effect took part of it, so
#: its linear fit on them falls short of it (validation trial_001: a pipe of 17.75
#: times the described resistance fitted at 8.1 times; read again there the record
#: replays 10.3 kPa, at twice the step 8.2 kPa, against 13.1 kPa).
REREAD_STEPS = (1.0, 2.0)

#: The multiple of the fitted step that is the description's own value: a term the
#: description already sizes (one not null at its defaults,
#: :meth:`~discovery.effect_terms.EffectTerm.null_at_default`: a valve's stated K, a
#: pipe, the oil, a stated groove; a scaled loss only where its described size is not
#: zero) is read there once when its fitted way leaves no gap a winner is credited with.
#: Its fit on ropes read without it can point away from the description's value, which
#: the mine measured: validation day 103 states its throttled valve's K = 2e4 and, with
#: ``local_loss`` taken out of its model, fitted it below that on the ropes read without
#: it; planned with the description whole the record replays 9.4 kPa against 15.2 kPa
#: without it.
DESCRIBED_STEP = (0.0,)


@dataclasses.dataclass
class _Reread:
    """What :func:`_tried_reread` found: the finding (None: not credited), the grown
    model, its parameters, the plan and its fitted baseline, and a note."""

    finding: Finding | None
    model: tuple[str, ...]
    params: Params
    plan: Any
    base: Any
    note: str


def _planned_with(
    samples: pl.DataFrame,
    hoist: HoistDescription,
    identified_ropes: IdentifiedFactors,
    identify_ropes: Callable[[HoistDescription, Params], Identified] | None,
    max_trips: int,
    number_from: dt.datetime | None,
    selector: dict[str, Any],
    model: list[str],
    params: Params,
) -> tuple[Any, Any, float]:
    """(plan, fitted baseline, gap [Pa]) of the record planned again with ``model`` and
    its ``params``, the ropes identified with them (``identify_ropes``; None: the ropes
    ``identified_ropes`` as first read)."""
    grown = hoist.with_effects(sorted(model))
    ropes: IdentifiedFactors = identified_ropes
    if identify_ropes is not None:
        ropes = functools.partial(identify_ropes, grown, params)
    again = plan_replay(
        samples,
        grown,
        max_trips=max_trips,
        number_from=number_from,
        parameters=params,
        identified_ropes=ropes,
    )
    base = fitted_baseline(again, model, params, passes=selector.get("passes", BASE_PASSES))
    return again, base, baseline_gap_pa(again, base)


def _tried_reread(
    search: EffectSelector,
    refusal: Finding,
    refused: RereadCandidate,
    result: DiscoveryResult,
    replan: Callable[[list[str], Params], tuple[Any, Any, float]],
    selector: dict[str, Any],
) -> _Reread:
    """The first search's refused winner, or the contender beside it, ``refused``, added
    with the record read again (``replan``), at :data:`REREAD_STEPS` of its fitted step
    while the gap shrinks (a signed term's, one without ``start_scales``, also the other
    way, once, when its fitted way does not shrink the gap; a term the description sizes
    also at the description's own value, :data:`DESCRIBED_STEP`, when no way before it
    left a gap, before refining, that a winner is credited with; no point twice), the
    best of them its coordinates then refined
    (:func:`~discovery.refit.refine_added`), and credited as any winner by how far the
    gap shrank from the first plan's (:func:`~discovery.iteration.credited_shrink`)."""
    name = refused.effect
    model = [*result.effects_after, name]
    library = selector.get("library") or EFFECT_LIBRARY
    hoist = result.plan.hoist
    term = library.fit(hoist)[name]
    start = term.coordinates(hoist, None)
    fitted = term.coordinates(hoist, refused.parameters)
    before = refusal.gap_before_pa

    def credits(gap: float) -> bool:
        return credited_shrink(
            before, gap, refused.size_x_noise, refusal.noise_pa,
            explain_fraction=search.explain_fraction,
            detectable_x_noise=search.detectable_x_noise,
        )  # fmt: skip

    # each way's multiples, and the best gap (before refining) that makes it needless:
    # a signed term's fit on ropes that took more than all of it can point the wrong
    # way (a groove wear scanned along the differential signature): the other way then,
    # unless the fitted way shrank the gap; a term the description sizes (a scaled one
    # only where the description's size is not zero) at its described value, unless a
    # way before left a gap a winner is credited with
    ways: list[tuple[tuple[float, ...], Callable[[float], bool] | None]] = [(REREAD_STEPS, None)]
    if not term.start_scales:
        ways.append(((-1.0,), lambda gap: gap < before))
    sized = not term.null_at_default(hoist) and not (term.start_scales and not np.any(start))
    if sized:
        ways.append((DESCRIBED_STEP, credits))
    best: tuple[Any, Any, float, Params, float] | None = None
    failed: list[str] = []
    tried: set[tuple[float, ...]] = set()
    for multiples, needless in ways:
        if best is not None and needless is not None and needless(best[2]):
            continue
        for multiple in multiples:
            theta = start + multiple * (fitted - start)
            if tuple(theta) in tried:
                continue  # the fitted step was none: every multiple is the description
            tried.add(tuple(theta))
            params = merge_parameters(refused.parameters, name, term.parameters(hoist, theta))
            params = {k: v for k, v in params.items() if k in model}
            try:
                plan, base, gap = replan(model, params)
            except (RuntimeError, ValueError) as exc:  # no shrink this way
                failed.append(f"at {multiple:g} x its step: {exc}")
                break
            if best is None or gap < best[2]:
                best = (plan, base, gap, params, multiple)
            if not gap < before or best[2] < gap:
                break  # no shrink this way, or less than one step gave
    if best is None:
        return _Reread(None, (), {}, None, None, f"{name} read with the record failed: {failed}")
    plan, base, gap, params, multiple = best
    if gap < before:
        try:
            base, gap, params = refine_added(plan, library, name, model, params, base)
        except (RuntimeError, ValueError) as exc:
            failed.append(f"refining: {exc}")
    credited = credits(gap)
    judged = "refused" if refused.place == 0 else "the runner-up"
    said = (
        f"{name}, {judged} on the ropes read without it, read with the record again "
        + ("at the described value" if multiple == 0.0 else f"at {multiple:g} x its fitted step")
        + f": the gap {before:.0f} -> {gap:.0f} Pa"
        + (f" ({'; '.join(failed)})" if failed else "")
    )
    if not credited:
        return _Reread(None, (), {}, None, None, f"{said}, not what a winner is credited with")
    finding = dataclasses.replace(
        refusal,
        effect=name,
        parameters=parameters_json(params.get(name, {}), significant_digits=6),
        confidence=refused.share,
        gap_after_pa=gap,
        gap_without_effect_pa=before,
        message=f"added {name} with the record read again ({before:.0f} -> {gap:.0f} Pa); "
        + ("" if refused.place == 0 else f"the runner-up to {refusal.ranking[0]['effect']}; ")
        + f"on the ropes read without it, {refusal.message}",
        reread=(),
    )
    return _Reread(finding, tuple(model), params, plan, base, said)
