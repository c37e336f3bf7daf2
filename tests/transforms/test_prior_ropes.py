"""Compensation without a logged x: the stick-slip solution on the ropes' prior spread.

Without x nothing identifies the head ropes, so the compensation solves the stick-slip
estimate on the sigma points of a stiffness spread about the description's ropes
(:func:`transforms.stick_slip_band.prior_rope_springs`) and takes their mean
(:func:`transforms.compensation_block.prior_mean`). Checked here on a small record of the
example hoist at the pithead (stiff ropes) with payload changes at rest:

- the estimate is the mean of the six sigma points' solutions, each solved alone as if
  identified (the unscented transform's mean, equal weights), to rounding;
- ropes that differ cancel part of the seals' friction: the mean's friction summed over
  the pistons is smaller than that of ropes taken alike, which share every slide;
- the band holds the estimate and spans the ropes-alike solution (the spread's end);
- the spread set to 0 gives the share-out of transforms.piston_motion, as before.
"""

from __future__ import annotations

import dataclasses
import datetime as dt

import numpy as np
import polars as pl

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from transforms.compensation import (
    CompensationSettings,
    compensate,
    compensate_window,
    compensation_context,
    context_sample,
    context_stride,
)
from transforms.stick_slip_band import RopeSprings, prior_rope_springs

HOIST = load_hoist(EXAMPLE_HOIST)
RATE = 50.0


def _record(seconds: float = 60.0) -> pl.DataFrame:
    """At rest at the pithead, no x logged; the load steps up by ~6 % and back down."""
    n = int(seconds * RATE)
    k = np.arange(n)
    ramp = np.clip((k - 10 * RATE) / RATE, 0, 1) - np.clip((k - 35 * RATE) / RATE, 0, 1)
    p = 4.5e6 + 0.3e6 * ramp + np.random.default_rng(3).normal(0, 2e3, n)
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    data: dict = {
        "time_utc": pl.datetime_range(
            start,
            start + dt.timedelta(seconds=(n - 1) / RATE),
            dt.timedelta(seconds=1 / RATE),
            eager=True,
            time_zone="UTC",
        ),
        **{f"p{i}_pa": p for i in range(1, 5)},
        **{f"x{i}_m": [None] * n for i in range(1, 5)},
        "depth_m": np.zeros(n),
        "speed_m_s": np.zeros(n),
        "oil_temp_c": np.full(n, 35.0),
    }
    return pl.DataFrame(data, schema_overrides={f"x{i}_m": pl.Float64 for i in range(1, 5)})


def _context(frame: pl.DataFrame, settings: CompensationSettings):
    stride = context_stride(frame.height)
    return compensation_context(context_sample(frame, stride).collect(), HOIST, settings, stride)


def _frictions(out: pl.DataFrame) -> np.ndarray:
    return np.vstack([out[f"friction{i}_n"].to_numpy() for i in range(1, 5)])


def test_without_x_the_estimate_is_the_mean_of_the_sigma_points_solutions():
    frame = _record()
    settings = CompensationSettings()
    context = _context(frame, settings)
    springs = context.rope_springs
    prior = prior_rope_springs((1.0,) * 4, settings.rope_stiffness_sigma)
    assert springs is not None
    assert springs.prior_sigma == settings.rope_stiffness_sigma
    assert springs.alternatives == prior.alternatives
    estimate = _frictions(compensate(frame, HOIST))
    alone = []
    for stiffness, offsets in springs.alternatives:  # each point as if identified
        point = RopeSprings(stiffness, offsets, 0.0, 0)
        out, _ = compensate_window(
            frame, HOIST, context=dataclasses.replace(context, rope_springs=point)
        )
        alone.append(_frictions(out))
    np.testing.assert_allclose(estimate, np.mean(alone, axis=0), rtol=0, atol=1e-6)
    # the points differ: which pistons slide, and so each one's friction
    held = int(30 * RATE)
    assert np.ptp([a[0, held] for a in alone]) > 100.0


def test_ropes_that_differ_cancel_friction_that_ropes_alike_would_add_up():
    frame = _record()
    context = _context(frame, CompensationSettings())
    alike = RopeSprings((1.0,) * 4, (0.0,) * 4, 0.0, 0)
    out_alike, _ = compensate_window(
        frame, HOIST, context=dataclasses.replace(context, rope_springs=alike)
    )
    out = compensate(frame, HOIST)
    held = slice(int(25 * RATE), int(34 * RATE))  # at the raised load, after the slide
    sum_alike = _frictions(out_alike)[:, held].sum(axis=0).mean()
    sum_mean = _frictions(out)[:, held].sum(axis=0).mean()
    assert sum_alike > 0  # the load rose: the seals resist the rods' pull
    assert 0 < sum_mean < sum_alike
    # ropes alike share the slide: every seal holds the same friction
    f = _frictions(out_alike)[:, held]
    np.testing.assert_allclose(f, np.broadcast_to(f[0], f.shape), rtol=1e-6)
    # the band holds the estimate and reaches the ropes-alike load
    load = out["load_n"].to_numpy()
    lo, hi = out["load_lo_n"].to_numpy(), out["load_hi_n"].to_numpy()
    assert np.all(lo <= load + 1.0)
    assert np.all(load <= hi + 1.0)
    alike_load = out_alike["load_n"].to_numpy()[held]
    assert np.all(alike_load <= hi[held] + 1.0)


