"""The sections of a hoist description (contract section 2), one typed object each.

Each ``[section]`` of the TOML file is a frozen pydantic model whose attribute names
carry their SI unit; dimensioned values are parsed from ``"value unit"`` strings
(:mod:`schemas.quantities`). The whole description and its loader:
:mod:`schemas.hoist`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    field_validator,
    model_validator,
)

from schemas.effects import EffectName
from schemas.names import name_problem
from schemas.quantities import QuantityError, parse_quantity
from schemas.time_zones import zone_problem

__all__ = [
    "G_STANDARD",
    "Alarms",
    "Conveyance",
    "Cylinders",
    "Drum",
    "Friction",
    "FrictionLaw",
    "HoistDescriptionError",
    "HoistInfo",
    "Model",
    "Oil",
    "Piping",
    "Ropes",
    "SafeName",
    "Section",
    "Sensor",
    "Shaft",
    "Winder",
]


G_STANDARD = 9.80665  # m/s2, standard gravity (CGPM 1901)


class HoistDescriptionError(ValueError):
    """A hoist description that cannot be used; the message names the file and key."""


def _quantity(dimension: str):
    def parse(value: object) -> float:
        try:
            return parse_quantity(value, dimension)  # type: ignore[arg-type]
        except QuantityError as exc:
            raise ValueError(str(exc)) from None

    return BeforeValidator(parse)


def _positive(value: float) -> float:
    if not value > 0:
        raise ValueError(f"must be positive, got {value:g}")
    return value


def _non_negative(value: float) -> float:
    if value < 0:
        raise ValueError(f"must not be negative, got {value:g}")
    return value


Length = Annotated[float, _quantity("length"), AfterValidator(_positive)]
SignedLength = Annotated[float, _quantity("length")]
DepthLength = Annotated[float, _quantity("length"), AfterValidator(_non_negative)]
Mass = Annotated[float, _quantity("mass"), AfterValidator(_positive)]
MassOrZero = Annotated[float, _quantity("mass"), AfterValidator(_non_negative)]
Force = Annotated[float, _quantity("force"), AfterValidator(_positive)]
Pressure = Annotated[float, _quantity("pressure"), AfterValidator(_positive)]
SignedPressure = Annotated[float, _quantity("pressure")]
LinearDensity = Annotated[float, _quantity("linear_density"), AfterValidator(_non_negative)]
Density = Annotated[float, _quantity("density"), AfterValidator(_positive)]
Velocity = Annotated[float, _quantity("velocity"), AfterValidator(_positive)]
Acceleration = Annotated[float, _quantity("acceleration"), AfterValidator(_positive)]
Volume = Annotated[float, _quantity("volume"), AfterValidator(_non_negative)]
KinematicViscosity = Annotated[float, _quantity("kinematic_viscosity"), AfterValidator(_positive)]
Stiffness = Annotated[float, _quantity("stiffness"), AfterValidator(_positive)]
Damping = Annotated[float, _quantity("damping"), AfterValidator(_non_negative)]
Duration = Annotated[float, _quantity("time"), AfterValidator(_positive)]
Temperature = Annotated[float, _quantity("temperature")]


def _safe_name(value: str) -> str:
    problem = name_problem(value)
    if problem is not None:
        raise ValueError(problem)
    return value


#: A name that becomes a folder or partition key (:mod:`schemas.names`): 1-64 of
#: ``A-Z a-z 0-9 . _ -``, starting with a letter or digit, no ``..``.
SafeName = Annotated[str, AfterValidator(_safe_name)]


class Section(BaseModel):
    """A section of the description: unknown keys refused, frozen, keys or aliases."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)


class HoistInfo(Section):
    """``[hoist]``: identity of the hoist; matches the ``site``/``hoist`` of its logs."""

    site: SafeName
    name: SafeName
    timezone: str = "UTC"

    @field_validator("timezone")
    @classmethod
    def _known_zone(cls, value: str) -> str:
        problem = zone_problem(value)
        if problem:
            raise ValueError(problem)
        return value


