"""Field logs as CSV (contract 1a): header, delimiter, decimal comma, batches of rows.

The file is read in byte batches of about ``batch_bytes`` that end at a newline, so
memory stays bounded however large the file is. Each batch goes through:

1. One compiled pass over the bytes (:mod:`.csv_scan`): line bounds, field count per
   line, lines with bytes >= 0x80 (UTF-8 checked only for those, whole batch first),
   whether the numeric fields hold only number bytes, and the timestamps of the plain
   ``YYYY-MM-DD HH:MM:SS.fff`` shape. Lines with the wrong field count or non-UTF-8
   bytes are rejected here and cut out of the batch; blank lines are not rows.
2. ``polars.read_csv`` of the remaining lines, only the timestamp (when some were not
   read in step 1) and the known channels. Fast path: the channels typed as floats,
   when every numeric field is clean and there is no decimal comma; if polars still
   finds an unparsable value it raises and the batch is read again the string way.
   String path: every column as a string, cast per column (``strict=False``), so the
   unparsable values can be told from empty ones. Both give the same values.
3. Polars expressions: timestamps to UTC (:mod:`.local_time`), numbers with decimal
   comma and sentinels to SI floats, one quarantine reason per row
   (:mod:`.field_checks`; a clock stepping back: :mod:`.clock`).

The header (``#`` lines, column line, units) is read by :mod:`.csv_header`. A header
repeated mid-file (two exports in one file) that differs from it quarantines the rows
after it, which the file's header would misread (:class:`RepeatedHeaders`).

A last line without a newline is held back: the file may still be growing
(``Reading.partial``, ``bytes_consumed`` stops before it). ``start_offset`` /
``start_line`` resume a grown file after the part an earlier ingest consumed;
``start_clock`` is where that part left the logger's clock (:class:`.clock.ClockState`).
"""

from __future__ import annotations

import datetime as dt
import zoneinfo
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from pipelines.ingest.batch import REJECTED_SCHEMA, Batch, Reading, RefusedFile, rejected_frame
from pipelines.ingest.clock import ClockState, clock_steps, steps_note, tolerance_us
from pipelines.ingest.csv_chunks import ChunkProgress, iter_chunks
from pipelines.ingest.csv_header import (
    CsvHeader,
    header_differences,
    parse_repeated_header,
    read_header,
)
from pipelines.ingest.csv_scan import NUMBER_BYTES, scan_chunk
from pipelines.ingest.field_checks import (
    CHANNELS,
    REASON_FIELD_COUNT,
    REASON_NON_UTF8,
    FieldLimits,
    HoistLookup,
    field_limits,
    physical_reason,
    to_si,
)
from pipelines.ingest.local_time import AmbiguityState, parse_timestamps
from schemas.tables import FIELD_SAMPLES, polars_schema

__all__ = ["DEFAULT_BATCH_BYTES", "open_csv"]

DEFAULT_BATCH_BYTES = 64 << 20
_SENTINEL = -9999.0


