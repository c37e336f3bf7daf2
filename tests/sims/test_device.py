"""The four-cylinder connection device: effects, sanity against Table 2, paper 3.2."""

from __future__ import annotations

import math

import numpy as np
import polars as pl
import pytest

from discovery.rope_stiffness import with_stiffness_factors
from physics.friction_law import friction_parameters
from schemas.effects import EFFECT_NAMES
from schemas.hoist import EXAMPLE_HOIST, G_STANDARD, load_hoist
from sims.device import (
    OUTPUT_COLUMNS,
    SCENARIO_3_2_LOAD_N,
    DeviceState,
    paper_scenario_3_2,
    simulate,
)
from sims.device_model import _segment_at, constant_until
from sims.effects import EFFECT_REGISTRY, resolve_effects
from sims.trips import hold, trip

ALL = set(EFFECT_NAMES)


@pytest.fixture(scope="module")
def hoist():
    return load_hoist(EXAMPLE_HOIST)


@pytest.fixture(scope="module")
def down_trip(hoist):
    """Pithead -> middle (320 m), then 40 s at rest, every effect on."""
    profile = trip(hoist, start_depth_m=0.0, end_depth_m=320.0, rest_after_s=40.0)
    result = simulate(hoist, profile, effects=ALL)
    assert result.status == "success", result.message
    return result


# --- effects by name -------------------------------------------------------------------
def test_registry_covers_contract_names():
    assert tuple(EFFECT_REGISTRY) == EFFECT_NAMES


def test_unknown_effect_name_lists_valid_ones(hoist):
    with pytest.raises(ValueError, match=r"unknown effect name 'seal_fricton'.*seal_friction"):
        simulate(hoist, hold(depth_m=0, duration_s=0.1), effects={"seal_fricton"})
    with pytest.raises(ValueError, match=r"unknown parameter 'offset'.*offset_pa"):
        resolve_effects(hoist, {"sensor_offset"}, {"sensor_offset": {"offset": 1.0}})
    with pytest.raises(ValueError, match="not switched on"):
        resolve_effects(hoist, {"seal_friction"}, {"sensor_gain": {"gains": [1, 1, 1, 1]}})
    with pytest.raises(ValueError, match="needs 'seal_friction'"):
        simulate(hoist, hold(depth_m=0, duration_s=0.1), effects={"presliding_hysteresis"})


def test_default_effects_are_the_hoists(hoist):
    assert resolve_effects(hoist).enabled == frozenset(hoist.model.effects)


# --- outputs and conservation ----------------------------------------------------------
def test_columns_and_rate(down_trip):
    frame = down_trip.frame
    assert tuple(frame.columns) == OUTPUT_COLUMNS
    assert np.allclose(np.diff(frame["time_s"].to_numpy()), 0.01)


def test_oil_volume_conserved(down_trip, hoist):
    vol = down_trip.frame["oil_volume_m3"].to_numpy()
    # the pistons move oil between chambers, pipes and manifold and compress it by
    # several 1e-5 m3 (Delta p V / beta); the reference-pressure volume stays put
    compressed = hoist.oil_volume_m3 * 5e6 / hoist.oil.bulk_modulus_pa
    assert vol[0] == pytest.approx(hoist.oil_volume_m3 + compressed, rel=1e-3)
    assert np.abs(vol - vol[0]).max() / vol[0] < 1e-8


def test_static_hang_matches_table2_total_mass(down_trip):
    # paper Table 2, middle of the pit: total mass 11.92 t (8.2 t cage + 300 m x 2 x 6.2 kg/m)
    rest = down_trip.frame.filter(pl.col("time_s") > down_trip.frame["time_s"].max() - 20.0)
    assert rest["load_n"].mean() / G_STANDARD == pytest.approx(11_920.0, rel=0.005)
    assert rest["speed_m_s"].abs().max() == 0.0


# --- friction shows in the sum (NOTES.md) -----------------------------------------------
def _loading(hoist, effects, payload_kg):
    profile = hold(depth_m=320.0, duration_s=20.0, payload_time_s=[1.0, 6.0], payload_kg=payload_kg)
    r = simulate(hoist, profile, effects=effects)
    assert r.status == "success", r.message
    last = r.frame.filter(pl.col("time_s") > 15.0)
    area = hoist.cylinders.bore_area_m2
    sensed = sum(last[f"p_sensor{i}_pa"] for i in range(1, 5)) * area
    return float((sensed - last["load_n"]).mean()), last, r.frame


