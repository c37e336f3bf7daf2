"""``ropeload calibrate``: friction-rig recordings -> a seal-friction parameter set.

The friction test of paper section 4.2.1 measures the steady-state Stribeck curve
(eq 16/18) per oil pressure (Table 1) and its parameters as straight lines in pressure
(eq 17). The physics lives in transforms: the force balance and the steady steps
(:mod:`transforms.rig_friction`), the Stribeck fits and the lines
(:mod:`transforms.friction_fit`). This module is the command around them (contract 3):

Inputs
    :func:`read_rig_info` -- ``/rig/info`` of an MCAP recording (bore, rod, moving mass).
    The rig samples are read from the lake (``rig_samples``).

Orchestration and outputs
    :func:`calibrate_rig` -- ingest (optional), read the lake, call the transforms, land
    a ``friction_parameter_sets`` row and a ``runs`` row; returns a
    :class:`CalibrationResult`.
    :func:`friction_toml` -- the ``[friction]`` section of a hoist description.
    :func:`format_calibration` -- the printed report of ``ropeload calibrate``.
    :func:`table1_report` -- OLS lines through paper Table 1 with residuals, and where
    they differ from the printed eq 17 (``ropeload calibrate --table1``).

Everything inside is SI (Pa, m, m/s, N, N s/m); the hoist-description snippet states
its units (friction as equivalent pressure in MPa, speeds in mm/s; NOTES.md).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from pipelines.lake import lake_partitions, scan_lake
from pipelines.provenance import code_version, utc_now
from schemas.hoist import FrictionLaw
from schemas.names import UnsafeNameError, safe_name
from transforms.friction_fit import (
    LinearFit,
    StribeckFit,
    compare_with_eq17,
    fit_friction_law,
    fit_table1,
)
from transforms.rig_friction import fit_pressure_levels, seal_friction_samples, steady_steps
from warehouse.store import DataRoot

__all__ = [
    "LINE_NAMES",
    "CalibrationError",
    "CalibrationResult",
    "RigInfo",
    "calibrate_rig",
    "eq17_coefficient_verdict",
    "eq17_line_verdict",
    "eq17_summary",
    "format_calibration",
    "friction_toml",
    "read_rig_info",
    "table1_report",
]

logger = logging.getLogger(__name__)

#: Keys of the eq-17 lines (SI), in the order Fc, Fs, vs, Kv.
LINE_NAMES = ("coulomb_n", "static_n", "stribeck_speed_m_s", "viscous_n_s_m")

#: Defaults of the dynamic (non-steady) parameters, which a steady-speed test does not
#: identify: those of the example hoist (``schemas/hoists/paper_field_test.toml``).
DEFAULT_BRISTLE_STIFFNESS_N_M = 2.5e7
DEFAULT_BRISTLE_DAMPING_N_S_M = 2e4
DEFAULT_PRESLIDING_ELEMENTS = 4

_SITE = "rig"


class CalibrationError(ValueError):
    """Calibration refused (no samples, refused recording, too few steps or pressures)."""


# ---------------------------------------------------------------------------------------
# Rig geometry (/rig/info)
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RigInfo:
    """The ``/rig/info`` message of a recording, in SI."""

    rig_id: str
    bore_m: float
    rod_m: float
    stroke_m: float
    moving_mass_kg: float
    oil: str

    @property
    def bore_area_m2(self) -> float:
        return math.pi * self.bore_m**2 / 4.0

    @property
    def annulus_area_m2(self) -> float:
        return math.pi * (self.bore_m**2 - self.rod_m**2) / 4.0


def read_rig_info(path: str | Path) -> RigInfo:
    """Read the ``/rig/info`` message (contract 3) of an MCAP rig recording.

    Ingest lands ``/rig/pressure``-timeline samples only, not ``/rig/info``, so the
    geometry is read from the recording itself. Uses the summary index when the file
    has one and reads sequentially otherwise (a truncated recording).
    """
    from mcap.reader import NonSeekingReader, make_reader

    from pipelines.ingest.rig_mcap import JsonDecoderFactory

    path = Path(path)
    body = None
    try:
        with path.open("rb") as handle:
            reader = make_reader(handle, decoder_factories=[JsonDecoderFactory()])
            for _schema, _channel, message in reader.iter_messages(topics=["/rig/info"]):
                body = json.loads(message.data)
                break
    except Exception:  # truncated: no summary; the info message comes first anyway
        with path.open("rb") as handle:
            reader = NonSeekingReader(handle, decoder_factories=[JsonDecoderFactory()])
            try:
                for _schema, channel, message in reader.iter_messages():
                    if channel.topic == "/rig/info":
                        body = json.loads(message.data)
                        break
            except Exception:
                body = None
    if not isinstance(body, dict):
        raise CalibrationError(f"{path}: no readable /rig/info message")
    try:
        return RigInfo(
            rig_id=str(body["rig_id"]),
            bore_m=float(body["bore_mm"]) * 1e-3,
            rod_m=float(body["rod_mm"]) * 1e-3,
            stroke_m=float(body["stroke_mm"]) * 1e-3,
            moving_mass_kg=float(body["moving_mass_kg"]),
            oil=str(body.get("oil", "")),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationError(f"{path}: /rig/info is missing or has a bad field ({exc})") from None


# ---------------------------------------------------------------------------------------
# Hoist-description snippet
# ---------------------------------------------------------------------------------------
def _toml_string(text: str) -> str:
    return json.dumps(text)  # a JSON string is a valid TOML basic string


def friction_toml(
    law: FrictionLaw, *, bore_m: float, parameter_set: str, source: str, comment: str = ""
) -> str:
    """The ``[friction]`` section of a hoist description for ``law`` (contract 2).

    Forces are written as the equivalent pressure of a ``bore_m`` piston (force / bore
    area) in MPa, speeds in mm/s, pressures in MPa: the layout of
    :class:`schemas.hoist.Friction`, whose :meth:`~schemas.hoist.Friction.law` inverts
    this conversion. ``comment`` lines go on top, prefixed with ``#``.
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
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------
# Orchestration
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`calibrate_rig` found and landed.

    ``per_pressure`` is the analogue of paper Table 1 (SI, 1-sigma), ``lines`` the
    eq-17 lines (keys :data:`LINE_NAMES`, SI per Pa, residuals per pressure), ``law``
    the :class:`~schemas.hoist.FrictionLaw` (SI), ``toml`` the ``[friction]`` section
    for a hoist description, ``steps`` the per-step steady means the fits used,
    ``inputs`` the source sha256 of the rig samples read.
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


