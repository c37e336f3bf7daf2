"""discovery.rope_stiffness: the head ropes' stiffness spread read off a record.

The records are the device simulation's own (ropes with known factors), so these tests
show that the search finds what made the data and that equal ropes stay equal; that the
spread matters on data ropeload did not make is measured by ``benchmarks/eval_sanity.py``
on the validation days (README)."""

from __future__ import annotations

import dataclasses
import datetime as dt

import numpy as np
import polars as pl
import pytest

from discovery.cases import scenario_hoist
from discovery.planning import plan_replay
from discovery.rope_stiffness import (
    piston_slides_m,
    spread_factors,
    with_rope_stiffness,
    with_stiffness_factors,
)
from sims.field_day import generate_field_day
from sims.replay import first_trips_gap, replay_fitted

#: the world's ropes: spread 0.03 between neighbours, not in rope order
_WORLD = [1.015, 0.985, 0.955, 1.045]


def _day(hoist, trips):
    """``trips`` trips of 150 s at 20 Hz, 30 degC oil, with every model effect of
    ``hoist``."""
    return generate_field_day(
        hoist,
        date="2026-03-02",
        seed=4,
        trips=trips,
        hours=trips * 150.0 / 3600,
        sample_rate_hz=20.0,
        loading_s=5.0,
        rest_after_s=20.0,
        oil_temp_c=(30.0, 30.0),
    )


@pytest.fixture(scope="module")
def spread_day():
    base = scenario_hoist("plain")
    return base, _day(with_stiffness_factors(base, _WORLD), 4)


def test_spread_factors_mean_one_evenly_spaced():
    assert spread_factors(0.02, 4) == pytest.approx([0.97, 0.99, 1.01, 1.03])
    assert spread_factors(0.02, 3) == pytest.approx([0.98, 1.0, 1.02])


