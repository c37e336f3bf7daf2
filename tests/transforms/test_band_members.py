"""The band's members on means (``band_member_step_s``, :mod:`transforms.band_members`).

A LuGre hoist of ropeload's own generator (its seals drift, its ropes are identified),
15 min at 50 Hz with a logger dropout and one across a 4-minute block edge. Checked:

- with no window steady (every window split into its samples) the means path is the
  members' solution at the sensors' rate (the drift's travel given per sample is the
  kernel's own play but for the record's first sample), the steps the sample step,
  the held difference the member;
- on means, block by block equals the whole record (the windows are multiples of the
  step since the epoch, the drift's play carried);
- on means the load's band stays within ~0.1 % of the load of the members' at the
  sensors' rate (measured 27 / 17 N RMS on a 1 h day: the module docstring).
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest

import transforms.compensation_block as block_module
from physics.sensor_branch import sensor_branch
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.field_day import generate_field_day
from transforms.band_members import mean_starts
from transforms.blocks import block_edges, compensate_blocks, record_context
from transforms.compensation import compensate
from transforms.compensation_record import CompensationSettings
from transforms.stick_slip import stick_slip, stick_slip_state
from transforms.stick_slip_band import RopeSprings

BLOCK = dt.timedelta(minutes=4)
BAND = ["load_lo_n", "load_hi_n"] + [f"tension{i}_{e}_n" for i in range(1, 5) for e in ("lo", "hi")]
ON_MEANS = CompensationSettings(band_member_step_s=0.1)


@pytest.fixture(scope="module")
def lugre(tmp_path_factory):
    toml = tmp_path_factory.mktemp("hoist") / "lugre.toml"
    toml.write_text(EXAMPLE_HOIST.read_text().replace('"presliding_hysteresis",', ""))
    hoist = load_hoist(toml)
    record = generate_field_day(
        hoist, date="2026-03-02", seed=6, trips=4, hours=0.25, sample_rate_hz=50.0
    ).sensors
    t0 = record["time_utc"][0]
    edge = [hi for _, hi in block_edges(t0, record["time_utc"][-1], BLOCK)][1]
    for lo_s in (100.0, (edge - t0).total_seconds() - 1.0):
        lo = t0 + dt.timedelta(seconds=lo_s)
        hi = lo + dt.timedelta(seconds=2.0)
        record = record.filter((pl.col("time_utc") < lo) | (pl.col("time_utc") >= hi))
    return hoist, record


@pytest.fixture(scope="module")
def at_rate(lugre) -> pl.DataFrame:
    hoist, record = lugre
    return compensate(record, hoist)


def _band(frame: pl.DataFrame, column: str) -> np.ndarray:
    return frame[column].cast(pl.Float64).to_numpy()


def test_means_of_single_samples_are_the_members_at_the_sensors_rate(
    lugre, at_rate, monkeypatch
) -> None:
    hoist, record = lugre
    monkeypatch.setattr(block_module, "STEADY_SIGMAS", -1.0)  # no window is steady
    split = compensate(record, hoist, settings=ON_MEANS)
    assert _band(at_rate, "load_hi_n")[-1] > _band(at_rate, "load_lo_n")[-1]
    later = (record["time_utc"] >= record["time_utc"][0] + dt.timedelta(minutes=1)).to_numpy()
    for column in BAND:
        # the kernel's own play starts at the record's second sample, the play whose
        # travel is given at its first: a few tens of newtons at the record's start,
        # < 1e-5 of the load a minute later
        got, want = _band(split, column), _band(at_rate, column)
        np.testing.assert_allclose(got, want, rtol=0.0, atol=50.0, err_msg=column)
        np.testing.assert_allclose(got[later], want[later], rtol=1e-5, err_msg=column)
    assert split["load_n"].equals(at_rate["load_n"])  # the estimate is not touched


def test_means_are_close_to_the_members_at_the_sensors_rate(lugre, at_rate, monkeypatch) -> None:
    hoist, record = lugre
    counted = []

    def counting_mean_starts(epoch_us, *args):  # the real function, its answer counted
        starts = mean_starts(epoch_us, *args)
        counted.append((starts.size, epoch_us.size))
        return starts

    monkeypatch.setattr(block_module, "mean_starts", counting_mean_starts)
    means = compensate(record, hoist, settings=ON_MEANS)
    (merged,) = counted
    assert merged[0] < 0.5 * merged[1]  # most windows of the record were steady
    assert means["load_n"].equals(at_rate["load_n"])
    load = _band(at_rate, "load_hi_n") + _band(at_rate, "load_lo_n")
    for column in ("load_lo_n", "load_hi_n"):
        moved = _band(means, column) - _band(at_rate, column)
        known = np.isfinite(moved)
        assert known.mean() > 0.99
        # within 0.1 % of the load in RMS, 0.5 % everywhere
        assert np.sqrt(np.mean(moved[known] ** 2)) < 1e-3 * np.median(load[known] / 2)
        assert np.max(np.abs(moved[known])) < 5e-3 * np.median(load[known] / 2)


@pytest.mark.parametrize("step_s", [0.1, 0.5])
def test_means_block_by_block_equal_the_whole_record(lugre, step_s) -> None:
    hoist, record = lugre
    settings = CompensationSettings(band_member_step_s=step_s)

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return record.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi))

    t0 = record["time_utc"][0]
    end = record["time_utc"][-1] + dt.timedelta(microseconds=1)
    context = record_context(read, hoist, start=t0, end=end, rows=record.height, block=BLOCK)
    assert context.rope_springs is not None  # the stick-slip solution and its members run
    blocks = pl.concat(
        list(
            compensate_blocks(
                read, hoist, start=t0, end=end, context=context, settings=settings, block=BLOCK
            )
        )
    )
    whole = compensate(record, hoist, settings=settings)
    assert blocks["time_utc"].equals(whole["time_utc"])
    for column in [*BAND, "load_n"]:
        np.testing.assert_allclose(
            _band(blocks, column), _band(whole, column), rtol=1e-6, atol=1e-3, err_msg=column
        )


@pytest.mark.parametrize("step_s", [0.3, 2.0, -0.1, float("inf"), float("nan")])
def test_a_step_that_is_no_whole_fraction_of_the_resume_margin_is_refused(step_s) -> None:
    with pytest.raises(ValueError, match="band_member_step_s"):
        CompensationSettings(band_member_step_s=step_s)


def test_stick_slip_steps_per_sample_are_the_runs_between_their_changes() -> None:
    """Steps that change along the record solve as the runs of one step each, resumed:
    each sample's step is the one from the sample before it."""
    hoist = load_hoist(EXAMPLE_HOIST)
    n = 300
    p = 4.0e6 + 3e5 * np.sin(np.linspace(0.0, 9.0, n))
    springs = RopeSprings((1.0, 1.01, 0.99, 1.0), (0.0, 1e-4, -1e-4, 0.0), 0.0, 0)
    runs = ((0, 120, 0.02), (120, 200, 0.2), (200, n, 0.05))
    steps = np.concatenate([np.full(hi - lo, v) for lo, hi, v in runs])
    inputs = ((p,) * 4, (np.zeros(n),) * 4, np.full(n, 300.0), np.zeros(n, int))
    _, each = stick_slip(*inputs, hoist, springs, dt_s=steps, branch=sensor_branch(hoist),
                         nu_m2_s=4e-5)  # fmt: skip
    state = stick_slip_state(4)
    pieces = [np.empty(n) for _ in range(4)]
    for lo, hi, v in runs:
        state[1] = 1.0 if lo else 0.0
        _, f = stick_slip(*(tuple(a[lo:hi] for a in x) if isinstance(x, tuple) else x[lo:hi]
                            for x in inputs), hoist, springs, dt_s=v,
                          branch=sensor_branch(hoist), nu_m2_s=4e-5, state=state)  # fmt: skip
        for whole, part in zip(pieces, f, strict=True):
            whole[lo:hi] = part
    for a, b in zip(each, pieces, strict=True):
        assert np.array_equal(a, b)
    # the steps matter: with the branch loss a slower piston is less damped
    _, one = stick_slip(*inputs, hoist, springs, dt_s=0.02, branch=sensor_branch(hoist),
                        nu_m2_s=4e-5)  # fmt: skip
    assert not all(np.array_equal(a, b) for a, b in zip(one, each, strict=True))


