"""MCAP recordings of simulated rig runs (contract section 3).

:func:`write_rig_mcap` (public through :mod:`sims.rig`) writes a :class:`RigRecording`
with sensor noise (:class:`RigSensors`) and acquisition jitter, and the awkward
variants the ingest tests need.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.writer import Writer

from schemas.rig_topics import schema_bytes
from sims.rig_design import RigRecording


@dataclass(frozen=True)
class RigSensors:
    """Rig sensor noise and rates (SI). Pressure transmitters 0.05 % of 40 MPa, an LVDT
    with 1 um noise, a Pt100 at 0.05 degC; log-time jitter of the acquisition."""

    pressure_sigma_pa: float = 2e3
    displacement_sigma_m: float = 1e-6
    temperature_sigma_c: float = 0.05
    pressure_rate_hz: float = 1000.0
    displacement_rate_hz: float = 500.0
    temperature_rate_hz: float = 1.0
    jitter_sigma_s: float = 20e-6


def _jittered(t_s: np.ndarray, start_ns: int, sigma_s: float, rng: np.random.Generator):
    nominal = start_ns + np.round(t_s * 1e9).astype(np.int64)
    if sigma_s <= 0 or t_s.size < 2:
        return nominal, nominal
    bound = 0.4 * float(np.min(np.diff(t_s))) * 1e9
    jitter = np.minimum(np.abs(rng.normal(0.0, sigma_s * 1e9, t_s.size)), bound)  # delay
    return nominal + np.round(jitter).astype(np.int64), nominal


def write_rig_mcap(
    path: str | Path,
    recording: RigRecording,
    *,
    start_time_ns: int = 1_772_409_600_000_000_000,  # 2026-03-02 00:00:00 UTC
    seed: int = 0,
    sensors: RigSensors | None = None,
    truncate_fraction: float | None = None,
    unknown_topic: bool = False,
    schema_encodings: dict[str, str] | None = None,
) -> Path:
    """Write a simulated rig run as one MCAP recording per contract section 3.

    Topics (message encoding ``json``, schema encoding ``jsonschema``, schemas from
    :mod:`schemas.rig_topics`): ``/rig/info`` once; ``/rig/pressure`` (``p_rodless_mpa``,
    ``p_rod_mpa``, 0.0001 MPa resolution) at ~1 kHz; ``/rig/displacement`` (``x_mm``,
    0.001 mm) at ~500 Hz; ``/rig/temperature`` (``oil_temp_c``) at ~1 Hz; ``/rig/step``
    at every step change. Log time is ns since the Unix epoch, each sample's nominal
    time plus Gaussian acquisition jitter (``publish_time`` is the nominal time);
    messages are written in log-time order.

    The displacement is the rig's x (positive rod out), offset so that mid-stroke is
    500 mm. Friction is recoverable as p_rodless A_bore - p_rod (A_bore - A_rod) - m a,
    with m = ``moving_mass_kg`` of ``/rig/info``.

    Awkward variants for ingest tests:

    * ``truncate_fraction`` -- keep only that fraction of the file's bytes (the rig
      stopped mid-write: no summary, no footer, a cut chunk).
    * ``unknown_topic`` -- add ``/rig/pump_status`` (``pump_on``, ``motor_current_a``)
      at 10 Hz, a topic the contract does not know.
    * ``schema_encodings`` -- e.g. ``{"/rig/temperature": "protobuf"}``: register that
      topic's schema with another schema encoding.
    """
    sensors = sensors or RigSensors()
    rng = np.random.default_rng(seed)
    path = Path(path)
    samples = _sample_messages(recording, sensors, rng, start_time_ns)
    messages = _program_messages(recording, start_time_ns) + samples
    if unknown_topic:
        t = recording.frame["time_s"].to_numpy()
        idx = _every(t, 10.0)
        log, pub = _jittered(t[idx], start_time_ns, sensors.jitter_sigma_s, rng)
        current = 12.0 + rng.normal(0, 0.2, idx.size)
        messages += [
            (int(a), int(b), 5, b'{"pump_on":true,"motor_current_a":%.2f}' % u)
            for a, b, u in zip(log, pub, current, strict=True)
        ]
    messages.sort(key=lambda m: (m[0], m[2]))
    _write_messages(path, messages, dict(schema_encodings or {}), unknown_topic=unknown_topic)
    if truncate_fraction is not None:
        if not 0 < truncate_fraction < 1:
            raise ValueError("truncate_fraction: must be in (0, 1)")
        size = path.stat().st_size
        with path.open("r+b") as handle:
            handle.truncate(int(size * truncate_fraction))
    return path


#: One message: (log time [ns], publish time [ns], channel order, JSON bytes); channel
#: order 0 info, 1 pressure, 2 displacement, 3 temperature, 4 step, 5 unknown.
_Message = tuple[int, int, int, bytes]


def _every(t: np.ndarray, rate_hz: float) -> np.ndarray:
    """Indices of the output grid ``t`` sampled at about ``rate_hz``."""
    out_rate = 1.0 / float(np.median(np.diff(t)))
    stride = max(round(out_rate / rate_hz), 1)
    return np.arange(0, t.size, stride)


def _sample_messages(
    recording: RigRecording, sensors: RigSensors, rng: np.random.Generator, start_time_ns: int
) -> list[_Message]:
    """The pressure, displacement and temperature messages, with noise and jitter (drawn
    from ``rng`` in that order)."""
    design = recording.design
    frame = recording.frame
    t = frame["time_s"].to_numpy()
    # pressure
    idx = _every(t, sensors.pressure_rate_hz)
    log, pub = _jittered(t[idx], start_time_ns, sensors.jitter_sigma_s, rng)
    pa = frame["p_rodless_pa"].to_numpy()[idx] + rng.normal(0, sensors.pressure_sigma_pa, idx.size)
    pb = frame["p_rod_pa"].to_numpy()[idx] + rng.normal(0, sensors.pressure_sigma_pa, idx.size)
    pressure = [
        (int(a), int(b), 1, b'{"p_rodless_mpa":%.4f,"p_rod_mpa":%.4f}' % (u, w))
        for a, b, u, w in zip(log, pub, pa / 1e6, pb / 1e6, strict=True)
    ]
    # displacement
    idx = _every(t, sensors.displacement_rate_hz)
    log, pub = _jittered(t[idx], start_time_ns, sensors.jitter_sigma_s, rng)
    x_mm = (frame["x_m"].to_numpy()[idx] + 0.5 * design.stroke_m) * 1e3
    x_mm = x_mm + rng.normal(0, sensors.displacement_sigma_m * 1e3, idx.size)
    displacement = [
        (int(a), int(b), 2, b'{"x_mm":%.3f}' % u) for a, b, u in zip(log, pub, x_mm, strict=True)
    ]
    # temperature
    idx = _every(t, sensors.temperature_rate_hz)
    log, pub = _jittered(t[idx], start_time_ns, sensors.jitter_sigma_s, rng)
    temp = frame["oil_temp_c"].to_numpy()[idx] + rng.normal(
        0, sensors.temperature_sigma_c, idx.size
    )
    temperature = [
        (int(a), int(b), 3, b'{"oil_temp_c":%.2f}' % u)
        for a, b, u in zip(log, pub, temp, strict=True)
    ]
    return pressure + displacement + temperature


def _program_messages(recording: RigRecording, start_time_ns: int) -> list[_Message]:
    """``/rig/info`` once, then ``/rig/step`` at each program step start."""
    design = recording.design
    prog = recording.program
    steps = []
    for k in range(prog.step.size):
        ns = start_time_ns + round(float(prog.t_start_s[k]) * 1e9)
        body = {
            "step": int(prog.step[k]),
            "pressure_setpoint_mpa": round(float(prog.pressure_setpoint_pa[k]) / 1e6, 6),
            "velocity_setpoint_mm_s": round(float(prog.velocity_setpoint_m_s[k]) * 1e3, 6),
        }
        steps.append((ns, ns, 4, json.dumps(body).encode()))
    info = {
        "rig_id": design.rig_id,
        "bore_mm": design.bore_m * 1e3,
        "rod_mm": design.rod_m * 1e3,
        "stroke_mm": design.stroke_m * 1e3,
        "moving_mass_kg": design.moving_mass_kg,
        "oil": design.oil,
    }
    return [(start_time_ns, start_time_ns, 0, json.dumps(info).encode()), *steps]


def _write_messages(
    path: Path, messages: list[_Message], encodings: dict[str, str], *, unknown_topic: bool
) -> None:
    """Register the topics' schemas and channels and write ``messages`` (sorted)."""
    topics = ["/rig/info", "/rig/pressure", "/rig/displacement", "/rig/temperature", "/rig/step"]
    with path.open("wb") as handle:
        writer = Writer(handle)
        writer.start(profile="", library="ropeload-sims")
        channel_ids = {}
        for order, topic in enumerate(topics):
            schema_id = writer.register_schema(
                name=topic, encoding=encodings.get(topic, "jsonschema"), data=schema_bytes(topic)
            )
            channel_ids[order] = writer.register_channel(
                topic=topic, message_encoding="json", schema_id=schema_id
            )
        # channel order in `messages`: 0 info, 1 pressure, 2 displacement, 3 temperature,
        # 4 step, 5 unknown
        remap = dict(channel_ids)
        if unknown_topic:
            schema = {
                "title": "vendor.PumpStatus",
                "type": "object",
                "properties": {
                    "pump_on": {"type": "boolean"},
                    "motor_current_a": {"type": "number"},
                },
            }
            schema_id = writer.register_schema(
                name="/rig/pump_status",
                encoding=encodings.get("/rig/pump_status", "jsonschema"),
                data=json.dumps(schema).encode(),
            )
            remap[5] = writer.register_channel(
                topic="/rig/pump_status", message_encoding="json", schema_id=schema_id
            )
        sequence = dict.fromkeys(remap, 0)
        for log_time, publish_time, channel, data in messages:
            writer.add_message(
                remap[channel], log_time, data, publish_time, sequence=sequence[channel]
            )
            sequence[channel] += 1
        writer.finish()