@pytest.mark.parametrize("payload", [[0.0, 6000.0], [6000.0, 0.0]])
def test_sensor_reads_low_while_oil_flows_out_high_while_in(hoist, payload):
    fx = {"tail_rope_weight", "oil_compressibility", "pipe_laminar_loss", "local_loss"}
    *_, frame = _loading(hoist, fx, payload)
    ramp = frame.filter((pl.col("time_s") > 2.0) & (pl.col("time_s") < 5.0))
    for i in range(1, 5):
        q = ramp[f"q{i}_m3_s"].to_numpy()
        drop = (ramp[f"p_sensor{i}_pa"] - ramp[f"p_chamber{i}_pa"]).to_numpy()
        # load rising: oil compressed, flows out of the chambers (q > 0), sensor low
        assert np.all(np.sign(q) == (1 if payload[1] > payload[0] else -1))
        assert np.all(np.sign(drop) == -np.sign(q))
    at_rest = frame.filter(pl.col("time_s") < 0.9)
    assert (at_rest["p_sensor1_pa"] - at_rest["p_chamber1_pa"]).abs().max() == 0.0


def test_seal_friction_sensors_low_after_load_increase_high_after_decrease(hoist):
    fx = {"seal_friction", "tail_rope_weight", "oil_compressibility", "pipe_laminar_loss"}
    gap_up, last, _ = _loading(hoist, fx, [0.0, 6000.0])
    gap_down, _, _ = _loading(hoist, fx, [6000.0, 0.0])
    p = float(last["p_chamber1_pa"].mean())
    fc, fs, _, _ = (float(a) for a in friction_parameters(p, hoist.friction_law))
    # the pistons slid out as the oil compressed (~0.3 mm, far past presliding) and
    # stuck: every seal holds friction in the same direction, at most Fs each; the rope
    # bounce afterwards lets the LuGre bristles creep back somewhat, not to zero
    assert -4 * 1.05 * fs < gap_up < -4 * 0.3 * fc
    assert 4 * 0.3 * fc < gap_down < 4 * 1.05 * fs
    no_friction, _, _ = _loading(hoist, fx - {"seal_friction"}, [0.0, 6000.0])
    assert abs(no_friction) < 0.01 * abs(gap_up)


# --- continuing from a final state (a day is one continuous history) --------------------
_LOADING = {"payload_time_s": [1.0, 6.0], "payload_kg": [0.0, 6000.0]}
_BASE_FX = {"tail_rope_weight", "oil_compressibility", "pipe_laminar_loss", "local_loss"}


