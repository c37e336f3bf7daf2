"""Block processing equals whole-record processing (issue 16).

A simulated 100 Hz record with four trips, a short logger gap (a new filter segment), a
long one (beyond the 120 s the differential bridges) and a gap across a block edge, cut
into 4-minute blocks so that edges fall inside trips and inside stops. The blocks'
concatenated rows must equal :func:`compensate` of the whole record: labels exactly,
numbers within 1e-9 relative (1e-6 absolute in their SI unit), the tolerance
:mod:`transforms.blocks` states.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest
from polars.testing import assert_frame_equal

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.field_day import generate_field_day
from transforms.alarms import evaluate_alarms, evaluate_alarms_in_blocks
from transforms.blocks import block_edges, compensate_blocks, record_context
from transforms.compensation import (
    compensate,
    compensation_context,
    compensation_margins_s,
    context_sample,
    context_stride,
)
from transforms.compensation_block import BlockCompensation
from transforms.compensation_record import (
    CompensationSettings,
    depth_turns,
    identification_means,
)
from transforms.reconciliation import (
    reconcile,
    stint_partials,
    summarise_positions_from_partials,
    summarise_trips_from_partials,
    trip_partials,
)

HOIST = load_hoist(EXAMPLE_HOIST)
BLOCK = dt.timedelta(minutes=4)


@pytest.fixture(scope="module")
def record() -> pl.DataFrame:
    day = generate_field_day(HOIST, date="2026-03-02", seed=5, trips=4, hours=0.5)
    samples = day.sensors
    t0 = samples["time_utc"][0]

    def cut(frame: pl.DataFrame, after_s: float, seconds: float) -> pl.DataFrame:
        lo = t0 + dt.timedelta(seconds=after_s)
        hi = lo + dt.timedelta(seconds=seconds)
        return frame.filter((pl.col("time_utc") < lo) | (pl.col("time_utc") >= hi))

    samples = cut(samples, 200.0, 2.0)  # a logger dropout: a new filter segment
    # longer than the differential's 120 s bridge, and than a block and both of its alarm
    # margins: no alarm window holds both its sides
    samples = cut(samples, 700.0, 540.0)
    # a gap across a block edge inside a trip (4-minute multiples from midnight UTC)
    edge = [hi for _, hi in block_edges(t0, samples["time_utc"][-1], BLOCK)][5]
    return cut(samples, (edge - t0).total_seconds() - 1.0, 3.0)


def _blocks(record: pl.DataFrame, **kwargs) -> pl.DataFrame:
    return pl.concat(list(_block_frames(record, **kwargs)))


def _block_frames(record: pl.DataFrame, hoist=HOIST, block=BLOCK, **kwargs):
    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return record.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi))

    start = record["time_utc"][0]
    end = record["time_utc"][-1] + dt.timedelta(microseconds=1)
    # the statistics of the record read block by block (as ropeload run does)
    context = record_context(
        read, hoist, start=start, end=end, rows=record.height, block=block,
        settings=kwargs.get("settings"),
    )  # fmt: skip
    return compensate_blocks(
        read, hoist, start=start, end=end, context=context, block=block, **kwargs
    )


def _assert_same(whole: pl.DataFrame, blocks: pl.DataFrame) -> None:
    assert blocks.height == whole.height
    assert blocks["time_utc"].equals(whole["time_utc"])
    for column in ("trip_id", "phase", "direction", "position"):
        assert blocks[column].equals(whole[column]), column
    for column, dtype in whole.schema.items():
        if not dtype.is_float():
            continue
        want = whole[column].cast(pl.Float64).to_numpy()
        got = blocks[column].cast(pl.Float64).to_numpy()
        assert np.array_equal(np.isnan(want), np.isnan(got)), column
        rtol = 1e-9 if dtype == pl.Float64 else 1e-6  # the band is landed as float32
        np.testing.assert_allclose(got, want, rtol=rtol, atol=1e-6, err_msg=column)


def test_blocks_cover_trips_and_stops(record: pl.DataFrame) -> None:
    whole = compensate(record, HOIST)
    edges = [lo for lo, _ in block_edges(record["time_utc"][0], record["time_utc"][-1], BLOCK)]
    first_after = whole["time_utc"].search_sorted(pl.Series(edges[1:]), side="left")
    at_edges = whole[first_after.clip(0, whole.height - 1)]
    # the case the test is about: block edges inside a trip and inside a stop
    assert at_edges["trip_id"].is_not_null().any()
    assert (at_edges["phase"] == "standstill").any()
    assert whole["trip_id"].n_unique() >= 3


def test_blocks_equal_whole_record(record: pl.DataFrame) -> None:
    _assert_same(compensate(record, HOIST), _blocks(record))


def test_the_stop_continuity_from_blocks_equals_the_whole_records(record: pl.DataFrame) -> None:
    """Blocks of 75 s put edges inside the trips' steady runs, whose sums the load's
    continuity carries to the stop (transforms/stop_continuity.py): the arrivals it
    updates must come out as in the record read whole."""
    block = dt.timedelta(seconds=75)
    whole = compensate(record, HOIST)
    plain = compensate(record, HOIST, settings=CompensationSettings(stop_continuity=False))
    moved = (whole["load_n"] - plain["load_n"]).abs() > 1.0
    updated = whole.filter(moved & (whole["phase"] == "standstill"))
    assert updated.height > 1000  # the update acts on the record's stops
    edges = pl.Series(
        [lo for lo, _ in block_edges(record["time_utc"][0], record["time_utc"][-1], block)][1:]
    )
    at_edges = whole[whole["time_utc"].search_sorted(edges, side="left").clip(0, whole.height - 1)]
    assert (at_edges["phase"] == "run").sum() >= 2  # edges inside the runs it sums
    _assert_same(whole, _blocks(record, block=block))


def test_blocks_equal_whole_record_with_drifting_seals(tmp_path) -> None:
    """LuGre seals: the drift's play, the ringing's demodulation at rest and the ropes'
    identification with the drift's travel, across block edges in trips and stops."""
    toml = tmp_path / "lugre.toml"
    toml.write_text(EXAMPLE_HOIST.read_text().replace('"presliding_hysteresis",', ""))
    hoist = load_hoist(toml)
    assert "presliding_hysteresis" not in hoist.model.effects
    record = generate_field_day(
        hoist, date="2026-03-02", seed=6, trips=4, hours=0.25, sample_rate_hz=50.0
    ).sensors
    t0 = record["time_utc"][0]
    edge = [hi for _, hi in block_edges(t0, record["time_utc"][-1], BLOCK)][1]
    for lo_s in (100.0, (edge - t0).total_seconds() - 1.0):  # a dropout; one at an edge
        lo = t0 + dt.timedelta(seconds=lo_s)
        hi = lo + dt.timedelta(seconds=2.0)
        record = record.filter((pl.col("time_utc") < lo) | (pl.col("time_utc") >= hi))

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return record.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi))

    end = record["time_utc"][-1] + dt.timedelta(microseconds=1)
    context = record_context(read, hoist, start=t0, end=end, rows=record.height, block=BLOCK)
    assert context.rope_springs is not None  # the stick-slip solution runs, with the drift
    # the drift's travel reaches the identification's means (the ringing's part:
    # tests/transforms/test_seal_drift.py)
    settings = CompensationSettings()
    means = identification_means(record, t0, hoist, settings)
    assert means["drift_travel_pa"].sum() > 0.0
    _assert_same(compensate(record, hoist), _blocks(record, hoist=hoist))


