"""The inputs of ``ropeload calibrate``: the rig, its geometry and its samples.

:func:`read_rig_info` reads ``/rig/info`` of an MCAP recording (bore, rod, moving
mass); the rig samples are read from the lake (``rig_samples``), those of the given
recordings (ingested first) or all of the rig's. :func:`pipelines.calibrate.calibrate_rig`
calls these in order: :func:`check_names`, :func:`select_rig`, :func:`rig_samples`,
:func:`recorded_infos`, :func:`rig_geometry`.
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from physics.tension import annulus_area_m2, bore_area_m2
from pipelines.ingest.rig_mcap import rig_geometry_problem
from pipelines.lake import lake_partitions, scan_lake
from schemas.names import name_problem
from warehouse.store import DataRoot

__all__ = [
    "RIG_SITE",
    "CalibrationError",
    "RigInfo",
    "check_names",
    "read_rig_info",
    "recorded_infos",
    "rig_geometry",
    "rig_samples",
    "select_rig",
]

#: The lake site of rig recordings.
RIG_SITE = "rig"


class CalibrationError(ValueError):
    """Calibration refused (no samples, refused recording, too few steps or pressures)."""


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
        return bore_area_m2(self.bore_m)

    @property
    def annulus_area_m2(self) -> float:
        return annulus_area_m2(self.bore_m, self.rod_m)


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
            try:  # in file order: an ordered read sorts all (up to the cut) first
                for _schema, channel, message in reader.iter_messages(log_time_order=False):
                    if channel.topic == "/rig/info":
                        body = json.loads(message.data)
                        break
            except Exception:
                body = None
    if not isinstance(body, dict):
        raise CalibrationError(f"{path}: no readable /rig/info message")
    try:
        bore_mm, rod_mm = float(body["bore_mm"]), float(body["rod_mm"])
        mass_kg = float(body["moving_mass_kg"])
        info = RigInfo(
            rig_id=str(body["rig_id"]),
            bore_m=bore_mm * 1e-3,
            rod_m=rod_mm * 1e-3,
            stroke_m=float(body["stroke_mm"]) * 1e-3,
            moving_mass_kg=mass_kg,
            oil=str(body.get("oil", "")),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationError(f"{path}: /rig/info is missing or has a bad field ({exc})") from None
    # the force balance divides by the bore area and needs a positive annulus
    problem = rig_geometry_problem(bore_mm, rod_mm, mass_kg)
    if problem is not None:
        raise CalibrationError(f"{path}: topic /rig/info: {problem}")
    return info


def check_names(rig_id: str | None, parameter_set: str | None) -> None:
    # a rig id is a lake folder, a parameter set a hoist description's name
    for key, value in (("rig", rig_id), ("parameter set", parameter_set)):
        if value is not None:
            problem = name_problem(value)
            if problem is not None:
                raise CalibrationError(f"{key}: {problem}")


def select_rig(
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


def _ingest(
    recordings: Sequence[Path], data: DataRoot
) -> tuple[list[str], list[RigInfo], list[str]]:
    from pipelines.ingest import ingest_paths
    from pipelines.ingest.sources import detect_format, expand_paths

    # before anything lands: a field log given (or found in a folder) here would be
    # ingested into the lake by a command that then fails on its missing /rig/info
    others = [
        f"{path}: not an MCAP rig recording ({kind}); calibrate takes rig recordings, "
        "field logs are landed by 'ropeload ingest'"
        for path in expand_paths(recordings)
        if path.is_file() and (kind := detect_format(path)) != "mcap"
    ]
    if others:
        raise CalibrationError("; ".join(others))
    report = ingest_paths(list(recordings), data=data)
    refused = [f for f in report.files if f.status == "refused"]
    if refused:
        raise CalibrationError("; ".join(f.message or f"{f.path}: refused" for f in refused))
    notes = [f"{f.path.name}: {f.status} {f.message}".rstrip() for f in report.files]
    infos = [read_rig_info(f.path) for f in report.files]
    return [f.sha256 for f in report.files], infos, notes


def _rig_ids(data: DataRoot) -> list[str]:
    parts = lake_partitions(data, "rig_samples")
    return sorted(parts.filter(pl.col("site") == RIG_SITE)["hoist"].unique().to_list())


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


def rig_samples(data: DataRoot, rig_id: str, given_shas: Sequence[str]) -> pl.DataFrame:
    """The rig's samples in the lake: those of the given recordings, or all of them."""
    if given_shas:
        manifest = _manifest_rows(data, given_shas).filter(pl.col("hoist") == rig_id)
        parts = [
            scan_lake(
                data,
                "rig_samples",
                site=RIG_SITE,
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
        samples = scan_lake(data, "rig_samples", site=RIG_SITE, hoist=rig_id).collect()
    if samples is None or samples.height == 0:
        raise CalibrationError(
            f"no rig samples for rig {rig_id!r} in {data.path}: ingest its MCAP recordings "
            "first (ropeload ingest FILE.mcap) or pass them to calibrate"
        )
    return samples


def recorded_infos(data: DataRoot, inputs: Sequence[str], rig_id: str) -> list[RigInfo]:
    """``/rig/info`` of the ingested recordings still at their manifest source paths."""
    infos: list[RigInfo] = []
    for row in _manifest_rows(data, inputs).iter_rows(named=True):
        if Path(row["source_path"]).is_file():
            info = read_rig_info(row["source_path"])
            if info.rig_id == rig_id:
                infos.append(info)
    return infos


def rig_geometry(
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