def open_csv(
    path: Path,
    *,
    hoist_lookup: HoistLookup | None = None,
    start_offset: int | None = None,
    start_line: int | None = None,
    batch_bytes: int = DEFAULT_BATCH_BYTES,
    start_clock: ClockState | None = None,
    complete: bool = False,
) -> Reading:
    """Open a CSV field log; batches are produced lazily as ``Reading.batches`` is iterated.

    ``complete``: the file is a finished export, its last line a row even without a line
    end (:func:`.csv_chunks.iter_chunks`).

    ``start_offset``/``start_line`` (both or neither) resume after an already ingested
    prefix; they must point at the start of a line past the header. ``start_clock`` is
    the clock state that prefix's reading ended with (the manifest's); without it a
    resume takes it from the prefix's last 64 KB (:func:`prefix_clock`).
    """
    header = read_header(path)
    hoist = hoist_lookup(header.site, header.hoist) if hoist_lookup is not None else None
    offset = header.data_offset if start_offset is None else max(start_offset, header.data_offset)
    line = header.data_line if start_line is None else max(start_line, header.data_line)
    progress = ChunkProgress(bytes_consumed=offset)
    reading = Reading(
        table="field_samples",
        site=header.site,
        hoist=header.hoist,
        batches=iter(()),
        notes=list(header.notes),
        bytes_consumed=offset,
    )
    zone_note = header.zone_note(hoist.hoist.timezone) if hoist is not None else None
    if zone_note is not None:
        reading.notes.append(zone_note)
    limits = field_limits(hoist)
    if offset > header.data_offset:  # the prefix's place in a repeated hour carries over
        progress.ambiguity = prefix_ambiguity(path, header, offset, limits, batch_bytes)
    if start_clock is not None:
        clock = start_clock
    elif offset > header.data_offset:
        clock = prefix_clock(path, header, offset, line, limits)
    else:
        clock = ClockState()
    reading.clock = clock
    repeated = RepeatedHeaders(path, header)
    if offset > header.data_offset:  # a header repeated in the prefix still holds
        repeated.read_prefix(offset)
    parser = _BatchParser(header, limits, progress.ambiguity, clock, repeated)

    def batches() -> Iterator[Batch]:
        chunks = iter_chunks(path, offset, line, batch_bytes, progress, complete=complete)
        for chunk, first_line, n_lines in chunks:
            yield parser.parse(chunk, first_line, n_lines)
            reading.bytes_consumed = progress.bytes_consumed
        reading.bytes_consumed = progress.bytes_consumed
        reading.partial = progress.partial
        if progress.ambiguity.undecided:
            reading.notes.append(
                f"{progress.ambiguity.undecided} sample(s) in the repeated hour of a "
                "daylight-saving change with no time before or after them in the file: "
                "taken as the first (daylight-saving) pass; export with UTC offsets to "
                "be sure"
            )
        if clock.steps:
            reading.notes.append(steps_note(clock.steps, "line"))

    reading.batches = batches()
    return reading


def prefix_clock(
    path: Path, header: CsvHeader, offset: int, line: int, limits: FieldLimits
) -> ClockState:
    """The clock state of the file's first ``offset`` bytes (``line`` the line after
    them) as their last 64 KB give it: for a resume whose earlier reading left none in
    the manifest (ingested before the manifest kept it). A step back that began before
    those 64 KB is not seen."""
    state = ClockState()
    start = max(header.data_offset, offset - _PREFIX_PROBE_BYTES)
    with path.open("rb") as handle:
        handle.seek(start)
        block = handle.read(offset - start)
    if start > header.data_offset:  # from the first whole line
        block = block[block.find(b"\n") + 1 :]
    n_lines = block.count(b"\n")
    if n_lines:
        parser = _BatchParser(header, limits, AmbiguityState(earlier_rows=True), state)
        parser.parse(block, line - n_lines, n_lines)
    state.steps.clear()
    return state


#: The prefix read back on resume covers at least this much time before its last sample:
#: a repeated hour's two passes (:data:`.local_time._EPISODE_US`), and the hour a tail
#: that begins in the second pass, read without the first, shifts its times by.
_PREFIX_SPAN = dt.timedelta(hours=4)
#: The tail read first, to see whether a change is near and how many bytes an hour is.
_PREFIX_PROBE_BYTES = 64 << 10


def prefix_ambiguity(
    path: Path,
    header: CsvHeader,
    offset: int,
    limits: FieldLimits,
    batch_bytes: int = DEFAULT_BATCH_BYTES,
) -> AmbiguityState:
    """Where the file's first ``offset`` bytes (an earlier ingest's, ending with a line)
    left the repeated hour of a daylight-saving change: the state a whole read would
    carry into the line at ``offset`` (:class:`.local_time.AmbiguityState`).

    A resumed read starts from it, not afresh: a file grown within the repeated hour
    (an earlier version cut in its second pass) would otherwise take its new samples
    for the first pass, which the lake already holds, and quarantine them as
    conflicts. Nothing to carry where the zone is UTC, where the timestamps carry their
    offsets, or where the zone's offset stays put from :data:`_PREFIX_SPAN` before the
    prefix's last 64 KB to as long after (the ordinary resume: one 64 KB parse). Near
    a change the prefix's last :data:`_PREFIX_SPAN` (sized from those 64 KB's bytes per
    hour, with a quarter to spare) is read again in batches of ``batch_bytes``, as the
    whole read would, and its state carried.
    """
    state = AmbiguityState(earlier_rows=True)
    if header.timezone == "UTC" or header.offsets:
        return state
    probe = _prefix_times(path, header, max(header.data_offset, offset - _PREFIX_PROBE_BYTES),
                          offset, limits, batch_bytes)  # fmt: skip
    if probe is None:  # no readable time in the tail: nothing to place
        return state
    first, last = probe
    if _offset_steady(first - _PREFIX_SPAN, last + _PREFIX_SPAN, header.timezone):
        return state
    probed = min(offset - header.data_offset, _PREFIX_PROBE_BYTES)
    seconds = (last - first).total_seconds()
    wanted = probed * 1.25 * _PREFIX_SPAN.total_seconds() / seconds if seconds > 0 else offset
    trial = AmbiguityState()
    _prefix_times(path, header, max(header.data_offset, offset - int(wanted)), offset,
                  limits, batch_bytes, trial)  # fmt: skip
    return AmbiguityState(trial.last_local_us, trial.seen_jump, earlier_rows=True)


