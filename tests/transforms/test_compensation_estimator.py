"""compensate() with the piston-motion estimator and its 95 % band (issue 13).

Analytic cases on small synthetic records of the example hoist (at rest, 100 Hz):

- a single piston pushed past breakaway: after the slide its friction is the law's
  static level in the direction of the slide (eq 16-17 at v = 0 after a Stribeck stop),
  the three others keep their presliding friction, and its band is narrow;
- a payload change at rest with one piston sliding and three sticking, x logged to a
  0.1 mm step with 0.02 mm noise: the three sticking pistons' friction does not change
  sign (the failure of the first wave's estimate);
- x missing: pressure only, the band spans the seals' whole static range;
- the band holds the tension and is ordered.

The share-out path (``rope_springs=False``): these records are not consistent with rope
springs (one piston slides millimetres at rest on equal ropes), which is what the
compensation falls back to when the ropes cannot be identified. The stick-slip solution
on rope springs has its own cases in tests/transforms/test_stick_slip.py.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from transforms.compensation import CompensationSettings, compensate

HOIST = load_hoist(EXAMPLE_HOIST)
AREA = HOIST.cylinders.bore_area_m2
RATE = 100.0
LAW = HOIST.friction_law


def _static_n(p_pa: float) -> float:
    a, b = LAW.static_n
    return a + b * p_pa


def _frame(p: np.ndarray, x: np.ndarray | None) -> pl.DataFrame:
    n = p.shape[-1]
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    times = [start + dt.timedelta(microseconds=int(1e6 * k / RATE)) for k in range(n)]
    data: dict = {"time_utc": times}
    for i in range(1, 5):
        data[f"p{i}_pa"] = p
        data[f"x{i}_m"] = x[i - 1] if x is not None else [None] * n
    data |= {
        "depth_m": np.zeros(n),
        "speed_m_s": np.zeros(n),
        "oil_temp_c": np.full(n, 40.0),
        "source_sha256": ["f"] * n,
        "source_line": np.arange(n),
    }
    return pl.DataFrame(data, schema_overrides={f"x{i}_m": pl.Float64 for i in range(1, 5)})


def _payload_change(n: int, at: int, dp: float, p0: float = 4e6) -> np.ndarray:
    """Common pressure with a payload change of dp over 1 s at sample ``at``."""
    k = np.arange(n)
    return p0 + dp * np.clip((k - at) / RATE, 0.0, 1.0)


def _slide_volume(dp: float) -> float:
    """Sum of the piston displacements the oil gives for dp [m] (closed volume)."""
    from physics.oil import effective_bulk_modulus_at

    beta = effective_bulk_modulus_at(
        4e6, HOIST.oil.bulk_modulus_pa, HOIST.oil.air_fraction, 1e5, 1.0
    )
    return HOIST.oil_volume_m3 * dp / (beta * AREA)


def _quantised(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A transducer: 0.02 mm of noise, then a 0.1 mm step."""
    return np.round((x + rng.normal(0.0, 0.02e-3, x.size)) / 1e-4) * 1e-4


def _one_piston_slides(
    dp: float,
    *,
    logged: bool,
    seed: int = 3,
    hoist=HOIST,
    settings: CompensationSettings | None = None,
) -> pl.DataFrame:
    """Two payload changes at rest (+dp, then -2 dp); piston 1 takes both slides (a
    2 MPa change moves ~1.5 mm of oil: millimetres, as on the independent days)."""
    n = 6000
    p = _payload_change(n, 1000, dp) + _payload_change(n, 3500, -2 * dp, 0.0)
    p = p + np.random.default_rng(seed).normal(0.0, 2e3, n)
    slide = np.cumsum(np.r_[0.0, np.diff(p)]) / dp * _slide_volume(dp)
    rng = np.random.default_rng(seed + 1)
    x = np.vstack([slide, np.zeros(n), np.zeros(n), np.zeros(n)]) + np.array(
        [[1e-3], [-2e-3], [0.5e-3], [3e-3]]
    )
    return compensate(
        _frame(p, np.vstack([_quantised(r, rng) for r in x]) if logged else None),
        hoist,
        settings=settings or CompensationSettings(rope_springs=False),
    )


