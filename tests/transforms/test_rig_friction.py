"""Tests for transforms.rig_friction: eq 1 solved for friction, steady steps, Table 1 analogue.

Synthetic frames with known answers; the end-to-end check (simulated rig -> MCAP -> lake
-> calibrated law) is tests/pipelines/test_calibrate.py.
"""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import polars as pl
import pytest

from physics.friction_law import stribeck_friction
from transforms.rig_friction import fit_pressure_levels, seal_friction_samples, steady_steps

BORE_M, ROD_M, MASS_KG = 0.1, 0.06, 25.0
T0 = dt.datetime(2026, 1, 5, 8, 0, tzinfo=dt.UTC)


def _samples(t_s: np.ndarray, x_m: np.ndarray, **columns) -> pl.DataFrame:
    n = t_s.size
    base = {
        "time_utc": [T0 + dt.timedelta(microseconds=round(t * 1e6)) for t in t_s],
        "step": np.ones(n, dtype=np.int32),
        "x_m": x_m,
        "p_rodless_pa": np.full(n, 5e6),
        "p_rod_pa": np.full(n, 1e6),
        "pressure_setpoint_pa": np.full(n, 5e6),
        "velocity_setpoint_m_s": np.full(n, 0.02),
    }
    base.update(columns)
    return pl.DataFrame(base).with_columns(
        pl.col("time_utc").cast(pl.Datetime("us", "UTC")), pl.col("step").cast(pl.Int32)
    )


def test_friction_is_the_force_balance_of_eq1():
    """Quadratic x(t): the Savitzky-Golay derivatives are exact, so is F = pA Ab - pB Aa - m a."""
    t = np.arange(0.0, 2.0, 1e-3)
    accel = 0.3
    x = 0.1 + 0.02 * t + 0.5 * accel * t**2
    p_a = 5e6 + 1e5 * np.sin(t)
    p_b = np.full(t.size, 1e6)
    out = seal_friction_samples(
        _samples(t, x, p_rodless_pa=p_a, p_rod_pa=p_b),
        bore_m=BORE_M,
        rod_m=ROD_M,
        moving_mass_kg=MASS_KG,
    )
    np.testing.assert_allclose(out["t_s"].to_numpy(), t, atol=1e-9)
    np.testing.assert_allclose(out["v_m_s"].to_numpy(), 0.02 + accel * t, atol=1e-9)
    np.testing.assert_allclose(out["a_m_s2"].to_numpy(), accel, atol=1e-6)
    area_bore = math.pi * BORE_M**2 / 4
    area_annulus = math.pi * (BORE_M**2 - ROD_M**2) / 4
    expected = p_a * area_bore - p_b * area_annulus - MASS_KG * accel
    np.testing.assert_allclose(out["friction_n"].to_numpy(), expected, atol=1e-3)


def test_gaps_and_step_changes_start_blocks_and_segments():
    t = np.r_[np.arange(0.0, 1.0, 1e-3), 2.0 + np.arange(0.0, 1.0, 1e-3)]  # a 1 s gap
    step = np.where(t < 0.5, 1, 2).astype(np.int32)
    step[t >= 2.0] = 3
    x = 0.01 * t + np.where(t >= 2.0, 0.3, 0.0)  # moved while not recorded
    shuffled = _samples(t, x, step=step).sample(fraction=1.0, shuffle=True, seed=1)
    out = seal_friction_samples(shuffled, bore_m=BORE_M, rod_m=ROD_M, moving_mass_kg=MASS_KG)
    assert out["t_s"].is_sorted()
    assert out["block"].unique().to_list() == [0, 1]
    changes = out["t_s"].filter(out["segment"].diff().fill_null(0) != 0).to_list()
    assert changes == pytest.approx([0.5, 2.0])  # a new step, then the gap
    # derivatives per block: the gap does not leak into either side
    np.testing.assert_allclose(out["v_m_s"].to_numpy(), 0.01, atol=1e-9)


def test_no_samples_is_an_error():
    empty = _samples(np.array([]), np.array([]))
    with pytest.raises(ValueError, match="no rig samples"):
        seal_friction_samples(empty, bore_m=BORE_M, rod_m=ROD_M, moving_mass_kg=MASS_KG)


