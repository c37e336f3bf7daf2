"""Tests for transforms.filtering: segments, spikes, zero-phase low-pass."""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np
import polars as pl
import pytest

from transforms.filtering import despike_median3, segment_ids, with_segment_id
from transforms.lowpass import edge_levels, lowpass, lowpass_columns

FS_HZ = 100.0


def _gapped_step():
    t = np.concatenate([np.arange(0, 5, 0.01), 8.0 + np.arange(0, 5, 0.01)])
    x = np.where(t < 6, 0.0, 1.0)  # a step hidden in the gap
    return t, x


def test_segment_ids_numpy_and_frame_agree():
    t, _ = _gapped_step()
    seg = segment_ids(t)
    assert seg[499] == 0
    assert seg[500] == 1
    assert seg.max() == 1
    start = datetime(2026, 3, 2, 6)
    df = pl.DataFrame({"timestamp": [start + timedelta(seconds=float(s)) for s in t]})
    out = with_segment_id(df.lazy(), "timestamp", nominal_dt_s=0.01).collect()
    np.testing.assert_array_equal(out["segment_id"].to_numpy(), seg)
    jitter = np.arange(10) * 0.01 + np.array([0, 0.002, -0.001, 0, 0, 0.003, 0, 0, 0, 0])
    assert segment_ids(jitter).max() == 0  # jitter is not a gap


def test_lowpass_does_not_smear_across_gap():
    t, x = _gapped_step()
    y = lowpass(x, segment_ids(t), sample_rate_hz=FS_HZ, cutoff_hz=2.0)
    np.testing.assert_allclose(y[:500], 0.0, atol=1e-12)
    np.testing.assert_allclose(y[500:], 1.0, atol=1e-12)
    smeared = lowpass(x, None, sample_rate_hz=FS_HZ, cutoff_hz=2.0)
    assert np.abs(smeared[490:510] - x[490:510]).max() > 0.1  # what the segments avoid


def test_lowpass_passes_sine_below_cutoff_and_stops_above():
    t = np.arange(0, 10, 0.01)
    slow = np.sin(2 * np.pi * 1.0 * t)
    y = lowpass(slow, None, sample_rate_hz=FS_HZ, cutoff_hz=5.0)
    assert np.max(np.abs(y - slow)) < 0.01  # within 1 % of the amplitude, no phase lag
    fast = 0.5 * np.sin(2 * np.pi * 30.0 * t)
    y = lowpass(slow + fast, None, sample_rate_hz=FS_HZ, cutoff_hz=5.0)
    # 30 Hz is 6x the cut-off: |H|^2 = 1 / (1 + 6^8) (edges excluded: odd-extension)
    assert np.max(np.abs(y[100:-100] - slow[100:-100])) < 0.001


def test_lowpass_nan_and_short_segments():
    x = np.sin(np.linspace(0, 3, 300))
    x[100] = np.nan
    seg = np.zeros(300, dtype=np.int64)
    seg[-5:] = 1  # too short to filter: left as is
    y = lowpass(x, seg, sample_rate_hz=FS_HZ, cutoff_hz=5.0)
    assert np.isnan(y[100])
    assert np.isfinite(y[99])
    assert np.isfinite(y[101])
    np.testing.assert_array_equal(y[-5:], x[-5:])


def test_lowpass_columns_respects_segments():
    """A step across a logger gap stays a step: each segment is filtered on its own."""
    t, x = _gapped_step()
    df = pl.DataFrame({"t_s": t, "p_pa": x * 1e6}).pipe(with_segment_id, "t_s", nominal_dt_s=0.01)
    lp = lowpass_columns(df, ["p_pa"], sample_rate_hz=FS_HZ, cutoff_hz=2.0)
    np.testing.assert_allclose(lp["p_pa"].to_numpy(), x * 1e6, atol=1e-6)


def test_time_column_type_checked():
    with pytest.raises(TypeError):
        with_segment_id(pl.DataFrame({"t": ["a"]}), "t", nominal_dt_s=0.01)


# -- play operator (added with the compensation) ----------------------------------------
def test_play_operator_ignores_jitter_and_passes_motion():
    from transforms.filtering import play_operator

    rng = np.random.default_rng(3)
    rest = 1e-3 + rng.uniform(-4e-5, 4e-5, 500)  # +-0.04 mm jitter at 1 mm
    ramp = np.linspace(1e-3, 3e-3, 200)
    y = play_operator(np.r_[rest, ramp, np.full(300, 3e-3)], half_width=5e-5)
    # jitter narrower than the band moves it at most ptp - w while it settles, then never
    assert np.ptp(y[:500]) <= np.ptp(rest) - 5e-5 + 1e-12
    assert np.count_nonzero(np.diff(y[:500])) <= 10  # the raw jitter changes every sample
    assert y[-1] == pytest.approx(3e-3 - 5e-5)  # the real 2 mm motion passes, lagged by w


