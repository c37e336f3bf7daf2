"""Alarms on synthetic 100 Hz hoist data with injected events of known start and end."""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest

from schemas.hoist import EXAMPLE_HOIST, G_STANDARD, load_hoist
from schemas.tables import ALARMS
from transforms.alarm_events import flatline_runs, reading_step, runs, unchanged
from transforms.alarms import (
    ALARM_RULES,
    alarm_id,
    evaluate_alarms,
    evaluate_alarms_in_blocks,
    rule_thresholds,
)
from transforms.compensation_record import (
    CompensationSettings,
    compensation_margins_s,
    flatlined_samples,
)

FS_HZ = 100.0
T0 = dt.datetime(2026, 3, 2, 6, 0, tzinfo=dt.UTC)
ROPE_SHARE = np.array([1.02, 0.99, 1.01, 0.98]) / 4.0  # static share of the load per rope


@pytest.fixture(scope="module")
def hoist():
    return load_hoist(EXAMPLE_HOIST)


def _trapezoid(distance_m: float, t: np.ndarray, v_max: float, acc: float):
    """Distance, speed and signed acceleration of a trapezoidal move over ``t``."""
    t_acc = v_max / acc
    t_cruise = (distance_m - v_max * t_acc) / v_max
    t_end = 2 * t_acc + t_cruise
    t = np.clip(t, 0.0, t_end)
    accel = np.where(t < t_acc, acc, np.where(t < t_acc + t_cruise, 0.0, -acc))
    speed = np.where(
        t < t_acc,
        acc * t,
        np.where(t < t_acc + t_cruise, v_max, v_max - acc * (t - t_acc - t_cruise)),
    )
    dist = np.where(
        t < t_acc,
        0.5 * acc * t**2,
        np.where(
            t < t_acc + t_cruise,
            0.5 * acc * t_acc**2 + v_max * (t - t_acc),
            distance_m - 0.5 * acc * (t_end - t) ** 2,
        ),
    )
    return dist, np.maximum(speed, 0.0), accel, t_end


def synthetic_day(hoist, payloads_kg, *, seed=0, standstill_s=20.0):
    """A ROPE_TENSIONS frame: cycles of load at bottom, trip up, unload, trip down.

    Returns the frame and a list of segments (kind, trip_id, start_s, end_s, payload).
    Payload changes as a step in the middle of each standstill (trip_id null there).
    """
    top, bottom = hoist.shaft.positions_m["pithead"], hoist.shaft.positions_m["bottom"]
    distance = bottom - top
    pieces, segments, t_now, trip = [], [], 0.0, 0
    for payload in payloads_kg:
        for kind in ("load", "up", "unload", "down"):
            if kind in ("load", "unload"):
                n = int(standstill_s * FS_HZ)
                t = np.arange(n) / FS_HZ
                before, after = (0.0, payload) if kind == "load" else (payload, 0.0)
                pieces.append(
                    {
                        "t": t_now + t,
                        "depth": np.full(n, bottom if kind == "load" else top),
                        "speed": np.zeros(n),
                        "a_up": np.zeros(n),
                        "payload": np.where(t < standstill_s / 2, before, after),
                        "trip": np.full(n, -1),
                    }
                )
                segments.append((kind, None, t_now, t_now + n / FS_HZ, payload))
                t_now += n / FS_HZ
                continue
            trip += 1
            _, _, _, t_end = _trapezoid(distance, np.zeros(1), 10.0, 0.75)
            n = int(np.ceil(t_end * FS_HZ)) + 1
            t = np.arange(n) / FS_HZ
            dist, v, acc, _ = _trapezoid(distance, t, 10.0, 0.75)
            up = kind == "up"
            pieces.append(
                {
                    "t": t_now + t,
                    "depth": bottom - dist if up else top + dist,
                    "speed": -v if up else v,  # positive downwards
                    "a_up": acc if up else -acc,
                    "payload": np.full(n, payload if up else 0.0),
                    "trip": np.full(n, trip),
                }
            )
            segments.append((kind, trip, t_now, t_now + n / FS_HZ, payload if up else 0.0))
            t_now += n / FS_HZ
    cat = {k: np.concatenate([p[k] for p in pieces]) for k in pieces[0]}
    rng = np.random.default_rng(seed)
    n = cat["t"].size
    tail_kg = (
        hoist.conveyance.tail_ropes
        * hoist.ropes.tail_rope_mass_per_length_kg_m
        * (hoist.shaft.depth_m - cat["depth"])
    )
    # the tail ropes hang from the conveyance and accelerate with it (issue 13)
    load = (hoist.conveyance.mass_kg + cat["payload"] + tail_kg) * (G_STANDARD + cat["a_up"])
    moving = np.abs(cat["speed"]) > 0
    tensions = []
    for i in range(4):
        ringing = 0.004 * np.sin(2 * np.pi * 1.7 * cat["t"] + i) * moving
        noise = rng.normal(0.0, 0.004, n)
        tensions.append(load * ROPE_SHARE[i] * (1.0 + ringing + noise))
    jitter_s = rng.uniform(-0.001, 0.001, n)
    frame = pl.DataFrame(
        {
            "time_utc": pl.Series(
                np.datetime64(T0.replace(tzinfo=None), "us")
                + ((cat["t"] + jitter_s) * 1e6).astype("timedelta64[us]")
            ).dt.replace_time_zone("UTC"),
            "depth_m": cat["depth"],
            "speed_m_s": cat["speed"],
            "acceleration_up_m_s2": cat["a_up"],
            "trip_id": pl.Series(cat["trip"], dtype=pl.Int64).set(pl.Series(cat["trip"] < 0), None),
            **{f"tension{i + 1}_n": tensions[i] for i in range(4)},
        }
    )
    return frame, segments