def _prefix_times(
    path: Path,
    header: CsvHeader,
    start: int,
    offset: int,
    limits: FieldLimits,
    batch_bytes: int,
    state: AmbiguityState | None = None,
) -> tuple[dt.datetime, dt.datetime] | None:
    """Bytes ``[start, offset)`` of the file (from the first whole line after ``start``
    unless it is the data's start) parsed in batches of about ``batch_bytes`` through
    ``state`` (a fresh one if None; it did not start the file unless ``start`` is the
    data's start); the 1st and 99th percentile of their times (a garbage time does not
    stretch the span), None without any."""
    state = state if state is not None else AmbiguityState()
    state.earlier_rows = start > header.data_offset
    parser = _BatchParser(header, limits, state)
    low: list[dt.datetime] = []
    high: list[dt.datetime] = []
    with path.open("rb") as handle:
        handle.seek(start)
        if start > header.data_offset:
            start += len(handle.readline())
        while start < offset:
            handle.seek(start)
            block = handle.read(min(batch_bytes, offset - start))
            if start + len(block) < offset:  # whole lines only
                block += handle.readline()
            n_lines = block.count(b"\n")
            if not n_lines:
                break
            times = parser.parse(block, 0, n_lines).samples["time_utc"].drop_nulls()
            if times.len():
                low.append(times.quantile(0.01, "lower"))
                high.append(times.quantile(0.99, "higher"))
            start += len(block)
    return (min(low), max(high)) if low else None


def _offset_steady(low: dt.datetime, high: dt.datetime, zone: str) -> bool:
    """Whether ``zone``'s UTC offset is one between the UTC instants ``low`` and ``high``
    (checked hourly: a daylight-saving change moves it for months)."""
    tz = zoneinfo.ZoneInfo(zone)
    hours = int((high - low) / dt.timedelta(hours=1)) + 1
    probes = (low + dt.timedelta(hours=k) for k in range(hours + 1))
    return len({probe.astimezone(tz).utcoffset() for probe in probes}) == 1


class _Lines:
    """Line bounds of one chunk (from :func:`.csv_scan.scan_chunk`)."""

    def __init__(self, chunk: bytes, starts: np.ndarray, ends: np.ndarray) -> None:
        self.chunk = chunk
        self.starts = starts
        self.ends = ends

    @property
    def lengths(self) -> np.ndarray:
        """Bytes of each line including its line end."""
        following = np.empty_like(self.starts)
        following[:-1] = self.starts[1:]
        following[-1:] = len(self.chunk)
        return following - self.starts

    def text(self, index: int) -> str:
        return self.chunk[self.starts[index] : self.ends[index]].decode("utf-8", errors="replace")


