"""discovery.planning and sims.replay: trips segmented from a synthetic log and replayed
against known truth."""

from __future__ import annotations

import dataclasses
import datetime as dt

import numpy as np
import polars as pl
import pytest

from discovery.cases import hidden_case
from discovery.planning import plan_replay
from discovery.record import (
    RAMP_LEAD_S,
    read_record,
    shortest_round_trip_s,
    trailing_ramp_start,
    trip_timing,
)
from discovery.replay_choices import choose_motion
from discovery.segmentation import CUT_WORDS, estimate_noise_sigma
from sims.replay import replay_fitted
from sims.replay_plan import replay_frame


@pytest.fixture(scope="module")
def null_case():
    return hidden_case(None, trips=3, seed=1)


def test_noise_estimate_white_noise():
    rng = np.random.default_rng(0)
    p = 5e6 + np.linspace(0, 2e5, 30000)[:, None] + rng.normal(0, 3e3, (30000, 4))
    assert estimate_noise_sigma(p, np.zeros(30000, bool)) == pytest.approx(3e3, rel=0.05)


def test_noise_estimate_of_sensors_updating_slower_than_the_logger():
    """A 10 Hz transducer on a 50 Hz logger repeats each reading five times: most
    differences are exactly 0 (their MAD 0, and every gap divided by it); the noise is
    the readings' own. Pressures that never vary give no estimate, and planning a
    replay on them says so in one line (a probe crashed ``discover`` with a
    ZeroDivisionError there)."""
    rng = np.random.default_rng(1)
    readings = 5e6 + np.linspace(0, 2e5, 6000)[:, None] + rng.normal(0, 3e3, (6000, 4))
    held = np.repeat(readings, 5, axis=0)
    assert estimate_noise_sigma(held, np.zeros(held.shape[0], bool)) == pytest.approx(3e3, rel=0.05)
    assert not estimate_noise_sigma(np.full((500, 4), 5e6), np.zeros(500, bool)) > 0.0
    # a reading quantised coarsely against its noise repeats irregularly: not held; its
    # noise with the quantisation's, sqrt(2^2 + 10^2 / 12) = 3.5 kPa, to 10 %
    smooth = 5e6 + np.linspace(0, 2e5, 6000)[:, None]
    coarse = np.round((smooth + rng.normal(0, 2e3, (6000, 4))) / 1e4) * 1e4
    assert estimate_noise_sigma(coarse, np.zeros(6000, bool)) == pytest.approx(3.5e3, rel=0.1)
    plan, info = hidden_case(None, trips=2, seed=2)
    flat = info["day"].sensors.with_columns(pl.lit(5e6).alias(f"p{i}_pa") for i in range(1, 5))
    with pytest.raises(ValueError, match="noise cannot be estimated"):
        plan_replay(flat, plan.hoist)


def test_plan_recovers_trip_inputs(null_case):
    plan, info = null_case
    trips = info["day"].info["trips"]
    assert len(plan.trips) == len(trips) == plan.trips_found
    assert plan.noise_sigma_pa == pytest.approx(5e3, rel=0.1)
    for tr, truth in zip(plan.trips, trips, strict=True):
        assert tr.direction == truth["direction"]
        assert tr.start_depth_m == pytest.approx(truth["start_depth_m"], abs=0.05)
        assert tr.end_depth_m == pytest.approx(truth["end_depth_m"], abs=0.05)
        assert tr.oil_temp_c == pytest.approx(truth["oil_temp_c"], abs=0.05)
        # motion starts 5 s loading + 5 s rest after the trip's start
        assert tr.motion_start_s == pytest.approx(truth["start_s"] + 10.0, abs=0.01)


def test_logged_motion_drives_every_planned_trip(null_case):
    """``motion="logged"``: each trip follows the encoder's logged speed, not only the
    first (a reused name once left the others on the winder profile). The default
    ("auto") takes whichever replays the first trips closer: on ropeload's own field
    day, whose winder steps its acceleration and whose ropes ring, the profile."""
    _, info = null_case
    plan = plan_replay(info["day"].sensors, info["day"].hoist, motion="logged")
    assert len(plan.trips) == 3
    assert all(tr.motion_knots is not None for tr in plan.trips)
    auto = plan_replay(info["day"].sensors, info["day"].hoist)
    assert all(tr.motion_knots is None for tr in auto.trips)
    assert any(n.startswith("motion: the winder profile drives") for n in auto.notes)
    winder = plan_replay(info["day"].sensors, info["day"].hoist, motion="winder")
    assert all(tr.motion_knots is None for tr in winder.trips)