@pytest.mark.parametrize(
    "friction_fx",
    [{"seal_friction"}, {"seal_friction", "presliding_hysteresis"}],
    ids=["lugre", "maxwell-slip"],
)
def test_continuing_from_final_state_keeps_friction_and_pressures(hoist, friction_fx):
    """Loading then standing still: a run continued from the final state is the same
    history as one long run -- the seals keep their friction, no pressure step."""
    fx = _BASE_FX | friction_fx
    full = simulate(hoist, hold(depth_m=320.0, duration_s=25.0, **_LOADING), effects=fx)
    first = simulate(hoist, hold(depth_m=320.0, duration_s=20.0, **_LOADING), effects=fx)
    state = first.final_state
    assert isinstance(state, DeviceState)
    assert state.payload_kg == 6000.0
    assert state.depth_m == 320.0
    memory = state.maxwell_slip_m if "presliding_hysteresis" in fx else state.lugre_z_m
    assert np.all(memory.any(axis=-1) if memory.ndim > 1 else memory != 0)
    rest = hold(depth_m=320.0, duration_s=5.0, payload_kg=[6000.0])
    cont = simulate(hoist, rest, effects=fx, initial_state=state)
    fresh = simulate(hoist, rest, effects=fx)  # the old behaviour: friction released
    assert cont.ok
    assert fresh.ok
    end, start = first.frame.tail(1), cont.frame.head(1)
    tail = full.frame.filter(pl.col("time_s") > 20.0 - 1e-6)
    assert tail.height == cont.frame.height
    for i in range(1, 5):
        p = float(end[f"p_chamber{i}_pa"].item())
        fc, fs, _, _ = (float(a) for a in friction_parameters(p, hoist.friction_law))
        held = float(end[f"friction{i}_n"].item())
        assert abs(held) > 0.3 * fc  # the pistons slid as the oil compressed and stuck
        # no step at the restart: pressures, sensor and pistons exact, friction up to the
        # last step's viscous / bristle-damping share (the piston is at rest now)
        for col in (f"p_chamber{i}_pa", f"p_sensor{i}_pa", f"x{i}_m", "p_manifold_pa"):
            assert float(start[col].item()) == float(end[col].item())
        assert float(start[f"friction{i}_n"].item()) == pytest.approx(held, abs=1e-4 * fs)
        # the continued history is the one-run history (same steps, same Jacobians)
        for col in (f"p_chamber{i}_pa", f"p_sensor{i}_pa", f"tension{i}_n"):
            assert np.abs(cont.frame[col].to_numpy() - tail[col].to_numpy()).max() < 1.0
        assert (
            np.abs(
                cont.frame[f"friction{i}_n"].to_numpy() - tail[f"friction{i}_n"].to_numpy()
            ).max()
            < 1e-4 * fs
        )
        # starting afresh instead releases the friction: the pressure steps by ~F / A
        step = float(fresh.frame[f"p_chamber{i}_pa"][0]) - p
        assert step == pytest.approx(held / hoist.cylinders.bore_area_m2, rel=0.1)
    vol = np.concatenate([first.frame["oil_volume_m3"], cont.frame["oil_volume_m3"]])
    assert np.abs(vol - vol[0]).max() / vol[0] < 1e-8


def test_continuation_must_match_the_profile_start(hoist):
    fx = _BASE_FX | {"seal_friction"}
    state = simulate(
        hoist, hold(depth_m=320.0, duration_s=2.0, payload_kg=[3000.0]), effects=fx
    ).final_state
    ok = simulate(
        hoist,
        hold(depth_m=320.03, duration_s=0.1, payload_kg=[3000.0]),
        effects=fx,
        initial_state=state,
    )
    assert ok.ok  # a few cm are tolerated
    with pytest.raises(ValueError, match=r"depth 320\.000 m.*starts at 300\.000 m"):
        simulate(
            hoist,
            hold(depth_m=300.0, duration_s=0.1, payload_kg=[3000.0]),
            effects=fx,
            initial_state=state,
        )
    with pytest.raises(ValueError, match=r"payload of 3000 kg.*with 2500 kg"):
        simulate(
            hoist,
            hold(depth_m=320.0, duration_s=0.1, payload_kg=[2500.0]),
            effects=fx,
            initial_state=state,
        )
    with pytest.raises(ValueError, match="other effects"):
        simulate(
            hoist,
            hold(depth_m=320.0, duration_s=0.1, payload_kg=[3000.0]),
            effects=_BASE_FX,
            initial_state=state,
        )
    with pytest.raises(ValueError, match="other effect parameters"):
        simulate(
            hoist,
            hold(depth_m=320.0, duration_s=0.1, payload_kg=[3000.0]),
            effects=fx,
            parameters={"oil_compressibility": {"bulk_modulus_pa": 1.2e9}},
            initial_state=state,
        )


def test_sensor_offset_override_by_name(hoist):
    r = simulate(
        hoist,
        hold(depth_m=0.0, duration_s=0.5),
        effects={"sensor_offset", "tail_rope_weight"},
        parameters={"sensor_offset": {"sensor": 2, "offset_pa": 5e4}},
    )
    f = r.frame
    diff = [float((f[f"p_sensor{i}_pa"] - f[f"p_chamber{i}_pa"]).abs().max()) for i in range(1, 5)]
    assert diff[1] == pytest.approx(5e4, rel=1e-9)
    assert max(diff[0], diff[2], diff[3]) < 1e-6
    # Table 2 pithead total mass 15.888 t
    assert f["load_n"].mean() / G_STANDARD == pytest.approx(15_888.0, rel=1e-6)