class Conveyance(Section):
    """``[conveyance]``: the cage or skip hanging on the head ropes."""

    mass_kg: Mass = Field(alias="mass")
    rated_payload_kg: Mass = Field(alias="rated_payload")
    head_ropes: int = Field(4, ge=1, le=8)
    tail_ropes: int = Field(2, ge=0, le=8)


class Ropes(Section):
    """``[ropes]``: head and tail rope properties."""

    head_rope_mass_per_length_kg_m: LinearDensity = Field(alias="head_rope_mass_per_length")
    head_rope_axial_stiffness_n: Force = Field(alias="head_rope_axial_stiffness")  # EA
    head_rope_breaking_strength_n: Force = Field(alias="head_rope_breaking_strength")
    head_rope_damping_ratio: float = Field(0.02, ge=0.0, le=1.0)
    #: Each head rope's axial stiffness as a factor on ``head_rope_axial_stiffness``
    #: (one per rope; None: all alike). Real ropes differ by several percent, which
    #: decides which piston slides when the load changes; a mine rarely knows them, so
    #: the replay reads them off the record (:mod:`discovery.rope_stiffness`).
    head_rope_stiffness_factors: list[Annotated[float, Field(gt=0.5, lt=1.5)]] | None = None
    tail_rope_mass_per_length_kg_m: LinearDensity = Field(alias="tail_rope_mass_per_length")


class Shaft(Section):
    """``[shaft]``: geometry; named positions are depths of the conveyance below pithead."""

    depth_m: Length = Field(alias="depth")
    headframe_height_m: Length = Field(alias="headframe_height")
    tail_rope_loop_m: DepthLength = Field(0.0, alias="tail_rope_loop")
    positions_m: dict[str, DepthLength] = Field(alias="positions")
    position_window_m: Length = Field(5.0, alias="position_window")

    @model_validator(mode="after")
    def _positions_in_shaft(self) -> Shaft:
        if not self.positions_m:
            raise ValueError("positions: name at least one position (e.g. pithead = '0 m')")
        for name, depth in self.positions_m.items():
            if depth > self.depth_m:
                raise ValueError(
                    f"positions.{name}: depth {depth:g} m is below the shaft depth "
                    f"{self.depth_m:g} m"
                )
        return self


class Drum(Section):
    """``[drum]``: Koepe drum; groove radius deviations drive the ``groove_wear`` effect."""

    radius_m: Length = Field(alias="radius")
    groove_radius_deviation_m: list[SignedLength] = Field(alias="groove_radius_deviation")


class Winder(Section):
    """``[winder]``: the trip profile the hoist runs (used by sims and trip segmentation)."""

    max_speed_m_s: Velocity = Field(alias="max_speed")
    acceleration_m_s2: Acceleration = Field(alias="acceleration")
    deceleration_m_s2: Acceleration = Field(alias="deceleration")
    creep_speed_m_s: Velocity = Field(alias="creep_speed")
    creep_distance_m: Length = Field(alias="creep_distance")


class Cylinders(Section):
    """``[cylinders]``: the four rope-attachment cylinders (identical)."""

    bore_m: Length = Field(alias="bore")
    rod_m: Length = Field(alias="rod")
    stroke_m: Length = Field(alias="stroke")
    dead_volume_m3: Volume = Field(alias="dead_volume")
    piston_mass_kg: Mass = Field(alias="piston_mass")

    @model_validator(mode="after")
    def _rod_in_bore(self) -> Cylinders:
        if self.rod_m >= self.bore_m:
            raise ValueError(f"rod {self.rod_m:g} m must be smaller than bore {self.bore_m:g} m")
        return self

    @property
    def bore_area_m2(self) -> float:
        """Piston area on the rodless side, pi D^2 / 4 (paper eq 2's A)."""
        return math.pi * self.bore_m**2 / 4.0

    @property
    def rod_area_m2(self) -> float:
        return math.pi * self.rod_m**2 / 4.0

    @property
    def chamber_volume_mid_m3(self) -> float:
        """Oil in one chamber at mid-stroke (x = 0), dead volume included."""
        return self.bore_area_m2 * self.stroke_m / 2.0 + self.dead_volume_m3