def test_a_piston_pushed_past_breakaway_ends_at_its_static_friction():
    out = _one_piston_slides(2e6, logged=True)
    # after the first change (pressure up, rod out): F1 > 0 at the static level
    f1 = out["friction1_n"].to_numpy()
    p_after = 6e6
    level = np.mean(f1[2500:3400])
    assert 0.6 * _static_n(p_after) < level <= 1.05 * _static_n(p_after)
    # after the change back (pressure down by twice as much): it slid in, F1 < 0
    assert np.mean(f1[5000:]) < -0.6 * _static_n(2e6)
    # its band there is narrow: the law's uncertainty and the sensor, not the seal's range
    width = (out["tension1_hi_n"] - out["tension1_lo_n"]).to_numpy()[5000:]
    assert np.median(width) < 0.5 * 2 * _static_n(2e6)


def test_the_sticking_pistons_keep_the_sign_of_their_friction_through_a_slide():
    out = _one_piston_slides(2e6, logged=True)
    for i in (2, 3, 4):
        f = out[f"friction{i}_n"].to_numpy()
        # during the first change the sum grows: presliding can only push them out
        assert f[1000:2500].min() > -0.05 * _static_n(4e6), i
        # they never reach the static level (they stick): at most their presliding
        assert np.abs(f).max() < _static_n(6e6), i


def test_x_missing_degrades_to_pressure_only_with_the_seals_whole_range():
    out = _one_piston_slides(0.5e6, logged=False)
    tension = out["tension1_n"].to_numpy()
    lo, hi = out["tension1_lo_n"].to_numpy(), out["tension1_hi_n"].to_numpy()
    assert np.all(lo <= tension)
    assert np.all(tension <= hi)
    # never seen sliding: at least the static range +-F_s around the chamber force
    p_chamber = out["p_chamber1_pa"].to_numpy()
    half = 0.5 * (hi - lo)
    assert np.all(half >= 0.99 * _static_n(3.5e6))
    assert np.all(lo <= p_chamber * AREA - 0.99 * (_static_n(3.5e6)))
    # and the load band holds the four together
    load = out["load_n"].to_numpy()
    assert np.all(out["load_lo_n"].to_numpy() <= load)
    assert np.all(load <= out["load_hi_n"].to_numpy())


def test_the_band_is_ordered_and_holds_the_value():
    out = _one_piston_slides(0.3e6, logged=True, seed=9)
    for i in range(1, 5):
        lo, t, hi = (out[f"tension{i}{s}_n"].to_numpy() for s in ("_lo", "", "_hi"))
        assert np.all(lo <= t)
        assert np.all(t <= hi)
    load = out["load_n"].to_numpy()
    lo, hi = out["load_lo_n"].to_numpy(), out["load_hi_n"].to_numpy()
    assert np.all(lo <= load)
    assert np.all(load <= hi)
    # the load band is at least as wide as the widest rope band's friction range
    assert np.all(hi - lo >= (out["tension1_hi_n"] - out["tension1_lo_n"]).to_numpy() - 1e-6)


