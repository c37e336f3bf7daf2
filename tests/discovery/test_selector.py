"""discovery.selection.EffectSelector: the pysindy-like face of :func:`discover_effects`."""

from __future__ import annotations

import numpy as np
import pytest

from discovery import EffectSelector, discover_effects
from discovery.cases import hidden_case


@pytest.fixture(scope="module")
def plan():
    plan, _ = hidden_case("sensor_offset")
    return plan


@pytest.fixture(scope="module")
def fitted(plan):
    selector = EffectSelector(bootstrap=20, max_iterations=1)
    assert selector.fit(plan) is selector
    return selector


def test_fit_gives_findings_coef_support_and_complexity(plan, fitted):
    selector = fitted
    assert [f.effect for f in selector.findings_] == ["sensor_offset"]
    assert selector.findings_ is selector.result_.findings
    names = selector.get_feature_names()
    support = selector.support_
    assert support.dtype == bool
    assert support.shape == (len(names),)
    held = {n for n, on in zip(names, support, strict=True) if on}
    assert held == set(selector.result_.effects_after) & set(names)
    assert "sensor_offset" in held
    assert list(selector.coef_) == [n for n in names if n in held]
    offsets = selector.coef_["sensor_offset"]
    assert offsets.shape == (plan.hoist.ropes_n,)
    assert int(np.argmax(np.abs(offsets))) == 1  # the offset hidden on sensor 2
    assert selector.complexity == sum(c.size for c in selector.coef_.values())


def test_discover_effects_is_the_selector(plan, fitted):
    result = discover_effects(plan, bootstrap=20, max_iterations=1)
    assert result.findings == fitted.findings_
    assert result.effects_after == fitted.result_.effects_after
    assert result.replays == fitted.result_.replays


def test_bad_hyperparameters_raise_at_fit(plan):
    with pytest.raises(ValueError, match="variance_threshold"):
        EffectSelector(variance_threshold=1.0).fit(plan)


def test_fit_more_goes_on_as_one_fit_with_more_iterations(plan):
    once = EffectSelector(bootstrap=20, max_iterations=2).fit(plan)
    stepped = EffectSelector(bootstrap=20, max_iterations=1).fit(plan)
    assert len(stepped.findings_) == 1
    assert stepped.fit_more(1) is stepped
    assert stepped.findings_ == once.findings_
    assert stepped.result_.effects_after == once.result_.effects_after
    assert stepped.result_.replays == once.result_.replays
    with pytest.raises(RuntimeError, match="call fit first"):
        EffectSelector().fit_more(1)


def test_columns_taken_over_from_a_search_on_the_same_samples(plan, fitted):
    taken = EffectSelector(bootstrap=20, max_iterations=1).fit(plan, columns_from=fitted)
    assert taken.findings_ == fitted.findings_
    # the base replays again; every candidate's columns come from ``fitted``
    assert 0 < taken.result_.replays < fitted.result_.replays