def test_replay_of_the_true_model_leaves_the_noise(null_case):
    plan, info = null_case
    result = replay_fitted(plan, passes=3)
    assert result.ok
    truth_pay = [t["payload_kg"] for t in info["day"].info["trips"]]
    np.testing.assert_allclose(result.payload_kg, truth_pay, atol=30.0)
    resid = np.concatenate([r[np.isfinite(r)] for r in result.residuals(plan)])
    assert np.sqrt(np.mean(resid**2)) < 1.15 * plan.noise_sigma_pa
    frame = replay_frame(plan, result)
    assert {"time_utc", "trip_id", "phase", "p1_pa", "p_sim4_pa"} <= set(frame.columns)


def test_replay_without_a_true_effect_shows_a_gap(null_case):
    plan, _ = null_case
    effects = [e for e in plan.hoist.model.effects if e != "conveyance_inertia"]
    result = replay_fitted(plan, effects=effects, passes=2)
    resid = np.concatenate([r[np.isfinite(r)] for r in result.residuals(plan)])
    assert np.sqrt(np.mean(resid**2)) > 10 * plan.noise_sigma_pa


def test_a_logger_gap_after_a_stop_does_not_lose_the_loading(null_case):
    """Rows missing from 1 s to 6 s after a stop (where the level before the next
    loading is read) move the reading to the nearest logged samples: the next trip's
    level before loading, its payload and its fit are as without the gap."""
    plan, info = null_case
    sensors = info["day"].sensors
    t0 = sensors["time_utc"][0]
    stop = plan.t_ref + dt.timedelta(seconds=plan.trips[0].motion_end_s)
    gapped = sensors.filter(
        (pl.col("time_utc") < stop + dt.timedelta(seconds=1))
        | (pl.col("time_utc") > stop + dt.timedelta(seconds=6))
    )
    assert gapped.height < sensors.height
    assert gapped["time_utc"][0] == t0
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=20.0)
    truth = info["day"].info["trips"][1]
    # the level before loading: the standstill pressure at the previous payload
    assert gap_plan.trips[1].p_before_pa == pytest.approx(plan.trips[1].p_before_pa, abs=5e3)
    result = replay_fitted(gap_plan, passes=3)
    assert result.payload_before_kg[1] == pytest.approx(truth["payload_before_kg"], abs=30.0)
    resid = np.concatenate([r[np.isfinite(r)] for r in result.residuals(gap_plan)])
    assert np.sqrt(np.mean(resid**2)) < 1.15 * gap_plan.noise_sigma_pa


@pytest.mark.parametrize("into_s", [20.0, 40.0, -8.0, -3.0])
def test_a_logger_gap_in_the_middle_of_a_trip_cuts_it_and_restarts_the_history(null_case, into_s):
    """Rows missing from 20 or 40 s into trip 0's motion (or 8 or 3 s before it stops)
    to 5 s after it stopped: the trip is cut there and compared up to the gap, not to
    the standstill after it (the gap hides where it stopped); its simulation stops at
    the gap, so the next trip starts a new history as an uncompared warm-up, whatever
    the cut trip's completion guessed, and the replay runs (was: the chain carried on
    from the gap's depth and the simulation refused the next trip)."""
    plan, info = null_case
    sensors = info["day"].sensors
    first = plan.trips[0]
    # from ``into_s`` after the motion starts (before it stops, if negative)
    at = first.motion_start_s + into_s if into_s > 0 else first.motion_end_s + into_s
    gap_from = _at(plan, at)
    gap_to = _at(plan, first.motion_end_s + 5.0)
    gapped = sensors.filter((pl.col("time_utc") < gap_from) | (pl.col("time_utc") > gap_to))
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=20.0)
    cut, after = gap_plan.trips[0], gap_plan.trips[1]
    assert cut.cut == "end"
    assert _at(gap_plan, cut.window_end_s) <= gap_from
    assert after.first_in_block
    assert not after.valid.any()
    assert gap_plan.trips[2].valid.any()  # the trip after the warm-up is compared
    result = replay_fitted(gap_plan, passes=2)
    assert result.ok, result.message
    # what is compared replays as well as without the gap
    assert _rms(result.residuals(gap_plan)[2]) < 1.3 * gap_plan.noise_sigma_pa


@pytest.fixture(scope="module")
def four_trips():
    return hidden_case(None, trips=4, seed=2)