def _step_frame() -> pl.DataFrame:
    """Three 1 s steps: ramp + bristle transient, standstill, and one too short."""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 1.0, 1e-3)
    v = 0.01 * (1.0 - np.exp(-t / 0.02))
    x = 0.01 * (t - 0.02 * (1.0 - np.exp(-t / 0.02)))
    force = 500.0 + 200.0 * np.exp(-t / 0.03) + rng.normal(0.0, 1.0, t.size)
    moving = {
        "segment": 0,
        "step": 1,
        "velocity_setpoint_m_s": 0.01,
        "t_s": t,
        "x_m": x,
        "v_m_s": v,
        "friction_n": force,
    }
    still = {**moving, "segment": 1, "step": 2, "velocity_setpoint_m_s": 0.0, "t_s": t + 1}
    short = {k: (val[:100] if isinstance(val, np.ndarray) else val) for k, val in moving.items()}
    short |= {"segment": 2, "step": 3, "t_s": t[:100] + 2}
    return pl.concat(
        pl.DataFrame(part).with_columns(
            pressure_setpoint_pa=pl.lit(5e6), p_rodless_pa=pl.lit(5.01e6)
        )
        for part in (moving, still, short)
    ).with_columns(pl.col("step").cast(pl.Int32))


def test_steady_steps_drop_the_transient_and_keep_moving_steps_only():
    steps = steady_steps(_step_frame())
    assert steps.height == 1  # standstill and the 0.1 s step are not steady steps
    row = steps.row(0, named=True)
    assert row["segment"] == 0
    assert row["step"] == 1
    assert 0.1 < row["steady_start_s"] < 0.3  # ramp and bristle transient left out
    assert row["steady_end_s"] == pytest.approx(0.999 - 0.05, abs=1.5e-3)
    assert row["velocity_m_s"] == pytest.approx(0.01, rel=1e-3)
    assert row["friction_n"] == pytest.approx(500.0, abs=4 * row["friction_sem_n"] + 0.5)
    assert row["p_rodless_pa"] == pytest.approx(5.01e6)


def test_a_step_whose_piston_did_not_follow_its_setpoint_is_not_a_sliding_step():
    """The moving step of the frame above again, its piston held by static friction
    (x constant, the friction below breakaway) and once driven backwards: neither is
    a sliding step (a stalled step's ~0 m/s speed forced the Stribeck fit through
    -F_s at zero and ruined every level's fit); the moving step is kept."""
    frame = _step_frame()
    moving = frame.filter(pl.col("segment") == 0)
    stalled = moving.with_columns(
        pl.lit(3).alias("segment"), pl.lit(4, pl.Int32).alias("step"),
        pl.col("t_s") + 3.0, pl.lit(0.0).alias("x_m"), pl.lit(0.0).alias("v_m_s"),
        pl.lit(-0.6).alias("friction_n"),
    )  # fmt: skip
    backwards = moving.with_columns(
        pl.lit(4).alias("segment"), pl.lit(5, pl.Int32).alias("step"), pl.col("t_s") + 4.0,
        -pl.col("x_m"), -pl.col("v_m_s"),
    )  # fmt: skip
    steps = steady_steps(pl.concat([frame, stalled, backwards]))
    assert steps["segment"].to_list() == [0]


def test_fit_pressure_levels_recovers_each_level_and_skips_thin_ones():
    speeds = np.r_[-np.geomspace(1e-3, 5e-2, 6), np.geomspace(1e-3, 5e-2, 6)]
    truth = {2e6: (600.0, 1400.0, 7e-3, 1.6e4), 7e6: (1600.0, 2400.0, 5.5e-3, 2e4)}
    rows = []
    for p, (fc, fs, vs, kv) in truth.items():
        force = stribeck_friction(speeds, fc, fs, vs, kv)
        rows += [
            {"pressure_setpoint_pa": p, "p_rodless_pa": p + 1e4, "velocity_m_s": v, "friction_n": f}
            for v, f in zip(speeds, force, strict=True)
        ]
    rows += [  # a level with too few steps
        {"pressure_setpoint_pa": 12e6, "p_rodless_pa": 12e6, "velocity_m_s": v, "friction_n": 1.0}
        for v in speeds[:3]
    ]
    steps = pl.DataFrame(rows).with_row_index("segment").cast({"segment": pl.Int64})
    per_pressure, fits = fit_pressure_levels(steps.reverse())
    assert per_pressure["pressure_setpoint_pa"].to_list() == [2e6, 7e6]
    assert per_pressure["p_rodless_pa"].to_list() == [2.01e6, 7.01e6]
    assert per_pressure["steps"].to_list() == [12, 12]
    assert len(fits) == 2
    assert per_pressure["converged"].all()
    names = ("coulomb_n", "static_n", "stribeck_speed_m_s", "viscous_n_s_m")
    for k, params in enumerate(truth.values()):
        got = per_pressure.select(names).row(k)
        np.testing.assert_allclose(got, params, rtol=1e-4)
