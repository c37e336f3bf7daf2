"""LuGre's drift in the stick-slip solution: what shakes a seal loose (issue 13).

A seal of LuGre's single bristle (paper eq 15) relaxes along any back-and-forth path,
not only along a slide; the validation README's ringing hoist and ropeload's own
LuGre simulation both show it (a ringing conveyance leaves its seals near 0 after a
stop). Cases, each against an answer the code under test does not produce:

- the drift of :func:`physics.lugre.lugre_drift` against eq 15 integrated exactly
  (:func:`physics.lugre.lugre_z_step`) along an oscillation with no net travel;
- a slow common rise of the pressure: every seal follows LuGre's presliding curve
  F = g - (g - F0) exp(-sigma_0 x / g), not the elasto-plastic line to the capacity;
- the sensors' noise alone (5 kPa per sensor) does not drain the seals at rest, a
  ringing of the conveyance does;
- a triangle wave just above the play's half-width: the play counts the travel it
  hides at each turn;
- the drift's travel of a record's full-rate samples, summed per identification mean,
  drives the stick-slip solution as the drift's pressure does sample by sample, and
  a ringing's travel is its whole path;
- a damped ringing at rest: its travel below the play is found by demodulation at the
  bounce frequency, the sensors' noise and a payload change's ramp are not;
- the ropes of a ringing hoist with LuGre seals identified with the drift (one rope
  4 % stiffer): closer to the truth, and a smaller misfit, than without it;
- a hoist with LuGre seals and ringing ropes, simulated by ropeload's device model
  (which integrates eq 15 at 2 ms): every position visit within 0.5 % of the true load
  (without the drift the bottom visits are ~3 % off, against < 1 % raw).
"""

from __future__ import annotations

import datetime as dt
import itertools

import numpy as np
import polars as pl
import pytest

from physics.friction_law import friction_law_at, law_array
from physics.lugre import lugre_drift, lugre_z_step
from physics.oil import effective_bulk_modulus_at
from physics.rope_spring import bounce_frequency_hz
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.accuracy import position_accuracy
from sims.field_day import generate_field_day
from transforms.alarm_events import reading_step
from transforms.compensation import compensate
from transforms.compensation_block import BlockCompensation
from transforms.compensation_record import CompensationSettings, identification_means
from transforms.filtering import despike_median3
from transforms.lowpass import lowpass
from transforms.rope_identification import identify_from_means, record_means
from transforms.seal_drift import (
    PLAYED_TRAVEL_STATE_SIZE,
    drift_pressure,
    drift_travel,
    played_travels,
    played_travels_into,
    ringing_travel,
    seals_drift,
)
from transforms.stick_slip import stick_slip
from transforms.stick_slip_band import RopeSprings

HOIST = load_hoist(EXAMPLE_HOIST)
AREA = HOIST.cylinders.bore_area_m2
SIGMA0 = float(HOIST.friction_law.bristle_stiffness_n_m)
EQUAL = RopeSprings((1.0,) * 4, (0.0,) * 4, 0.0, 0)
DEPTH = 300.0


def _static_n(p: float) -> float:
    return friction_law_at(p, law_array(HOIST.friction_law))[1]


def _share_m(a: float, b: float) -> float:
    """Each of four sticking pistons' share of the oil's compression from a to b (eq 5)."""
    oil = HOIST.oil
    beta = effective_bulk_modulus_at(b, oil.bulk_modulus_pa, oil.air_fraction, 1e5, 1.0)
    return HOIST.oil_volume_m3 / (beta * AREA) * (b - a) / 4


def _solve(p: np.ndarray, drift: np.ndarray, half_width: float, dt_s: float):
    n = p.size
    return stick_slip(
        (p,) * 4, (np.zeros(n),) * 4, np.full(n, DEPTH), np.zeros(n, int), HOIST, EQUAL,
        dt_s=dt_s, drift_pressure_pa=drift, drift_half_width_pa=half_width,
    )  # fmt: skip


