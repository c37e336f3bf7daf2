"""The hoist description (contract section 2): TOML layout, typed objects, loader.

Everything a run needs to know about a hoist that is not in its logs. The TOML file
states every dimensioned number as a ``"value unit"`` string (``mass = "8.2 t"``); the
loader converts to SI and the attribute names carry the SI unit (``mass_kg``). The
layout, key by key, is documented in ``schemas/hoists/README.md`` and shown by
``schemas/hoists/paper_field_test.toml`` (the paper's field-test hoist).

>>> hoist = load_hoist(EXAMPLE_HOIST)
>>> hoist.conveyance.mass_kg, hoist.shaft.depth_m
(8200.0, 620.0)
"""

from __future__ import annotations

import hashlib
import tomllib
from collections.abc import Mapping, Sequence
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    ValidationError,
    model_validator,
)

from schemas.hoist_sections import (
    G_STANDARD,
    Alarms,
    Conveyance,
    Cylinders,
    Drum,
    Friction,
    FrictionLaw,
    HoistDescriptionError,
    HoistInfo,
    Model,
    Oil,
    Piping,
    Ropes,
    Section,
    Sensor,
    Shaft,
    Winder,
)

# the sections are part of this module's interface (schemas.hoist_sections defines them)
__all__ = [
    "EXAMPLE_HOIST",
    "G_STANDARD",
    "Alarms",
    "Conveyance",
    "Cylinders",
    "Drum",
    "Friction",
    "FrictionLaw",
    "HoistDescription",
    "HoistDescriptionError",
    "HoistInfo",
    "Model",
    "Oil",
    "Piping",
    "Ropes",
    "Sensor",
    "Shaft",
    "Winder",
    "hoist_sha256",
    "load_hoist",
    "parse_hoist",
]

#: The paper's field-test hoist (section 5), shipped with the package.
EXAMPLE_HOIST = Path(__file__).parent / "hoists" / "paper_field_test.toml"


class HoistDescription(Section):
    """A whole hoist description; see the module docstring for the file layout."""

    schema_version: Literal[1] = 1
    hoist: HoistInfo
    conveyance: Conveyance
    ropes: Ropes
    shaft: Shaft
    drum: Drum
    winder: Winder
    cylinders: Cylinders
    piping: Piping
    oil: Oil
    sensors: list[Sensor]
    friction: Friction
    alarms: Alarms = Alarms()
    model: Model

    @model_validator(mode="after")
    def _one_per_rope(self) -> HoistDescription:
        n = self.conveyance.head_ropes
        cylinders = sorted(s.cylinder for s in self.sensors)
        if cylinders != list(range(1, n + 1)):
            raise ValueError(
                f"sensors: need exactly one [[sensors]] entry per head rope, cylinders "
                f"1..{n}; got {cylinders}"
            )
        if len(self.drum.groove_radius_deviation_m) != n:
            raise ValueError(
                f"drum.groove_radius_deviation: need {n} values (one per head rope), "
                f"got {len(self.drum.groove_radius_deviation_m)}"
            )
        factors = self.ropes.head_rope_stiffness_factors
        if factors is not None and len(factors) != n:
            raise ValueError(
                f"ropes.head_rope_stiffness_factors: need {n} values (one per head rope), "
                f"got {len(factors)}"
            )
        return self

    def model_copy(
        self, *, update: Mapping[str, Any] | None = None, deep: bool = False
    ) -> HoistDescription:
        """pydantic's copy, without the friction law cached from the original (the
        update may change the ``friction`` or ``cylinders`` it derives from)."""
        copied = super().model_copy(update=update, deep=deep)
        copied.__dict__.pop("friction_law", None)
        return copied

    def with_effects(self, effects: Sequence[str]) -> HoistDescription:
        """This hoist with its ``[model] effects`` replaced by ``effects`` (in that order:
        give a sorted list where the order must not depend on a set's)."""
        return self.model_copy(update={"model": Model(effects=list(effects))})

    # -- derived quantities used across the pipeline ------------------------------------
    @property
    def ropes_n(self) -> int:
        return self.conveyance.head_ropes

    @cached_property
    def friction_law(self) -> FrictionLaw:
        return self.friction.law(self.cylinders.bore_area_m2)

    @property
    def oil_volume_m3(self) -> float:
        """All oil in the closed connection device at mid-stroke: chambers, pipes, manifold."""
        branch = self.piping.branch_volume_m3
        return self.ropes_n * (self.cylinders.chamber_volume_mid_m3 + branch) + (
            self.piping.manifold_volume_m3
        )


def _format_errors(source: str, error: ValidationError) -> str:
    lines = []
    for item in error.errors():
        location = ".".join(str(part) for part in item["loc"]) or "(top level)"
        kind = item["type"]
        if kind == "missing":
            message = "required key is missing"
        elif kind == "extra_forbidden":
            message = "unknown key (check the spelling against schemas/hoists/README.md)"
        elif kind == "literal_error" and "effects" in location:
            message = f"unknown effect name {item['input']!r}; {item['msg'].lower()}"
        else:
            message = item["msg"].removeprefix("Value error, ")
        lines.append(f"{source}: {location}: {message}")
    return "\n".join(lines)


def parse_hoist(text: str, *, source: str = "<hoist description>") -> HoistDescription:
    """Parse a hoist description from TOML text; errors name ``source`` and the key."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise HoistDescriptionError(f"{source}: not valid TOML: {exc}") from None
    try:
        return HoistDescription.model_validate(raw)
    except ValidationError as exc:
        raise HoistDescriptionError(_format_errors(source, exc)) from None


def load_hoist(path: str | Path) -> HoistDescription:
    """Load and validate a hoist description file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise HoistDescriptionError(f"{path}: hoist description not found") from None
    except UnicodeDecodeError as exc:
        raise HoistDescriptionError(f"{path}: not UTF-8 text ({exc.reason})") from None
    return parse_hoist(text, source=str(path))


def hoist_sha256(path: str | Path) -> str:
    """Content hash of a hoist description file, recorded with every run for lineage."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