def test_groove_wear_spreads_pistons_with_travel(hoist):
    dev = [0.0, 2e-4, 0.0, -2e-4]
    profile = trip(hoist, start_depth_m=0.0, end_depth_m=320.0, rest_after_s=10.0)
    r = simulate(
        hoist,
        profile,
        effects={"groove_wear", "tail_rope_weight", "oil_compressibility", "pipe_laminar_loss"},
        parameters={"groove_wear": {"groove_radius_deviation_m": dev}},
    )
    end = r.frame.tail(1)
    # rope i pays out 320 m x dr_i / R more; its piston takes that up (pulled in)
    expected = -320.0 * 2e-4 / hoist.drum.radius_m
    assert float((end["x2_m"] - end["x1_m"]).item()) == pytest.approx(expected, rel=0.02)
    assert float((end["x4_m"] - end["x1_m"]).item()) == pytest.approx(-expected, rel=0.02)


# --- paper section 3.2 ------------------------------------------------------------------
@pytest.fixture(scope="module")
def scenario():
    r = paper_scenario_3_2()
    assert r.status == "success", r.message
    return r


def _spread(frame, t0, t1):
    w = frame.filter((pl.col("time_s") >= t0) & (pl.col("time_s") <= t1))
    p = np.column_stack([w[f"p_chamber{i}_pa"].to_numpy() for i in range(1, 5)])
    return p.max(axis=1) - p.min(axis=1), p.mean(axis=1)


def test_scenario_pressures_equalise(scenario):
    area = np.pi * 0.08**2 / 4
    # during the ramps oil flows between the cylinders (pistons at ~5 mm/s) and the
    # pressures differ by the branches' laminar drop, 128 mu l q / (pi d^4) ~ 35 kPa each
    ramp, mean = _spread(scenario.frame, 1.0, 2.95)
    assert np.all(ramp < 0.12 * mean)
    # after the load change the balancing flow relaxes with R A^2 / k ~ 0.7 s per branch
    spread, mean = _spread(scenario.frame, 5.9, 5.95)
    assert spread.max() < 0.01 * mean.min()
    # at rest the pressure carries the mean load, the pistons take up the spread (k = 5e4 N/m)
    _, mean = _spread(scenario.frame, 5.9, 5.95)
    assert mean.mean() * area == pytest.approx(SCENARIO_3_2_LOAD_N[-1].mean(), rel=0.01)
    end = scenario.frame.tail(1)
    expected = (SCENARIO_3_2_LOAD_N[-1] - SCENARIO_3_2_LOAD_N[-1].mean()) / 5e4
    got = [float(end[f"x{i}_m"].item()) for i in range(1, 5)]
    assert got == pytest.approx(list(expected), abs=1e-3)


def test_scenario_pressure_shock_after_step_decays(scenario):
    shock, mean = _spread(scenario.frame, 3.0, 3.3)
    before, _ = _spread(scenario.frame, 2.5, 2.95)
    late, _ = _spread(scenario.frame, 4.0, 6.0)
    assert shock.max() > 0.05 * mean.mean()  # visible
    assert shock.max() > 10 * before.max()
    assert late.max() < 0.1 * shock.max()  # decays


def test_scenario_without_pipe_characteristics_also_equalises():
    r = paper_scenario_3_2(pipe_characteristics=False, duration_s=3.0)
    spread, mean = _spread(r.frame, 2.5, 2.95)
    assert spread.max() < 0.01 * mean.min()


# --- head ropes of different stiffness ---------------------------------------------------
_FACTORS = [0.96, 1.03, 0.99, 1.02]


def test_ropes_of_different_stiffness_start_at_equal_tension(hoist):
    """Static start: the pipes equalise the pressures, so every rope carries W / n and
    the softer ropes stretch further; the pistons take the difference up."""
    stiff = with_stiffness_factors(hoist, _FACTORS)
    r = simulate(stiff, hold(depth_m=320.0, duration_s=0.5), effects={"oil_compressibility"})
    assert r.status == "success", r.message
    first = r.frame.head(1)
    tensions = np.array([float(first[f"tension{i}_n"].item()) for i in range(1, 5)])
    np.testing.assert_allclose(tensions, tensions.mean(), rtol=1e-9)
    k = hoist.ropes.head_rope_axial_stiffness_n / (hoist.shaft.headframe_height_m + 320.0)
    stretch = tensions.mean() / (k * np.array(_FACTORS))
    x = np.array([float(first[f"x{i}_m"].item()) for i in range(1, 5)])
    np.testing.assert_allclose(x - x.mean(), -(stretch - stretch.mean()), atol=1e-9)