class Piping(Section):
    """``[piping]``: each cylinder's branch to the manifold (paper Fig. 22).

    The oil leaves the rodless chamber through the globe valve and the first part of the
    branch (``length_chamber_to_sensor``), passes the sensor tee, and continues along
    ``length_sensor_to_manifold`` to the manifold shared by all four branches.
    Loss coefficients K are referred to the mean velocity in the branch bore
    (paper eq 13, xi).
    """

    bore_m: Length = Field(alias="bore")
    length_chamber_to_sensor_m: Length = Field(alias="length_chamber_to_sensor")
    length_sensor_to_manifold_m: Length = Field(alias="length_sensor_to_manifold")
    roughness_m: Annotated[float, _quantity("length"), AfterValidator(_non_negative)] = Field(
        1.5e-6, alias="roughness"
    )
    valve_loss_coefficient: float = Field(ge=0.0)
    fittings_loss_coefficient_chamber_to_sensor: float = Field(0.0, ge=0.0)
    fittings_loss_coefficient_sensor_to_manifold: float = Field(0.0, ge=0.0)
    manifold_volume_m3: Volume = Field(alias="manifold_volume")

    @property
    def area_m2(self) -> float:
        return math.pi * self.bore_m**2 / 4.0

    @property
    def branch_volume_m3(self) -> float:
        """Oil in one branch pipe, chamber to manifold [m3]."""
        return self.area_m2 * (self.length_chamber_to_sensor_m + self.length_sensor_to_manifold_m)


class Oil(Section):
    """``[oil]``: hydraulic oil; viscosity at 40 and 100 degC feeds ASTM D341 (Walther)."""

    grade: str
    density_kg_m3: Density = Field(alias="density")
    kinematic_viscosity_40c_m2_s: KinematicViscosity = Field(alias="kinematic_viscosity_40c")
    kinematic_viscosity_100c_m2_s: KinematicViscosity = Field(alias="kinematic_viscosity_100c")
    bulk_modulus_pa: Pressure = Field(alias="bulk_modulus")
    air_fraction: float = Field(0.0, ge=0.0, lt=0.2)
    reference_temperature_c: Temperature = Field(40.0, alias="reference_temperature")

    @model_validator(mode="after")
    def _viscosity_falls(self) -> Oil:
        if self.kinematic_viscosity_100c_m2_s >= self.kinematic_viscosity_40c_m2_s:
            raise ValueError("kinematic_viscosity_100c must be below kinematic_viscosity_40c")
        return self