def test_a_gap_at_rest_that_hides_a_round_trip_restarts_the_history(four_trips):
    """Rows missing from just after trip 0 stops (at the bottom) to just before trip 3
    starts (at the bottom again): trips 1 and 2 went up and came back unseen, so the
    depth matches but the seals' history does not. Trip 3 starts a new history, a
    warm-up not compared (was: chained on, and failed where it replays to the noise)."""
    plan, info = four_trips
    sensors = info["day"].sensors
    assert [tr.start_depth_m for tr in plan.trips] == pytest.approx([0, 600, 0, 600], abs=0.1)
    gap_from = _at(plan, plan.trips[0].motion_end_s + 4.0)
    gap_to = _at(plan, plan.trips[3].motion_start_s - 6.0)
    gapped = sensors.filter((pl.col("time_utc") < gap_from) | (pl.col("time_utc") > gap_to))
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=20.0)
    assert len(gap_plan.trips) == 2
    after = gap_plan.trips[1]
    assert after.start_depth_m == pytest.approx(600.0, abs=0.1)
    assert after.first_in_block
    assert not after.valid.any()
    assert replay_fitted(gap_plan, passes=2).ok


def test_a_gap_at_rest_that_hides_a_trip_reads_each_side_s_depth(four_trips):
    """Rows missing from just after trip 0 stops (at the bottom) to the middle of the
    standstill after trip 1 (at the pithead): the standstill's depth is read on each
    side of the gap, so trip 0 ends at the bottom and trip 2 starts at the pithead,
    going down (the median over both sides had made a trip down from the bottom an
    'up' trip and the next trip's simulation refuse its start), and trip 2 starts a
    new history."""
    plan, info = four_trips
    sensors = info["day"].sensors
    gap_from = _at(plan, plan.trips[0].motion_end_s + 4.0)
    gap_to = _at(plan, 0.5 * (plan.trips[1].motion_end_s + plan.trips[2].motion_start_s))
    gapped = sensors.filter((pl.col("time_utc") < gap_from) | (pl.col("time_utc") > gap_to))
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=20.0)
    first, second = gap_plan.trips[:2]
    assert (first.start_depth_m, first.end_depth_m) == pytest.approx((0.0, 600.0), abs=0.1)
    assert (second.start_depth_m, second.end_depth_m) == pytest.approx((0.0, 600.0), abs=0.1)
    assert second.direction == "down"
    assert second.first_in_block
    result = replay_fitted(gap_plan, passes=2)
    assert result.ok, result.message
    # the trip after the warm-up (trip 3) replays as well as in the whole record
    whole = _rms(replay_fitted(plan, passes=2).residuals(plan)[3])
    assert _rms(result.residuals(gap_plan)[2]) < 1.1 * whole


def test_a_trip_s_stop_before_two_gaps_is_where_it_stopped(four_trips):
    """Rows missing from just after trip 1 stops (at the pithead) to after trip 2, and
    again until trip 3 is moving (review): trip 1 ends where the record logged it
    stopping, not at the median over the standstills either side of the gap (it
    planned as 'up 600 -> 600', 394 m off the profile, and failed at 4.8 x the noise),
    and trip 3, which the record resumes during, starts a new history."""
    plan, info = four_trips
    trips = plan.trips
    sensors = info["day"].sensors
    gaps = [
        (trips[1].motion_end_s + 4.0, trips[2].motion_end_s + 3.0),
        (trips[2].motion_end_s + 8.0, trips[3].motion_start_s + 3.0),
    ]
    kept = pl.lit(True)
    for lo, hi in gaps:
        kept &= ~pl.col("time_utc").is_between(_at(plan, lo), _at(plan, hi))
    gap_plan = plan_replay(sensors.filter(kept), plan.hoist, settle_s=20.0)
    second, resumed = gap_plan.trips[1], gap_plan.trips[2]
    assert (second.start_depth_m, second.end_depth_m) == pytest.approx((600.0, 0.0), abs=0.1)
    assert resumed.cut == "start"
    assert resumed.first_in_block
    result = replay_fitted(gap_plan, passes=2)
    assert _rms(result.residuals(gap_plan)[1]) < 2.0 * gap_plan.noise_sigma_pa


def _cut(sensors: pl.DataFrame, plan, lo: float, hi: float) -> pl.DataFrame:
    """``sensors`` without the rows from ``lo`` to ``hi`` [s after the plan's t_ref]."""
    return sensors.filter(~pl.col("time_utc").is_between(_at(plan, lo), _at(plan, hi)))