def test_lugre_drift_is_eq15_along_a_back_and_forth_path():
    g, z0 = 1000.0, 0.6 * 1000.0 / SIGMA0
    amplitude = 0.02 * g / SIGMA0  # small against the presliding length g / sigma_0
    cycles, per_cycle = 20, 400
    t = np.arange(cycles * per_cycle + 1) / per_cycle
    x = amplitude * np.sin(2 * np.pi * t)
    z = z0
    for dx in np.diff(x):
        z = lugre_z_step(z, dx, 1.0, SIGMA0, g)  # v = dx over a unit step
    path = 4 * amplitude * cycles
    assert SIGMA0 * z == pytest.approx(lugre_drift(SIGMA0 * z0, path, SIGMA0, g), rel=0.02)
    assert SIGMA0 * z < 0.5 * SIGMA0 * z0  # no net travel, yet more than halved


def test_a_slow_common_rise_follows_lugre_presliding_curve():
    """All four seals stick and share the oil's compression; with the drift each one's
    force approaches its capacity exponentially (eq 15 for monotone travel)."""
    p0 = 4.0e6
    travel = 2.0 * _static_n(p0) / SIGMA0  # two presliding lengths per piston
    rise = travel / _share_m(p0, p0 + 1.0)
    p = np.r_[np.full(10, p0), np.linspace(p0, p0 + rise, 4000)[1:]]
    _, f = _solve(p, p, 1e-6, dt_s=1.0)
    expected = 0.0
    for a, b in itertools.pairwise(p):
        g = _static_n(b)
        expected = g + (expected - g) * np.exp(-SIGMA0 * _share_m(a, b) / g)
    for fi in f:
        assert fi[-1] == pytest.approx(expected, rel=2e-3)
    assert expected < 0.9 * _static_n(p[-1])  # the elasto-plastic seal would sit at F_s


