"""The outputs of ``ropeload calibrate``: the result, its TOML snippet, its landing.

:class:`CalibrationResult` is what :func:`pipelines.calibrate.calibrate_rig` returns;
:func:`friction_toml` the ``[friction]`` section of a hoist description;
:func:`land_calibration` one ``friction_parameter_sets`` row and one ``runs`` row.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from dataclasses import dataclass, field

import numpy as np
import polars as pl

from pipelines.calibrate_inputs import RIG_SITE, RigInfo
from pipelines.provenance import code_version, utc_now
from schemas.hoist import FrictionLaw
from transforms.friction_fit import LinearFit, StribeckFit
from warehouse.store import DataRoot

__all__ = [
    "LINE_NAMES",
    "CalibrationResult",
    "friction_toml",
    "land_calibration",
    "line_standard_errors",
    "written_uncertainty",
]


#: Keys of the eq-17 lines (SI), in the order Fc, Fs, vs, Kv.
LINE_NAMES = ("coulomb_n", "static_n", "stribeck_speed_m_s", "viscous_n_s_m")


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`pipelines.calibrate.calibrate_rig` found and landed.

    ``per_pressure`` is the analogue of paper Table 1 (SI, 1-sigma), ``lines`` the
    eq-17 lines (keys :data:`LINE_NAMES`, SI per Pa, residuals per pressure), ``law``
    the :class:`~schemas.hoist.FrictionLaw` (SI), ``toml`` the ``[friction]`` section
    for a hoist description, ``steps`` the per-step steady means the fits used,
    ``inputs`` the source sha256 of the rig samples read, ``relative_uncertainty`` the
    law's relative standard uncertainty (:func:`transforms.friction_lines.law_relative_sigma`,
    written into ``toml``).
    """

    rig_id: str
    parameter_set: str
    run_id: str
    rig: RigInfo
    per_pressure: pl.DataFrame
    fits: tuple[StribeckFit, ...]
    lines: dict[str, LinearFit]
    law: FrictionLaw
    toml: str
    steps: pl.DataFrame
    inputs: tuple[str, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)
    relative_uncertainty: float = float("nan")


def _toml_string(text: str) -> str:
    return json.dumps(text)  # a JSON string is a valid TOML basic string


def written_uncertainty(value: float | None) -> float | None:
    """``value`` as :func:`friction_toml` writes it (3 significant digits), or None where
    a hoist description would refuse it (outside [0, 0.5), or NaN: not determined).

    >>> written_uncertainty(0.047161), written_uncertainty(0.49996), written_uncertainty(None)
    (0.0472, None, None)
    """
    if value is None or not math.isfinite(value):
        return None
    rounded = float(f"{value:.3g}")
    return rounded if 0.0 <= rounded < 0.5 else None


def friction_toml(
    law: FrictionLaw,
    *,
    bore_m: float,
    parameter_set: str,
    source: str,
    comment: str = "",
    relative_uncertainty: float | None = None,
) -> str:
    """The ``[friction]`` section of a hoist description for ``law`` (contract 2).

    Forces are written as the equivalent pressure of a ``bore_m`` piston (force / bore
    area) in MPa, speeds in mm/s, pressures in MPa: the layout of
    :class:`schemas.hoist.Friction`, whose :meth:`~schemas.hoist.Friction.law` inverts
    this conversion. ``comment`` lines go on top, prefixed with ``#``.
    ``relative_uncertainty`` (the law's, 1 sigma) is written when a description would
    take it (:func:`written_uncertainty`).
    """
    area = math.pi * bore_m**2 / 4.0
    force, speed, pressure = 1e6 * area, 1e-3, 1e6  # N per MPa, m/s per mm/s, Pa per MPa

    def pair(value: tuple[float, float], scale: float) -> str:
        return f"[{value[0] / scale:.6g}, {value[1] * pressure / scale:.6g}]"

    lines = [f"# {c}" for c in comment.splitlines() if c.strip()]
    lines += [
        "[friction]",
        "# value = intercept + slope * p, p in MPa (paper eq 17 form). Friction forces are",
        f"# stated as equivalent pressure: force / bore area ({bore_m * 1e3:g} mm bore), MPa.",
        "# Bristle stiffness / damping and the presliding element count are not identified",
        "# by a steady-speed test; they are the given values, not fitted.",
        f"parameter_set = {_toml_string(parameter_set)}",
        f"source = {_toml_string(source)}",
        'force_unit = "MPa"',
        'speed_unit = "mm/s"',
        'pressure_unit = "MPa"',
        f"coulomb = {pair(law.coulomb_n, force)}",
        f"static = {pair(law.static_n, force)}",
        f"stribeck_speed = {pair(law.stribeck_speed_m_s, speed)}",
        f"viscous = {pair(law.viscous_n_s_m, force / speed)}",
        f'bristle_stiffness = "{law.bristle_stiffness_n_m:.6g} N/m"',
        f'bristle_damping = "{law.bristle_damping_n_s_m:.6g} N*s/m"',
        f"presliding_elements = {law.presliding_elements}",
    ]
    written = written_uncertainty(relative_uncertainty)
    if written is not None:
        lines += [
            "# the law's relative standard uncertainty: the Coulomb and static lines'",
            "# scatter about themselves and their standard error (the band's, 1 sigma)",
            f"relative_uncertainty = {written:g}",
        ]
    return "\n".join(lines) + "\n"


