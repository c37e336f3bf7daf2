"""``ropeload calibrate``: friction-rig recordings -> a seal-friction parameter set.

The friction test of paper section 4.2.1 measures the steady-state Stribeck curve
(eq 16/18) per oil pressure (Table 1) and its parameters as straight lines in pressure
(eq 17). The physics lives in transforms: the force balance and the steady steps
(:mod:`transforms.rig_friction`), the Stribeck fits and the lines
(:mod:`transforms.friction_fit`). This module is the command around them (contract 3):
:func:`calibrate_rig` -- ingest (optional), read the lake, call the transforms, land
a ``friction_parameter_sets`` row and a ``runs`` row; returns a
:class:`~pipelines.calibrate_outputs.CalibrationResult`.

Beside it, by idea:

:mod:`pipelines.calibrate_inputs`
    :func:`~pipelines.calibrate_inputs.read_rig_info` -- ``/rig/info`` of an MCAP
    recording (bore, rod, moving mass); the rig and its samples in the lake
    (``rig_samples``).
:mod:`pipelines.calibrate_outputs`
    :func:`~pipelines.calibrate_outputs.friction_toml` -- the ``[friction]`` section of
    a hoist description; the landing of the parameter set and its run.
:mod:`pipelines.calibrate_report`
    :func:`~pipelines.calibrate_report.format_calibration` -- the printed report of
    ``ropeload calibrate``; :func:`~pipelines.calibrate_report.table1_report` -- OLS
    lines through paper Table 1 with residuals, and where they differ from the printed
    eq 17 (``ropeload calibrate --table1``).

Everything inside is SI (Pa, m, m/s, N, N s/m); the hoist-description snippet states
its units (friction as equivalent pressure in MPa, speeds in mm/s; NOTES.md).
"""

from __future__ import annotations

import hashlib
import logging
from collections.abc import Sequence
from pathlib import Path

import polars as pl

from pipelines.calibrate_inputs import (
    CalibrationError,
    RigInfo,
    check_names,
    recorded_infos,
    rig_geometry,
    rig_samples,
    select_rig,
)
from pipelines.calibrate_outputs import (
    CalibrationResult,
    friction_toml,
    land_calibration,
    written_uncertainty,
)
from pipelines.provenance import utc_now
from schemas.hoist import FrictionLaw
from transforms.friction_fit import LinearFit, StribeckFit, fit_friction_law
from transforms.friction_lines import law_relative_sigma
from transforms.rig_friction import fit_pressure_levels, seal_friction_samples, steady_steps
from warehouse.store import DataRoot

__all__ = [
    "DEFAULT_BRISTLE_DAMPING_N_S_M",
    "DEFAULT_BRISTLE_STIFFNESS_N_M",
    "DEFAULT_PRESLIDING_ELEMENTS",
    "calibrate_rig",
]

logger = logging.getLogger(__name__)

#: Defaults of the dynamic (non-steady) parameters, which a steady-speed test does not
#: identify: those of the example hoist (``schemas/hoists/paper_field_test.toml``).
DEFAULT_BRISTLE_STIFFNESS_N_M = 2.5e7
DEFAULT_BRISTLE_DAMPING_N_S_M = 2e4
DEFAULT_PRESLIDING_ELEMENTS = 4


def _fit(
    samples: pl.DataFrame,
    rig: RigInfo,
    notes: list[str],
    *,
    smooth_s: float,
    bristle_stiffness_n_m: float,
    bristle_damping_n_s_m: float,
    presliding_elements: int,
) -> tuple[pl.DataFrame, pl.DataFrame, list[StribeckFit], FrictionLaw, dict[str, LinearFit]]:
    """The transforms: friction per sample (eq 1), steady steps, Table 1 analogue (eq
    16/18 per pressure), eq-17 lines. Returns ``steps, per_pressure, fits, law, lines``;
    appends a note on the moving steps left out to ``notes``."""
    frame = seal_friction_samples(
        samples, bore_m=rig.bore_m, rod_m=rig.rod_m, moving_mass_kg=rig.moving_mass_kg,
        smooth_s=smooth_s,
    )  # fmt: skip
    steps = steady_steps(frame, smooth_s=smooth_s)
    moving = frame.filter(pl.col("velocity_setpoint_m_s").fill_null(0.0) != 0.0)
    dropped = moving["segment"].n_unique() - steps.height
    if dropped:
        notes.append(
            f"{dropped} moving step(s) without {0.1:g} s of steady data, or that did not "
            "follow their velocity setpoint (stalled), were left out"
        )
    per_pressure, fits = fit_pressure_levels(steps)
    logger.info(
        "calibrate rig %s: %d samples, %d steady steps, %d pressure level(s) fitted",
        rig.rig_id,
        samples.height,
        steps.height,
        per_pressure.height,
    )
    if per_pressure.height < 3:
        raise CalibrationError(
            f"rig {rig.rig_id!r}: {per_pressure.height} pressure level(s) with at least 5 "
            f"steady steps ({steps.height} steady steps in all); need 3 levels for the eq-17 "
            "lines"
        )
    notes += _undetermined(per_pressure)
    law, lines = fit_friction_law(
        per_pressure["p_rodless_pa"].to_numpy(),
        fits,
        bristle_stiffness_n_m=bristle_stiffness_n_m,
        bristle_damping_n_s_m=bristle_damping_n_s_m,
        presliding_elements=presliding_elements,
    )
    return steps, per_pressure, fits, law, lines


#: The Stribeck parameters a level's fit must pin down: (name, value, its 1-sigma).
_DETERMINED = (
    ("Fc", "coulomb_n", "coulomb_sigma_n"),
    ("Fs", "static_n", "static_sigma_n"),
    ("vs", "stribeck_speed_m_s", "stribeck_speed_sigma_m_s"),
)


