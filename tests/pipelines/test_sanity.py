"""pipelines.sanity: per-trip simulated-vs-measured check against known truth."""

from __future__ import annotations

import pytest

from pipelines.sanity import sanity_check
from schemas.tables import SANITY_CHECKS
from sims.discovery.cases import hidden_case


def test_complete_model_passes_and_missing_effect_fails():
    plan_ok, info = hidden_case(None)
    sensors = info["day"].sensors
    good = sanity_check(sensors, plan_ok.hoist, run_id="r1", settle_s=20.0)
    assert good.columns == SANITY_CHECKS.names
    assert good.height == 1  # two trips; the first only warms up the friction state
    assert good["passed"].all()
    assert (good["rms_gap_pa"] / good["noise_pa"]).max() < 1.2
    lacking = plan_ok.hoist.model_copy(
        update={
            "model": plan_ok.hoist.model.model_copy(
                update={
                    "effects": [e for e in plan_ok.hoist.model.effects if e != "conveyance_inertia"]
                }
            )
        }
    )
    bad = sanity_check(sensors, lacking, run_id="r2", settle_s=20.0)
    assert bad.height == 1
    assert not bad["passed"].any()
    assert bad["message"][0].startswith(("down", "up"))


def test_threshold_validated():
    plan, info = hidden_case(None, trips=1)
    with pytest.raises(ValueError, match="threshold"):
        sanity_check(info["day"].sensors, plan.hoist, run_id="r", threshold=1.0)


def test_trips_before_report_from_only_warm_up():
    plan, info = hidden_case(None)
    sensors = info["day"].sensors
    everything = sanity_check(sensors, plan.hoist, run_id="r", settle_s=20.0)
    late = sanity_check(
        sensors,
        plan.hoist,
        run_id="r",
        settle_s=20.0,
        report_from=sensors["time_utc"].max(),
    )
    assert everything.height == 1
    assert late.height == 0
