"""Adding the winner: its fitted coordinates, the refitted replay, the nonlinear fixes.

Step 6 of the method (:mod:`discovery.selection`): the winning term is switched on at
the coordinates of its linear fit (sensor offsets relative to their median, gains to
theirs: the common part is the payload's, :func:`as_added`) and the trips re-simulated
with payloads and ramps refitted (:func:`discovery.columns.replay_refitted`). A term
null and strongly nonlinear at its default (groove wear) is then fitted along its
coordinates with payloads refitted (Brent, :func:`_refine_along`) while the gap is
above the noise and one of its starts shrinks it (where none does, it is refused as it
stands); a Gauss-Newton step on the winner's coordinates follows when the re-simulated
gap is more than 10 % above the linear prediction (:func:`_gauss_newton_step`).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from scipy import optimize

from discovery.columns import FitEngine, TermColumns, replay_refitted
from discovery.gap import rms
from discovery.library import EffectLibrary, EffectTerm, term_parameters
from discovery.normal_equations import normal_equations, solve_normal
from discovery.results import Params, merge_parameters
from schemas.hoist import HoistDescription
from sims.replay import replay, side_by_side
from sims.replay_plan import ReplayPlan, ReplayResult

__all__ = ["add_winner", "as_added", "gap_without", "refine_added", "winner_parameters"]

#: :func:`refine_added` goes on while a step shrinks the refitted gap by more than this
#: share of it.
REFINE_SHRINK = 0.01


def as_added(name: str, theta: np.ndarray) -> np.ndarray:
    """A candidate's fitted coordinates as they are added: sensor offsets relative to
    their median and gains to theirs (the common part is the payload's, which the
    per-trip payloads cannot be told from); other terms' as fitted.

    >>> as_added("sensor_offset", np.array([10.0, 40.0, 10.0, 20.0])).tolist()
    [-5.0, 25.0, -5.0, 5.0]
    """
    if name == "sensor_offset":
        return theta - np.median(theta)
    if name == "sensor_gain":
        return theta / np.median(theta)
    return theta


def winner_parameters(
    lib: EffectLibrary,
    hoist: HoistDescription,
    top: str,
    best: dict[str, Any],
    retune_cols: list[TermColumns],
    params: Params,
) -> tuple[np.ndarray, Params, Params]:
    """(winner's coordinates, parameters with the winner set, what re-tuning moved while
    scoring -- reported, not applied) from the linear fit ``best`` of candidate ``top``."""
    cols: TermColumns = best["cols"]
    k_c = cols.jac.shape[1]
    beta = best["beta"]
    term = lib[top]
    theta = as_added(top, cols.theta0 + beta[:k_c])
    winner_only = merge_parameters(params, top, term.parameters(hoist, theta))
    retuned: Params = {}  # what re-tuning moved while scoring (reported, not applied)
    pos = k_c
    for c in retune_cols:
        kk = c.jac.shape[1]
        t_new = c.theta0 + beta[pos : pos + kk]
        pos += kk
        values = lib[c.name].parameters(hoist, t_new)
        retuned[c.name] = values
    return theta, winner_only, retuned


def add_winner(
    plan: ReplayPlan,
    eng: FitEngine,
    nuis: np.ndarray,
    term: EffectTerm,
    theta: np.ndarray,
    theta0: np.ndarray,
    model: list[str],
    params: Params,
    winner_only: Params,
    current: ReplayResult,
    predicted: float,
    gap_before: float,
) -> tuple[ReplayResult, float, Params]:
    """(replay, gap, parameters) with ``term`` added at ``theta`` to ``model``, refitted;
    ``predicted`` is the gap the linear fit promised, ``gap_before`` the gap of
    ``current`` (without the term)."""
    lay = eng.layout
    new_model = [*model, term.name]
    new_params = winner_only
    after = replay_refitted(plan, eng, new_model, new_params, current)
    gap_after = rms(lay.y - lay.flat(after.simulated)) if after.ok else np.inf
    if term.start_amplitudes and gap_after > 1.1 * plan.noise_sigma_pa:
        after, gap_after, new_params = _refine_along(
            plan, eng, new_model, params, term, [theta, theta0], current, gap_before,
            (gap_after, after, new_params),
        )  # fmt: skip
        if not gap_after < gap_before:  # no start shrinks it: refused as it stands
            return after, gap_after, new_params
    if gap_after > 1.1 * predicted and not term.analytic:
        after, gap_after, new_params = _gauss_newton_step(
            plan, eng, nuis, term, new_model, new_params, after, gap_after, current
        )
    return after, gap_after, new_params


def gap_without(
    plan: ReplayPlan, eng: FitEngine, model: list[str], params: Params, after: ReplayResult
) -> tuple[float, np.ndarray]:
    """(gap [Pa], residual) of ``model`` -- the winner left out -- replayed with the
    inputs fitted with the winner in: ``after``'s payloads, payloads before loading and
    loading ramps, and ``params`` (the retuned and the added term's values; the left-out
    term's are not used); NaN where that replay fails. A finding's
    ``gap_without_effect_pa``: adding the effect is then the only change, so
    ``gap_without^2 - gap_after^2`` is the variance the effect itself accounts for, to
    compare with the hidden effect's own (issue 14's ``effect_rms_pa``). The finding's
    ``gap_before_pa`` stays the model's own fit before the effect (contract 5: what the
    model achieved), whose payloads take the effect's mean over each trip (a tail
    rope's weight, 1.54 MPa in RMS over the trips, left 0.85 MPa)."""
    eng.count_replays(1)
    lay = eng.layout
    without = replay(
        plan,
        effects=model,
        parameters=term_parameters(plan.hoist, params, model),
        payload_kg=after.payload_kg,
        payload_before_kg=after.payload_before_kg,
        ramps_s=after.ramps_s,
    )
    residual = lay.y - lay.flat(without.simulated)
    return (rms(residual) if without.ok else float("nan")), residual


