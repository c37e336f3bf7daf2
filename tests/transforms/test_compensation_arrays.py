"""The array helpers of transforms.compensation against their frame / numpy originals."""

from __future__ import annotations

import numpy as np
import polars as pl

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from transforms.compensation import _label_arrays, _mean_horizontal, common_mode_displacement
from transforms.kinematics import PHASES, with_position, with_trip_phases
from transforms.oil import effective_bulk_modulus

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


def test_label_arrays_follow_the_frame_rules() -> None:
    rng = np.random.default_rng(3)
    n = 30_000
    speed = np.repeat(rng.choice([0.0, 0.01, 0.3, 5.0, -5.0, -0.2], n // 100), 100)
    speed = speed + rng.normal(0.0, 0.01, n)
    accel = rng.normal(0.0, 0.5, n)
    depth = rng.uniform(-5.0, 650.0, n)
    depth[rng.random(n) < 0.01] = np.nan
    segment = _segments(rng, n)
    # logger gaps at the segment changes: short ones (bridged), long ones (bridged only
    # where the depth says the conveyance kept moving)
    step = np.full(n, 0.01)
    new_segment = np.r_[False, segment[1:] != segment[:-1]]
    step[new_segment] = rng.choice([0.05, 1.5, 3.0, 60.0], new_segment.sum())
    time_s = 1.77e9 + np.cumsum(step)
    frame = pl.DataFrame(
        {
            "time_utc": pl.Series((time_s * 1e6).astype(np.int64)).cast(pl.Datetime("us", "UTC")),
            "speed_m_s": speed,
            "acceleration_m_s2": accel,
            "segment_id": segment,
            "depth_m": depth,
        }
    ).with_columns(pl.col("depth_m").fill_nan(None))
    expected = with_position(with_trip_phases(frame, HOIST), HOIST)
    time_s = frame["time_utc"].dt.epoch("us").to_numpy() * 1e-6  # as compensate reads it
    phase, direction, trip_id, position = _label_arrays(time_s, speed, accel, segment, depth, HOIST)
    names = sorted(HOIST.shaft.positions_m, key=HOIST.shaft.positions_m.get)

    def decode(codes: np.ndarray, labels: list[str]) -> list[str | None]:
        return [labels[c] if c >= 0 else None for c in codes.tolist()]

    assert decode(phase, list(PHASES)) == expected["phase"].to_list()
    assert decode(direction, ["down", "up"]) == expected["direction"].to_list()
    assert [t if t >= 0 else None for t in trip_id.tolist()] == expected["trip_id"].to_list()
    assert decode(position, names) == expected["position"].to_list()

    # the data exercise both outcomes of a gap inside a motion
    moving = np.abs(speed) >= 0.02
    inside = new_segment & moving & np.r_[False, moving[:-1]]
    trips_at_gaps = np.r_[0, np.diff(trip_id)][inside]
    assert (trips_at_gaps == 0).any()
    assert (trips_at_gaps == 1).any()