def _rig_ids(data: DataRoot) -> list[str]:
    parts = lake_partitions(data, "rig_samples")
    return sorted(parts.filter(pl.col("site") == _SITE)["hoist"].unique().to_list())


def _manifest_rows(data: DataRoot, shas: Sequence[str]) -> pl.DataFrame:
    from warehouse.store import open_reader

    try:
        con = open_reader(data)
    except FileNotFoundError:
        return pl.DataFrame(
            schema={
                "source_sha256": pl.String,
                "source_path": pl.String,
                "hoist": pl.String,
                "time_start_utc": pl.Datetime("us", "UTC"),
                "time_end_utc": pl.Datetime("us", "UTC"),
            }
        )
    try:
        return con.sql(
            "SELECT source_sha256, source_path, hoist, time_start_utc, time_end_utc "
            "FROM manifest WHERE list_contains(?, source_sha256)",
            params=[list(shas)],
        ).pl()
    finally:
        con.close()


def _ingest(
    recordings: Sequence[Path], data: DataRoot
) -> tuple[list[str], list[RigInfo], list[str]]:
    from pipelines.ingest import ingest_paths

    report = ingest_paths(list(recordings), data=data)
    refused = [f for f in report.files if f.status == "refused"]
    if refused:
        raise CalibrationError("; ".join(f.message or f"{f.path}: refused" for f in refused))
    notes = [f"{f.path.name}: {f.status} {f.message}".rstrip() for f in report.files]
    infos = [read_rig_info(f.path) for f in report.files]
    return [f.sha256 for f in report.files], infos, notes