def test_the_play_counts_the_travel_it_hides_at_each_turn():
    """Constant sensor pressures and a triangle wave of amplitude 1.5 w on the drift's
    pressure (w the play's half-width): each seal relaxes by LuGre's drift along its
    quarter of the oil's motion for the input's whole travel after the play first
    engages, (A - w) + 2 A per swing; the play's output alone travels 2 A - 2 w per
    swing. The ropes are made 1000x stiffer than the hoist's so that what the bristles
    take back each step is small and exact: with rho = sigma_0 / (sigma_0 + k) of the
    drifted force returned, F' = F (e^-lambda (1 - rho) + rho) per step."""
    p0, w, amplitude, swings, per_swing = 4.0e6, 5.0e3, 7.5e3, 30, 500
    k = 1000.0 * HOIST.ropes.head_rope_axial_stiffness_n / (HOIST.shaft.headframe_height_m + DEPTH)
    f0 = 0.5 * _static_n(p0)
    d = f0 / k
    ropes = RopeSprings((1000.0,) * 4, (d, -d, d, -d), 0.0, 0)
    rise = np.linspace(p0, p0 + amplitude, per_swing // 2 + 1)
    swing = np.linspace(p0 + amplitude, p0 - amplitude, per_swing + 1)[1:]
    wave = [np.full(5, p0), rise, *[swing if j % 2 == 0 else swing[::-1] for j in range(swings)]]
    drift = np.concatenate(wave)
    n = drift.size
    _, f = stick_slip(
        (np.full(n, p0),) * 4, (np.zeros(n),) * 4, np.full(n, DEPTH), np.zeros(n, int), HOIST,
        ropes, dt_s=1.0, drift_pressure_pa=drift, drift_half_width_pa=w,
    )  # fmt: skip
    rho = SIGMA0 / (SIGMA0 + k)

    def kept(travel_pa: float) -> float:  # each piston's quarter of the oil's motion
        return np.exp(-(1 - rho) * SIGMA0 * _share_m(p0 - travel_pa, p0) / _static_n(p0))

    want = f0 * kept((amplitude - w) + 2 * amplitude * swings)
    assert [abs(fi[0]) for fi in f] == pytest.approx([f0] * 4, rel=1e-9)
    assert [abs(fi[-1]) for fi in f] == pytest.approx([want] * 4, rel=0.01)
    # what the play's output alone travels would leave the seals more than twice as loaded
    played_only = f0 * kept((amplitude - w) + (2 * amplitude - 2 * w) * swings)
    assert max(abs(fi[-1]) for fi in f) < 0.6 * played_only


def _drift_mean(clean: np.ndarray, rate_hz: float, rng: np.random.Generator):
    """Segments, the four sensors reading ``clean`` with 5 kPa of white noise each,
    low-passed at 10 Hz as the compensation does, their drift's mean pressure and its
    play's half-width."""
    segment = np.zeros(clean.size, int)
    noisy = tuple(
        lowpass(clean + rng.normal(0.0, 5e3, clean.size), segment, sample_rate_hz=rate_hz,
                cutoff_hz=10.0)
        for _ in range(4)
    )  # fmt: skip
    mean, half_width = drift_pressure(
        noisy, segment, HOIST, sample_rate_hz=rate_hz, pressure_sigma_pa=5e3,
        pressure_cutoff_hz=10.0,
    )  # fmt: skip
    return segment, noisy, mean, half_width


def _seals_total(pressures, segment, rate_hz: float, mean, half_width: float) -> np.ndarray:
    """The four seals' summed friction of the stick-slip solution on equal ropes at the
    shaft's depth, the pistons logged still, drifting along ``mean`` through a play of
    ``half_width``."""
    n = segment.size
    _, f = stick_slip(
        pressures, (np.zeros(n),) * 4, np.full(n, DEPTH), segment, HOIST, EQUAL,
        dt_s=1.0 / rate_hz, drift_pressure_pa=mean, drift_half_width_pa=half_width,
    )  # fmt: skip
    return np.sum(f, axis=0)


@pytest.mark.parametrize("rate_hz", [50.0, 100.0])
def test_the_noise_does_not_drain_the_seals_and_a_ringing_does(rate_hz):
    """A common rise loads the seals, then 10 min at rest with 5 kPa of white noise on
    each sensor (low-passed at 10 Hz, as the compensation does): the seals keep > 95 %
    of their force. Then the conveyance rings (20 kPa at 1.5 Hz, damping ratio 0.03, as
    the validation README's ringing hoist): it shakes them loose, to < 50 %. A play of
    one noise sigma instead of DRIFT_SIGMAS drains them in the noise alone."""
    rng = np.random.default_rng(7)
    n_rise, n_rest, n_ring = int(20 * rate_hz), int(600 * rate_hz), int(40 * rate_hz)
    t = np.arange(n_ring) / rate_hz
    ring = 2e4 * np.exp(-2 * np.pi * 0.03 * 1.5 * t) * np.sin(2 * np.pi * 1.5 * t)
    top = 4.06e6
    clean = np.r_[np.linspace(4.0e6, top, n_rise), np.full(n_rest, top), top + ring]
    segment, noisy, mean, half_width = _drift_mean(clean, rate_hz, rng)
    second = int(rate_hz)
    loaded = slice(n_rise + 5 * second, n_rise + 15 * second)
    rested = slice(n_rise + n_rest - 10 * second, n_rise + n_rest)
    rung = slice(-5 * second, None)

    def kept(play: float) -> tuple[float, float]:
        total = _seals_total(noisy, segment, rate_hz, mean, play)
        return float(total[rested].mean() / total[loaded].mean()), float(
            total[rung].mean() / total[loaded].mean()
        )

    after_rest, after_ring = kept(half_width)
    assert after_rest > 0.95
    assert after_ring < 0.5
    assert kept(half_width / 4)[0] < 0.5


def test_a_ringing_hoist_with_lugre_seals_is_compensated_to_its_truth(tmp_path):
    """ropeload's device simulation of the example hoist with LuGre seals: the ropes ring
    after each stop and shake the seals loose, so the raw reading is < 1 % off at rest.
    The compensation must not put back the friction the ringing took away."""
    toml = tmp_path / "lugre.toml"
    text = EXAMPLE_HOIST.read_text()
    toml.write_text(text.replace('"presliding_hysteresis",', ""))
    hoist = load_hoist(toml)
    assert text != toml.read_text()
    assert seals_drift(set(hoist.model.effects))
    day = generate_field_day(
        hoist, date="2026-03-02", seed=11, trips=4, hours=0.3, rest_after_s=20.0
    )
    samples = day.sensors.with_columns(
        source_sha256=pl.lit("synthetic"), source_line=pl.int_range(pl.len())
    )
    # the stick-slip solution runs (the ropes identify; remembered for the compensation)
    means = identification_means(samples, samples["time_utc"][0], hoist, CompensationSettings())
    assert identify_from_means(means, hoist) is not None
    visits = position_accuracy(compensate(samples, hoist), day.truth)
    assert set(visits["position"]) == {"pithead", "middle", "bottom"}
    assert visits["error_after_fraction"].abs().max() < 0.005
    assert visits["rope_error_after_fraction"].max() < 0.005
    at_rest = visits.filter(pl.col("phase") == "standstill")
    assert (at_rest["error_after_fraction"].abs() < 0.002).all()
    assert at_rest["error_before_fraction"].abs().max() > 0.005  # the raw is off


@pytest.mark.parametrize("amplitude_pa", [3e3, 15e3])
def test_without_x_a_ringing_drains_the_shared_out_seals_as_eq15_says(
    tmp_path, monkeypatch, amplitude_pa
):
    """Without a logged x and the oil's motion shared out (``rope_stiffness_sigma=0``, no
    stick-slip solution on the ropes' prior spread) LuGre
    seals drift along a ringing at rest that the shared-out x's deadband hides (5 um:
    ~26 kPa of oil here; BlockCompensation.ringing_drift): a decaying ringing of
    amplitude A_0 travels 4 A_0 f_b / (2 pi zeta f_b) in all, of which all but what
    decays under the noise (~1.5 kPa) counts, a quarter a piston (eq 5); a seal a 0.5
    MPa ramp loaded keeps exp(-sigma_0 s / F_s) of the friction it keeps without (eq
    15's drift along the path s, at rest g = F_s)."""
    toml = tmp_path / "lugre.toml"
    toml.write_text(EXAMPLE_HOIST.read_text().replace('"presliding_hysteresis",', ""))
    hoist = load_hoist(toml)
    rate, zeta, p0, p1 = 50.0, 0.03, 4.0e6, 4.5e6
    f_b = _bounce_hz(DEPTH, p1)
    decay = 2 * np.pi * zeta * f_b
    t = np.arange(int(90 * rate)) / rate
    after = np.clip(t - 20.0, 0.0, None)
    ring = amplitude_pa * np.exp(-decay * after) * np.sin(2 * np.pi * f_b * after)
    p = p0 + (p1 - p0) * np.clip((t - 5.0) / 5.0, 0.0, 1.0) + np.where(t >= 20.0, ring, 0.0)
    rng = np.random.default_rng(7)
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    frame = pl.DataFrame({
        "time_utc": [start + dt.timedelta(seconds=float(s)) for s in t],
        **{f"p{i}_pa": p + rng.normal(0.0, 100.0, t.size) for i in range(1, 5)},
        **{f"x{i}_m": np.full(t.size, None, dtype=float) for i in range(1, 5)},
        "depth_m": np.full(t.size, DEPTH), "speed_m_s": np.zeros(t.size),
        "oil_temp_c": np.full(t.size, 40.0),
    })  # fmt: skip
    drifts = []
    ringing_drift = BlockCompensation.ringing_drift

    def counting(self):
        drifts.append(ringing_drift(self))
        return drifts[-1]

    monkeypatch.setattr(BlockCompensation, "ringing_drift", counting)
    shared = CompensationSettings(rope_stiffness_sigma=0.0)
    drained = compensate(frame, hoist, settings=shared)["friction1_n"].to_numpy()
    (path,) = drifts
    assert path[t < 20.0].sum() == 0.0  # the ramp is not a ringing
    whole = 4 * amplitude_pa * f_b / decay * _share_m(p1, p1 + 1.0)  # [m] a piston
    counted = (amplitude_pa - 2e3) / amplitude_pa * whole
    assert 0.8 * counted < path.sum() < whole
    monkeypatch.setattr(BlockCompensation, "ringing_drift", lambda self: np.zeros(1))
    kept = compensate(frame, hoist, settings=shared)["friction1_n"].to_numpy()
    assert abs(kept[-1]) > 200.0  # the ramp left the seal loaded, and rest keeps it
    expected = kept[-1] * np.exp(-SIGMA0 * path.sum() / _static_n(p1))
    assert drained[-1] == pytest.approx(expected, rel=0.02)


def test_the_travel_given_drives_the_drift_as_the_pressure_does():
    """The stick-slip solution driven by the drift's travel per sample (what the ropes'
    identification sums over each mean) is the one driven by the drift's pressure and
    its play, to the last bit; a ringing of amplitude A > w travels 4 A per cycle
    (:func:`transforms.seal_drift.drift_travel` of the sensors' full-rate samples)."""
    rate, seconds, amplitude = 50.0, 40, 5e4
    t = np.arange(int(rate * seconds)) / rate
    # a full cycle per second, the play's half-width well below the amplitude
    clean = 4.06e6 + amplitude * np.sin(2 * np.pi * t)
    segment = np.zeros(t.size, int)
    moving = np.zeros(t.size, bool)  # in motion: the play's travel alone
    travel = drift_travel(
        (clean,) * 4, t, np.full(t.size, DEPTH), moving, HOIST, pressure_sigma_pa=5e3,
        pressure_cutoff_hz=10.0, spike_sigmas=6.0, gap_factor=3.0,
    )  # fmt: skip
    mean, half_width = drift_pressure(
        (lowpass(clean.copy(), segment, sample_rate_hz=rate, cutoff_hz=10.0),) * 4, segment,
        HOIST, sample_rate_hz=rate, pressure_sigma_pa=5e3, pressure_cutoff_hz=10.0,
    )  # fmt: skip
    assert 0 < half_width < 0.1 * amplitude
    # 4 A per cycle of the filtered ringing (the low-pass keeps it within 2 %)
    middle = slice(int(5 * rate), int(35 * rate))
    assert travel[middle].sum() == pytest.approx(4 * amplitude * 30, rel=0.02)
    n = t.size
    args = ((mean,) * 4, (np.zeros(n),) * 4, np.full(n, DEPTH), segment, HOIST, EQUAL)
    by_pressure = stick_slip(*args, dt_s=1 / rate, drift_pressure_pa=mean,
                             drift_half_width_pa=half_width)  # fmt: skip
    # the kernel's play starts at its second sample (the first only sets the state)
    given = played_travels(np.r_[np.nan, mean[1:]], segment, half_width)
    by_travel = stick_slip(*args, dt_s=1 / rate, drift_travel_pa=given)
    for a, b in zip((*by_pressure[0], *by_pressure[1]), (*by_travel[0], *by_travel[1]),
                    strict=True):  # fmt: skip
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="not both"):
        stick_slip(*args, dt_s=1 / rate, drift_pressure_pa=mean, drift_travel_pa=given)


