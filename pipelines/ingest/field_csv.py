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
   (:mod:`.field_checks`).

A last line without a newline is held back: the file may still be growing
(``Reading.partial``, ``bytes_consumed`` stops before it). ``start_offset`` /
``start_line`` resume a grown file after the part an earlier ingest consumed.
"""

from __future__ import annotations

import re
import zoneinfo
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from pipelines.ingest.batch import REJECTED_SCHEMA, Batch, Reading, RefusedFile, rejected_frame
from pipelines.ingest.csv_scan import NUMBER_BYTES, count_newlines, scan_chunk
from pipelines.ingest.field_checks import (
    CHANNELS,
    REASON_FIELD_COUNT,
    REASON_NON_UTF8,
    HoistLookup,
    depth_limits_m,
    physical_reason,
    to_si,
)
from pipelines.ingest.local_time import AmbiguityState, formats_for, parse_timestamps
from schemas.names import UnsafeNameError, safe_name
from schemas.quantities import QuantityError, unit_factor
from schemas.tables import FIELD_SAMPLES

__all__ = ["DEFAULT_BATCH_BYTES", "CsvHeader", "open_csv", "read_header"]

DEFAULT_BATCH_BYTES = 64 << 20
_HEADER_LIMIT = 1 << 16
_BOM = b"\xef\xbb\xbf"
_REQUIRED_KEYS = ("site", "hoist", "units")
_SEPARATORS = (",", ";", "\t")
_DECIMAL_COMMA = re.compile(r"^[-+]?\d*,\d+$")
_KELVIN = {"K": -273.15}
_SENTINEL = -9999.0
_CONTROL_BYTES = re.compile(rb"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


@dataclass(frozen=True)
class CsvHeader:
    """What the ``#`` header and the column line of a CSV field log say."""

    site: str
    hoist: str
    timezone: str
    sample_rate_hz: float | None
    columns: tuple[str, ...]
    separator: str
    decimal_comma: bool
    #: raw channel name -> (factor, offset) to SI, for the channels present
    units: dict[str, tuple[float, float]]
    #: byte offset and 1-based line number of the first data line
    data_offset: int
    data_line: int
    timestamp_formats: tuple[str, ...]
    notes: tuple[str, ...] = ()