def _shift(sensors: pl.DataFrame, plan, start: float, by: float) -> pl.DataFrame:
    """``sensors`` with every row from ``start`` [s after the plan's t_ref] on ``by`` s later."""
    later = pl.col("time_utc") >= _at(plan, start)
    moved = pl.col("time_utc") + dt.timedelta(seconds=by)
    return sensors.with_columns(pl.when(later).then(moved).otherwise(pl.col("time_utc")))


def test_a_trip_s_window_ends_at_a_gap_across_which_the_conveyance_moved(four_trips):
    """Trip 1 stops at the pithead at 242.8 s; the logger stops 7 s later and resumes
    15 s on with the conveyance at the bottom (trip 2 unseen). Trip 1's window ends at
    the gap, not in the standstill logged at 600 m (a probe: 275 x the noise with the
    sanity check's 45 s of settling): it is compared up to the gap, and the trip after
    the gap starts a new history."""
    plan, info = four_trips
    gapped = _shift(_cut(info["day"].sensors, plan, 250.0, 395.0), plan, 395.0, -130.0)
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=45.0)
    first, second = gap_plan.trips[1], gap_plan.trips[2]
    assert (first.start_depth_m, first.end_depth_m) == pytest.approx((600.0, 0.0), abs=0.1)
    compared = first.time_s[first.valid.any(axis=1)]
    assert compared.size
    assert _at(gap_plan, float(compared.max())) < _at(plan, 250.0)
    assert second.first_in_block
    assert not second.valid.any()
    result = replay_fitted(gap_plan, passes=3)
    assert _rms(result.residuals(gap_plan)[1]) < 1.5 * gap_plan.noise_sigma_pa


@pytest.mark.parametrize("into_s", [1.6, 1.4])
def test_a_loading_a_gap_or_the_record_s_end_cuts_early_ends_the_window_before_it(
    four_trips, into_s
):
    """Trip 2's loading (285.2 s once 15 s of rest before it are taken out) is cut
    1.4 or 1.6 s in, by a logger stop that hides a round trip (1.6 s) or by the record's
    end (1.4 s): too little of it for the level after (a 3 s median) to pass the ramp
    threshold. Trip 1's window still ends before it (a probe: 4.1 x and 3.8 x the noise
    over the loading's start) and its standstill replays as without the loading."""
    plan, info = four_trips
    short = _shift(_cut(info["day"].sensors, plan, 250.0, 265.0), plan, 265.0, -15.0)
    loading = info["day"].info["trips"][2]["start_s"] - 15.0
    cut_at = loading + into_s
    if into_s > 1.5:  # a gap: the rest of the record 120 s on
        gapped = _shift(short, plan, cut_at, 120.0)
    else:
        gapped = short.filter(pl.col("time_utc") < _at(plan, cut_at))
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=45.0)
    before = gap_plan.trips[1]
    assert _at(gap_plan, before.window_end_s) <= _at(plan, loading + 0.1)
    result = replay_fitted(gap_plan, passes=3)
    assert _rms(result.residuals(gap_plan)[1]) < 2.0 * gap_plan.noise_sigma_pa


def test_the_settling_after_a_stop_is_no_payload_change_where_the_record_ends(four_trips):
    """The common-mode pressure settles 25 kPa over the seconds after trip 1 stops
    (e-folding 4 s, as the ringing validation hoist's settles by 20-25 kPa over 10 s),
    with no payload change before trip 2's loading. A record ending anywhere in that
    standstill shows no payload change after its last stop, so the last trip's window is
    not cut short (a review: the early-cut loading's reading took such settling for a
    loading at 147 of ~1800 cut positions on validation day 104)."""
    plan, info = four_trips
    stop = plan.trips[1].motion_end_s
    loading = info["day"].info["trips"][2]["start_s"]
    since = (pl.col("time_utc") - _at(plan, 0.0)).dt.total_microseconds() / 1e6
    settling = (
        pl.when((since > stop) & (since < loading))
        .then(25e3 * ((stop - since) / 4.0).exp())
        .otherwise(0.0)
    )
    settled = info["day"].sensors.with_columns(pl.col(f"p{i}_pa") + settling for i in range(1, 5))
    for end in np.arange(stop + 3.0, loading - 1.0, 1.0):
        rec = read_record(settled.filter(pl.col("time_utc") < _at(plan, end)), plan.hoist)
        timing = [trip_timing(rec, plan.hoist, k) for k in range(len(rec.motions))]
        assert trailing_ramp_start(rec, timing, []) == np.inf, f"record ending at {end:.0f} s"