def _recorded_infos(data: DataRoot, inputs: Sequence[str], rig_id: str) -> list[RigInfo]:
    """``/rig/info`` of the ingested recordings still at their manifest source paths."""
    infos: list[RigInfo] = []
    for row in _manifest_rows(data, inputs).iter_rows(named=True):
        if Path(row["source_path"]).is_file():
            info = read_rig_info(row["source_path"])
            if info.rig_id == rig_id:
                infos.append(info)
    return infos


def _geometry(
    infos: Sequence[RigInfo],
    rig_id: str,
    *,
    bore_m: float | None,
    rod_m: float | None,
    moving_mass_kg: float | None,
) -> RigInfo:
    explicit = None not in (bore_m, rod_m, moving_mass_kg)
    if not infos and not explicit:
        raise CalibrationError(
            f"rig {rig_id!r}: no /rig/info (ingest does not land it and the recorded files "
            "are not at their ingested paths); pass the recordings, or bore_m, rod_m and "
            "moving_mass_kg"
        )
    if infos:
        first = infos[0]
        for other in infos[1:]:
            same = (other.bore_m, other.rod_m, other.moving_mass_kg)
            if not np.allclose(same, (first.bore_m, first.rod_m, first.moving_mass_kg)):
                raise CalibrationError(
                    f"rig {rig_id!r}: recordings disagree on bore / rod / moving mass "
                    f"({first} vs {other}); calibrate them separately"
                )
    else:
        first = RigInfo(rig_id, 0.0, 0.0, float("nan"), 0.0, "")
    return RigInfo(
        rig_id=rig_id,
        bore_m=first.bore_m if bore_m is None else bore_m,
        rod_m=first.rod_m if rod_m is None else rod_m,
        stroke_m=first.stroke_m,
        moving_mass_kg=first.moving_mass_kg if moving_mass_kg is None else moving_mass_kg,
        oil=first.oil,
    )


def _check_names(rig_id: str | None, parameter_set: str | None) -> None:
    try:  # a rig id is a lake folder, a parameter set a hoist description's name
        for key, value in (("--rig", rig_id), ("--parameter-set", parameter_set)):
            if value is not None:
                safe_name(value, key=key, source="ropeload calibrate")
    except UnsafeNameError as exc:
        raise CalibrationError(str(exc)) from None


def _select_rig(
    data: DataRoot, recordings: Sequence[str | Path], rig_id: str | None
) -> tuple[str, list[str], list[RigInfo], list[str]]:
    """The rig to calibrate, the given recordings' sha256 and ``/rig/info``, and notes."""
    notes: list[str] = []
    given_shas: list[str] = []
    infos: list[RigInfo] = []
    if recordings:
        given_shas, infos, ingest_notes = _ingest([Path(r) for r in recordings], data)
        notes += ingest_notes
        ids = sorted({i.rig_id for i in infos})
        if rig_id is None and len(ids) > 1:
            raise CalibrationError(f"recordings of several rigs ({', '.join(ids)}): pass one rig")
        rig_id = rig_id or ids[0]
        infos = [i for i in infos if i.rig_id == rig_id]
        if not infos:
            raise CalibrationError(
                f"none of the recordings is of rig {rig_id!r} ({', '.join(ids)})"
            )
    elif rig_id is None:
        ids = _rig_ids(data)
        if len(ids) != 1:
            found = ", ".join(ids) if ids else "none"
            raise CalibrationError(
                f"no rig samples to calibrate in {data.path} (rigs found: {found}); "
                "ingest MCAP recordings or pass them, and name the rig when there are several"
            )
        rig_id = ids[0]
    return rig_id, given_shas, infos, notes