def finish(frame: pl.DataFrame, hoist) -> pl.DataFrame:
    """Derive the remaining ROPE_TENSIONS columns from tension{i}_n."""
    area = hoist.cylinders.bore_area_m2
    return frame.with_columns(
        *[(pl.col(f"tension{i}_n") * 0.95).alias(f"tension_raw{i}_n") for i in range(1, 5)],
        *[(pl.col(f"tension{i}_n") * 0.95 / area).alias(f"p{i}_pa") for i in range(1, 5)],
        load_n=pl.sum_horizontal(f"tension{i}_n" for i in range(1, 5)),
        load_raw_n=pl.sum_horizontal(f"tension{i}_n" for i in range(1, 5)) * 0.95,
    )


def _at(frame: pl.DataFrame, start_s: float, end_s: float) -> pl.Expr:
    t = (pl.col("time_utc") - pl.lit(T0)).dt.total_microseconds() / 1e6
    return (t >= start_s) & (t < end_s)


def _load_scaled(frame: pl.DataFrame, window: tuple[float, float], factor: float) -> pl.DataFrame:
    """The four ropes' tensions x ``factor`` over ``window`` [s]: the load, shared alike."""
    return frame.with_columns(
        pl.when(_at(frame, *window))
        .then(pl.col(f"tension{i}_n") * factor)
        .otherwise(pl.col(f"tension{i}_n"))
        for i in range(1, 5)
    )


def _seconds(value: dt.datetime) -> float:
    return (value - T0).total_seconds()


def _events(alarms: pl.DataFrame, rule: str) -> list[tuple[int | None, float, float]]:
    rows = alarms.filter(pl.col("rule") == rule).sort("rope", "start_utc")
    return [
        (r["rope"], _seconds(r["start_utc"]), _seconds(r["end_utc"]))
        for r in rows.iter_rows(named=True)
    ]


def _assert_events(found, expected, *, tol_s=1.0):
    assert len(found) == len(expected), (found, expected)
    for (rope, s, e), (rope_x, s_x, e_x) in zip(
        sorted(found, key=str), sorted(expected, key=str), strict=True
    ):
        assert rope == rope_x
        assert abs(s - s_x) <= tol_s, (rope, s, s_x)
        assert abs(e - e_x) <= tol_s, (rope, e, e_x)


def test_thresholds_follow_the_regulations(hoist):
    th = rule_thresholds(hoist)
    # Quebec s.253.2 read per rope: 60 % of 8.2 t x g / 4, and max static + 10 % of 900 kN
    assert th.slack_n == pytest.approx(0.6 * 8200 * 9.80665 / 4)
    assert th.tight_n == pytest.approx((8200 + 6000 + 2 * 6.2 * 620) * 9.80665 / 4 + 90e3)
    assert th.imbalance_fraction == 0.10
    assert {r.name for r in ALARM_RULES.values()} >= {"rope_imbalance", "slack_rope", "overload"}