def test_the_band_takes_the_friction_laws_uncertainty_the_hoist_states():
    """The band's friction law part is +-1.96 sigma |F| (transforms.uncertainty, part
    2; the sensor's noise set to 0 here, its range part the same for any sigma), so two
    stated uncertainties differ in each rope's half-width by 1.96 |F| (sigma_b -
    sigma_a). The description's ``[friction] relative_uncertainty`` is what runs unless
    the settings give one; none stated: 10 %."""

    def stating(sigma):
        friction = HOIST.friction.model_copy(update={"relative_uncertainty": sigma})
        return HOIST.model_copy(update={"friction": friction})

    def half_width(hoist, sigma=None):
        settings = CompensationSettings(
            rope_springs=False, friction_relative_sigma=sigma, pressure_sigma_pa=0.0
        )
        out = _one_piston_slides(0.3e6, logged=True, seed=9, hoist=hoist, settings=settings)
        end = out.tail(500)  # at rest after the second slide
        half = ((end["tension1_hi_n"] - end["tension1_lo_n"]) / 2).to_numpy()
        return half, end["friction1_n"].to_numpy()

    narrow, friction = half_width(stating(0.02))
    wide, _ = half_width(stating(0.2))
    assert np.median(np.abs(friction)) > 500.0  # a seal holding its static level
    np.testing.assert_allclose(
        wide - narrow, 1.96 * np.abs(friction) * (0.2 - 0.02), rtol=1e-4
    )  # float32 columns
    given, _ = half_width(stating(0.02), sigma=0.2)  # the settings' over the description's
    np.testing.assert_array_equal(given, wide)
    unstated, _ = half_width(stating(None))
    np.testing.assert_array_equal(unstated, half_width(stating(0.1))[0])


def test_a_sensor_off_the_others_at_rest_does_not_move_the_other_seals():
    """Equal ropes at rest through a payload change, then sensor 1 reads 20 % high for
    2 s (a fault: the pipes equalise the chambers at rest, contract 1a). The stick-slip
    solution takes the others' mean for it there (and as far either side as the
    low-pass filter spreads the step), so seals 2-4 keep the friction they have without
    the fault (every seal moved to explain it before: up to 2.4 kN here, the other ropes 10 %
    off on a probe's record), and rope 1's tension still shows its reading, its band and
    the load's reaching what the others read too."""
    import dataclasses

    from transforms.compensation import (
        compensate_window,
        compensation_context,
        context_sample,
        context_stride,
    )
    from transforms.stick_slip_band import RopeSprings

    n = 1500
    p = _payload_change(n, 300, 2e5)
    healthy = _frame(p, np.zeros((4, n)))
    fault = slice(1000, 1200)
    p1 = p.copy()
    p1[fault] *= 1.2
    faulty = healthy.with_columns(pl.Series("p1_pa", p1))
    stride = context_stride(n)
    settings = CompensationSettings()
    context = compensation_context(
        context_sample(healthy, stride).collect(), HOIST, settings, stride
    )
    equal = RopeSprings((1.0,) * 4, (0.0,) * 4, 0.0, 0)
    context = dataclasses.replace(context, rope_springs=equal)
    a, b = (compensate_window(f, HOIST, context=context)[0] for f in (healthy, faulty))
    for i in (2, 3, 4):  # to the filter's tail beyond the masked reach: 0.4 N of ~1 kN
        np.testing.assert_allclose(b[f"friction{i}_n"], a[f"friction{i}_n"], rtol=0, atol=2.0)
    assert abs(a["friction2_n"][900] - a["friction2_n"][100]) > 10.0  # the seals moved
    inside = b["tension_raw1_n"].to_numpy()[1050:1150] / a["tension_raw1_n"].to_numpy()[1050:1150]
    assert np.median(inside) == pytest.approx(1.2, rel=2e-3)
    # the record cannot say whether it is the sensor or the oil: rope 1's band, and the
    # load's, reach the others' reading too (their tension had sensor 1 read as they do:
    # the healthy record's, within the filter's tail and the seal's few newtons)
    core = slice(1050, 1150)
    for name, healthy_values in (("tension1", a["tension1_n"]), ("load", a["load_n"])):
        lo, hi = (b[f"{name}{s}_n"].to_numpy()[core] for s in ("_lo", "_hi"))
        other = healthy_values.to_numpy()[core]
        assert np.all(lo <= other + 5.0)
        assert np.all(b[f"{name}_n"].to_numpy()[core] <= hi + 1.0)
        assert np.all(hi - lo > 0.15 * 4e6 * AREA)  # ~20 % of a rope's tension, not a few %
    # away from the fault the bands are the healthy record's
    before = slice(600, 900)
    for column in ("load_lo_n", "load_hi_n", "tension1_lo_n", "tension1_hi_n"):
        np.testing.assert_allclose(b[column][before], a[column][before], rtol=1e-6)