def test_play_operator_restarts_per_segment_and_holds_nan():
    from transforms.filtering import play_operator

    x = np.array([0.0, 1.0, np.nan, 2.0, 5.0, 5.1])
    y = play_operator(x, np.array([0, 0, 0, 0, 1, 1]), half_width=0.5)
    assert y.tolist() == [0.0, 0.5, 0.5, 1.5, 5.0, 5.0]


# -- 3-point median despike (added with the compensation) --------------------------------
def test_despike_median3_removes_isolated_spikes_only():
    from transforms.filtering import despike_median3

    rng = np.random.default_rng(5)
    x = rng.normal(0.0, 1.0, 2000)
    x[500:560] += 40.0  # a real 0.6 s step-like event, 40 sigma: must survive
    spiky = x.copy()
    spiky[[100, 900, 1500]] += [30.0, -25.0, 50.0]
    cleaned, sigma = despike_median3(spiky)
    assert sigma == pytest.approx(1.0, rel=0.1)
    assert np.abs(cleaned[[100, 900, 1500]] - x[[100, 900, 1500]]).max() < 5.0
    np.testing.assert_array_equal(cleaned[500:560], spiky[500:560])
    changed = np.flatnonzero(cleaned != spiky)
    assert set(changed) == {100, 900, 1500}


def test_despike_median3_respects_segments_and_nan():
    from transforms.filtering import despike_median3

    x = np.array([0.0, 0.0, 100.0, 0.0, 0.0, np.nan, 50.0, 0.0])
    cleaned, _ = despike_median3(x, np.array([0, 0, 1, 1, 1, 1, 1, 1]))
    assert cleaned[2] == 100.0  # first sample of a segment: no left neighbour, kept
    assert cleaned[6] == 50.0  # next to a NaN: kept


def _polyfit_level(y: np.ndarray, samples: int) -> float:
    """The value at y[-1] of numpy's least-squares parabola through y's last ``samples``
    samples (the end sample where fewer than four)."""
    k = min(samples, y.size)
    if k < 4:
        return float(y[-1])
    return float(np.polyval(np.polyfit(np.arange(k), y[-k:], 2), k - 1))


def _odd_extended_sosfiltfilt(sos, x: np.ndarray, pad: int, samples: int) -> np.ndarray:
    """scipy's sosfiltfilt of ``x`` odd-extended by ``pad`` about its edges' levels (those
    :func:`edge_levels` gives, checked against numpy's polyfit on their own below)."""
    from scipy import signal

    first, last = edge_levels(x, samples)
    ext = np.concatenate([2 * first - x[pad:0:-1], x, 2 * last - x[-2 : -pad - 2 : -1]])
    return signal.sosfiltfilt(sos, ext, padtype=None)[pad : pad + x.size]


@pytest.mark.parametrize("samples", [2, 3, 4, 5, 10, 20, 50])
def test_edge_levels_are_a_least_squares_parabolas_ends(samples: int):
    """Each edge's level is numpy's polyfit parabola there, through the first (last)
    ``samples`` samples, or the end sample where fewer than four; a parabola is kept."""
    rng = np.random.default_rng(samples)
    x = np.cumsum(rng.normal(size=40)) + 5e6
    first, last = edge_levels(x, samples)
    assert first == pytest.approx(_polyfit_level(x[::-1], samples), rel=1e-13, abs=0)
    assert last == pytest.approx(_polyfit_level(x, samples), rel=1e-13, abs=0)
    j = np.arange(40.0)
    bowl = 3.0 + 0.5 * j - 0.02 * j**2
    if samples >= 4:
        assert edge_levels(bowl, samples) == pytest.approx((bowl[0], bowl[-1]), abs=1e-9)


def test_lowpass_equals_scipy_sosfiltfilt_per_segment():
    """The numba forward-backward pass is scipy's sosfiltfilt of the segment odd-extended
    about its edges' levels, bit for bit: long and short segments, a segment shorter than
    the pad, bridged NaN samples (one in an edge's stretch)."""
    from scipy import signal

    rng = np.random.default_rng(3)
    lengths = [5000, 40, 11, 13, 200, 3000]
    x = np.concatenate([np.cumsum(rng.normal(size=k)) + 5e6 for k in lengths])
    x[[3, 100, 101, 5002, 5100, 8000]] = np.nan  # 3 and 5002 in an edge level's stretch
    seg = np.repeat(np.arange(len(lengths)), lengths)
    got = lowpass(x, seg, sample_rate_hz=100.0, cutoff_hz=10.0)
    in_place = x.copy()
    assert lowpass(in_place, seg, sample_rate_hz=100.0, cutoff_hz=10.0, out=in_place) is in_place
    np.testing.assert_array_equal(in_place, got)
    work = np.full(x.size + 100, np.inf)  # a caller's scratch array: any content
    with_work = lowpass(x, seg, sample_rate_hz=100.0, cutoff_hz=10.0, work=work)
    np.testing.assert_array_equal(with_work, got)
    sos = signal.butter(4, 10.0, btype="low", fs=100.0, output="sos")
    start = 0
    for k in lengths:
        part = x[start : start + k]
        bad = np.isnan(part)
        if k < 12:
            np.testing.assert_array_equal(got[start : start + k], part)
        else:
            idx = np.arange(k)
            filled = part.copy()
            filled[bad] = np.interp(idx[bad], idx[~bad], part[~bad])
            want = _odd_extended_sosfiltfilt(sos, filled, min(30, k - 1), 10)
            want[bad] = np.nan
            np.testing.assert_array_equal(got[start : start + k], want)
        start += k


