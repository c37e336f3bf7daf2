"""Which refused candidates are tried with the record read again
(:func:`discovery.iteration._to_reread`), on made-up scores and shares.

The winner is tried when the ropes' identification reads it, it is decisive and
stable. The runner-up is tried after it when it is also read by the ropes, decisive,
and won at least ``CONTENDER_SHARE`` of the trip resamples.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from discovery import EFFECT_LIBRARY
from discovery.iteration import CONTENDER_SHARE, DECISIVE_DBIC, DecisionThresholds, _to_reread
from schemas.effects import READ_WITH_THE_ROPES
from schemas.hoist import EXAMPLE_HOIST, load_hoist

N = 200
NOISE_PA = 5000.0


@pytest.fixture(scope="module")
def fitted():
    hoist = load_hoist(EXAMPLE_HOIST)
    lib = EFFECT_LIBRARY.fit(hoist)
    opts = DecisionThresholds(
        variance_threshold=1.3,
        explain_fraction=0.5,
        detectable_x_noise=2.0,
        stability=0.6,
        ambiguity=0.05,
    )
    fit = SimpleNamespace(
        opts=opts, lib=lib, plan=SimpleNamespace(hoist=hoist, noise_sigma_pa=NOISE_PA), params={}
    )
    return fit, SimpleNamespace(retune_cols=[])


def _score(fit, name: str, dbic: float, change_x_noise: float) -> dict:
    """A candidate's linear fit that leaves its coordinates where its columns were taken
    (its fitted change is its column at the start: ``change_x_noise`` sigmas)."""
    theta0 = np.asarray(fit.lib[name].coordinates(fit.plan.hoist, None), dtype=float)
    k = theta0.size
    cols = SimpleNamespace(
        delta=np.full(N, change_x_noise * NOISE_PA), jac=np.zeros((N, k)), theta0=theta0
    )
    return {"rss": 1.0, "dbic": dbic, "k": k, "cols": cols, "beta": np.zeros(k + 3)}


def _tried(fitted, candidates: list[tuple[str, float, float, float]], *, winner_only=False):
    """Names (and sizes) of the candidates tried; ``candidates`` are (name, dbic, share,
    fitted change x noise) in ranking order; ``winner_only``: only the winner's score
    is given (a winner its re-simulation refused)."""
    fit, bl = fitted
    scores = {name: _score(fit, name, dbic, size) for name, dbic, _, size in candidates}
    if winner_only:
        scores = {candidates[0][0]: scores[candidates[0][0]]}
    share = {name: s for name, _, s, _ in candidates}
    ranking = [{"effect": name, "score": dbic} for name, dbic, _, _ in candidates]
    tried = _to_reread(fit, bl, scores, share, ranking)
    names = [row["effect"] for row in ranking]
    assert [r.place for r in tried] == [names.index(r.effect) for r in tried]
    return [(r.effect, round(r.size_x_noise, 6), r.share) for r in tried]


def test_a_contender_beside_the_winner_is_tried_after_it(fitted):
    """Validation day 103 without its throttled valve: groove wear won 64 % of the
    resamples, the valve 36 %; both are read by the ropes and decisive."""
    assert {"groove_wear", "local_loss"} <= READ_WITH_THE_ROPES
    got = _tried(fitted, [("groove_wear", 250.0, 0.64, 2.2), ("local_loss", 160.0, 0.36, 2.5)])
    assert got == [("groove_wear", 2.2, 0.64), ("local_loss", 2.5, 0.36)]


@pytest.mark.parametrize(
    ("runner_up", "why"),
    [
        (("local_loss", 160.0, CONTENDER_SHARE - 0.01, 2.5), "a stray on the resamples"),
        (("local_loss", DECISIVE_DBIC - 1.0, 0.36, 2.5), "not decisive"),
        (("conveyance_inertia", 160.0, 0.36, 2.5), "not read by the ropes"),
    ],
)
def test_a_runner_up_is_tried_only_as_a_decisive_contender_the_ropes_read(fitted, runner_up, why):
    got = _tried(fitted, [("groove_wear", 250.0, 0.60, 2.2), runner_up])
    assert [name for name, *_ in got] == ["groove_wear"], why


def test_a_winner_the_ropes_do_not_read_leaves_the_contender(fitted):
    assert "seal_friction" not in READ_WITH_THE_ROPES
    got = _tried(fitted, [("seal_friction", 250.0, 0.7, 4.0), ("sensor_offset", 40.0, 0.3, 2.1)])
    assert got == [("sensor_offset", 2.1, 0.3)]


def test_a_winner_refused_by_its_re_simulation_is_tried_alone(fitted):
    candidates = [("groove_wear", 250.0, 0.64, 2.2), ("local_loss", 160.0, 0.36, 2.5)]
    assert [n for n, *_ in _tried(fitted, candidates, winner_only=True)] == ["groove_wear"]


@pytest.mark.parametrize(
    "winner", [("groove_wear", 250.0, 0.5, 2.2), ("groove_wear", DECISIVE_DBIC - 1.0, 0.64, 2.2)]
)
def test_a_winner_the_ropes_read_that_is_not_stable_or_decisive_leaves_nothing(fitted, winner):
    """Split resamples (50 / 36 %) or weak evidence: the winner is not tried, and the
    contender is not tried in its place (a split between two is what ``_verdict`` calls
    ambiguous when the winner is credited)."""
    assert _tried(fitted, [winner, ("local_loss", 160.0, 0.36, 2.5)]) == []


def test_the_winners_size_is_the_one_the_verdict_measured(fitted):
    """The verdict stores the winner's fitted change (``size_x_noise``); it is what the
    re-read's credit is judged by, not measured again; the runner-up's is measured."""
    fit, bl = fitted
    scores = {
        "groove_wear": {**_score(fit, "groove_wear", 250.0, 2.2), "size_x_noise": 7.5},
        "local_loss": _score(fit, "local_loss", 160.0, 2.5),
    }
    ranking = [{"effect": "groove_wear", "score": 250.0}, {"effect": "local_loss", "score": 160.0}]
    tried = _to_reread(fit, bl, scores, {"groove_wear": 0.64, "local_loss": 0.36}, ranking)
    assert [(r.effect, r.size_x_noise, r.place) for r in tried] == [
        ("groove_wear", 7.5, 0),
        ("local_loss", pytest.approx(2.5), 1),
    ]
