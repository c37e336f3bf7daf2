"""What the logged pistons say about a hidden effect: the ropes' identification with and
without it (issue 14, validation trials; a diagnosis, not a target).

Discovery judges a candidate effect by the replay's pressure gap. The ropes the replay
uses were identified from the logged piston positions x (:mod:`transforms.
rope_identification`) with the model the hoist declares; an effect that changes what the
identification reads (a branch pipe or valve, the oil, the sensors, a worn groove) biases
them when it is missing, and the pressure gap then judges the candidate on biased ropes
(validation trial_001, a pipe: 13.1 kPa as found, 8.2 kPa with the world's pipe written
into the description and the ropes read with it; trial_009, a groove wear: 16.9 against
11.8 kPa). The identification's own residual, the RMS of the model's x against the logged
x (``RopeSprings.mismatch_m``), is a second, independent measure of the same question.

For each trial this prints that residual with the description as given, with the answer's
hidden effect written into it (:func:`pipelines.identified_ropes.identified_ropes_under`,
where the identification reads that effect), and with the same effect the other way (a
groove's radii negated, a pipe's resistance divided instead of multiplied at the
described bore, the oil's bulk modulus as far above the description's as the world's is
below, a sensor's offset or gain error the other way; a valve's is its described
coefficient, as found), and the identified stiffness factors. The answer's
parameters are read from ``answers.json`` (the key): this measures how far the logged x
could tell a candidate's coordinates, and is not used by ropeload.

    uv run python benchmarks/diagnose_identification_evidence.py [--only trial_001,...]
        [--data-roots DIR]   # data roots kept by eval_discovery.py --trials --keep DIR/..
"""

from __future__ import annotations

import argparse
import gzip
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from eval_trials import DEFAULT_TRIALS, ingest_record  # the sibling script

#: Effects the identification reads (:data:`pipelines.identified_ropes._DESCRIBED`, the
#: sensors and the drum).
READ_BY_IDENTIFICATION = (
    "pipe_laminar_loss",
    "local_loss",
    "viscosity_temperature",
    "oil_compressibility",
    "sensor_offset",
    "sensor_gain",
    "groove_wear",
)


def effect_parameters(hoist: Any, key: dict[str, Any], sign: float) -> dict[str, Any]:
    """The answer's hidden effect in :mod:`sims.effects` names (``sign`` -1: the same
    size the other way), or {} where the key's parameters do not map."""
    name, p = key["hidden_effect"], key["parameters"]
    pp = hoist.piping
    if name == "pipe_laminar_loss":
        described = pp.length_chamber_to_sensor_m + pp.length_sensor_to_manifold_m
        length, bore = p["length_m"] / described, p["bore_m"]
        if sign < 0:  # the description's bore, the resistance as far below as the world's is above
            ratio = (length / bore**4) / (1.0 / pp.bore_m**4)
            length, bore = 1.0 / ratio, pp.bore_m
        return {
            "length_chamber_to_sensor_m": length * pp.length_chamber_to_sensor_m,
            "length_sensor_to_manifold_m": length * pp.length_sensor_to_manifold_m,
            "bore_m": bore,
        }
    if name == "groove_wear":
        return {"groove_radius_deviation_m": [sign * d * 1e-3 for d in p["dr_mm"]]}
    if name == "oil_compressibility":
        beta = p["beta_pa"]
        return {"bulk_modulus_pa": beta if sign > 0 else hoist.oil.bulk_modulus_pa**2 / beta}
    if name == "local_loss":
        k = p["k"] if sign > 0 else hoist.piping.valve_loss_coefficient
        return {"valve_loss_coefficient": k}
    if name == "sensor_offset":
        return {"sensor": int(p["sensor"]), "offset_pa": sign * p["offset_mpa"] * 1e6}
    if name == "sensor_gain":
        return {"sensor": int(p["sensor"]), "gain": 1.0 + sign * (p["gain"] - 1.0)}
    return {}


def _data_root(folder: Path, roots: Path | None, work: Path) -> Path:
    """The trial's data root: kept by an evaluation, else ingested into ``work``."""
    if roots is not None and (roots / folder.name).is_dir():
        return roots / folder.name
    csv = work / f"{folder.name}.csv"
    with gzip.open(folder / f"{folder.name}.csv.gz", "rb") as src, csv.open("wb") as dst:
        shutil.copyfileobj(src, dst)
    try:
        data, _ = ingest_record(csv, folder / "hoist.toml", work / folder.name)
    except RuntimeError as exc:
        raise SystemExit(f"diagnose_identification_evidence: {folder.name}: {exc}") from exc
    finally:
        csv.unlink()
    return data.path


def _line(label: str, springs: Any, seconds: float) -> str:
    if springs is None:
        return f"    {label:<26} no ropes within the bounds fit the logged x ({seconds:.1f} s)"
    factors = " ".join(f"{f:.4f}" for f in springs.stiffness_factors)
    return (
        f"    {label:<26} x mismatch {springs.mismatch_m * 1e3:.4f} mm   factors {factors}"
        f"   ({seconds:.1f} s)"
    )


def diagnose(folder: Path, key: dict[str, Any], roots: Path | None, work: Path) -> None:
    from pipelines.identified_ropes import identified_ropes, identified_ropes_under
    from pipelines.ingest.field_checks import within_limits
    from pipelines.lake import scan_lake
    from schemas.hoist import load_hoist
    from warehouse.store import DataRoot

    hoist = load_hoist(folder / "hoist.toml")
    data = DataRoot.resolve(_data_root(folder, roots, work))
    samples = within_limits(
        scan_lake(
            data,
            "field_samples",
            site=hoist.hoist.site,
            hoist=hoist.hoist.name,
            start=None,
            end=None,
        ),
        hoist,
    ).collect()
    name = key["hidden_effect"]
    print(f"{folder.name}  hidden {name}  {key['rms_over_noise']:.2f} x the noise")
    started = time.perf_counter()
    print(_line("as described", identified_ropes(samples, hoist), time.perf_counter() - started))
    if name not in READ_BY_IDENTIFICATION:
        return
    grown = hoist.with_effects([*hoist.model.effects, name])
    for label, sign in (("the answer written in", 1.0), ("the other way", -1.0)):
        given = effect_parameters(hoist, key, sign)
        if not given:
            continue
        started = time.perf_counter()
        springs = identified_ropes_under(samples, grown, {name: given})
        print(_line(label, springs, time.perf_counter() - started))


def main() -> None:
    import json

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=Path, default=DEFAULT_TRIALS, metavar="DIR")
    ap.add_argument("--only", default=None, metavar="NAMES", help="e.g. trial_001,trial_009")
    ap.add_argument("--data-roots", type=Path, default=None, metavar="DIR")
    args = ap.parse_args()
    keys = {t["trial"]: t for t in json.loads((args.trials / "answers.json").read_text())["trials"]}
    only = [n.strip() for n in args.only.split(",")] if args.only else sorted(keys)
    unknown = [n for n in only if n not in keys]
    if unknown:
        raise SystemExit(f"diagnose_identification_evidence: --only: unknown {', '.join(unknown)}")
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="ropeload-ident-") as tmp:
        for name in only:
            diagnose(args.trials / name, keys[name], args.data_roots, Path(tmp))
            sys.stdout.flush()
    print(f"wall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