def refine_added(
    plan: ReplayPlan,
    library: EffectLibrary,
    name: str,
    model: list[str],
    params: Params,
    base: ReplayResult,
    *,
    steps: int = 3,
) -> tuple[ReplayResult, float, Params]:
    """(replay, gap, parameters) with the coordinates of ``name`` (an effect of ``model``
    at ``params``, ``base`` their :func:`~discovery.selection.fitted_baseline` on
    ``plan``) refined by up to ``steps`` Gauss-Newton steps, payloads and ramps refitted
    at each (:func:`_gauss_newton_step`), while each shrinks the gap by more than
    :data:`REFINE_SHRINK` of it; a sensor term (analytic columns) is returned as given.

    The record planned again once an effect joined (:mod:`discovery.record_rereading`)
    reads the ropes and the motion with it: the effect's coordinates were fitted on the
    plan before, whose ropes had taken part of it, and are refined on the new one. On
    the validation trials it moves the fit part of the way: trial_005 hides an oil of
    0.636 GPa, fitted at 0.381 GPa (20.0 kPa), refined to 0.450 GPa (19.0 kPa), where
    the hoist described with 0.636 GPa replays to 12.8 kPa; trial_000 hides tail ropes of
    6.307 kg/m, fitted at 6.224 kg/m (18.3 kPa), refined to 6.272 kg/m (17.3 kPa), 10.3
    kPa described with 6.307 kg/m. The ropes stay those read at the first fit."""
    fitted = library.fit(plan.hoist)
    term = fitted[name]
    eng = FitEngine(plan, fitted, base)
    eng.rebase(base, model, params)
    lay = eng.layout
    gap = rms(lay.y - lay.flat(base.simulated))
    if term.analytic:
        return base, gap, params
    nuis = lay.trip_columns(len(plan.trips))
    current = base
    for _ in range(steps):
        after, gap_after, new_params = _gauss_newton_step(
            plan, eng, nuis, term, model, params, current, gap, current
        )
        if not gap_after < (1.0 - REFINE_SHRINK) * gap:
            break
        current, gap, params = after, gap_after, new_params
    return current, gap, params


