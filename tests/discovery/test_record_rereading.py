"""discovery.record_rereading: the record planned again once an effect joins the model."""

from __future__ import annotations

import pytest

from discovery import discover_effects, discover_in_record, plan_replay
from discovery.cases import hidden_case


@pytest.mark.slow
def test_the_record_is_planned_again_with_the_effect_added():
    """Sims data hiding the tail ropes' weight (0.85 MPa of gap): named, then the record
    planned again with it at its fitted parameters (the ropes and motion read anew), and
    the next iteration starts from that plan's gap, which is the added effect's gap
    after -- not above what the same trips left without the new plan."""
    plan, info = hidden_case("tail_rope_weight")
    samples = info["day"].sensors
    result = discover_in_record(samples, plan.hoist, max_iterations=2, bootstrap=50)
    first, second = result.findings
    assert (first.iteration, first.effect) == (1, "tail_rope_weight")
    assert second.iteration == 2
    assert "tail_rope_weight" in result.plan.hoist.model.effects
    fitted = result.plan.parameters["tail_rope_weight"]
    assert fitted["mass_per_length_kg_m"] == pytest.approx(
        first.parameters["mass_per_length_kg_m"], rel=1e-5
    )
    assert second.gap_before_pa == first.gap_after_pa
    assert first.gap_after_pa < 0.05 * first.gap_before_pa
    alone = discover_effects(plan_replay(samples, plan.hoist), max_iterations=1, bootstrap=50)
    assert alone.findings[0].effect == "tail_rope_weight"
    assert first.gap_after_pa <= alone.findings[0].gap_after_pa + 1.0
