"""Sensor models for synthetic logs: what a logger does to the true signal.

Every function is pure: it takes arrays (or a polars frame) and a seeded
:class:`numpy.random.Generator` and returns new arrays; nothing is changed in place.

Array functions
    :func:`gaussian_noise` -- additive white noise of a given standard deviation.
    :func:`quantise` -- rounding to the resolution the file format prints.
    :func:`jitter_times_ns` -- sample-clock jitter on nominal timestamps (order kept).
    :func:`drop_mask` -- samples the logger drops: isolated losses and whole gaps.
    :func:`spikes` -- occasional single-sample spikes (electrical interference).

Frame function
    :func:`apply_sensor_noise` -- the whole model (:class:`NoiseModel`) on a sensor-level
    frame in SI (``time_utc``, ``p{i}_pa``, ``x{i}_m``, ``depth_m``, ``speed_m_s``,
    ``oil_temp_c``): noise and spikes on values, jitter on time, dropped rows removed.

Quantisation is not part of :func:`apply_sensor_noise`: it belongs to the file writer,
which knows the printed unit and decimals (0.001 MPa in the contract 1a example).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

__all__ = [
    "NoiseModel",
    "apply_sensor_noise",
    "drop_mask",
    "gaussian_noise",
    "jitter_times_ns",
    "quantise",
    "spikes",
]


def gaussian_noise(values: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """``values`` plus zero-mean Gaussian noise of standard deviation ``sigma`` (same unit).

    >>> rng = np.random.default_rng(0)
    >>> gaussian_noise(np.zeros(3), 0.0, rng).tolist()
    [0.0, 0.0, 0.0]
    """
    values = np.asarray(values, dtype=np.float64)
    if sigma < 0:
        raise ValueError(f"sigma: must not be negative, got {sigma}")
    if sigma == 0:
        return values.copy()
    return values + rng.normal(0.0, sigma, values.shape)


def quantise(values: np.ndarray, step: float) -> np.ndarray:
    """Round to the nearest multiple of ``step`` (e.g. 1e3 Pa for 0.001 MPa printed).

    The quantisation error is uniform in [-step/2, step/2]. NaN stays NaN.

    >>> quantise(np.array([4812345.0, -1.2e3]), 1e3).tolist()
    [4812000.0, -1000.0]
    """
    if not step > 0:
        raise ValueError(f"step: must be positive, got {step}")
    return np.round(np.asarray(values, dtype=np.float64) / step) * step


def jitter_times_ns(times_ns: np.ndarray, sigma_ns: float, rng: np.random.Generator) -> np.ndarray:
    """Nominal timestamps [ns] plus acquisition jitter, kept strictly increasing.

    The jitter is a delay (a logger stamps a sample after taking it): the absolute
    value of a Gaussian of ``sigma_ns``, clipped to 0.45 of the smallest nominal spacing
    so that no two samples swap order and no sample moves before its nominal time.

    >>> t = np.arange(5, dtype=np.int64) * 10_000_000
    >>> bool(np.all(np.diff(jitter_times_ns(t, 1e6, np.random.default_rng(1))) > 0))
    True
    """
    t = np.asarray(times_ns, dtype=np.int64)
    if sigma_ns <= 0 or t.size < 2:
        return t.copy()
    spacing = float(np.min(np.diff(t)))
    bound = 0.45 * spacing
    jitter = np.minimum(np.abs(rng.normal(0.0, sigma_ns, t.shape)), bound)
    return t + np.round(jitter).astype(np.int64)


def drop_mask(
    n: int,
    rng: np.random.Generator,
    *,
    drop_probability: float = 0.0,
    gaps_per_hour: float = 0.0,
    gap_samples: tuple[int, int] = (10, 200),
    sample_rate_hz: float = 100.0,
) -> np.ndarray:
    """Boolean mask of the samples the logger keeps (``True`` = kept).

    Two kinds of loss: single samples dropped independently with ``drop_probability``,
    and whole gaps (a logger hiccup), on average ``gaps_per_hour`` of them, each a
    uniform-random length in ``gap_samples`` (inclusive). The first and last samples are
    always kept so that the record's span is that of the truth.

    >>> keep = drop_mask(1000, np.random.default_rng(2), drop_probability=0.01)
    >>> bool(keep[0] and keep[-1]), int((~keep).sum()) > 0
    (True, True)
    """
    keep = np.ones(n, dtype=bool)
    if n == 0:
        return keep
    if drop_probability > 0:
        keep &= rng.random(n) >= drop_probability
    hours = n / sample_rate_hz / 3600.0
    n_gaps = rng.poisson(gaps_per_hour * hours) if gaps_per_hour > 0 else 0
    lo, hi = gap_samples
    for start in rng.integers(0, n, n_gaps):
        length = int(rng.integers(lo, hi + 1))
        keep[start : start + length] = False
    keep[0] = keep[-1] = True
    return keep


def spikes(
    values: np.ndarray, probability: float, amplitude: float, rng: np.random.Generator
) -> np.ndarray:
    """Add single-sample spikes: each sample with ``probability``, size +-``amplitude``.

    Spike size is uniform in [0.5, 1] x amplitude with a random sign.

    >>> out = spikes(np.zeros(10_000), 1e-3, 1e6, np.random.default_rng(3))
    >>> 0 < int((out != 0).sum()) < 50, float(np.abs(out).max()) <= 1e6
    (True, True)
    """
    values = np.asarray(values, dtype=np.float64)
    if probability <= 0 or amplitude == 0:
        return values.copy()
    hit = rng.random(values.shape) < probability
    size = amplitude * rng.uniform(0.5, 1.0, values.shape) * rng.choice([-1.0, 1.0], values.shape)
    return values + np.where(hit, size, 0.0)


@dataclass(frozen=True)
class NoiseModel:
    """Sensor-noise parameters of a field logger, in SI.

    Defaults are those of a 0.1 % class 25 MPa pressure transmitter (sigma ~ 5 kPa),
    a 0.05 mm displacement transducer, an encoder depth of 1 cm, and a logger clock with
    0.2 ms jitter that drops about one sample in ten thousand plus a few gaps per hour.
    """

    pressure_sigma_pa: float = 5e3
    displacement_sigma_m: float = 5e-5
    depth_sigma_m: float = 0.01
    speed_sigma_m_s: float = 0.002
    temperature_sigma_c: float = 0.05
    jitter_sigma_s: float = 2e-4
    drop_probability: float = 1e-4
    gaps_per_hour: float = 2.0
    gap_samples: tuple[int, int] = (10, 200)
    spike_probability: float = 2e-5
    spike_amplitude_pa: float = 0.5e6

    @classmethod
    def none(cls) -> NoiseModel:
        """A perfect logger: no noise, no jitter, nothing dropped."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, (10, 200), 0.0, 0.0)