def test_no_spread_falls_back_to_the_share_out():
    frame = _record()
    settings = CompensationSettings(rope_stiffness_sigma=0.0)
    assert _context(frame, settings).rope_springs is None
    shared = compensate(frame, HOIST, settings=settings)
    without = compensate(frame, HOIST, settings=CompensationSettings(rope_springs=False))
    np.testing.assert_array_equal(_frictions(shared), _frictions(without))


def test_an_x_logged_for_some_ropes_only_is_not_taken_for_where_the_pistons_start():
    """x1 missing, x2-x4 logged at mid-stroke (0.15 m): nothing identifies the ropes
    (every rope's x is needed), and the prior's ropes have no length offsets, so the
    logged positions would put three pistons 0.15 m from the first, ~100 kN of rope
    force: the solution starts as without any x."""
    frame = _record()
    partial = frame.with_columns(
        pl.lit(0.15 + 1e-4 * i, dtype=pl.Float64).alias(f"x{i}_m") for i in (2, 3, 4)
    )
    np.testing.assert_array_equal(
        _frictions(compensate(partial, HOIST)), _frictions(compensate(frame, HOIST))
    )


def test_band_members_on_means_leave_the_prior_estimate_as_it_is():
    """band_member_step_s runs the band's members on means, never the estimate: the
    prior's sigma points make the estimate, so they stay at the sensors' rate."""
    frame = _record()
    at_rate = compensate(frame, HOIST)
    on_means = compensate(frame, HOIST, settings=CompensationSettings(band_member_step_s=0.2))
    assert on_means["load_n"].equals(at_rate["load_n"])
    assert not on_means["load_hi_n"].equals(at_rate["load_hi_n"])  # the members moved


def test_stated_ropes_are_taken_as_known_and_a_partial_x_as_no_start():
    """A description that states its ropes' stiffness factors: without x the solution
    runs on them alone (no spread); an x logged for some ropes only does not start it."""
    stated = HOIST.model_copy(
        update={"ropes": HOIST.ropes.model_copy(update={"head_rope_stiffness_factors": [1.0] * 4})}
    )
    frame = _record()
    springs = compensation_context(
        context_sample(frame, context_stride(frame.height)).collect(), stated,
        CompensationSettings(), context_stride(frame.height),
    ).rope_springs  # fmt: skip
    assert springs is not None
    assert springs.stiffness_factors == (1.0,) * 4
    assert springs.alternatives == ()
    partial = frame.with_columns(pl.lit(0.15, dtype=pl.Float64).alias(f"x{i}_m") for i in (2, 3))
    np.testing.assert_array_equal(
        _frictions(compensate(partial, stated)), _frictions(compensate(frame, stated))
    )


def _logged_x(frame: pl.DataFrame, speed_m_s: float) -> pl.DataFrame:
    """``frame`` with every rope's x logged (0.1 mm steps, 0.02 mm noise): ropes 1-2
    sliding out and 3-4 in at ``speed_m_s`` (0: still)."""
    rng = np.random.default_rng(5)
    drift = speed_m_s * np.arange(frame.height) / RATE
    return frame.with_columns(
        pl.Series(
            f"x{i}_m",
            np.round((0.1 + sign * drift + rng.normal(0, 2e-5, frame.height)) / 1e-4) * 1e-4,
        )
        for i, sign in zip(range(1, 5), (1, 1, -1, -1), strict=True)
    )


def test_a_logged_x_that_shows_no_motion_runs_on_the_prior_as_without_x(caplog):
    """Every rope's x logged, but the pistons never move beyond the transducer's noise
    (a record at rest): nothing identifies the ropes, so the compensation runs on their
    prior spread, the logged x taken for no start (its offsets are unknown): the same
    tensions and band as the record without x, and a warning; not the share-out, which
    would read equal shares of every slide from that x."""
    frame = _record()
    logged = _logged_x(frame, 0.0)
    with caplog.at_level("WARNING", logger="transforms.compensation_record"):
        out = compensate(logged, HOIST)
    assert "did not identify the head ropes" in caplog.text
    assert "prior spread" in caplog.text
    without = compensate(frame, HOIST)
    for column in ("load_n", "load_lo_n", "load_hi_n", "tension1_n", "tension1_hi_n"):
        np.testing.assert_allclose(out[column], without[column], rtol=0, atol=1e-6)
    shared = compensate(logged, HOIST, settings=CompensationSettings(rope_stiffness_sigma=0.0))
    assert np.max(np.abs(_frictions(shared) - _frictions(out))) > 10.0  # not the share-out