def test_stuck_pistons_share_a_load_change_by_rope_stiffness(hoist):
    """Seals that never break away: a payload loaded at rest is shared in proportion to
    the ropes' stiffness, dT_i = f_i / sum(f) dW (rigid attachments, the conveyance one
    body); with free pistons the pipes would share it equally."""
    stiff = with_stiffness_factors(hoist, _FACTORS)
    held = {
        "seal_friction": {
            "coulomb_n": [4e5, 0.0],
            "static_n": [4e5, 0.0],
            "bristle_stiffness_n_m": 2e8,
        }
    }
    profile = hold(
        depth_m=320.0, duration_s=40.0, payload_time_s=[1.0, 6.0], payload_kg=[0.0, 6000.0]
    )
    r = simulate(stiff, profile, effects={"seal_friction", "oil_compressibility"}, parameters=held)
    assert r.status == "success", r.message
    before = r.frame.filter(pl.col("time_s") < 0.9)
    after = r.frame.filter(pl.col("time_s") > 30.0)
    d_t = np.array(
        [float(after[f"tension{i}_n"].mean() - before[f"tension{i}_n"].mean()) for i in range(1, 5)]
    )
    d_w = 6000.0 * G_STANDARD
    np.testing.assert_allclose(d_t, d_w * np.array(_FACTORS) / sum(_FACTORS), rtol=5e-3)


# --- a start with the pistons where a record logged them -----------------------------------
_GROOVES_M = [0.0, 2e-4, -1e-4, 1e-4]


@pytest.mark.parametrize(
    "friction_fx",
    [
        {"seal_friction"},
        {"seal_friction", "presliding_hysteresis"},
        {"seal_friction", "groove_wear"},
    ],
    ids=["lugre", "maxwell-slip", "lugre-groove-wear"],
)
def test_pistons_started_where_given_stay_and_their_seals_hold_the_ropes_imbalance(
    hoist, friction_fx
):
    """``pistons_m``: at rest eq 2 gives T_i = p A + F_i with the pipes' equal p, so with
    the pistons placed (not where equal tensions put them) each seal holds its rope's
    share of the imbalance, T_i = k f_i (eta - u_i), sum T_i = W (hand-computed here), and
    nothing moves. The positions are in the ropes' frame (u_i, a rope's whole imbalance):
    with a groove wear in the model the pistons sit its offsets o_i = depth dr_i / R
    away, x_i = u_i - o_i (means zero)."""
    stiff = with_stiffness_factors(hoist, _FACTORS)
    fx = friction_fx | {"oil_compressibility"}
    depth = 320.0
    placed = np.array([0.6e-3, -0.4e-3, 0.1e-3, -0.3e-3]) + 5e-3  # the mean does not count
    grooves = {"groove_wear": {"groove_radius_deviation_m": _GROOVES_M}}
    r = simulate(
        stiff, hold(depth_m=depth, duration_s=5.0), effects=fx, pistons_m=placed,
        parameters=grooves if "groove_wear" in fx else None,
    )  # fmt: skip
    assert r.ok, r.message
    weight = hoist.conveyance.mass_kg * G_STANDARD
    k = hoist.ropes.head_rope_axial_stiffness_n / (hoist.shaft.headframe_height_m + depth)
    f = np.array(_FACTORS)
    u = placed - placed.mean()
    offsets = depth * np.array(_GROOVES_M) / hoist.drum.radius_m if "groove_wear" in fx else 0.0
    x = u - offsets + np.mean(offsets)
    eta = (weight / k + np.sum(f * u)) / np.sum(f)
    tension = k * f * (eta - u)
    area = hoist.cylinders.bore_area_m2
    p0 = weight / (4 * area)
    first, last = r.frame.head(1), r.frame.tail(1)
    _, fs, _, _ = (float(a) for a in friction_parameters(p0, hoist.friction_law))
    assert np.abs(tension - weight / 4).max() > 0.1 * fs  # an imbalance worth holding
    assert np.abs(tension - weight / 4).max() < fs
    for i in range(1, 5):
        assert float(first[f"x{i}_m"].item()) == pytest.approx(x[i - 1], abs=1e-12)
        assert float(first[f"tension{i}_n"].item()) == pytest.approx(tension[i - 1], rel=1e-9)
        assert float(first[f"p_chamber{i}_pa"].item()) == pytest.approx(p0, rel=1e-12)
        held = tension[i - 1] - p0 * area
        assert float(first[f"friction{i}_n"].item()) == pytest.approx(held, abs=1e-3 * fs)
        # held: the pistons stay and so do the forces
        assert abs(float(last[f"x{i}_m"].item()) - x[i - 1]) < 1e-7
        assert float(last[f"friction{i}_n"].item()) == pytest.approx(held, abs=1e-2 * fs)