def test_the_ropes_of_a_ringing_hoist_identify_with_the_drift(tmp_path):
    """ropeload's device simulation of a hoist with LuGre seals (eq 15 at 2 ms) and ropes
    that ring, rope 2 4 % stiffer, x logged to a 0.1 mm step. Identified on the means
    with each mean's played travel (the drift the 0.2 s means hide), rope 2 is the
    stiffer one by 5.4 % (the model's quasi-static seals on a world of inertia and
    bristle damping) at a misfit of 0.09 mm. Without the drift the search takes ropes 2
    and 3 as 11 % stiffer at 0.33 mm."""
    toml = tmp_path / "lugre.toml"
    toml.write_text(EXAMPLE_HOIST.read_text().replace('"presliding_hysteresis",', ""))
    factors = (1.0, 1.04, 1.0, 1.0)
    described = load_hoist(toml)
    hoist = described.model_copy(
        update={
            "ropes": described.ropes.model_copy(update={"head_rope_stiffness_factors": factors})
        }
    )
    day = generate_field_day(hoist, date="2026-03-02", seed=5, trips=8, hours=1.0)
    step = 1e-4
    samples = day.sensors.with_columns(
        (pl.col(f"x{i}_m") / step).round() * step for i in range(1, 5)
    ).sort("time_utc")
    start = samples["time_utc"][0]
    with_drift = identify_from_means(
        identification_means(samples, start, described, CompensationSettings()), described
    )
    without = identify_from_means(record_means(samples, start), described)
    assert with_drift is not None
    assert without is not None
    ratios = np.array(with_drift.stiffness_factors) / with_drift.stiffness_factors[0]
    assert ratios == pytest.approx(np.array(factors), abs=0.02)
    assert int(np.argmax(ratios)) == 1
    assert with_drift.mismatch_m < 0.15e-3
    assert without.mismatch_m > 2 * with_drift.mismatch_m