def test_clean_day_raises_no_alarm(hoist):
    payloads = [4000.0, 5500.0, 3000.0, 6000.0, 0.0, 5000.0, 4500.0, 2500.0]
    frame, segments = synthetic_day(hoist, payloads, seed=1)
    frame = finish(frame, hoist)
    trips = pl.DataFrame(
        {
            "trip_id": [s[1] for s in segments if s[1]],
            "payload_kg": [s[4] for s in segments if s[1]],
        }
    )
    alarms = evaluate_alarms(frame, hoist, run_id="r-clean", trip_payloads=trips)
    assert frame.height > 100_000
    assert alarms.height == 0, alarms


def test_injected_events_found_once_with_start_and_end(hoist):
    payloads = [4000.0, 7000.0, 5000.0]  # trip 3 (second up trip) carries 7 t: overload
    frame, segments = synthetic_day(hoist, payloads, seed=2)
    # Overload: from the load step in the 2nd cycle's loading to the unload step.
    load2 = next(s for s in segments if s[0] == "load" and s[4] == 7000.0)
    unload2 = next(s for s in segments if s[0] == "unload" and s[4] == 7000.0)
    overload = (None, (load2[2] + load2[3]) / 2, (unload2[2] + unload2[3]) / 2)
    # Imbalance on rope 2 during the first up trip's cruise (sum kept): 20 % up, others down.
    up1 = next(s for s in segments if s[0] == "up")
    imb = (up1[2] + 30.0, up1[2] + 38.0)
    # Slack rope 3 during the first down trip's cruise: 25 % of its share, others take it.
    down1 = next(s for s in segments if s[0] == "down")
    slack = (down1[2] + 25.0, down1[2] + 30.0)
    # Short blip (0.2 s, below min_duration): no alarm.
    blip = (down1[2] + 50.0, down1[2] + 50.2)
    # Imbalance of rope 1 oscillating around the threshold (11 % +- 2 % at 0.5 Hz) for
    # 10 s: it drops below the release level every 2 s, yet it is one alarm, not five.
    down2 = [s for s in segments if s[0] == "down"][1]
    flicker = (down2[2] + 20.0, down2[2] + 30.0)
    t = np.arange(frame.height) / FS_HZ
    flick = np.where(
        (t >= blip[0]) & (t < blip[1]), 1.3, 1.122 + 0.028 * np.sin(2 * np.pi * 0.5 * t)
    )

    frame = (
        frame.with_columns(
            pl.when(_at(frame, *imb))
            .then(pl.col("tension2_n") * 1.2)
            .otherwise(pl.col("tension2_n")),
            *[
                pl.when(_at(frame, *imb))
                .then(pl.col(c) - 0.2 * pl.col("tension2_n") / 3)
                .otherwise(pl.col(c))
                for c in ("tension1_n", "tension3_n", "tension4_n")
            ],
        )
        .with_columns(
            pl.when(_at(frame, *slack))
            .then(pl.col("tension3_n") * 0.25)
            .otherwise(pl.col("tension3_n")),
            *[
                pl.when(_at(frame, *slack))
                .then(pl.col(c) + 0.75 * pl.col("tension3_n") / 3)
                .otherwise(pl.col(c))
                for c in ("tension1_n", "tension2_n", "tension4_n")
            ],
        )
        .with_columns(
            pl.when(_at(frame, *blip) | _at(frame, *flicker))
            .then(pl.col("tension1_n") * pl.Series(flick))
            .otherwise(pl.col("tension1_n")),
        )
    )
    frame = finish(frame, hoist)
    trips = pl.DataFrame(
        {
            "trip_id": [s[1] for s in segments if s[1]],
            "payload_kg": [s[4] for s in segments if s[1]],
        }
    )
    alarms = evaluate_alarms(frame, hoist, run_id="r-inj", trip_payloads=trips)

    assert alarms.schema == pl.from_arrow(ALARMS.empty_table()).schema
    _assert_events(_events(alarms, "overload"), [overload])
    _assert_events(_events(alarms, "slack_rope"), [(3, *slack)])
    # imbalance: rope 2 in its window; in the slack window every rope is > 10 % off the mean
    # (rope 3 at 25 %, the others carrying 1.25x); the flicker on rope 1 is one event.
    expected_imbalance = [(2, *imb), *[(i, *slack) for i in (1, 2, 3, 4)], (1, *flicker)]
    found = _events(alarms, "rope_imbalance")
    # the flicker holds the hysteresis band with gaps < merge gap: one alarm within ~1 s
    _assert_events(found, expected_imbalance)
    assert set(alarms["rule"]) == {"overload", "slack_rope", "rope_imbalance"}
    # peaks and thresholds
    slack_row = alarms.filter(pl.col("rule") == "slack_rope").row(0, named=True)
    assert (
        slack_row["peak_value"]
        < slack_row["threshold"]
        == pytest.approx(rule_thresholds(hoist).slack_n)
    )
    assert slack_row["unit"] == "N"
    assert "253.2" in slack_row["message"]
    over = alarms.filter(pl.col("rule") == "overload").row(0, named=True)
    assert over["peak_value"] / G_STANDARD == pytest.approx(8200 + 7000 + 2 * 6.2 * 620, rel=0.02)
    # deterministic ids: the same run again gives the same ids
    again = evaluate_alarms(frame, hoist, run_id="r-inj-2", trip_payloads=trips)
    assert sorted(again["alarm_id"]) == sorted(alarms["alarm_id"])
    assert alarms["alarm_id"].n_unique() == alarms.height
    row = alarms.row(0, named=True)
    assert row["alarm_id"] == alarm_id(
        row["site"], row["hoist"], row["rule"], row["rope"], row["start_utc"]
    )


