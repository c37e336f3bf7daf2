"""Writers for field logs in the formats mines export (contract sections 1a and 1b).

:func:`write_csv`
    LabVIEW "write delimited spreadsheet" CSV: ``#`` header lines (site, hoist,
    timezone, sample_rate_hz, units), then ``timestamp,p1..p4,x1..x4,depth,speed,oil_temp``
    with timestamps in the hoist's local time (or ISO 8601 with offset), values in the
    header's units, a chosen delimiter and decimal separator, and a chosen missing-value
    token. Options produce the awkward variants ingest must handle (semicolon with decimal
    comma, bar/kPa, ``-9999`` sentinels, a last line cut off mid-write).
:func:`write_tdms`
    LabVIEW TDMS: group ``hoist``, one channel per CSV column (``timestamp`` included, as
    the real sample times), waveform properties ``wf_start_time``, ``wf_increment``,
    ``wf_start_offset``, file properties ``site``, ``hoist``, ``timezone`` and a
    per-channel ``unit_string``.

Input is a sensor-level frame in SI: ``time_utc`` (UTC datetime) and ``p{i}_pa``,
optionally ``x{i}_m``, ``depth_m``, ``speed_m_s``, ``oil_temp_c``. Values are converted
from SI once, with polars expressions (a 100 Hz hoist-day, 8.64 M rows, writes in a few
seconds); the printed decimals set the quantisation (:data:`DECIMALS`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Literal

import numpy as np
import polars as pl
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

from schemas.hoist import HoistDescription

__all__ = [
    "CSV_COLUMNS",
    "DECIMALS",
    "DEFAULT_UNITS",
    "UNIT_FACTORS",
    "csv_header",
    "write_csv",
    "write_tdms",
]

#: Contract 1a column -> SI column of the sensor-level frame.
CSV_COLUMNS: dict[str, str] = {
    **{f"p{i}": f"p{i}_pa" for i in range(1, 5)},
    **{f"x{i}": f"x{i}_m" for i in range(1, 5)},
    "depth": "depth_m",
    "speed": "speed_m_s",
    "oil_temp": "oil_temp_c",
}

#: Units of the ``# units:`` line by quantity (contract 1a example).
DEFAULT_UNITS: dict[str, str] = {
    "p": "MPa",
    "x": "mm",
    "depth": "m",
    "speed": "m/s",
    "oil_temp": "degC",
}

#: SI value = file value x factor, per quantity and unit.
UNIT_FACTORS: dict[str, dict[str, float]] = {
    "p": {"MPa": 1e6, "bar": 1e5, "kPa": 1e3},
    "x": {"mm": 1e-3, "m": 1.0},
    "depth": {"m": 1.0},
    "speed": {"m/s": 1.0},
    "oil_temp": {"degC": 1.0},
}

#: Printed decimals per quantity and unit: the file's quantisation step is 10^-decimals
#: of the unit (0.001 MPa = 0.01 bar = 1 kPa; 0.1 mm = 0.0001 m).
DECIMALS: dict[str, dict[str, int]] = {
    "p": {"MPa": 3, "bar": 2, "kPa": 0},
    "x": {"mm": 1, "m": 4},
    "depth": {"m": 2},
    "speed": {"m/s": 3},
    "oil_temp": {"degC": 1},
}

MissingToken = Literal["", "NaN", "nan", "-9999", "-9999.0"]


def _quantity(column: str) -> str:
    return column.rstrip("1234") if column[0] in "px" and column[-1].isdigit() else column


def _resolve_units(units: Mapping[str, str] | None) -> dict[str, str]:
    resolved = dict(DEFAULT_UNITS)
    for quantity, unit in (units or {}).items():
        if quantity not in UNIT_FACTORS:
            raise ValueError(f"units: unknown quantity {quantity!r}; use {sorted(UNIT_FACTORS)}")
        if unit not in UNIT_FACTORS[quantity]:
            raise ValueError(
                f"units: {quantity}={unit!r} is not allowed; use one of "
                f"{sorted(UNIT_FACTORS[quantity])}"
            )
        resolved[quantity] = unit
    return resolved


def _present_columns(frame: pl.DataFrame) -> list[str]:
    if "time_utc" not in frame.columns:
        raise ValueError("frame: needs a 'time_utc' column (UTC datetimes)")
    missing_p = [si for col, si in CSV_COLUMNS.items() if col[0] == "p" and si not in frame]
    if missing_p:
        raise ValueError(f"frame: pressure columns {missing_p} are required")
    return [col for col, si in CSV_COLUMNS.items() if si in frame.columns]


def csv_header(
    *,
    site: str,
    hoist: str,
    timezone: str,
    sample_rate_hz: float,
    units: Mapping[str, str],
    present: Sequence[str],
) -> str:
    """The ``#`` header lines of contract 1a (each ending in a newline).

    >>> print(csv_header(site="s", hoist="h", timezone="UTC", sample_rate_hz=100,
    ...                  units=DEFAULT_UNITS, present=["p1", "depth"]), end="")
    # site: s
    # hoist: h
    # timezone: UTC
    # sample_rate_hz: 100
    # units: p=MPa, depth=m
    """
    quantities = list(dict.fromkeys(_quantity(c) for c in present))
    unit_text = ", ".join(f"{q}={units[q]}" for q in quantities)
    rate = f"{sample_rate_hz:g}"
    return (
        f"# site: {site}\n# hoist: {hoist}\n# timezone: {timezone}\n"
        f"# sample_rate_hz: {rate}\n# units: {unit_text}\n"
    )


def _value_expr(column: str, units: Mapping[str, str], missing: str, decimal: str) -> pl.Expr:
    quantity = _quantity(column)
    unit = units[quantity]
    factor = UNIT_FACTORS[quantity][unit]
    decimals = DECIMALS[quantity][unit]
    value = pl.col(CSV_COLUMNS[column]).cast(pl.Float64)
    value = pl.when(value.is_nan()).then(None).otherwise(value)
    text = (value / factor).round(decimals)
    if decimals == 0:
        text = text.cast(pl.Int64).cast(pl.String)
    else:
        text = text.cast(pl.String)
        if decimal != ".":
            text = text.str.replace(".", decimal, literal=True)
    return text.fill_null(missing).alias(column)


def _timestamp_expr(timezone: str, with_offset: bool) -> pl.Expr:
    local = pl.col("time_utc").dt.convert_time_zone(timezone)
    fmt = "%Y-%m-%dT%H:%M:%S%.3f%:z" if with_offset else "%Y-%m-%d %H:%M:%S%.3f"
    return local.dt.strftime(fmt).alias("timestamp")


def write_csv(
    frame: pl.DataFrame,
    path: str | Path,
    *,
    hoist: HoistDescription,
    units: Mapping[str, str] | None = None,
    delimiter: Literal[",", ";", "\t"] = ",",
    decimal: Literal[".", ","] = ".",
    timezone: str | None = None,
    with_offset: bool = False,
    missing: MissingToken = "",
    sample_rate_hz: float = 100.0,
    header_timezone: bool = True,
    cut_last_line: bool = False,
) -> Path:
    """Write a sensor-level SI frame as a contract-1a CSV field log.

    Longer than 80 lines on purpose: most of it is this docstring (every parameter and
    the result documented); the code is 43 lines.

    Parameters
    ----------
    frame : polars.DataFrame
        ``time_utc`` (datetime, UTC) and SI columns ``p{i}_pa`` (required),
        ``x{i}_m``, ``depth_m``, ``speed_m_s``, ``oil_temp_c`` (each written when present).
        NaN or null values are written as ``missing``.
    path : str or Path
        Output file.
    hoist : HoistDescription
        Supplies ``site``, ``hoist`` name and (default) ``timezone`` for the header.
    units : mapping, optional
        ``{"p": "MPa"|"bar"|"kPa", "x": "mm"|"m"}``; default MPa and mm.
    delimiter : {",", ";", "\\t"}
        Field separator.
    decimal : {".", ","}
        Decimal separator; ``","`` only with ``";"`` or tab (contract 1a).
    timezone : str, optional
        IANA zone of the timestamps and the header; default the hoist's.
    with_offset : bool
        ISO 8601 timestamps with a UTC offset (``2026-03-02T06:00:00.000+08:00``)
        instead of naive local time.
    missing : {"", "NaN", "nan", "-9999", "-9999.0"}
        Token for missing values.
    sample_rate_hz : float
        Nominal rate for the header.
    header_timezone : bool
        Write the ``# timezone:`` line (contract: optional, defaults to UTC).
    cut_last_line : bool
        Cut the file in the middle of its last data line, as a log that is still
        being written (contract 1: "the newest one may still be growing").

    Returns
    -------
    Path
        The written file.
    """
    if decimal == "," and delimiter == ",":
        raise ValueError("decimal ',' needs delimiter ';' or tab (contract 1a)")
    path = Path(path)
    resolved = _resolve_units(units)
    present = _present_columns(frame)
    tz = timezone or hoist.hoist.timezone
    header = csv_header(
        site=hoist.hoist.site,
        hoist=hoist.hoist.name,
        timezone=tz,
        sample_rate_hz=sample_rate_hz,
        units=resolved,
        present=present,
    )
    if not header_timezone:
        header = "".join(
            line + "\n" for line in header.splitlines() if not line.startswith("# timezone")
        )
    text = frame.select(
        _timestamp_expr(tz, with_offset),
        *[_value_expr(c, resolved, missing, decimal) for c in present],
    )
    with path.open("wb") as handle:
        handle.write(header.encode())
        text.write_csv(handle, separator=delimiter, quote_style="never")
    if cut_last_line and text.height > 0:
        _cut_last_line(path)
    return path


def _cut_last_line(path: Path) -> None:
    """Truncate ``path`` halfway through its last line (no trailing newline left)."""
    size = path.stat().st_size
    with path.open("r+b") as handle:
        handle.seek(max(size - 4096, 0))
        tail = handle.read()
        start = tail.rstrip(b"\n").rfind(b"\n") + 1  # first byte of the last line
        line_length = len(tail.rstrip(b"\n")) - start
        handle.truncate(size - len(tail) + start + max(line_length // 2, 1))


def write_tdms(
    frame: pl.DataFrame,
    path: str | Path,
    *,
    hoist: HoistDescription,
    units: Mapping[str, str] | None = None,
    timezone: str | None = None,
    sample_rate_hz: float = 100.0,
    omit_properties: Sequence[str] = (),
) -> Path:
    """Write a sensor-level SI frame as a contract-1b TDMS field log.

    Group ``hoist`` holds one channel per CSV column present: ``timestamp``
    (``datetime64[us]``, UTC, the real sample times including jitter and gaps) and the
    values in ``units`` (quantised like the CSV, NaN where missing). Every channel
    carries ``unit_string`` and the waveform properties ``wf_start_time`` (first sample,
    UTC), ``wf_increment`` (1 / ``sample_rate_hz``, nominal) and ``wf_start_offset``
    (0.0). The root carries ``site``, ``hoist``, ``timezone``, ``sample_rate_hz``.

    ``omit_properties`` leaves out the named properties (e.g. ``["wf_increment"]``) to
    produce the defective files ingest must refuse or repair.
    """
    path = Path(path)
    resolved = _resolve_units(units)
    present = _present_columns(frame)
    tz = timezone or hoist.hoist.timezone
    omit = set(omit_properties)
    t_us = frame["time_utc"].dt.epoch("us").to_numpy()
    start = np.datetime64(int(t_us[0]), "us") if t_us.size else np.datetime64(0, "us")
    wave = {
        "wf_start_time": start,
        "wf_increment": 1.0 / sample_rate_hz,
        "wf_start_offset": 0.0,
    }
    root_props = {
        "site": hoist.hoist.site,
        "hoist": hoist.hoist.name,
        "timezone": tz,
        "sample_rate_hz": float(sample_rate_hz),
    }
    channels = [
        ChannelObject(
            "hoist",
            "timestamp",
            t_us.astype("datetime64[us]"),
            properties=_keep({"unit_string": "UTC", **wave}, omit),
        )
    ]
    values = frame.select(
        [
            (
                pl.col(CSV_COLUMNS[c]).cast(pl.Float64)
                / UNIT_FACTORS[_quantity(c)][resolved[_quantity(c)]]
            )
            .round(DECIMALS[_quantity(c)][resolved[_quantity(c)]])
            .alias(c)
            for c in present
        ]
    )
    for column in present:
        data = values[column].fill_null(np.nan).to_numpy().astype(np.float64)
        unit = resolved[_quantity(column)]
        channels.append(
            ChannelObject(
                "hoist", column, data, properties=_keep({"unit_string": unit, **wave}, omit)
            )
        )
    with TdmsWriter(path) as writer:
        writer.write_segment([RootObject(_keep(root_props, omit)), GroupObject("hoist"), *channels])
    return path


def _keep(properties: dict[str, object], omit: set[str]) -> dict[str, object]:
    return {k: v for k, v in properties.items() if k not in omit}