def _undetermined(per_pressure: pl.DataFrame) -> list[str]:
    """A note per pressure level whose Coulomb, static or Stribeck-speed value the
    recording does not pin down (its 1-sigma above half of it, or not finite): the
    set is landed as fitted, but its lines through such a level are not to be trusted
    (three speeds a direction left Fc 687 +- 48.6 MPa-equivalent N, vs 3.9 +- 5713 mm/s)."""
    notes = []
    for row in per_pressure.iter_rows(named=True):
        loose = [
            name
            for name, value, sigma in _DETERMINED
            if not abs(row[sigma]) <= 0.5 * abs(row[value])  # NaN, inf: not determined
        ]
        if loose:
            notes.append(
                f"level {row['p_rodless_pa'] / 1e6:.2f} MPa: {', '.join(loose)} not determined "
                "by the recording (1-sigma above half the value): more speeds each way, "
                "around the Stribeck speed, would pin them down"
            )
    return notes


def calibrate_rig(
    *,
    data: DataRoot,
    rig_id: str | None = None,
    recordings: Sequence[str | Path] = (),
    parameter_set: str | None = None,
    bore_m: float | None = None,
    rod_m: float | None = None,
    moving_mass_kg: float | None = None,
    bristle_stiffness_n_m: float = DEFAULT_BRISTLE_STIFFNESS_N_M,
    bristle_damping_n_s_m: float = DEFAULT_BRISTLE_DAMPING_N_S_M,
    presliding_elements: int = DEFAULT_PRESLIDING_ELEMENTS,
    smooth_s: float = 0.05,
) -> CalibrationResult:
    """Calibrate the seal-friction law from friction-rig recordings (paper 4.2.1, eq 15-18).

    1. ``recordings`` (MCAP, contract 3), if given, are ingested first
       (:func:`pipelines.ingest.ingest_paths`; already-ingested content is skipped) and
       only their samples are used; without them, every rig sample of ``rig_id`` in the
       lake is used. ``rig_id`` defaults to the recordings' (or the lake's only) rig.
    2. Seal friction per sample by the force balance of eq 1
       (:func:`transforms.rig_friction.seal_friction_samples`), with bore, rod and
       moving mass from ``/rig/info`` of the recordings (read from the files: the lake
       does not keep it; for lake-only runs, from the manifest's source paths), unless
       given explicitly.
    3. Steady part of each step (:func:`transforms.rig_friction.steady_steps`), a
       Stribeck fit per pressure level (:func:`transforms.rig_friction.fit_pressure_levels`,
       Table 1 analogue), weighted lines in pressure
       (:func:`transforms.friction_fit.fit_friction_law`, eq 17 analogue).
    4. Lands one ``friction_parameter_sets`` row (replaced by name) and one ``runs``
       row (command ``calibrate``, inputs = source sha256) in one
       :func:`warehouse.store.open_writer` block. The default ``parameter_set`` name is
       ``<rig_id>-<hash of the inputs>`` and the run id ``calibrate-<parameter_set>``,
       so calibrating the same data again replaces both rows, never duplicates them.

    The bristle parameters (``bristle_*``, ``presliding_elements``) are not identified
    by steady-speed data; they are carried into the law as given.

    Raises
    ------
    CalibrationError
        A refused recording, no rig samples, missing geometry, or fewer than three
        pressure levels with at least five steady steps each.
    """
    started = utc_now()
    check_names(rig_id, parameter_set)
    rig_id, given_shas, infos, notes = select_rig(data, recordings, rig_id)
    samples = rig_samples(data, rig_id, given_shas)
    inputs = tuple(sorted(set(samples["source_sha256"].unique().to_list()) | set(given_shas)))

    if not infos and None in (bore_m, rod_m, moving_mass_kg):
        infos = recorded_infos(data, inputs, rig_id)
    rig = rig_geometry(infos, rig_id, bore_m=bore_m, rod_m=rod_m, moving_mass_kg=moving_mass_kg)

    steps, per_pressure, fits, law, lines = _fit(
        samples, rig, notes, smooth_s=smooth_s, bristle_stiffness_n_m=bristle_stiffness_n_m,
        bristle_damping_n_s_m=bristle_damping_n_s_m, presliding_elements=presliding_elements,
    )  # fmt: skip
    if parameter_set is None:
        digest = hashlib.sha256("\n".join(inputs).encode()).hexdigest()[:12]
        parameter_set = f"{rig_id[:51]}-{digest}"  # a safe name: at most 64 characters
    run_id = f"calibrate-{parameter_set}"
    source = f"ropeload calibrate: rig {rig_id}, {len(inputs)} recording(s), run {run_id}"
    relative = law_relative_sigma(
        lines["coulomb_n"], lines["static_n"], per_pressure["p_rodless_pa"].to_numpy()
    )
    if written_uncertainty(relative) is None:  # NaN too: a line not clearly positive
        notes.append(
            f"the law's relative uncertainty ({relative:.3g}) is not one a hoist description "
            "takes ([0, 0.5)): not written; the compensation's band then takes 10 %"
        )
    toml = friction_toml(
        law, bore_m=rig.bore_m, parameter_set=parameter_set, source=source,
        relative_uncertainty=relative,
    )  # fmt: skip
    result = CalibrationResult(
        rig_id=rig_id,
        parameter_set=parameter_set,
        run_id=run_id,
        rig=rig,
        per_pressure=per_pressure,
        fits=tuple(fits),
        lines=lines,
        law=law,
        toml=toml,
        steps=steps,
        inputs=inputs,
        notes=tuple(notes),
        relative_uncertainty=relative,
    )
    land_calibration(data, result, samples, source=source, started=started)
    return result