def test_a_piston_placed_beyond_what_its_seal_holds_slides_and_without_seals_none_is_held(
    hoist,
):
    """A seal holds at most its static friction F_s: a piston placed 10 mm off equal
    tension (a rope imbalance of several F_s at 320 m) starts at F_s and slides; without
    seal friction nothing holds a piston and the start is the equal-tension one."""
    stiff = with_stiffness_factors(hoist, _FACTORS)
    placed = np.array([10e-3, -10e-3 / 3, -10e-3 / 3, -10e-3 / 3])
    fx = {"seal_friction", "oil_compressibility"}
    r = simulate(stiff, hold(depth_m=320.0, duration_s=5.0), effects=fx, pistons_m=placed)
    assert r.ok, r.message
    p0 = hoist.conveyance.mass_kg * G_STANDARD / (4 * hoist.cylinders.bore_area_m2)
    _, fs, _, _ = (float(a) for a in friction_parameters(p0, hoist.friction_law))
    first, last = r.frame.head(1), r.frame.tail(1)
    assert abs(float(first["friction1_n"].item())) == pytest.approx(fs, rel=1e-3)
    assert abs(float(last["x1_m"].item()) - float(first["x1_m"].item())) > 0.1e-3
    free = simulate(stiff, hold(depth_m=320.0, duration_s=0.5), effects={"oil_compressibility"},
                    pistons_m=placed)  # fmt: skip
    equal = simulate(stiff, hold(depth_m=320.0, duration_s=0.5), effects={"oil_compressibility"})
    for i in range(1, 5):
        assert float(free.frame[f"x{i}_m"][0]) == float(equal.frame[f"x{i}_m"][0])


# --- a device at rest is held, not stepped ----------------------------------------------
def test_the_forcing_is_constant_until_the_winder_moves_or_a_knot_changes_it():
    # rest until 5 s, accelerate at 1 m/s2 until 10 s, run at 5 m/s
    seg = np.array([[0.0, 0.0, 0.0, 0.0], [5.0, 0.0, 0.0, 1.0], [10.0, 12.5, 5.0, 0.0]])
    flat_src_t, flat_src = np.array([0.0]), np.zeros((1, 4))
    no_load = np.array([[0.0, 0.0]])
    assert constant_until(1.0, seg, no_load, flat_src_t, flat_src) == 5.0
    assert constant_until(6.0, seg, no_load, flat_src_t, flat_src) == 6.0  # accelerating
    assert constant_until(11.0, seg, no_load, flat_src_t, flat_src) == 11.0  # running
    # loading from 2 s to 4 s (a flat knot pair before it changes nothing)
    loading = np.array([[0.5, 0.0], [2.0, 0.0], [4.0, 6000.0]])
    assert constant_until(1.0, seg, loading, flat_src_t, flat_src) == 2.0
    assert constant_until(3.0, seg, loading, flat_src_t, flat_src) == 3.0
    assert constant_until(4.5, seg, loading, flat_src_t, flat_src) == 5.0
    # a step (a repeated knot) at 5 s with the winder at rest: at 5 s the value is the
    # one before it, about to change
    at_rest = np.array([[0.0, 7.0, 0.0, 0.0]])
    step = np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 6000.0], [10.0, 6000.0]])
    assert constant_until(1.0, at_rest, step, flat_src_t, flat_src) == 5.0
    assert constant_until(5.0, at_rest, step, flat_src_t, flat_src) == 5.0
    assert constant_until(5.5, at_rest, step, flat_src_t, flat_src) == math.inf
    # at a segment's start the segment applies; a ramp's last point is still on it
    assert constant_until(5.0, seg, no_load, flat_src_t, flat_src) == 5.0
    assert constant_until(10.0, seg, no_load, flat_src_t, flat_src) == 10.0
    ramp = np.array([[2.0, 0.0], [4.0, 6000.0], [9.0, 6000.0]])
    assert constant_until(4.0, seg, ramp, flat_src_t, flat_src) == 4.0
    assert constant_until(4.001, seg, ramp, flat_src_t, flat_src) == 5.0
    # a logged rest is a run of segments at rest at one depth: one span to the motion
    logged = np.array([[0.0, 7.0, 0.0, 0.0], [0.1, 7.0, 0.0, 0.0], [0.2, 7.0, 0.0, 0.0],
                       [0.3, 7.0, 0.0, 0.5], [0.4, 7.0025, 0.05, 0.0]])  # fmt: skip
    assert constant_until(0.05, logged, no_load, flat_src_t, flat_src) == 0.3
    moved = logged.copy()
    moved[2, 1] = 7.001  # at rest elsewhere: a change of depth
    assert constant_until(0.05, moved, no_load, flat_src_t, flat_src) == 0.2
    # one rope's source offset steps at 3 s
    src_t = np.array([0.0, 3.0, 3.5])
    src = np.zeros((3, 4))
    src[2, 1] = 1e-3
    assert constant_until(0.5, seg, no_load, src_t, src) == 3.0
    assert constant_until(4.0, at_rest, no_load, src_t, src) == math.inf


