"""compensate(): sensor pressures -> rope tensions, checked against hand-computed physics."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import polars as pl
import pytest

from schemas.hoist import EXAMPLE_HOIST, load_hoist, parse_hoist
from schemas.tables import ROPE_TENSIONS
from transforms.compensation import CompensationSettings, compensate, logger_rate_hz

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


def test_a_pressure_not_logged_gives_null_tensions_not_nan():
    """Rope 2's sensor silent for 0.5 s: its tension, friction and the load there are
    null (SQL's max() would take a NaN for the largest value); the others have theirs."""
    p = np.full((4, 300), 4.2e6)
    p[1, 100:150] = np.nan
    frame = _frame(p, np.zeros(300)).with_columns(pl.col("p2_pa").fill_nan(None))
    out = compensate(frame, HOIST)
    floats = [c for c, t in out.schema.items() if t.is_float()]
    assert out.select(pl.col(floats).is_nan().any()).row(0) == (False,) * len(floats)
    silent = out.slice(100, 50)
    assert silent["tension2_n"].null_count() == silent["load_n"].null_count() == 50
    assert silent["tension1_n"].null_count() == 0
    assert out["tension2_n"].max() == pytest.approx(4.2e6 * AREA, rel=1e-3)


def test_at_rest_without_history_tension_is_pressure_times_area():
    out = compensate(_frame(np.full(500, 4.2e6), np.zeros(500)), HOIST)
    assert out["tension1_n"].to_numpy() == pytest.approx(4.2e6 * AREA, rel=1e-9)
    assert out["load_n"][-1] == pytest.approx(4 * 4.2e6 * AREA, rel=1e-9)
    assert out["load_raw_n"][-1] == pytest.approx(4 * 4.2e6 * AREA, rel=1e-9)


def _equalising_flow(v: float, seconds: float = 80.0) -> np.ndarray:
    """Ropes 1-2 pulled out at v, ropes 3-4 drawn in at v: oil flows 1,2 -> 3,4.

    The only steady piston motion a closed connection device allows at constant
    pressure: the oil volume, hence the common pressure, stays the same.
    """
    t = np.arange(int(seconds * RATE)) / RATE
    return np.stack([v * t, v * t, -v * t, -v * t])


def test_equalising_flow_adds_branch_loss_and_stribeck_friction():
    """Rod 1 pulled out at 5 mm/s: its sensor reads low by the branch loss; seal resists."""
    v, p_sensor = 5e-3, 5e6
    x = _equalising_flow(v)
    out = compensate(_frame(np.full(x.shape[1], p_sensor), x), HOIST)
    middle = out.slice(3000, 2000)  # away from the 0.1 Hz differential filter's edges
    loss = _branch_loss_laminar(v)
    assert middle["p_chamber1_pa"].mean() == pytest.approx(p_sensor + loss, rel=2e-4)
    expected_friction = _stribeck_eq16(v, p_sensor + loss)
    assert middle["friction1_n"].mean() == pytest.approx(expected_friction, rel=1e-2)
    expected = (p_sensor + loss) * AREA + expected_friction
    assert middle["tension1_n"].mean() == pytest.approx(expected, rel=2e-4)
    assert middle["tension_raw1_n"].mean() == pytest.approx(p_sensor * AREA, rel=1e-9)
    # rope 3 sees the mirror image: inflow, sensor reads high, friction negative
    loss_in = _branch_loss_laminar(-v)
    assert middle["p_chamber3_pa"].mean() == pytest.approx(p_sensor + loss_in, rel=2e-4)
    assert middle["friction3_n"].mean() == pytest.approx(
        _stribeck_eq16(-v, p_sensor + loss_in), rel=1e-2
    )
    # the sum: branch losses and frictions of opposite motions cancel
    assert middle["load_n"].mean() == pytest.approx(4 * p_sensor * AREA, rel=2e-4)


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_friction_from_last_motion_is_kept_at_standstill(direction):
    """Load rises (falls) 1 MPa, then holds for 20 s: the friction stays, it does not drop to 0.

    The load change squeezes oil out of (lets it into) all four chambers, so all rods move
    out (in) by V dp / (n A beta); the friction that resists it is held at standstill.
    The logged x shows no motion (0.19 mm is under 5 logger steps), so nothing identifies
    the ropes: by default the stick-slip solution on their prior spread, whose mean
    cancels part of the friction (tests/transforms/test_prior_ropes.py); without the
    spread, the share-out of the oil's motion, every rod alike.
    """
    ramp = 5e6 + direction * 1e6 * np.arange(400) / 400
    p = np.r_[np.full(300, 5e6), ramp, np.full(2000, ramp[-1])]
    frame = _frame(p, np.zeros_like(p))
    shared = compensate(frame, HOIST, settings=CompensationSettings(rope_stiffness_sigma=0.0))
    end_friction = shared["friction1_n"][-1]
    assert np.sign(end_friction) == direction
    # V dp / (n A beta) ~ 0.19 mm: far past the presliding range, so the full
    # low-speed (static) friction is reached and then held
    assert abs(end_friction) > 0.8 * _stribeck_eq16(1e-4, 5e6 + direction * 1e6)
    out = compensate(frame, HOIST)
    held = out["friction1_n"].to_numpy()[800:]  # 1 s after the ramp's end, to the end
    assert np.all(np.sign(held) == direction)
    assert np.ptp(held) < 0.01 * abs(held[-1])
    assert abs(held[-1]) < abs(end_friction)


def test_sensor_calibration_is_applied():
    text = EXAMPLE_HOIST.read_text().replace(
        'cylinder = 2\noffset = "0 MPa"\ngain = 1.0',
        'cylinder = 2\noffset = "0.1 MPa"\ngain = 1.02',
    )
    from schemas.hoist import parse_hoist

    hoist = parse_hoist(text)
    reading = 1.02 * 4e6 + 0.1e6
    out = compensate(_frame(np.full(300, reading), np.zeros(300)), hoist)
    assert out["p2_pa"].to_numpy() == pytest.approx(4e6, rel=1e-9)


def test_without_displacement_velocity_follows_oil_compression():
    """x not logged, the oil's motion shared out (``rope_stiffness_sigma=0``): a pressure
    ramp implies v = V / (n A beta) dp/dt for every piston."""
    n = 3000
    dp_dt = 0.2e6  # Pa/s
    p = 3e6 + dp_dt * np.arange(n) / RATE
    shared = CompensationSettings(rope_stiffness_sigma=0.0)
    out_no_x = compensate(_frame(p, None), HOIST, settings=shared)
    v_expected = HOIST.oil_volume_m3 / (4 * AREA * 1.5e9) * dp_dt
    x = v_expected * np.arange(n) / RATE
    out_x = compensate(_frame(p, x), HOIST)
    mid = slice(1000, 2500)
    np.testing.assert_allclose(
        out_no_x["friction1_n"].to_numpy()[mid], out_x["friction1_n"].to_numpy()[mid], rtol=1e-3
    )
    assert out_no_x["friction1_n"].to_numpy()[mid].mean() > 0


def test_effects_off_means_no_correction():
    x = _equalising_flow(5e-3, seconds=20)
    out = compensate(_frame(np.full(x.shape[1], 5e6), x), HOIST, effects=set())
    np.testing.assert_allclose(out["tension1_n"], out["tension_raw1_n"])


def _gapped_move(gap_s: float) -> pl.DataFrame:
    """Rope 1 out and rope 3 in by 5 mm while the logger is down for ``gap_s``."""
    n = 6000
    x1 = np.r_[np.zeros(n // 2), np.full(n // 2, 5e-3)]
    frame = _frame(np.full(n, 5e6), np.stack([x1, np.zeros(n), -x1, np.zeros(n)]))
    times = frame["time_utc"].to_list()
    shifted = times[: n // 2] + [t + dt.timedelta(seconds=gap_s) for t in times[n // 2 :]]
    return frame.with_columns(pl.Series("time_utc", shifted))


def test_motion_across_a_short_dropout_counts():
    """Pistons do not jump: a 5 mm move seen across a 10 s dropout was real motion."""
    out = compensate(_gapped_move(10.0), HOIST)
    static = _stribeck_eq16(1e-4, 5e6)
    assert out["friction1_n"][-1] == pytest.approx(static, rel=0.05)
    assert out["friction3_n"][-1] == pytest.approx(-static, rel=0.05)
    assert out["friction2_n"][-1] == pytest.approx(0.0, abs=1.0)
    # no velocity spike: 5 mm in one sample would be 0.5 m/s and ~0.5 MPa of branch loss;
    # the move spread over the smoothing window gives ~1.6 mm/s and ~2 kPa
    loss = (out["p_chamber1_pa"] - out["p1_pa"]).abs().max()
    assert loss < 5e3


def test_nothing_is_invented_across_a_long_gap():
    """Beyond the bridge (default 120 s) a restart: an unlogged move is not guessed."""
    out = compensate(_gapped_move(600.0), HOIST)
    assert np.all(np.abs(out["friction1_n"].to_numpy()) < 1.0)


def _paused_rest(pauses: int, seed: int, *, paused: bool) -> pl.DataFrame:
    """A 1 MPa rise (the seals take friction), then 10 s at rest ``pauses + 1`` times,
    with 4 kPa of sensor noise; ``paused``: the logger stopped 600 s between them."""
    rng = np.random.default_rng(seed)
    ramp = 5e6 + 1e6 * np.arange(400) / 400
    p = np.r_[np.full(300, 5e6), ramp, np.full(1000 * (pauses + 1), ramp[-1])]
    frame = _frame(p[None, :] + 4e3 * rng.normal(size=(4, p.size)), np.zeros(p.size))
    t = np.arange(p.size) / RATE
    if paused:
        for k in range(1, pauses + 1):
            t[700 + 1000 * k :] += 600.0
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    return frame.with_columns(
        pl.Series("time_utc", [start + dt.timedelta(seconds=float(s)) for s in t])
    )


def test_a_logger_pause_at_rest_leaves_the_seals_as_they_were():
    """LuGre seals at rest drift only as far as the oil's played travel moves them: a
    logger paused at rest (the same state either side) must not add travel at its
    edges. Over 8 pauses of 10 min on 3 noise draws, the seals' summed friction drifts
    at most 2x as far as in the same samples logged without the pauses (the filters'
    edges carry 0.6-0.95 of a sample's noise, :func:`transforms.lowpass.edge_levels`; with
    scipy's odd extension about the edge sample, 3-5x: 124-194 N against 29-44 N)."""
    lugre = parse_hoist(EXAMPLE_HOIST.read_text().replace('    "presliding_hysteresis",\n', ""))
    assert "presliding_hysteresis" not in lugre.model.effects
    drift = {True: 0.0, False: 0.0}
    for seed in range(3):
        for paused in (True, False):
            out = compensate(_paused_rest(8, seed, paused=paused), lugre)
            summed = sum(out[f"friction{i}_n"].to_numpy() for i in range(1, 5))
            assert summed[900:1700].mean() > 4000.0  # the rise left the seals loaded
            means = [summed[700 + 1000 * k + 200 : 700 + 1000 * (k + 1)].mean() for k in range(9)]
            drift[paused] += abs(means[-1] - means[0])
    assert drift[True] < 2.0 * drift[False]


def test_positions_and_phases_are_labelled():
    n = 500
    out = compensate(_frame(np.full(n, 5e6), np.zeros(n), depth=320.0), HOIST)
    assert set(out["position"].unique()) == {"middle"}
    assert set(out["phase"].unique()) == {"standstill"}


@pytest.mark.parametrize("cutoff_hz", [2.0, 10.0])
def test_settings_are_respected(cutoff_hz):
    """The pressure low-pass runs at the settings' cut-off: a 5 Hz ripple on the sensors
    comes out scaled by the forward-backward Butterworth's gain (order 4, bilinear),
    |H|^2 = 1 / (1 + (tan(pi f / fs) / tan(pi fc / fs))^8), by hand: 6.19e-4 at a 2 Hz
    cut-off, 0.9968 at 10 Hz."""
    n, f_hz, ripple = 1000, 5.0, 2e4
    t = np.arange(n) / RATE
    p = 4e6 + ripple * np.sin(2 * np.pi * f_hz * t)
    out = compensate(
        _frame(p, np.zeros(n)), HOIST, settings=CompensationSettings(pressure_cutoff_hz=cutoff_hz)
    )
    assert out.height == n
    inner = slice(200, 800)  # whole periods, away from the filter's edges
    wave = out["p1_pa"].to_numpy()[inner] - 4e6
    in_phase = 2 * np.mean(wave * np.sin(2 * np.pi * f_hz * t[inner])) / ripple
    gain = 1 / (1 + (np.tan(np.pi * f_hz / RATE) / np.tan(np.pi * cutoff_hz / RATE)) ** 8)
    assert in_phase == pytest.approx(gain, rel=0.01)


def test_empty_input_gives_empty_schema():
    empty = _frame(np.full(1, 4e6), np.zeros(1)).head(0)
    out = compensate(empty, HOIST)
    assert out.height == 0
    assert out.columns == ROPE_TENSIONS.names


def test_logger_rate_from_the_record_ignores_gaps_and_jitter():
    rng = np.random.default_rng(5)
    t = np.arange(200_000) / 20.0 + rng.normal(0, 2e-4, 200_000)
    t[50_000:] += 30.0  # a 30 s logger gap
    t[120_000:] += 3600.0  # and an hour off
    assert logger_rate_hz(np.sort(t)) == pytest.approx(20.0, rel=1e-3)
    assert logger_rate_hz(np.array([5.0])) == 100.0  # nothing to measure: the default


def test_a_frame_in_chunks_gives_the_same_tensions():
    """A day read from Parquet arrives as one chunk per row group (and with nulls from
    dropped channels); the columns are read chunk by chunk, the result is the same."""
    v = 5e-3
    x = _equalising_flow(v, seconds=30.0)
    frame = _frame(np.full(x.shape[1], 5e6), x, speed=np.linspace(0.0, 2.0, x.shape[1]))
    frame = frame.with_columns(
        pl.when(pl.int_range(pl.len()) % 97 == 3).then(None).otherwise(pl.col(c)).alias(c)
        for c in ("p2_pa", "speed_m_s", "oil_temp_c")
    )
    chunked = pl.concat([frame.slice(k, 700) for k in range(0, frame.height, 700)], rechunk=False)
    assert chunked["p1_pa"].n_chunks() > 1
    whole = compensate(frame.rechunk(), HOIST)
    assert compensate(chunked, HOIST).equals(whole, null_equal=True)
    assert whole["p2_pa"].null_count() == frame["p2_pa"].null_count()


def test_a_failing_stage_raises_instead_of_hanging(monkeypatch):
    """The rope jobs wait for the common mode, which the calling thread computes: when
    that fails, they must fail too, and compensate must raise, not wait for ever."""
    import threading

    import transforms.compensation_block as module

    def broken(*args, **kwargs):
        raise RuntimeError("common mode failed")

    monkeypatch.setattr(module, "common_mode_displacement", broken)
    x = _equalising_flow(5e-3, seconds=5.0)
    frame = _frame(np.full(x.shape[1], 5e6), x)
    outcome: list[BaseException] = []

    def call() -> None:
        try:
            compensate(frame, HOIST)
        except BaseException as error:
            outcome.append(error)

    worker = threading.Thread(target=call, daemon=True)
    worker.start()
    worker.join(timeout=60)
    assert not worker.is_alive()
    assert len(outcome) == 1
    assert str(outcome[0]) == "common mode failed"


def _a_trip(seed: int, n: int = 9000):
    """Four sensors' pressures (4, n) of 90 s at RATE: 10 s at rest, a 70 s trip whose
    pressure swings 0.2 MPa, 10 s at rest, 5 kPa of noise; and the compensation of such
    pressures on that motion, no x logged (the ropes' prior)."""
    t = np.arange(n) / RATE
    rng = np.random.default_rng(seed)
    load = 4.0e6 + 2.0e5 * np.sin(2 * np.pi * t / 40.0)  # the trip's pressure swing
    speed = np.where((t > 10.0) & (t < 80.0), 5.0, 0.0)
    depth = np.cumsum(speed) / RATE

    def tensions(pressures: np.ndarray) -> pl.DataFrame:
        return compensate(_frame(pressures, None, speed=speed).with_columns(depth_m=depth), HOIST)

    return load + rng.normal(0.0, 5e3, (4, n)), tensions


def test_a_stuck_sensor_is_taken_as_not_logged_not_as_its_reading():
    """Rope 3's sensor repeats one reading for 40 s (past the example's 30 s
    ``flatline_duration``) while the conveyance travels and the others follow the load:
    its tension and the load are null there (as where it is silent), the other ropes'
    as with the sensor working; its reading repeated for 20 s, and a sensor that updates
    every fifth sample (each reading repeated), are pressures as they are."""
    n = 9000
    p, tensions = _a_trip(seed=5)
    working = tensions(p)
    stuck = p.copy()
    stuck[2, 2000:6000] = stuck[2, 2000]  # 40 s
    out = tensions(stuck)
    silent = out.slice(2000, 4000)
    assert silent["tension3_n"].null_count() == silent["load_n"].null_count() == 4000
    assert out.slice(0, 2000)["tension3_n"].null_count() == 0
    assert out.slice(6000, n - 6000)["load_n"].null_count() == 0
    for rope in (1, 2, 4):
        got, want = out[f"tension{rope}_n"].to_numpy(), working[f"tension{rope}_n"].to_numpy()
        # the oil's motion from three sensors instead of four: the same within the noise
        assert np.max(np.abs(got - want)) < 0.01 * np.mean(want)

    short = p.copy()
    short[2, 2000:4000] = short[2, 2000]  # 20 s: no flat line
    assert tensions(short).slice(2000, 2000)["tension3_n"].null_count() == 0
    slow = p.copy()
    slow[2] = np.repeat(p[2, ::5], 5)  # a sensor updating at 20 Hz
    assert tensions(slow)["load_n"].null_count() == 0


def test_a_sensor_off_the_others_at_every_rest_takes_their_reading():
    """Rope 3's sensor reads 0.24 MPa high (6 %) all record (a bad calibration): at the
    rests, where the pipes equalise the chambers, it departs from the others, so it is
    no pressure anywhere (``CompensationContext.offset_sensors``): the stick-slip
    solution runs on the others and rope 3 takes their reading. Its tension, the
    others' and the load are those of the sensor working, within the noise; its raw
    tension keeps the reading. Left in while the oil flows, it moved every seal."""
    p, tensions = _a_trip(seed=7)
    working = tensions(p)
    off = p.copy()
    off[2] += 0.24e6
    out = tensions(off)
    for rope in (1, 2, 3, 4):
        got, want = out[f"tension{rope}_n"].to_numpy(), working[f"tension{rope}_n"].to_numpy()
        assert np.max(np.abs(got - want)) < 0.01 * np.mean(want), rope
    got, want = out["load_n"].to_numpy(), working["load_n"].to_numpy()
    assert np.max(np.abs(got - want)) < 0.005 * np.mean(want)
    area = HOIST.cylinders.bore_area_m2
    raw = out["tension_raw3_n"].to_numpy() - working["tension_raw3_n"].to_numpy()
    np.testing.assert_allclose(raw, 0.24e6 * area, rtol=1e-9)
    assert (out["p3_pa"].to_numpy() - working["p3_pa"].to_numpy()).min() > 0.2e6


def test_a_sensor_apart_from_the_others_at_every_rest_widens_its_band():
    """Rope 3's sensor reads 2 % low all record (a gain error under the disagreement
    alarm's 5 %): the record's context finds it apart at the rests
    (``CompensationContext.sensor_departures``), and the bands of its rope and of the
    load reach the bands they would have with it reading as the others: their upper
    edges rise by 0.02 / 0.98 of its pressure force, the estimates stay; the working
    record's sensors read alike at rest, and its context holds no departure."""
    import dataclasses

    from transforms.compensation import compensate_window, compensation_context
    from transforms.compensation_record import context_sample, context_stride

    p, _ = _a_trip(seed=8)
    t = np.arange(p.shape[1]) / RATE
    speed = np.where((t > 10.0) & (t < 80.0), 5.0, 0.0)
    frame = _frame(p, None, speed=speed).with_columns(depth_m=np.cumsum(speed) / RATE)
    low = frame.with_columns(pl.col("p3_pa") * 0.98)

    def context(record):
        stride = context_stride(record.height)
        sample = context_sample(record, stride).collect()
        return compensation_context(sample, HOIST, CompensationSettings(), stride)

    assert context(frame).sensor_departures == ()
    found = context(low)
    assert found.sensor_departures[2] == pytest.approx(-0.0196, abs=1e-3)
    # the others by what one low sensor does to the median of four, a noise's fraction
    assert max(abs(d) for k, d in enumerate(found.sensor_departures) if k != 2) < 1e-3
    widened, _ = compensate_window(low, HOIST, context=found)
    plain, _ = compensate_window(
        low, HOIST, context=dataclasses.replace(found, sensor_departures=())
    )
    assert widened["tension3_n"].equals(plain["tension3_n"])
    area = HOIST.cylinders.bore_area_m2
    force = [  # each rope's tension were its sensor reading as the others
        -widened[f"p{k + 1}_pa"].to_numpy() * d / (1.0 + d) * area
        for k, d in enumerate(found.sensor_departures)
    ]
    for column, shift in (("tension3", force[2]), ("load", sum(force))):
        assert np.min(shift) > 500.0  # 2 % of ~3.1e6 Pa x 7.85e-3 m2, ~+620 N
        rise = widened[f"{column}_hi_n"].to_numpy() - plain[f"{column}_hi_n"].to_numpy()
        np.testing.assert_allclose(rise, shift, rtol=1e-4, atol=0.5)  # float32 bands
        assert widened[f"{column}_lo_n"].equals(plain[f"{column}_lo_n"])


def test_a_frozen_logger_while_travelling_is_taken_as_not_logged():
    """Every sensor repeats its reading for 40 s while the conveyance travels (a logger
    whose pressures froze, the ``sensor_stuck`` rule): the tensions and the load are null
    there; the same frozen readings at rest, which that rule does not name, stay."""
    n = 9000
    t = np.arange(n) / RATE
    rng = np.random.default_rng(6)
    p = 4.0e6 + 2.0e5 * np.sin(2 * np.pi * t / 40.0) + rng.normal(0.0, 5e3, (4, n))
    p[:, 2000:6000] = p[:, 2000:2001]

    def tensions(speed):
        depth = np.cumsum(speed) / RATE
        return compensate(_frame(p, None, speed=speed).with_columns(depth_m=depth), HOIST)

    frozen = tensions(np.where((t > 10.0) & (t < 80.0), 5.0, 0.0)).slice(2000, 4000)
    assert frozen["load_n"].null_count() == frozen["tension1_n"].null_count() == 4000
    assert tensions(np.zeros(n)).slice(2000, 4000)["load_n"].null_count() == 0
