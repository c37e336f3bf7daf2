"""Builders of field logs (CSV, TDMS) and rig recordings (MCAP), good and bad.

Everything is generated from code into a temporary folder, so the corpus is readable
here and no binary files are committed.
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mcap.writer import Writer
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

from schemas.rig_topics import RIG_TOPICS, schema_bytes

__all__ = [
    "COLUMNS",
    "HEADER",
    "csv_file",
    "data_rows",
    "mcap_file",
    "tdms_file",
]

COLUMNS = [
    "timestamp",
    "p1",
    "p2",
    "p3",
    "p4",
    "x1",
    "x2",
    "x3",
    "x4",
    "depth",
    "speed",
    "oil_temp",
]

HEADER = {
    "site": "xuzhou-north",
    "hoist": "main-shaft-1",
    "timezone": "UTC",
    "sample_rate_hz": "100",
    "units": "p=MPa, x=mm, depth=m, speed=m/s, oil_temp=degC",
}


def data_rows(
    n: int,
    *,
    start: dt.datetime = dt.datetime(2026, 3, 2, 6, 0, 0),
    step_ms: int = 10,
    p: float = 4.812,
    fmt: str = "%Y-%m-%d %H:%M:%S.%f",
) -> list[list[str]]:
    """``n`` plausible rows (all channels), 3-decimal milliseconds timestamps."""
    rows = []
    for i in range(n):
        t = start + dt.timedelta(milliseconds=step_ms * i)
        stamp = t.strftime(fmt)[:-3] if fmt.endswith(".%f") else t.strftime(fmt)
        rows.append(
            [
                stamp,
                f"{p:.3f}",
                f"{p - 0.02:.3f}",
                f"{p + 0.02:.3f}",
                f"{p - 0.01:.3f}",
                "12.1",
                "-3.4",
                "0.2",
                "7.9",
                f"{i * 0.5:.2f}",
                "1.000",
                "31.2",
            ]
        )
    return rows


def csv_file(
    path: Path,
    rows: Sequence[Sequence[str] | str],
    *,
    header: dict[str, str] | None = None,
    columns: Sequence[str] = COLUMNS,
    sep: str = ",",
    newline: str = "\n",
    trailing_newline: bool = True,
    bom: bool = False,
) -> Path:
    """A contract-1a CSV; a row given as ``str`` is written verbatim (for broken lines)."""
    head = HEADER if header is None else header
    lines = [f"# {k}: {v}" for k, v in head.items()]
    lines.append(sep.join(columns))
    lines += [r if isinstance(r, str) else sep.join(r) for r in rows]
    text = newline.join(lines) + (newline if trailing_newline else "")
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode())
    return path


def tdms_file(
    path: Path,
    n: int = 100,
    *,
    omit: Sequence[str] = (),
    omit_in: str = "p2",
    start: dt.datetime = dt.datetime(2026, 3, 2, 6, 0, 0),
    p_mpa: float = 4.8,
    properties: dict[str, str] | None = None,
    channel_properties: dict[str, object] | None = None,
    text_in: str | None = None,
    oil_temp: tuple[float, str] | None = None,
    stamps: np.ndarray | None = None,
    segments: str = "one",
) -> Path:
    """A contract-1b TDMS; ``omit`` names waveform properties left out of ``omit_in``,
    ``channel_properties`` replace some of its properties; ``properties`` replace file
    properties (``site``, ``hoist``, ``timezone``); ``text_in`` names a channel written
    as text; ``oil_temp`` (value, unit_string) adds that channel; ``stamps`` adds a
    ``timestamp`` channel of those times. ``segments``: ``"one"``; ``"groups"`` the
    pressures in one segment, the other channels in a second; ``"uneven"`` two segments
    with the pressures cut after 90 % of the samples, the others after 50 %."""
    t0 = np.datetime64(start.replace(tzinfo=None), "us")
    wave = {"wf_start_time": t0, "wf_increment": 0.01, "wf_start_offset": 0.0}
    channels = []
    values = {
        **{f"p{i}": (np.full(n, p_mpa) + 0.001 * i, "MPa") for i in range(1, 5)},
        "depth": (np.linspace(0, 600, n), "m"),
        "speed": (np.full(n, 1.0), "m/s"),
    }
    if oil_temp is not None:
        values["oil_temp"] = (np.full(n, oil_temp[0]), oil_temp[1])
    if text_in == "timestamp":  # a sample-time channel, written as text below
        values["timestamp"] = (np.arange(n, dtype=np.float64), "")
    elif stamps is not None:
        values["timestamp"] = (stamps, "")
    values["p3"][0][5] = -9999.0  # a sentinel
    values["p1"][0][7] = 75.0  # impossible: above 60 MPa
    for name, (data, unit) in values.items():
        props = {"unit_string": unit, **wave}
        if name == omit_in:
            props = {k: v for k, v in props.items() if k not in omit}
            props.update(channel_properties or {})
        if name == text_in:
            data = np.array([f"{v:.3f}" for v in data])
        channels.append((name, data, props))
    file_props = {"site": HEADER["site"], "hoist": "tdms-hoist", "timezone": "UTC"}
    root = RootObject({**file_props, **(properties or {})})
    pressure = {f"p{i}" for i in range(1, 5)}
    if segments == "one":
        cuts = {name: n for name, _, _ in channels}
    elif segments == "groups":  # the pressures first, whole; the rest after
        cuts = {name: (n if name in pressure else 0) for name, _, _ in channels}
    else:
        cuts = {name: (n * 9 // 10 if name in pressure else n // 2) for name, _, _ in channels}
    with TdmsWriter(path) as writer:
        parts = [
            [ChannelObject("hoist", name, data[:cut], properties=props)
             for name, data, props in channels if (cut := cuts[name]) > 0],
            [ChannelObject("hoist", name, data[cuts[name]:], properties=props)
             for name, data, props in channels if cuts[name] < n],
        ]  # fmt: skip
        writer.write_segment([root, GroupObject("hoist"), *parts[0]])
        if parts[1]:
            writer.write_segment([root, GroupObject("hoist"), *parts[1]])
    return path


def mcap_file(
    path: Path,
    *,
    seconds: float = 2.0,
    start_ns: int = 1_772_460_000 * 10**9,
    rig_id: str = "rig-a",
    unknown_topic: bool = False,
    bad_encoding_topic: str | None = None,
    bad_messages: int = 0,
    nan_messages: int = 0,
    bad_displacements: int = 0,
    nan_displacements: int = 0,
    truncate_fraction: float | None = None,
    chunk_size: int = 16 * 1024,
    info: dict | None = None,
) -> Path:
    """A contract-3 rig recording: info, pressure 1 kHz, displacement 500 Hz, temp 1 Hz,
    steps every 0.5 s. Options make it defective (``info``: ``/rig/info`` fields changed,
    a value None leaves the field out)."""
    with path.open("wb") as handle:
        writer = Writer(handle, chunk_size=chunk_size)
        writer.start(profile="", library="ropeload-tests")
        ids = {}
        for topic in RIG_TOPICS:
            encoding = "protobuf" if topic == bad_encoding_topic else "jsonschema"
            schema_id = writer.register_schema(
                name=RIG_TOPICS[topic]["title"], encoding=encoding, data=schema_bytes(topic)
            )
            ids[topic] = writer.register_channel(
                topic=topic, message_encoding="json", schema_id=schema_id
            )
        if unknown_topic:
            schema_id = writer.register_schema(name="x", encoding="jsonschema", data=b"{}")
            ids["/rig/camera"] = writer.register_channel(
                topic="/rig/camera", message_encoding="json", schema_id=schema_id
            )

        def put(topic: str, t_ns: int, payload: dict) -> None:
            data = json.dumps(payload).encode()
            writer.add_message(ids[topic], log_time=t_ns, data=data, publish_time=t_ns)

        described = {
            "rig_id": rig_id,
            "bore_mm": 100,
            "rod_mm": 60,
            "stroke_mm": 400,
            "moving_mass_kg": 12.5,
            "oil": "L-HM46",
            **(info or {}),
        }
        put("/rig/info", start_ns, {k: v for k, v in described.items() if v is not None})
        n = int(seconds * 1000)
        for i in range(n):
            t = start_ns + i * 1_000_000
            if i % 500 == 0:
                put(
                    "/rig/step",
                    t,
                    {
                        "step": i // 500,
                        "pressure_setpoint_mpa": 2.0 + i // 500,
                        "velocity_setpoint_mm_s": 5.0,
                    },
                )
            if i % 1000 == 0:
                put("/rig/temperature", t, {"oil_temp_c": 35.0 + i / 1000})
            if i % 2 == 0:
                x_mm = "far" if i < 2 * bad_displacements else 0.005 * i
                if i < 2 * nan_displacements:  # json.dumps writes NaN
                    x_mm = float("nan")
                put("/rig/displacement", t, {"x_mm": x_mm})
            if unknown_topic and i % 100 == 0:
                put("/rig/camera", t, {"frame": i})
            payload = {"p_rodless_mpa": 2.0 + i // 500 + 0.001 * (i % 7), "p_rod_mpa": 0.5}
            if i < bad_messages:
                payload = {"p_rodless_mpa": "high"}
            elif i < bad_messages + nan_messages:  # json.dumps writes NaN
                payload["p_rodless_mpa"] = float("nan")
            put("/rig/pressure", t + 100_000, payload)
        writer.finish()
    if truncate_fraction is not None:
        data = path.read_bytes()
        path.write_bytes(data[: int(len(data) * truncate_fraction)])
    return path