class _BatchParser:
    def __init__(
        self,
        header: CsvHeader,
        limits: FieldLimits,
        ambiguity: AmbiguityState,
        clock: ClockState | None = None,
        repeated: RepeatedHeaders | None = None,
    ) -> None:
        """``clock``: the file's clock state, carried over its batches; None parses the
        times alone (no clock-step check: a probe of a file's tail, a parser test).
        ``repeated``: the headers repeated in the file, carried over its batches; None
        reads every row with ``header`` (a probe)."""
        self.header = header
        self.repeated = repeated
        self.limits = limits
        self.ambiguity = ambiguity
        self.clock = clock
        rate = header.sample_rate_hz
        self.clock_tolerance = tolerance_us(1 / rate if rate and rate > 0 else None)
        self.names = [f"c{i}" for i in range(len(header.columns))]
        self.separator_byte = ord(header.separator)
        #: raw column index of each known channel, in column order
        self.channel_index = [
            i for i, name in enumerate(header.columns) if i > 0 and name in CHANNELS
        ]
        self.numeric = np.zeros(len(header.columns), np.bool_)
        self.numeric[self.channel_index] = True

    def parse(self, chunk: bytes, first_line: int, n_lines: int) -> Batch:
        buffer = np.frombuffer(chunk, np.uint8)
        starts, ends, fields, high, clean, naive_us, ts_ok = scan_chunk(
            buffer, n_lines, self.separator_byte, self.numeric, NUMBER_BYTES
        )
        lines = _Lines(chunk, starts, ends)
        blank = ends == starts
        wrong_count = ~blank & (fields != len(self.header.columns))
        non_utf8 = np.zeros_like(blank)
        if high.any():
            try:
                chunk.decode("utf-8")
            except UnicodeDecodeError:
                for index in np.flatnonzero(high):
                    try:
                        chunk[starts[index] : ends[index]].decode("utf-8")
                    except UnicodeDecodeError:
                        non_utf8[index] = True
        bad = non_utf8 | wrong_count
        foreign = None
        if self.repeated is not None:
            foreign = self.repeated.reasons(buffer, starts, ends, first_line)
        if foreign is not None:
            bad = bad | (~blank & foreign.astype(bool))
        keep = ~blank & ~bad
        rejected_rows = [
            (
                first_line + int(i),
                None,
                (foreign[i] if foreign is not None else None)
                or (REASON_NON_UTF8 if non_utf8[i] else REASON_FIELD_COUNT),
                lines.text(int(i)),
            )
            for i in np.flatnonzero(bad)
        ]
        if keep.all():
            data = chunk
        else:
            data = buffer[np.repeat(keep, lines.lengths)].tobytes()
            naive_us, ts_ok, clean = naive_us[keep], ts_ok[keep], clean[keep]
        row_numbers = first_line + np.flatnonzero(keep)

        def raw_of(rows: list[int]) -> list[str | None]:
            return [lines.text(r - first_line) for r in rows]

        samples, rejected, held = self._parse_rows(
            data, row_numbers, raw_of, _FastPath(naive_us, ts_ok, bool(clean.all()))
        )
        rejected_all = pl.concat([rejected_frame(rejected_rows), rejected])
        return Batch(samples=samples, rejected=rejected_all, raw_of=raw_of, held=held)

    def _read(self, data: bytes, fast: _FastPath) -> tuple[pl.DataFrame, bool]:
        """The timestamp (unless all fast-parsed) and channel columns; typed if possible.

        Returns the frame and whether its channel columns are already floats. The typed
        read is tried only when every numeric field is clean (see :mod:`.csv_scan`; a
        comma is not a number's byte, so such a batch has no decimal comma); a value
        polars cannot parse makes it raise, and the batch falls back to strings + cast
        (which find the row and the reason).
        """
        wanted = ([] if fast.all_times else [0]) + self.channel_index
        options = dict(
            has_header=False,
            columns=wanted,
            quote_char=None,
            separator=self.header.separator,
            raise_if_empty=False,
        )
        if fast.clean:  # no comma in any number: the typed read holds for ";" too
            typed = {name: pl.String for name in self.names}
            typed.update({self.names[i]: pl.Float64 for i in self.channel_index})
            try:
                return pl.read_csv(data, schema=typed, **options), True
            except pl.exceptions.PolarsError:  # the string path finds row and reason
                pass
        text = pl.read_csv(
            data,
            schema=dict.fromkeys(self.names, pl.String),
            empty_string_is_null=False,
            **options,
        )
        return text, False

    def _parse_rows(
        self, data: bytes, row_numbers: np.ndarray, raw_of, fast: _FastPath
    ) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame | None]:
        columns = [f.name for f in FIELD_SAMPLES if f.name not in ("source_sha256",)]
        if row_numbers.size == 0:
            empty = pl.DataFrame(schema={**_sample_schema(), "_row": pl.Int64})
            return empty.select(*columns, "_row"), rejected_frame([]), None
        text, typed = self._read(data, fast)
        time_utc, time_reason = parse_timestamps(
            None if fast.all_times else text["c0"],
            self.header.timezone,
            self.header.timestamp_formats,
            self.ambiguity,
            prefilled=fast.naive(),
        )
        stepped = None
        if self.clock is not None:  # a row in a clock step has a time: no time reason
            stepped = clock_steps(time_utc, row_numbers, self.clock, self.clock_tolerance)
        present, raw_of_column, casts = self._casts(typed)
        # Stage 1: one cast per column (in parallel; nothing to do when read typed).
        # Stage 2 only does work where the cheap whole-column statistics say there is
        # something to do. Read typed, a null is an empty field (an unparsable value
        # would have made the typed read fail), so only infinities are unparsable.
        numbers = text.select(*casts)
        # s_: may hold a sentinel or an infinity (NaN or infinite, or a value <= -9999);
        # a false alarm only costs the exact expressions below.
        flags = numbers.select(
            *[pl.col(c).null_count().alias(f"n_{c}") for c in present],
            *[
                ((~pl.col(c).is_finite().all()) | (pl.col(c).min() <= _SENTINEL)).alias(f"s_{c}")
                for c in present
            ],
        ).row(0, named=True)
        values, reasons = self._values(present, raw_of_column, flags, typed)
        if reasons:
            if not typed:
                numbers = pl.concat(
                    [numbers, text.select([raw_of_column[c] for c in present])],
                    how="horizontal",
                )
            reason_values = numbers.select(pl.coalesce(*reasons).alias("_reason"))["_reason"]
            time_reason = time_reason.zip_with(time_reason.is_not_null(), reason_values)
        for channel in CHANNELS.values():
            if channel.column not in present:
                values.append(pl.lit(None, pl.Float64).alias(channel.column))
        rows = pl.Series("_row", row_numbers, dtype=pl.Int64)
        parsed = numbers.select(
            *values,
            pl.lit(time_utc).alias("time_utc"),
            pl.lit(rows).alias("_row"),
            pl.lit(rows).alias("source_line"),
            pl.lit(time_reason).alias("_reason"),
            *([] if stepped is None else [pl.lit(stepped).alias("_clock")]),
        )
        return self._split(parsed, list(present), columns, raw_of)

    def _casts(self, typed: bool) -> tuple[dict[str, str], dict[str, str], list[pl.Expr]]:
        """SI column -> raw channel name and -> raw column, and each channel's cast to a
        float (decimal comma replaced; nothing to cast when read typed)."""
        present: dict[str, str] = {}  # SI column -> raw channel name
        raw_of_column: dict[str, str] = {}
        casts: list[pl.Expr] = []
        for index in self.channel_index:
            name, raw = self.header.columns[index], self.names[index]
            channel = CHANNELS[name]
            present[channel.column] = name
            raw_of_column[channel.column] = raw
            source = pl.col(raw)
            if typed:
                casts.append(source.alias(channel.column))
                continue
            if self.header.decimal_comma:
                source = source.str.replace(",", ".", literal=True)
            casts.append(source.cast(pl.Float64, strict=False).alias(channel.column))
        return present, raw_of_column, casts

    def _values(
        self,
        present: dict[str, str],
        raw_of_column: dict[str, str],
        flags: dict[str, object],
        typed: bool,
    ) -> tuple[list[pl.Expr], list[pl.Expr]]:
        """Each channel's SI value and, where ``flags`` say a column may hold one, the
        expression of its unparsable values' reason."""
        reasons: list[pl.Expr] = []
        values: list[pl.Expr] = []
        for column, name in present.items():
            number = pl.col(column)
            if typed:
                if flags[f"s_{column}"]:
                    reasons.append(
                        pl.when(number.is_infinite()).then(pl.lit(f"unparsable value ({name})"))
                    )
            elif flags[f"n_{column}"] or flags[f"s_{column}"]:
                unparsable = (pl.col(raw_of_column[column]) != "") & number.is_null()
                reasons.append(
                    pl.when(unparsable | number.is_infinite()).then(
                        pl.lit(f"unparsable value ({name})")
                    )
                )
            factor, offset = self.header.units[name]
            if flags[f"s_{column}"]:
                values.append(to_si(number, factor, offset).alias(column))
            else:
                scaled = number * factor if factor != 1.0 else number
                values.append((scaled + offset if offset else scaled).alias(column))
        return values, reasons

    def _split(
        self, parsed: pl.DataFrame, present: list[str], columns: list[str], raw_of
    ) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame | None]:
        """The samples, the rejected rows (physically impossible values included) and
        the rows held back by a clock step (``_clock``; see :class:`.batch.Batch`): those
        with no other fault, the others rejected with the step's reason."""
        physical = physical_reason(present, self.limits)
        if physical:
            any_bad = parsed.select(
                pl.any_horizontal(p.is_not_null() for p in physical).any()
            ).item()
            if any_bad:
                parsed = parsed.with_columns(
                    pl.coalesce(pl.col("_reason"), *physical).alias("_reason")
                )
        held = None
        if "_clock" in parsed.columns:
            holding = pl.col("_clock").is_not_null() & pl.col("_reason").is_null()
            held = parsed.filter(holding).select(
                *columns, "_row", pl.col("_clock").alias("_reason")
            )
            parsed = parsed.filter(~holding).with_columns(
                pl.coalesce("_clock", "_reason").alias("_reason")
            )
        if parsed["_reason"].null_count() == parsed.height:
            return parsed.select(*columns, "_row"), rejected_frame([]), held
        samples = parsed.filter(pl.col("_reason").is_null())
        bad = parsed.filter(pl.col("_reason").is_not_null())
        bad_rows = bad["_row"].to_list()
        rejected = pl.DataFrame(
            {"row": bad_rows, "topic": None, "reason": bad["_reason"], "raw": raw_of(bad_rows)},
            schema=REJECTED_SCHEMA,
        )
        return samples.select(*columns, "_row"), rejected, held


