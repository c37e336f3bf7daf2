"""Tests for transforms.kinematics on synthetic trapezoidal trips with known phases."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from transforms.filtering import with_segment_id
from transforms.kinematics import (
    smoothed_derivative,
    with_acceleration,
    with_piston_velocity,
    with_position,
    with_trip_phases,
)

HOIST = load_hoist(EXAMPLE_HOIST)
DT = 0.01


def _trip(direction: float) -> tuple[np.ndarray, list[tuple[str, float]]]:
    """Speed profile of one trip and its (phase, duration) list, winder of the example."""
    a, vmax, creep = 0.75, 10.0, 0.5
    pieces = [
        ("standstill", 3.0, lambda t: 0.0 * t),
        ("accelerate", vmax / a, lambda t: a * t),
        ("run", 20.0, lambda t: vmax + 0.0 * t),
        ("decelerate", (vmax - creep) / a, lambda t: vmax - a * t),
        ("creep", 5.0, lambda t: creep + 0.0 * t),
        ("decelerate", creep / a, lambda t: creep - a * t),
        ("standstill", 3.0, lambda t: 0.0 * t),
    ]
    speed = np.concatenate([f(np.arange(round(d / DT)) * DT) for _, d, f in pieces])
    return direction * speed, [(name, d) for name, d, _ in pieces]


@pytest.fixture(scope="module")
def trips() -> tuple[pl.DataFrame, list[tuple[str, float, float]]]:
    down, phases = _trip(+1.0)
    up, _ = _trip(-1.0)
    speed = np.concatenate([down, up])
    t = np.arange(speed.size) * DT
    t[down.size :] += 60.0  # a logger gap between the trips
    truth = []
    start = 0.0
    for offset in (0.0, t[down.size] - 0.0):
        start = offset
        for name, d in phases:
            truth.append((name, start, start + d))
            start += d
    depth = np.cumsum(speed) * DT
    df = pl.DataFrame({"t_s": t, "speed_m_s": speed, "depth_m": depth})
    return df, truth


def test_smoothed_derivative_respects_gaps():
    t = np.concatenate([np.arange(0, 2, DT), 10 + np.arange(0, 2, DT)])
    x = np.where(t < 5, 0.01 * np.sin(3 * t), 0.2 + 0.004 * t**2)  # jump across the gap
    seg = (t > 5).astype(np.int64)
    d = smoothed_derivative(x, seg, dt_s=DT, window_s=0.1)
    truth = np.where(t < 5, 0.03 * np.cos(3 * t), 0.008 * t)
    np.testing.assert_allclose(d, truth, atol=3e-4)  # 1 % of the peak velocity
    np.testing.assert_allclose(d[t > 5], truth[t > 5], rtol=1e-9)  # exact for a parabola
    smeared = smoothed_derivative(x, None, dt_s=DT, window_s=0.1)
    assert np.abs(smeared - truth).max() > 1.0  # what the segments avoid


def test_piston_velocity_and_flow_with_noise():
    rng = np.random.default_rng(0)
    t = np.arange(0, 10, DT)
    x = 0.02 * np.sin(0.5 * t) + rng.normal(0, 2e-6, t.size)
    df = pl.DataFrame({"t_s": t, "x1_m": x, "x2_m": -x}).pipe(
        with_segment_id, "t_s", nominal_dt_s=DT
    )
    out = with_piston_velocity(
        df.lazy(),
        ["x1_m", "x2_m"],
        bore_area_m2=HOIST.cylinders.bore_area_m2,
        dt_s=DT,
        window_s=0.3,
    ).collect()
    v_true = 0.01 * np.cos(0.5 * t)
    np.testing.assert_allclose(out["v1_m_s"].to_numpy(), v_true, atol=5e-5)
    np.testing.assert_allclose(out["v2_m_s"].to_numpy(), -v_true, atol=5e-5)
    np.testing.assert_allclose(
        out["q1_m3_s"].to_numpy(), out["v1_m_s"].to_numpy() * np.pi * 0.1**2 / 4, rtol=1e-12
    )


def test_trip_phases_on_trapezoidal_trips(trips):
    df, truth = trips
    out = (
        df.lazy()
        .pipe(with_segment_id, "t_s", nominal_dt_s=DT)
        .pipe(with_acceleration, dt_s=DT, window_s=0.5)
        .pipe(with_trip_phases, HOIST, time_col="t_s")
        .collect()
    )
    t = out["t_s"].to_numpy()
    phase = out["phase"].to_numpy()
    assert out["acceleration_m_s2"].to_numpy()[(t > 8) & (t < 15)] == pytest.approx(0.75)
    for name, start, end in truth:
        inner = (t > start + 0.3) & (t < end - 0.3)
        if inner.any():
            assert set(phase[inner]) == {name}, (name, start, end)
    # boundaries located within 0.3 s: every sample is right outside the margins
    wrong = np.zeros(t.size, dtype=bool)
    for name, start, end in truth:
        inside = (t >= start) & (t < end)
        wrong |= inside & (phase != name)
    for _, start, end in truth:
        near = (np.abs(t - start) < 0.3) | (np.abs(t - end) < 0.3)
        wrong &= ~near
    assert not wrong.any()
    # directions and trip ids
    moving = phase != "standstill"
    first = t < 60
    assert set(out["direction"].to_numpy()[moving & first]) == {"down"}
    assert set(out["direction"].to_numpy()[moving & ~first]) == {"up"}
    assert out["trip_id"].drop_nulls().unique().sort().to_list() == [0, 1]
    assert out["trip_id"].filter(out["phase"] == "standstill").null_count() == int((~moving).sum())


def test_positions_on_a_trip(trips):
    df, _ = trips
    out = with_position(df, HOIST)
    depth = out["depth_m"].to_numpy()
    pos = out["position"].to_list()
    for d, p in zip(depth, pos, strict=True):
        if d <= 5.0:
            assert p == "pithead"
        elif abs(d - 320.0) <= 5.0:
            assert p == "middle"
        elif abs(d - 600.0) <= 5.0:
            assert p == "bottom"
        else:
            assert p is None
    assert {"pithead", "middle", "bottom"} <= set(pos) - {None} or depth.max() < 595


@pytest.mark.parametrize(
    ("gap_s", "depth_after_m", "trips"),
    [
        (0.24, 102.4, 1),  # a dropout mid-shaft at 10 m/s
        (30.0, 400.0, 1),  # a long one, but the depth kept pace: no stop hid in it
        (30.0, 110.0, 2),  # it advanced too little: the hoist stopped in the gap
        (600.0, 50.0, 2),  # it went back up: an unseen round trip, then a new descent
        (600.0, 450.0, 2),  # an unseen round trip ending deeper still
    ],
)
def test_a_logger_gap_inside_a_motion(gap_s, depth_after_m, trips):
    """Down at 10 m/s on both sides of a logger gap: one trip, unless the depth says the
    conveyance did not keep moving through the gap at a speed between half the slower
    and twice the faster of the two sides."""
    t = np.r_[np.arange(0.0, 10.0, DT), 10.0 + gap_s + np.arange(0.0, 10.0, DT)]
    depth = np.r_[np.linspace(0.0, 100.0, 1000), depth_after_m + np.arange(1000) * 0.1]
    frame = pl.DataFrame({"t_s": t, "speed_m_s": np.full(t.size, 10.0), "depth_m": depth})
    out = (
        frame.pipe(with_segment_id, "t_s", nominal_dt_s=DT)
        .with_columns(acceleration_m_s2=pl.lit(0.0))
        .pipe(with_trip_phases, HOIST, time_col="t_s")
    )
    assert out["trip_id"].n_unique() == trips


def test_trip_phases_of_a_lazy_frame_replace_existing_labels():
    """A LazyFrame that already has the label columns gets them replaced, as a
    DataFrame does (one evaluation of the plan)."""
    t = np.arange(0.0, 20.0, 0.1)
    v = np.where((t > 5) & (t < 15), 2.0, 0.0)
    frame = pl.DataFrame(
        {"t_s": t, "speed_m_s": v, "acceleration_m_s2": np.zeros(t.size), "segment_id": 0,
         "phase": "x", "direction": "x", "trip_id": 7}
    )  # fmt: skip
    eager = with_trip_phases(frame, HOIST, time_col="t_s")
    lazy = with_trip_phases(frame.lazy(), HOIST, time_col="t_s").collect()
    assert lazy.equals(eager)
    assert set(eager["trip_id"].drop_nulls().to_list()) == {0}
