"""Field logs as TDMS (contract 1b), streamed with ``TdmsFile.open`` + ``data_chunks``.

Group ``hoist``; channels named as the CSV columns, whatever their case (``p1..p4``
required; ``P1`` is ``p1``, as in a CSV's column line); per-channel
``unit_string`` (the same units as the CSV ``units`` line); waveform properties
``wf_start_time``, ``wf_increment`` (+ ``wf_start_offset``, default 0) on every value
channel; file properties ``site``, ``hoist`` (required) and ``timezone``.

Sample times: a ``timestamp`` channel (datetime64), when present, holds the real sample
times (LabVIEW logs jitter and drop samples) and is used; otherwise
``wf_start_time + wf_start_offset + i * wf_increment``. TDMS timestamps are absolute
(UTC), so ``timezone`` is informational here. A value channel without ``wf_increment``
or ``wf_start_time`` refuses the file, naming the channel.

A truncated file (channels end unevenly: the logger stopped mid-write) lands the
samples every channel has and is ``partial``; the complete file, exported later, lands
the rest (the first part as exact duplicates). Channels written in segments of their
own (or in uneven pieces) are aligned by their offsets. A sample whose time no
calendar date holds is quarantined as an unreadable timestamp. A ``timestamp`` channel
whose clock steps back has the repeated stretch quarantined as the CSV reader does
(:mod:`.clock`; the reason names the 0-based sample where the step began).

Quarantine rows of TDMS files have no line; ``raw`` starts with the 0-based sample index
(the samples' ``_row``).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import polars as pl
from nptdms import TdmsChannel, TdmsFile
from nptdms import log as nptdms_log

from pipelines.ingest.batch import REJECTED_SCHEMA, Batch, Reading, RefusedFile, rejected_frame
from pipelines.ingest.clock import ClockState, clock_steps, steps_note, tolerance_us
from pipelines.ingest.field_checks import (
    CHANNELS,
    REASON_TIMESTAMP,
    FieldLimits,
    HoistLookup,
    field_limits,
    physical_reason,
    to_si,
    unit_to_si,
)
from schemas.names import UnsafeNameError, safe_name
from schemas.quantities import QuantityError
from schemas.tables import FIELD_SAMPLES

__all__ = ["open_tdms"]

_GROUP = "hoist"
#: The times a sample may have: those of Python's datetime (years 1-9999).
_EARLIEST = np.datetime64("0001-01-01T00:00:00", "us")
_LATEST = np.datetime64("9999-12-31T23:59:59.999999", "us")

# a damaged file's complaints are the file's outcome (refused, partial), said once by
# the ingest report: npTDMS's own warnings would be further stderr lines. Its module
# loggers ("nptdms.reader", ...) each set their own level and write through their own
# stderr handler, so the package logger's level does not reach them: its log manager's
# does (and holds for loggers of modules it imports later)
nptdms_log.log_manager.set_level(logging.ERROR)


def open_tdms(path: Path, *, hoist_lookup: HoistLookup | None = None) -> Reading:
    """Open a TDMS field log; refuse it (naming the property or channel) if unusable."""
    try:
        tdms = TdmsFile.open(path)
    except Exception as exc:  # npTDMS raises ValueError, KeyError, struct.error ...
        raise RefusedFile(f"{path}: not a readable TDMS file ({exc})") from None
    try:
        site, hoist_name, units, timebase = _metadata(path, tdms)
    except BaseException:
        tdms.close()
        raise
    hoist = hoist_lookup(site, hoist_name) if hoist_lookup is not None else None
    limits = field_limits(hoist)
    notes = []
    unknown = [
        c.name for c in tdms[_GROUP].channels() if _key(c.name) not in (*CHANNELS, "timestamp")
    ]
    if unknown:
        notes.append(f"unknown channel(s) {', '.join(unknown)} ignored")
    reading = Reading(
        table="field_samples", site=site, hoist=hoist_name, batches=iter(()), notes=notes
    )
    reading.batches = _batches(tdms, units, timebase, limits, reading)
    return reading


def _key(name: str) -> str:
    """A channel's name as the CSV's column: whatever its case and surrounding blanks
    (a LabVIEW user may name it ``P1`` or ``Depth``, as a CSV export may write them).

    >>> _key("P1"), _key(" Depth "), _key("oil_temp")
    ('p1', 'depth', 'oil_temp')
    """
    return name.strip().lower()


def _metadata(path: Path, tdms: TdmsFile):
    props = tdms.properties
    for key in ("site", "hoist"):
        if not str(props.get(key, "")).strip():
            raise RefusedFile(f"{path}: file property {key!r} is missing")
        try:  # they become lake folders: safe names only
            safe_name(str(props[key]).strip(), key=f"file property {key!r}", source=str(path))
        except UnsafeNameError as exc:
            raise RefusedFile(str(exc)) from None
    groups = {g.name: g for g in tdms.groups()}
    if _GROUP not in groups:
        raise RefusedFile(f"{path}: no group {_GROUP!r} (groups: {', '.join(groups) or 'none'})")
    channels: dict[str, TdmsChannel] = {}  # channel name as the CSV's column -> channel
    for channel in groups[_GROUP].channels():
        key = _key(channel.name)
        if key in channels and key in (*CHANNELS, "timestamp"):
            raise RefusedFile(
                f"{path}: channel hoist/{channel.name}: the same channel as "
                f"hoist/{channels[key].name} ({key}) but for case: which one holds?"
            )
        channels.setdefault(key, channel)
    lacking = [c for c in ("p1", "p2", "p3", "p4") if c not in channels]
    if lacking:
        raise RefusedFile(f"{path}: group 'hoist' lacks required channel(s) {', '.join(lacking)}")
    stamps = channels.get("timestamp")
    if stamps is not None and not np.issubdtype(
        np.dtype(getattr(stamps, "dtype", np.float64)), np.datetime64
    ):
        raise RefusedFile(
            f"{path}: channel hoist/{stamps.name}: values of type {stamps.dtype} are not times"
        )
    units: dict[str, tuple[float, float]] = {}
    timebase = None
    for name, channel in channels.items():
        spec = CHANNELS.get(name)
        if spec is None:
            continue
        for key in ("wf_increment", "wf_start_time"):
            if key not in channel.properties:
                raise RefusedFile(
                    f"{path}: channel hoist/{channel.name}: waveform property {key!r} is missing "
                    "(no time base)"
                )
        base = _timebase(path, channel.name, channel.properties)
        if not np.issubdtype(np.dtype(getattr(channel, "dtype", np.float64)), np.number):
            raise RefusedFile(
                f"{path}: channel hoist/{channel.name}: values of type {channel.dtype} "
                "are not numbers"
            )
        if timebase is None:
            timebase = base
        elif base != timebase:
            raise RefusedFile(
                f"{path}: channel hoist/{channel.name}: waveform time base differs from "
                "the other channels"
            )
        unit = str(channel.properties.get("unit_string", "")).strip() or spec.default_unit
        if unit is None:
            raise RefusedFile(f"{path}: channel hoist/{channel.name}: no unit_string property")
        try:
            units[name] = unit_to_si(unit, spec)
        except QuantityError as exc:
            raise RefusedFile(f"{path}: channel hoist/{channel.name}: unit_string: {exc}") from None
    return str(props["site"]).strip(), str(props["hoist"]).strip(), units, timebase


def _timebase(path: Path, name: str, props) -> tuple[np.datetime64, float, float]:
    """(start, offset [s], increment [s]) of a channel's waveform properties; refuse the
    file naming the channel and property where one is not a time or a finite number."""
    try:
        start = np.datetime64(props["wf_start_time"], "us")
    except (ValueError, TypeError, OverflowError):
        raise RefusedFile(
            f"{path}: channel hoist/{name}: wf_start_time {props['wf_start_time']!r} is not a time"
        ) from None
    if np.isnat(start):
        raise RefusedFile(f"{path}: channel hoist/{name}: wf_start_time is not a time (NaT)")
    numbers = []
    for key, default in (("wf_start_offset", 0.0), ("wf_increment", None)):
        value = props.get(key, default)
        try:
            number = float(value)
        except (ValueError, TypeError, OverflowError):
            number = float("nan")
        if not np.isfinite(number):
            raise RefusedFile(
                f"{path}: channel hoist/{name}: {key} {value!r} is not a finite number"
            )
        numbers.append(number)
    if not numbers[1] > 0:
        raise RefusedFile(f"{path}: channel hoist/{name}: wf_increment {numbers[1]} is not > 0")
    return start, numbers[0], numbers[1]


def _batches(
    tdms: TdmsFile,
    units: dict[str, tuple[float, float]],
    timebase,
    limits: FieldLimits,
    reading: Reading,
) -> Iterator[Batch]:
    """Batches of the samples every channel has, as the data chunks bring them.

    A chunk holds what one segment wrote of each channel, at the channel's offset: all
    channels alike, or (a logger that writes each group of channels in a segment of its
    own) some of them, or uneven lengths whose totals agree. Each channel's values are
    held until every channel has them; a batch lands the samples all have so far.
    Channels that end unevenly are a truncated file (the logger stopped mid-write): the
    samples every channel has land and the reading is ``partial`` (a channel filled with
    nulls instead would land wrong rows that the complete file's rows then conflict
    with)."""
    names = [
        _key(c.name)
        for c in tdms[_GROUP].channels()
        if _key(c.name) in units or _key(c.name) == "timestamp"
    ]
    held: dict[str, list[np.ndarray]] = {name: [] for name in names}
    ends = dict.fromkeys(names, 0)  # each channel's values read so far
    landed = 0  # the samples every channel had, batched already
    clock = reading.clock = ClockState()
    tolerance = tolerance_us(timebase[2] if timebase is not None else None)
    try:
        for chunk in tdms.data_chunks():
            for channel in chunk[_GROUP].channels():
                name = _key(channel.name)
                if name in held and len(channel):
                    held[name].append(channel[:])
                    ends[name] = channel.offset + len(channel)
            n = min(ends.values()) - landed
            if n <= 0:
                continue
            arrays = {}
            for name in names:
                values = np.concatenate(held[name]) if len(held[name]) > 1 else held[name][0]
                arrays[name] = (landed, values[:n])
                held[name] = [values[n:]] if len(values) > n else []
            si, present = _si_frame(arrays, units, timebase, landed, n)
            landed += n
            yield _screened_batch(si, present, limits, clock, tolerance)
        if max(ends.values()) > landed:
            short = min(ends, key=ends.__getitem__)
            reading.partial = (
                f"truncated: channel hoist/{short} ends at sample {landed}, "
                f"{max(ends.values()) - landed} sample(s) before the longest channel; "
                "landed the samples every channel has"
            )
        if clock.steps:
            reading.notes.append(steps_note(clock.steps, "sample"))
    finally:
        tdms.close()


def _si_frame(
    arrays: dict[str, tuple[int, np.ndarray]],
    units: dict[str, tuple[float, float]],
    timebase,
    first: int,
    n: int,
) -> tuple[pl.DataFrame, list[str]]:
    """The chunk's samples in SI with their times and row numbers (``_row``), and the
    columns of the channels present (the others are null)."""
    start, offset_s, increment_s = timebase
    index = np.arange(first, first + n, dtype=np.int64)
    if "timestamp" in arrays and len(arrays["timestamp"][1]) == n:
        stamps = arrays["timestamp"][1].astype("datetime64[us]")
    else:
        with np.errstate(invalid="ignore", over="ignore"):  # beyond int64: quarantined
            step_us = np.rint((offset_s + index * increment_s) * 1e6).astype(np.int64)
        stamps = start + step_us.astype("timedelta64[us]")
    # a time no calendar date holds (a garbage stamp: npTDMS reads NaT as year 294181)
    # is no time: quarantined as such, not landed in a partition of that "date"
    stamps = np.where((stamps >= _EARLIEST) & (stamps <= _LATEST), stamps, np.datetime64("NaT"))
    times = pl.Series("time_utc", stamps)
    columns = {"time_utc": times.dt.replace_time_zone("UTC"), "_row": index}
    values = []
    for name, spec in CHANNELS.items():
        if name in arrays and len(arrays[name][1]) == n and arrays[name][0] == first:
            columns[name] = np.asarray(arrays[name][1], dtype=np.float64)
            factor, offset = units[name]
            values.append(to_si(pl.col(name), factor, offset).alias(spec.column))
        else:
            values.append(pl.lit(None, pl.Float64).alias(spec.column))
    frame = pl.DataFrame(columns).with_columns(
        pl.col(name).fill_nan(None) for name in units if name in columns
    )
    present = [CHANNELS[n].column for n in units if n in columns]
    return frame.select("time_utc", "_row", *values), present


def _screened_batch(
    si: pl.DataFrame,
    present: list[str],
    limits: FieldLimits,
    clock: ClockState,
    tolerance: int,
) -> Batch:
    """The chunk's samples that pass the timestamp, clock-step and physical checks, and
    the rejected rows with their reason and raw text."""
    stepped = clock_steps(si["time_utc"], si["_row"].to_numpy(), clock, tolerance, "sample")
    reasons = [
        pl.when(pl.col("time_utc").is_null()).then(pl.lit(REASON_TIMESTAMP)),
        *physical_reason(present, limits),
    ]
    si = si.with_columns(pl.coalesce(*reasons).alias("_reason"))
    names = [f.name for f in FIELD_SAMPLES if f.name != "source_sha256"]
    every = si  # raw text of any row, held ones included
    held = None
    if stepped is not None:  # rows of a clock step: held (see Batch.held) unless faulty
        si = si.with_columns(pl.lit(stepped).alias("_clock"))
        holding = pl.col("_clock").is_not_null() & pl.col("_reason").is_null()
        held = (
            si.filter(holding)
            .with_columns(pl.col("_row").alias("source_line"))
            .select(*names, "_row", pl.col("_clock").alias("_reason"))
        )
        si = si.filter(~holding).with_columns(pl.coalesce("_clock", "_reason").alias("_reason"))
        si = si.drop("_clock")
    good = si.filter(pl.col("_reason").is_null())
    bad = si.filter(pl.col("_reason").is_not_null())
    samples = good.with_columns(pl.col("_row").alias("source_line")).select(*names, "_row")

    def raw_of(rows: list[int], si: pl.DataFrame = every) -> list[str | None]:
        picked = si.filter(pl.col("_row").is_in(rows)).drop("_reason")
        texts = {r["_row"]: _raw_text(r) for r in picked.iter_rows(named=True)}
        return [texts.get(r) for r in rows]

    rejected = (
        pl.DataFrame(
            {
                "row": bad["_row"],
                "topic": None,
                "reason": bad["_reason"],
                "raw": raw_of(bad["_row"].to_list()),
            },
            schema=REJECTED_SCHEMA,
        )
        if bad.height
        else rejected_frame([])
    )
    return Batch(samples=samples, rejected=rejected, raw_of=raw_of, held=held)


def _raw_text(row: dict) -> str:
    values = ", ".join(f"{k}={v}" for k, v in row.items() if k not in ("_row",) and v is not None)
    return f"sample {row['_row']}: {values}"
