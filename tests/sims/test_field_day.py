"""Tests of sims.field_day: truth physics, sensor model, files, reproducibility."""

from __future__ import annotations

import json

import numpy as np
import polars as pl
import pytest

from physics.friction_law import friction_parameters
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.field_day import generate_field_day, write_field_day
from sims.noise import NoiseModel

HOIST = load_hoist(EXAMPLE_HOIST)
G = 9.80665


@pytest.fixture(scope="module")
def day():
    return generate_field_day(
        HOIST, date="2026-03-02", seed=11, trips=6, hours=1.0, start_hour=6.0, dt_s=5e-3
    )


def test_truth_load_at_standstill_is_the_weight(day):
    """At rest the four rope tensions carry (cage + payload + tail rope) x g (Table 2)."""
    rest = day.truth.filter(pl.col("trip_id").is_null())  # held between trips
    assert rest.height > 100_000
    tail_kg = 2 * 6.2 * (620.0 - rest["depth_m"].to_numpy())  # 2 tail ropes, 6.2 kg/m
    expected = (8200.0 + rest["payload_kg"].to_numpy() + tail_kg) * (
        G + rest["acceleration_up_m_s2"].to_numpy()
    )
    assert np.abs(rest["load_n"].to_numpy() / expected - 1).max() < 0.002


def _trip_starts(truth: pl.DataFrame) -> np.ndarray:
    trip_id = truth["trip_id"].fill_null(-1).to_numpy()
    return np.flatnonzero((trip_id[1:] != trip_id[:-1]) & (trip_id[1:] >= 0)) + 1


def test_trip_starts_continue_the_friction_state(day):
    """A day is one history: each trip continues from the held state of the one before,
    so the seal friction and the pressures do not step when a trip starts."""
    truth = day.truth
    starts = _trip_starts(truth)
    assert len(starts) == 5  # trips 1..5; trip 0 starts from static equilibrium
    for s in starts:
        for i in range(1, 5):
            p = truth[f"p_chamber{i}_pa"].to_numpy()
            _, fs, _, _ = (float(a) for a in friction_parameters(p[s], HOIST.friction_law))
            friction = truth[f"friction{i}_n"].to_numpy()
            x = truth[f"x{i}_m"].to_numpy()
            assert x[s] == x[s - 1]  # no piston motion in that sample...
            assert abs(friction[s] - friction[s - 1]) < 0.01 * fs  # ...so no friction jump
            assert p[s] == p[s - 1]
            sensor = truth[f"p_sensor{i}_pa"].to_numpy()
            assert sensor[s] == sensor[s - 1]


def test_friction_stays_in_the_seals_at_standstill(day):
    """Held between trips: the ropes carry the weight (tension sum), the chamber
    pressures carry it less the friction the seals hold -- which is not zero."""
    rest = day.truth.filter(pl.col("trip_id").is_null())
    area = HOIST.cylinders.bore_area_m2
    pressure = sum(rest[f"p_chamber{i}_pa"] for i in range(1, 5)).to_numpy() * area
    friction = sum(rest[f"friction{i}_n"] for i in range(1, 5)).to_numpy()
    load = rest["load_n"].to_numpy()
    assert np.abs(pressure + friction - load).max() < 1e-4 * load.min()
    assert np.abs(friction / load).max() > 0.005  # the seals hold friction through rest


def test_truth_load_while_moving_includes_inertia(day):
    """Moving, the load follows (m + payload + tail)(g + a_up) up to the rope bounce."""
    moving = day.truth.filter(pl.col("phase").is_in(["accelerate", "run", "decelerate"]))
    tail_kg = 2 * 6.2 * (620.0 - moving["depth_m"].to_numpy())
    a_up = moving["acceleration_up_m_s2"].to_numpy()
    mass = 8200.0 + moving["payload_kg"].to_numpy() + tail_kg
    error = np.abs(moving["load_n"].to_numpy() / (mass * (G + a_up)) - 1)
    static_error = np.abs(moving["load_n"].to_numpy() / (mass * G) - 1)
    assert np.median(error) < 0.02
    assert np.median(error) < 0.5 * np.median(static_error)  # inertia is in the truth


