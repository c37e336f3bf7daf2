"""The head ropes' constants a replay takes from the compensation (issue 14).

The replay (:func:`discovery.planning.plan_replay`) needs to know how the head ropes'
stiffnesses differ, and which rope is which: while the pistons stick, rope i takes
``k_i / sum(k)`` of a load change, and the piston pushed hardest slides first. It also
needs the ropes' length offsets, to start a block with its pistons where the record
logged them and the seals holding what the ropes leave them
(:func:`sims.replay.block_pistons`). The compensation identifies both from the logged
piston positions (:mod:`transforms.rope_identification`); discovery imports no
transforms, so the pipelines that replay a record (the sanity check, ``ropeload
discover``) bring the identified ropes with them (``identified_ropes=``).

The identification reads the record's first two hours (its 0.2 s means) and is
remembered in ``<data>/cache/rope_springs`` by a digest of those means and the hoist:
a sanity check that reads its samples from where its run's record starts
(:func:`pipelines.run_period.record_start`) takes the run's ropes from there instead of
identifying them again. Where no run identified them (``ropeload discover`` on a record
not yet run), only the whole record's ropes are searched, not the alternatives the
compensation's band takes from its quarters (a third of the time).

Once discovery adds an effect it plans the record again and asks for the ropes as that
grown model reads them (:func:`identified_ropes_under`): the identification turns each
sensor's pressure into its chamber's through the branch the description gives and the
sensors' calibrations, and each rope's payout with depth through the drum's grooves, so
a branch, a sensor or a worn groove the model lacked had biased them
(:mod:`discovery.record_rereading`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import polars as pl

from schemas.hoist import HoistDescription
from sims.effects import resolve_effects
from transforms.compensation import CompensationSettings
from transforms.compensation_record import identification_means
from transforms.rope_identification import identify_from_means
from transforms.stick_slip_band import RopeSprings
from warehouse.store import DataRoot

__all__ = ["described_by_parameters", "identified_ropes", "identified_ropes_under"]


def identified_ropes(
    samples: pl.DataFrame,
    hoist: HoistDescription,
    *,
    data: DataRoot | None = None,
    settings: CompensationSettings | None = None,
    start: RopeSprings | None = None,
) -> RopeSprings | None:
    """The head ropes' constants (each one's stiffness relative to the description's EA
    and its length offset) as the compensation identifies them from ``samples`` (landed
    field samples of one hoist, the record from its first sample); None when nothing
    identifies them (no logged piston positions, no piston motion, no constants within
    the bounds fit the logged x) or the description states its ropes' factors (the
    replay keeps those); as the run, only when every rope's displacement is logged
    somewhere in ``samples`` and ``settings.rope_springs``.

    ``data``: the data root whose ``cache/rope_springs`` remembers identified ropes;
    ``settings``: the compensation's (the seals' drift travel, where they drift);
    ``start``: the ropes the record gave under a nearby description, polished from
    (:func:`transforms.rope_identification.identify_from_means`).
    """
    settings = settings or CompensationSettings()
    x_columns = [f"x{i}_m" for i in range(1, hoist.ropes_n + 1)]
    if (
        hoist.ropes.head_rope_stiffness_factors is not None
        or not settings.rope_springs
        or samples.height == 0
        or not all(_logged(samples, c) for c in x_columns)
    ):
        return None
    record = samples.sort("time_utc")
    means = identification_means(record, record["time_utc"][0], hoist, settings)
    cache = None if data is None else data.under("cache", "rope_springs")
    return identify_from_means(means, hoist, cache_dir=cache, alternatives=False, start=start)


def identified_ropes_under(
    samples: pl.DataFrame,
    hoist: HoistDescription,
    parameters: Mapping[str, Mapping[str, Any]],
    *,
    data: DataRoot | None = None,
    settings: CompensationSettings | None = None,
    start: RopeSprings | None = None,
) -> RopeSprings | None:
    """:func:`identified_ropes` with ``hoist``'s ``[model] effects`` and those effects'
    ``parameters`` (``{effect: {parameter: value}}``, :mod:`sims.effects` names; a
    discovery's fitted ones) written into its description
    (:func:`described_by_parameters`); ``start``: the ropes the record gave before the
    effects joined (the search polished from them)."""
    described = described_by_parameters(hoist, parameters)
    return identified_ropes(samples, described, data=data, settings=settings, start=start)


#: (effect, description section, ((effect parameter, section field), ...)): what of the
#: model's effects :func:`described_by_parameters` writes into the description.
_DESCRIBED = (
    (
        "pipe_laminar_loss",
        "piping",
        (
            ("length_chamber_to_sensor_m", "length_chamber_to_sensor_m"),
            ("length_sensor_to_manifold_m", "length_sensor_to_manifold_m"),
            ("bore_m", "bore_m"),
        ),
    ),
    (
        "local_loss",
        "piping",
        (
            ("valve_loss_coefficient", "valve_loss_coefficient"),
            ("fittings_chamber_to_sensor", "fittings_loss_coefficient_chamber_to_sensor"),
            ("fittings_sensor_to_manifold", "fittings_loss_coefficient_sensor_to_manifold"),
        ),
    ),
    (
        "viscosity_temperature",
        "oil",
        (
            ("kinematic_viscosity_40c_m2_s", "kinematic_viscosity_40c_m2_s"),
            ("kinematic_viscosity_100c_m2_s", "kinematic_viscosity_100c_m2_s"),
        ),
    ),
    (
        "oil_compressibility",
        "oil",
        (("bulk_modulus_pa", "bulk_modulus_pa"), ("air_fraction", "air_fraction")),
    ),
)


def described_by_parameters(
    hoist: HoistDescription, parameters: Mapping[str, Mapping[str, Any]]
) -> HoistDescription:
    """``hoist`` with what the identification reads of its model's effects' ``parameters``
    written into its description: the branch pipe's lengths and bore
    (``pipe_laminar_loss``), its loss coefficients (``local_loss``), the oil's viscosity
    points (``viscosity_temperature``) and bulk modulus (``oil_compressibility``: the
    closed oil volume ties the pistons together), the drum's groove radius deviations
    (``groove_wear``: each rope's payout grows with depth, which the identification
    reads beside each rope's stiffness) and the sensors' offsets and gains
    (``sensor_offset``, ``sensor_gain``), the manifold giving up the oil a fitted pipe
    holds (:func:`_manifold_keeping_the_oil`); the other effects' parameters (the seals', the
    conveyance's, the tail ropes') are left as described. Effects not in the model keep
    the description's values.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> h = load_hoist(EXAMPLE_HOIST)
    >>> "pipe_laminar_loss" in h.model.effects
    True
    >>> described_by_parameters(h, {"pipe_laminar_loss": {"bore_m": 0.004}}).piping.bore_m
    0.004
    >>> gain = {"sensor_gain": {"sensor": 3, "gain": 0.98}}
    >>> grown = h.with_effects([*h.model.effects, "sensor_gain"])
    >>> oil = {"oil_compressibility": {"bulk_modulus_pa": 6e8}}
    >>> d = described_by_parameters(grown, {**oil, **gain})
    >>> d.oil.bulk_modulus_pa, [s.gain for s in d.sensors], d.piping == h.piping
    (600000000.0, [1.0, 1.0, 0.98, 1.0], True)
    >>> described_by_parameters(h, gain) == h  # sensor_gain not in h's model
    True
    >>> worn = h.with_effects([*h.model.effects, "groove_wear"])
    >>> radii = {"groove_wear": {"groove_radius_deviation_m": [0.0, 2e-5, -3e-5, -1e-5]}}
    >>> described_by_parameters(worn, radii).drum.groove_radius_deviation_m
    [0.0, 2e-05, -3e-05, -1e-05]
    """
    on = set(hoist.model.effects)
    given = {k: dict(v) for k, v in parameters.items() if k in on}
    prm = resolve_effects(hoist, sorted(on), given).parameters
    sections: dict[str, dict[str, float]] = {}
    for effect, section, fields in _DESCRIBED:
        if effect in on:
            sections.setdefault(section, {}).update(
                {field: float(prm[effect][name]) for name, field in fields}
            )
    if "piping" in sections:
        sections["piping"]["manifold_volume_m3"] = _manifold_keeping_the_oil(
            hoist, sections["piping"]
        )
    update: dict[str, Any] = {
        section: getattr(hoist, section).model_copy(update=fields)
        for section, fields in sections.items()
    }
    if "groove_wear" in on:
        radii = [float(r) for r in prm["groove_wear"]["groove_radius_deviation_m"]]
        update["drum"] = hoist.drum.model_copy(update={"groove_radius_deviation_m": radii})
    if {"sensor_offset", "sensor_gain"} & on:
        offsets = prm["sensor_offset"]["offsets_pa"] if "sensor_offset" in on else None
        gains = prm["sensor_gain"]["gains"] if "sensor_gain" in on else None
        sensors = []
        for sensor in hoist.sensors:
            k = sensor.cylinder - 1
            change: dict[str, float] = {}
            if offsets is not None:
                change["offset_pa"] = float(offsets[k])
            if gains is not None:
                change["gain"] = float(gains[k])
            sensors.append(sensor.model_copy(update=change))
        update["sensors"] = sensors
    return hoist.model_copy(update=update) if update else hoist


#: The least share of the described manifold volume :func:`_manifold_keeping_the_oil`
#: leaves when a fitted pipe would hold more oil than the manifold gave up: the
#: manifold is a real vessel, never empty.
MANIFOLD_FLOOR_SHARE = 0.1


def _manifold_keeping_the_oil(hoist: HoistDescription, piping: Mapping[str, float]) -> float:
    """The manifold volume [m3] that keeps the description's oil in all
    (:attr:`~schemas.hoist.HoistDescription.oil_volume_m3`) with the branch pipes of
    ``piping`` (their lengths and bore as fitted).

    The oil in the closed device is what a mine knows (it filled it), not how the oil
    outside the chambers divides between pipes and manifold; the identification reads
    that total through the closed-volume relation (sum A dx = V dp / beta, eq 5). A pipe
    found longer or narrower therefore holds oil the description had counted in the
    manifold, and does not add oil. (Growing the total with the fitted pipe made the
    oil seem softer than it is: on an independent simulator's record with a pipe 7.8
    times as long, the ropes read with it replayed 8.0 kPa from the pressures with the
    total kept, 11.7 kPa with it grown by 1.9 L.) Floored at
    :data:`MANIFOLD_FLOOR_SHARE` of the described manifold: beside a small manifold
    (the example hoist's 0.5 L beside 1.04 L of pipe, reached at 1.43 times the pipes'
    length) the oil grows with a longer pipe beyond that, as it did before.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> h = load_hoist(EXAMPLE_HOIST)
    >>> twice = {"length_chamber_to_sensor_m": 2 * h.piping.length_chamber_to_sensor_m,
    ...          "length_sensor_to_manifold_m": 2 * h.piping.length_sensor_to_manifold_m}
    >>> v = _manifold_keeping_the_oil(h, {"bore_m": h.piping.bore_m * 0.5, **twice})
    >>> piped = h.piping.model_copy(update={**twice, "bore_m": h.piping.bore_m * 0.5,
    ...                                     "manifold_volume_m3": v})
    >>> round(h.model_copy(update={"piping": piped}).oil_volume_m3 / h.oil_volume_m3, 12)
    1.0
    """
    described = hoist.piping
    fitted = described.model_copy(update=dict(piping))
    if fitted.branch_volume_m3 == described.branch_volume_m3:
        return described.manifold_volume_m3
    gave_up = hoist.ropes_n * (fitted.branch_volume_m3 - described.branch_volume_m3)
    kept = described.manifold_volume_m3 - gave_up
    return max(kept, MANIFOLD_FLOOR_SHARE * described.manifold_volume_m3)


def _logged(samples: pl.DataFrame, column: str) -> bool:
    """The column has a value somewhere (the run identifies the ropes only then:
    ``CompensationContext.has_x``, every rope's displacement logged somewhere)."""
    if column not in samples.columns:
        return False
    values = samples[column].cast(pl.Float64)
    return bool(values.is_finite().fill_null(False).any())
