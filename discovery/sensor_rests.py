"""A sensor's zero or its span: told apart at the record's rests.

A pressure sensor that reads ``p + offset`` (``sensor_offset``) and one that reads
``gain x p`` (``sensor_gain``) leave alike residuals where the pressure does not range
far: on validation trial_010 with sensor 2 written 40 kPa low
(``benchmarks/eval_sensor_errors.py``), the twelve trips the search replays scored the
two within 10 of each other in BIC and split their resamples 51 / 49 %, so the search
answered ``ambiguous`` and named the excitation that separates them: the conveyance at
rest, empty and loaded. The record holds that excitation: at rest no oil flows, so the
four chambers' pressures are equal and the sensors' readings differ only by the sensors'
errors (contract 1a), and its stops span empty and loaded, pithead and bottom (2.6-6.7
MPa on the validation records). A payload loaded at a stop moves oil for a few seconds,
which a rest's mean takes in with its tens of seconds at rest; a seal's friction changes
what a rope pulls, not the equal pressure of the connected oil.

:func:`sensor_error_at_rest` takes each rest of the whole record (speed below the trip
rule's standstill, trimmed at both ends so the oil has settled), one mean per rest, and
fits each sensor's departure from the others' mean, d_k = p_k - mean_{j != k} p_j, two
ways: a constant per sensor (an offset: d_k = o_k) and a share of the pressure per sensor
(a gain: d_k = (g_k - 1) p). Both have one coordinate per sensor, so the Bayesian
information criterion of each (Schwarz 1978, Ann. Stat. 6(2) 461-464; Gaussian residuals
of unknown variance: n ln(RSS / n) + k ln n) differs by n ln(RSS_offset / RSS_gain),
n the rests x (sensors - 1) (a rest's departures sum to zero);
at :data:`DECISIVE_DBIC` the rests tell, if the better fit explains at least
:data:`MIN_EXPLAINED` of the departures (rests whose readings agree to their noise show
no sensor error). Where the rests span too little of the pressure
(:data:`MIN_RANGE_SHARE`) or are too few (:data:`MIN_RESTS`) they tell nothing and the
search's answer stands (:func:`discovery.record_rereading.discover_in_record` asks them
whenever its first search ranks the two first and second: with sensor 2 written 20 kPa
low, trial_010's trips ranked the gain first by 142 in BIC and refused it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from physics.trip_rule import STANDSTILL_SPEED_M_S

__all__ = [
    "DECISIVE_DBIC",
    "MIN_EXPLAINED",
    "MIN_RANGE_SHARE",
    "MIN_RESTS",
    "RestVerdict",
    "rest_means",
    "sensor_error_at_rest",
]

#: The BIC margin [-] at which the rests decide (Kass & Raftery 1995: "very strong").
DECISIVE_DBIC = 10.0
#: Rests needed, and the span of their mean pressures as a share of its mean [-].
MIN_RESTS, MIN_RANGE_SHARE = 6, 0.2
#: Share of the departures' sum of squares the better fit must explain [-]: rests whose
#: readings agree to their noise show no sensor error, however the two fits compare.
MIN_EXPLAINED = 0.5
#: Seconds left out at each end of a rest (the oil settling after a stop, the winder
#: starting) and the shortest rest kept after that [s].
SETTLE_S, SHORTEST_S = 3.0, 2.0


@dataclass(frozen=True)
class RestVerdict:
    """What the rests say: ``effect`` (``sensor_offset``, ``sensor_gain`` or None: they
    do not tell), ``dbic`` (BIC of the offsets less the gains': > 0 favours a gain),
    ``rests`` used, and each sensor's fitted offset [Pa] and gain error [-]."""

    effect: str | None
    dbic: float
    rests: int
    offsets_pa: tuple[float, ...]
    gain_errors: tuple[float, ...]

    def note(self) -> str:
        said = self.effect or "neither"
        return (
            f"the record's {self.rests} rests tell {said} (BIC of offsets less gains "
            f"{self.dbic:+.1f}, decisive from {DECISIVE_DBIC:g})"
        )


def rest_means(samples: pl.DataFrame, sensors: int) -> np.ndarray:
    """(rests, sensors) mean readings [Pa] of each rest of ``samples`` (landed field
    samples: ``time_utc``, ``speed_m_s``, ``p1_pa``..); a rest is a run of samples whose
    speed is logged and under :data:`physics.trip_rule.STANDSTILL_SPEED_M_S`, trimmed by
    :data:`SETTLE_S` at each end and kept from :data:`SHORTEST_S`; a sample with any
    reading missing is left out."""
    columns = [f"p{i}_pa" for i in range(1, sensors + 1)]
    if not {"time_utc", "speed_m_s", *columns} <= set(samples.columns):
        return np.empty((0, sensors))
    frame = (
        samples.select("time_utc", "speed_m_s", *columns)
        .sort("time_utc")
        .with_columns(
            pl.col("time_utc").dt.epoch("us").cast(pl.Float64).mul(1e-6).alias("t"),
            (pl.col("speed_m_s").cast(pl.Float64).abs() < STANDSTILL_SPEED_M_S)
            .fill_null(False)
            .alias("still"),
        )
        .with_columns(pl.col("still").rle_id().alias("run"))
        .filter(pl.col("still"))
        .with_columns(
            (pl.col("t") - pl.col("t").min().over("run")).alias("since"),
            (pl.col("t").max().over("run") - pl.col("t")).alias("until"),
        )
        .filter((pl.col("since") >= SETTLE_S) & (pl.col("until") >= SETTLE_S))
        .with_columns(pl.col(columns).cast(pl.Float64).fill_nan(None))
        .drop_nulls(columns)
    )
    rests = (
        frame.group_by("run", maintain_order=True)
        .agg(
            (pl.col("t").max() - pl.col("t").min()).alias("span"),
            *(pl.col(c).mean() for c in columns),
        )
        .filter(pl.col("span") >= SHORTEST_S)
    )
    return rests.select(columns).to_numpy().reshape(-1, sensors)


def sensor_error_at_rest(
    samples: pl.DataFrame,
    sensors: int,
    *,
    gains: np.ndarray | None = None,
    offsets_pa: np.ndarray | None = None,
) -> RestVerdict:
    """Offsets or gains: which the record's rests hold (module docstring), beyond the
    sensors' ``gains`` and ``offsets_pa`` the model already has (a reading is
    ``gain x p + offset``; default 1 and 0)."""
    means = rest_means(samples, sensors)
    if gains is not None or offsets_pa is not None:
        gain = np.ones(sensors) if gains is None else np.asarray(gains, dtype=float)
        offset = np.zeros(sensors) if offsets_pa is None else np.asarray(offsets_pa, dtype=float)
        means = (means - offset) / gain
    n_rests = means.shape[0]
    nothing = RestVerdict(None, 0.0, n_rests, (0.0,) * sensors, (0.0,) * sensors)
    if n_rests < MIN_RESTS or sensors < 2:
        return nothing
    level = means.mean(axis=1)
    if np.ptp(level) < MIN_RANGE_SHARE * float(np.mean(level)):
        return nothing
    others = (means.sum(axis=1, keepdims=True) - means) / (sensors - 1)
    departure = means - others  # (rests, sensors)
    offsets = departure.mean(axis=0)
    shares = (departure * level[:, None]).sum(axis=0) / float(np.sum(level**2))
    rss_offset = float(np.sum((departure - offsets) ** 2))
    rss_gain = float(np.sum((departure - level[:, None] * shares) ** 2))
    n = n_rests * (sensors - 1)  # a rest's departures sum to zero: sensors - 1 of them free
    floor = 1e-30  # exact fits: the same tiny floor either way
    dbic = n * float(np.log(max(rss_offset, floor) / max(rss_gain, floor)))
    effect = None
    shown = min(rss_offset, rss_gain) <= (1.0 - MIN_EXPLAINED) * float(np.sum(departure**2))
    if shown and dbic >= DECISIVE_DBIC:
        effect = "sensor_gain"
    elif shown and dbic <= -DECISIVE_DBIC:
        effect = "sensor_offset"
    return RestVerdict(
        effect, dbic, n_rests, tuple(float(v) for v in offsets), tuple(float(v) for v in shares)
    )