def test_schedule_payloads_and_phases(day):
    trips = day.info["trips"]
    assert len(trips) == 6
    assert [t["direction"] for t in trips] == ["down", "up"] * 3
    rated = HOIST.conveyance.rated_payload_kg
    assert all(0.6 * rated <= t["payload_kg"] <= rated for t in trips if t["direction"] == "up")
    assert set(day.truth["phase"].unique()) >= {"standstill", "accelerate", "run", "decelerate"}
    temps = [t["oil_temp_c"] for t in trips]
    assert temps == sorted(temps)
    assert temps[-1] > temps[0]
    assert day.info["seed"] == 11
    assert "seal_friction" in day.info["effects"]


def test_sensor_frame_is_truth_plus_logger_noise(day):
    sensors, truth = day.sensors, day.truth
    assert sensors.columns[:5] == ["time_utc", "p1_pa", "p2_pa", "p3_pa", "p4_pa"]
    assert 0.99 * truth.height < sensors.height < truth.height  # some samples dropped
    assert sensors["time_utc"].is_sorted()
    joined = sensors.join_asof(truth, on="time_utc", strategy="backward")
    resid = (joined["p1_pa"] - joined["p_sensor1_pa"]).to_numpy()
    core = resid[np.abs(resid) < 1e5]  # spikes aside
    assert np.std(core) == pytest.approx(NoiseModel().pressure_sigma_pa, rel=0.1)


def test_same_seed_same_day_other_seed_other_day():
    kwargs = {"date": "2026-03-02", "trips": 2, "hours": 0.1, "dt_s": 5e-3}
    a = generate_field_day(HOIST, seed=5, **kwargs)
    b = generate_field_day(HOIST, seed=5, **kwargs)
    c = generate_field_day(HOIST, seed=6, **kwargs)
    assert a.sensors.equals(b.sensors)
    assert a.truth.equals(b.truth)
    assert not a.sensors.equals(c.sensors)


def test_write_field_day_files(day, tmp_path):
    paths = write_field_day(day, tmp_path, split="hour")
    names = sorted(p.name for p in paths)
    assert names == [
        "paper-field-test_main-shaft_20260302_0600.csv",
        "paper-field-test_main-shaft_20260302_0600.tdms",
        "paper-field-test_main-shaft_20260302_truth.json",
        "paper-field-test_main-shaft_20260302_truth.parquet",
    ]
    csv = pl.read_csv(tmp_path / names[0], comment_prefix="#")
    assert csv.height == day.sensors.height
    assert np.abs(csv["p3"].to_numpy() * 1e6 - day.sensors["p3_pa"].to_numpy()).max() <= 500.5
    truth = pl.read_parquet(tmp_path / names[3])
    assert truth.equals(day.truth)
    info = json.loads((tmp_path / names[2]).read_text())
    assert info["seed"] == 11
    assert len(info["trips"]) == 6


def test_per_trip_max_speeds_cycle_over_the_trips():
    day = generate_field_day(
        HOIST, date="2026-03-02", seed=5, trips=3, hours=0.25, dt_s=5e-3, max_speeds_m_s=[4.0, 10.0]
    )
    moving = day.truth.filter(pl.col("trip_id").is_not_null())
    top = moving.group_by("trip_id").agg(pl.col("speed_m_s").abs().max()).sort("trip_id")
    assert top["speed_m_s"].to_list() == pytest.approx([4.0, 10.0, 4.0], rel=1e-3)
    with pytest.raises(ValueError, match="max_speeds_m_s"):
        generate_field_day(HOIST, date="2026-03-02", seed=5, trips=1, hours=0.1, max_speeds_m_s=[])