def test_ringing_members_copied_where_nothing_rings_equal_those_solved(
    tmp_path, monkeypatch
) -> None:
    """LuGre seals: a ringing member (the estimate's ringing halved or doubled) whose
    block stage has no ringing and whose carried state is the estimate's is copied from
    the estimate, not solved (BlockCompensation.is_estimate): on ropes damped critically
    (nothing rings) every member is copied, and solving them all gives the same rows to
    the last bit; on the example's ropes (damping ratio 0.02: ropeload's simulation
    rings from its first stop) none is."""
    lugre = EXAMPLE_HOIST.read_text().replace('"presliding_hysteresis",', "")
    damped = lugre.replace("head_rope_damping_ratio = 0.02", "head_rope_damping_ratio = 1.0")
    assert damped != lugre
    decided = []
    is_estimate = BlockCompensation.is_estimate

    def counting(self, inputs, m, members):
        answer = is_estimate(self, inputs, m, members)
        if members[m].source == "ringing":  # the others differ from the estimate
            decided.append(answer)
        return answer

    monkeypatch.setattr(BlockCompensation, "is_estimate", counting)
    minute = dt.timedelta(minutes=1)
    frames = {}
    for name, text in (("rings", lugre), ("damped", damped)):
        toml = tmp_path / f"{name}.toml"
        toml.write_text(text)
        hoist = load_hoist(toml)
        record = generate_field_day(
            hoist, date="2026-03-02", seed=6, trips=2, hours=0.1, sample_rate_hz=50.0
        ).sensors
        decided.clear()
        frames[name] = _blocks(record, hoist=hoist, block=minute)
        assert decided
        assert all(decided) == (name == "damped")
        assert any(decided) == all(decided)
    monkeypatch.setattr(BlockCompensation, "is_estimate", lambda *args: False)
    solved = _blocks(record, hoist=hoist, block=minute)
    assert_frame_equal(solved, frames["damped"], check_exact=True)


