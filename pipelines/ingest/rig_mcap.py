"""Friction-rig recordings (contract 3, MCAP) onto the ``/rig/pressure`` timeline.

Reading: ``mcap.reader.make_reader`` with :class:`JsonDecoderFactory`;
``iter_messages(log_time_order=False)`` (twice as fast as ordered), then each topic
sorted by log time. The high-rate topics are decoded in bulk (the JSON payloads joined
as NDJSON and read by polars against the topic's schema); a message that does not fit
its schema is decoded alone and quarantined with its topic and reason, and so is a
NaN or infinite number of the displacement, temperature and step topics.

Alignment: one landed row per ``/rig/pressure`` message (``rig_samples``, partition
``site=rig/hoist=<rig_id>/date=<UTC date>``). Other topics are joined as-of, backward
(the latest value at or before the pressure sample): ``/rig/displacement`` within
``DISPLACEMENT_TOLERANCE_S``, ``/rig/temperature`` within ``TEMPERATURE_TOLERANCE_S``
(older values give null, not a stale number), ``/rig/step`` without limit (a step lasts
until the next one; samples before the first step have a null step). Units to SI.

Refusals: a channel whose schema encoding is not ``jsonschema`` (or whose message
encoding is not ``json``) refuses the file, naming the topic; no ``/rig/info``
message refuses it (no rig_id). Unknown topics are ignored and named in the report.
A truncated recording (the rig stopped mid-write) lands the messages read before the
damage and is reported ``partial`` with the reason.

Row accounting counts ``/rig/pressure`` messages: read = landed + quarantined +
duplicates. Bad messages of the other topics are quarantined too (with their topic)
but are not rows of ``rig_samples``; the report message counts them. A quarantine
row's ``raw`` says where the message is (its index among its topic's messages and its
log time: ``line`` is null in a binary file), then its payload.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import polars as pl
from mcap.decoder import DecoderFactory
from mcap.reader import NonSeekingReader, make_reader
from mcap.records import Schema

from pipelines.ingest.batch import REJECTED_SCHEMA, Batch, Reading, RefusedFile
from pipelines.ingest.field_checks import MAX_PRESSURE_PA
from schemas.names import UnsafeNameError, safe_name
from schemas.tables import RIG_SAMPLES

__all__ = [
    "DISPLACEMENT_TOLERANCE_S",
    "KNOWN_TOPICS",
    "TEMPERATURE_TOLERANCE_S",
    "JsonDecoderFactory",
    "open_mcap",
]

DISPLACEMENT_TOLERANCE_S = 0.02
TEMPERATURE_TOLERANCE_S = 10.0

#: Topic -> polars schema of the fields ingest uses.
KNOWN_TOPICS: dict[str, dict[str, pl.DataType]] = {
    "/rig/info": {
        "rig_id": pl.String(),
        "bore_mm": pl.Float64(),
        "rod_mm": pl.Float64(),
        "stroke_mm": pl.Float64(),
        "moving_mass_kg": pl.Float64(),
        "oil": pl.String(),
    },
    "/rig/pressure": {"p_rodless_mpa": pl.Float64(), "p_rod_mpa": pl.Float64()},
    "/rig/displacement": {"x_mm": pl.Float64()},
    "/rig/temperature": {"oil_temp_c": pl.Float64()},
    "/rig/step": {
        "step": pl.Int64(),
        "pressure_setpoint_mpa": pl.Float64(),
        "velocity_setpoint_mm_s": pl.Float64(),
    },
}


class JsonDecoderFactory(DecoderFactory):
    """Decodes ``json`` messages (contract 3) to Python objects."""

    def decoder_for(
        self, message_encoding: str, schema: Schema | None
    ) -> Callable[[bytes], Any] | None:
        if message_encoding != "json":
            return None
        return json.loads


class _Collected:
    def __init__(self) -> None:
        self.times: dict[str, list[int]] = {t: [] for t in KNOWN_TOPICS}
        self.payloads: dict[str, list[bytes]] = {t: [] for t in KNOWN_TOPICS}
        self.unknown: Counter[str] = Counter()


def open_mcap(path: Path) -> Reading:
    """Read a rig recording; all of it is decoded before anything is landed."""
    collected = _Collected()
    partial = None
    try:
        with path.open("rb") as handle:
            reader = make_reader(handle, decoder_factories=[JsonDecoderFactory()])
            _collect(path, reader.iter_messages(log_time_order=False), collected)
    except RefusedFile:
        raise
    except Exception as exc:  # truncated / corrupt: salvage the complete prefix
        collected = _Collected()
        try:
            with path.open("rb") as handle:
                reader = NonSeekingReader(handle, decoder_factories=[JsonDecoderFactory()])
                _collect(path, reader.iter_messages(log_time_order=False), collected)
        except RefusedFile:
            raise
        except Exception as salvage:
            partial = (
                f"recording truncated or damaged ({type(salvage).__name__}: {salvage}); "
                "landed the messages before it"
            )
        if partial is None:
            partial = f"summary unreadable ({type(exc).__name__}: {exc}); read sequentially"
        if not any(collected.times.values()):
            why = partial.removesuffix("; landed the messages before it")
            raise RefusedFile(f"{path}: no readable MCAP messages ({why})") from None
    return _reading(path, collected, partial)


def _collect(path: Path, messages, collected: _Collected) -> None:
    checked: set[int] = set()
    for schema, channel, message in messages:
        topic = channel.topic
        if channel.id not in checked:
            encoding = schema.encoding if schema is not None else "(no schema)"
            if encoding != "jsonschema":
                raise RefusedFile(
                    f"{path}: topic {topic}: schema encoding {encoding!r}, expected 'jsonschema'"
                )
            if channel.message_encoding != "json":
                raise RefusedFile(
                    f"{path}: topic {topic}: message encoding {channel.message_encoding!r}, "
                    "expected 'json'"
                )
            checked.add(channel.id)
        if topic not in KNOWN_TOPICS:
            collected.unknown[topic] += 1
            continue
        collected.times[topic].append(message.log_time)
        collected.payloads[topic].append(message.data)


def _decode(
    topic: str, times: list[int], payloads: list[bytes]
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """Decoded messages of one topic (sorted by time, ``_row`` = file order) and rejects."""
    schema = KNOWN_TOPICS[topic]
    base = pl.DataFrame(
        {"_row": range(len(times)), "_ns": times}, schema={"_row": pl.Int64, "_ns": pl.Int64}
    )
    fields = None
    joined = b"\n".join(payloads)
    if payloads and joined.count(b"\n") == len(payloads) - 1:
        try:
            fields = pl.read_ndjson(joined, schema=schema)
        except Exception:
            fields = None
    if fields is None:
        rows = []
        for data in payloads:
            try:
                value = json.loads(data)
            except ValueError:
                value = None
            rows.append(value if isinstance(value, dict) else {})
        fields = pl.DataFrame(
            [{k: _typed(r.get(k), dtype) for k, dtype in schema.items()} for r in rows],
            schema=schema,
            orient="row",
        )
    frame = pl.concat([base, fields], how="horizontal")
    missing = pl.concat_str(
        [pl.when(_invalid(topic, k, dtype)).then(pl.lit(k)) for k, dtype in schema.items()],
        separator=", ",
        ignore_nulls=True,
    )
    frame = frame.with_columns(
        pl.when(missing != "")
        .then(pl.lit(f"message does not match the {topic} schema: missing or invalid ") + missing)
        .alias("_reason")
    )
    bad = frame.filter(pl.col("_reason").is_not_null())
    rejected = pl.DataFrame(
        {
            "row": bad["_row"],
            "topic": topic,
            "reason": bad["_reason"],
            "raw": [_located(i, times[i], payloads[i]) for i in bad["_row"]],
        },
        schema=REJECTED_SCHEMA,
    )
    good = frame.filter(pl.col("_reason").is_null()).drop("_reason")
    good = good.with_columns(
        pl.from_epoch("_ns", time_unit="ns")
        .dt.cast_time_unit("us")
        .dt.replace_time_zone("UTC")
        .alias("time_utc")
    ).sort("_ns", "_row")
    return good, rejected


#: Topics whose numbers are screened after decoding (pressures: NaN, negative, above
#: 60 MPa, each with its reason) or not used as numbers by ingest (``/rig/info``, whose
#: geometry calibrate checks): a non-finite value there is not a schema mismatch.
_SCREENED_LATER = ("/rig/pressure", "/rig/info")


def _invalid(topic: str, key: str, dtype: pl.DataType) -> pl.Expr:
    """Whether ``key`` is missing or invalid: null, or (the other topics' numbers) NaN
    or infinite, which JSON has no words for and a sample cannot be."""
    if dtype != pl.Float64 or topic in _SCREENED_LATER:
        return pl.col(key).is_null()
    return pl.col(key).is_null() | ~pl.col(key).is_finite()


_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)


def _located(row: int, log_time_ns: int, payload: bytes) -> str:
    """A quarantined message's raw text: where it is in the recording (its 0-based index
    among its topic's messages, its log time), then its payload, as a TDMS sample's."""
    at = (_EPOCH + dt.timedelta(microseconds=log_time_ns // 1000)).isoformat()
    return f"message {row}, log time {at}: {payload.decode('utf-8', errors='replace')}"


def _typed(value: Any, dtype: pl.DataType) -> Any:
    """``value`` if it has the JSON type the topic schema asks for, else None."""
    if isinstance(value, bool):
        return None
    if dtype == pl.String:
        return value if isinstance(value, str) else None
    if dtype == pl.Int64:
        return value if isinstance(value, int) else None
    return float(value) if isinstance(value, int | float) else None


def _reading(path: Path, collected: _Collected, partial: str | None) -> Reading:
    decoded = {t: _decode(t, collected.times[t], collected.payloads[t]) for t in KNOWN_TOPICS}
    rig_id = _rig_id(path, *decoded["/rig/info"])
    pressure, rejected_p = decoded["/rig/pressure"]
    aligned = _aligned(_screened_pressure(pressure), decoded).with_columns(
        pl.lit(rig_id).alias("rig_id")
    )
    bad = aligned.filter(pl.col("_reason").is_not_null())
    payloads, times = collected.payloads["/rig/pressure"], collected.times["/rig/pressure"]

    def raw_of(rows: list[int]) -> list[str | None]:
        return [_located(r, times[r], payloads[r]) for r in rows]

    rejected = pl.concat(
        [
            rejected_p,
            pl.DataFrame(
                {
                    "row": bad["_row"],
                    "topic": "/rig/pressure",
                    "reason": bad["_reason"],
                    "raw": raw_of(bad["_row"].to_list()),
                },
                schema=REJECTED_SCHEMA,
            ),
            *(decoded[t][1] for t in KNOWN_TOPICS if t != "/rig/pressure"),
        ]
    )
    notes = _notes(collected, rejected)
    info = decoded["/rig/info"][0].row(0, named=True)
    problem = rig_geometry_problem(info["bore_mm"], info["rod_mm"], info["moving_mass_kg"])
    if problem is not None:
        notes.append(f"topic /rig/info: {problem}: ropeload calibrate will refuse this recording")
    names = [f.name for f in RIG_SAMPLES if f.name != "source_sha256"]
    good = aligned.filter(pl.col("_reason").is_null()).select(*names, "_row")
    return Reading(
        table="rig_samples",
        site="rig",
        hoist=rig_id,
        batches=iter([Batch(samples=good, rejected=rejected, raw_of=raw_of)]),
        notes=notes,
        partial=partial,
    )


def rig_geometry_problem(bore_mm: float, rod_mm: float, moving_mass_kg: float) -> str | None:
    """What makes a rig's ``/rig/info`` geometry unusable for the friction fit (the force
    balance divides by the bore's area and needs a positive annulus), or None. Ingest
    says it (the samples land, they are measurements); ``ropeload calibrate`` refuses
    such a recording (:func:`pipelines.calibrate_inputs.read_rig_info`).

    >>> rig_geometry_problem(100.0, 60.0, 25.0) is None
    True
    >>> rig_geometry_problem(100.0, 120.0, 25.0)
    'rod_mm 120.0: not at least 0 and below bore_mm 100.0'
    """
    if not (math.isfinite(bore_mm) and bore_mm > 0):
        return f"bore_mm {bore_mm!r}: not a positive finite number"
    if not (math.isfinite(rod_mm) and 0 <= rod_mm < bore_mm):
        return f"rod_mm {rod_mm!r}: not at least 0 and below bore_mm {bore_mm!r}"
    if not (math.isfinite(moving_mass_kg) and moving_mass_kg >= 0):
        return f"moving_mass_kg {moving_mass_kg!r}: not a non-negative finite number"
    return None


def _rig_id(path: Path, info: pl.DataFrame, rejected: pl.DataFrame) -> str:
    """The rig id of the first valid ``/rig/info`` message (refused when none or unsafe;
    the first invalid one's reason said)."""
    if info.height == 0:
        why = f" ({rejected['reason'][0]})" if rejected.height else ""
        raise RefusedFile(f"{path}: topic /rig/info: no valid message, so no rig_id{why}")
    try:  # the rig id becomes a lake folder (hoist=<rig_id>): a safe name only
        return safe_name(info["rig_id"][0], key="rig_id", source=f"{path}: topic /rig/info")
    except UnsafeNameError as exc:
        raise RefusedFile(str(exc)) from None


def _screened_pressure(pressure: pl.DataFrame) -> pl.DataFrame:
    """The pressures in Pa with ``_reason`` set where one is not a number (NaN, which
    polars orders above every number), negative or above 60 MPa."""
    samples = pressure.select(
        "time_utc",
        "_row",
        (pl.col("p_rodless_mpa") * 1e6).alias("p_rodless_pa"),
        (pl.col("p_rod_mpa") * 1e6).alias("p_rod_pa"),
    )
    reasons = []
    for column in ("p_rodless_pa", "p_rod_pa"):
        name = column.removesuffix("_pa")
        reasons.append(pl.when(pl.col(column).is_nan()).then(pl.lit(f"not a number ({name})")))
        reasons.append(
            pl.when(pl.col(column) < 0).then(pl.lit(f"negative absolute pressure ({name})"))
        )
        reasons.append(
            pl.when(pl.col(column) > MAX_PRESSURE_PA).then(
                pl.lit(f"pressure above 60 MPa ({name})")
            )
        )
    return samples.with_columns(pl.coalesce(*reasons).alias("_reason"))


def _aligned(
    samples: pl.DataFrame, decoded: dict[str, tuple[pl.DataFrame, pl.DataFrame]]
) -> pl.DataFrame:
    """One row per pressure message with the latest step, and the latest displacement and
    temperature within their tolerances (SI)."""
    displacement = decoded["/rig/displacement"][0].select(
        "time_utc", (pl.col("x_mm") * 1e-3).alias("x_m")
    )
    temperature = decoded["/rig/temperature"][0].select("time_utc", "oil_temp_c")
    steps = decoded["/rig/step"][0].select(
        "time_utc",
        pl.col("step").cast(pl.Int32),
        (pl.col("pressure_setpoint_mpa") * 1e6).alias("pressure_setpoint_pa"),
        (pl.col("velocity_setpoint_mm_s") * 1e-3).alias("velocity_setpoint_m_s"),
    )
    return (
        samples.sort("time_utc")
        .join_asof(steps.unique("time_utc", keep="last", maintain_order=True), on="time_utc")
        .join_asof(
            displacement.unique("time_utc", keep="last", maintain_order=True),
            on="time_utc",
            tolerance=f"{round(DISPLACEMENT_TOLERANCE_S * 1e6)}us",
        )
        .join_asof(
            temperature.unique("time_utc", keep="last", maintain_order=True),
            on="time_utc",
            tolerance=f"{round(TEMPERATURE_TOLERANCE_S * 1e6)}us",
        )
    )


def _notes(collected: _Collected, rejected: pl.DataFrame) -> list[str]:
    """What the reading ignored: unknown topics, invalid messages of the other topics."""
    notes = []
    if collected.unknown:
        listed = ", ".join(f"{t} ({n} messages)" for t, n in sorted(collected.unknown.items()))
        notes.append(f"ignored unknown topic(s): {listed}")
    auxiliary = rejected.filter(pl.col("topic") != "/rig/pressure").height
    if auxiliary:
        notes.append(f"{auxiliary} invalid message(s) of other topics quarantined (not rows)")
    return notes
