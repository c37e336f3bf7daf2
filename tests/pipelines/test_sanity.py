"""pipelines.sanity: per-trip simulated-vs-measured check against known truth."""

from __future__ import annotations

import datetime as dt

import polars as pl
import pytest

from discovery.cases import hidden_case
from physics.trip_rule import STANDSTILL_SPEED_M_S
from pipelines.sanity import (
    NO_SPEED_WORDS,
    PART_SPEED_WORDS,
    WARM_UP_WORDS,
    sanity_check,
    sanity_step,
)
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from schemas.tables import SANITY_CHECKS
from sims.field_day import generate_field_day
from transforms.compensation import compensate
from transforms.reconciliation import reconcile


def test_complete_model_passes_and_missing_effect_fails():
    plan_ok, info = hidden_case(None)
    sensors = info["day"].sensors
    good = sanity_check(sensors, plan_ok.hoist, run_id="r1", settle_s=20.0)
    assert good.columns == SANITY_CHECKS.names
    # two trips; the first only warms up the friction state: skipped, with its reason
    assert good["status"].to_list() == ["skipped", "passed"]
    assert good["passed"].to_list() == [None, True]
    assert good["message"][0] == WARM_UP_WORDS
    assert (good["rms_gap_pa"] / good["noise_pa"]).drop_nans().max() < 1.2
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
    assert bad["status"].to_list() == ["skipped", "failed"]
    assert bad["passed"].to_list() == [None, False]
    assert bad["message"][1].startswith(("down", "up"))


def test_a_log_without_speed_skips_every_trip_saying_why():
    """Without the encoder's speed the trips are found by the depth's derivative, which
    the replay cannot follow (a healthy log failed 15 of 16 trips that way): each trip
    is skipped with the reason, none passed or failed."""
    plan, info = hidden_case(None)
    # landed, a log without the column has it null
    sensors = info["day"].sensors.with_columns(pl.lit(None, dtype=pl.Float64).alias("speed_m_s"))
    checks = sanity_check(sensors, plan.hoist, run_id="r", settle_s=20.0)
    assert checks.height == 2
    assert checks["status"].to_list() == ["skipped", "skipped"]
    assert checks["passed"].to_list() == [None, None]
    assert set(checks["message"].to_list()) == {NO_SPEED_WORDS}


def test_a_trip_whose_speed_is_missing_for_a_stretch_is_skipped_saying_why():
    """Speed blank for 5 s inside the second trip's motion: that trip is skipped (the
    replay would follow the depth's derivative there), the first keeps its warm-up."""
    plan, info = hidden_case(None)
    sensors = info["day"].sensors
    second = plan.trips[1]
    t = (sensors["time_utc"] - plan.t_ref).dt.total_microseconds() / 1e6
    lo = second.motion_start_s + 10.0
    blank = (t >= lo) & (t < lo + 5.0)
    holed = sensors.with_columns(
        pl.when(blank).then(None).otherwise(pl.col("speed_m_s")).alias("speed_m_s")
    )
    checks = sanity_check(holed, plan.hoist, run_id="r", settle_s=20.0)
    assert checks["status"].to_list() == ["skipped", "skipped"]
    assert checks["message"].to_list() == [WARM_UP_WORDS, PART_SPEED_WORDS]


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
    assert everything["status"].to_list() == ["skipped", "passed"]
    assert late.height == 0


# ------------------------------------------------- ordinary records that cut trips


@pytest.fixture(scope="module")
def ten_hz():
    """Three trips (down, up, down) from a 10 Hz logger, 150 s apart; 5 s of loading
    and 5 s of rest before each motion (motions start at 10, 160 and 310 s)."""
    hoist = load_hoist(EXAMPLE_HOIST)
    day = generate_field_day(
        hoist,
        date="2026-03-02",
        seed=4,
        trips=3,
        hours=3 * 150 / 3600,
        sample_rate_hz=10.0,
        loading_s=5.0,
        rest_after_s=20.0,
        oil_temp_c=(30.0, 32.0),
    )
    return hoist, day