#: Without a logged x, the oil's motion shared out (transforms.piston_motion).
SHARED = CompensationSettings(rope_stiffness_sigma=0.0)


def test_blocks_equal_whole_record_pressure_only_with_drifting_seals(tmp_path) -> None:
    """LuGre seals without a logged x, the oil's motion shared out
    (``rope_stiffness_sigma=0``): the ringing the seals drift along
    (BlockCompensation.ringing_drift) is the same across block edges. (The stick-slip
    solution on the ropes' prior spread, the default without x, is
    test_blocks_equal_whole_record_pressure_only's.)"""
    toml = tmp_path / "lugre.toml"
    toml.write_text(EXAMPLE_HOIST.read_text().replace('"presliding_hysteresis",', ""))
    hoist = load_hoist(toml)
    record = generate_field_day(
        hoist, date="2026-03-02", seed=6, trips=4, hours=0.25, sample_rate_hz=50.0
    ).sensors.with_columns(pl.lit(None, dtype=pl.Float64).alias(f"x{i}_m") for i in range(1, 5))
    drifts = []
    ringing_drift = BlockCompensation.ringing_drift

    def counting(self):
        drifts.append(ringing_drift(self))
        return drifts[-1]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(BlockCompensation, "ringing_drift", counting)
        whole = compensate(record, hoist, settings=SHARED)
    assert any(d.size > 1 and d.max() > 0.0 for d in drifts)  # the simulation rings
    _assert_same(whole, _blocks(record, hoist=hoist, settings=SHARED))
    # and the default: the stick-slip solution on the ropes' prior spread, drifting too
    _assert_same(compensate(record, hoist), _blocks(record, hoist=hoist))


def test_blocks_equal_whole_record_pressure_only(record: pl.DataFrame) -> None:
    pressure_only = record.with_columns(
        pl.lit(None, dtype=pl.Float64).alias(f"x{i}_m") for i in range(1, 5)
    )
    _assert_same(compensate(pressure_only, HOIST), _blocks(pressure_only))


def test_blocks_equal_whole_record_lugre_and_turbulent_branch(record: pl.DataFrame) -> None:
    """LuGre instead of Maxwell-slip; a tiny pipe makes the branch flow turbulent so the
    kernel's general (numpy) loss path runs."""
    effects = {"seal_friction", "pipe_laminar_loss", "local_loss"}
    _assert_same(
        compensate(record, HOIST, effects=effects),
        _blocks(record, hoist=HOIST.with_effects(sorted(effects))),
    )


@pytest.mark.parametrize("before_edge_s", [30.0, None])
def test_blocks_equal_whole_record_with_a_sensor_stuck_near_an_edge(
    record: pl.DataFrame, before_edge_s: float | None
) -> None:
    """Sensor 2 repeats one reading for 100 s, the hoist's flat-line duration 90 s
    (longer than the filters' 40 s halo): across a block edge (from 30 s before it),
    and ending 0.01 s before a block's resume margin (None). The blocks, whose window
    reaches the filters' halo plus the duration past them, take the stretch as not
    logged as the whole record does (a halo of the duration alone saw 89.99 s of the
    second, took the reading as a pressure, and the low-pass carried it into the block:
    1 kN on the load to the record's end)."""
    hoist = HOIST.model_copy(
        update={"alarms": HOIST.alarms.model_copy(update={"flatline_duration_s": 90.0})}
    )
    t0 = record["time_utc"][0]
    edge = [hi for _, hi in block_edges(t0, record["time_utc"][-1], BLOCK)][1]
    if before_edge_s is None:
        resume_s = compensation_margins_s(CompensationSettings(), hoist)[0]
        lo = edge - dt.timedelta(seconds=resume_s + 0.01 + 100.0)
    else:
        lo = edge - dt.timedelta(seconds=before_edge_s)
    inside = (record["time_utc"] >= lo) & (record["time_utc"] < lo + dt.timedelta(seconds=100))
    assert inside.sum() > 9000  # no logger gap inside
    first = record.filter(inside)["p2_pa"][0]
    stuck = record.with_columns(
        pl.when(inside).then(first).otherwise(pl.col("p2_pa")).alias("p2_pa")
    )
    whole = compensate(stuck, hoist)
    assert whole.filter(inside)["tension2_n"].null_count() == inside.sum()
    _assert_same(whole, _blocks(stuck, hoist=hoist))


