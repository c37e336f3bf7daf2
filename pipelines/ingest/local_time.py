"""Timestamps of field logs: ISO 8601 strings, with or without offset, to UTC.

A timestamp without offset is local time in the file's ``timezone`` (contract 1a).
Daylight-saving days make local time ambiguous or impossible:

* Repeated hour (clocks go back): the same local time occurs twice. Ingest resolves it
  by the order of the file: ambiguous samples before the first backward jump of local
  time are the earlier instant (still daylight-saving time), those after it the later
  one. A file that starts in the repeated hour and leaves it into standard time
  without a jump (an hourly export cut at the change) held the second pass (seen in
  its first batch of rows, 64 MB: over an hour at 100 Hz); one that
  holds only one pass of the repeated hour and nothing after it gets 'earliest' (the
  file does not tell). The state carries over batch boundaries of one file.
* Skipped hour (clocks go forward): the local time never happened; such samples are
  quarantined with ``REASON_DST_GAP``.

Parsing is vectorised (polars ``str.to_datetime``); the formats are tried in order,
each later one only on the rows the earlier ones could not read, and last the same
formats with a comma before the seconds' fraction read as a point (ISO 8601 allows
either). The CSV reader hands
in the times its compiled scan already read (:mod:`.csv_scan`, the plain
``YYYY-MM-DD HH:MM:SS.fff`` shape); the formats then only see the rest. Batches in
which the zone's offset cannot change (checked every 6 hours) are shifted by that one
offset instead of going through the time-zone rules row by row.
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
_PROBE = dt.timedelta(hours=6)
_EPOCH = dt.datetime(1970, 1, 1)
#: The times a sample may have, µs since the epoch: those of Python's datetime (years
#: 1-9999, as the TDMS reader's) in UTC, and a local time a day inside them, so that no
#: zone's offset takes it out. polars reads more ("-2026-03-02", "+12026-03-02",
#: "0000-01-01"); such a time is no time: the row is quarantined, not the file refused.
_UTC_RANGE_US = (
    (dt.datetime(1, 1, 1) - _EPOCH) // dt.timedelta(microseconds=1),
    (dt.datetime(9999, 12, 31, 23, 59, 59, 999999) - _EPOCH) // dt.timedelta(microseconds=1),
)
_LOCAL_RANGE_US = (
    (dt.datetime(1, 1, 2) - _EPOCH) // dt.timedelta(microseconds=1),
    (dt.datetime(9999, 12, 30, 23, 59, 59, 999999) - _EPOCH) // dt.timedelta(microseconds=1),
)


@dataclass
class AmbiguityState:
    """Where the repeated hour stood at the end of the previous batch of the file."""

    last_local_us: int | None = None
    seen_jump: bool = False
    #: an earlier batch of the file had a time (the file did not start in this one)
    earlier_rows: bool = False
    #: samples of the repeated hour the file does not place (nothing before or after)
    undecided: int = 0


def has_utc_offset(example: str) -> bool:
    """Whether timestamp ``example`` carries its UTC offset (``Z`` or ``+hh:mm``), which
    makes the file's ``timezone`` irrelevant to it (contract 1a).

    >>> has_utc_offset("2026-03-02 06:00:00.000"), has_utc_offset("2026-03-02T06:00:00+08:00")
    (False, True)
    """
    return example.endswith("Z") or (len(example) > 19 and example[-6] in "+-")


def formats_for(example: str) -> tuple[str, ...]:
    """Formats to try, the one matching ``example`` (first data timestamp) first."""
    aware = has_utc_offset(example)
    t_sep = len(example) > 10 and example[10] == "T"
    naive = _NAIVE[::-1] if t_sep else _NAIVE
    offset = _AWARE if t_sep else _AWARE[::-1]
    return (*offset, *naive) if aware else (*naive, *offset)


def parse_timestamps(
    raw: pl.Series | None,
    zone: str,
    formats: tuple[str, ...],
    state: AmbiguityState,
    *,
    prefilled: pl.Series | None = None,
) -> tuple[pl.Series, pl.Series]:
    """UTC times and a reason (null when fine) for each raw timestamp string.

    ``prefilled`` holds naive local times already read by a faster parser (null where
    it could not tell); the formats then only run on its null rows, and ``raw`` may be
    ``None`` when it has none.
    """
    remaining: np.ndarray | None = None  # None: all rows
    if prefilled is not None:
        n = len(prefilled)
        naive = prefilled.alias("naive")
        remaining = np.flatnonzero(prefilled.is_null().to_numpy())
    elif raw is not None:
        n = len(raw)
        naive = pl.repeat(None, n, dtype=pl.Datetime("us"), eager=True).alias("naive")
    else:
        raise ValueError("parse_timestamps needs raw strings or prefilled times")
    aware = pl.repeat(None, n, dtype=_UTC, eager=True).alias("aware")
    todo = formats if remaining is None or remaining.size else ()
    if todo and raw is None:
        raise ValueError("prefilled times have nulls but no raw strings were given")
    # ISO 8601's other decimal sign: a fraction after a comma ("05:59:59,999", as a
    # decimal-comma export may write it), read as the formats' point, on the rows the
    # formats did not read (no cost where they read every row)
    for fmt, comma in [(fmt, False) for fmt in todo] + [(fmt, True) for fmt in todo]:
        assert raw is not None
        sub = raw if remaining is None else raw.gather(remaining)
        if comma:
            sub = sub.str.replace(r"(:\d\d),(\d)", "$1.$2")
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
    naive = _within(naive, _LOCAL_RANGE_US)
    aware = _within(aware, _UTC_RANGE_US)
    local = _localise(naive, zone, state)
    if aware.null_count() == n:
        time_utc = local.alias("time_utc")
    else:
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


def _within(times: pl.Series, bounds: tuple[int, int]) -> pl.Series:
    """``times`` with those outside ``bounds`` (µs since the epoch, inclusive) null."""
    us = times.dt.epoch("us")
    low, high = us.min(), us.max()
    if low is None or high is None or (low >= bounds[0] and high <= bounds[1]):
        return times
    keep = us.is_between(bounds[0], bounds[1]).fill_null(False)
    return pl.select(pl.when(keep).then(times)).to_series().alias(times.name)


def _localise(naive: pl.Series, zone: str, state: AmbiguityState) -> pl.Series:
    earlier_rows = state.earlier_rows
    state.earlier_rows = earlier_rows or naive.null_count() < len(naive)
    if zone == "UTC" or naive.null_count() == len(naive):
        return naive.dt.replace_time_zone("UTC")
    offset = _constant_offset(naive, zone)
    if offset is not None:  # the common case: a plain shift, no time-zone rules per row
        return (naive - offset).dt.replace_time_zone("UTC")
    earliest = naive.dt.replace_time_zone(zone, ambiguous="earliest", non_existent="null")
    latest = naive.dt.replace_time_zone(zone, ambiguous="latest", non_existent="null")
    ambiguous = (earliest != latest).fill_null(False).to_numpy()
    if ambiguous.any():
        rows = np.flatnonzero(ambiguous)
        values = naive.gather(rows).dt.epoch("us").to_numpy()
        if not earlier_rows:
            entered = _enters_in_second_pass(naive, ambiguous, rows[0])
            if entered is None:
                state.undecided += int(rows.size)
            elif entered:
                state.last_local_us, state.seen_jump = int(values[0]), True
        second = _second_pass(values, state)
        if second.any():
            earliest = earliest.scatter(rows[second], latest.gather(rows[second]))
    return earliest.dt.convert_time_zone("UTC")


def _enters_in_second_pass(naive: pl.Series, ambiguous: np.ndarray, first: int) -> bool | None:
    """Whether the first run of repeated-hour samples of a file's first batch, starting
    at row ``first``, is the second pass: no time before it in the file (the file
    starts in the repeated hour) and, without a backward jump, the first time after it
    past the hour. A continuous log that leaves the repeated hour into standard time
    without going back was in its second pass (an export cut at the change). None
    where the file holds only one pass of the hour (nothing tells which: the first is
    taken, and the file's report says so)."""
    first = int(first)
    if naive.slice(0, first).null_count() < first:
        return False  # the file came into the hour from before it: the first pass
    known = naive.is_not_null().to_numpy()  # an unparsable time tells nothing
    after = np.flatnonzero(~ambiguous[first:] & known[first:])
    if after.size == 0:  # only the repeated hour: one pass, unless it jumps back
        times = naive.slice(first, None).drop_nulls().dt.epoch("us").to_numpy()
        return None if bool((np.diff(times) >= 0).all()) else False
    out = first + int(after[0])
    run = naive.slice(first, out - first).drop_nulls().dt.epoch("us").to_numpy()
    step_out = int(naive.slice(out, 1).dt.epoch("us")[0]) - int(run[-1])
    return bool((np.diff(run) >= 0).all() and 0 <= step_out <= _EPISODE_US)


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


def _constant_offset(naive: pl.Series, zone: str) -> dt.timedelta | None:
    """The zone's UTC offset when it cannot change within the batch (the common case).

    Checked at both ends and every 6 hours between, each for both folds, so a
    daylight-saving change anywhere in the batch (or an ambiguous or skipped local time
    at an end) gives ``None``. Batches spanning more than 20 days always give ``None``.
    """
    low, high = naive.min(), naive.max()
    if low is None or high is None:
        return None
    assert isinstance(low, dt.datetime)
    assert isinstance(high, dt.datetime)
    if high - low > dt.timedelta(days=20):
        return None
    tz = zoneinfo.ZoneInfo(zone)
    probes = [low + dt.timedelta(hours=6 * k) for k in range(int((high - low) / _PROBE) + 1)]
    offsets = {
        value.replace(tzinfo=tz, fold=fold).utcoffset()
        for value in (*probes, high)
        for fold in (0, 1)
    }
    if len(offsets) != 1:
        return None
    return offsets.pop()
