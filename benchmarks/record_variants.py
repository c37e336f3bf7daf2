"""A field-log CSV changed the way real loggers and exports change records (the
evaluations' ``--variant NAME``).

The validation files come from one independent simulator with one logger: 50 Hz, every
column logged, pressures on a 1 kPa step, no outage. Mines' loggers differ, and the
contract allows it (contract 1a: x and oil temperature optional, missing values,
duplicates, rows out of order). :func:`make_variant` writes a validation file as such a
logger would have written it, so that an evaluation measures what ropeload makes of the
same hoist-day through another logger: more records of the same kind than the files it
has (``eval_compensation.py``, ``eval_sanity.py``, ``eval_discovery.py --trials``). Not
a unit test and not ropeload code: the scripts in ``benchmarks/`` import it as a sibling.

:data:`VARIANTS` names each change and says what it does. The truth stays the file's
(the hoist, its loads and effects did not change, only what was logged of them). Each
change keeps the file's delimiter, decimal separator and units.
"""

from __future__ import annotations

import datetime as dt
import math
import random
import re
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

__all__ = [
    "PAUSES",
    "VARIANTS",
    "LogTable",
    "delimiter_of",
    "header_keys",
    "make_variant",
    "pause_row",
    "pressure_rms_pa",
    "read_log",
    "sensor_error",
    "write_changed",
]


def delimiter_of(names_line: str) -> str:
    """The delimiter of a contract-1a file from its column-name line: ``,``, ``;`` or
    tab, whichever it holds most of (contract 1a)."""
    return max((",", ";", "\t"), key=names_line.count)


def header_keys(header: list[str] | tuple[str, ...]) -> dict[str, str]:
    """The ``# key: value`` header lines as {key in lower case: value}."""
    out = {}
    for line in header:
        key, sep, value = line.lstrip("#").partition(":")
        if sep:
            out.setdefault(key.strip().lower(), value.strip())
    return out


@dataclass(frozen=True)
class LogTable:
    """A contract-1a CSV as text: its ``#`` header lines, its column names, its rows
    (each a list of fields as written), its delimiter and whether numbers carry a
    decimal comma."""

    header: tuple[str, ...]
    names: tuple[str, ...]
    rows: list[list[str]]
    delimiter: str
    decimal_comma: bool

    def column(self, name: str) -> int:
        """The index of column ``name`` (any case, as ingest reads it); KeyError naming
        the columns there are."""
        lowered = [n.lower() for n in self.names]
        try:
            return lowered.index(name.lower())
        except ValueError:
            raise KeyError(f"no column {name!r} (columns: {', '.join(self.names)})") from None

    def key(self, name: str, default: str = "") -> str:
        """The value of header line ``# name: value`` (any case; ``default`` without one)."""
        return header_keys(self.header).get(name.lower(), default)

    def rate_hz(self) -> float:
        """The header's nominal ``sample_rate_hz``; ValueError without one."""
        text = self.key("sample_rate_hz").replace(",", ".")
        try:
            rate = float(text)
        except ValueError:
            raise ValueError(f"no usable '# sample_rate_hz:' header line ({text!r})") from None
        if not rate > 0.0:
            raise ValueError(f"sample_rate_hz {text!r} is not positive")
        return rate

    def with_key(self, name: str, value: str) -> LogTable:
        """The same table with header line ``# name: value`` set."""
        lines = [
            f"# {name}: {value}"
            if line.lstrip("#").partition(":")[0].strip().lower() == name.lower()
            else line
            for line in self.header
        ]
        return replace(self, header=tuple(lines))

    def number(self, text: str) -> float:
        """A field as a float (NaN where it is empty)."""
        text = text.strip()
        return (
            float(text.replace(",", ".") if self.decimal_comma else text) if text else float("nan")
        )

    def field(self, value: float, like: str) -> str:
        """``value`` written with as many decimals as field ``like`` has."""
        decimals = len(like.replace(",", ".").partition(".")[2].strip())
        text = f"{value:.{decimals}f}"
        return text.replace(".", ",") if self.decimal_comma else text