def test_despike_median3_in_place_sees_raw_neighbours():
    """Written over its input, the 3-point median still uses the raw neighbours: two
    spikes side by side are a feature (the median of each triple keeps them), exactly
    as out of place."""
    rng = np.random.default_rng(5)
    x = rng.normal(0.0, 1.0, 2000)
    x[[100, 700, 701, 1500]] = [40.0, 35.0, 35.0, -50.0]
    seg = np.repeat([0, 1], 1000)
    want, sigma = despike_median3(x, seg)
    in_place = x.copy()
    got, got_sigma = despike_median3(in_place, seg, out=in_place)
    assert got is in_place
    assert got_sigma == sigma
    np.testing.assert_array_equal(got, want)
    assert abs(got[100]) < 5
    assert abs(got[1500]) < 5
    assert got[700] == got[701] == 35.0


@pytest.mark.parametrize("order", [2, 4, 6])
def test_lowpass_equals_scipy_sosfiltfilt_for_any_order(order: int):
    """Order 4 (two sections) has its own register-state kernel; other orders take the
    general one. Both are scipy's sosfiltfilt of scipy's own design (the sections come
    from physics.filter_design, which designs them as scipy.signal does) on the odd
    extension about the edges' levels, bit for bit."""
    from scipy import signal

    x = np.cumsum(np.random.default_rng(order).normal(size=3000)) + 5e6
    got = lowpass(x, None, sample_rate_hz=100.0, cutoff_hz=10.0, order=order)
    sos = signal.butter(order, 10.0, btype="low", fs=100.0, output="sos")
    np.testing.assert_array_equal(got, _odd_extended_sosfiltfilt(sos, x, 30, 10))


@pytest.mark.parametrize(
    ("rate_hz", "cutoff_hz", "edge_share"), [(100.0, 5.0, 0.61), (50.0, 4.0, 0.72)]
)
def test_lowpass_edges_carry_less_noise_than_a_sample(
    rate_hz: float, cutoff_hz: float, edge_share: float
):
    """White noise about a known level: at a segment's edges the low-pass is off by about
    the share of the noise its edge levels carry (a parabola's end over one cut-off
    period: 20 samples, 0.61; 13, the drift's low-pass at 50 Hz, 0.72), where scipy's odd
    extension about the edge sample returns that sample, all of it; inside the segment
    both by about the filter's own share. A logger gap must not turn one sample's noise
    into a step."""
    from scipy import signal

    rng = np.random.default_rng(11)
    segments, length = 400, 200
    x = 2.5e6 + 4e3 * rng.normal(size=(segments, length))  # 4 kPa of noise at 2.5 MPa
    seg = np.repeat(np.arange(segments), length)
    y = lowpass(x.ravel(), seg, sample_rate_hz=rate_hz, cutoff_hz=cutoff_hz)
    y = y.reshape(segments, length)
    sos = signal.butter(4, cutoff_hz, btype="low", fs=rate_hz, output="sos")
    scipys = signal.sosfiltfilt(sos, x, axis=1, padlen=int(3 * rate_hz / cutoff_hz))
    edges = np.std(np.r_[y[:, 0], y[:, -1]] - 2.5e6) / 4e3
    assert edges == pytest.approx(edge_share, abs=0.08)
    assert np.std(np.r_[scipys[:, 0], scipys[:, -1]] - 2.5e6) > 0.9 * 4e3
    inside = np.std(y[:, length // 2] - 2.5e6)
    assert inside < 0.5 * 4e3
    assert np.std(scipys[:, length // 2] - 2.5e6) == pytest.approx(inside, rel=1e-3)


def test_an_odd_order_low_pass_is_refused():
    with pytest.raises(ValueError, match="even Butterworth order"):
        lowpass(np.zeros(100), None, sample_rate_hz=100.0, cutoff_hz=10.0, order=3)