def _gauss_newton_step(
    plan: ReplayPlan,
    eng: FitEngine,
    nuis: np.ndarray,
    term: EffectTerm,
    new_model: list[str],
    new_params: Params,
    after: ReplayResult,
    gap_after: float,
    current: ReplayResult,
) -> tuple[ReplayResult, float, Params]:
    """A Gauss-Newton step on the winner's coordinates at the refitted point, kept when
    it shrinks the refitted gap."""
    lay = eng.layout
    m = nuis.shape[1]
    eng.rebase(after, new_model, new_params)
    s_new = lay.flat(after.simulated)
    g_cols = eng.fd(term, new_model, new_params, s_new)
    if g_cols.ok:
        xg = np.column_stack([g_cols.jac, nuis])
        _, bg = solve_normal(normal_equations(xg, lay.y - s_new, lay.trip, m), np.ones(m))
        th2 = g_cols.theta0 + bg[: g_cols.jac.shape[1]]
        p2 = merge_parameters(new_params, term.name, term.parameters(plan.hoist, th2))
        alt = replay_refitted(plan, eng, new_model, p2, current)
        gap_alt = rms(lay.y - lay.flat(alt.simulated)) if alt.ok else np.inf
        if gap_alt < gap_after:
            after, gap_after, new_params = alt, gap_alt, p2
    return after, gap_after, new_params


def _refine_along(
    plan: ReplayPlan,
    eng: FitEngine,
    effects: list[str],
    params: Params,
    term: EffectTerm,
    starts: list[np.ndarray],
    current: ReplayResult,
    gap_before: float,
    at_first: tuple[float, ReplayResult, Params],
    *,
    evaluations: int = 8,
) -> tuple[ReplayResult, float, Params]:
    """Refitted gap minimised along the coordinates of a strongly nonlinear term.

    A linear step from the scan's start (``term.start_amplitudes``) can land on the far
    side of a kink in the response (seal friction flipping as the pistons drift apart)
    and the payloads fitted without the term are biased; so the gap with payloads and
    ramps refitted (:func:`replay_refitted`) is minimised over the scale ``c`` of the better of
    ``starts`` (Brent's bounded method on ``0.5 <= c <= 1.5``). Returns the best replay,
    its gap and parameters; ``at_first`` is (gap, replay, parameters) at the first start,
    already replayed. Where neither start brings the refitted gap below ``gap_before``
    (the replay without the term) the search is not run, nor the Gauss-Newton step
    after it (:func:`add_winner`): a term the refit cannot make explain anything at its
    fitted size is refused as it stands (on an independent simulator's record a groove
    wear credited by the linear scoring left a 14.1 kPa gap at 14.1 kPa, after eight
    more replays of 4-5 s).
    """
    lay = eng.layout
    seen: dict[float, tuple[float, ReplayResult, Params]] = {}

    def at(theta: np.ndarray) -> tuple[float, ReplayResult, Params]:
        prm = merge_parameters(params, term.name, term.parameters(plan.hoist, theta))
        res = replay_refitted(plan, eng, effects, prm, current)
        gap = rms(lay.y - lay.flat(res.simulated)) if res.ok else np.inf
        return gap, res, prm

    rest = [functools.partial(at, np.asarray(t, float)) for t in starts[1:]]
    # one start left: its replays take the cores themselves (side_by_side runs a call's
    # replays one block after the other, for calls that share the cores)
    first = [at_first, *(side_by_side(rest) if len(rest) > 1 else [call() for call in rest])]
    k = int(np.argmin([f[0] for f in first]))
    direction = np.asarray(starts[k], float)
    seen[1.0] = first[k]
    if not first[k][0] < gap_before:
        gap, res, prm = first[k]
        return res, gap, prm

    def gap_of(c: float) -> float:
        if c not in seen:
            seen[c] = at(c * direction)
        return seen[c][0]

    optimize.minimize_scalar(
        gap_of, bounds=(0.5, 1.5), method="bounded", options={"maxiter": evaluations}
    )
    gap, res, prm = seen[min(seen, key=lambda c: seen[c][0])]
    return res, gap, prm
