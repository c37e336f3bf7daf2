"""The header of a CSV field log (contract 1a): ``#`` lines, column line, units.

:func:`read_header` reads the ``# key: value`` lines (``site``, ``hoist``, ``units``
required; ``timezone``, ``sample_rate_hz``), the column line (delimiter: comma,
semicolon or tab), the unit of every known channel, and from the first data rows
whether numbers have a decimal comma and the shape of the timestamps. A file it cannot
read is refused (:class:`~pipelines.ingest.batch.RefusedFile`) naming file and line.
The rows are :mod:`.field_csv`'s.
"""

from __future__ import annotations

import datetime as dt
import re
import zoneinfo
from dataclasses import dataclass
from pathlib import Path

from pipelines.ingest.batch import RefusedFile
from pipelines.ingest.field_checks import CHANNELS, unit_to_si
from pipelines.ingest.local_time import formats_for, has_utc_offset
from schemas.names import UnsafeNameError, safe_name
from schemas.quantities import QuantityError
from schemas.time_zones import zone_problem

__all__ = [
    "CsvHeader",
    "header_differences",
    "parse_header",
    "parse_repeated_header",
    "read_header",
]


_HEADER_LIMIT = 1 << 16
_BOM = b"\xef\xbb\xbf"
_REQUIRED_KEYS = ("site", "hoist", "units")
#: The header keys ingest reads: stated twice with two values, the file is refused.
_READ_KEYS = (*_REQUIRED_KEYS, "timezone", "sample_rate_hz")
_SEPARATORS = (",", ";", "\t")
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
    #: numbers may have a decimal comma: with ";" between fields (contract 1a)
    decimal_comma: bool
    #: raw channel name -> (factor, offset) to SI, for the channels present
    units: dict[str, tuple[float, float]]
    #: byte offset and 1-based line number of the first data line
    data_offset: int
    data_line: int
    timestamp_formats: tuple[str, ...]
    notes: tuple[str, ...] = ()
    #: the line that states ``timezone`` (0: none, so UTC by default)
    timezone_line: int = 0
    #: whether the first data timestamp carries its UTC offset
    offsets: bool = False

    def zone_note(self, described: str) -> str | None:
        """A note when timestamps without offset are taken in another zone than the
        hoist description's ``[hoist] timezone`` (``described``): a logger exporting
        local time without a ``timezone`` line lands hours off, and nothing in the data
        says so. None when they agree or the timestamps carry their offsets."""
        if self.offsets or _same_clock(self.timezone, described):
            return None
        taken = (
            f"as local time in {self.timezone} (line {self.timezone_line})"
            if self.timezone_line
            else "as UTC (the file has no timezone line; contract 1a)"
        )
        return (
            f"timestamps without a UTC offset taken {taken}, but the hoist's description "
            f"says {described}: check the export"
        )


def parse_repeated_header(path: Path, file_header: bytes, block: bytes) -> CsvHeader:
    """The header that ``block`` (``#`` lines and a column line repeated mid-file, and
    data lines after them) states, each key it does not state (``site``, ``hoist``,
    ``units``, ...) as ``file_header`` (the file's own header lines) states it: a logger
    that writes a comment and the column line again after a restart keeps the file's."""
    file_meta = _header_lines(path, file_header)[0]
    stated = set()
    for raw in block.split(b"\n"):
        text = raw.removeprefix(_BOM)
        if not text.startswith(b"#"):
            break
        stated.add(text[1:].decode("utf-8", "replace").partition(":")[0].strip().lower())
    kept = [
        f"# {key}: {value}".encode()
        for key, (_, value) in file_meta.items()
        if key in _READ_KEYS and key not in stated
    ]
    return parse_header(path, b"".join(line + b"\n" for line in kept) + block)


def header_differences(header: CsvHeader, other: CsvHeader) -> list[str]:
    r"""What ``other`` (a header repeated in the file) says unlike ``header`` (the file's):
    the names of the keys (``site``, ``hoist``, ``timezone``, ``units``) and ``columns``
    (the column line: names, order or delimiter) that would read its rows otherwise.
    The nominal ``sample_rate_hz`` and free keys do not count.

    >>> import dataclasses
    >>> head = b"# site: s\n# hoist: h\n# units: p=MPa\ntimestamp,p1,p2,p3,p4\n"
    >>> a = parse_header(Path("f"), head)
    >>> header_differences(a, dataclasses.replace(a, units={**a.units, "p1": (1e5, 0.0)}))
    ['units (p1)']
    """
    found = [key for key in ("site", "hoist") if getattr(header, key) != getattr(other, key)]
    if not (header.offsets and other.offsets) and not _same_clock(header.timezone, other.timezone):
        found.append("timezone")
    if (header.columns, header.separator) != (other.columns, other.separator):
        found.append("columns")
    units = [c for c in other.units if header.units.get(c, other.units[c]) != other.units[c]]
    if units:
        found.append(f"units ({', '.join(units)})")
    return found