class Sensor(Section):
    """``[[sensors]]``: one pressure sensor per cylinder. Ingest lands what the sensor
    read; the compensation and the rules that compare sensors apply :meth:`calibrated`."""

    cylinder: int = Field(ge=1, le=8)
    offset_pa: SignedPressure = Field(0.0, alias="offset")
    gain: float = Field(1.0, gt=0.5, lt=2.0)
    full_scale_pa: Pressure = Field(alias="full_scale")

    def calibrated(self, reading_pa: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The pressure [Pa] from the sensor's reading: (reading - offset) / gain
        (``out``: in place, as numpy's)."""
        values = np.subtract(reading_pa, self.offset_pa, out=out)
        return np.divide(values, self.gain, out=values)


@dataclass(frozen=True)
class FrictionLaw:
    """Seal friction parameters in SI as linear functions of chamber pressure (eq 17 form).

    ``value(p) = intercept + slope * p`` with p in Pa; forces in N, speeds in m/s,
    viscous coefficient in N s/m. Built by :meth:`Friction.law` for one bore.
    """

    coulomb_n: tuple[float, float]
    static_n: tuple[float, float]
    stribeck_speed_m_s: tuple[float, float]
    viscous_n_s_m: tuple[float, float]
    bristle_stiffness_n_m: float
    bristle_damping_n_s_m: float
    presliding_elements: int


class Friction(Section):
    """``[friction]``: seal friction parameter set, eq 17 form, with explicit units.

    Each law is ``[intercept, slope]`` of ``value = intercept + slope * p`` with p in
    ``pressure_unit``. ``force_unit`` says what Table-1-style forces mean: ``"MPa"`` is
    friction stated as an equivalent pressure (force / bore area), ``"kN"``/``"N"`` a
    force. ``speed_unit`` applies to the Stribeck speed and to the viscous coefficient's
    denominator. Paper Table 1 gives no units; see NOTES.md for why ``MPa`` is the
    reading consistent with the paper's field result.

    ``relative_uncertainty`` (optional) is the law's relative standard uncertainty (1
    sigma) as the hoist's seals follow it, which the compensation's 95 % band takes
    (:mod:`transforms.uncertainty`); ``ropeload calibrate`` writes the calibration's
    (:func:`transforms.friction_lines.law_relative_sigma`). Not stated: 10 %
    (``transforms.compensation_record.DEFAULT_FRICTION_RELATIVE_SIGMA``, unless the
    compensation's settings give one: ``CompensationSettings.friction_sigma``).
    """

    parameter_set: SafeName
    source: str = ""
    force_unit: Literal["MPa", "kPa", "bar", "N", "kN"]
    speed_unit: Literal["mm/s", "m/s"]
    pressure_unit: Literal["MPa", "bar", "kPa", "Pa"] = "MPa"
    coulomb: tuple[float, float]
    static: tuple[float, float]
    stribeck_speed: tuple[float, float]
    viscous: tuple[float, float]
    bristle_stiffness_n_m: Stiffness = Field(alias="bristle_stiffness")
    bristle_damping_n_s_m: Damping = Field(alias="bristle_damping")
    presliding_elements: int = Field(4, ge=1, le=32)
    relative_uncertainty: float | None = Field(None, ge=0.0, lt=0.5)

    def law(self, bore_area_m2: float) -> FrictionLaw:
        """Convert to SI for a cylinder of the given bore area [m2]."""
        pressure_scale = {"MPa": 1e6, "bar": 1e5, "kPa": 1e3, "Pa": 1.0}[self.pressure_unit]
        force_scale = {
            "MPa": 1e6 * bore_area_m2,
            "kPa": 1e3 * bore_area_m2,
            "bar": 1e5 * bore_area_m2,
            "N": 1.0,
            "kN": 1e3,
        }[self.force_unit]
        speed_scale = {"mm/s": 1e-3, "m/s": 1.0}[self.speed_unit]

        def si(pair: tuple[float, float], scale: float) -> tuple[float, float]:
            return (pair[0] * scale, pair[1] * scale / pressure_scale)

        return FrictionLaw(
            coulomb_n=si(self.coulomb, force_scale),
            static_n=si(self.static, force_scale),
            stribeck_speed_m_s=si(self.stribeck_speed, speed_scale),
            viscous_n_s_m=si(self.viscous, force_scale / speed_scale),
            bristle_stiffness_n_m=self.bristle_stiffness_n_m,
            bristle_damping_n_s_m=self.bristle_damping_n_s_m,
            presliding_elements=self.presliding_elements,
        )


class Alarms(Section):
    """``[alarms]``: thresholds; the defaults cite the regulation they come from."""

    # China, Coal Mine Safety Regulations: rope tension within +-10 % of the mean.
    imbalance_fraction: float = Field(0.10, gt=0.0, lt=1.0)
    # Quebec S-2.1 r.14 s.253.2: slack below 60 % of the empty conveyance's share.
    slack_fraction_of_empty: float = Field(0.60, gt=0.0, lt=1.0)
    # Quebec S-2.1 r.14 s.253.2: tight above max static load + 10 % of breaking strength.
    tight_fraction_of_breaking: float = Field(0.10, gt=0.0, lt=1.0)
    reconciliation_tolerance_fraction: float = Field(0.03, gt=0.0, lt=1.0)
    min_duration_s: Duration = Field(0.5, alias="min_duration")
    flatline_duration_s: Duration = Field(30.0, alias="flatline_duration")
    dropout_duration_s: Duration = Field(1.0, alias="dropout_duration")


class Model(Section):
    """``[model]``: the effects (contract section 4) this hoist's simulation includes."""

    effects: list[EffectName]

    @field_validator("effects")
    @classmethod
    def _unique(cls, value: list[str]) -> list[str]:
        seen = set()
        for name in value:
            if name in seen:
                raise ValueError(f"effect {name!r} is listed twice")
            seen.add(name)
        return value