def test_reconciliation_residual_at_standstill(hoist):
    frame, segments = synthetic_day(hoist, [4000.0, 4000.0], seed=3)
    # The 2nd unload standstill: the 4 t payload stays on for its first 10 s. Give those
    # samples a trip id whose payload is known, and let the sensors read 6 % low for 6 s.
    unload = [s for s in segments if s[0] == "unload"][1]
    loaded = (unload[2], unload[2] + 10.0)
    drift = (unload[2] + 2.0, unload[2] + 8.0)
    frame = frame.with_columns(
        *[
            pl.when(_at(frame, *drift))
            .then(pl.col(f"tension{i}_n") * 0.94)
            .otherwise(pl.col(f"tension{i}_n"))
            for i in range(1, 5)
        ],
        trip_id=pl.when(_at(frame, *loaded)).then(99).otherwise(pl.col("trip_id")),
    )
    frame = finish(frame, hoist)
    unknown = evaluate_alarms(frame, hoist, run_id="r")
    assert unknown.filter(pl.col("rule") == "reconciliation_residual").height == 0
    known = pl.DataFrame({"trip_id": [99], "payload_kg": [4000.0]})
    alarms = evaluate_alarms(frame, hoist, run_id="r", trip_payloads=known)
    _assert_events(_events(alarms, "reconciliation_residual"), [(None, *drift)])
    row = alarms.filter(pl.col("rule") == "reconciliation_residual").row(0, named=True)
    assert row["peak_value"] == pytest.approx(0.06, abs=0.01)


def test_sensor_faults(hoist):
    frame, _ = synthetic_day(hoist, [3000.0, 3000.0], seed=4)
    frame = finish(frame, hoist)
    n = frame.height
    t = np.arange(n) / FS_HZ
    p4 = frame["p4_pa"].to_numpy().copy()
    flat = (t >= 100.0) & (t < 140.0)  # 40 s flat-line on sensor 4 while the others move
    p4[flat] = p4[np.argmax(flat)]
    p2 = frame["p2_pa"].to_numpy().copy()
    over = (t >= 200.0) & (t < 203.0)
    p2[over] = 26e6  # above the 25 MPa full scale
    p1 = frame["p1_pa"].to_numpy().copy()
    p1[(t >= 250.0) & (t < 252.0)] = np.nan  # sensor 1 missing 2 s
    frame = frame.with_columns(
        p4_pa=pl.Series(p4), p2_pa=pl.Series(p2), p1_pa=pl.Series(p1).fill_nan(None)
    )
    # logger gap: 3 s without rows
    times = (frame["time_utc"] - pl.lit(T0)).dt.total_microseconds() / 1e6
    frame = frame.filter((times < 300.0) | (times >= 303.0))
    alarms = evaluate_alarms(frame, hoist, run_id="r")
    _assert_events(_events(alarms, "sensor_flatline"), [(4, 100.0, 140.0)])
    _assert_events(_events(alarms, "sensor_out_of_range"), [(2, 200.0, 203.0)])
    _assert_events(_events(alarms, "sensor_dropout"), [(None, 300.0, 303.0), (1, 250.0, 252.0)])
    assert alarms.filter(pl.col("rule") == "sensor_out_of_range")["peak_value"][0] == 26e6
    assert _events(alarms, "sensor_stuck") == []


