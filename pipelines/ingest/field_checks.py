"""Field-log channels and the checks every field sample passes, for CSV and TDMS alike.

Channels (contract 1a/1b) map to SI columns of :data:`schemas.tables.FIELD_SAMPLES`:

========== ============== ===========================================
raw        landed column  unit in the raw file
========== ============== ===========================================
p1..p4     p{i}_pa        pressure (MPa, bar, kPa, Pa) - required
x1..x4     x{i}_m         length (mm, m) - optional
depth      depth_m        length, default m - optional
speed      speed_m_s      velocity, default m/s - optional
oil_temp   oil_temp_c     degC - optional
========== ============== ===========================================

Missing values (empty field, ``NaN``/``nan``, ``-9999``/``-9999.0``) become null.
A sample is quarantined with the first reason that applies, in this order:
unparsable timestamp, local time in a daylight-saving gap, a logger clock that stepped
back (:mod:`.clock`: "the logger clock stepped back 30.0 s at line N: time before the
latest already read"; such a row without another fault is an exact duplicate where it
equals a landed sample; a lone time ahead of both neighbours is that row's own fault),
unparsable value (per channel), negative absolute pressure,
pressure above 60 MPa, depth outside the shaft, a piston beyond a whole stroke from
mid-stroke, a speed beyond twice the winder's maximum, an oil temperature outside
:data:`OIL_TEMP_LIMITS_C` (:class:`FieldLimits`: a malformed number that parses, e.g.
``1e5`` in an x column, is 100 m of a 400 mm stroke).

Depth outside the shaft: with a hoist description the landed range is
``[-DEPTH_MARGIN_M, shaft depth + DEPTH_MARGIN_M]`` (overtravel and encoder slack);
without one only ``depth < -DEPTH_MARGIN_M`` is impossible, since the shaft depth is
unknown; the piston's and the speed's limits, likewise, need the description's stroke and
winder. The stroke is counted whole either way from mid-stroke (the transducer's zero
may be off mid-stroke, not by a stroke), the speed to twice the winder's ``max_speed``
(an overspeed trip acts at ~1.1 x). ``ropeload ingest --hoist FILE`` gives ingest the descriptions
(:func:`hoist_lookup_from_files`); nightly and backfill give each hoist's own. Samples
landed without one keep every value; a run, its sanity check and discovery, which have the
description, read a value beyond its limits as not logged (:func:`within_limits`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from schemas.hoist import HoistDescription, load_hoist
from schemas.quantities import unit_factor

__all__ = [
    "CHANNELS",
    "DEPTH_MARGIN_M",
    "MAX_PRESSURE_PA",
    "OIL_TEMP_LIMITS_C",
    "REASON_CONFLICT",
    "REASON_DST_GAP",
    "REASON_FIELD_COUNT",
    "REASON_NON_UTF8",
    "REASON_TIMESTAMP",
    "Channel",
    "FieldLimits",
    "ForeignHoistError",
    "HoistLookup",
    "depth_misfit",
    "field_limits",
    "hoist_lookup_from_files",
    "physical_reason",
    "to_si",
    "unit_to_si",
    "unknown_beyond_limits",
    "within_limits",
]

#: Pressure above which a sensor reading is impossible (contract 1a) [Pa].
MAX_PRESSURE_PA = 60e6
#: Tolerance around the shaft for the depth check [m].
DEPTH_MARGIN_M = 10.0

REASON_FIELD_COUNT = "wrong field count"
REASON_NON_UTF8 = "non-UTF-8 bytes"
REASON_TIMESTAMP = "unparsable timestamp"
REASON_DST_GAP = "local time in daylight-saving gap"
REASON_CONFLICT = "conflicts with landed sample"

HoistLookup = Callable[[str, str], HoistDescription | None]


class ForeignHoistError(ValueError):
    """Raised by a :data:`HoistLookup` for a file whose header names a hoist its caller
    does not take here (a file in another hoist's incoming folder): ingest refuses it."""


@dataclass(frozen=True)
class Channel:
    """One raw channel: its landed SI column, the unit key of the ``units`` line, dimension."""

    raw: str
    column: str
    unit_key: str
    dimension: str
    default_unit: str | None

    @property
    def required(self) -> bool:
        return self.unit_key == "p"


CHANNELS: dict[str, Channel] = {
    **{f"p{i}": Channel(f"p{i}", f"p{i}_pa", "p", "pressure", None) for i in range(1, 5)},
    **{f"x{i}": Channel(f"x{i}", f"x{i}_m", "x", "length", None) for i in range(1, 5)},
    "depth": Channel("depth", "depth_m", "depth", "length", "m"),
    "speed": Channel("speed", "speed_m_s", "speed", "velocity", "m/s"),
    "oil_temp": Channel("oil_temp", "oil_temp_c", "oil_temp", "temperature", "degC"),
}

_SENTINEL = -9999.0


#: Temperature units given as an offset from degC (the landed oil_temp_c).
_TEMPERATURE_OFFSETS = {"K": -273.15}


def unit_to_si(unit: str, channel: Channel) -> tuple[float, float]:
    """(factor, offset) that take ``channel``'s values in ``unit`` to its landed column
    (:func:`to_si`): a factor to SI, and for a temperature in kelvin the offset to degC.
    Raises :class:`schemas.quantities.QuantityError` for a unit of another dimension or
    none known. The one conversion of CSV ``units`` lines and TDMS ``unit_string``s.

    >>> unit_to_si("bar", CHANNELS["p1"]), unit_to_si("K", CHANNELS["oil_temp"])
    ((100000.0, 0.0), (1.0, -273.15))
    """
    if channel.dimension == "temperature" and unit in _TEMPERATURE_OFFSETS:
        return 1.0, _TEMPERATURE_OFFSETS[unit]
    return unit_factor(unit, channel.dimension), 0.0


def to_si(value: pl.Expr, factor: float, offset: float = 0.0) -> pl.Expr:
    """Float values with sentinels (NaN, -9999) as null, scaled to SI."""
    cleaned = pl.when(value.is_nan() | (value == _SENTINEL)).then(None).otherwise(value)
    scaled = cleaned * factor if factor != 1.0 else cleaned
    return scaled + offset if offset else scaled


def hoist_lookup_from_files(paths: Sequence[str | Path]) -> HoistLookup | None:
    """A ``hoist_lookup`` over hoist description files, by their ``[hoist] site``/``name``.

    ``None`` for no files. Raises :class:`schemas.hoist.HoistDescriptionError` (naming
    the file and key) for an invalid description, and ``ValueError`` when two files
    describe the same hoist.
    """
    if not paths:
        return None
    by_key: dict[tuple[str, str], tuple[Path, HoistDescription]] = {}
    for path in paths:
        description = load_hoist(path)
        key = (description.hoist.site, description.hoist.name)
        if key in by_key:
            raise ValueError(
                f"{path}: describes {key[0]}/{key[1]}, as {by_key[key][0]} does: one file per hoist"
            )
        by_key[key] = (Path(path), description)

    def lookup(site: str, hoist: str) -> HoistDescription | None:
        found = by_key.get((site, hoist))
        return found[1] if found is not None else None

    return lookup


#: An oil temperature outside this range is not the hoist's oil's [degC] (a mineral
#: hydraulic oil is solid below its pour point, ~-30 degC for ISO VG46, and flashes
#: above ~220 degC): a logger's fault or a malformed number.
OIL_TEMP_LIMITS_C = (-60.0, 200.0)


@dataclass(frozen=True)
class FieldLimits:
    """The landed range of each checked channel (SI; the module docstring)."""

    depth_m: tuple[float, float]
    piston_x_m: float = float("inf")  # |x| at most
    speed_m_s: float = float("inf")  # |speed| at most
    oil_temp_c: tuple[float, float] = OIL_TEMP_LIMITS_C


def field_limits(hoist: HoistDescription | None) -> FieldLimits:
    """The landed ranges for a hoist's samples, or for a hoist not described (see the
    module docstring).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> limits = field_limits(load_hoist(EXAMPLE_HOIST))
    >>> limits.depth_m[1], limits.piston_x_m, limits.speed_m_s
    (630.0, 0.4, 20.0)
    >>> field_limits(None).piston_x_m
    inf
    """
    if hoist is None:
        return FieldLimits(depth_m=(-DEPTH_MARGIN_M, float("inf")))
    return FieldLimits(
        depth_m=(-DEPTH_MARGIN_M, hoist.shaft.depth_m + DEPTH_MARGIN_M),
        piston_x_m=hoist.cylinders.stroke_m,
        speed_m_s=2.0 * hoist.winder.max_speed_m_s,
    )


def _beyond_limits(columns: Sequence[str], limits: FieldLimits) -> dict[str, pl.Expr]:
    """Per checked channel of ``columns`` (depth, pistons, speed): true where its value
    is beyond ``limits`` (an infinity always: a TDMS float can hold one)."""
    beyond: dict[str, pl.Expr] = {}
    if "depth_m" in columns:
        low, high = limits.depth_m
        depth = pl.col("depth_m")
        beyond["depth_m"] = (depth < low) | (depth > high) | depth.is_infinite()
    for c in (c for c in columns if c.startswith("x") and c.endswith("_m")):
        beyond[c] = (pl.col(c).abs() > limits.piston_x_m) | pl.col(c).is_infinite()
    if "speed_m_s" in columns:
        speed = pl.col("speed_m_s")
        beyond["speed_m_s"] = (speed.abs() > limits.speed_m_s) | speed.is_infinite()
    return beyond


def unknown_beyond_limits(columns: Sequence[str], limits: FieldLimits) -> list[pl.Expr]:
    """Each checked channel of ``columns`` with its values beyond ``limits`` read as not
    logged (null): what a run reads of samples landed without the hoist's description
    (``ropeload ingest`` without ``--hoist`` checks the depth against the pithead only
    and the pistons and the speed not at all), whose impossible values the description
    now shows (a piston 100 m out of its cylinder).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> frame = pl.DataFrame({"x1_m": [0.01, 100.0], "speed_m_s": [1e300, 2.0]})
    >>> limits = field_limits(load_hoist(EXAMPLE_HOIST))
    >>> frame.with_columns(unknown_beyond_limits(frame.columns, limits)).rows()
    [(0.01, None), (None, 2.0)]
    """
    return [
        pl.when(outside).then(None).otherwise(pl.col(c)).alias(c)
        for c, outside in _beyond_limits(columns, limits).items()
    ]


#: A record whose landed depth lies outside the described shaft for more than this share
#: of its samples (and :data:`DEPTH_MISFIT_MIN_SAMPLES`) is not this description's: a
#: logger's glitch is a sample or a few, while a shaft described too short puts every
#: visit to the deep positions outside it (a probe's 400 m shaft for a 620 m one: 18 %).
DEPTH_MISFIT_SHARE = 0.01
DEPTH_MISFIT_MIN_SAMPLES = 100


def depth_misfit(samples: pl.LazyFrame, hoist: HoistDescription) -> str | None:
    """Why the landed depth of ``samples`` does not fit the ``hoist``'s shaft, or None.

    A run reads a depth outside the shaft as not logged (:func:`within_limits`); where
    that is most of a stop's samples, the trips end where the depth leaves the shaft,
    the stops lose their positions and the payloads come out wrong with nothing said (a
    probe: 4.9 t for 2.2 t). So the run is refused instead, naming the key.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)  # a shaft of 620 m
    >>> depth_misfit(pl.LazyFrame({"depth_m": [10.0] * 800 + [900.0] * 200}), hoist)
    'shaft.depth 620 m: 200 of 1000 landed samples have a depth outside it (down to 900.0 m)'
    >>> depth_misfit(pl.LazyFrame({"depth_m": [10.0] * 999 + [900.0]}), hoist) is None
    True
    """
    if "depth_m" not in samples.collect_schema().names():
        return None
    low, high = field_limits(hoist).depth_m
    depth = pl.col("depth_m")
    outside = (depth < low) | (depth > high)
    rows, beyond, deepest = (
        samples.select(
            pl.len(), outside.sum().alias("beyond"), depth.filter(outside).max().alias("deepest")
        )
        .collect()
        .row(0)
    )
    if beyond <= max(DEPTH_MISFIT_MIN_SAMPLES, DEPTH_MISFIT_SHARE * rows):
        return None
    return (
        f"shaft.depth {hoist.shaft.depth_m:g} m: {beyond} of {rows} landed samples have a "
        f"depth outside it (down to {deepest:.1f} m)"
    )


def within_limits(samples: pl.LazyFrame, hoist: HoistDescription) -> pl.LazyFrame:
    """Landed field samples as a run reads them: each value beyond the ``hoist``'s
    description's limits not logged (:func:`unknown_beyond_limits`)."""
    names = samples.collect_schema().names()
    return samples.with_columns(unknown_beyond_limits(names, field_limits(hoist)))


def physical_reason(columns: list[str], limits: FieldLimits) -> list[pl.Expr]:
    """Reason expressions (null when fine) for impossible SI values, in priority order."""
    reasons: list[pl.Expr] = []
    pressures = [c for c in columns if c.startswith("p") and c.endswith("_pa")]
    for c in pressures:
        raw = c.removesuffix("_pa")
        reasons.append(pl.when(pl.col(c) < 0).then(pl.lit(f"negative absolute pressure ({raw})")))
    for c in pressures:
        raw = c.removesuffix("_pa")
        reasons.append(
            pl.when(pl.col(c) > MAX_PRESSURE_PA).then(pl.lit(f"pressure above 60 MPa ({raw})"))
        )
    # an infinity is beyond every limit, an unknown one (inf) too: a TDMS float can hold
    # one (a CSV's is quarantined as unparsable before these)
    beyond = _beyond_limits(columns, limits)
    if "depth_m" in beyond:
        reasons.append(pl.when(beyond["depth_m"]).then(pl.lit("depth outside the shaft")))
    for c in (c for c in beyond if c.startswith("x")):
        reasons.append(
            pl.when(beyond[c]).then(pl.lit(f"piston beyond a stroke from mid-stroke ({c[:-2]})"))
        )
    if "speed_m_s" in beyond:
        reasons.append(
            pl.when(beyond["speed_m_s"]).then(pl.lit("speed above twice the winder's maximum"))
        )
    if "oil_temp_c" in columns:
        low, high = limits.oil_temp_c
        outside = (pl.col("oil_temp_c") < low) | (pl.col("oil_temp_c") > high)
        reasons.append(
            pl.when(outside).then(pl.lit(f"oil temperature outside {low:g}..{high:g} degC"))
        )
    return reasons
