"""compensate(): sensor pressures -> rope tensions, checked against hand-computed physics."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import polars as pl
import pytest

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from schemas.tables import ROPE_TENSIONS
from transforms.compensation import CompensationSettings, compensate

HOIST = load_hoist(EXAMPLE_HOIST)
AREA = math.pi * 0.1**2 / 4  # 100 mm bore
RATE = 100.0


def _frame(p: np.ndarray, x: np.ndarray | None, *, depth=0.0, speed=None, temp=40.0):
    n = p.shape[-1]
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    times = [start + dt.timedelta(microseconds=int(1e6 * k / RATE)) for k in range(n)]
    data = {"time_utc": times}
    for i in range(1, 5):
        data[f"p{i}_pa"] = p if p.ndim == 1 else p[i - 1]
        data[f"x{i}_m"] = (x if x.ndim == 1 else x[i - 1]) if x is not None else [None] * n
    data |= {
        "depth_m": np.full(n, depth),
        "speed_m_s": np.zeros(n) if speed is None else speed,
        "oil_temp_c": np.full(n, temp),
        "source_sha256": ["f"] * n,
        "source_line": np.arange(n),
    }
    return pl.DataFrame(data, schema_overrides={f"x{i}_m": pl.Float64 for i in range(1, 5)})


def _stribeck_eq16(v: float, p_pa: float) -> float:
    """Paper eq 16 with the example's OLS line (MPa-equivalent, mm/s), by hand."""
    p = p_pa / 1e6
    fc = (0.0292 + 0.0259 * p) * 1e6 * AREA
    fs = (0.1276 + 0.0253 * p) * 1e6 * AREA
    vs = (8.034 - 0.3657 * p) * 1e-3
    kv = (0.00121 + 0.000066 * p) * 1e6 * AREA / 1e-3
    return (fc + (fs - fc) * math.exp(-((v / vs) ** 2))) * math.copysign(1, v) + kv * v


def _branch_loss_laminar(v_piston: float) -> float:
    """Hagen-Poiseuille + K losses of the chamber-to-sensor part, by hand (eq 6, 13)."""
    d, length = 0.010, 0.8
    q = AREA * v_piston
    u = q / (math.pi * d**2 / 4)
    nu = 46e-6  # at the 40 degC reference temperature
    rho = 900.0
    re = abs(u) * d / nu
    assert re < 2000
    laminar = 128 * nu * rho * length * q / (math.pi * d**4)
    local = (9.0 + 0.5) * rho * u * abs(u) / 2
    return laminar + local


def test_output_has_rope_tension_schema():
    out = compensate(_frame(np.full(200, 4e6), np.zeros(200)), HOIST)
    assert out.columns == ROPE_TENSIONS.names
    assert out.height == 200


def test_at_rest_without_history_tension_is_pressure_times_area():
    out = compensate(_frame(np.full(500, 4.2e6), np.zeros(500)), HOIST)
    assert out["tension1_n"].to_numpy() == pytest.approx(4.2e6 * AREA, rel=1e-9)
    assert out["load_n"][-1] == pytest.approx(4 * 4.2e6 * AREA, rel=1e-9)
    assert out["load_raw_n"][-1] == pytest.approx(4 * 4.2e6 * AREA, rel=1e-9)


def test_steady_outward_motion_adds_branch_loss_and_stribeck_friction():
    """Rod pulled out at 5 mm/s: sensor reads low by the branch loss; seal resists."""
    v, p_sensor, n = 5e-3, 5e6, 3000
    x = v * np.arange(n) / RATE
    out = compensate(_frame(np.full(n, p_sensor), x), HOIST)
    late = out.slice(2000, 500)
    loss = _branch_loss_laminar(v)
    assert late["p_chamber1_pa"].mean() == pytest.approx(p_sensor + loss, rel=1e-4)
    expected_friction = _stribeck_eq16(v, p_sensor + loss)
    assert late["friction1_n"].mean() == pytest.approx(expected_friction, rel=1e-3)
    expected = (p_sensor + loss) * AREA + expected_friction
    assert late["tension1_n"].mean() == pytest.approx(expected, rel=1e-4)
    assert late["tension_raw1_n"].mean() == pytest.approx(p_sensor * AREA, rel=1e-9)