def _rig_samples(data: DataRoot, rig_id: str, given_shas: Sequence[str]) -> pl.DataFrame:
    """The rig's samples in the lake: those of the given recordings, or all of them."""
    if given_shas:
        manifest = _manifest_rows(data, given_shas).filter(pl.col("hoist") == rig_id)
        parts = [
            scan_lake(
                data,
                "rig_samples",
                site=_SITE,
                hoist=rig_id,
                start=row["time_start_utc"],
                end=row["time_end_utc"] + dt.timedelta(microseconds=1),
            )
            for row in manifest.iter_rows(named=True)
            if row["time_start_utc"] is not None
        ]
        samples = (
            pl.concat([p.collect() for p in parts]).unique(maintain_order=True) if parts else None
        )
    else:
        samples = scan_lake(data, "rig_samples", site=_SITE, hoist=rig_id).collect()
    if samples is None or samples.height == 0:
        raise CalibrationError(
            f"no rig samples for rig {rig_id!r} in {data.path}: ingest its MCAP recordings "
            "first (ropeload ingest FILE.mcap) or pass them to calibrate"
        )
    return samples


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
        notes.append(f"{dropped} moving step(s) without {0.1:g} s of steady data were left out")
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
    law, lines = fit_friction_law(
        per_pressure["p_rodless_pa"].to_numpy(),
        fits,
        bristle_stiffness_n_m=bristle_stiffness_n_m,
        bristle_damping_n_s_m=bristle_damping_n_s_m,
        presliding_elements=presliding_elements,
    )
    return steps, per_pressure, fits, law, lines


def _land(
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
        site=_SITE,
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
    _check_names(rig_id, parameter_set)
    rig_id, given_shas, infos, notes = _select_rig(data, recordings, rig_id)
    samples = _rig_samples(data, rig_id, given_shas)
    inputs = tuple(sorted(set(samples["source_sha256"].unique().to_list()) | set(given_shas)))

    if not infos and None in (bore_m, rod_m, moving_mass_kg):
        infos = _recorded_infos(data, inputs, rig_id)
    rig = _geometry(infos, rig_id, bore_m=bore_m, rod_m=rod_m, moving_mass_kg=moving_mass_kg)

    steps, per_pressure, fits, law, lines = _fit(
        samples, rig, notes, smooth_s=smooth_s, bristle_stiffness_n_m=bristle_stiffness_n_m,
        bristle_damping_n_s_m=bristle_damping_n_s_m, presliding_elements=presliding_elements,
    )  # fmt: skip
    if parameter_set is None:
        digest = hashlib.sha256("\n".join(inputs).encode()).hexdigest()[:12]
        parameter_set = f"{rig_id[:51]}-{digest}"  # a safe name: at most 64 characters
    run_id = f"calibrate-{parameter_set}"
    source = f"ropeload calibrate: rig {rig_id}, {len(inputs)} recording(s), run {run_id}"
    toml = friction_toml(law, bore_m=rig.bore_m, parameter_set=parameter_set, source=source)
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
    )
    _land(data, result, samples, source=source, started=started)
    return result


# ---------------------------------------------------------------------------------------
# Reports
# ---------------------------------------------------------------------------------------
#: Table-1 units of each SI line: (label, unit, scale from SI given the bore area [m2]).
def _table1_units(area_m2: float) -> dict[str, tuple[str, str, float]]:
    force = 1e6 * area_m2  # N per MPa of equivalent pressure
    return {
        "coulomb_n": ("Fc", "MPa", 1.0 / force),
        "static_n": ("Fs", "MPa", 1.0 / force),
        "stribeck_speed_m_s": ("vs", "mm/s", 1e3),
        "viscous_n_s_m": ("Kv", "MPa/(mm/s)", 1e-3 / force),
    }