def _bounce_hz(depth_m: float, p_pa: float) -> float:
    """The example hoist's bounce frequency at that depth, its ropes loaded to p."""
    mass = 4 * AREA * p_pa / 9.80665
    ropes = HOIST.ropes.head_rope_axial_stiffness_n
    return bounce_frequency_hz(ropes, 4, HOIST.shaft.headframe_height_m + depth_m, mass)


def _at_rest_record(rate_hz: float, seconds: float, signal, seed: int):
    """Times, segments, the drift's mean pressure and play half-width of four sensors
    reading ``signal`` (a function of time) (:func:`_drift_mean`)."""
    t = np.arange(int(rate_hz * seconds)) / rate_hz
    segment, _, mean, half_width = _drift_mean(signal(t), rate_hz, np.random.default_rng(seed))
    return t, segment, mean, half_width


@pytest.mark.parametrize("depth_m", [0.0, 600.0])
def test_a_ringing_below_the_play_is_counted_and_noise_and_ramps_are_not(depth_m):
    """At rest, a ringing at the bounce frequency (damping ratio 0.03) decays through the
    play's half-width w: its whole travel, 4 A f per second, is ~4 w / (2 pi zeta)
    below w alone. The ringing's travel counts > 40 % of that (the rest is under the
    noise), the play and it together the whole travel (integrated exactly here) within
    15 %; the sensors' noise alone (10 min) and a payload change's 1 MPa ramp over 3 s
    count < 1 % of it."""
    rate, zeta, p0 = 50.0, 0.03, 4.0e6
    f_b = _bounce_hz(depth_m, p0)
    decay = 2 * np.pi * zeta * f_b
    amplitude = 12e3
    start = 20.0

    def ringing(t):
        after = np.clip(t - start, 0.0, None)
        return p0 + np.where(t >= start, amplitude * np.exp(-decay * after), 0.0) * np.sin(
            2 * np.pi * f_b * after
        )

    seconds = start + 8.0 / decay
    t, segment, mean, w = _at_rest_record(rate, seconds, ringing, seed=3)
    depth, rest = np.full(t.size, depth_m), np.ones(t.size, bool)
    below = ringing_travel(
        mean, segment, depth, rest, HOIST, sample_rate_hz=rate, pressure_cutoff_hz=10.0,
        half_width_pa=w,
    )  # fmt: skip
    played = played_travels(mean, segment, w)
    whole = 4 * amplitude * f_b / decay  # the integral of 4 A(t) f_b
    hidden = 4 * w * f_b / decay  # of which below w
    assert hidden > 0.3 * whole
    assert below.sum() > 0.4 * hidden
    assert played.sum() + below.sum() == pytest.approx(whole, rel=0.15)

    def ramp(t):
        return p0 + 1e6 * np.clip((t - 30.0) / 3.0, 0.0, 1.0)

    # the sensors' noise alone for 10 min, and a payload change's ramp
    for seconds, signal, seed in ((600.0, lambda t: np.full(t.size, p0), 4), (60.0, ramp, 5)):
        _, segment, mean, w = _at_rest_record(rate, seconds, signal, seed=seed)
        n = mean.size
        counted = ringing_travel(
            mean, segment, np.full(n, depth_m), np.ones(n, bool), HOIST, sample_rate_hz=rate,
            pressure_cutoff_hz=10.0, half_width_pa=w,
        )  # fmt: skip
        assert counted.sum() < 0.01 * hidden