def test_a_logger_that_rounds_coarsely_flatlines_only_a_stuck_sensor(hoist):
    """A logger rounding to 50 kPa (ten times the sensors' noise) holds each reading
    for minutes at rest while the others flip between neighbouring steps: not a stuck
    sensor (every sensor was taken for one, and the compensation nulled its tensions).
    A sensor that stays put while the pressure moves by several steps still is."""
    rng = np.random.default_rng(7)
    rate, step = 50.0, 50e3
    t = np.arange(0.0, 600.0, 1.0 / rate)
    oil = 3.01e6 + 6e5 * np.clip((t - 300.0) / 20.0, 0.0, 1.0)  # at rest, a rise, at rest
    noisy = [oil + off + rng.normal(0.0, 5e3, t.size) for off in (0.0, 8e3, -6e3, 12e3)]
    rounded = [np.round(p / step) * step for p in noisy]
    held = max(float(np.max(t[e] - t[s])) for s, e in (runs(unchanged(p)) for p in rounded))
    assert held > 4 * hoist.alarms.flatline_duration_s  # the rounding holds readings
    duration = hoist.alarms.flatline_duration_s
    assert all(s.size == 0 for s, _ in flatline_runs(rounded, t, duration))
    frame = pl.DataFrame({f"p{i}_pa": p for i, p in enumerate(rounded, 1)}).with_columns(
        depth_m=pl.lit(600.0)
    )
    assert flatlined_samples(frame, t, hoist) == {}
    # sensor 4 holds its reading through the rise: stuck, and only it (its jump back at
    # 400 s, within the others' rounded readings at rest, does not make them stuck)
    stuck = rounded[3].copy()
    through = (t >= 250.0) & (t < 400.0)
    stuck[through] = stuck[np.argmax(through)]
    runs_found = flatline_runs([*rounded[:3], stuck], t, duration)
    assert [s.size for s, _ in runs_found] == [0, 0, 0, 1]
    start, end = runs_found[3][0][0], runs_found[3][1][0]
    assert t[start] <= 250.0
    assert t[end] >= 399.0
    masks = flatlined_samples(frame.with_columns(p4_pa=pl.Series(stuck)), t, hoist)
    assert set(masks) == {"p4_pa"}
    assert masks["p4_pa"][through].all()
    # without the rounding any change of another sensor is enough, as before
    live = [p.copy() for p in noisy]
    live[3][through] = live[3][np.argmax(through)]
    assert [s.size for s, _ in flatline_runs(live, t, duration)] == [0, 0, 0, 1]
    # three stuck while the fourth follows the oil: the held ones say nothing of each
    # other, the one that moves speaks for all three
    for k in (1, 2):
        live[k][through] = live[k][np.argmax(through)]
    assert [s.size for s, _ in flatline_runs(live, t, duration)] == [0, 1, 1, 1]


def test_tight_rope(hoist):
    frame, segments = synthetic_day(hoist, [3000.0], seed=6)
    threshold = rule_thresholds(hoist).tight_n
    up = next(s for s in segments if s[0] == "up")
    window = (up[2] + 40.0, up[2] + 42.0)  # rope 1 jammed: 1.2 x the tight threshold
    frame = finish(
        frame.with_columns(
            pl.when(_at(frame, *window)).then(1.2 * threshold).otherwise(pl.col("tension1_n"))
            .alias("tension1_n")
        ),
        hoist,
    )  # fmt: skip
    alarms = evaluate_alarms(frame, hoist, run_id="r")
    _assert_events(_events(alarms, "tight_rope"), [(1, *window)])
    tight = alarms.filter(pl.col("rule") == "tight_rope").row(0, named=True)
    assert tight["peak_value"] == pytest.approx(1.2 * threshold)
    # the same spike puts every rope > 10 % off the mean; the sign says which way
    imbalance = alarms.filter(pl.col("rule") == "rope_imbalance").sort("rope")
    _assert_events(_events(alarms, "rope_imbalance"), [(i, *window) for i in (1, 2, 3, 4)])
    assert imbalance["peak_value"][0] > 0.1
    assert (imbalance["peak_value"][1:] < -0.1).all()