def _same_clock(zone: str, other: str) -> bool:
    """Whether two IANA zones keep the same clock: the same name, or an alias
    (``Etc/UTC`` and ``UTC``, ``PRC`` and ``Asia/Shanghai``) with the same UTC offsets
    in January and in July (winter and summer time)."""
    if zone == other:
        return True
    try:
        a, b = zoneinfo.ZoneInfo(zone), zoneinfo.ZoneInfo(other)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        return False
    instants = [dt.datetime(2026, month, 1, 12, tzinfo=dt.UTC) for month in (1, 7)]
    return all(t.astimezone(a).utcoffset() == t.astimezone(b).utcoffset() for t in instants)


#: The magic bytes of compressed files a CSV export may come as, and their names.
_COMPRESSED = {
    b"\x1f\x8b": "gzip",
    b"PK\x03\x04": "zip",
    b"BZh": "bzip2",
    b"\xfd7zXZ\x00": "xz",
    b"(\xb5/\xfd": "zstd",
}


def read_header(path: Path) -> CsvHeader:
    """Parse the header of ``path``; raise :class:`RefusedFile` naming file and line."""
    with path.open("rb") as handle:
        head = handle.read(_HEADER_LIMIT)
    if not head:
        raise RefusedFile(f"{path}: empty file (0 bytes)")
    kind = next((k for magic, k in _COMPRESSED.items() if head.startswith(magic)), None)
    if kind is not None:
        raise RefusedFile(
            f"{path}: compressed ({kind}), not a text log: decompress it first and ingest the CSV"
        )
    return parse_header(path, head)


def parse_header(path: Path, head: bytes) -> CsvHeader:
    """The header that the bytes ``head`` (a file's first bytes, or a header repeated
    in it) begin with; ``path`` names the file in a refusal (lines counted in ``head``)."""
    meta, notes, (col_no, col_text), pos = _header_lines(path, head)
    missing = [k for k in _REQUIRED_KEYS if k not in meta]
    if missing:
        have = ", ".join(sorted(meta)) or "none"
        where = f"lines 1-{col_no - 1}" if col_no > 1 else "line 1"
        raise RefusedFile(
            f"{path}: {where}: header lacks required key(s) "
            f"{', '.join(repr(k) for k in missing)} (found: {have})"
        )
    for key in ("site", "hoist"):  # they become lake folders: safe names only
        try:
            safe_name(meta[key][1], key=key, source=f"{path}: line {meta[key][0]}")
        except UnsafeNameError as exc:
            raise RefusedFile(str(exc)) from None
    separator = max(_SEPARATORS, key=col_text.count)
    if col_text.count(separator) == 0:
        raise RefusedFile(
            f"{path}: line {col_no}: cannot find the delimiter (comma, semicolon or tab) "
            f"in the column line {col_text[:80]!r}"
        )
    # channel names as the contract writes them (a LabVIEW export may capitalise them:
    # "P1", "Depth")
    columns = tuple(c.strip().lower() for c in col_text.split(separator))
    _check_columns(path, col_no, columns, notes)
    zone = meta.get("timezone", (0, "UTC"))
    problem = zone_problem(zone[1])
    if problem:
        raise RefusedFile(f"{path}: line {zone[0]}: {problem}")
    rate: float | None = None
    if "sample_rate_hz" in meta:
        try:
            rate = float(meta["sample_rate_hz"][1])
        except ValueError:
            notes.append(f"line {meta['sample_rate_hz'][0]}: sample_rate_hz not a number, ignored")
    units = _units(path, meta["units"], columns, notes)
    first_rows = _first_data_fields(head[pos:], separator)
    # with ";" between fields a comma in a number can only be its decimal separator
    # (contract 1a), wherever in the file it first appears
    decimal_comma = separator == ";"
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
        timezone_line=zone[0],
        offsets=has_utc_offset(example),
    )


