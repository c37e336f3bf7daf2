"""sims.replay: the blocks of a plan are independent histories, replayed on threads.

The truth is the replay of each block alone (a plan of its trips only): the threaded
replay of the whole plan must give exactly that, trip for trip, and the same as on one
thread."""

from __future__ import annotations

import dataclasses
from itertools import pairwise

import numpy as np
import pytest

import sims.replay as replay_module
from discovery.cases import scenario_hoist
from discovery.planning import plan_replay
from discovery.rope_stiffness import with_stiffness_factors
from sims.device import simulate
from sims.field_day import generate_field_day
from sims.trips import hold


@pytest.fixture(scope="module")
def two_blocks():
    """Five trips of 150 s at 20 Hz; two blocks of two analysed trips (the second
    after a warm-up trip)."""
    hoist = with_stiffness_factors(scenario_hoist("plain"), [1.0] * 4)
    day = generate_field_day(
        hoist, date="2026-03-02", seed=5, trips=5, hours=5 * 150.0 / 3600,
        sample_rate_hz=20.0, loading_s=5.0, rest_after_s=20.0, oil_temp_c=(30.0, 30.0),
    )  # fmt: skip
    plan = plan_replay(day.sensors, hoist, settle_s=20.0, motion="winder", max_trips=4, blocks=2)
    assert [tr.block for tr in plan.trips] == [0, 0, 1, 1, 1], plan.trips  # a warm-up trip
    assert [tr.first_in_block for tr in plan.trips] == [True, False, True, False, False]
    return plan


def test_blocks_on_threads_replay_as_each_block_alone(two_blocks, monkeypatch):
    plan = two_blocks
    payloads = np.array([9000.0, 8000.0, 10000.0, 7000.0, 8500.0])
    monkeypatch.setattr(replay_module, "REPLAY_THREADS", 2)
    threaded = replay_module.replay(plan, payload_kg=payloads)
    monkeypatch.setattr(replay_module, "REPLAY_THREADS", 1)
    single = replay_module.replay(plan, payload_kg=payloads)
    alone = [
        replay_module.replay(dataclasses.replace(plan, trips=plan.trips[k:j]),
                             payload_kg=payloads[k:j])
        for k, j in ((0, 2), (2, 5))
    ]  # fmt: skip
    expected = [sim for result in alone for sim in result.simulated]
    assert threaded.status == "success"
    for got, one, want in zip(threaded.simulated, single.simulated, expected, strict=True):
        assert np.isfinite(got).all()
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(one, want)
    # a block's second trip starts with its first trip's payload, the block's first its own
    assert threaded.payload_before_kg[1] == payloads[0]
    assert threaded.payload_before_kg[3] == payloads[2]