def test_a_long_debounce_across_a_block_edge_is_raised_as_on_the_whole_record(hoist):
    """``min_duration = 5 min`` (a valid setting) and a 340 s imbalance of rope 1 at rest
    straddling a block edge: evaluated in 10-minute blocks it is raised once, with the
    start and end the whole record gives (the fixed 120 s margin lost it: neither window
    saw 300 s of it)."""
    from transforms.alarms import evaluate_alarms_in_blocks

    alarms_section = hoist.alarms.model_copy(update={"min_duration_s": 300.0})
    slow = hoist.model_copy(update={"alarms": alarms_section})
    frame, segments = synthetic_day(slow, [3000.0], standstill_s=420.0)
    rest = next(s for s in segments if s[0] == "unload")
    event = (rest[2] + 20.0, rest[2] + 360.0)  # within the stay's first, unloaded half
    frame = finish(
        frame.with_columns(
            pl.when(_at(frame, *event)).then(pl.col("tension1_n") * 1.25)
            .otherwise(pl.col("tension1_n")).alias("tension1_n")
        ),
        slow,
    )  # fmt: skip
    edge = T0 + dt.timedelta(seconds=event[0] + 170.0)
    blocks, lo = [], frame["time_utc"].min()
    while lo <= frame["time_utc"].max():
        hi = edge if lo < edge else lo + dt.timedelta(minutes=10)
        blocks.append((lo, hi))
        lo = hi
    t = pl.col("time_utc")

    def read(a: dt.datetime, b: dt.datetime) -> pl.DataFrame:
        return frame.filter((t >= a) & (t < b))

    whole = _events(evaluate_alarms(frame, slow, run_id="r"), "rope_imbalance")
    blocked = _events(evaluate_alarms_in_blocks(read, blocks, slow, run_id="r"), "rope_imbalance")
    _assert_events(whole, [(1, *event)])
    _assert_events(blocked, whole, tol_s=0.05)


def test_a_sensor_off_the_others_at_rest_is_a_disagreement(hoist):
    """Sensor 1 reads 20 % high for 60 s at rest (its ropes' shares differ by up to 3 %,
    a real imbalance the sensors show while the ropes hold it): one
    ``sensor_disagreement`` on rope 1 over those 60 s, its peak the departure from the
    median of the four (at least 1.02 x 1.2 / median - 1 = +0.22); a 20 s step, shorter than
    ``flatline_duration``, and the same step while travelling are not."""
    frame, segments = synthetic_day(hoist, [3000.0], seed=5, standstill_s=200.0)
    frame = finish(frame, hoist)
    rest = next(s for s in segments if s[0] == "unload")
    up = next(s for s in segments if s[0] == "up")
    step = (rest[2] + 10.0, rest[2] + 70.0)
    short = (rest[2] + 120.0, rest[2] + 140.0)
    moving = (up[2] + 10.0, up[2] + 50.0)
    windows = _at(frame, *step) | _at(frame, *short) | _at(frame, *moving)
    frame = frame.with_columns(
        pl.when(windows).then(pl.col("p1_pa") * 1.2).otherwise(pl.col("p1_pa")).alias("p1_pa")
    )
    alarms = evaluate_alarms(frame, hoist, run_id="r")
    _assert_events(_events(alarms, "sensor_disagreement"), [(1, *step)], tol_s=0.05)
    peak = alarms.filter(pl.col("rule") == "sensor_disagreement")["peak_value"][0]
    shares = np.array([1.02 * 1.2, 0.99, 1.01, 0.98])
    assert 0.0 < shares[0] / np.median(shares) - 1.0 <= peak < 0.3  # signed, noise on top


def test_a_sensor_with_its_declared_gain_agrees_and_so_does_a_hoist_off_its_ropes(hoist):
    """Sensor 1 declared with a gain of 1.15: its reading (the logged column) is 15 %
    high and its calibrated pressure (``p1_pa``) is not; neither disagrees (the rule
    calibrated ``p1_pa`` a second time). At rest with the pressures near zero (a hoist
    off its ropes) 20 % of nearly nothing is below the slack floor: no alarm."""
    from transforms.alarm_checks import LOGGED_PRESSURE

    sensors = [s.model_copy(update={"gain": 1.15}) if s.cylinder == 1 else s
               for s in hoist.sensors]  # fmt: skip
    gained = hoist.model_copy(update={"sensors": sensors})
    frame, _ = synthetic_day(gained, [3000.0], seed=7, standstill_s=100.0)
    frame = finish(frame, gained)
    assert _events(evaluate_alarms(frame, gained, run_id="r"), "sensor_disagreement") == []
    logged = frame.with_columns(
        *(pl.col(f"p{i}_pa").alias(LOGGED_PRESSURE.format(i=i)) for i in range(2, 5)),
        (pl.col("p1_pa") * 1.15).alias(LOGGED_PRESSURE.format(i=1)),
    )
    assert _events(evaluate_alarms(logged, gained, run_id="r"), "sensor_disagreement") == []
    off_ropes = frame.with_columns(
        pl.col("p1_pa") * 0.0 + 2e4 * 1.2, *(pl.col(f"p{i}_pa") * 0.0 + 2e4 for i in (2, 3, 4))
    )
    assert _events(evaluate_alarms(off_ropes, hoist, run_id="r"), "sensor_disagreement") == []