def _same(a: str, b: str) -> bool:
    """Two header values alike: the same text but for case and blanks, or the same
    number (``100`` and ``100.0``).

    >>> _same("UTC", " utc"), _same("100", "100.0"), _same("main-shaft", "other")
    (True, True, False)
    """
    a, b = a.strip(), b.strip()
    if a.casefold() == b.casefold():
        return True
    try:
        return float(a) == float(b)
    except ValueError:
        return False


def _header_lines(
    path: Path, head: bytes
) -> tuple[dict[str, tuple[int, str]], list[str], tuple[int, str], int]:
    """The ``# key: value`` lines of ``head`` (key -> (line, value)), notes on them, the
    column line (its number and text) and the byte offset just after it."""
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
            name = key.strip().lower()
            if colon and name in _READ_KEYS and name in meta and not _same(meta[name][1], value):
                raise RefusedFile(
                    f"{path}: line {line_no}: {name!r} stated again ({value.strip()!r}) "
                    f"unlike line {meta[name][0]} ({meta[name][1]!r}): which one holds?"
                )
            if colon and name not in meta:  # stated again alike: the first holds
                meta[name] = (line_no, value.strip())
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
        if b"\r" in head and b"\n" not in head:  # checked first: such a file's head is
            # one "line" to the limit
            raise RefusedFile(
                f"{path}: line 1: its lines end with a bare carriage return (classic Mac "
                "OS), not a newline: export with LF or CRLF line ends"
            )
        if len(head) == _HEADER_LIMIT:
            raise RefusedFile(f"{path}: no column line within the first {_HEADER_LIMIT} bytes")
        raise RefusedFile(f"{path}: line {line_no}: header only, no column line and no data")
    return meta, notes, column_line, pos


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
            raise RefusedFile(
                f"{path}: line {line}: column {name!r} appears twice"
                + (" (separators at the end of the line?)" if not name else "")
            )
        seen.add(name)
    lacking = [c for c in ("p1", "p2", "p3", "p4") if c not in seen]
    if lacking:
        raise RefusedFile(
            f"{path}: line {line}: column line lacks required channel(s) {', '.join(lacking)}"
        )
    unknown = [
        c or f"unnamed column {k + 2} (a separator at the end of the line?)"
        for k, c in enumerate(columns[1:])
        if c not in CHANNELS
    ]
    if unknown:
        notes.append(f"line {line}: unknown column(s) {', '.join(unknown)} ignored")


#: The keys a ``units`` line may use besides a column's own name: each channel kind's
#: (``p`` for p1..p4, ``x`` for x1..x4, ...).
_UNIT_KEYS = frozenset(channel.unit_key for channel in CHANNELS.values())


def _units(
    path: Path, units_line: tuple[int, str], columns: tuple[str, ...], notes: list[str]
) -> dict[str, tuple[float, float]]:
    """Each known column's (scale, offset) to SI from the ``units`` line. A key stated
    twice with two units is refused (which one holds cannot be known, and a pressure in
    bar read as MPa is 10 x off), as a header key stated twice is; alike twice, one
    holds. A key that names no channel is noted, not silently dropped.

    >>> notes = []
    >>> _units(Path("f.csv"), (3, "p=bar, q=furlong"), ("timestamp", "p1"), notes)
    {'p1': (100000.0, 0.0)}
    >>> notes
    ['line 3: units for q name no channel, ignored']
    >>> _units(Path("f.csv"), (3, "p=MPa, p=bar"), ("timestamp", "p1"), [])
    Traceback (most recent call last):
    ...
    pipelines.ingest.batch.RefusedFile: f.csv: line 3: units: 'p' stated twice ...
    """
    line, text = units_line
    given: dict[str, str] = {}
    for item in re.split(r"[,;]", text):
        if not item.strip():
            continue
        key, eq, unit = item.partition("=")
        if not eq:
            raise RefusedFile(f"{path}: line {line}: units item {item.strip()!r} is not key=unit")
        key, unit = key.strip().lower(), unit.strip()
        if key in given and given[key] != unit:  # exactly: mPa is not MPa
            raise RefusedFile(
                f"{path}: line {line}: units: {key!r} stated twice ({given[key]!r} and "
                f"{unit!r}); which one holds?"
            )
        given.setdefault(key, unit)
    stray = [k for k in given if k not in CHANNELS and k not in _UNIT_KEYS]
    if stray:
        notes.append(f"line {line}: units for {', '.join(stray)} name no channel, ignored")
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
        try:
            result[name] = unit_to_si(unit, channel)
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