def read_header(path: Path) -> CsvHeader:
    """Parse the header of ``path``; raise :class:`RefusedFile` naming file and line."""
    with path.open("rb") as handle:
        head = handle.read(_HEADER_LIMIT)
    if not head:
        raise RefusedFile(f"{path}: empty file (0 bytes)")
    pos = len(_BOM) if head.startswith(_BOM) else 0
    meta: dict[str, tuple[int, str]] = {}
    notes: list[str] = []
    line_no = 0
    column_line: tuple[int, str] | None = None
    while pos < len(head):
        end = head.find(b"\n", pos)
        terminated = end >= 0
        raw = head[pos : end if terminated else len(head)].rstrip(b"\r")
        line_no += 1
        text = _header_text(path, raw, line_no, notes)
        next_pos = end + 1 if terminated else len(head)
        if not text.strip():
            pos = next_pos
            continue
        if text.startswith("#"):
            if not terminated and len(head) == _HEADER_LIMIT:
                break
            body = text[1:].strip()
            key, colon, value = body.partition(":")
            if colon:
                meta[key.strip().lower()] = (line_no, value.strip())
            else:
                notes.append(f"line {line_no}: header line without 'key: value' ignored")
            pos = next_pos
            continue
        if not terminated:
            raise RefusedFile(
                f"{path}: line {line_no}: header only, no data rows "
                "(the column line is not even complete)"
            )
        column_line = (line_no, text)
        pos = next_pos
        break
    if column_line is None:
        if len(head) == _HEADER_LIMIT:
            raise RefusedFile(f"{path}: no column line within the first {_HEADER_LIMIT} bytes")
        raise RefusedFile(f"{path}: line {line_no}: header only, no column line and no data")
    missing = [k for k in _REQUIRED_KEYS if k not in meta]
    if missing:
        have = ", ".join(sorted(meta)) or "none"
        where = f"lines 1-{column_line[0] - 1}" if column_line[0] > 1 else "line 1"
        raise RefusedFile(
            f"{path}: {where}: header lacks required key(s) "
            f"{', '.join(repr(k) for k in missing)} (found: {have})"
        )
    for key in ("site", "hoist"):  # they become lake folders: safe names only
        try:
            safe_name(meta[key][1], key=key, source=f"{path}: line {meta[key][0]}")
        except UnsafeNameError as exc:
            raise RefusedFile(str(exc)) from None
    col_no, col_text = column_line
    separator = max(_SEPARATORS, key=col_text.count)
    if col_text.count(separator) == 0:
        raise RefusedFile(
            f"{path}: line {col_no}: cannot find the delimiter (comma, semicolon or tab) "
            f"in the column line {col_text[:80]!r}"
        )
    columns = tuple(c.strip() for c in col_text.split(separator))
    _check_columns(path, col_no, columns, notes)
    zone = meta.get("timezone", (0, "UTC"))
    try:
        zoneinfo.ZoneInfo(zone[1])
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise RefusedFile(f"{path}: line {zone[0]}: unknown time zone {zone[1]!r}") from None
    rate: float | None = None
    if "sample_rate_hz" in meta:
        try:
            rate = float(meta["sample_rate_hz"][1])
        except ValueError:
            notes.append(f"line {meta['sample_rate_hz'][0]}: sample_rate_hz not a number, ignored")
    units = _units(path, meta["units"], columns)
    first_rows = _first_data_fields(head[pos:], separator)
    decimal_comma = separator == ";" and any(
        _DECIMAL_COMMA.match(v) for fields in first_rows for v in fields[1:]
    )
    example = first_rows[0][0].strip() if first_rows else ""
    return CsvHeader(
        site=meta["site"][1],
        hoist=meta["hoist"][1],
        timezone=zone[1],
        sample_rate_hz=rate,
        columns=columns,
        separator=separator,
        decimal_comma=decimal_comma,
        units=units,
        data_offset=pos,
        data_line=col_no + 1,
        timestamp_formats=formats_for(example),
        notes=tuple(notes),
    )


def _header_text(path: Path, raw: bytes, line_no: int, notes: list[str]) -> str:
    if b"\x00" in raw:
        if raw.startswith(b"#"):  # a header value with a NUL: show the line, key and all
            raise RefusedFile(f"{path}: line {line_no}: NUL byte in header line {raw[:80]!r}")
        raise RefusedFile(f"{path}: line {line_no}: binary data (NUL bytes), not a text log")
    header_line = raw.lstrip().startswith(b"#")
    if not header_line and (found := _CONTROL_BYTES.search(raw)):
        # the column line (or whatever stands first) holds no control bytes in a text log
        raise RefusedFile(
            f"{path}: line {line_no}: binary data (control byte {found.group()!r} at byte "
            f"{found.start()}), not a text log"
        )
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        if not header_line:  # column names are ASCII
            raise RefusedFile(
                f"{path}: line {line_no}: binary data or not a column line (not UTF-8 text "
                f"at byte {exc.start}), not a text log"
            ) from None
    # A '#' line that is not UTF-8: a LabVIEW export on a Windows PC writes its code
    # page. Read it as cp1252, else Latin-1 (never fails): an operator comment in
    # Latin-1 must not refuse the rows, and what matters keeps its meaning ('°C' in
    # units; site and hoist must be ASCII safe names anyway, checked after this).
    try:
        text, encoding = raw.decode("cp1252"), "cp1252"
    except UnicodeDecodeError:
        text, encoding = raw.decode("latin-1"), "Latin-1"
    notes.append(f"line {line_no}: not UTF-8 text, read as {encoding}")
    return text


def _check_columns(path: Path, line: int, columns: tuple[str, ...], notes: list[str]) -> None:
    if columns[0].lower() != "timestamp":
        raise RefusedFile(
            f"{path}: line {line}: first column must be 'timestamp', got {columns[0][:40]!r}"
        )
    seen = set()
    for name in columns:
        if name in seen:
            raise RefusedFile(f"{path}: line {line}: column {name!r} appears twice")
        seen.add(name)
    lacking = [c for c in ("p1", "p2", "p3", "p4") if c not in seen]
    if lacking:
        raise RefusedFile(
            f"{path}: line {line}: column line lacks required channel(s) {', '.join(lacking)}"
        )
    unknown = [c for c in columns[1:] if c not in CHANNELS]
    if unknown:
        notes.append(f"line {line}: unknown column(s) {', '.join(unknown)} ignored")