def apply_sensor_noise(
    frame: pl.DataFrame,
    model: NoiseModel,
    rng: np.random.Generator,
    *,
    sample_rate_hz: float,
) -> pl.DataFrame:
    """Apply ``model`` to a sensor-level SI frame; returns the frame the logger records.

    Columns handled when present: ``p{i}_pa`` (noise + spikes), ``x{i}_m``, ``depth_m``,
    ``speed_m_s``, ``oil_temp_c`` (noise), ``time_utc`` (jitter). Dropped samples are
    removed from the result. Other columns pass through unchanged (and are dropped with
    their rows).
    """
    n = frame.height
    columns: dict[str, np.ndarray] = {}
    for name in frame.columns:
        if name == "time_utc":
            continue
        values = frame[name].to_numpy()
        if name.startswith("p") and name.endswith("_pa"):
            values = gaussian_noise(values, model.pressure_sigma_pa, rng)
            values = spikes(values, model.spike_probability, model.spike_amplitude_pa, rng)
        elif name.startswith("x") and name.endswith("_m"):
            values = gaussian_noise(values, model.displacement_sigma_m, rng)
        elif name == "depth_m":
            values = gaussian_noise(values, model.depth_sigma_m, rng)
        elif name == "speed_m_s":
            values = gaussian_noise(values, model.speed_sigma_m_s, rng)
        elif name == "oil_temp_c":
            values = gaussian_noise(values, model.temperature_sigma_c, rng)
        else:
            continue
        columns[name] = values
    out = frame.with_columns(pl.Series(k, v, dtype=pl.Float64) for k, v in columns.items())
    if "time_utc" in frame.columns and model.jitter_sigma_s > 0:
        t_ns = frame["time_utc"].dt.epoch("ns").to_numpy()
        t_ns = jitter_times_ns(t_ns, model.jitter_sigma_s * 1e9, rng)
        out = out.with_columns(
            pl.Series("time_utc", t_ns)
            .cast(pl.Datetime("ns", "UTC"))
            .cast(frame.schema["time_utc"])
        )
    keep = drop_mask(
        n,
        rng,
        drop_probability=model.drop_probability,
        gaps_per_hour=model.gaps_per_hour,
        gap_samples=model.gap_samples,
        sample_rate_hz=sample_rate_hz,
    )
    if not keep.all():
        out = out.filter(pl.Series(keep))
    return out
