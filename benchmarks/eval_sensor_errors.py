"""Evaluate discovery on small sensor errors written into independent records (issue 14).

Not a unit test: a script. The validation trials hold two hidden effects between 2 and
5 times the noise (a pipe and a worn groove); issue 14's target at that size (>= 70 %
named) is judged on records that hold more. A sensor's zero or span error is one such
effect that can be made exactly in data ropeload did not generate: it changes what the
logger wrote, not the hoist. So each record hiding nothing (the independent simulator's
``none`` trials and its field days, :func:`eval_undeclared.full_records`) is written
again with one sensor reading ``gain x p + offset`` (:func:`record_variants.sensor_error`,
to the file's resolution), and discovery must name ``sensor_offset`` or ``sensor_gain``.

The cases are fixed, not drawn: per record one offset and one gain error, on the sensor
and with the sign the record's place in the list gives, at 2.5 or 4 times the noise by
turns (:func:`cases`). The size is issue 14's: the RMS of the change over the four
sensors' readings over the 5 kPa noise of the validation README (an offset on one
sensor of 25 kPa is 2.5x). The hoist TOML is the record's own (it declares neither
effect), so what is found is the injected error.

Prints a line per case, the confusion matrix, top-1 by size, the median variance
removed ((gap_before^2 - gap_after^2) / effect_rms^2) and seconds per record.

    uv run python benchmarks/eval_sensor_errors.py [--only NAMES] [--sizes 2.5,4] [--keep DIR]
"""

from __future__ import annotations

import argparse
import gzip
import shutil
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from eval_trials import (  # the sibling scripts
    SIZE_BANDS,
    TrialOutcome,
    _one_line,
    _print_confusion,
    discover_record,
)
from eval_undeclared import (
    Record,
    chosen,
    full_records,
    print_crashes_and_seconds,
    record_arguments,
)
from record_variants import pressure_rms_pa, read_log, sensor_error, write_changed

#: The validation README's sensor noise [Pa]: the size's unit.
NOISE_PA = 5e3
#: The sizes the cases take by turns, in noise RMS.
SIZES_X_NOISE = (2.5, 4.0)


@dataclass(frozen=True)
class Case:
    """One sensor error written into a record: the effect it is, the sensor, the error's
    offset [Pa] or gain, and its intended size (x the noise)."""

    effect: str
    sensor: int
    offset_pa: float
    gain: float
    size_x_noise: float

    @property
    def name(self) -> str:
        if self.effect == "sensor_offset":
            return f"p{self.sensor}{self.offset_pa / 1e3:+.0f}kPa"
        return f"p{self.sensor}x{self.gain:.4f}"


def cases(index: int, p_rms_pa: float, sizes: tuple[float, ...] = SIZES_X_NOISE) -> Iterator[Case]:
    """The two cases of the ``index``-th record, whose sensors read ``p_rms_pa`` RMS: an
    offset and a gain error on sensors ``index % 4 + 1`` and the next, of opposite
    signs, ``sizes`` by turns (the gain's from the readings' RMS)."""
    sign = 1.0 if index % 2 == 0 else -1.0
    sensor = index % 4 + 1
    size = sizes[index % len(sizes)]
    change = 2.0 * size * NOISE_PA  # on one sensor of four: the RMS over four is half
    yield Case("sensor_offset", sensor, sign * round(change, -3), 1.0, size)
    size = sizes[(index + 1) % len(sizes)]
    gain = 1.0 - sign * 2.0 * size * NOISE_PA / p_rms_pa
    yield Case("sensor_gain", sensor % 4 + 1, 0.0, round(gain, 4), size)