def _units(
    path: Path, units_line: tuple[int, str], columns: tuple[str, ...]
) -> dict[str, tuple[float, float]]:
    line, text = units_line
    given: dict[str, str] = {}
    for item in re.split(r"[,;]", text):
        if not item.strip():
            continue
        key, eq, unit = item.partition("=")
        if not eq:
            raise RefusedFile(f"{path}: line {line}: units item {item.strip()!r} is not key=unit")
        given[key.strip()] = unit.strip()
    result: dict[str, tuple[float, float]] = {}
    for name in columns[1:]:
        channel = CHANNELS.get(name)
        if channel is None:
            continue
        unit = given.get(name) or given.get(channel.unit_key) or channel.default_unit
        if unit is None:
            raise RefusedFile(
                f"{path}: line {line}: units line gives no unit for {name} "
                f"(write e.g. '{channel.unit_key}={'MPa' if channel.unit_key == 'p' else 'mm'}')"
            )
        if channel.dimension == "temperature" and unit in _KELVIN:
            result[name] = (1.0, _KELVIN[unit])
            continue
        try:
            result[name] = (unit_factor(unit, channel.dimension), 0.0)
        except QuantityError as exc:
            raise RefusedFile(f"{path}: line {line}: units: {name}: {exc}") from None
    return result


def _first_data_fields(rest: bytes, separator: str) -> list[list[str]]:
    rows = []
    for raw in rest.split(b"\n")[:50]:
        text = raw.rstrip(b"\r").decode("utf-8", errors="replace")
        if text.strip():
            rows.append(text.split(separator))
    return rows[:-1] if len(rows) > 1 else rows  # the last may be cut by the head limit


@dataclass
class _Progress:
    bytes_consumed: int
    partial: str | None = None
    ambiguity: AmbiguityState = field(default_factory=AmbiguityState)


def open_csv(
    path: Path,
    *,
    hoist_lookup: HoistLookup | None = None,
    start_offset: int | None = None,
    start_line: int | None = None,
    batch_bytes: int = DEFAULT_BATCH_BYTES,
) -> Reading:
    """Open a CSV field log; batches are produced lazily as ``Reading.batches`` is iterated.

    ``start_offset``/``start_line`` (both or neither) resume after an already ingested
    prefix; they must point at the start of a line past the header.
    """
    header = read_header(path)
    hoist = hoist_lookup(header.site, header.hoist) if hoist_lookup is not None else None
    offset = header.data_offset if start_offset is None else max(start_offset, header.data_offset)
    line = header.data_line if start_line is None else max(start_line, header.data_line)
    progress = _Progress(bytes_consumed=offset)
    reading = Reading(
        table="field_samples",
        site=header.site,
        hoist=header.hoist,
        batches=iter(()),
        notes=list(header.notes),
        bytes_consumed=offset,
    )
    parser = _BatchParser(header, depth_limits_m(hoist), progress.ambiguity)

    def batches() -> Iterator[Batch]:
        for chunk, first_line, n_lines in _iter_chunks(path, offset, line, batch_bytes, progress):
            yield parser.parse(chunk, first_line, n_lines)
            reading.bytes_consumed = progress.bytes_consumed
        reading.bytes_consumed = progress.bytes_consumed
        reading.partial = progress.partial

    reading.batches = batches()
    return reading


def _iter_chunks(
    path: Path, offset: int, line: int, batch_bytes: int, progress: _Progress
) -> Iterator[tuple[bytes, int, int]]:
    """``(chunk, first line number, lines in it)``; each chunk ends with a newline.

    A chunk is ``batch_bytes`` plus the rest of the line it ends in: a small probe at
    the nominal end finds that newline, then one ``read`` of exactly that length gives
    the chunk (no carry, no copy). Near the end of the file the rest is read at once.
    """
    with path.open("rb") as handle:
        position = offset
        while True:
            length = _through_newline(handle, position, batch_bytes)
            handle.seek(position)
            if length is not None:
                chunk = handle.read(length)
                carry = b""
            else:
                rest = handle.read()
                cut = rest.rfind(b"\n")
                chunk = rest if cut == len(rest) - 1 else rest[: cut + 1]
                carry = rest[cut + 1 :]
                del rest
            if not chunk:
                break
            n_lines = count_newlines(np.frombuffer(chunk, np.uint8))
            yield chunk, line, n_lines
            line += n_lines
            position += len(chunk)
            progress.bytes_consumed += len(chunk)
            if carry:
                break
        if carry:
            progress.partial = (
                f"line {line} is cut off ({len(carry)} bytes without a newline at the end): "
                "held back until the file grows"
            )