def test_the_profile_segment_is_the_last_started_as_a_scan_finds_it():
    rng = np.random.default_rng(7)
    starts = np.cumsum(rng.uniform(0.01, 2.0, 40))
    seg = np.column_stack([starts, np.zeros((40, 3))])
    times = np.concatenate([starts, np.nextafter(starts, -np.inf),
                            np.nextafter(starts, np.inf), [starts[0] - 1.0, starts[-1] + 1.0],
                            rng.uniform(starts[0] - 1.0, starts[-1] + 1.0, 200)])  # fmt: skip
    for t in times:
        scan = max([j for j in range(40) if starts[j] <= t], default=0)
        assert _segment_at(t, seg) == scan, t


@pytest.mark.parametrize(
    "profile",
    [
        # the winder starts between steps: one starting on a step could start a step
        # later in the stepped run, whose clock sums the steps' increments
        trip(hoist=load_hoist(EXAMPLE_HOIST), start_depth_m=0.0, end_depth_m=320.0,
             rest_before_s=20.0004, rest_after_s=30.0),
        hold(depth_m=320.0, duration_s=40.0, payload_time_s=[10.0, 15.0],
             payload_kg=[0.0, 6000.0]),
    ],
    ids=["trip", "loading"],
)  # fmt: skip
def test_a_device_held_at_rest_matches_one_stepped_through_it(hoist, profile):
    """The rests before and after a trip, or around a loading at rest, held instead of
    stepped: the pressures and the load stay within a hundredth of the sensor's 1 kPa
    resolution of every step taken, and the rest up to the first change of forcing (the
    static start) is held."""
    # a Jacobian every 7th step: the first hold ends off that schedule, so the run must
    # factor an iteration matrix of its own after a hold from its start
    held = simulate(hoist, profile, effects=ALL, jacobian_every=7)
    stepped = simulate(hoist, profile, effects=ALL, jacobian_every=7, hold_at_rest=False)
    assert held.status == stepped.status == "success"
    assert stepped.solver["steps_held_at_rest"] == 0
    # the static start is held to the first change of forcing: the first 10 s at least
    assert held.solver["steps_held_at_rest"] * held.solver["dt_s"] >= 10.0
    for col in [*(f"p_sensor{i}_pa" for i in range(1, 5)), "p_manifold_pa"]:
        diff = held.frame[col].to_numpy() - stepped.frame[col].to_numpy()
        assert np.max(np.abs(diff)) < 10.0, (col, np.max(np.abs(diff)))
    diff = held.frame["load_n"].to_numpy() - stepped.frame["load_n"].to_numpy()
    assert np.max(np.abs(diff)) < 1.0, np.max(np.abs(diff))
