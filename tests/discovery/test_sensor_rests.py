"""discovery.sensor_rests: a sensor's zero or span told apart at the record's rests,
on records made here with a known error (analytic: at rest the four readings differ
only by the sensors' errors)."""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest

from discovery.sensor_rests import DECISIVE_DBIC, rest_means, sensor_error_at_rest

RATE_HZ = 10.0


def _record(
    levels_pa: tuple[float, ...],
    *,
    sensor: int = 2,
    offset_pa: float = 0.0,
    gain: float = 1.0,
    rest_s: float = 30.0,
    trip_s: float = 20.0,
    seed: int = 1,
) -> pl.DataFrame:
    """Rests at ``levels_pa`` in turn, trips between them whose branch flows part the
    sensors by up to 60 kPa; sensor ``sensor`` reads ``gain x p + offset_pa``; 5 kPa
    of white noise on every reading."""
    rng = np.random.default_rng(seed)
    pieces = []
    for level in levels_pa:
        n_rest, n_trip = int(rest_s * RATE_HZ), int(trip_s * RATE_HZ)
        speed = np.r_[np.zeros(n_rest), np.full(n_trip, 5.0)]
        p = np.full((n_rest + n_trip, 4), level)
        p[n_rest:] += np.array([60e3, -20e3, -20e3, -20e3])  # oil flowing: apart
        pieces.append((speed, p))
    speed = np.concatenate([s for s, _ in pieces])
    p = np.concatenate([q for _, q in pieces])
    p[:, sensor - 1] = gain * p[:, sensor - 1] + offset_pa
    p += rng.normal(0.0, 5e3, p.shape)
    start = dt.datetime(2026, 3, 1, tzinfo=dt.UTC)
    times = [start + dt.timedelta(seconds=k / RATE_HZ) for k in range(speed.size)]
    return pl.DataFrame(
        {"time_utc": times, "speed_m_s": speed, **{f"p{i + 1}_pa": p[:, i] for i in range(4)}}
    )


LEVELS = (2.6e6, 4.0e6, 5.5e6, 6.7e6, 3.2e6, 6.0e6, 2.9e6, 4.8e6)


def test_an_offset_is_told_from_a_gain_and_measured():
    verdict = sensor_error_at_rest(_record(LEVELS, sensor=2, offset_pa=30e3), 4)
    assert verdict.effect == "sensor_offset"
    assert verdict.dbic <= -DECISIVE_DBIC
    assert verdict.rests == len(LEVELS)
    # sensor 2 departs from the others' mean by the offset, each other one by -1/3 of it
    assert verdict.offsets_pa == pytest.approx((-10e3, 30e3, -10e3, -10e3), abs=1.5e3)


def test_a_gain_is_told_from_an_offset_and_measured():
    verdict = sensor_error_at_rest(_record(LEVELS, sensor=3, gain=1.008), 4)
    assert verdict.effect == "sensor_gain"
    assert verdict.dbic >= DECISIVE_DBIC
    assert verdict.gain_errors[2] == pytest.approx(0.008, abs=5e-4)


def test_rests_at_one_pressure_tell_nothing():
    """An offset and a gain are the same error where the pressure does not change."""
    verdict = sensor_error_at_rest(_record((4.0e6,) * 8, sensor=2, offset_pa=30e3), 4)
    assert verdict.effect is None
    assert "neither" in verdict.note()


def test_readings_that_agree_at_rest_show_no_sensor_error():
    """No error: the two fits differ only by the noise, and neither is named."""
    verdict = sensor_error_at_rest(_record(LEVELS * 6, seed=3), 4)
    assert verdict.effect is None


def test_too_few_rests_or_no_speed_tell_nothing():
    assert sensor_error_at_rest(_record(LEVELS[:3], offset_pa=30e3), 4).effect is None
    no_speed = _record(LEVELS, offset_pa=30e3).drop("speed_m_s")
    assert sensor_error_at_rest(no_speed, 4).rests == 0


def test_a_rest_is_read_after_the_oil_settled_and_not_while_it_flows():
    """The trips' flows (sensor 1 60 kPa above the others) are not in the rests' means,
    nor the first and last seconds of each rest."""
    frame = _record(LEVELS, rest_s=30.0)
    means = rest_means(frame, 4)
    assert means.shape == (len(LEVELS), 4)
    assert np.abs(means - np.array(LEVELS)[:, None]).max() < 3e3
    # a reading missing at rest leaves its sample out, not its rest
    holed = frame.with_columns(
        pl.when(pl.int_range(pl.len()) == 150).then(None).otherwise(pl.col("p1_pa")).alias("p1_pa")
    )
    assert rest_means(holed, 4).shape == (len(LEVELS), 4)


def test_what_the_model_already_calibrates_is_not_the_error():
    """Sensor 2 reads 60 kPa high, which the model's sensor_offset holds, and sensor 4's
    span is 0.8 % off, which it does not: the rests tell the gain beyond the offset."""
    frame = _record(LEVELS, sensor=4, gain=1.008).with_columns(pl.col("p2_pa") + 60e3)
    verdict = sensor_error_at_rest(frame, 4, offsets_pa=np.array([0.0, 60e3, 0.0, 0.0]))
    assert verdict.effect == "sensor_gain"
    assert verdict.gain_errors[3] == pytest.approx(0.008, abs=5e-4)


@pytest.mark.parametrize(
    ("hidden", "other"), [("sensor_offset", "sensor_gain"), ("sensor_gain", "sensor_offset")]
)
def test_discovery_asks_the_rests_when_its_two_best_are_a_sensors_offset_and_gain(hidden, other):
    """ropeload's own simulation (the wiring, not accuracy: discovery.record_rereading),
    eight trips hiding a 20 kPa offset on sensor 2 or a 1 % span error on sensor 3: the
    first search ranks the pair first and second and adds the hidden one; its rests,
    with the model's calibration before anything was added, agree."""
    from discovery import discover_in_record
    from discovery.cases import hidden_case

    plan, info = hidden_case(hidden, trips=8)
    result = discover_in_record(info["day"].sensors, plan.hoist, max_iterations=1, bootstrap=50)
    (finding,) = result.findings
    assert [row["effect"] for row in finding.ranking[:2]] == [hidden, other]
    assert finding.effect == hidden
    (said,) = [note for note in result.notes if "rests tell" in note]
    assert f"tell {hidden} " in said