def _seconds(day, seconds: float) -> dt.datetime:
    return day.sensors["time_utc"].min() + dt.timedelta(seconds=seconds)


def test_a_record_ending_in_a_trips_acceleration_does_not_judge_that_departure(ten_hz):
    """Cut 8 s after trip 2 starts moving, only its acceleration is in the record: the
    replay's weakest part, with no run to dilute it; the trip is skipped, saying so.
    Cut in its run (the test below), it is judged."""
    hoist, day = ten_hz
    cut = day.sensors.filter(pl.col("time_utc") < _seconds(day, 318.0))
    checks = sanity_check(cut, hoist, run_id="r", settle_s=20.0)
    assert checks["trip_id"].to_list() == [0, 1, 2]
    assert checks["status"].to_list() == ["skipped", "passed", "skipped"], checks["message"]
    assert "before its acceleration ended" in checks["message"][2]


def test_a_10_hz_record_ending_mid_trip_checks_the_cut_trip(ten_hz):
    hoist, day = ten_hz
    cut = day.sensors.filter(pl.col("time_utc") < _seconds(day, 350.0))  # trip 2 moving
    checks = sanity_check(cut, hoist, run_id="r", settle_s=20.0)
    assert checks["trip_id"].to_list() == [0, 1, 2]
    assert checks["status"].to_list() == ["skipped", "passed", "passed"], checks["message"]
    assert "cut by the end of the record" in checks["message"][2]
    assert sanity_step(checks).message == (
        "2 of 2 trips passed, 1 skipped (reasons in sanity_checks)"
    )


def test_a_record_starting_mid_trip_says_the_cut_trip_only_warmed_up(ten_hz):
    hoist, day = ten_hz
    cut = day.sensors.filter(pl.col("time_utc") >= _seconds(day, 40.0))  # trip 0 moving
    checks = sanity_check(cut, hoist, run_id="r", settle_s=20.0)
    assert checks["trip_id"].to_list() == [0, 1, 2]
    assert checks["status"].to_list() == ["skipped", "passed", "passed"]
    assert checks["passed"][0] is None
    assert checks["message"][0].startswith("the record starts (or resumes after a logger gap)")
    step = sanity_step(checks)
    assert step.status == "done"
    assert step.message == "2 of 2 trips passed, 1 skipped (reasons in sanity_checks)"
    # a period that starts with the record: the cut trip is the period's (its first
    # sample is in it), though its fitted start lies before (it had no row)
    first = cut["time_utc"].min()
    period = sanity_check(cut, hoist, run_id="r", settle_s=20.0, report_from=first)
    assert period["trip_id"].to_list() == [0, 1, 2]


def test_a_trip_that_cannot_be_simulated_is_skipped_with_the_reason(ten_hz):
    """A model the device simulation refuses for a trip (groove offsets beyond the
    piston stroke when it starts from rest at the bottom) skips that block's trips,
    each with the reason; the check itself does not fail."""
    hoist, day = ten_hz
    drum = hoist.drum.model_copy(update={"groove_radius_deviation_m": [1e-3, -1e-3, 1e-3, -1e-3]})
    effects = [*hoist.model.effects, "groove_wear"]
    worn = hoist.model_copy(update={"drum": drum}).with_effects(effects)
    # from the up trip's loading on (trips 0 and 1 of this record): the block starts at
    # the bottom
    record = day.sensors.filter(pl.col("time_utc") >= _seconds(day, 149.0))
    checks = sanity_check(record, worn, run_id="r", settle_s=20.0)
    assert checks["trip_id"].to_list() == [0, 1]
    assert checks["status"].to_list() == ["skipped", "skipped"]
    assert checks["passed"].to_list() == [None, None]
    assert checks["message"][0].startswith("simulation failed")  # its own reason
    assert checks["message"][1].startswith("not simulated: trip 0 before it could not be simulated")
    assert "stroke" in checks["message"][1]