def test_the_ringing_counts_only_at_rest_and_where_the_pressure_is_known():
    """A slowly decaying ringing at the bounce frequency (3.5 kPa, 0.01 /s), the
    conveyance moving for its first 30 s of 120 and the sensors silent for 5 s later:
    nothing counts while moving or silent, some at rest, and the full-rate travel is
    the play's plus the ringing's."""
    rate, p0, depth_m = 50.0, 4.0e6, 600.0
    f_b = _bounce_hz(depth_m, p0)

    def ringing(t):
        return p0 + 3.5e3 * np.exp(-0.01 * t) * np.sin(2 * np.pi * f_b * t)

    t, segment, mean, w = _at_rest_record(rate, 120.0, ringing, seed=8)
    n = t.size
    rest = t >= 30.0
    silent = (t >= 60.0) & (t < 65.0)
    mean[silent] = np.nan
    below = ringing_travel(
        mean, segment, np.full(n, depth_m), rest, HOIST, sample_rate_hz=rate,
        pressure_cutoff_hz=10.0, half_width_pa=w,
    )  # fmt: skip
    assert below[~rest].sum() == 0.0
    assert below[silent].sum() == 0.0
    assert below[rest & ~silent].sum() > 0.0
    with pytest.raises(ValueError, match="at_rest has"):
        ringing_travel(
            mean, segment, np.full(n, depth_m), rest[1:], HOIST, sample_rate_hz=rate,
            pressure_cutoff_hz=10.0, half_width_pa=w,
        )  # fmt: skip
    # drift_travel of the sensors is the play's travel plus the ringing's, on its mean
    rng = np.random.default_rng(9)
    sensors = tuple(ringing(t) + rng.normal(0.0, 5e3, n) for _ in range(4))
    travel = drift_travel(
        sensors, t, np.full(n, depth_m), rest, HOIST, pressure_sigma_pa=5e3,
        pressure_cutoff_hz=10.0, spike_sigmas=6.0, gap_factor=3.0,
    )  # fmt: skip
    filtered = tuple(
        lowpass(despike_median3(p, segment)[0], segment, sample_rate_hz=rate, cutoff_hz=10.0)
        for p in sensors
    )
    mean, w = drift_pressure(
        filtered, segment, HOIST, sample_rate_hz=rate, pressure_sigma_pa=5e3,
        pressure_cutoff_hz=10.0, reading_step_pa=max(reading_step(p) for p in sensors),
    )  # fmt: skip
    want = played_travels(mean, segment, w) + ringing_travel(
        mean, segment, np.full(n, depth_m), rest, HOIST, sample_rate_hz=rate,
        pressure_cutoff_hz=10.0, half_width_pa=w,
    )  # fmt: skip
    np.testing.assert_allclose(travel, want, rtol=1e-9, atol=1e-6)
    assert travel[rest].sum() > played_travels(mean, segment, w)[rest].sum()