def test_stick_slip_steps_per_sample_equal_one_step() -> None:
    hoist = load_hoist(EXAMPLE_HOIST)
    n = 200
    p = 4.0e6 + 3e5 * np.sin(np.linspace(0.0, 6.0, n))
    springs = RopeSprings((1.0, 1.01, 0.99, 1.0), (0.0, 1e-4, -1e-4, 0.0), 0.0, 0)
    args = ((p,) * 4, (np.zeros(n),) * 4, np.full(n, 300.0), np.zeros(n, int), hoist, springs)
    _, one = stick_slip(*args, dt_s=0.02)
    _, each = stick_slip(*args, dt_s=np.full(n, 0.02))
    for a, b in zip(one, each, strict=True):
        assert np.array_equal(a, b)
    with pytest.raises(ValueError, match="dt_s"):
        stick_slip(*args, dt_s=np.full(n - 1, 0.02))
    with pytest.raises(ValueError, match="dt_s"):
        stick_slip(*args, dt_s=np.zeros(n))


def test_means_after_a_long_logger_gap_block_by_block_equal_the_whole_record(lugre) -> None:
    """A logger gap of 5 min: a block read from the gap's end has no mean before its
    first, whose step (the pistons' speed, the branch loss's damping) is then the
    sample step; the whole record's must be too, not the index distance to the last mean
    before the gap (the load's band moved by up to 0.22 kN after the gap)."""
    hoist, record = lugre
    t0 = record["time_utc"][0]
    lo, hi = t0 + dt.timedelta(seconds=300.0), t0 + dt.timedelta(seconds=600.0)
    record = record.filter((pl.col("time_utc") < lo) | (pl.col("time_utc") >= hi))
    block = dt.timedelta(minutes=2)

    def read(lo: dt.datetime, hi: dt.datetime) -> pl.DataFrame:
        return record.filter((pl.col("time_utc") >= lo) & (pl.col("time_utc") < hi))

    end = record["time_utc"][-1] + dt.timedelta(microseconds=1)
    context = record_context(read, hoist, start=t0, end=end, rows=record.height, block=block)
    parts = compensate_blocks(read, hoist, start=t0, end=end, context=context,
                              settings=ON_MEANS, block=block)  # fmt: skip
    blocks = pl.concat(list(parts))
    whole = compensate(record, hoist, settings=ON_MEANS)
    assert blocks["time_utc"].equals(whole["time_utc"])
    after = (whole["time_utc"] >= hi).to_numpy()
    assert _band(whole, "load_hi_n")[after][-1] > _band(whole, "load_lo_n")[after][-1]
    for column in [*BAND, "load_n"]:
        np.testing.assert_allclose(
            _band(blocks, column), _band(whole, column), rtol=1e-6, atol=1e-3, err_msg=column
        )