def test_a_record_resuming_as_a_trip_leaves_the_pithead_loads_the_seals(four_trips):
    """The logger stops for 30 s just as trip 2 leaves the pithead (nothing lost, the
    rows after it 30 s on): the trip, cut at its start, is completed from the pithead
    and loads the seals for trip 3, which is compared. Before, an encoder reading of
    -1 mm at the pithead put every candidate start above the shaft and the trip was
    skipped as outside it, its history restarting with trip 3 uncompared."""
    plan, info = four_trips
    gapped = _shift(info["day"].sensors, plan, 310.0, 30.0)
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=20.0)
    assert [tr.trip_id for tr in gap_plan.trips] == [0, 1, 2, 3]
    assert gap_plan.skipped == ()
    resumed, after = gap_plan.trips[2], gap_plan.trips[3]
    assert resumed.cut == "start"
    assert resumed.start_depth_m == pytest.approx(0.0, abs=0.1)
    assert resumed.first_in_block
    assert not resumed.valid.any()
    assert after.valid.any()
    result = replay_fitted(gap_plan, passes=3)
    assert result.ok, result.message
    # a history restarted from rest: within the sanity check's 3 x (1.5 x here)
    assert _rms(result.residuals(gap_plan)[3]) < 2.0 * gap_plan.noise_sigma_pa


@pytest.mark.parametrize(("starts_s", "compared"), [(299.0, True), (304.8, False), (309.0, False)])
def test_a_record_starting_just_before_a_motion_compares_it_only_with_its_loading_seen(
    four_trips, starts_s, compared
):
    """Trip 2 loads from 300.2 s to 305.1 s and moves at 310 s. A record starting at
    299 s shows the loading (its first trip compared, as discovery compares a record's
    first trip); one starting within it (304.8 s) or after it (309 s) holds less than
    ``STANDSTILL_SEEN_S`` (8 s) of the standstill: the trip only loads the seals' state
    (a probe: 4.7 x and 3.1 x the noise when compared), and the next is compared."""
    plan, info = four_trips
    late = info["day"].sensors.filter(pl.col("time_utc") >= _at(plan, starts_s))
    late_plan = plan_replay(late, plan.hoist, settle_s=20.0)
    first, second = late_plan.trips[:2]
    assert first.trip_id == 0
    assert bool(first.valid.any()) is compared
    assert second.valid.any()
    result = replay_fitted(late_plan, passes=3)
    assert _rms(result.residuals(late_plan)[1]) < 1.5 * late_plan.noise_sigma_pa
    if compared:
        assert _rms(result.residuals(late_plan)[0]) < 2.0 * late_plan.noise_sigma_pa


def test_two_short_gaps_around_another_level_restart_the_history(four_trips):
    """Trip 0 stops at the bottom; two 15 s logger stops, each shorter than a round
    trip, hide trips 1 and 2 around 5 s logged at the pithead; the conveyance is at the
    bottom again when trip 3 leaves. The depth before the first gap and after the
    last agree, but the stretch between them says it moved: trip 3 starts a new history
    as a warm-up (was: chained on as if the seals had stood still)."""
    plan, info = four_trips
    sensors = info["day"].sensors
    kept = [
        sensors.filter(pl.col("time_utc") < _at(plan, 100.0)),
        _shift(_cut(_cut(sensors, plan, 0.0, 250.0), plan, 255.0, 1e4), plan, 0.0, -135.0),
        _shift(_cut(sensors, plan, 0.0, 400.0), plan, 0.0, -265.0),
    ]
    gapped = pl.concat(kept)
    assert gapped["time_utc"].is_sorted()
    gap_plan = plan_replay(gapped, plan.hoist, settle_s=20.0)
    assert len(gap_plan.trips) == 2
    last = gap_plan.trips[1]
    assert (last.start_depth_m, last.end_depth_m) == pytest.approx((600.0, 0.0), abs=0.1)
    assert last.first_in_block
    assert not last.valid.any()


# ------------------------------------------------- records that cut a trip, and their ends


def _at(plan, seconds: float) -> dt.datetime:
    return plan.t_ref + dt.timedelta(seconds=seconds)