def line_standard_errors(lines: dict[str, LinearFit]) -> dict[str, float]:
    """Each eq 17 line's 1-sigma standard errors and intercept-slope covariance, keyed
    as ``friction_parameter_sets`` columns (SI): ``<name>``, ``<name>_per_pa``,
    ``<name>_covariance``.

    >>> from transforms.friction_lines import fit_line
    >>> fit = fit_line(np.array([1e6, 2e6, 3e6]), np.array([10.0, 12.1, 13.9]))
    >>> sorted(line_standard_errors({"static_n": fit}))
    ['static_n', 'static_n_covariance', 'static_n_per_pa']
    """
    out: dict[str, float] = {}
    for name in LINE_NAMES:
        if name in lines:
            fit = lines[name]
            out[name] = float(fit.se_intercept)
            out[f"{name}_per_pa"] = float(fit.se_slope)
            out[f"{name}_covariance"] = float(fit.cov_intercept_slope)
    return out


def land_calibration(
    data: DataRoot, result: CalibrationResult, samples: pl.DataFrame, *, source: str,
    started: dt.datetime,
) -> None:  # fmt: skip
    """One ``friction_parameter_sets`` row and one ``runs`` row, in one writer block."""
    from warehouse.landing import RunRecord, land_friction_parameter_sets, land_run
    from warehouse.store import open_writer

    law, lines, inputs = result.law, result.lines, result.inputs
    residual_rms = {
        name: float(np.sqrt(np.mean(lines[name].residuals ** 2))) for name in LINE_NAMES
    }
    residual_rms["stribeck_curve_n"] = float(np.sqrt(np.mean([f.rms**2 for f in result.fits])))
    errors = line_standard_errors(lines)
    if math.isfinite(result.relative_uncertainty):
        errors["law_relative"] = result.relative_uncertainty
    row = pl.DataFrame(
        [
            {
                "parameter_set": result.parameter_set,
                "created_at_utc": started,
                "source": source,
                "bore_m": result.rig.bore_m,
                **{name: getattr(law, name)[0] for name in LINE_NAMES},
                **{f"{name}_per_pa": getattr(law, name)[1] for name in LINE_NAMES},
                "residual_rms": [{"key": k, "value": v} for k, v in residual_rms.items()],
                "inputs": list(inputs),
                "standard_error": [{"key": k, "value": v} for k, v in errors.items()],
            }
        ]
    )
    times = samples["time_utc"]
    run = RunRecord(
        run_id=result.run_id,
        command="calibrate",
        code_version=code_version(),
        started_at_utc=started,
        parameter_set=result.parameter_set,
        site=RIG_SITE,
        hoist=result.rig_id,
        period_start_utc=times.min(),  # type: ignore[arg-type]
        period_end_utc=times.max(),  # type: ignore[arg-type]
        inputs=inputs,
        finished_at_utc=utc_now(),
        message=f"{result.per_pressure.height} pressure levels, {result.steps.height} steady steps",
    )
    with open_writer(data) as con:
        land_friction_parameter_sets(con, row)
        land_run(con, run)