def test_inward_motion_reverses_both_corrections():
    v, p_sensor, n = -5e-3, 5e6, 3000
    x = v * np.arange(n) / RATE
    out = compensate(_frame(np.full(n, p_sensor), x), HOIST).slice(2000, 500)
    loss = _branch_loss_laminar(v)  # negative: the sensor reads high
    assert out["p_chamber1_pa"].mean() == pytest.approx(p_sensor + loss, rel=1e-4)
    assert out["friction1_n"].mean() == pytest.approx(_stribeck_eq16(v, p_sensor + loss), rel=1e-3)


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_friction_from_last_motion_is_kept_at_standstill(direction):
    """Move 2 mm at 5 mm/s, then stop for 20 s: the friction stays, it does not drop to 0."""
    moving = direction * 5e-3 * np.arange(401) / RATE
    x = np.r_[moving, np.full(2000, moving[-1])]
    out = compensate(_frame(np.full(x.size, 5e6), x), HOIST)
    end_friction = out["friction1_n"][-1]
    assert np.sign(end_friction) == direction
    # held near the static level of the Stribeck curve at low speed
    assert abs(end_friction) > 0.5 * _stribeck_eq16(1e-4, 5e6)


def test_sensor_calibration_is_applied():
    text = EXAMPLE_HOIST.read_text().replace(
        'cylinder = 2\noffset = "0 MPa"\ngain = 1.0', 'cylinder = 2\noffset = "0.1 MPa"\ngain = 1.02'
    )
    from schemas.hoist import parse_hoist

    hoist = parse_hoist(text)
    reading = 1.02 * 4e6 + 0.1e6
    out = compensate(_frame(np.full(300, reading), np.zeros(300)), hoist)
    assert out["p2_pa"].to_numpy() == pytest.approx(4e6, rel=1e-9)


def test_without_displacement_velocity_follows_oil_compression():
    """x not logged: a pressure ramp implies v = V / (n A beta) dp/dt for every piston."""
    n = 3000
    dp_dt = 0.2e6  # Pa/s
    p = 3e6 + dp_dt * np.arange(n) / RATE
    out_no_x = compensate(_frame(p, None), HOIST)
    v_expected = HOIST.oil_volume_m3 / (4 * AREA * 1.5e9) * dp_dt
    x = v_expected * np.arange(n) / RATE
    out_x = compensate(_frame(p, x), HOIST)
    mid = slice(1000, 2500)
    np.testing.assert_allclose(
        out_no_x["friction1_n"].to_numpy()[mid], out_x["friction1_n"].to_numpy()[mid], rtol=1e-3
    )
    assert out_no_x["friction1_n"].to_numpy()[mid].mean() > 0


def test_effects_off_means_no_correction():
    n = 2000
    x = 5e-3 * np.arange(n) / RATE
    out = compensate(_frame(np.full(n, 5e6), x), HOIST, effects=set())
    np.testing.assert_allclose(out["tension1_n"], out["tension_raw1_n"])


def test_gap_is_not_bridged_by_velocity():
    """A 10 s logger dropout with the piston moved meanwhile: no velocity spike at the gap."""
    n = 600
    frame = _frame(np.full(n, 5e6), np.r_[np.zeros(300), np.full(300, 5e-3)])
    times = frame["time_utc"].to_list()
    shifted = times[:300] + [t + dt.timedelta(seconds=10) for t in times[300:]]
    frame = frame.with_columns(pl.Series("time_utc", shifted))
    out = compensate(frame, HOIST)
    assert np.all(np.abs(out["friction1_n"].to_numpy()) < 1.0)


def test_positions_and_phases_are_labelled():
    n = 500
    out = compensate(_frame(np.full(n, 5e6), np.zeros(n), depth=320.0), HOIST)
    assert set(out["position"].unique()) == {"middle"}
    assert set(out["phase"].unique()) == {"standstill"}


def test_settings_are_respected():
    out = compensate(
        _frame(np.full(200, 4e6), np.zeros(200)),
        HOIST,
        settings=CompensationSettings(pressure_cutoff_hz=2.0),
    )
    assert out.height == 200


def test_empty_input_gives_empty_schema():
    empty = _frame(np.full(1, 4e6), np.zeros(1)).head(0)
    out = compensate(empty, HOIST)
    assert out.height == 0
    assert out.columns == ROPE_TENSIONS.names
