"""Field logs as CSV (contract 1a): header, delimiter, decimal comma, batches of rows.

The file is read in byte batches of about ``batch_bytes`` that end at a newline, so
memory stays bounded however large the file is. Each batch goes through:

1. numpy over the bytes: line bounds, field count per line (separator positions),
   UTF-8 validity (fast whole-batch check, per line only if that fails). Lines with
   the wrong field count or non-UTF-8 bytes are rejected here and cut out of the batch;
   blank lines are not rows.
2. ``polars.read_csv`` of the remaining lines, every column as a string.
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
        text = _header_text(path, raw, line_no)
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
        raise RefusedFile(
            f"{path}: lines 1-{column_line[0] - 1}: header lacks required key(s) "
            f"{', '.join(repr(k) for k in missing)} (found: {have})"
        )
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


def _header_text(path: Path, raw: bytes, line_no: int) -> str:
    if b"\x00" in raw:
        raise RefusedFile(f"{path}: line {line_no}: binary data (NUL bytes), not a text log")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RefusedFile(
            f"{path}: line {line_no}: header is not UTF-8 text (byte {exc.start}); "
            "binary file or wrong encoding"
        ) from None


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
        for batch in _iter_chunks(path, offset, line, batch_bytes, progress):
            yield parser.parse(*batch)
            reading.bytes_consumed = progress.bytes_consumed
        reading.bytes_consumed = progress.bytes_consumed
        reading.partial = progress.partial

    reading.batches = batches()
    return reading


def _iter_chunks(
    path: Path, offset: int, line: int, batch_bytes: int, progress: _Progress
) -> Iterator[tuple[bytes, int]]:
    with path.open("rb") as handle:
        handle.seek(offset)
        carry = b""
        while True:
            block = handle.read(batch_bytes)
            if not block:
                break
            buffer = carry + block if carry else block
            cut = buffer.rfind(b"\n")
            if cut < 0:
                carry = buffer
                continue
            chunk, carry = buffer[: cut + 1], buffer[cut + 1 :]
            del buffer
            yield chunk, line
            line += chunk.count(b"\n")
            progress.bytes_consumed += len(chunk)
        if carry:
            progress.partial = (
                f"line {line} is cut off ({len(carry)} bytes without a newline at the end): "
                "held back until the file grows"
            )


class _Lines:
    """Line bounds of one chunk (computed once, on demand)."""

    def __init__(self, chunk: bytes) -> None:
        self.chunk = chunk
        self.bytes = np.frombuffer(chunk, np.uint8)
        newlines = np.flatnonzero(self.bytes == 10)
        self.starts = np.empty_like(newlines)
        self.starts[:1] = 0
        self.starts[1:] = newlines[:-1] + 1
        self.lengths = newlines + 1 - self.starts
        ends = newlines.copy()
        carriage = (ends > self.starts) & (self.bytes[np.maximum(ends - 1, 0)] == 13)
        ends[carriage] -= 1
        self.ends = ends

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

    def parse(self, chunk: bytes, first_line: int) -> Batch:
        lines = _Lines(chunk)
        blank = lines.ends == lines.starts
        separators = np.flatnonzero(lines.bytes == self.separator_byte)
        fields = (
            np.searchsorted(separators, lines.ends) - np.searchsorted(separators, lines.starts) + 1
        )
        wrong_count = ~blank & (fields != len(self.header.columns))
        non_utf8 = np.zeros_like(blank)
        try:
            chunk.decode("utf-8")
        except UnicodeDecodeError:
            high = np.flatnonzero(lines.bytes >= 0x80)
            for index in np.unique(np.searchsorted(lines.starts, high, side="right") - 1):
                try:
                    chunk[lines.starts[index] : lines.ends[index]].decode("utf-8")
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
            data = lines.bytes[np.repeat(keep, lines.lengths)].tobytes()
        row_numbers = first_line + np.flatnonzero(keep)

        def raw_of(rows: list[int]) -> list[str | None]:
            return [lines.text(r - first_line) for r in rows]

        samples, rejected = self._parse_rows(data, row_numbers, raw_of)
        rejected_all = pl.concat([rejected_frame(rejected_rows), rejected])
        return Batch(samples=samples, rejected=rejected_all, raw_of=raw_of)

    def _parse_rows(
        self, data: bytes, row_numbers: np.ndarray, raw_of
    ) -> tuple[pl.DataFrame, pl.DataFrame]:
        columns = [f.name for f in FIELD_SAMPLES if f.name not in ("source_sha256",)]
        if row_numbers.size == 0:
            empty = pl.DataFrame(schema={**_sample_schema(), "_row": pl.Int64})
            return empty.select(*columns, "_row"), rejected_frame([])
        text = pl.read_csv(
            data,
            has_header=False,
            new_columns=self.names,
            infer_schema=False,
            quote_char=None,
            separator=self.header.separator,
            empty_string_is_null=False,
            raise_if_empty=False,
        )
        time_utc, time_reason = parse_timestamps(
            text["c0"], self.header.timezone, self.header.timestamp_formats, self.ambiguity
        )
        present: dict[str, str] = {}  # SI column -> raw channel name
        raw_of_column: dict[str, str] = {}
        casts: list[pl.Expr] = []
        for name, raw in zip(self.header.columns[1:], self.names[1:], strict=True):
            channel = CHANNELS.get(name)
            if channel is None:
                continue
            present[channel.column] = name
            raw_of_column[channel.column] = raw
            source = pl.col(raw)
            if self.header.decimal_comma:
                source = source.str.replace(",", ".", literal=True)
            casts.append(source.cast(pl.Float64, strict=False).alias(channel.column))
        # Stage 1: one cast per column (in parallel). Stage 2 only does work where the
        # cheap whole-column statistics say there is something to do.
        numbers = text.select(*casts)
        flags = numbers.select(
            *[pl.col(c).null_count().alias(f"n_{c}") for c in present],
            *[
                (pl.col(c).is_nan() | (pl.col(c) == -9999.0) | pl.col(c).is_infinite())
                .any()
                .alias(f"s_{c}")
                for c in present
            ],
        ).row(0, named=True)
        reasons: list[pl.Expr] = []
        values: list[pl.Expr] = []
        for column, name in present.items():
            number = pl.col(column)
            if flags[f"n_{column}"] or flags[f"s_{column}"]:
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
            numbers = pl.concat(
                [numbers, text.select([raw_of_column[c] for c in present])], how="horizontal"
            )
            reason_values = numbers.select(pl.coalesce(*reasons).alias("_reason"))["_reason"]
            time_reason = time_reason.zip_with(time_reason.is_not_null(), reason_values)
        for channel in CHANNELS.values():
            if channel.column not in present:
                values.append(pl.lit(None, pl.Float64).alias(channel.column))
        parsed = numbers.select(
            *values,
            pl.lit(time_utc).alias("time_utc"),
            pl.Series("_row", row_numbers, dtype=pl.Int64),
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
        good = parsed.filter(pl.col("_reason").is_null())
        samples = good.with_columns(pl.col("_row").alias("source_line"))
        bad = parsed.filter(pl.col("_reason").is_not_null())
        if bad.height:
            rows = bad["_row"].to_list()
            rejected = pl.DataFrame(
                {"row": rows, "topic": None, "reason": bad["_reason"], "raw": raw_of(rows)},
                schema=REJECTED_SCHEMA,
            )
        else:
            rejected = rejected_frame([])
        return samples.select(*columns, "_row"), rejected


def _sample_schema() -> dict[str, pl.DataType]:
    return dict(pl.from_arrow(FIELD_SAMPLES.empty_table()).schema)