def test_every_trip_is_checked_in_one_chain_unless_a_sample_is_asked_for(ten_hz):
    """By default every trip of the record is replayed in one chain and compared after
    the first (which starts the history); a sample of two trips checks them in two
    blocks, the second after a warm-up trip that is replayed but not compared."""
    hoist, day = ten_hz
    every = sanity_check(day.sensors, hoist, run_id="r", settle_s=20.0)
    assert every["trip_id"].to_list() == [0, 1, 2]
    assert every["status"].to_list() == ["skipped", "passed", "passed"]
    assert WARM_UP_WORDS in every["message"][0]
    sampled = sanity_check(day.sensors, hoist, run_id="r", settle_s=20.0, max_trips=2)
    assert sampled["status"].to_list() == ["skipped", "skipped", "passed"]
    assert WARM_UP_WORDS in sampled["message"][1]  # the second block's warm-up


def test_only_trips_starting_in_the_reported_period_are_reported(ten_hz):
    hoist, day = ten_hz
    checks = sanity_check(
        day.sensors,
        hoist,
        run_id="r",
        settle_s=20.0,
        report_from=_seconds(day, 100.0),
        report_to=_seconds(day, 300.0),
    )
    assert checks["trip_id"].to_list() == [1]  # numbered from the record's first sample
    assert checks["status"].to_list() == ["passed"]


def test_a_trip_is_reported_by_the_period_holding_its_first_moving_sample(ten_hz):
    """A period edge between the fitted start of a trip's motion and the first sample
    the trip rule counts as moving (a fraction of a second apart) gives the trip to the
    period holding that sample, the one with its trip_summary row, on either side of
    the fitted start: reported by exactly one of two adjoining periods."""
    hoist, day = ten_hz
    moving = day.sensors.filter(
        (pl.col("time_utc") > _seconds(day, 100.0))
        & (pl.col("speed_m_s").abs() >= STANDSTILL_SPEED_M_S)
    )
    first_moving = moving["time_utc"].min()  # trip 1's first labelled row
    tick = dt.timedelta(milliseconds=1)
    for edge in (first_moving, first_moving + tick):
        before = sanity_check(
            day.sensors,
            hoist,
            run_id="r",
            settle_s=20.0,
            report_from=_seconds(day, 100.0),
            report_to=edge,
        )
        after = sanity_check(day.sensors, hoist, run_id="r", settle_s=20.0,
                             report_from=edge, report_to=_seconds(day, 300.0))  # fmt: skip
        assert before["trip_id"].to_list() + after["trip_id"].to_list() == [1]
        assert (before.height == 1) == (edge > first_moving)


def _jogged(day, at_s: float) -> pl.DataFrame:
    """The record with a 1-s encoder jog (0.05 m/s, depth unchanged) at ``at_s``."""
    t = pl.col("time_utc")
    jog = t.is_between(_seconds(day, at_s), _seconds(day, at_s + 1.0), closed="left")
    return day.sensors.with_columns(
        pl.when(jog).then(0.05).otherwise(pl.col("speed_m_s")).alias("speed_m_s")
    )