def test_block_edges_reject_nonpositive_block() -> None:
    t = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    with pytest.raises(ValueError, match="block must be positive"):
        block_edges(t, t + dt.timedelta(hours=1), dt.timedelta(0))


def test_reconciliation_and_alarms_from_blocks_equal_whole_record(record: pl.DataFrame) -> None:
    """Per-stint and per-trip partials of the blocks, and alarms of the blocks with their
    margin, merged: the whole record's position and trip summaries and alarms."""
    hoist = HOIST.model_copy(
        update={"alarms": HOIST.alarms.model_copy(update={"imbalance_fraction": 0.004})}
    )  # tight enough that the record raises imbalance alarms, some across block edges
    whole = compensate(record, hoist)
    blocks = list(_block_frames(record))
    want = reconcile(whole, hoist, run_id="r")
    stints, trips, carry = [], [], None
    for frame in blocks:
        part, carry = stint_partials(frame, hoist, carry=carry)
        stints.append(part)
        trips.append(trip_partials(frame))
    positions = summarise_positions_from_partials(
        pl.concat(stints, how="diagonal_relaxed"), hoist, run_id="r"
    )
    trip_summary = summarise_trips_from_partials(
        pl.concat(trips, how="diagonal_relaxed"),
        positions,
        run_id="r",
        site=hoist.hoist.site,
        hoist_name=hoist.hoist.name,
    )
    assert positions.height == want.position_summary.height > 10
    assert_frame_equal(positions, want.position_summary, rel_tol=1e-9, abs_tol=1e-6)
    assert_frame_equal(trip_summary, want.trip_summary, rel_tol=1e-9, abs_tol=1e-6)

    alarms = evaluate_alarms(whole, hoist, run_id="r", trip_payloads=want.trip_summary)
    start, end = whole["time_utc"][0], whole["time_utc"][-1] + dt.timedelta(microseconds=1)

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return whole.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi))

    merged = evaluate_alarms_in_blocks(
        read,
        block_edges(start, end, BLOCK),
        hoist,
        run_id="r",
        trip_payloads=want.trip_summary,
    )
    assert alarms.height >= 3
    assert_frame_equal(merged, alarms, rel_tol=1e-6)


def test_blocks_equal_whole_record_without_speed(record: pl.DataFrame) -> None:
    """No speed logged: the speed is the depth's derivative, its standstill within
    DEADBAND_SIGMAS x the scatter the depth's noise gives it (physics.conveyance.
    conveyance_speed), that noise the record's (CompensationContext.depth_sigma_m), not
    each block's own."""
    noise = np.random.default_rng(11).normal(0.0, 0.005, record.height)
    no_speed = record.with_columns(
        pl.lit(None, dtype=pl.Float64).alias("speed_m_s"),
        (pl.col("depth_m") + pl.Series(noise)).alias("depth_m"),
    )
    whole = compensate(no_speed, HOIST)
    _assert_same(whole, _blocks(no_speed))
    logged = compensate(record, HOIST)
    assert whole["trip_id"].drop_nulls().n_unique() == logged["trip_id"].drop_nulls().n_unique()


def _at_rest_without_speed(
    depth: np.ndarray, rate: float, start: dt.datetime, rng: np.random.Generator
) -> pl.DataFrame:
    """A record at rest with this depth, no speed and no x logged, pressures at 4.5 MPa
    with 2 kPa of noise."""
    n = depth.size
    return pl.DataFrame(
        {
            "time_utc": pl.datetime_range(start, start + dt.timedelta(seconds=(n - 1) / rate),
                                          dt.timedelta(seconds=1 / rate), eager=True,
                                          time_zone="UTC"),
            **{f"p{i}_pa": 4.5e6 + rng.normal(0.0, 2e3, n) for i in range(1, 5)},
            **{f"x{i}_m": pl.Series([None] * n, dtype=pl.Float64) for i in range(1, 5)},
            "depth_m": depth,
            "speed_m_s": pl.Series([None] * n, dtype=pl.Float64),
            "oil_temp_c": np.full(n, 35.0),
        }
    )  # fmt: skip