def evaluate(
    records: list[tuple[int, Record]],
    work: Path,
    *,
    keep: bool = False,
    sizes: tuple[float, ...] = SIZES_X_NOISE,
) -> list[TrialOutcome]:
    """Every case of every (index in the full list, record) under ``work``: one line
    each; a case's data root is removed once analysed unless ``keep``; a record that
    cannot be unpacked or sized is one crashed line, a case that cannot be written its
    crash, and the run goes on."""
    print(
        f"{'record':14s} {'case':14s} {'hidden effect':16s} {'size':>5s} {'answer':22s}"
        f"{'gap0':>8s}{'gap1':>8s} {'disc s':>6s}  parameters / ranked first"
    )
    outcomes = []
    for index, record in records:
        inputs = work / "inputs" / record.name
        inputs.mkdir(parents=True, exist_ok=True)
        csv = inputs / f"{record.name}.csv"
        try:
            with gzip.open(record.csv_gz, "rb") as src, csv.open("wb") as dst:
                shutil.copyfileobj(src, dst)
            p_rms = pressure_rms_pa(read_log(csv), 1)  # a gain's change scales with it
            if not p_rms > 0.0:
                raise ValueError("sensor 1 logs no pressure: no gain error to size")
        except Exception as exc:  # the record's cases end here; the run goes on
            crashed = TrialOutcome(record.name, "(record)", np.nan, 0.0, reason=_one_line(exc))
            outcomes.append(crashed)
            print(f"{record.name:14s} crashed: {crashed.reason}", flush=True)
            csv.unlink(missing_ok=True)
            continue
        for case in cases(index, p_rms, sizes):
            stem = f"{record.name}-{case.name}"
            label = f"{record.name} {case.name}"
            key = {"hidden_effect": case.effect, "rms_over_noise": np.nan, "effect_rms_pa": 0.0}
            try:
                error = sensor_error(case.sensor, offset_pa=case.offset_pa, gain=case.gain)
                changed, rms = write_changed(csv, case.name, error)
                key |= {"rms_over_noise": rms / NOISE_PA, "effect_rms_pa": rms}
                o = discover_record(changed, record.toml, label, stem, key, work)
            except Exception as exc:  # a case that could not be written: its crash
                o = TrialOutcome(label, case.effect, np.nan, 0.0, reason=_one_line(exc))
            finally:
                csv.with_name(f"{csv.stem}-{case.name}.csv").unlink(missing_ok=True)
                if not keep:
                    shutil.rmtree(work / "data" / stem, ignore_errors=True)
            outcomes.append(o)
            print(_line(o, record.name, case), flush=True)
        csv.unlink(missing_ok=True)
    return outcomes


def _line(o: TrialOutcome, record: str, case: Case) -> str:
    r = o.report
    mark = "ok " if o.answer == o.hidden else "   "
    ranked = [x.get("effect") for x in r.get("ranking") or []][:3]
    said = r.get("parameters") if o.answer == o.hidden else ", ".join(map(str, ranked))
    gaps = [r.get(k) for k in ("gap_before_pa", "gap_after_pa")]
    kpa = "".join(f"{g / 1e3:8.1f}" if g is not None else f"{'-':>8s}" for g in gaps)
    return (
        f"{record:14s} {case.name:14s} {o.hidden:16s} {o.rms_over_noise:5.2f} "
        f"{mark}{o.answer:19s}{kpa} {o.discover_s:6.1f}  {said} {o.reason}"
    )


def summary(outcomes: list[TrialOutcome]) -> None:
    """Confusion, top-1 by size, variance removed, seconds."""
    _print_confusion(outcomes)
    print("\ntop-1 accuracy by effect size (RMS of the change over the noise)")
    for label, lo, hi, target in SIZE_BANDS:
        band = [o for o in outcomes if lo <= o.rms_over_noise < hi]
        hits = sum(o.answer == o.hidden for o in band)
        goal = f" (issue 14's target {target:.0%})" if target is not None else ""
        share = f"{hits}/{len(band)}" + (f" = {hits / len(band):.0%}" if band else "")
        print(f"  {label:12s} {share}{goal}")
    for effect in ("sensor_offset", "sensor_gain"):
        mine = [o for o in outcomes if o.hidden == effect]
        print(f"  {effect}: {sum(o.answer == effect for o in mine)}/{len(mine)} named")
    removed = [o.variance_removed for o in outcomes if o.variance_removed is not None]
    if removed:
        print(
            "median share of the error's variance removed, (gap_before^2 - gap_after^2) / "
            f"effect_rms^2: {np.median(removed):.0%} over the {len(removed)} named"
        )
    print_crashes_and_seconds(outcomes)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    record_arguments(ap)
    ap.add_argument(
        "--sizes", default=",".join(map(str, SIZES_X_NOISE)), metavar="X,Y",
        help="the errors' sizes in noise RMS, taken by turns (default 2.5,4.0)",
    )  # fmt: skip
    args = ap.parse_args()
    sizes = tuple(float(v) for v in args.sizes.split(",") if v.strip())
    if not sizes or not all(v > 0 for v in sizes):
        ap.error(f"--sizes {args.sizes!r}: one or more positive sizes, comma-separated")
    every = full_records(args.trials, args.days)
    records = [(k, every[k]) for k in chosen(every, args.only, ap)]  # the place: the case
    started = time.perf_counter()
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
        outcomes = evaluate(records, args.keep.absolute(), keep=True, sizes=sizes)
    else:
        with tempfile.TemporaryDirectory(prefix="ropeload-sensor-errors-") as tmp:
            outcomes = evaluate(records, Path(tmp), sizes=sizes)
    summary(outcomes)
    print(f"\nwall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