def _rms(residual: np.ndarray) -> float:
    finite = residual[np.isfinite(residual)]
    return float(np.sqrt(np.mean(finite**2)))


def test_a_record_ending_mid_trip_replays_what_is_logged(null_case):
    """The logger stops halfway through the last trip: no crash; the trip is completed by
    the winder profile fitted to its logged depth and compared up to the record's end."""
    plan, info = null_case
    truth = info["day"].info["trips"]
    last = plan.trips[2]
    end = _at(plan, 0.5 * (last.motion_start_s + last.motion_end_s))
    cut = info["day"].sensors.filter(pl.col("time_utc") < end)
    cut_plan = plan_replay(cut, plan.hoist, settle_s=20.0)
    assert [tr.cut for tr in cut_plan.trips] == ["", "", "end"]
    tr = cut_plan.trips[2]
    assert not tr.first_in_block  # it continues the seals' history of the trip before
    assert tr.start_depth_m == pytest.approx(truth[2]["start_depth_m"], abs=0.05)
    assert tr.motion_start_s == pytest.approx(truth[2]["start_s"] + 10.0, abs=0.05)
    assert tr.end_depth_m > 300.0  # going down, past the depth logged when it stopped
    assert _at(cut_plan, tr.time_s[-1]) < end
    assert any(CUT_WORDS["end"] in note for note in cut_plan.notes)
    result = replay_fitted(cut_plan, passes=3)
    assert result.ok, result.message
    assert np.isfinite(result.simulated[2]).all()
    assert _rms(result.residuals(cut_plan)[2]) < 1.3 * cut_plan.noise_sigma_pa


def test_a_record_starting_mid_trip_warms_up_on_it(null_case):
    """The logger starts 5 s into the first trip's motion: that trip is simulated from
    rest at its fitted start, not compared, and the next trip continues from it."""
    plan, info = null_case
    truth = info["day"].info["trips"]
    start = _at(plan, plan.trips[0].motion_start_s + 5.0)
    cut = info["day"].sensors.filter(pl.col("time_utc") >= start)
    cut_plan = plan_replay(cut, plan.hoist, settle_s=20.0)
    assert [tr.cut for tr in cut_plan.trips] == ["start", "", ""]
    first = cut_plan.trips[0]
    assert first.start_depth_m == pytest.approx(truth[0]["start_depth_m"], abs=0.5)
    assert first.end_depth_m == pytest.approx(truth[0]["end_depth_m"], abs=0.05)
    assert _at(cut_plan, first.motion_start_s) < start  # it started before the record
    assert not first.valid.any()
    assert not cut_plan.trips[1].first_in_block
    result = replay_fitted(cut_plan, passes=3)
    assert result.ok, result.message
    assert _rms(result.residuals(cut_plan)[1]) < 1.3 * cut_plan.noise_sigma_pa


def test_a_record_starting_during_a_trip_up_infers_its_payload_where_it_stopped(null_case):
    """The logger starts 5 s into the trip up from the bottom (600 m): the payload of
    the trip it cuts can only be read from the standstill after its stop, at the
    pithead, where the whole tail rope hangs below the conveyance (eq 3-4). Read with
    the start's tail rope (none at the bottom) it was 13.1 t for a true 5.9 t, the
    next trip's loading then replayed from it; read where it stopped it is the true
    payload to within the seals' friction held at rest (~2 kN here)."""
    plan, info = null_case
    truth = info["day"].info["trips"][1]
    assert truth["direction"] == "up"
    assert truth["start_depth_m"] == pytest.approx(600.0)
    start = _at(plan, plan.trips[1].motion_start_s + 5.0)
    cut_plan = plan_replay(
        info["day"].sensors.filter(pl.col("time_utc") >= start), plan.hoist, settle_s=20.0
    )
    first = cut_plan.trips[0]
    assert first.cut == "start"
    assert first.levels_depth_m == pytest.approx(truth["end_depth_m"], abs=0.05)
    # a block starting with it puts the pistons where the record first logs them
    logged = info["day"].sensors.filter(
        pl.col("time_utc").is_between(start, start + dt.timedelta(seconds=2.0))
    )
    first_x = [logged[f"x{i}_m"].median() for i in range(1, 5)]
    np.testing.assert_allclose(first.x_start_m, first_x, atol=1e-4)  # the logger step
    result = replay_fitted(cut_plan, passes=3)
    assert result.ok, result.message
    assert result.payload_kg[0] == pytest.approx(truth["payload_kg"], abs=300.0)
    assert _rms(result.residuals(cut_plan)[1]) < 1.3 * cut_plan.noise_sigma_pa