#: First bytes of a line that may belong to a header repeated mid-file: ``#`` (a header
#: line), ``t``/``T`` (the column line), a BOM (the second export of ``cat a.csv b.csv``).
_HEADER_FIRST_BYTES = np.zeros(256, np.bool_)
_HEADER_FIRST_BYTES[[ord("#"), ord("t"), ord("T"), 0xEF]] = True
_BOM = b"\xef\xbb\xbf"
#: Data lines after a repeated column line read with it (whether times carry offsets).
_FOLLOWING_LINES = 5


class RepeatedHeaders:
    """Headers repeated mid-file (two exports in one file, ``cat a.csv b.csv``; a logger
    that writes its header again after a restart) and the rows they make unreadable.

    The rows after a repeated header are read with the file's header (the first). Where
    the repeated one (its ``#`` lines and column line, or a column line alone) reads
    alike (:func:`.csv_header.header_differences`), nothing changes; where it differs
    (other units, another hoist, another column order), the file's header would land
    wrong numbers (49.6 bar as 49.6 MPa), another hoist's samples or swapped ropes: every
    row after it is quarantined with one reason naming its line and what differs, until
    a header like the file's own comes again. The header lines themselves are rows of
    the wrong shape as before. The state carries over batches and a resumed file
    (:meth:`read_prefix`).
    """

    def __init__(self, path: Path, header: CsvHeader) -> None:
        self.path, self.header = path, header
        #: the ``#`` lines (line number, bytes) read since the last data row
        self.pending: list[tuple[int, bytes]] = []
        #: the reason of the rows after a differing header, None where they read alike
        self.reason: str | None = None
        #: the file's own header lines, read when a repeated one is to be judged
        self.file_header: bytes | None = None

    def reasons(
        self, buffer: np.ndarray, starts: np.ndarray, ends: np.ndarray, first_line: int
    ) -> np.ndarray | None:
        """The reason quarantining each line of a batch (None where none), None when no
        line has one; the state is read and advanced. Lines ``[starts, ends)`` of
        ``buffer``, the first being line ``first_line``."""
        n = starts.size
        nonblank = ends > starts
        firsts = np.zeros(n, np.bool_)
        firsts[nonblank] = _HEADER_FIRST_BYTES[buffer[starts[nonblank]]]
        candidates = np.flatnonzero(firsts)
        if not candidates.size:
            if nonblank.any():
                self.pending.clear()  # data rows: no header goes on after them
            return _reasons_of(n, [(0, n, self.reason)])
        spans: list[tuple[int, int, str | None]] = []
        begin, previous = 0, -1
        for i in candidates.tolist():
            if nonblank[previous + 1 : i].any():
                self.pending.clear()
            previous = i
            raw = buffer[starts[i] : ends[i]].tobytes().removeprefix(_BOM)
            if raw.startswith(b"#"):
                self.pending.append((first_line + i, raw))
                continue
            separator = max((",", ";", "\t"), key=raw.decode("utf-8", "replace").count)
            if raw.split(separator.encode())[0].strip().lower() != b"timestamp":
                self.pending.clear()  # a row of garbage, not a column line
                continue
            following = [
                buffer[starts[k] : ends[k]].tobytes()
                for k in range(i + 1, min(i + 1 + _FOLLOWING_LINES, n))
            ]
            spans.append((begin, i, self.reason))
            self.reason = self._judge(first_line + i, raw, following)
            self.pending.clear()
            begin = i + 1
        spans.append((begin, n, self.reason))
        return _reasons_of(n, spans)

    def _judge(self, line: int, column_line: bytes, following: list[bytes]) -> str | None:
        """The reason of the rows after the header ending with ``column_line`` (line
        ``line``) and the ``#`` lines pending before it, None where it reads alike."""
        start = self.pending[0][0] if self.pending else line
        where = f"after the header repeated at line {start}"
        if self.file_header is None:
            with self.path.open("rb") as handle:
                self.file_header = handle.read(self.header.data_offset)
        block = [raw for _, raw in self.pending] + [column_line, *following]
        try:
            other = parse_repeated_header(self.path, self.file_header, b"\n".join(block) + b"\n")
        except RefusedFile as exc:
            what = str(exc).removeprefix(f"{self.path}: ")
            return f"{where}, which cannot be read ({what}): not read with the file's header"
        found = header_differences(self.header, other)
        if not found:
            return None
        return (
            f"{where}, which differs from the file's ({', '.join(found)}): "
            "not read with the file's header (two exports in one file?)"
        )

    def read_prefix(self, offset: int) -> None:
        """Advance the state over the file's first ``offset`` bytes (an earlier ingest's,
        ending with a line): a resumed read goes on under the header they left in
        effect. Only blocks holding a line that begins like a header line are parsed."""
        position, line = self.header.data_offset, self.header.data_line
        firsts = (b"#", b"t", b"T", _BOM)  # a line's first bytes, as _HEADER_FIRST_BYTES
        marks = tuple(b"\n" + first for first in firsts)
        with self.path.open("rb") as handle:
            handle.seek(position)
            while position < offset:
                block = handle.read(min(_PREFIX_BLOCK, offset - position))
                if position + len(block) < offset:
                    block += handle.readline()  # whole lines only
                if not block:
                    break
                n_lines = block.count(b"\n")
                if block.startswith(firsts) or any(mark in block for mark in marks):
                    buffer = np.frombuffer(block, np.uint8)
                    newlines = np.flatnonzero(buffer == 10)
                    starts = np.concatenate(([0], newlines[:-1] + 1))
                    ends = newlines - (buffer[np.maximum(newlines - 1, 0)] == 13)
                    self.reasons(buffer, starts, np.maximum(ends, starts), line)
                elif block.strip():
                    self.pending.clear()
                position += len(block)
                line += n_lines


_PREFIX_BLOCK = 8 << 20


def _reasons_of(n: int, spans: list[tuple[int, int, str | None]]) -> np.ndarray | None:
    """Per line of ``n``, the reason of the span ``[begin, end)`` it is in; None if none."""
    if all(reason is None for _, _, reason in spans):
        return None
    out = np.full(n, None, dtype=object)
    for begin, end, reason in spans:
        if reason is not None:
            out[begin:end] = reason
    return out


@dataclass(frozen=True)
class _FastPath:
    """What the compiled scan found for the kept lines of a batch."""

    naive_us: np.ndarray
    ts_ok: np.ndarray
    clean: bool

    @property
    def all_times(self) -> bool:
        return bool(self.ts_ok.all())

    def naive(self) -> pl.Series:
        """Fast-parsed naive local times; null where the polars formats must decide."""
        times = pl.Series("naive", self.naive_us, dtype=pl.Int64).cast(pl.Datetime("us"))
        if self.all_times:
            return times
        ok = pl.Series(self.ts_ok)
        return pl.select(pl.when(ok).then(times)).to_series().alias("naive")


def _sample_schema() -> dict[str, pl.DataType]:
    return dict(polars_schema(FIELD_SAMPLES))