def test_a_logged_x_whose_motion_no_ropes_explain_is_followed(caplog):
    """The pistons slide 2 mm/s apart while the pressures say nothing moves them (a
    groove's wear, which the rope springs do not hold): no constants match, and the
    measured motion decides the pistons' shares (the share-out), with a warning."""
    logged = _logged_x(_record(), 2e-3)
    with caplog.at_level("WARNING", logger="transforms.compensation_record"):
        out = compensate(logged, HOIST)
    assert "share-out of the logged x" in caplog.text
    shared = compensate(logged, HOIST, settings=CompensationSettings(rope_springs=False))
    np.testing.assert_array_equal(_frictions(out), _frictions(shared))


def test_a_single_spike_in_a_logged_x_at_rest_is_no_motion(caplog):
    """One 2 mm spike of one transducer at rest (what the despiking removes, and the
    identification's 0.2 s means average away) does not make the record's x one that
    shows motion: the prior, as without the spike, not the share-out; read on the
    sample's triplets where no identification was asked, on its means where it was."""
    logged = _logged_x(_record(), 0.0)
    x1 = logged["x1_m"].to_numpy().copy()
    x1[1500] += 2e-3
    spiky = logged.with_columns(pl.Series("x1_m", x1))
    springs = _context(spiky, CompensationSettings()).rope_springs
    assert springs is not None
    assert springs.prior_sigma > 0
    with caplog.at_level("WARNING", logger="transforms.compensation_record"):
        compensate(spiky, HOIST)
    assert "prior spread" in caplog.text


def test_a_logged_x_that_moves_after_the_identifications_span_is_followed():
    """x still for the identification's first IDENTIFY_SPAN (2 h), then the pistons
    slide apart: the record's x shows motion, so it is not taken for a record at rest
    (the share-out follows it; the prior would ignore it)."""
    from transforms.compensation import identification_means

    rate = 10.0
    n = int(2.5 * 3600 * rate)
    t = np.arange(n) / rate
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    late = np.clip(t - 2.2 * 3600, 0.0, None) * 2e-3
    frame = pl.DataFrame(
        {
            "time_utc": pl.datetime_range(start, start + dt.timedelta(seconds=(n - 1) / rate),
                                          dt.timedelta(seconds=1 / rate), eager=True,
                                          time_zone="UTC"),
            **{f"p{i}_pa": np.full(n, 4.5e6) for i in range(1, 5)},
            **{f"x{i}_m": 0.1 + sign * late
               for i, sign in zip(range(1, 5), (1, 1, -1, -1), strict=True)},
            "depth_m": np.zeros(n),
            "speed_m_s": np.zeros(n),
            "oil_temp_c": np.full(n, 35.0),
        }
    )  # fmt: skip
    settings = CompensationSettings()
    stride = context_stride(n)
    means = identification_means(frame, start, HOIST, settings)
    context = compensation_context(
        context_sample(frame, stride).collect(), HOIST, settings, stride, means=means
    )
    assert context.rope_springs is None  # the share-out


def test_a_large_lone_spike_of_a_logged_x_at_rest_identifies_nothing(caplog):
    """A 6 mm spike of one transducer for one sample at rest: its 0.2 s mean moves by
    0.6 mm, beyond the identification's 0.5 mm gate, but a lone value is no motion
    (the gate reads three consecutive means' median): no ropes identified from it, the
    prior as without the spike."""
    logged = _logged_x(_record(), 0.0)
    x1 = logged["x1_m"].to_numpy().copy()
    x1[1500] += 6e-3
    spiky = logged.with_columns(pl.Series("x1_m", x1))
    with caplog.at_level("WARNING", logger="transforms.compensation_record"):
        out = compensate(spiky, HOIST)
    assert "prior spread" in caplog.text
    np.testing.assert_allclose(
        out["load_n"], compensate(_record(), HOIST)["load_n"], rtol=0, atol=1e-6
    )


def test_a_noisy_logged_x_at_rest_is_no_motion(caplog):
    """An hour at rest, every x logged with 0.12 mm of noise at 0.1 mm steps: over
    ~60 000 triplets the medians' span reaches past 0.5 mm on noise alone, so the gate
    scales with the transducer's measured noise (8 x): no motion, the prior."""
    frame = _record(3600.0)
    rng = np.random.default_rng(8)
    noisy = frame.with_columns(
        pl.Series(f"x{i}_m", np.round((0.1 + rng.normal(0, 1.2e-4, frame.height)) / 1e-4) * 1e-4)
        for i in range(1, 5)
    )
    with caplog.at_level("WARNING", logger="transforms.compensation_record"):
        compensate(noisy, HOIST)
    assert "prior spread" in caplog.text