def test_a_record_inside_one_trip_skips_it_with_the_reason(null_case):
    plan, info = null_case
    tr = plan.trips[1]
    inside = info["day"].sensors.filter(
        pl.col("time_utc").is_between(
            _at(plan, tr.motion_start_s + 20.0), _at(plan, tr.motion_end_s - 20.0)
        )
    )
    cut_plan = plan_replay(inside, plan.hoist, settle_s=20.0)
    assert cut_plan.trips == ()
    assert [(s.trip_id, s.reason) for s in cut_plan.skipped] == [
        (0, CUT_WORDS["start"] + ": the record holds neither its start nor its stop")
    ]


def test_a_payload_change_after_the_last_stop_ends_its_window(null_case):
    """The record ends after the next trip's loading but before it moves: the last
    trip's standstill is compared only up to the loading, which it does not simulate."""
    plan, info = null_case
    truth = info["day"].info["trips"]
    loading = _at(plan, truth[2]["start_s"])  # trip 2 loads for 5 s, moves at +10 s
    cut = info["day"].sensors.filter(pl.col("time_utc") < loading + dt.timedelta(seconds=8))
    cut_plan = plan_replay(cut, plan.hoist, settle_s=60.0)  # 60 s reach past the loading
    assert len(cut_plan.trips) == 2
    last = cut_plan.trips[-1]
    assert _at(cut_plan, last.window_end_s) <= loading
    # it ends RAMP_LEAD_S before the ramp the pressure shows, which starts near the loading
    assert _at(cut_plan, last.window_end_s) > loading - dt.timedelta(seconds=RAMP_LEAD_S + 1.0)
    assert any("payload changes after the last stop" in note for note in cut_plan.notes)
    with_loading = _rms(replay_fitted(cut_plan, passes=3).residuals(cut_plan)[1])
    # the same standstill, the record ending before the loading: the same gap (the
    # generator holds the state 20 s after a stop, so 60 s leave more than the noise)
    before = info["day"].sensors.filter(pl.col("time_utc") < loading - dt.timedelta(seconds=1))
    plain = plan_replay(before, plan.hoist, settle_s=60.0)
    assert not any("payload changes" in note for note in plain.notes)
    without = _rms(replay_fitted(plain, passes=3).residuals(plain)[1])
    assert with_loading == pytest.approx(without, rel=0.03)


def test_a_payload_change_before_a_logger_gap_ends_the_window_before_it(null_case):
    """The next trip's loading is logged, then the logger stops at rest for longer than
    a round trip, so the next trip's history restarts after the gap and its loading
    ramp is read there: the loading before the gap belongs to no trip's ramp. The trip
    before it is compared only up to that loading, as when the record ends there (was:
    its window ran over the unsimulated payload change; on validation day 104 with a
    10 min gap at rest such a trip failed the sanity check at 90 x the noise)."""
    plan, info = null_case
    truth = info["day"].info["trips"]
    loading = _at(plan, truth[2]["start_s"])  # trip 2 loads for 5 s, moves at +10 s
    gap_from = loading + dt.timedelta(seconds=8)
    sensors = info["day"].sensors
    later = pl.col("time_utc") >= gap_from
    shifted = sensors.with_columns(
        pl.when(later)
        .then(pl.col("time_utc") + dt.timedelta(seconds=shortest_round_trip_s(plan.hoist) + 60))
        .otherwise(pl.col("time_utc"))
    )
    gap_plan = plan_replay(shifted, plan.hoist, settle_s=60.0)  # 60 s reach past the loading
    assert len(gap_plan.trips) == 3
    before, after = gap_plan.trips[1], gap_plan.trips[2]
    assert after.first_in_block
    assert not after.valid.any()
    assert _at(gap_plan, before.window_end_s) <= loading
    assert _at(gap_plan, before.window_end_s) > loading - dt.timedelta(seconds=RAMP_LEAD_S + 1.0)
    with_loading = _rms(replay_fitted(gap_plan, passes=3).residuals(gap_plan)[1])
    # the same standstill, the record ending before the loading: the same gap
    plain_samples = sensors.filter(pl.col("time_utc") < loading - dt.timedelta(seconds=1))
    plain = plan_replay(plain_samples, plan.hoist, settle_s=60.0)
    without = _rms(replay_fitted(plain, passes=3).residuals(plain)[1])
    assert with_loading == pytest.approx(without, rel=0.03)


