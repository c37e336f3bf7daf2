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

import random
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

__all__ = ["VARIANTS", "LogTable", "make_variant", "read_log"]


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
        """The index of column ``name``; KeyError naming the columns there are."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no column {name!r} (columns: {', '.join(self.names)})") from None

    def key(self, name: str, default: str = "") -> str:
        """The value of header line ``# name: value`` (``default`` without one)."""
        for line in self.header:
            key, sep, value = line.lstrip("#").partition(":")
            if sep and key.strip() == name:
                return value.strip()
        return default

    def with_key(self, name: str, value: str) -> LogTable:
        """The same table with header line ``# name: value`` set."""
        lines = [
            f"# {name}: {value}" if line.lstrip("#").partition(":")[0].strip() == name else line
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
    """The CSV at ``csv`` as a :class:`LogTable`."""
    lines = csv.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    names_line = lines[first]
    delimiter = ";" if names_line.count(";") > names_line.count(",") else ","
    rows = [line.split(delimiter) for line in lines[first + 1 :] if line.strip()]
    probe = next((row[1] for row in rows if len(row) > 1 and row[1].strip()), "")
    return LogTable(
        tuple(lines[:first]),
        tuple(name.strip() for name in names_line.split(delimiter)),
        rows,
        delimiter,
        delimiter == ";" and "," in probe,
    )


def _write(table: LogTable, path: Path) -> Path:
    lines = [*table.header, table.delimiter.join(table.names)]
    lines += [table.delimiter.join(row) for row in table.rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _without(*names: str) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        drop = {table.column(name) for name in names}
        keep = [i for i in range(len(table.names)) if i not in drop]
        return replace(
            table,
            names=tuple(table.names[i] for i in keep),
            rows=[[row[i] for i in keep] for row in table.rows],
        )

    return change


def _emptied(name: str) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        k = table.column(name)
        return replace(table, rows=[[*row[:k], "", *row[k + 1 :]] for row in table.rows])

    return change


def _at_rate(rate_hz: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        logged = float(table.key("sample_rate_hz", "0").replace(",", ".") or 0.0)
        every = max(1, round(logged / rate_hz)) if logged > 0 else 1
        out = replace(table, rows=table.rows[::every])
        return out.with_key("sample_rate_hz", f"{logged / every:g}") if logged > 0 else out

    return change


#: Pascals per unit of the contract's pressure units (``# units: p=...``).
_PA = {"MPa": 1e6, "bar": 1e5, "kPa": 1e3, "Pa": 1.0}


def _pressure_unit_pa(table: LogTable) -> float:
    units = dict(
        part.strip().split("=", 1) for part in table.key("units").split(",") if "=" in part
    )
    return _PA[units.get("p", "MPa").strip()]


def _pressure_step(step_pa: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        step = step_pa / _pressure_unit_pa(table)
        columns = [table.column(f"p{i}") for i in range(1, 5)]
        rows = []
        for row in table.rows:
            row = list(row)
            for k in columns:
                value = table.number(row[k]) if row[k].strip() else float("nan")
                if value == value:  # not NaN: a missing value stays missing
                    row[k] = table.field(round(value / step) * step, row[k])
            rows.append(row)
        return replace(table, rows=rows)

    return change


def _stuck(sensor: int, minutes: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        k = table.column(f"p{sensor}")
        logged = float(table.key("sample_rate_hz", "50").replace(",", ".") or 50.0)
        span = min(len(table.rows) // 3, round(minutes * 60.0 * logged))
        lo = (len(table.rows) - span) // 2
        held = table.rows[lo][k]
        rows = [
            [*row[:k], held, *row[k + 1 :]] if lo <= n < lo + span else row
            for n, row in enumerate(table.rows)
        ]
        return replace(table, rows=rows)

    return change


def _outage(minutes: float) -> Callable[[LogTable], LogTable]:
    def change(table: LogTable) -> LogTable:
        logged = float(table.key("sample_rate_hz", "50").replace(",", ".") or 50.0)
        span = min(len(table.rows) // 3, round(minutes * 60.0 * logged))
        lo = (len(table.rows) - span) // 2
        return replace(table, rows=table.rows[:lo] + table.rows[lo + span :])

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


#: Each variant's name, what a logger does to write it, and the change.
VARIANTS: dict[str, tuple[str, Callable[[LogTable], LogTable]]] = {
    "no-x": ("no displacement transducers (x1..x4 taken out)", _without("x1", "x2", "x3", "x4")),
    "no-oil-temp": ("no oil thermometer (oil_temp taken out)", _without("oil_temp")),
    "no-speed": ("the encoder's speed not exported (every speed field empty)", _emptied("speed")),
    "10hz": ("a logger at 10 Hz (every fifth row of a 50 Hz file)", _at_rate(10.0)),
    "p-step-10kpa": ("pressures on a 10 kPa step (a coarse analogue input)", _pressure_step(1e4)),
    "stuck-p2": ("sensor 2 frozen at its last value for 20 min mid-record", _stuck(2, 20.0)),
    "outage-5min": ("a 5 min logger outage mid-record (its rows missing)", _outage(5.0)),
    "repeated-rows": (
        "2 % of rows written twice and 100 rows out of order (a logger's retries)",
        _repeated(0.02, 100),
    ),
}  # fmt: skip


def make_variant(csv: Path, name: str) -> Path:
    """``csv`` as a logger of variant ``name`` (:data:`VARIANTS`) would have written it,
    beside it as ``<stem>-<name>.csv``; ``csv`` itself for ``name`` None or empty.
    KeyError for an unknown name or a column the file does not have."""
    if not name:
        return csv
    if name not in VARIANTS:
        raise KeyError(f"no variant {name!r} (variants: {', '.join(VARIANTS)})")
    _, change = VARIANTS[name]
    return _write(change(read_log(csv)), csv.with_name(f"{csv.stem}-{name}.csv"))