def _through_newline(handle, position: int, batch_bytes: int) -> int | None:
    """Bytes from ``position`` through the first newline at or after its ``batch_bytes``-th
    byte, or ``None`` when the file ends before such a newline."""
    probe_at = position + max(batch_bytes, 1) - 1
    handle.seek(probe_at)
    while probe := handle.read(1 << 16):
        found = probe.find(b"\n")
        if found >= 0:
            return probe_at + found + 1 - position
        probe_at += len(probe)
    return None


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
        self, header: CsvHeader, depth_limits: tuple[float, float], ambiguity: AmbiguityState
    ) -> None:
        self.header = header
        self.depth_limits = depth_limits
        self.ambiguity = ambiguity
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
        keep = ~blank & ~bad
        rejected_rows = [
            (
                first_line + int(i),
                None,
                REASON_NON_UTF8 if non_utf8[i] else REASON_FIELD_COUNT,
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

        samples, rejected = self._parse_rows(
            data, row_numbers, raw_of, _FastPath(naive_us, ts_ok, bool(clean.all()))
        )
        rejected_all = pl.concat([rejected_frame(rejected_rows), rejected])
        return Batch(samples=samples, rejected=rejected_all, raw_of=raw_of)

    def _read(self, data: bytes, fast: _FastPath) -> tuple[pl.DataFrame, bool]:
        """The timestamp (unless all fast-parsed) and channel columns; typed if possible.

        Returns the frame and whether its channel columns are already floats. The typed
        read is tried only when every numeric field is clean (see :mod:`.csv_scan`) and
        the file has no decimal comma; a value polars cannot parse makes it raise, and
        the batch falls back to strings + cast (which find the row and the reason).
        """
        wanted = ([] if fast.all_times else [0]) + self.channel_index
        options = dict(
            has_header=False,
            columns=wanted,
            quote_char=None,
            separator=self.header.separator,
            raise_if_empty=False,
        )
        if fast.clean and not self.header.decimal_comma:
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
    ) -> tuple[pl.DataFrame, pl.DataFrame]:
        columns = [f.name for f in FIELD_SAMPLES if f.name not in ("source_sha256",)]
        if row_numbers.size == 0:
            empty = pl.DataFrame(schema={**_sample_schema(), "_row": pl.Int64})
            return empty.select(*columns, "_row"), rejected_frame([])
        text, typed = self._read(data, fast)
        time_utc, time_reason = parse_timestamps(
            None if fast.all_times else text["c0"],
            self.header.timezone,
            self.header.timestamp_formats,
            self.ambiguity,
            prefilled=fast.naive(),
        )
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
        )
        physical = physical_reason(list(present), self.depth_limits)
        if physical:
            any_bad = parsed.select(
                pl.any_horizontal(p.is_not_null() for p in physical).any()
            ).item()
            if any_bad:
                parsed = parsed.with_columns(
                    pl.coalesce(pl.col("_reason"), *physical).alias("_reason")
                )
        if parsed["_reason"].null_count() == parsed.height:
            return parsed.select(*columns, "_row"), rejected_frame([])
        samples = parsed.filter(pl.col("_reason").is_null())
        bad = parsed.filter(pl.col("_reason").is_not_null())
        bad_rows = bad["_row"].to_list()
        rejected = pl.DataFrame(
            {"row": bad_rows, "topic": None, "reason": bad["_reason"], "raw": raw_of(bad_rows)},
            schema=REJECTED_SCHEMA,
        )
        return samples.select(*columns, "_row"), rejected


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
    return dict(pl.from_arrow(FIELD_SAMPLES.empty_table()).schema)