def test_a_later_block_follows_an_unscored_warm_up_trip(null_case):
    """Two blocks of one trip out of three: the second block's history starts with the
    trip before it, simulated from rest and not compared, so the compared trip meets
    the seals as the trips before left them."""
    _, info = null_case
    plan = plan_replay(info["day"].sensors, info["day"].hoist, max_trips=2, blocks=2)
    assert [tr.trip_id for tr in plan.trips] == [0, 1, 2]
    assert [tr.first_in_block for tr in plan.trips] == [True, True, False]
    assert [bool(tr.valid.any()) for tr in plan.trips] == [True, False, True]
    assert [tr.block for tr in plan.trips] == [0, 1, 1]
    assert any("each later one after a warm-up trip" in note for note in plan.notes)


def test_no_limit_plans_every_trip_in_one_chain(null_case):
    """``max_trips=None`` (the sanity check's default): every trip of the record, one
    block, the first trip starting the history and every trip compared; a limit of
    the record's own trip count gives the same plan."""
    _, info = null_case
    every = plan_replay(info["day"].sensors, info["day"].hoist, max_trips=None)
    assert [tr.trip_id for tr in every.trips] == [0, 1, 2]
    assert [tr.block for tr in every.trips] == [0, 0, 0]
    assert [tr.first_in_block for tr in every.trips] == [True, False, False]
    assert all(tr.valid.any() for tr in every.trips)
    assert not any("warm-up" in note for note in every.notes)
    three = plan_replay(info["day"].sensors, info["day"].hoist, max_trips=3)
    assert [tr.window_end_s for tr in three.trips] == [tr.window_end_s for tr in every.trips]


def test_motion_choice_without_logged_motion_keeps_the_ropes_notes(null_case):
    """A record whose trips have no logged motion (all cut at their start) is driven by
    the winder profile, and what the ropes' reading found stays in the notes."""
    plan, _ = null_case
    no_knots = dataclasses.replace(
        plan,
        trips=tuple(dataclasses.replace(tr, motion_knots=None) for tr in plan.trips),
        notes=("rope stiffness: a note",),
    )
    winder = dataclasses.replace(plan, notes=())
    chosen = choose_motion(no_knots, winder)
    assert chosen.notes == ("rope stiffness: a note",)
    assert chosen.trips is winder.trips


def test_a_loading_soon_after_a_stop_is_replayed_from_where_it_started(null_case):
    """Windows long enough to reach the next loading (60 s of settling; the generator
    loads 37 s after a stop) end RAMP_LEAD_S before the ramp the pressure shows, so the
    replay's refit can start the load where the generator did, before the pressure
    shows it (the seals take its start). Ended at the ramp, the window held trip 1's
    load back to 150.26 s against the generator's 150 s."""
    plan, info = null_case
    truth = info["day"].info["trips"]
    long = plan_replay(info["day"].sensors, plan.hoist, settle_s=60.0)
    before, loaded = long.trips[0], long.trips[1]
    assert before.window_end_s == pytest.approx(loaded.ramp_start_s - RAMP_LEAD_S)
    assert loaded.ramp_start_s - truth[1]["start_s"] > 0.15  # the pressure shows it late
    res = replay_fitted(long, passes=3)
    replayed_from = max(res.ramps_s[1, 0], before.window_end_s)  # as the replay starts it
    assert replayed_from == pytest.approx(truth[1]["start_s"], abs=0.1)


def test_a_record_without_depth_or_without_a_comparable_trip_says_so(null_case):
    """No encoder depth logged (contract 1a: optional): one line saying the replay needs
    it (was: 'need at least one array to concatenate'); a record whose only trip is cut
    at both ends: no trip to compare, and the reasons."""
    from discovery.selection import discover_effects

    plan, info = null_case
    sensors = info["day"].sensors
    with pytest.raises(ValueError, match="the record has no depth logged"):
        plan_replay(sensors.with_columns(pl.lit(None, pl.Float64).alias("depth_m")), plan.hoist)
    first = plan.trips[0]
    middle = sensors.filter(
        (pl.col("time_utc") > _at(plan, first.motion_start_s + 10.0))
        & (pl.col("time_utc") < _at(plan, first.motion_end_s - 10.0))
    )
    cut_plan = plan_replay(middle, plan.hoist)
    with pytest.raises(ValueError, match="no trip of the record can be compared"):
        discover_effects(cut_plan, bootstrap=10)