def format_calibration(result: CalibrationResult) -> str:
    """The report ``ropeload calibrate`` prints: per-pressure table, lines, TOML.

    Table-1 units: friction as equivalent pressure (force / bore area) in MPa, speed in
    mm/s, pressure in MPa; SI forces in N beside them. Each value carries its 1-sigma
    uncertainty (``+-``); each line its standard errors and residual per pressure.
    """
    rig = result.rig
    units = _table1_units(rig.bore_area_m2)
    out = [
        f"ropeload calibrate: rig {result.rig_id}, parameter set {result.parameter_set}, "
        f"run {result.run_id}",
        f"rig: bore {rig.bore_m * 1e3:g} mm, rod {rig.rod_m * 1e3:g} mm, moving mass "
        f"{rig.moving_mass_kg:g} kg; {len(result.inputs)} recording(s), "
        f"{result.steps.height} steady steps",
        *(f"note: {n}" for n in result.notes),
        "",
        "Stribeck fit per pressure (paper eq 16/18; analogue of Table 1), +- 1 sigma.",
        "Friction as equivalent pressure F / A_bore [MPa] (and [N]), speed [mm/s].",
    ]
    header = (
        f"{'p [MPa]':>8} {'steps':>5} {'Fc [MPa]':>18} {'Fs [MPa]':>18} {'vs [mm/s]':>15} "
        f"{'Kv [MPa/(mm/s)]':>22} {'Fc [N]':>8} {'Fs [N]':>8} {'rms [N]':>8}"
    )
    out += [header, "-" * len(header)]
    for row in result.per_pressure.iter_rows(named=True):
        cells = []
        for name, width, fmt in (
            ("coulomb_n", 18, ".4f"),
            ("static_n", 18, ".4f"),
            ("stribeck_speed_m_s", 15, ".3f"),
            ("viscous_n_s_m", 22, ".6f"),
        ):
            scale = units[name][2]
            sigma_key = (
                name.replace("_n", "_sigma_n", 1)
                if name != "stribeck_speed_m_s"
                else ("stribeck_speed_sigma_m_s")
            )
            text = f"{row[name] * scale:{fmt}} +- {row[sigma_key] * scale:{fmt}}"
            cells.append(f"{text:>{width}}")
        out.append(
            f"{row['p_rodless_pa'] / 1e6:8.3f} {row['steps']:5d} {' '.join(cells)} "
            f"{row['coulomb_n']:8.1f} {row['static_n']:8.1f} {row['rms_n']:8.2f}"
        )
    out += ["", "Lines in pressure, value = a + b p (paper eq 17 form), weighted by 1/sigma^2:"]
    p_mpa = result.per_pressure["p_rodless_pa"].to_numpy() / 1e6
    for name in LINE_NAMES:
        label, unit, scale = units[name]
        line = result.lines[name]
        residuals = ", ".join(
            f"{p:.1f}: {r * scale:+.3g}" for p, r in zip(p_mpa, line.residuals, strict=True)
        )
        out.append(
            f"  {label} [{unit}] = {line.intercept * scale:.5g} "
            f"(+- {line.se_intercept * scale:.2g}) + {line.slope * scale * 1e6:.5g} "
            f"(+- {line.se_slope * scale * 1e6:.2g}) p[MPa]"
            f"   R2 {line.r_squared:.4f}"
        )
        out.append(f"      residuals by p [MPa]: {residuals}")
    out += ["", "Hoist description snippet:", "", result.toml.rstrip()]
    return "\n".join(out) + "\n"


def eq17_coefficient_verdict(row: dict) -> str:
    """One coefficient of eq 17 against the OLS fit, in words (a row of
    :func:`transforms.friction_fit.compare_with_eq17`).

    Two separate statements: whether eq 17 prints the OLS value (arithmetic: the OLS
    line of the printed table is unique) and whether it is within the 95 % interval of
    the OLS estimate (statistics: |z| against Student's t).
    """
    printed = "the OLS value to its printed digits" if row["reproduced"] else "not the OLS value"
    z, limit = abs(row["z"]), row["z_limit"]
    if row["consistent"]:
        stat = f"consistent with OLS at 95 % (|z| {z:.2f} < {limit:.2f})"
    else:
        stat = f"differs from OLS at 95 % (|z| {z:.2f} >= {limit:.2f})"
    return f"{printed}; {stat}"


def eq17_line_verdict(row: dict) -> str:
    """The eq-17 line of one parameter as a whole against the OLS line, in words (F
    test of intercept and slope together, their correlation included)."""
    test = f"F {row['line_f']:.2f}, p {row['line_p']:.2g}"
    if row["line_consistent"]:
        return f"line consistent with the OLS line at 95 % ({test})"
    return (
        f"line differs from the OLS line at 95 % ({test}; "
        f"{row['line_gap_se']:.1f} standard errors apart at {row['line_gap_at']:g} MPa)"
    )