def test_slides_from_quantised_positions():
    """One piston slides 3 mm in 60 s, three stick; x logged to 0.1 mm with 0.02 mm of
    noise (a sticking piston's reading toggles between two steps)."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 120.0, 0.02)
    true = np.tile([5e-5, -3e-5, 2e-5, 0.0], (t.size, 1))
    true[:, 1] += np.clip((t - 30.0) / 60.0, 0.0, 1.0) * 3e-3
    logged = np.round((true + rng.normal(0, 2e-5, true.shape)) / 1e-4) * 1e-4
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    frame = pl.DataFrame(
        {
            "time_utc": [start + dt.timedelta(seconds=float(s)) for s in t],
            **{f"x{i + 1}_m": logged[:, i] for i in range(4)},
        }
    )
    slides = piston_slides_m(frame, 4)
    assert slides[1] == pytest.approx(3e-3, abs=0.3e-3)
    assert np.all(np.delete(slides, 1) < 0.5e-3)
    assert piston_slides_m(frame.drop("x4_m"), 4) is None


def test_spread_found_and_replay_closes(spread_day):
    """The description gives one EA; the record's ropes differ by 3 % between neighbours.
    The plan reads the spread (within the grid's resolution) and its replay leaves the
    noise where equal ropes leave several times it: the sensors do not tell which rope
    is which, so the factors go in rope order and still replay the record."""
    base, day = spread_day
    plan = plan_replay(day.sensors, base, settle_s=20.0)
    factors = plan.hoist.ropes.head_rope_stiffness_factors
    assert factors is not None, plan.notes
    steps = np.diff(np.sort(factors))
    assert steps == pytest.approx([0.03] * 3, abs=0.006)
    gap = replay_fitted(plan, passes=2).rms_gap_pa(plan)
    assert gap < 1.3 * plan.noise_sigma_pa
    equal = plan_replay(day.sensors, with_stiffness_factors(base, [1.0] * 4), settle_s=20.0)
    assert replay_fitted(equal, passes=2).rms_gap_pa(equal) > 2.0 * gap


def test_equal_ropes_stay_equal(spread_day):
    base, _ = spread_day
    day = _day(base, 3)
    plan = plan_replay(day.sensors, base, settle_s=20.0)
    assert plan.hoist.ropes.head_rope_stiffness_factors is None
    assert any("equal ropes kept" in n for n in plan.notes), plan.notes


def test_identified_factors_name_the_ropes_and_replay_to_the_noise(spread_day):
    """The ropes as the compensation identifies them from the logged x (here the
    world's own factors, as a perfect identification would give them) are used in rope
    order and replay the record to the noise."""
    base, day = spread_day
    # given as a function (``ropeload discover`` identifies them meanwhile)
    plan = plan_replay(day.sensors, base, settle_s=20.0, identified_ropes=lambda: _WORLD)
    assert plan.hoist.ropes.head_rope_stiffness_factors == pytest.approx(_WORLD)
    assert any("as identified from the logged piston positions" in n for n in plan.notes)
    assert replay_fitted(plan, passes=2).rms_gap_pa(plan) < 1.3 * plan.noise_sigma_pa
    # a function is called once and gives the choice and notes the factors give
    equal = dataclasses.replace(plan, hoist=with_stiffness_factors(plan.hoist, None))
    slides = piston_slides_m(day.sensors, 4)
    given = with_rope_stiffness(equal, slides, _WORLD)
    asked = []
    lazily = with_rope_stiffness(equal, slides, lambda: asked.append(1) or _WORLD)
    assert asked == [1]
    assert (lazily.hoist, lazily.notes) == (given.hoist, given.notes)
    none = with_rope_stiffness(equal, slides, lambda: None)
    assert none.hoist == with_rope_stiffness(equal, slides).hoist  # the spread's choice
    assert (
        none.hoist.ropes.head_rope_stiffness_factors
        != given.hoist.ropes.head_rope_stiffness_factors
    )


def test_identified_factors_that_replay_worse_than_the_spread_are_refused(spread_day):
    """Factors that do not describe the ropes (the world's mirrored about 1 and twice
    as far apart) replay the first trips further off than the spread's choice:
    refused, said, and the spread kept."""
    base, day = spread_day
    wrong = [1.0 - 2.0 * (f - 1.0) for f in _WORLD]
    plan = plan_replay(day.sensors, base, settle_s=20.0, identified_ropes=wrong)
    assert any("identified factors refused" in n for n in plan.notes), plan.notes
    factors = plan.hoist.ropes.head_rope_stiffness_factors
    assert factors is not None
    assert factors != wrong
    assert np.diff(np.sort(factors)) == pytest.approx([0.03] * 3, abs=0.006)
    with pytest.raises(ValueError, match="3 stiffness factors for 4 ropes"):
        plan_replay(day.sensors, base, settle_s=20.0, identified_ropes=_WORLD[:3])


def test_a_first_trips_gap_asked_again_is_not_replayed_again(spread_day, monkeypatch):
    """The choices ask for some replays twice (the ropes they kept, then the motion with
    them): the second answer is the first's, without a replay; another hoist or other
    trips are replayed. The gap is the first three trips' fitted replay."""
    import sims.replay as replay_module

    base, day = spread_day
    world = with_stiffness_factors(base, _WORLD)
    plan = plan_replay(day.sensors, world, settle_s=20.0, motion="winder")
    replays = []
    real = replay_module.replay_fitted
    monkeypatch.setattr(
        replay_module, "replay_fitted", lambda p, **kw: replays.append(p) or real(p, **kw)
    )
    # the plan's own choices may have asked for this one already (its damping's
    # candidates): remembered, it would not be replayed here at all
    monkeypatch.setattr(replay_module, "_GAPS", type(replay_module._GAPS)())
    gap = first_trips_gap(plan)
    three = dataclasses.replace(plan, trips=plan.trips[:3])
    assert gap == real(three, passes=2).rms_gap_pa(three)
    assert first_trips_gap(dataclasses.replace(plan, notes=("another note",))) == gap
    assert len(replays) == 1
    equal = with_stiffness_factors(base, [1.0] * 4)
    assert first_trips_gap(plan, equal) > 2.0 * gap
    assert first_trips_gap(plan, trips=2) != gap
    assert len(replays) == 3


def test_a_later_block_starts_with_the_pistons_where_the_record_logged_them():
    """The identified ropes with their length offsets (here the world's: its ropes have
    none) start each block with the pistons where the log has them before the block's
    first trip and the seals holding what the ropes leave them. Deep in the shaft the
    seals hold the pistons millimetres from equal tension, so a block started there with
    equal tensions replays its trips further off; started from the log, to the noise.
    Whether to keep the factors is decided on replays started alike (equal tensions)."""
    base = scenario_hoist("plain")
    day = _day(with_stiffness_factors(base, _WORLD), 6)
    x_logged = day.sensors.select([f"x{i}_m" for i in range(1, 5)]).to_numpy()
    t_logged = (day.sensors["time_utc"] - day.sensors["time_utc"][0]).dt.total_microseconds() / 1e6
    ropes = _Ropes(tuple(_WORLD), (0.0, 0.0, 0.0, 0.0))
    gaps, chosen = {}, {}
    for name, given in (("logged", ropes), ("equal tensions", _WORLD)):
        plan = plan_replay(
            day.sensors, base, settle_s=20.0, max_trips=4, blocks=2, identified_ropes=given
        )
        later = [tr for tr in plan.trips if tr.block == plan.trips[-1].block]
        assert later[0].first_in_block
        assert later[0].start_depth_m > 500.0  # at the bottom
        if name == "logged":
            assert plan.rope_offsets_m == (0.0, 0.0, 0.0, 0.0)
            before = (t_logged.to_numpy() <= later[0].window_start_s) & (
                t_logged.to_numpy() >= later[0].window_start_s - 2.0
            )
            np.testing.assert_allclose(
                later[0].x_start_m, np.median(x_logged[before], axis=0), atol=1e-12
            )
        else:
            assert plan.rope_offsets_m is None
        chosen[name] = [n for n in plan.notes if n.startswith("rope stiffness")]
        result = replay_fitted(plan, passes=2)
        residuals = result.residuals(plan)
        scored = [r for tr, r in zip(plan.trips, residuals, strict=True) if tr in later[1:]]
        gaps[name] = float(np.sqrt(np.nanmean(np.concatenate(scored) ** 2)))
    assert gaps["logged"] < 1.7 * plan.noise_sigma_pa
    assert gaps["logged"] < 0.8 * gaps["equal tensions"]
    # kept either way; with the offsets weighed in both starts (the better one counts)
    assert all("as identified" in chosen[name][0] for name in chosen)
    assert "started from equal tensions" in chosen["logged"][0]
    assert "started from equal tensions" not in chosen["equal tensions"][0]


def test_a_record_starting_deep_in_the_shaft_keeps_the_worlds_own_ropes():
    """A record cut to start at the bottom, where the seals hold the pistons millimetres
    from equal tensions: the world's own ropes (a perfect identification, no length
    offsets), started from equal tensions, replay the first trips further off than
    equal ropes do and were refused; started where the record logged the pistons (as
    they are replayed once kept), they replay closest, and are kept. (An independent
    simulator's day cut at its second hour had refused its identified ropes that way,
    and every trip of the hour failed the sanity check at 3-8 x the noise.)"""
    base = scenario_hoist("plain")
    day = _day(with_stiffness_factors(base, _WORLD), 6)
    at_bottom = day.sensors["time_utc"][0] + dt.timedelta(seconds=140.0)
    cut = day.sensors.filter(pl.col("time_utc") >= at_bottom)
    assert cut["depth_m"][0] > 500.0
    alone = plan_replay(cut, base, settle_s=20.0, identified_ropes=_WORLD)
    assert any("identified factors refused" in n for n in alone.notes), alone.notes
    offsets = (0.0, 0.0, 0.0, 0.0)
    plan = plan_replay(cut, base, settle_s=20.0, identified_ropes=_Ropes(tuple(_WORLD), offsets))
    assert plan.hoist.ropes.head_rope_stiffness_factors == pytest.approx(_WORLD)
    assert plan.rope_offsets_m == offsets
    (said,) = [n for n in plan.notes if n.startswith("rope stiffness")]
    assert said.startswith("rope stiffness: as identified"), said


@dataclasses.dataclass(frozen=True)
class _Ropes:
    """Identified ropes as ``transforms.stick_slip_band.RopeSprings`` carries them."""

    stiffness_factors: tuple[float, ...]
    length_offsets_m: tuple[float, ...]