def _rounded_at_rest(seconds: float, rate: float, drift_pa: float, seed: int) -> tuple:
    """Four sensors of one oil at rest, drifting by ``drift_pa``, 5 kPa of noise, logged
    rounded to 50 kPa."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / rate)
    oil = 3.01e6 + drift_pa * np.sin(np.pi * t / seconds)
    noisy = [oil + off + rng.normal(0.0, 5e3, t.size) for off in (0.0, 8e3, -6e3, 12e3)]
    return t, [np.round(p / 50e3) * 50e3 for p in noisy]


def test_one_reading_off_a_rounded_grid_does_not_set_the_reading_step(hoist):
    """A garbage line (every sensor 1.2 kPa off the logger's 50 kPa grid, once) made the
    smallest change 1.2 kPa: the others' flips between neighbouring steps counted again,
    and healthy sensors at rest flat-lined over a fifth of the record (whole, not in the
    blocks without the line)."""
    t, rounded = _rounded_at_rest(1800.0, 50.0, 60e3, seed=3)
    for p in rounded:
        p[1000] += 1234.0
    assert [reading_step(p) for p in rounded] == [50e3] * 4
    duration = hoist.alarms.flatline_duration_s
    assert all(s.size == 0 for s, _ in flatline_runs(rounded, t, duration))


def test_a_sensor_stuck_through_a_window_flatlines_there_as_in_the_whole_record(hoist):
    """Sensor 4 of a rounded logger sticks at rest for 4 h, longer than a block's window
    (an hour and its margins): the window, where it never changes, read its step as 0
    and took the others' span over three steps for the oil moving, and the block nulled
    an hour of its tension; the whole record, with its step of 50 kPa, does not."""
    t, rounded = _rounded_at_rest(21600.0, 10.0, 60e3, seed=2)
    through = (t >= 3600.0) & (t < 18000.0)
    rounded[3][through] = rounded[3][np.argmax(through)]
    duration = hoist.alarms.flatline_duration_s
    margin = sum(compensation_margins_s(CompensationSettings(), hoist))

    def flagged(pressures, times):
        mask = np.zeros(times.size, dtype=bool)
        for s, e in zip(*flatline_runs(pressures, times, duration)[3], strict=True):
            mask[s : e + 1] = True
        return mask

    whole = flagged(rounded, t)
    for lo in np.arange(3600.0 + margin, 18000.0 - 3600.0 - margin, 3600.0):
        window = (t >= lo - margin) & (t < lo + 3600.0 + margin)
        core = (t[window] >= lo) & (t[window] < lo + 3600.0)
        part = flagged([p[window] for p in rounded], t[window])
        np.testing.assert_array_equal(part[core], whole[window][core], err_msg=str(lo))


def test_a_slow_loggers_own_step_is_not_a_dropout(hoist):
    """A 1 Hz logger whose steps jitter to 1.001 s raised a "no samples logged" alarm at
    nearly every step against a dropout duration of 1 s; its one sample missing (a 2 s
    spacing) is a dropout, also where blocks read the record with its step given."""
    frame, _ = synthetic_day(hoist, [3000.0, 3000.0], seed=4)
    frame = finish(frame, hoist).gather_every(int(FS_HZ))  # 1 Hz, its clock jittering
    frame = frame.filter(pl.int_range(pl.len()) != 200)  # the sample of t = 200 s missing
    steps = frame["time_utc"].diff().dt.total_microseconds().drop_nulls() / 1e6
    assert (steps > 1.0).sum() > 100  # each past the hoist's dropout duration of 1 s
    assert steps.max() == pytest.approx(2.0, abs=0.01)
    alarms = evaluate_alarms(frame, hoist, run_id="r")
    _assert_events(_events(alarms, "sensor_dropout"), [(None, 199.0, 201.0)], tol_s=0.01)
    given = evaluate_alarms(frame, hoist, run_id="r", sample_step_s=1.0)
    assert _events(given, "sensor_dropout") == _events(alarms, "sensor_dropout")
    # block by block, the record's step given, or the first block's median: the same
    edges = [T0, T0 + dt.timedelta(seconds=199.5), T0 + dt.timedelta(hours=1)]
    blocks = [(edges[0], edges[1]), (edges[1], edges[2])]

    def read(lo, hi):
        return frame.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi))

    for step in (1.0, None):
        pieces = evaluate_alarms_in_blocks(read, blocks, hoist, run_id="r", sample_step_s=step)
        assert _events(pieces, "sensor_dropout") == _events(alarms, "sensor_dropout")
    # a 100 Hz record keeps the hoist's duration: a 1.2 s gap is one
    fast, _ = synthetic_day(hoist, [3000.0, 3000.0], seed=4)
    fast = finish(fast, hoist)
    times = (fast["time_utc"] - pl.lit(T0)).dt.total_microseconds() / 1e6
    fast = fast.filter((times < 300.0) | (times >= 301.2))
    found = _events(evaluate_alarms(fast, hoist, run_id="r"), "sensor_dropout")
    _assert_events(found, [(None, 300.0, 301.2)], tol_s=0.02)


def test_a_conveyance_resting_on_the_keps_is_an_underload_the_slack_rule_misses(hoist):
    frame, segments = synthetic_day(hoist, [3000.0, 3000.0], seed=7)
    unload = [s for s in segments if s[0] == "unload"][1]
    # after its payload left at the pithead, the conveyance sits on the keps for 6 s: its
    # four ropes carry 70 % of it and its tail rope, each still ~2.3x the slack threshold
    keps = (unload[2] + 12.0, unload[2] + 18.0)
    frame = finish(_load_scaled(frame, keps, 0.7), hoist)
    alarms = evaluate_alarms(frame, hoist, run_id="r")
    _assert_events(_events(alarms, "underload"), [(None, *keps)])
    assert set(alarms["rule"]) == {"underload"}  # not a slack rope, nor an imbalance
    row = alarms.row(0, named=True)
    empty_at_pithead_n = (8200 + 2 * 6.2 * 620) * G_STANDARD  # conveyance + tail rope
    assert row["threshold"] == pytest.approx(0.97 * empty_at_pithead_n)
    assert row["peak_value"] == pytest.approx(0.7 * empty_at_pithead_n, rel=0.01)
    assert row["peak_value"] > 4 * rule_thresholds(hoist).slack_n


def test_a_conveyance_described_a_tonne_too_heavy_is_an_underload_while_empty(hoist):
    """The record's conveyance 8.2 t, its description's 9.2 t: every trip reconciles to
    about -1 t; the load of the empty conveyance (down trips, the stops between unload
    and load) is below the described empty load, the loaded one (3 t) is not."""
    frame, segments = synthetic_day(hoist, [3000.0, 3000.0], seed=8)
    frame = finish(frame, hoist)
    heavy = hoist.model_copy(
        update={"conveyance": hoist.conveyance.model_copy(update={"mass_kg": 9200.0})}
    )
    assert evaluate_alarms(frame, hoist, run_id="r").height == 0
    found = _events(evaluate_alarms(frame, heavy, run_id="r"), "underload")
    assert found
    for kind, _, start, end, _ in segments:
        covered = sum(max(0.0, min(e, end) - max(s, start)) for _, s, e in found)
        if kind == "up":  # loaded: 12.2 t against 9.2 t described
            assert covered == 0.0
        if kind == "down":  # empty all the way: 8.2 t against 9.2 t
            assert covered >= 0.95 * (end - start) - 1.0


def test_an_overload_ends_when_the_load_is_back_below_its_threshold_near_the_rated(hoist):
    """A trip at 99.7 % of the rated load (5.95 t of 6 t) with 5 s at 6 % above it: one
    overload of those 5 s. A hysteresis band of 5 % of the threshold (before session 66)
    held the alarm until the payload left, the load never falling below 97.9 % of it."""
    frame, segments = synthetic_day(hoist, [5950.0], seed=9)
    up = next(s for s in segments if s[0] == "up")
    spike = (up[2] + 30.0, up[2] + 35.0)
    frame = finish(_load_scaled(frame, spike, 1.06), hoist)
    alarms = evaluate_alarms(frame, hoist, run_id="r")
    _assert_events(_events(alarms, "overload"), [(None, *spike)])
