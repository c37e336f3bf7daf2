"""JSON schemas of the friction-rig MCAP topics (contract section 3).

The rig simulator registers these schemas (encoding ``jsonschema``) and ingest checks
message fields against them. Log time is nanoseconds since the Unix epoch.
"""

from __future__ import annotations

import json

__all__ = ["RIG_TOPICS", "schema_bytes"]

_NUMBER = {"type": "number"}

RIG_TOPICS: dict[str, dict] = {
    "/rig/info": {
        "title": "ropeload.rig.Info",
        "type": "object",
        "properties": {
            "rig_id": {"type": "string"},
            "bore_mm": _NUMBER,
            "rod_mm": _NUMBER,
            "stroke_mm": _NUMBER,
            "moving_mass_kg": _NUMBER,
            "oil": {"type": "string"},
        },
        "required": ["rig_id", "bore_mm", "rod_mm", "stroke_mm", "moving_mass_kg", "oil"],
    },
    "/rig/pressure": {
        "title": "ropeload.rig.Pressure",
        "type": "object",
        "properties": {"p_rodless_mpa": _NUMBER, "p_rod_mpa": _NUMBER},
        "required": ["p_rodless_mpa", "p_rod_mpa"],
    },
    "/rig/displacement": {
        "title": "ropeload.rig.Displacement",
        "type": "object",
        "properties": {"x_mm": _NUMBER},
        "required": ["x_mm"],
    },
    "/rig/temperature": {
        "title": "ropeload.rig.Temperature",
        "type": "object",
        "properties": {"oil_temp_c": _NUMBER},
        "required": ["oil_temp_c"],
    },
    "/rig/step": {
        "title": "ropeload.rig.Step",
        "type": "object",
        "properties": {
            "step": {"type": "integer"},
            "pressure_setpoint_mpa": _NUMBER,
            "velocity_setpoint_mm_s": _NUMBER,
        },
        "required": ["step", "pressure_setpoint_mpa", "velocity_setpoint_mm_s"],
    },
}


def schema_bytes(topic: str) -> bytes:
    """The JSON schema of ``topic`` as MCAP schema data."""
    return json.dumps(RIG_TOPICS[topic], separators=(",", ":")).encode()
