"""Evaluate discovery on independent records with a declared effect taken out (issue 14).

Not a unit test: a script. The validation trials hide one effect each, eleven in all.
More cases come from the records that hide nothing:

- the independent simulator's ``none`` trials (``../shared/validation/trials/``);
- its field days (``../shared/validation/days/``).

Each such record's hoist TOML declares every effect of its world in ``[model]
effects``. Take one of them out, and the record hides that effect at the description's
own values: a case whose answer is known, in data ropeload did not generate. A record
with a full TOML gives 1 + (effects declared) cases:

- the record as described, where the answer is ``none``;
- one case per declared effect, that effect taken out.

Each case is ingested into its own data root and analysed by
:func:`pipelines.discover.discover_period`, as ``--trials`` does
(:func:`eval_trials.discover_record`).

The size of a hidden effect is not in any key here. It is measured as the excess it
leaves in the baseline's replay gap over the same record's gap as described:
``sqrt(gap_before^2 - gap_described^2)`` over the record's noise. That is what the data
show of it once the per-trip payloads have taken their part. A pipe loss at the
described 1 m x 6 mm pipe, for example, is below the noise.

The script prints a line per case, a confusion matrix, top-1 accuracy by that size, false
alarms on the records as described, and the gap after each named effect against the
record's own gap as described.

    uv run python benchmarks/eval_undeclared.py [--only trial_004,mine_day103] [--keep DIR]
"""

from __future__ import annotations

import argparse
import gzip
import json
import re
import shutil
import tempfile
import time
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from eval_trials import (  # the sibling scripts
    DEFAULT_TRIALS,
    SIZE_BANDS,
    TrialOutcome,
    _one_line,
    _print_confusion,
    discover_record,
)

DEFAULT_DAYS = DEFAULT_TRIALS.parent / "days"
#: ``[model]`` and what follows it up to the next table header.
_MODEL_TABLE = re.compile(r"^\[model\][ \t]*$(.*?)(?=^\[|\Z)", re.MULTILINE | re.DOTALL)
_EFFECTS_KEY = re.compile(r"^effects\s*=\s*\[[^\]]*\]", re.MULTILINE)


@dataclass(frozen=True)
class Record:
    """A record that hides nothing: its compressed CSV and its hoist TOML."""

    name: str
    csv_gz: Path
    toml: Path


def full_records(trials: Path, days: Path) -> list[Record]:
    """The ``none`` trials of ``trials/answers.json`` and every field day in ``days``
    (those with both their record and their hoist TOML)."""
    records = []
    answers = trials / "answers.json"
    if answers.exists():
        for t in json.loads(answers.read_text())["trials"]:
            folder = trials / t["trial"]
            if t["hidden_effect"] == "none" and folder.is_dir():
                records.append(
                    Record(t["trial"], folder / f"{t['trial']}.csv.gz", folder / "hoist.toml")
                )
    for gz in sorted(days.glob("*.csv.gz")):
        name = gz.name.removesuffix(".csv.gz")
        records.append(Record(name, gz, days / f"{name}.hoist.toml"))
    return [r for r in records if r.csv_gz.is_file() and r.toml.is_file()]


def without_effect(toml_text: str, effect: str) -> str:
    """``toml_text`` with ``effect`` taken out of ``[model] effects`` (KeyError if absent,
    ValueError if the key cannot be rewritten in place)."""
    effects = list(tomllib.loads(toml_text)["model"]["effects"])
    if effect not in effects:
        raise KeyError(f"{effect} is not declared")
    kept = [e for e in effects if e != effect]
    table = _MODEL_TABLE.search(toml_text)
    if table is None:
        raise ValueError("the [model] effects key could not be rewritten")
    listed = "effects = [" + ", ".join(f'"{e}"' for e in kept) + "]"
    body, count = _EFFECTS_KEY.subn(lambda _: listed, table.group(1), count=1)
    text = toml_text[: table.start(1)] + body + toml_text[table.end(1) :]
    if count != 1 or tomllib.loads(text)["model"]["effects"] != kept:
        raise ValueError("the [model] effects key could not be rewritten")
    return text