def eq17_summary(compare: pl.DataFrame) -> list[str]:
    """What the comparison of eq 17 with OLS says, in a few sentences."""
    rows = list(compare.iter_rows(named=True))
    names = list(dict.fromkeys(r["parameter"] for r in rows))

    def where(test) -> str:
        chosen = [n for n in names if test([r for r in rows if r["parameter"] == n])]
        return ", ".join(chosen) or "none"

    worst = max(abs(r["z"]) for r in rows)
    out = [
        f"Printed digits: eq 17 is the OLS line of Table 1 for "
        f"{where(lambda rs: all(r['reproduced'] for r in rs))}; not for "
        f"{where(lambda rs: not all(r['reproduced'] for r in rs))}.",
    ]
    if all(r["consistent"] for r in rows):
        out.append(
            f"Statistics: every printed coefficient is within the 95 % interval of its OLS "
            f"estimate (largest |z| {worst:.2f} < {rows[0]['z_limit']:.2f})."
        )
    else:
        out.append(
            "Statistics: outside the 95 % interval of the OLS estimate: "
            + ", ".join(
                f"{r['parameter']} {r['coefficient']} (|z| {abs(r['z']):.2f})"
                for r in rows
                if not r["consistent"]
            )
            + "."
        )
    out.append(
        f"Whole lines at 95 %: consistent for "
        f"{where(lambda rs: rs[0]['line_consistent'])}; different for "
        f"{where(lambda rs: not rs[0]['line_consistent'])}."
    )
    return out


def table1_report(table1: pl.DataFrame) -> str:
    """Ordinary least squares through paper Table 1, residuals, and the eq-17 comparison.

    Fits every column of Table 1 as a + b p (p in MPa) by OLS
    (:func:`transforms.friction_fit.fit_table1`), prints each line with standard errors
    and R^2, the residual at each pressure, and then each coefficient of eq 17 as
    printed against the OLS value (:func:`transforms.friction_fit.compare_with_eq17`):
    whether eq 17 prints the OLS value, and whether it is statistically consistent with
    it (per coefficient, |z| against Student's t at 95 %; per line, an F test of both
    coefficients together). Table 1 has no units (NOTES.md): the numbers are Table 1's
    own (friction read as equivalent pressure in MPa, speed in mm/s).

    ``table1`` has the columns of :data:`transforms.friction_fit.TABLE1_COLUMNS`; the
    caller reads the file.
    """
    fits = fit_table1(table1)
    compare = compare_with_eq17(fits)
    p = table1["oil_pressure_mpa"].cast(pl.Float64).to_numpy()
    out = [
        f"Paper Table 1: ordinary least squares, value = a + b p (p in MPa), {p.size} points.",
        "Units as printed (none given; NOTES.md reads friction as equivalent pressure [MPa]",
        "and speed as [mm/s]). +- is one standard error.",
        "",
    ]
    for name, fit in fits.items():
        out.append(
            f"{name:20s} a = {fit.intercept:.6g} +- {fit.se_intercept:.2g}, "
            f"b = {fit.slope:.6g} +- {fit.se_slope:.2g}, R2 = {fit.r_squared:.4f}, "
            f"residual rms = {float(np.sqrt(np.mean(fit.residuals**2))):.3g}"
        )
    out += ["", "Residuals (Table 1 minus OLS line):"]
    names = list(fits)
    out.append(f"{'p [MPa]':>8} " + " ".join(f"{n:>20s}" for n in names))
    for k, pk in enumerate(p):
        out.append(f"{pk:8.1f} " + " ".join(f"{fits[n].residuals[k]:+20.5f}" for n in names))
    rows = list(compare.iter_rows(named=True))
    out += [
        "",
        "Eq 17 as printed against OLS (z = (eq17 - OLS) / se; 95 % two-sided limit "
        f"|z| < {rows[0]['z_limit']:.2f}, Student t, {p.size - 2} degrees of freedom):",
    ]
    for row in rows:
        out.append(
            f"  {row['parameter']:20s} {row['coefficient']:9s} OLS {row['ols']:+.6g} "
            f"eq17 {row['eq17']:+.6g} (diff {row['difference']:+.3g}, z {row['z']:+.2f}): "
            f"{eq17_coefficient_verdict(row)}"
        )
        if row["coefficient"] == "slope":
            out.append(f"  {'':20s} {'':9s} {eq17_line_verdict(row)}")
    out += ["", "Summary:", *(f"  {line}" for line in eq17_summary(compare))]
    out.append("Use the OLS lines (with their residuals), not eq 17, as the fit of Table 1.")
    return "\n".join(out) + "\n"
