"""Selecting the missing effect: residual test, scoring with re-tuning, BIC + bootstrap.

Problem. Measured sensor pressures y (trips x samples x sensors, scored at
``score_rate_hz``) and the device simulation s(E, theta) of the same trips
(:func:`sims.replay.replay`) with the hoist's model effects E and parameters theta. Is an
effect of contract section 4 missing from E, and which?

Method (one iteration)
----------------------
1. *Nuisance and re-tuning.* The residual r = y - s is fitted by least squares on the
   columns of a design matrix: one common-mode column per trip (the payload, the log's
   free input) and the finite-difference columns ``ds/dphi`` of every coordinate phi of
   the effects already in the model (:mod:`discovery.library`): the calibrated
   parameters may re-adjust. Its residual sum of squares is RSS_0.
2. *Is anything missing?* With the noise variance sigma^2 estimated from the data
   (second differences at standstill,
   :func:`discovery.segmentation.estimate_noise_sigma`), the variance ratio
   ``RSS_0 / (N sigma^2)`` is ~1 when the model is complete (the residual is the
   sensor noise). Below ``variance_threshold`` the answer is ``none``.
   The residual's integrated autocorrelation time tau (whiteness; 1 for white noise)
   is reported and sets the effective sample count ``N_eff = N / tau`` used below.
3. *Scoring.* Every candidate c (an effect not in the model, its requirements in it)
   is switched on at its default parameters (a fixed column Delta_c = s_c - s) and its
   coordinates get finite-difference columns J_c (a term the data may put far from its
   description -- a branch loss, the oil's bulk modulus, the seal friction -- is first
   walked out from its default while each step lowers the gap by more than the noise
   shows, and Delta_c and J_c are taken where the walk ended: ``EffectTerm.start_scales``
   / ``start_shifts``, :meth:`discovery.columns.FitEngine.switch_on_all`); the joint
   least squares of r -
   Delta_c on [re-tuning, J_c, nuisance] gives RSS_c. A candidate is credited only for
   what re-tuning cannot explain: its score is the BIC difference (Schwarz 1978, Ann.
   Stat. 6(2) 461-464)

   .. math:: \\Delta BIC_c = N_{eff} \\ln(RSS_0 / RSS_c) - k_c \\ln N_{eff}

   with k_c its number of coordinates.
4. *Stability.* Trips are resampled with replacement (``bootstrap`` times; Efron 1979)
   and the winner counted per resample from the per-trip normal equations; the
   winner's share is the reported confidence.
5. *Decision.* The best candidate wins when its score is positive, it is credited with
   a share of the residual -- at least ``explain_fraction`` of the excess variance
   ``RSS_0 - N sigma^2``, or, when its fitted sensor change ``Delta_c + J_c delta_c``
   is at least ``detectable_x_noise`` sigma in RMS, an explained RMS
   ``sqrt((RSS_0 - RSS_c) / N)`` of at least
   :data:`discovery.iteration.NOTICEABLE_X_NOISE` (1) sigma -- and it wins at least
   ``stability`` of the resamples, on at least :data:`discovery.iteration.MIN_TRIPS`
   (2) compared trips (one trip cannot be resampled). The second route is for a
   baseline model that is
   not perfect: on a hoist the model was not built with, the replay leaves an excess
   no candidate names (2-6 x the noise in RMS on an independent simulator's records
   with nothing hidden), and a hidden effect 30 x the noise, named first with BIC
   margins of hundreds, explained under half of it. An effect's size is its own sensor
   change, as issue 14 measures it (``rms_over_noise``), and twice the noise is where
   it counts as detectable; what it explains is less, as the per-trip payloads take
   the common part of every change (a seal friction whose fitted change was 5.6 x the
   noise explained 1.9 x). Offsets and gains are sized as they are added, relative to
   their median (:func:`discovery.refit.as_added`): a gain fitted in common, which the
   payloads cannot be told from, has no size. The floor on what a winner explains
   keeps what a baseline that is not perfect leaves from being claimed: the best
   candidates of the validation records with nothing hidden explained 0.3-0.6 x the
   noise (session 28); on the larger gap an added effect leaves, second iterations'
   best explained up to 1.5 x, refused by their size (a local loss's, just under 2 x)
   or by the re-simulated gap (a groove wear's, which left it as it was). When the
   runner-up's RSS is within
   ``ambiguity`` of the best's explained variance and their BIC scores differ by less
   than :data:`discovery.iteration.DECISIVE_DBIC` (10, "very strong" evidence: Kass and
   Raftery 1995), or the resamples split between the two, the answer is ``ambiguous``
   with both names and the excitations that would separate them; resamples that split
   between the best and no effect at all make it ``none`` (contract 5: ``ambiguous``
   names two candidates). (Two candidates can
   explain nearly the same variance of a long record and still be told apart by the
   information criterion: tail-rope weight and groove wear, 5 % apart in RSS, are
   ~4400 apart in BIC on the plain two-trip case.)
6. *Add, refit, re-simulate.* The winner is switched on at its fitted coordinates (and
   the re-tuned parameters updated), the trips re-simulated with payloads re-fitted,
   and the gap (RMS of y - s) before and after reported overall and per region (trip
   phase, direction, shaft position, oil temperature, pressure level, cylinder); beside
   them the gap without the winner at the inputs fitted with it
   (:func:`discovery.refit.gap_without`, ``gap_without_effect_pa``), so that
   ``gap_without^2 - gap_after^2`` is the variance the winner itself accounts for (the
   gap before, the baseline's own fit, lets each trip's payload take the effect's mean
   over the trip: a tail rope's weight of 1.54 MPa in RMS over the trips left 0.85 MPa,
   its spread about each trip's mean). A
   term that is null and strongly nonlinear at its default (groove wear: it starts from
   a scan along the residual's differential signature, ``FitEngine.start``) is then
   fitted along its coordinates with payloads refitted (Brent,
   :func:`discovery.refit._refine_along`)
   while the gap is above the noise and one of its starts (the linear step, the scan's
   start) shrinks it: payloads fitted without it are biased, so the linear step alone
   stops short (where neither start shrinks it, it is refused as it stands). A
   Gauss-Newton step on the winner's coordinates follows when the re-simulated gap is
   more than 10 % above the linear prediction.

The loop repeats while a further effect passes (``max_iterations``); the columns of
candidates are linearisations around the first base and are reused (each costs one
chained replay per coordinate).

Where each step lives
---------------------
:mod:`discovery.columns` (replays and columns, step 1 and 3), :mod:`discovery.layout`
(the flat scored entries), :mod:`discovery.normal_equations` (the per-trip least
squares), :mod:`discovery.ranking` (BIC, ranking; step 3), :mod:`discovery.bootstrap`
(step 4), :mod:`discovery.refit` (step 6), :mod:`discovery.gap` (the regions of the
gap), :mod:`discovery.iteration` (one iteration: the steps in order, the decision of
step 2 and 5). This module holds the loop and its pysindy-like face.

In the shape of a pysindy model (``SINDy`` / its optimizers): :class:`EffectSelector`
takes the library and the hyperparameters, :meth:`EffectSelector.fit` takes the planned
trips and returns the selector, which then holds ``coef_`` (the fitted coordinates of
each selected term), ``support_`` (which library terms the fitted model holds),
``complexity`` (their number of coordinates) and ``findings_`` / ``result_``.
:func:`discover_effects` is the same as a function.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from discovery.bootstrap import trip_weights
from discovery.columns import FitEngine
from discovery.gap import locate_gap, rms
from discovery.iteration import DecisionThresholds, FitState, run_iteration
from discovery.layout import EntryLayout, entry_layout
from discovery.library import EFFECT_LIBRARY, EffectLibrary, term_parameters
from discovery.results import AMBIGUOUS, DiscoveryResult, Finding, Params
from sims.replay import replay_fitted
from sims.replay_plan import ReplayPlan, ReplayResult

__all__ = [
    "AMBIGUOUS",
    "DiscoveryResult",
    "EffectSelector",
    "Finding",
    "ModelDoesNotSimulate",
    "baseline_gap_pa",
    "discover_effects",
    "fitted_baseline",
    "locate_gap",
]

#: Payload / loading-ramp fitting passes of the base replay (:func:`fitted_baseline`).
BASE_PASSES = 3


class EffectSelector:
    """Select the effects missing from a hoist's model (pysindy-like; module docstring).

    Parameters
    ----------
    library : EffectLibrary
        Candidate terms (default :data:`~discovery.library.EFFECT_LIBRARY`).
    effects, parameters
        The model: effect names (default the hoist's ``[model] effects``) and parameter
        overrides ``{effect: {parameter: value}}``.
    candidates : names, optional
        Restrict the candidates (default every library term not in the model).
    max_iterations : int
        Effects added at most.
    bootstrap, seed : int
        Trip resamples for the stability and their random seed.
    variance_threshold : float
        Residual variance / noise variance above which something is missing.
    explain_fraction : float
        Share of the excess variance a winner explains to be credited.
    detectable_x_noise : float
        Or the RMS of its fitted sensor change, in noise sigmas, to be credited when it
        also explains :data:`~discovery.iteration.NOTICEABLE_X_NOISE` sigma (step 5).
    stability : float
        Share of bootstrap resamples the winner must win.
    ambiguity : float
        Runner-up within this share of the winner's explained variance: ambiguous.
    passes : int
        Payload / loading-ramp fitting passes of the base replays.

    Attributes (after :meth:`fit`)
    ------------------------------
    library_ : EffectLibrary
        The library sized to the plan's hoist.
    result_ : DiscoveryResult
        Every iteration and the model they lead to.
    findings_ : list of Finding
        One per iteration (``result_.findings``).
    coef_ : dict of str to numpy.ndarray
        The coordinates (:meth:`~discovery.library.EffectTerm.coordinates`) of every
        selected term at the fitted parameters, in library order.
    support_ : numpy.ndarray of bool
        Which terms of ``library_.get_feature_names()`` the fitted model holds (the
        model's effects and the ones found).
    complexity : int
        The number of coordinates in ``coef_``.
    """

    def __init__(
        self,
        library: EffectLibrary | None = None,
        *,
        effects: Iterable[str] | None = None,
        parameters: Mapping[str, Mapping[str, Any]] | None = None,
        candidates: Iterable[str] | None = None,
        max_iterations: int = 3,
        bootstrap: int = 200,
        seed: int = 0,
        variance_threshold: float = 1.3,
        explain_fraction: float = 0.5,
        detectable_x_noise: float = 2.0,
        stability: float = 0.6,
        ambiguity: float = 0.05,
        passes: int = BASE_PASSES,
    ) -> None:
        self.library = library
        self.effects = effects
        self.parameters = parameters
        self.candidates = candidates
        self.max_iterations = max_iterations
        self.bootstrap = bootstrap
        self.seed = seed
        self.variance_threshold = variance_threshold
        self.explain_fraction = explain_fraction
        self.detectable_x_noise = detectable_x_noise
        self.stability = stability
        self.ambiguity = ambiguity
        self.passes = passes

    # -- the pysindy-like surface ------------------------------------------------------
    def fit(
        self,
        plan: ReplayPlan,
        base: ReplayResult | None = None,
        *,
        columns_from: EffectSelector | None = None,
    ) -> EffectSelector:
        """Run the discovery on the planned trips (:func:`discovery.planning.plan_replay`);
        returns self. ``base``: the plan's :func:`fitted_baseline` with this selector's
        effects, parameters and passes, when the caller has it. Raises ValueError for bad
        hyperparameters, RuntimeError when the hoist's model does not simulate the trips.

        ``columns_from``: a selector fitted on another plan of the same record (planned
        again: the same trips and samples, the ropes and the motion read anew) whose
        candidates' columns are taken over where both base replays score the same
        samples (else every column is replayed anew), instead of replayed again: those
        that simulated, but not of an effect that search added (its column was taken at
        its default, not where it was fitted), one started from a scan of that plan's
        residual (groove wear: its start fits that plan's gap) or a candidate walked out on
        that plan's gap (a term of the model's re-tuning is taken over), which are replayed on
        ``plan``. They are linearisations around that plan's base, used as the later
        iterations of one search use the columns of its first base (module docstring):
        they re-tune the model, score, rank and refuse the candidates and set a
        winner's first coordinates; a winner is added only if its re-simulation on
        ``plan`` shrinks the gap (step 5)."""
        self._check()
        self._state = self._start(plan, base)
        before = getattr(columns_from, "_state", None)
        if before is not None and _same_entries(before.eng.layout, self._state.eng.layout):
            lib = self._state.lib
            # effects added by that search, or since (a winner tried with the record read
            # again, discovery.record_rereading): their columns were taken at the default
            added = (set(before.model) - set(before.first.effects)) | (
                set(self._state.model) - set(before.model)
            )
            self._state.eng.cache.update(
                (name, cols)
                for name, cols in before.eng.cache.items()
                if cols.ok
                and name not in added
                and not lib[name].start_amplitudes
                # a candidate walked out on the other plan's gap (a term of the model is
                # re-tuned where it was fitted: no walk)
                and (name in before.model or not lib[name].walks)
            )
        return self._iterate(self.max_iterations)

    def fit_more(self, iterations: int = 1) -> EffectSelector:
        """Go on for up to ``iterations`` more iterations from where :meth:`fit` (or the
        last call) stopped, with the same plan, engine and candidate columns (the
        iterations of :meth:`fit` share them the same way: linearisations around the
        first base); returns self with ``result_`` holding every iteration so far.
        Nothing is run once an iteration ended the loop (``none``, ``ambiguous``, or
        no candidate left).
        What :func:`discovery.record_rereading.discover_in_record` does when planning
        the record again with an added effect does not bring the gap down."""
        if not hasattr(self, "_state"):
            raise RuntimeError("fit_more: call fit first")
        if iterations < 1:
            raise ValueError("iterations must be at least 1")
        return self if self._ended else self._iterate(iterations)

    def _iterate(self, iterations: int) -> EffectSelector:
        """Up to ``iterations`` iterations on the kept state, then ``result_``; once an
        iteration ends the loop (nothing added, or no candidate left) none follows."""
        fit = self._state
        done = len(fit.findings)
        self._ended = False
        for iteration in range(done + 1, done + iterations + 1):
            if not run_iteration(fit, iteration):
                self._ended = True
                break
        hoist = fit.plan.hoist
        self.library_ = fit.lib
        self.result_ = DiscoveryResult(
            plan=fit.plan,
            findings=list(fit.findings),
            effects_before=tuple(hoist.model.effects if self.effects is None else self.effects),
            effects_after=tuple(fit.model),
            parameters_after={k: dict(v) for k, v in fit.params.items()},
            before=fit.first,
            after=fit.current,
            replays=fit.eng.replays + 0,
            notes=list(fit.notes),
        )
        return self

    @property
    def findings_(self) -> list[Finding]:
        return self.result_.findings

    def get_feature_names(self) -> list[str]:
        """The candidate library's term names (fitted: sized to the hoist)."""
        return self.library_.get_feature_names()

    @property
    def support_(self) -> np.ndarray:
        held = set(self.result_.effects_after)
        return np.array([name in held for name in self.get_feature_names()], dtype=bool)

    @property
    def coef_(self) -> dict[str, np.ndarray]:
        hoist = self.result_.plan.hoist
        params = self.result_.parameters_after
        names = self.get_feature_names()
        return {
            name: self.library_[name].coordinates(hoist, params)
            for name, on in zip(names, self.support_, strict=True)
            if on
        }

    @property
    def complexity(self) -> int:
        """Number of fitted coordinates of the selected terms (pysindy: nonzero
        coefficients)."""
        return int(sum(c.size for c in self.coef_.values()))

    # -- the method, step by step ------------------------------------------------------
    def _check(self) -> None:
        if not 0 < self.explain_fraction <= 1 or not 0 < self.stability <= 1:
            raise ValueError("explain_fraction and stability must be in (0, 1]")
        if not self.detectable_x_noise > 0:
            raise ValueError("detectable_x_noise must be positive")
        if self.variance_threshold <= 1.0:
            raise ValueError("variance_threshold must exceed 1 (the noise alone gives 1)")
        if self.max_iterations < 1 or self.bootstrap < 1:
            raise ValueError("max_iterations and bootstrap must be at least 1")

    def _start(self, plan: ReplayPlan, base: ReplayResult | None) -> FitState:
        """The base replay (payloads and ramps fitted; ``base`` when given), its engine
        and layout."""
        hoist = plan.hoist
        if not any(tr.valid.any() for tr in plan.trips):
            why = "; ".join(f"trip {s.trip_id}: {s.reason}" for s in plan.skipped[:3])
            raise ValueError(
                f"no trip of the record can be compared ({plan.trips_found} found"
                + (f"; {why}" if why else "")
                + "): nothing to discover from"
            )
        lib = (self.library or EFFECT_LIBRARY).fit(hoist)
        model = list(hoist.model.effects if self.effects is None else self.effects)
        params: Params = {k: dict(v) for k, v in (self.parameters or {}).items()}
        allowed = set(lib.get_feature_names() if self.candidates is None else self.candidates)
        if base is None:
            base = fitted_baseline(plan, model, params, passes=self.passes)
        elif base.effects != frozenset(model) or len(base.simulated) != len(plan.trips):
            raise ValueError("base: not the plan's replay with the selector's effects")
        eng = FitEngine(plan, lib, base)
        eng.rebase(base, model, params)
        lay = eng.layout
        m = len(plan.trips)
        nuis = lay.trip_columns(m)
        s0 = lay.flat(base.simulated)
        weights = trip_weights(self.seed, m, self.bootstrap)
        opts = DecisionThresholds(
            self.variance_threshold,
            self.explain_fraction,
            self.detectable_x_noise,
            self.stability,
            self.ambiguity,
        )
        return FitState(opts, plan, lib, eng, allowed, nuis, weights, model, params, base, base, s0)


def _same_entries(a: EntryLayout, b: EntryLayout) -> bool:
    """Both layouts score the same samples of the same trips, in the same order."""
    return (
        np.array_equal(a.y, b.y)
        and len(a.mask) == len(b.mask)
        and all(
            x.shape == y.shape and np.array_equal(x, y) for x, y in zip(a.mask, b.mask, strict=True)
        )
    )


def discover_effects(
    plan: ReplayPlan,
    *,
    effects: Iterable[str] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    library: EffectLibrary | None = None,
    candidates: Iterable[str] | None = None,
    max_iterations: int = 3,
    bootstrap: int = 200,
    seed: int = 0,
    variance_threshold: float = 1.3,
    explain_fraction: float = 0.5,
    detectable_x_noise: float = 2.0,
    stability: float = 0.6,
    ambiguity: float = 0.05,
    passes: int = BASE_PASSES,
    base: ReplayResult | None = None,
) -> DiscoveryResult:
    """Find the effects missing from a hoist's model (module docstring for the method).

    ``EffectSelector(library, ...).fit(plan, base).result_``: the parameters are the
    :class:`EffectSelector`'s; ``plan`` the measured trips
    (:func:`discovery.planning.plan_replay`); ``base`` its :func:`fitted_baseline`
    when the caller has it.
    """
    selector = EffectSelector(
        library,
        effects=effects,
        parameters=parameters,
        candidates=candidates,
        max_iterations=max_iterations,
        bootstrap=bootstrap,
        seed=seed,
        variance_threshold=variance_threshold,
        explain_fraction=explain_fraction,
        detectable_x_noise=detectable_x_noise,
        stability=stability,
        ambiguity=ambiguity,
        passes=passes,
    )
    return selector.fit(plan, base).result_


class ModelDoesNotSimulate(RuntimeError):
    """The hoist's model does not simulate the record's trips (:func:`fitted_baseline`):
    a finding about the record and its description, which ``ropeload discover`` reports
    in one line (exit 1), not a traceback."""


def fitted_baseline(
    plan: ReplayPlan, effects: Iterable[str], parameters: Params, *, passes: int = BASE_PASSES
) -> ReplayResult:
    """The plan's replay with ``effects`` and their ``parameters``, payloads and loading
    ramps fitted (``passes``): where the first iteration of :func:`discover_effects`
    starts. :class:`ModelDoesNotSimulate` (a RuntimeError) when the model does not
    simulate the trips."""
    model = list(effects)
    base = replay_fitted(
        plan, effects=model, parameters=term_parameters(plan.hoist, parameters, model),
        passes=passes,
    )  # fmt: skip
    if not base.ok:
        raise ModelDoesNotSimulate(
            f"the hoist's model does not simulate the measured trips: {base.message}"
        )
    return base


def baseline_gap_pa(plan: ReplayPlan, base: ReplayResult) -> float:
    """RMS gap [Pa] of a :func:`fitted_baseline` over the samples discovery scores: the
    first finding's ``gap_before_pa`` of :func:`discover_effects` from it."""
    layout = entry_layout(plan, base)
    return rms(layout.y - layout.flat(base.simulated))