def test_trip_ids_name_the_trips_the_periods_trip_summary_names(ten_hz):
    """The check of a period numbers trips as the run of that period does (the trip
    rule of the compensation, counted from the run's first sample; here a run without
    lead-in), a jog too short to replay included: each checked trip's id is the
    trip_summary row of the same motion (the generator's truth says when it moved)."""
    hoist, day = ten_hz
    truth = day.truth.filter(pl.col("trip_id").is_not_null() & (pl.col("phase") != "standstill"))
    moving = truth.group_by("trip_id").agg(
        pl.col("time_utc").min().alias("start"), pl.col("time_utc").max().alias("end")
    )
    first_end = moving.filter(pl.col("trip_id") == 0)["end"][0]
    jog_s = (first_end - day.sensors["time_utc"].min()).total_seconds() + 20.0
    record = _jogged(day, jog_s)
    start, end = _seconds(day, jog_s - 5.0), _seconds(day, 340.0)
    checks = sanity_check(
        record, hoist, run_id="r", settle_s=20.0, report_from=start, report_to=end,
        number_from=start,
    )  # fmt: skip
    period = record.filter(pl.col("time_utc").is_between(start, end, closed="left"))
    trips = reconcile(compensate(period, hoist), hoist, run_id="r").trip_summary
    assert trips["trip_id"].to_list() == [0, 1, 2]  # the jog, the day's trips 1 and 2
    assert checks["trip_id"].to_list() == [0, 1, 2]
    assert checks["status"].to_list() == ["skipped", "passed", "passed"]
    assert "too short to replay" in checks["message"][0]
    for trip_id in (1, 2):
        row = trips.filter(pl.col("trip_id") == trip_id)
        true = moving.filter(pl.col("trip_id") == trip_id)  # the day's numbering = run's
        late = abs((row["time_start_utc"][0] - true["start"][0]).total_seconds())
        assert late < 0.5
    jog = trips.filter(pl.col("trip_id") == 0)
    assert abs((jog["time_start_utc"][0] - _seconds(day, jog_s)).total_seconds()) < 0.2


def test_a_sensor_40_kpa_off_fails_at_the_default_limit():
    """The default limit (3 x the noise, the replay's accuracy on a hoist it was not built
    with) still catches a sensor 40 kPa off (~0.5 % of the load): the payload fit takes
    the common-mode quarter, the differential 30 / -10 / -10 / -10 kPa stays (RMS
    17.3 kPa, over 3 x the logger's 5 kPa noise). The same trips unchanged pass."""
    plan, info = hidden_case(None)
    sensors = info["day"].sensors
    good = sanity_check(sensors, plan.hoist, run_id="r1", settle_s=20.0)
    assert good["status"].to_list() == ["skipped", "passed"]  # the first warms up
    off = sensors.with_columns(pl.col("p2_pa") + 40e3)
    bad = sanity_check(off, plan.hoist, run_id="r2", settle_s=20.0)
    assert bad["status"].to_list() == ["skipped", "failed"]
    ratio = (bad["rms_gap_pa"] / bad["noise_pa"])[1]
    assert 3.0 < ratio < 5.0, bad["message"].to_list()
    assert "limit 3 x" in bad["message"][1]


def test_a_stuck_sensor_is_left_out_not_compared():
    """Sensor 2 holds its reading through the second trip (the ``sensor_flatline``
    rule): the check compares the trip on the other three sensors, as the compensation
    leaves the stuck reading out, and it passes as the healthy record's does. Compared
    with the oil's pressure, the stuck reading failed it by megapascals."""
    plan, info = hidden_case(None)
    sensors = info["day"].sensors
    second = plan.trips[1]
    t = (sensors["time_utc"] - plan.t_ref).dt.total_microseconds() / 1e6
    through = (t >= second.motion_start_s - 5.0) & (t <= second.motion_end_s + 5.0)
    held = sensors.filter(through)["p2_pa"][0]
    stuck = sensors.with_columns(
        pl.when(through).then(pl.lit(held)).otherwise(pl.col("p2_pa")).alias("p2_pa")
    )
    assert second.motion_end_s - second.motion_start_s > plan.hoist.alarms.flatline_duration_s
    good = sanity_check(sensors, plan.hoist, run_id="r1", settle_s=20.0)
    checks = sanity_check(stuck, plan.hoist, run_id="r2", settle_s=20.0)
    assert checks["status"].to_list() == ["skipped", "passed"] == good["status"].to_list()
    assert checks["rms_gap_pa"][1] < 1.5 * good["rms_gap_pa"][1]