def read_log(csv: Path) -> LogTable:
    """The CSV at ``csv`` as a :class:`LogTable` (delimiter ``,``, ``;`` or tab; with
    ``;`` decimal commas, as ingest reads such a file)."""
    lines = csv.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    names_line = lines[first]
    delimiter = delimiter_of(names_line)
    rows = [line.split(delimiter) for line in lines[first + 1 :] if line.strip()]
    return LogTable(
        tuple(lines[:first]),
        tuple(name.strip() for name in names_line.split(delimiter)),
        rows,
        delimiter,
        delimiter == ";",
    )


def _write(table: LogTable, path: Path) -> Path:
    lines = [*table.header, table.delimiter.join(table.names)]
    lines += [table.delimiter.join(row) for row in table.rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _without(*names: str) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        drop = {table.column(name) for name in names}
        width = len(table.names)
        keep = [i for i in range(width) if i not in drop]
        return replace(
            table,
            names=tuple(table.names[i] for i in keep),
            rows=[[row[i] for i in keep] if len(row) == width else row for row in table.rows],
        )

    return change


def _emptied(name: str) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        k, width = table.column(name), len(table.names)
        rows = [[*row[:k], "", *row[k + 1 :]] if len(row) == width else row for row in table.rows]
        return replace(table, rows=rows)

    return change


def _at_rate(rate_hz: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        logged = table.rate_hz()
        every = round(logged / rate_hz)
        if every < 2 or not math.isclose(logged / every, rate_hz, rel_tol=0.01):
            raise ValueError(f"a {logged:g} Hz record has no every-n-th rows at {rate_hz:g} Hz")
        out = replace(table, rows=table.rows[::every])
        return out.with_key("sample_rate_hz", f"{logged / every:g}")

    return change


#: Pascals per unit of the contract's pressure units (``# units: p=...``).
_PA = {"MPa": 1e6, "bar": 1e5, "kPa": 1e3, "Pa": 1.0}
#: The contract's missing-value marker (as a number): kept as written.
_MISSING = -9999.0


def _pressure_units_pa(table: LogTable) -> dict[str, float]:
    """Pascals per unit of each pressure column, as ingest reads the units line: items
    split at ``,`` or ``;``, a column's own key (``p2=bar``) before ``p=``."""
    given = {}
    for item in re.split(r"[,;]", table.key("units")):
        key, eq, unit = item.partition("=")
        if eq:
            given[key.strip().lower()] = unit.strip()
    out = {}
    for i in range(1, 5):
        unit = given.get(f"p{i}") or given.get("p") or "MPa"
        if unit not in _PA:
            raise ValueError(f"pressure unit {unit!r} of p{i} is not one of {', '.join(_PA)}")
        out[f"p{i}"] = _PA[unit]
    return out


def _pressure_step(step_pa: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        units = _pressure_units_pa(table)
        columns = [(table.column(name), step_pa / pa) for name, pa in units.items()]
        width = len(table.names)
        rows = []
        for row in table.rows:
            row = list(row)
            for k, step in columns if len(row) == width else ():
                try:
                    value = table.number(row[k])
                except ValueError:  # not a number: ingest quarantines it, kept
                    continue
                if math.isfinite(value) and value != _MISSING:  # missing stays missing
                    row[k] = table.field(round(value / step) * step, row[k])
            rows.append(row)
        return replace(table, rows=rows)

    return change


def _middle(table: LogTable, minutes: float) -> tuple[int, int]:
    """The rows [lo, hi) of ``minutes`` at the header's rate in the middle of the record;
    ValueError where the record is not three times as long (the variant would not be
    what its name says)."""
    span = round(minutes * 60.0 * table.rate_hz())
    if 3 * span > len(table.rows):
        raise ValueError(
            f"{len(table.rows)} rows: too short for {minutes:g} min in the middle of the record"
        )
    lo = (len(table.rows) - span) // 2
    return lo, lo + span


def _stuck(sensor: int, minutes: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        k, width = table.column(f"p{sensor}"), len(table.names)
        lo, hi = _middle(table, minutes)
        before = [row[k] for row in table.rows[: lo + 1] if len(row) == width and row[k].strip()]
        if not before:
            raise ValueError(f"p{sensor} logs no value before its frozen stretch")
        held = before[-1]  # the last value the sensor gave
        rows = [
            [*row[:k], held, *row[k + 1 :]] if lo <= n < hi and len(row) == width else row
            for n, row in enumerate(table.rows)
        ]
        return replace(table, rows=rows)

    return change


def _outage(minutes: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        lo, hi = _middle(table, minutes)
        return replace(table, rows=table.rows[:lo] + table.rows[hi:])

    return change


#: Seconds of standstill either side of the row a paused logger stops at (:func:`pause_row`).
PAUSE_REST_S = 5.0


def pause_row(table: LogTable) -> int:
    """The row a logger paused at a standstill mid-record resumes with (:data:`PAUSES`):
    the first from the middle of the record on with :data:`PAUSE_REST_S` of logged speed
    0 either side. ValueError without one (no ``speed`` column, no such standstill)."""
    k, width = table.column("speed"), len(table.names)
    rest = round(PAUSE_REST_S * table.rate_hz())
    still = [
        len(row) == width and row[k].strip() != "" and table.number(row[k]) == 0.0
        for row in table.rows
    ]
    run = 0  # standstill rows ending at n
    for n in range(len(still)):
        run = run + 1 if still[n] else 0
        lo = n + 1 - 2 * rest  # a standstill of 2 x rest rows ending at n: resume at lo + rest
        if run >= 2 * rest and lo + rest >= len(table.rows) // 2:
            return lo + rest
    raise ValueError(f"no standstill of {2 * PAUSE_REST_S:g} s after the record's middle")


def _shifted(stamp: str, seconds: float) -> str:
    """A timestamp field ``seconds`` later, written as it was (separator, decimals, any
    offset)."""
    text = stamp.strip()
    when = dt.datetime.fromisoformat(text) + dt.timedelta(seconds=seconds)
    decimals = len(re.split(r"[+\-Z]", text.partition(".")[2])[0]) if "." in text else 0
    spec = {0: "seconds", 3: "milliseconds", 6: "microseconds"}.get(decimals, "milliseconds")
    return when.isoformat(sep="T" if "T" in text else " ", timespec=spec)


def _paused(minutes: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        k, start = table.column("timestamp"), pause_row(table)
        rows = table.rows[:start] + [
            [*row[:k], _shifted(row[k], 60.0 * minutes), *row[k + 1 :]]
            for row in table.rows[start:]
        ]
        return replace(table, rows=rows)

    return change


def _repeated(share: float, shuffled: int, seed: int = 20261130) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        rng = random.Random(seed)
        rows: list[list[str]] = []
        for row in table.rows:
            rows.append(row)
            if rng.random() < share:
                rows.append(list(row))  # an exact duplicate, as a logger's retry writes
        lo = len(rows) // 2
        block = rows[lo : lo + shuffled]
        rng.shuffle(block)
        rows[lo : lo + shuffled] = block
        return replace(table, rows=rows)

    return change


def _reading(table: LogTable, row: list[str], k: int) -> float:
    """Field ``k`` of ``row`` as a number, NaN where it is missing, not a number or the
    row is not whole (ingest quarantines those; they are kept as written)."""
    if len(row) != len(table.names):
        return float("nan")
    try:
        value = table.number(row[k])
    except ValueError:
        return float("nan")
    return value if value != _MISSING else float("nan")


def pressure_rms_pa(table: LogTable, sensor: int) -> float:
    """The RMS of sensor ``sensor``'s logged readings [Pa] (0 where it logs none)."""
    pa = _pressure_units_pa(table)[f"p{sensor}"]
    k = table.column(f"p{sensor}")
    values = [v for row in table.rows if math.isfinite(v := _reading(table, row, k))]
    return pa * math.sqrt(sum(v * v for v in values) / len(values)) if values else 0.0


def sensor_error(
    sensor: int, *, offset_pa: float = 0.0, gain: float = 1.0
) -> Callable[[LogTable], tuple[LogTable, float]]:
    """A change making pressure sensor ``sensor`` read ``gain`` x p + ``offset_pa``
    (contract 4's ``sensor_offset`` / ``sensor_gain``: a transmitter's zero or span off),
    written to the file's own resolution; with the RMS of what it changed over the four
    sensors' readings [Pa] (as ``answers.json``'s ``effect_rms_pa`` measures a hidden
    effect). Missing values stay missing."""

    def change(table: LogTable) -> tuple[LogTable, float]:
        pa = _pressure_units_pa(table)[f"p{sensor}"]
        k = table.column(f"p{sensor}")
        rows, squares, counted = [], 0.0, 0
        for row in table.rows:
            value = _reading(table, row, k)
            if math.isfinite(value):
                changed = (gain - 1.0) * value + offset_pa / pa
                row = [*row[:k], table.field(value + changed, row[k]), *row[k + 1 :]]
                squares += (changed * pa) ** 2
                counted += 1
            rows.append(row)
        rms = math.sqrt(squares / max(counted, 1) / 4.0)  # over the four sensors
        return replace(table, rows=rows), rms

    return change


def write_changed(csv: Path, name: str, change: Callable[[LogTable], tuple[LogTable, float]]):
    """``csv`` with ``change`` (e.g. :func:`sensor_error`) made, beside it as
    ``<stem>-<name>.csv``: (its path, the change's RMS [Pa])."""
    table, rms = change(read_log(csv))
    return _write(table, csv.with_name(f"{csv.stem}-{name}.csv")), rms


#: Each variant's name, what a logger does to write it, and the change.
VARIANTS: dict[str, tuple[str, Callable[[LogTable], LogTable]]] = {
    "no-x": ("no displacement transducers (x1..x4 taken out)", _without("x1", "x2", "x3", "x4")),
    "no-oil-temp": ("no oil thermometer (oil_temp taken out)", _without("oil_temp")),
    "no-speed": ("the encoder's speed not exported (every speed field empty)", _emptied("speed")),
    "10hz": ("a logger at 10 Hz (every fifth row of a 50 Hz file)", _at_rate(10.0)),
    "p-step-10kpa": ("pressures on a 10 kPa step (a coarse analogue input)", _pressure_step(1e4)),
    "stuck-p2": ("sensor 2 frozen at its last value for 20 min mid-record", _stuck(2, 20.0)),
    "outage-5min": ("a 5 min logger outage mid-record (its rows missing)", _outage(5.0)),
    "pause-10min": (
        "the logger paused 10 min at a standstill mid-record (the later rows 10 min on; "
        "the truth's windows after it too)",
        _paused(10.0),
    ),
    "repeated-rows": (
        "2 % of rows written twice and 100 rows out of order (a logger's retries)",
        _repeated(0.02, 100),
    ),
}  # fmt: skip
#: The variants that pause the logger, and for how long [s]: the truth's windows after
#: :func:`pause_row` move on by as much (``eval_compensation.as_variant``).
PAUSES = {"pause-10min": 600.0}


def make_variant(csv: Path, name: str) -> Path:
    """``csv`` as a logger of variant ``name`` (:data:`VARIANTS`) would have written it,
    beside it as ``<stem>-<name>.csv``; ``csv`` itself for ``name`` None or empty.
    KeyError for an unknown name or a column the file does not have; ValueError where
    the variant cannot be made whole (no ``sample_rate_hz`` header for a rate or a span,
    a record shorter than three times the span, a rate that is no every-n-th row)."""
    if not name:
        return csv
    if name not in VARIANTS:
        raise KeyError(f"no variant {name!r} (variants: {', '.join(VARIANTS)})")
    _, change = VARIANTS[name]
    return _write(change(read_log(csv)), csv.with_name(f"{csv.stem}-{name}.csv"))
