"""Issue 5's accuracy figure on sims-generated field logs with known truth.

A short synthetic day of the paper's field hoist (device model of ``sims/``, sensor noise,
jitter, dropouts, spikes) is compensated; per visit of a named position the load must be
within 0.5 % of the true load and each rope within 1 % (the paper reached 1.5 % on the
load). Before compensation the error is several percent, which the test also asserts so
that it cannot pass by a model that does nothing.

These pin the share-out of the pistons' motion (``rope_springs=False``,
:mod:`transforms.piston_motion`: the compensation without identified ropes) on ropeload's
own simulator, whose seals are the compensation's LuGre. The default stick-slip solution
on identified rope springs (:mod:`transforms.stick_slip`, with the hoist's Maxwell-slip
elements since session 17) leaves 0.03-0.19 % on the load, 0.05-0.37 % per rope at
these visits (0.6-1.1 % with one elasto-plastic bristle; tests/transforms/
test_stick_slip.py has its own cases; its accuracy is measured on independent data
by benchmarks/eval_compensation.py).
"""

from __future__ import annotations

import polars as pl
import pytest

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.accuracy import position_accuracy
from sims.field_day import generate_field_day
from transforms.compensation import CompensationSettings, compensate

HOIST = load_hoist(EXAMPLE_HOIST)
SHARE_OUT = CompensationSettings(rope_springs=False)


@pytest.fixture(scope="module")
def visits() -> pl.DataFrame:
    day = generate_field_day(HOIST, date="2026-03-02", seed=11, trips=4, hours=0.75)
    samples = day.sensors.with_columns(
        source_sha256=pl.lit("synthetic"), source_line=pl.int_range(pl.len())
    )
    tensions = compensate(samples, HOIST, settings=SHARE_OUT)
    # The simulated day starts from rest (no friction stored), as the compensation does;
    # on real logs ropeload's run compensates a lead-in before the period for this.
    return position_accuracy(tensions, day.truth)


def test_every_position_is_visited(visits):
    assert set(visits["position"]) == {"pithead", "middle", "bottom"}


def test_load_within_half_a_percent_after_compensation(visits):
    worst = visits.group_by("position").agg(pl.col("error_after_fraction").abs().max())
    for position, error in worst.iter_rows():
        assert error < 0.005, f"{position}: load error {error:.2%}"


def test_each_rope_within_one_and_a_half_percent_after_compensation(visits):
    """1.5 %: the paper's load figure; issue 13 asks <= 2 % per rope at stops. The
    sticking-piston estimate (transforms.piston_motion) gives 1.2 % at the pithead here,
    where it gives a third of the first wave's error on independent data."""
    worst = visits.group_by("position").agg(pl.col("rope_error_after_fraction").max())
    for position, error in worst.iter_rows():
        assert error < 0.015, f"{position}: rope error {error:.2%}"


def test_uncompensated_error_is_several_percent(visits):
    """Before compensation the error is what the paper's Table 2 shows: percent level."""
    assert visits["error_before_fraction"].abs().max() > 0.02
    assert (
        visits["error_before_fraction"].abs().mean()
        > 5 * visits["error_after_fraction"].abs().mean()
    )


def test_a_20_hz_logger_is_compensated_as_well():
    """The record's own rate sets the filters and segments: a 20 Hz log (a common
    logger setting) is not mistaken for a 100 Hz one whose every step is a gap."""
    day = generate_field_day(
        HOIST, date="2026-03-02", seed=11, trips=4, hours=0.75, sample_rate_hz=20.0
    )
    samples = day.sensors.with_columns(
        source_sha256=pl.lit("synthetic"), source_line=pl.int_range(pl.len())
    )
    visits = position_accuracy(
        compensate(samples, HOIST, settings=SHARE_OUT), day.truth, min_samples=20
    )
    assert set(visits["position"]) == {"pithead", "middle", "bottom"}
    assert visits["error_after_fraction"].abs().max() < 0.005
    assert visits["rope_error_after_fraction"].max() < 0.01
    assert visits["error_before_fraction"].abs().max() > 0.02


def test_a_logger_dropout_mid_trip_is_not_a_second_trip():
    """The demo's day (seed 7) drops 0.24 s of samples 39 s into a down trip at 10 m/s.
    Every trip is labelled once, in its true direction, and its payload is inferred
    within 50 kg of the payload the simulation carried (a split trip's second half
    was a trip of its own, with the payload of its one position)."""
    from transforms.reconciliation import reconcile

    day = generate_field_day(HOIST, date="2026-03-02", seed=7, trips=6, hours=1.0, start_hour=6.0)
    times = day.sensors["time_utc"]
    steps = times.diff().dt.total_milliseconds()
    moving = day.sensors["speed_m_s"].abs() > 1.0
    assert ((steps > 100) & moving & moving.shift(1)).any()  # the dropout is there
    tensions = compensate(day.sensors, HOIST, settings=SHARE_OUT)
    trips = reconcile(tensions, HOIST, run_id="t").trip_summary
    truth = day.info["trips"]
    assert trips["direction"].to_list() == [trip["direction"] for trip in truth]
    error = trips["payload_kg"].to_numpy() - [trip["payload_kg"] for trip in truth]
    assert abs(error).max() < 50.0
