"""discovery.selection.EffectSelector: the pysindy-like face of :func:`discover_effects`."""

from __future__ import annotations

import dataclasses

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
    first = stepped.result_
    assert len(first.findings) == 1
    assert stepped.fit_more(1) is stepped
    assert len(first.findings) == 1  # the earlier result is not grown in place
    assert stepped.findings_ == once.findings_
    assert stepped.result_.effects_after == once.result_.effects_after
    assert stepped.result_.notes == once.result_.notes
    assert stepped.result_.replays == once.result_.replays
    if once.findings_[-1].effect in ("none", "ambiguous"):  # the loop ended: nothing more
        assert stepped.fit_more(1).findings_ == once.findings_
    with pytest.raises(RuntimeError, match="call fit first"):
        EffectSelector().fit_more(1)


def test_columns_are_taken_over_only_from_a_search_on_the_same_samples(plan):
    """A candidate switched on at its default (the oil's viscosity-temperature law, left
    out of the model here) has columns another search on the same samples can take;
    on other samples every column is replayed."""
    fewer = [e for e in plan.hoist.model.effects if e != "viscosity_temperature"]

    def search(trips: slice, columns_from: EffectSelector | None = None) -> EffectSelector:
        part = dataclasses.replace(plan, trips=plan.trips[trips])
        selector = EffectSelector(effects=fewer, bootstrap=20, max_iterations=1)
        return selector.fit(part, columns_from=columns_from)

    first = search(slice(0, 1))
    taken = search(slice(0, 1), columns_from=first)
    assert taken.findings_ == first.findings_
    assert taken.result_.replays < first.result_.replays
    fresh = search(slice(1, 2))
    other = search(slice(1, 2), columns_from=first)  # the other trip: nothing taken
    assert other.result_.replays == fresh.result_.replays
    assert other.findings_ == fresh.findings_
