"""Step 5's decision (:func:`discovery.iteration._verdict`) on made-up scores and shares.

Contract 5: ``effect`` is ``ambiguous`` only when the data cannot tell two *candidates*
apart, and then ``ambiguous_between`` holds two names of section 4; ``none`` is an
answer, never one of the pair.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from discovery import EFFECT_LIBRARY
from discovery.iteration import DecisionThresholds, _verdict
from schemas.effects import EFFECT_NAMES

N = 400
NOISE_PA = 5000.0


def _state(shares: dict[str, float]):
    """A fit whose best candidate (local loss) explains most of a residual 4x the
    noise variance with a change 6x the noise, the runner-up (pipe loss) far less."""
    opts = DecisionThresholds(
        variance_threshold=1.3,
        explain_fraction=0.5,
        detectable_x_noise=2.0,
        stability=0.6,
        ambiguity=0.05,
    )
    fit = SimpleNamespace(
        opts=opts,
        lib=EFFECT_LIBRARY,
        eng=SimpleNamespace(layout=SimpleNamespace(y=np.zeros(N))),
        plan=SimpleNamespace(noise_sigma_pa=NOISE_PA),
    )
    rss0 = 4.0 * N * NOISE_PA**2
    bl = SimpleNamespace(
        iteration=1, rss0=rss0, ratio=4.0, gap_before=2.0 * NOISE_PA, tau=1.0, where=[]
    )

    def score(rss: float, dbic: float) -> dict:
        cols = SimpleNamespace(
            delta=np.full(N, 6.0 * NOISE_PA), jac=np.zeros((N, 0)), theta0=np.zeros(0)
        )
        return {"rss": rss, "dbic": dbic, "k": 0, "cols": cols, "beta": np.zeros(2)}

    scores = {
        "local_loss": score(1.2 * N * NOISE_PA**2, 300.0),
        "pipe_laminar_loss": score(3.0 * N * NOISE_PA**2, 60.0),
    }
    ranking = [
        {"effect": "local_loss", "score": 300.0},
        {"effect": "pipe_laminar_loss", "score": 60.0},
    ]
    explained = (rss0 - scores["local_loss"]["rss"]) / (rss0 - N * NOISE_PA**2)
    return fit, bl, scores, shares, ranking, explained


def test_a_winner_split_with_nothing_is_none_not_ambiguous_with_none():
    """The trip resamples split between the best candidate and no effect at all (none
    won the rest): the winner is not stable, which is ``none``; it was ``ambiguous``
    with ``ambiguous_between: ["local_loss", "none"]``, a pair that is not two names."""
    finding = _verdict(*_state({"local_loss": 0.55, "pipe_laminar_loss": 0.05, "none": 0.4}))
    assert finding is not None
    if finding.effect == "ambiguous":
        assert set(finding.ambiguous_between) <= set(EFFECT_NAMES), finding.ambiguous_between
    assert finding.effect == "none"
    assert finding.ambiguous_between == ()
    # the confidence that nothing is missing: the share of the resamples the winner lost
    assert finding.confidence == pytest.approx(0.45)
    assert "local_loss" in finding.message


def test_a_winner_split_with_another_candidate_is_ambiguous_between_the_two():
    finding = _verdict(*_state({"local_loss": 0.5, "pipe_laminar_loss": 0.3, "none": 0.2}))
    assert finding is not None
    assert finding.effect == "ambiguous"
    assert finding.ambiguous_between == ("local_loss", "pipe_laminar_loss")
    assert "local_loss" in finding.excitation
    assert "pipe_laminar_loss" in finding.excitation


def test_a_stable_winner_passes():
    assert _verdict(*_state({"local_loss": 0.9, "pipe_laminar_loss": 0.05, "none": 0.05})) is None
