"""The array helpers of transforms.compensation against their frame / numpy originals."""

from __future__ import annotations

import numpy as np
import polars as pl

from physics.closed_volume import common_mode_displacement
from physics.oil import effective_bulk_modulus
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from transforms.compensation_record import mean_horizontal as _mean_horizontal

HOIST = load_hoist(EXAMPLE_HOIST)


def _segments(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.cumsum(rng.random(n) < 0.002)


def test_common_mode_displacement_equals_the_array_formula() -> None:
    rng = np.random.default_rng(1)
    n = 20_000
    p = 6e6 + np.cumsum(rng.normal(0.0, 1e4, n))
    p[rng.random(n) < 0.01] = np.nan
    segment = _segments(rng, n)
    beta = effective_bulk_modulus(
        np.maximum(np.nan_to_num(p, nan=1e6), 1e5),
        HOIST.oil.bulk_modulus_pa,
        HOIST.oil.air_fraction,
    )
    compliance = HOIST.oil_volume_m3 / (HOIST.ropes_n * HOIST.cylinders.bore_area_m2 * beta)
    dp = np.r_[0.0, np.diff(p)]
    starts = np.r_[True, segment[1:] != segment[:-1]]
    dp[starts | ~np.isfinite(dp)] = 0.0
    dx = compliance * dp
    x = np.cumsum(dx)
    offsets = np.maximum.accumulate(np.where(starts, np.arange(n), 0))
    expected = x - x[offsets] + dx[offsets]
    assert np.array_equal(common_mode_displacement(p, segment, HOIST), expected)


def test_mean_horizontal_ignores_nan_like_polars() -> None:
    rng = np.random.default_rng(2)
    arrays = [rng.normal(size=5000) for _ in range(4)]
    for a in arrays:
        a[rng.random(a.size) < 0.3] = np.nan
    frame = pl.DataFrame({f"c{k}": pl.Series(a).fill_nan(None) for k, a in enumerate(arrays)})
    expected = frame.select(pl.mean_horizontal(frame.columns)).to_series().to_numpy()
    # polars may add in another order: equal to rounding
    np.testing.assert_allclose(_mean_horizontal(arrays), expected, rtol=1e-12, atol=1e-15)
    assert np.array_equal(np.isnan(_mean_horizontal(arrays)), np.isnan(expected))