def test_a_depth_read_to_the_centimetre_is_seen_on_every_row_not_the_sample():
    """At rest, no speed logged, the depth read to the centimetre and toggling by one
    count now and then: the reading's step (CompensationContext.depth_quantum_m, one
    step is no motion) is taken from every row's changes, whole or block by block, not
    from the context's sample, which on a long record (one row pair in 14 for a day at
    100 Hz) catches too few toggles (26 trips in 8 h at rest, a review found); here
    the sample's pairs are thinned to one in 14 by hand."""
    rate, n = 100.0, 60_000
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    depth = np.full(n, 300.0)
    rng = np.random.default_rng(4)
    for s in rng.integers(0, n - 200, 15):
        depth[s : s + rng.integers(5, 100)] += 0.01
    frame = _at_rest_without_speed(depth, rate, start, rng)
    settings = CompensationSettings(rope_springs=False)
    sample = context_sample(frame, 14).collect()
    thinned = compensation_context(sample, HOIST, settings, 14)
    assert thinned.depth_quantum_m == 0.0  # the sample's pairs miss the step
    every_row = compensation_context(sample, HOIST, settings, 14, depth_turns=depth_turns(frame))
    assert every_row.depth_quantum_m == pytest.approx(0.01)

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return frame.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi))

    end = start + dt.timedelta(seconds=n / rate)
    blocks = record_context(read, HOIST, start=start, end=end, rows=n, block=BLOCK,
                            settings=settings)  # fmt: skip
    assert blocks.depth_quantum_m == pytest.approx(0.01)
    out = compensate(frame, HOIST, settings=settings)
    assert out["trip_id"].drop_nulls().n_unique() == 0


def test_a_depth_toggle_across_a_blocks_edge_counts_as_in_the_whole_record():
    """Two one-count excursions of the depth at rest, the first straddling a block's
    edge: three reversals in the whole record (the step found), and as many block by
    block (the change across the edge and its turn carried over)."""
    rate, n = 10.0, 3 * 36_000
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    depth = np.full(n, 300.0)
    depth[36_000 - 100 : 36_000 + 100] += 0.01
    depth[90_000:90_050] += 0.01
    rng = np.random.default_rng(1)
    frame = _at_rest_without_speed(depth, rate, start, rng)
    settings = CompensationSettings(rope_springs=False)
    stride = context_stride(n)
    whole = compensation_context(context_sample(frame, stride).collect(), HOIST, settings,
                                 stride, depth_turns=depth_turns(frame))  # fmt: skip
    assert whole.depth_quantum_m == pytest.approx(0.01)

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return frame.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi))

    end = start + dt.timedelta(seconds=n / rate)
    blocks = record_context(read, HOIST, start=start, end=end, rows=n,
                            block=dt.timedelta(hours=1), settings=settings)  # fmt: skip
    assert blocks.depth_quantum_m == whole.depth_quantum_m
    # and no trip, whole or block by block (a one-count step's slope peaks at 1.5 x the
    # step over the window, which a band at exactly that left to rounding)
    trips = compensate(frame, HOIST, settings=settings)["trip_id"].drop_nulls().n_unique()
    parts = compensate_blocks(read, HOIST, start=start, end=end, context=blocks,
                              settings=settings, block=dt.timedelta(hours=1))  # fmt: skip
    assert trips == 0
    assert pl.concat(list(parts))["trip_id"].drop_nulls().n_unique() == 0


def test_a_stop_longer_than_the_blocks_reach_takes_the_whole_records_departure() -> None:
    """Blocks of 120 s in the day's 6-minute stops: a block whose edge is a stop's
    departure more than BACK_S away solves only the start of the next trip's run; the
    departure's shift (transforms/stop_continuity.py) must be found by the block that
    reaches it, from the whole run, as in the record read whole."""
    record = generate_field_day(HOIST, date="2026-03-02", seed=5, trips=4, hours=0.5).sensors
    whole = compensate(record, HOIST)
    stops = whole["phase"] == "standstill"
    assert (stops & (whole["trip_id"].is_null())).sum() > 0.5 * whole.height  # long stops
    _assert_same(whole, _blocks(record, block=dt.timedelta(seconds=120)))