def cases(record: Record) -> Iterator[tuple[str, str]]:
    """(hidden effect or ``none``, TOML text) of each case ``record`` makes."""
    text = record.toml.read_text()
    yield "none", text
    for effect in tomllib.loads(text)["model"]["effects"]:
        yield effect, without_effect(text, effect)


def _gap(o: TrialOutcome, key: str = "gap_before_pa") -> float:
    value = o.report.get(key)
    return float(value) if value is not None else float("nan")


def excess_over_noise(o: TrialOutcome, described: TrialOutcome) -> float:
    """The hidden effect's excess in the baseline's gap over the record's gap as
    described, over the record's noise (NaN when either crashed)."""
    before, floor = _gap(o), _gap(described)
    noise = float(o.report.get("noise_pa") or np.nan)
    if not (np.isfinite(before) and np.isfinite(floor)):
        return float("nan")
    return float(np.sqrt(max(before**2 - floor**2, 0.0)) / noise)


def evaluate(records: list[Record], work: Path, *, keep: bool = False) -> None:
    """Every case of every record under ``work``: one line each, then the summary. A
    case's data root is removed once it is analysed unless ``keep``; a record that
    cannot be unpacked or rewritten is one crashed case, and the run goes on."""
    print(
        f"{'record':14s} {'hidden effect':22s} {'answer':22s}{'gap0':>8s}{'gap1':>8s}"
        f"{'excess':>8s} {'disc s':>6s}  ranked first"
    )
    rows: list[tuple[TrialOutcome, float, float]] = []  # (outcome, excess x noise, floor)
    for record in records:
        inputs = work / "inputs" / record.name
        inputs.mkdir(parents=True, exist_ok=True)
        csv = inputs / f"{record.name}.csv"
        described: TrialOutcome | None = None
        try:
            with gzip.open(record.csv_gz, "rb") as src, csv.open("wb") as dst:
                shutil.copyfileobj(src, dst)
            for hidden, text in cases(record):
                stem = f"{record.name}-no-{hidden}" if hidden != "none" else record.name
                toml = inputs / f"{stem}.toml"
                toml.write_text(text)
                key = {"hidden_effect": hidden, "rms_over_noise": np.nan, "effect_rms_pa": 0.0}
                o = discover_record(csv, toml, record.name, stem, key, work)
                if not keep:
                    shutil.rmtree(work / "data" / stem, ignore_errors=True)
                described = o if hidden == "none" else described
                assert described is not None
                excess = excess_over_noise(o, described) if hidden != "none" else 0.0
                rows.append((o, excess, _gap(described)))
                print(_line(o, excess), flush=True)
        except Exception as exc:  # the record's cases end here; the run goes on
            crashed = TrialOutcome(record.name, "(record)", np.nan, 0.0, reason=_one_line(exc))
            rows.append((crashed, float("nan"), float("nan")))
            print(_line(crashed, float("nan")), flush=True)
        finally:
            csv.unlink(missing_ok=True)
    summary(rows)


def _line(o: TrialOutcome, excess: float) -> str:
    ranked = [x.get("effect") for x in o.report.get("ranking") or []][:3]
    mark = "ok " if o.answer == o.hidden else "   "
    return (
        f"{o.name:14s} {o.hidden:22s} {mark}{o.answer:19s}"
        f"{_gap(o) / 1e3:8.1f}{_gap(o, 'gap_after_pa') / 1e3:8.1f}{excess:7.1f}x"
        f" {o.discover_s:6.1f}  {', '.join(map(str, ranked))} {o.reason}"
    )


