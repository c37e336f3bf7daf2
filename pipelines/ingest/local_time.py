"""Timestamps of field logs: ISO 8601 strings, with or without offset, to UTC.

A timestamp without offset is local time in the file's ``timezone`` (contract 1a).
Daylight-saving days make local time ambiguous or impossible:

* Repeated hour (clocks go back): the same local time occurs twice. Ingest resolves it
  by the order of the file: ambiguous samples before the first backward jump of local
  time are the earlier instant (still daylight-saving time), those after it the later
  one. A file that holds only one pass of the repeated hour (no jump) gets 'earliest'.
  The state carries over batch boundaries of one file.
* Skipped hour (clocks go forward): the local time never happened; such samples are
  quarantined with ``REASON_DST_GAP``.

Parsing is vectorised (polars ``str.to_datetime``); the formats are tried in order,
each later one only on the rows the earlier ones could not read.
"""

from __future__ import annotations

import datetime as dt
import zoneinfo
from dataclasses import dataclass

import numpy as np
import polars as pl

from pipelines.ingest.field_checks import REASON_DST_GAP, REASON_TIMESTAMP

__all__ = ["AmbiguityState", "formats_for", "parse_timestamps"]

_NAIVE = ("%Y-%m-%d %H:%M:%S%.f", "%Y-%m-%dT%H:%M:%S%.f")
_AWARE = ("%Y-%m-%dT%H:%M:%S%.f%#z", "%Y-%m-%d %H:%M:%S%.f%#z")
_UTC = pl.Datetime("us", "UTC")
_EPISODE_US = 2 * 3600 * 1_000_000  # ambiguous samples further apart belong to another day


@dataclass
class AmbiguityState:
    """Where the repeated hour stood at the end of the previous batch of the file."""

    last_local_us: int | None = None
    seen_jump: bool = False


def formats_for(example: str) -> tuple[str, ...]:
    """Formats to try, the one matching ``example`` (first data timestamp) first."""
    aware = example.endswith("Z") or (len(example) > 19 and example[-6] in "+-")
    t_sep = len(example) > 10 and example[10] == "T"
    naive = _NAIVE[::-1] if t_sep else _NAIVE
    offset = _AWARE if t_sep else _AWARE[::-1]
    return (*offset, *naive) if aware else (*naive, *offset)


def parse_timestamps(
    raw: pl.Series, zone: str, formats: tuple[str, ...], state: AmbiguityState
) -> tuple[pl.Series, pl.Series]:
    """UTC times and a reason (null when fine) for each raw timestamp string."""
    n = len(raw)
    naive = pl.Series("naive", [None] * n, dtype=pl.Datetime("us"))
    aware = pl.Series("aware", [None] * n, dtype=_UTC)
    remaining: np.ndarray | None = None  # None: all rows
    for fmt in formats:
        sub = raw if remaining is None else raw.gather(remaining)
        parsed = sub.str.to_datetime(fmt, strict=False, time_unit="us", cache=False)
        has_offset = fmt.endswith("%#z")
        if has_offset:
            parsed = parsed.dt.convert_time_zone("UTC")
        if remaining is None:
            if has_offset:
                aware = parsed
            else:
                naive = parsed
            remaining = np.flatnonzero(parsed.is_null().to_numpy())
        else:
            ok = parsed.is_not_null().to_numpy()
            if ok.any():
                target = aware if has_offset else naive
                target = target.scatter(remaining[ok], parsed.filter(pl.Series(ok)))
                if has_offset:
                    aware = target
                else:
                    naive = target
            remaining = remaining[~ok]
        if remaining.size == 0:
            break
    local = _localise(naive, zone, state)
    time_utc = aware.fill_null(local).alias("time_utc")
    reason = (
        pl.select(
            pl.when(pl.lit(time_utc).is_not_null())
            .then(None)
            .when(pl.lit(naive).is_not_null())
            .then(pl.lit(REASON_DST_GAP))
            .otherwise(pl.lit(REASON_TIMESTAMP))
        )
        .to_series()
        .alias("time_reason")
    )
    return time_utc, reason


def _localise(naive: pl.Series, zone: str, state: AmbiguityState) -> pl.Series:
    if zone == "UTC" or naive.null_count() == len(naive):
        return naive.dt.replace_time_zone("UTC")
    earliest = naive.dt.replace_time_zone(zone, ambiguous="earliest", non_existent="null")
    if not _may_change_offset(naive, zone):
        return earliest.dt.convert_time_zone("UTC")
    latest = naive.dt.replace_time_zone(zone, ambiguous="latest", non_existent="null")
    ambiguous = (earliest != latest).fill_null(False).to_numpy()
    if ambiguous.any():
        rows = np.flatnonzero(ambiguous)
        values = naive.gather(rows).dt.epoch("us").to_numpy()
        second = _second_pass(values, state)
        if second.any():
            earliest = earliest.scatter(rows[second], latest.gather(rows[second]))
    return earliest.dt.convert_time_zone("UTC")


def _second_pass(values: np.ndarray, state: AmbiguityState) -> np.ndarray:
    """Which ambiguous samples (in file order) come after a backward jump of local time."""
    previous = np.empty_like(values)
    previous[1:] = values[:-1]
    previous[0] = values[0] if state.last_local_us is None else state.last_local_us
    new_episode = np.abs(values - previous) > _EPISODE_US
    jump = (values < previous) & ~new_episode
    episode = np.cumsum(new_episode)
    frame = pl.DataFrame({"episode": episode, "jump": jump})
    if not new_episode[0]:
        frame = frame.with_columns(
            pl.when(pl.col("episode") == 0)
            .then(pl.col("jump") | state.seen_jump)
            .otherwise(pl.col("jump"))
            .alias("jump")
        )
    seen = frame.select(pl.col("jump").cum_max().over("episode")).to_series().to_numpy()
    state.last_local_us = int(values[-1])
    state.seen_jump = bool(seen[-1])
    return seen


def _may_change_offset(naive: pl.Series, zone: str) -> bool:
    """False when no UTC-offset change can lie within the batch (the common case)."""
    low, high = naive.min(), naive.max()
    if low is None or high is None:
        return False
    assert isinstance(low, dt.datetime)
    assert isinstance(high, dt.datetime)
    if high - low > dt.timedelta(days=20):
        return True
    tz = zoneinfo.ZoneInfo(zone)
    offsets = {
        value.replace(tzinfo=tz, fold=fold).utcoffset() for value in (low, high) for fold in (0, 1)
    }
    return len(offsets) > 1
