"""The ropes' identification reads 0.2 s means of the pressures: a single-sample spike
(50 MPa, below ingest's 60 MPa limit) must not move them (a validation day with four such
samples lost its identified ropes: worst load error 0.80 -> 2.16 %, band 97 -> 72 %)."""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from transforms.compensation_record import CompensationSettings, identification_means
from transforms.rope_identification import record_means

HOIST = load_hoist(EXAMPLE_HOIST)
T0 = dt.datetime(2026, 2, 10, 6, 0, tzinfo=dt.UTC)


def _record(n: int = 1000, spike_at: int | None = None) -> pl.DataFrame:
    rng = np.random.default_rng(1)
    t = np.datetime64(T0.replace(tzinfo=None), "us") + (np.arange(n) * 20_000).astype(
        "timedelta64[us]"
    )
    columns: dict[str, object] = {"time_utc": pl.Series(t).dt.replace_time_zone("UTC")}
    for i in range(1, 5):
        p = 4.9e6 + 1e5 * np.sin(np.arange(n) / 200.0) + rng.normal(0.0, 5e3, n)
        if spike_at is not None and i == 1:
            p[spike_at] = 50e6
        columns[f"p{i}_pa"] = p
        columns[f"x{i}_m"] = np.full(n, 1e-3 * i)
    columns |= {"depth_m": np.zeros(n), "speed_m_s": np.zeros(n), "oil_temp_c": np.full(n, 20.0)}
    return pl.DataFrame(columns)


def test_a_single_sample_spike_leaves_the_means():
    settings = CompensationSettings()
    clean = identification_means(_record(), T0, HOIST, settings)
    spiked = identification_means(_record(spike_at=505), T0, HOIST, settings)
    assert clean.height == spiked.height == 100
    moved = np.abs(spiked["p1_pa"].to_numpy() - clean["p1_pa"].to_numpy())
    assert moved.max() < 1e4, moved.max()  # was 4.5 MPa: 45 MPa over 10 samples
    for i in range(2, 5):
        assert spiked[f"p{i}_pa"].equals(clean[f"p{i}_pa"])


def test_a_sensor_off_the_others_at_rest_is_left_out_of_the_means():
    """A sensor 10 % high at every rest is no pressure (:func:`transforms.compensation_
    record.offset_sensors`): its means are unknown, the model takes the others' for it;
    a sensor within the disagreement limit stays."""
    frame = _record()
    off = frame.with_columns(pl.col("p2_pa") * 1.1, pl.col("p3_pa") * 1.02)
    means = identification_means(off, T0, HOIST, CompensationSettings())
    assert means["p2_pa"].null_count() == means.height
    assert means["p3_pa"].null_count() == 0
    clean = identification_means(frame, T0, HOIST, CompensationSettings())
    assert means["p1_pa"].equals(clean["p1_pa"])


def test_a_logger_quieter_than_its_step_keeps_its_means():
    """Pressures logged to 1 kPa over 250 Pa of noise at rest: their differences' MAD is
    0, and a threshold of 0 took every single-sample flip between steps for a spike
    (here 133 of 3000 samples, 91 of 300 means moved by up to 200 Pa); the logger's
    rounding, q / sqrt 12, is the noise at least, and a 50 MPa sample still goes."""
    settings = CompensationSettings()
    rng = np.random.default_rng(2)
    frame = _record(3000)
    steps = {
        f"p{i}_pa": np.round((4.9e6 + rng.normal(0.0, 250.0, frame.height)) / 1e3) * 1e3
        for i in range(1, 5)
    }
    spiked = {**steps, "p1_pa": steps["p1_pa"].copy()}
    spiked["p1_pa"][1505] = 50e6
    means = identification_means(frame.with_columns(**spiked), T0, HOIST, settings)
    # as logged, the spike alone replaced by its 3-point median, nothing despiked
    steps["p1_pa"][1505] = np.median([*steps["p1_pa"][[1504, 1506]], 50e6])
    logged = record_means(frame.with_columns(**steps), T0)
    for i in range(1, 5):
        np.testing.assert_array_equal(means[f"p{i}_pa"], logged[f"p{i}_pa"])