def _assert_same_replay(got, want):
    """The two replays' results are equal to the last bit."""
    assert (got.status, got.message, got.trip_messages, got.effects) == (
        want.status,
        want.message,
        want.trip_messages,
        want.effects,
    )
    for name in ("payload_kg", "payload_before_kg", "ramps_s"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
    for a, b in zip(
        got.simulated + got.ramp_simulated, want.simulated + want.ramp_simulated, strict=True
    ):
        np.testing.assert_array_equal(a, b)


def test_many_replays_sharing_the_threads_are_each_replay_alone(two_blocks, monkeypatch):
    """``replay_many`` runs the blocks of all its runs on one pool, longest first: each
    result must be exactly the replay of its run alone, on one thread."""
    plan = two_blocks
    base = np.array([9000.0, 8000.0, 10000.0, 7000.0, 8500.0])
    runs = [
        {"payload_kg": base},
        {"payload_kg": base + 500.0, "effects": [*plan.hoist.model.effects][:-1]},
        {"payload_kg": base - 500.0, "ramps_s": None},
        {"payload_kg": np.where(np.arange(5) == 3, np.nan, base)},  # block 2 fails at trip 3
    ]
    monkeypatch.setattr(replay_module, "REPLAY_THREADS", 2)
    together = replay_module.replay_many(plan, runs)
    monkeypatch.setattr(replay_module, "REPLAY_THREADS", 1)
    alone = [replay_module.replay(plan, **run) for run in runs]
    assert len(together) == len(runs)
    assert [r.status for r in together] == ["success"] * 3 + ["failed"]
    assert "not simulated" in together[3].trip_messages[4]
    for got, want in zip(together, alone, strict=True):
        _assert_same_replay(got, want)
    # the runs differ: the payloads and the effects reach the simulation
    assert not np.array_equal(together[0].simulated[0], together[2].simulated[0])
    assert together[1].effects != together[0].effects


def _pass_after_pass(plan, passes, payload_kg=None):
    """``replay_fitted`` as it was before its passes ran as a pipeline (session 47), one
    whole pass after the other with :func:`sims.replay.replay`: the reference."""
    R = replay_module
    hoist = plan.hoist
    names = frozenset(hoist.model.effects)
    parameters = R._parameters(plan, names, None)
    gain, _ = R.sensor_gain_offset(hoist, names, parameters)
    scale = hoist.ropes_n * hoist.cylinders.bore_area_m2 / R.G_STANDARD / float(gain.mean())
    result = R.replay(plan, effects=names, parameters=parameters, payload_kg=payload_kg)
    for _ in range(passes - 1):
        if not any(np.isfinite(sim).any() for sim in result.simulated):
            break  # nothing simulated: nothing to fit (a failed trip leaves the others)
        dp = np.array(
            [float(np.nanmean(r)) if np.isfinite(r).any() else 0.0 for r in result.residuals(plan)]
        )
        pay = np.maximum(result.payload_kg + dp * scale, 0.0)
        threshold = R.loading_threshold_pa(plan.noise_sigma_pa)
        for k, (warm, scored) in enumerate(pairwise(plan.trips)):
            # a warm-up carries the scored trip's payload across a stop without a loading
            if (
                not scored.first_in_block
                and not warm.valid.any()
                and scored.valid.any()
                and abs(scored.p_after_pa - scored.p_before_pa) <= threshold
            ):
                pay[k] = pay[k + 1]
        ramps = np.array([
            R._refine_ramp(tr, sr, rp, d)
            for tr, sr, rp, d in zip(
                plan.trips, result.ramp_simulated, result.ramps_s, dp, strict=True
            )
        ])  # fmt: skip
        result = R.replay(plan, effects=names, parameters=parameters, payload_kg=pay,
                          payload_before_kg=result.payload_before_kg, ramps_s=ramps)  # fmt: skip
    return result


def _one_chain(plan):
    """The plan's trips as one block (the sanity check's chain of a whole record)."""
    trips = tuple(
        dataclasses.replace(tr, block=0, first_in_block=k == 0) for k, tr in enumerate(plan.trips)
    )
    return dataclasses.replace(plan, trips=trips)


PAYLOADS = np.array([9000.0, 8000.0, 10000.0, 7000.0, 8500.0])


@pytest.mark.parametrize(
    ("case", "passes"),
    [("two blocks", 3), ("one chain", 3), ("static payloads", 2), ("a trip fails", 3),
     ("nothing simulates", 3), ("no trip", 3), ("one pass", 1)],
)  # fmt: skip
def test_fitted_passes_run_as_a_pipeline_give_pass_after_pass(
    two_blocks, case, passes, monkeypatch
):
    """The passes of ``replay_fitted`` run as a pipeline (a trip's next pass starts once
    its own pass is done), each block and pass on a thread: the result is exactly the
    parent's passes one after the other, as on one thread -- for one chain, two blocks,
    payloads from the static pressure, a trip that fails (its block's later trips not
    simulated), a fit where nothing simulates (the first pass is the result) and a plan
    without trips."""
    plan = _one_chain(two_blocks) if case == "one chain" else two_blocks
    payloads = None if case == "static payloads" else PAYLOADS
    if case == "a trip fails":  # block 2 fails at trip 3
        payloads = np.where(np.arange(5) == 3, np.nan, PAYLOADS)
    if case == "nothing simulates":
        payloads = np.full(5, np.nan)
    if case == "no trip":
        plan = dataclasses.replace(plan, trips=())
        payloads = np.zeros(0)
    monkeypatch.setattr(replay_module, "REPLAY_THREADS", 1)
    want = _pass_after_pass(plan, passes, payloads)
    monkeypatch.setattr(replay_module, "REPLAY_THREADS", 2)
    piped = replay_module.replay_fitted(plan, passes=passes, payload_kg=payloads)
    one = replay_module.side_by_side(
        [lambda: replay_module.replay_fitted(plan, passes=passes, payload_kg=payloads)]
    )[0]
    expected_status = {"a trip fails": "failed", "nothing simulates": "failed"}
    assert want.status == expected_status.get(case, "success")
    if case in ("two blocks", "one chain", "static payloads"):  # the passes moved them
        initial = replay_module.replay(plan).payload_kg if payloads is None else payloads
        assert not np.array_equal(want.payload_kg, initial)
    for got in (piped, one):
        _assert_same_replay(got, want)


def test_a_warm_up_carries_the_payload_across_a_stop_without_a_loading(two_blocks, monkeypatch):
    """A block's warm-up trip (no scored sample) has only its levels at rest for its
    payload, and those hold what the seals held there (validation trial_001 cut by an
    outage: the scored trip after a warm-up, stopped without a loading, replayed 137 kPa
    off at its window's start). Where the scored trip after it stopped without a loading
    (its levels before and after within the loading threshold), the payload is the same
    on both sides: from the second pass the warm-up carries that trip's fitted payload.
    Where the stop shows a loading (this plan's, ~3 t), the warm-up keeps its own.
    The warm-up's level is read 600 kg high here (the seals holding 5.9 kN, about what
    four validation seals hold)."""
    plan = two_blocks
    k = 2  # block 1's warm-up, then two scored trips
    assert not plan.trips[k].valid.any()
    assert plan.trips[k + 1].valid.any()
    hoist = plan.hoist
    pa_per_kg = replay_module.G_STANDARD / (hoist.ropes_n * hoist.cylinders.bore_area_m2)
    warm, scored = plan.trips[k], plan.trips[k + 1]
    held = dataclasses.replace(warm, p_after_pa=warm.p_after_pa + 600 * pa_per_kg)

    def with_trips(*trips):
        return dataclasses.replace(plan, trips=(*plan.trips[:k], *trips, *plan.trips[k + 2 :]))

    loaded = with_trips(held, scored)
    unloaded = with_trips(held, dataclasses.replace(scored, p_before_pa=scored.p_after_pa))
    assert (scored.p_after_pa - scored.p_before_pa) / pa_per_kg > 1000.0  # a loading
    own = replay_module.replay(loaded).payload_kg[k]  # the warm-up's levels' payload
    fitted = {name: replay_module.replay_fitted(p, passes=3) for name, p in
              (("loaded", loaded), ("unloaded", unloaded))}  # fmt: skip
    monkeypatch.setattr(replay_module._FittedPasses, "_warm_up_tie", lambda self, k: False)
    untied = replay_module.replay_fitted(unloaded, passes=3)
    # across the loading the warm-up keeps its own payload, as without the tie
    assert fitted["loaded"].payload_kg[k] == own
    # across a stop without one it carries the scored trip's (as the pass before fitted
    # it: within what the last pass moved it), which starts from it
    tied = fitted["unloaded"]
    assert tied.payload_before_kg[k + 1] == tied.payload_kg[k]
    assert abs(tied.payload_kg[k] - tied.payload_kg[k + 1]) < 30.0
    assert abs(own - tied.payload_kg[k + 1]) > 400.0
    assert untied.payload_kg[k] == own


def test_an_error_in_a_later_pass_is_raised_and_the_others_stop(two_blocks, monkeypatch):
    """A simulation that raises in the second pass: that error is raised (not the other
    tasks' giving up), no task hangs, and the passes after it stop at their next trip."""

    class Broken(Exception):
        pass

    calls = []
    real = replay_module._simulate_trip

    def simulate(plan, tr, *args):
        calls.append(tr.trip_id)
        if tr.trip_id == 3 and calls.count(3) == 2:  # trip 3's second pass
            raise Broken("the device broke")
        return real(plan, tr, *args)

    monkeypatch.setattr(replay_module, "_simulate_trip", simulate)
    monkeypatch.setattr(replay_module, "REPLAY_THREADS", 2)
    with pytest.raises(Broken, match="the device broke"):
        replay_module.replay_fitted(two_blocks, passes=3, payload_kg=PAYLOADS)
    assert len(calls) < 3 * len(two_blocks.trips)  # the third pass did not run whole


def test_a_planned_trip_holds_what_it_was_planned_with(two_blocks):
    """A replay's answer is remembered by the very trips (``first_trips_gap``): their
    arrays cannot be written."""
    trip = two_blocks.trips[1]
    with pytest.raises(ValueError, match="read-only"):
        trip.measured_pa[0, 0] = 0.0
    with pytest.raises(ValueError, match="read-only"):
        trip.time_s[0] = 0.0


def test_an_older_jacobian_changes_a_hard_replay_by_a_hundredth_of_the_noise(
    two_blocks, monkeypatch
):
    """The replay refreshes the device's Jacobian every ``REPLAY_JACOBIAN_EVERY`` steps.
    ROS2 is a W-method (second order for any Jacobian) that retakes a step whose error
    jumps, so on the stiffest device the contract allows (a throttled valve, K = 3e5)
    with ringing ropes (damping ratio 0.03) the replay must stay within 1 % of the sensor
    noise (5 kPa) of the one with a fresh Jacobian at every step."""
    hoist = two_blocks.hoist
    ropes = hoist.ropes.model_copy(update={"head_rope_damping_ratio": 0.03})
    piping = hoist.piping.model_copy(update={"valve_loss_coefficient": 3e5})
    stiff = hoist.model_copy(update={"ropes": ropes, "piping": piping})
    assert "local_loss" in hoist.model.effects  # the valve's loss is simulated
    plan = dataclasses.replace(two_blocks, hoist=stiff, trips=two_blocks.trips[:2])
    payloads = np.array([9000.0, 8000.0])
    assert replay_module.REPLAY_JACOBIAN_EVERY > 1
    older = replay_module.replay(plan, payload_kg=payloads)
    monkeypatch.setattr(replay_module, "REPLAY_JACOBIAN_EVERY", 1)
    fresh = replay_module.replay(plan, payload_kg=payloads)
    assert older.status == fresh.status == "success", (older.message, fresh.message)
    diff = np.concatenate([a - b for a, b in zip(older.simulated, fresh.simulated, strict=True)])
    assert np.isfinite(diff).all()
    swing = np.ptp(np.concatenate(fresh.simulated))
    assert swing > 1e6  # the trips load, accelerate and stop: pressures move by MPa
    assert np.sqrt(np.mean(diff**2)) < 50.0


def test_a_block_deep_in_the_shaft_starts_its_pistons_where_logged_with_a_groove_wear(
    two_blocks,
):
    """A block starts with its pistons where the record logged them (the ropes' length
    offsets applied); a groove's payout counts from the pithead (z dr_i / R, as the
    compensation's rope law reads it), so a block that starts at the bottom keeps its
    logged positions with a groove wear in the model: given as the simulation's
    parameters, or described by the hoist's drum and not given (the radii the device
    resolves). Before session 57 the device took the payout there off the logged
    positions: 600 m x 2e-5 / R ~ 8 mm per rope."""
    plan = dataclasses.replace(two_blocks, rope_offsets_m=(0.0,) * 4)
    logged = np.array([1.0e-3, -0.5e-3, 0.2e-3, -0.7e-3])
    tr = dataclasses.replace(two_blocks.trips[1], x_start_m=logged)
    assert tr.start_depth_m > 300.0  # the up trip starts at the bottom
    radii = [0.0, 2e-5, -2e-5, 1e-5]
    grooves = {"groove_wear": {"groove_radius_deviation_m": radii}}
    worn = plan.hoist.model_copy(
        update={"drum": plan.hoist.drum.model_copy(update={"groove_radius_deviation_m": radii})}
    ).with_effects([*plan.hoist.model.effects, "groove_wear"])
    fx = frozenset({"seal_friction", "oil_compressibility"})
    cases = [
        (plan, fx, {}),  # no groove
        (plan, fx | {"groove_wear"}, grooves),  # the groove given
        (dataclasses.replace(plan, hoist=worn), fx | {"groove_wear"}, {}),  # described
    ]
    for case, names, prm in cases:
        pistons = replay_module.block_pistons(case, tr, names, prm, tr.start_depth_m)
        run = simulate(
            case.hoist, hold(depth_m=tr.start_depth_m, duration_s=0.5), effects=names,
            parameters=prm, pistons_m=pistons,
        )  # fmt: skip
        assert run.ok, run.message
        first = np.array([float(run.frame[f"x{i}_m"][0]) for i in range(1, 5)])
        np.testing.assert_allclose(first - first.mean(), logged - logged.mean(), atol=1e-9)