def summary(rows: list[tuple[TrialOutcome, float, float]]) -> None:
    """Confusion, top-1 by size, false alarms, the gap after against the record's own."""
    _print_confusion([o for o, _, _ in rows])
    hidden = [(o, x, f) for o, x, f in rows if o.hidden != "none"]
    print(
        "\ntop-1 accuracy by the hidden effect's excess over the record's gap as described "
        "(a proxy for its size: what the data show of it once the payloads took their part)"
    )
    for label, lo, hi, target in SIZE_BANDS:
        band = [o for o, x, _ in hidden if lo <= x < hi]
        hits = sum(o.answer == o.hidden for o in band)
        goal = f" (issue 14's target for the size >= {target:.0%})" if target is not None else ""
        share = f"{hits}/{len(band)}" + (f" = {hits / len(band):.0%}" if band else "")
        print(f"  {label:12s} {share}{goal}")
    unknown = [o for o, x, _ in hidden if not np.isfinite(x)]
    if unknown:
        print(f"  size unknown (a crash): {len(unknown)}, each a miss")
    described = [o for o, _, _ in rows if o.hidden == "none"]
    alarms = [o for o in described if o.answer not in ("none", "crash")]
    print(
        f"false alarms on the records as described: {len(alarms)}/{len(described)}"
        + (" (" + ", ".join(f"{o.name}: {o.answer}" for o in alarms) + ")" if alarms else "")
    )
    named = [(o, f) for o, _, f in hidden if o.answer == o.hidden and np.isfinite(f)]
    if named:
        ratios = [_gap(o, "gap_after_pa") / f for o, f in named]
        print(
            "gap after the effects found (the hidden one named) over the record's gap as "
            f"described: median {np.median(ratios):.2f}, worst {max(ratios):.2f} "
            f"({len(named)} named)"
        )
    print_crashes_and_seconds([o for o, _, _ in rows])


def print_crashes_and_seconds(outcomes: list[TrialOutcome]) -> None:
    """The crashed cases with their reasons, and the discovery's seconds per record."""
    crashes = [o for o in outcomes if o.answer == "crash"]
    print(f"crashes: {len(crashes)}/{len(outcomes)}")
    for o in crashes:
        print(f"  {o.name} {o.hidden}: {o.reason}")
    seconds = [o.discover_s for o in outcomes if np.isfinite(o.discover_s)]
    if seconds:
        print(
            "seconds per record (discover, wall): "
            f"median {np.median(seconds):.1f}, max {max(seconds):.1f}"
        )


def record_arguments(ap: argparse.ArgumentParser) -> None:
    """The options of a script over the records hiding nothing."""
    ap.add_argument("--trials", type=Path, default=DEFAULT_TRIALS, help="the trials folder")
    ap.add_argument("--days", type=Path, default=DEFAULT_DAYS, help="the field days folder")
    ap.add_argument("--only", default=None, metavar="NAMES", help="e.g. trial_004,mine_day103")
    ap.add_argument("--keep", type=Path, default=None, metavar="DIR", help="work in DIR, keep it")


def chosen(records: list[Record], only: str | None, ap: argparse.ArgumentParser) -> list[int]:
    """The places in ``records`` of those ``only`` names (comma-separated; every one
    without it); ``ap.error`` for a name no record has."""
    if not only:
        return list(range(len(records)))
    names = {n.strip() for n in only.split(",") if n.strip()}
    unknown = sorted(names - {r.name for r in records})
    if unknown:
        ap.error(f"no record hiding nothing is called {', '.join(unknown)}")
    return [k for k, r in enumerate(records) if r.name in names]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    record_arguments(ap)
    args = ap.parse_args()
    records = full_records(args.trials, args.days)
    records = [records[k] for k in chosen(records, args.only, ap)]
    started = time.perf_counter()
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
        evaluate(records, args.keep.absolute(), keep=True)
    else:
        with tempfile.TemporaryDirectory(prefix="ropeload-undeclared-") as tmp:
            evaluate(records, Path(tmp))
    print(f"\nwall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