def test_played_travels_resumed_in_pieces_equal_the_whole() -> None:
    """The play carried across a cut (a block edge) plays as the record read whole; a new
    segment restarts it as a fresh state does."""
    rng = np.random.default_rng(3)
    p = np.cumsum(rng.normal(0.0, 2e3, 500))
    p[[40, 41, 300]] = np.nan
    segment = np.repeat([0, 1], [250, 250])
    whole = played_travels(p, segment, 3e3)
    pieces = np.zeros(p.size)
    state = np.zeros(PLAYED_TRAVEL_STATE_SIZE)
    for lo, hi in ((0, 97), (97, 250), (250, 333), (333, 500)):
        state[1] = 1.0 if lo and segment[lo] == segment[lo - 1] else 0.0
        played_travels_into(p[lo:hi], segment[lo:hi], 3e3, state, pieces[lo:hi])
    np.testing.assert_array_equal(pieces, whole)
    assert whole.sum() > 0.0


def test_a_logger_rounding_coarsely_does_not_drain_the_seals_at_rest():
    """The seals loaded by a common rise, then 10 min at rest, the four sensors read
    with 5 kPa of noise and rounded to 25 kPa (a logger's steps, before the low-pass):
    each reading flips between two steps at rest, and the mean of four flips past the
    white-noise play, draining the seals (the validation days rounded so: stop windows
    3-5 % off). With the rounding in the play (half a step at least) they keep > 95 %."""
    rate_hz, step = 50.0, 25e3
    rng = np.random.default_rng(3)
    n_rise, n_rest = int(20 * rate_hz), int(600 * rate_hz)
    top = 4.06e6 + 0.4 * step  # the readings sit near a step's edge
    clean = np.r_[np.linspace(4.0e6, top, n_rise), np.full(n_rest, top)]
    segment = np.zeros(clean.size, int)
    rounded = tuple(
        lowpass(np.round((clean + rng.normal(0.0, 5e3, clean.size)) / step) * step, segment,
                sample_rate_hz=rate_hz, cutoff_hz=10.0)
        for _ in range(4)
    )  # fmt: skip
    loaded = slice(n_rise + int(5 * rate_hz), n_rise + int(15 * rate_hz))
    rested = slice(-int(10 * rate_hz), None)

    def kept(step_pa: float) -> float:
        mean, half_width = drift_pressure(
            rounded, segment, HOIST, sample_rate_hz=rate_hz, pressure_sigma_pa=5e3,
            pressure_cutoff_hz=10.0, reading_step_pa=step_pa,
        )  # fmt: skip
        total = _seals_total(rounded, segment, rate_hz, mean, half_width)
        return float(total[rested].mean() / total[loaded].mean())

    assert kept(step) > 0.95
    assert kept(0.0) < 0.9  # the white noise's play alone: 13 % drained in 10 min
