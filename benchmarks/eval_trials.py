"""The ``--trials`` evaluation of ``eval_discovery.py`` (issue 14): the hidden-effect
records of an independent simulator, each ingested into a data root of its own and
analysed by :func:`pipelines.discover.discover_period`, with the summary and the
issue-14 targets. Not a unit test: ``eval_discovery.py --trials`` runs it (see its
docstring).
"""

from __future__ import annotations

import datetime as dt
import gzip
import json
import shutil
import tempfile
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from record_parts import split_record  # the sibling scripts
from record_variants import make_variant

#: The effects, in the order the seeded trials hide them and the summaries list them.
EFFECTS = [
    "tail_rope_weight",
    "conveyance_inertia",
    "seal_friction",
    "presliding_hysteresis",
    "oil_compressibility",
    "sensor_offset",
    "sensor_gain",
    "pipe_laminar_loss",
    "local_loss",
    "viscosity_temperature",
    "groove_wear",
]

DEFAULT_TRIALS = Path(__file__).resolve().parents[1].parent / "shared" / "validation" / "trials"
#: Answer columns that are not effect names.
OTHER_ANSWERS = ("none", "ambiguous", "crash")
#: Effect-size bands of ``rms_over_noise``: (label, low, high, top-1 target or None).
SIZE_BANDS = (
    (">= 5x noise", 5.0, np.inf, 0.90),
    ("2-5x noise", 2.0, 5.0, 0.70),
    ("< 2x noise", -np.inf, 2.0, None),
)
#: Issue-14 targets: replay gap on ``none`` records <= this x the noise; false-alarm
#: share; median variance removed; seconds per 2 h record.
TARGET_NONE_GAP_X = 3.0
TARGET_FALSE_ALARMS = 0.05
TARGET_VARIANCE_REMOVED = 0.80
TARGET_SECONDS = 60.0


@dataclass
class TrialOutcome:
    """One validation trial: its key (``answers.json``) and what discovery answered."""

    name: str
    hidden: str
    rms_over_noise: float
    effect_rms_pa: float
    answer: str = "crash"
    report: dict[str, Any] = field(default_factory=dict)
    reason: str = ""
    ingest_s: float = float("nan")
    discover_s: float = float("nan")
    #: CPU seconds of the discovery (all threads; wall time suffers when cores are shared)
    discover_cpu_s: float = float("nan")
    quarantined: int = 0

    @property
    def variance_removed(self) -> float | None:
        """(gap_before^2 - gap_after^2) / effect_rms^2 of the finding that added the
        hidden effect (``None`` when no finding named it or nothing is hidden): issue
        14's figure, the gap before being the model's own fit (contract 5)."""
        return self._removed("gap_before_pa")

    @property
    def effect_share(self) -> float | None:
        """The same with the gap without the added effect at the inputs fitted with it
        (``gap_without_effect_pa``): the variance the added effect itself accounts for,
        of which the baseline's payloads had taken each trip's mean."""
        return self._removed("gap_without_effect_pa")

    def _removed(self, before_key: str) -> float | None:
        if self.hidden == "none" or self.effect_rms_pa <= 0:
            return None
        for f in self.report.get("findings") or [self.report]:
            if f.get("effect") == self.hidden:
                before = float(f.get(before_key, f["gap_before_pa"]))
                after = float(f["gap_after_pa"])
                return (before**2 - after**2) / self.effect_rms_pa**2
        return None


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}"[:300]


def _record_hours(report: dict[str, Any]) -> float:
    try:
        a, b = (dt.datetime.fromisoformat(t) for t in report["period"])
    except (KeyError, TypeError, ValueError):
        return float("nan")
    return (b - a).total_seconds() / 3600.0


def run_trial(
    folder: Path, key: dict[str, Any], work: Path, parts: int = 1, variant: str = ""
) -> list[TrialOutcome]:
    """Ingest one trial into its own data root, run ``ropeload discover``'s function
    over the whole record, read the report JSON back; a crash is caught and named. With
    ``parts`` > 1 the record is cut into that many consecutive records
    (:func:`record_parts.split_record`: each starts and ends wherever the cut falls, as
    an export's), each ingested and analysed on its own: one outcome each, named
    ``trial_NNN k/parts``; the key's ``effect_rms_pa`` is the whole record's. ``variant``:
    each record (each part) as another logger would have written it
    (:func:`record_variants.make_variant`; the key is the record's own); a variant that
    cannot be made of it stops the evaluation with the reason (a choice of the
    evaluation's, not a crash of the trial)."""
    name = folder.name
    inputs = work / "inputs" / name
    inputs.mkdir(parents=True, exist_ok=True)
    csv = inputs / f"{name}.csv"
    hoist_path = inputs / "hoist.toml"
    records = [csv]
    outcomes = []
    started = time.perf_counter()
    try:
        with gzip.open(folder / f"{name}.csv.gz", "rb") as src, csv.open("wb") as dst:
            shutil.copyfileobj(src, dst)
        shutil.copyfile(folder / "hoist.toml", hoist_path)
        records = [p.path for p in split_record(csv, parts)] if parts > 1 else [csv]
    except Exception as exc:  # a record that cannot be read is a crash of its trial
        crashed = _outcome(name, key)
        crashed.reason = _one_line(exc)
        _remove_records(csv)
        return [crashed]
    try:  # each export as the logger wrote it (as eval_compensation.py's parts)
        records = [make_variant(record, variant) for record in records]
    except (KeyError, ValueError) as exc:
        _remove_records(csv)
        raise SystemExit(f"eval_discovery: {name}: variant {variant!r}: {exc}") from exc
    unpacked_s = time.perf_counter() - started  # counted in the first record's ingest
    try:
        for k, record in enumerate(records, start=1):
            label = name if parts <= 1 else f"{name} {k}/{parts}"
            stem = name if parts <= 1 else f"{name}-part{k}"
            outcomes.append(discover_record(record, hoist_path, label, stem, key, work))
    finally:
        _remove_records(csv)
    outcomes[0].ingest_s += unpacked_s
    return outcomes


def _remove_records(csv: Path) -> None:
    """The decompressed record and every part or variant written beside it
    (``<stem>-*.csv``; 2 h at 50 Hz: ~40 MB each)."""
    for written in [csv, *csv.parent.glob(f"{csv.stem}-*.csv")]:
        written.unlink(missing_ok=True)


def _outcome(label: str, key: dict[str, Any]) -> TrialOutcome:
    """A trial's outcome before it is analysed (a crash until an answer is read)."""
    return TrialOutcome(
        name=label,
        hidden=key["hidden_effect"],
        rms_over_noise=float(key["rms_over_noise"]),
        effect_rms_pa=float(key["effect_rms_pa"]),
    )


def ingest_record(csv: Path, hoist_path: Path, root: Path) -> tuple[Any, int]:
    """(data root, rows quarantined) of ``csv`` ingested into a data root at ``root``
    with the hoist of ``hoist_path``; RuntimeError when the ingest refuses it."""
    from pipelines.ingest import ingest_paths
    from pipelines.ingest.field_checks import hoist_lookup_from_files
    from warehouse.store import DataRoot

    data = DataRoot.resolve(root)
    hoists = hoist_lookup_from_files([str(hoist_path)])
    ingested = ingest_paths([csv], data=data, hoist_lookup=hoists)
    if not ingested.ok:
        raise RuntimeError("ingest refused " + "; ".join(ingested.refusal_lines()))
    return data, ingested.totals()["rows_quarantined"]


def discover_record(
    csv: Path, hoist_path: Path, label: str, stem: str, key: dict[str, Any], work: Path
) -> TrialOutcome:
    """One record ingested into ``work/data/<stem>`` and discovered, its report in
    ``work/reports/<stem>.json``."""
    from pipelines.discover import discover_period

    out = _outcome(label, key)
    json_path = work / "reports" / f"{stem}.json"
    started = time.perf_counter()
    try:
        try:
            data, out.quarantined = ingest_record(csv, hoist_path, work / "data" / stem)
        finally:
            out.ingest_s = time.perf_counter() - started
        started, cpu = time.perf_counter(), time.process_time()
        try:
            discover_period(hoist_path=hoist_path, data=data, json_path=json_path)
        finally:
            out.discover_s = time.perf_counter() - started
            out.discover_cpu_s = time.process_time() - cpu
        out.report = json.loads(json_path.read_text())
        out.answer = str(out.report["effect"])
    except Exception as exc:  # a crash is a finding of the evaluation, not its end
        out.answer = "crash"
        out.reason = _one_line(exc)
    return out


def _fmt_kpa(report: dict[str, Any], key: str) -> str:
    value = report.get(key)
    return f"{float(value) / 1e3:8.1f}" if value is not None else f"{'-':>8s}"


def _trial_line(o: TrialOutcome, width: int = 10) -> str:
    r = o.report
    answer = o.answer
    if o.answer == "ambiguous" and r.get("ambiguous_between"):
        answer += "(" + "|".join(r["ambiguous_between"]) + ")"
    extra = []
    ranked = [x.get("effect") for x in r.get("ranking") or []]
    if ranked and o.answer != o.hidden:
        where = f"#{ranked.index(o.hidden) + 1}" if o.hidden in ranked else "unranked"
        hidden_rank = f", hidden {where}" if o.hidden != "none" else ""
        extra.append(f"ranked 1st {ranked[0]}{hidden_rank}")
    if r.get("trips_analysed") is not None:
        extra.append(f"{r['trips_analysed']}/{r.get('trips_in_period')} trips")
    if len(r.get("effects") or []) > 1:
        extra.append("then " + ",".join(r["effects"][1:]))
    if r.get("unexplained_gap_pa") is not None:
        extra.append(f"unexplained {float(r['unexplained_gap_pa']) / 1e3:.1f} kPa")
    vr = o.variance_removed
    if vr is not None:
        extra.append(f"var removed {vr:.0%} (the effect's own {o.effect_share:.0%})")
    if o.quarantined:
        extra.append(f"{o.quarantined} rows quarantined")
    if o.reason:
        extra.append(o.reason)
    mark = "ok " if o.answer == o.hidden else "   "
    return (
        f"{o.name:{width}s} {o.hidden:22s} {o.rms_over_noise:7.2f} {mark}{answer:26s}"
        f"{_fmt_kpa(r, 'gap_before_pa')}{_fmt_kpa(r, 'gap_after_pa')}{_fmt_kpa(r, 'noise_pa')}"
        f" {_record_hours(r):4.2f} {o.ingest_s:6.1f} {o.discover_s:6.1f} {o.discover_cpu_s:6.1f}  "
        + "; ".join(extra)
    )


def _share(hits: int, n: int) -> str:
    return f"{hits}/{n} = {hits / n:.0%}" if n else "0/0"


def _mark(ok: bool | None) -> str:
    return "n/a (no such trial)" if ok is None else "met" if ok else "NOT met"


def trials_summary(outcomes: list[TrialOutcome], noise_pa: float) -> None:
    """Confusion matrix, accuracy by size, false alarms, variance removed, replay gap on
    ``none`` records, seconds per record, and the issue-14 targets."""
    _print_confusion(outcomes)
    crashes = [o for o in outcomes if o.answer == "crash"]
    hidden = [o for o in outcomes if o.hidden != "none"]
    nones = [o for o in outcomes if o.hidden == "none"]
    band_ok = _print_accuracy(hidden)
    alarms = [o for o in nones if o.answer not in ("none", "crash")]
    print(
        f"false alarms on none records: {_share(len(alarms), len(nones))}"
        + (" (" + ", ".join(f"{o.name}: {o.answer}" for o in alarms) + ")" if alarms else "")
    )
    med_right = _print_variance_removed(hidden)
    none_gaps = [float(o.report["gap_before_pa"]) for o in nones if o.answer != "crash"]
    if none_gaps:
        print(
            "replay gap on none records: "
            + ", ".join(
                f"{o.name} {float(o.report['gap_before_pa']) / 1e3:.1f} kPa"
                for o in nones
                if o.answer != "crash"
            )
            + f" (noise {noise_pa / 1e3:.1f} kPa, {max(none_gaps) / noise_pa:.1f}x at worst)"
        )
    seconds = _print_seconds(outcomes)
    if crashes:
        print(f"crashes: {len(crashes)}/{len(outcomes)}")
        for o in crashes:
            print(f"  {o.name}: {o.reason}")
    print("\ntargets (issue 14)")
    targets = [
        (f"no crash ({len(crashes)}/{len(outcomes)})", not crashes),
        (
            f"replay gap on none <= {TARGET_NONE_GAP_X:g}x noise "
            f"({TARGET_NONE_GAP_X * noise_pa / 1e3:.0f} kPa)",
            max(none_gaps) <= TARGET_NONE_GAP_X * noise_pa if none_gaps else None,
        ),
        ("top-1 >= 90 % at >= 5x noise", band_ok[0]),
        ("top-1 >= 70 % at 2-5x noise", band_ok[1]),
        (
            f"false alarms <= {TARGET_FALSE_ALARMS:.0%}",
            len(alarms) <= TARGET_FALSE_ALARMS * len(nones) if nones else None,
        ),
        (
            f"median variance removed >= {TARGET_VARIANCE_REMOVED:.0%}",
            (
                med_right >= TARGET_VARIANCE_REMOVED
                if med_right is not None
                else (False if hidden else None)
            ),
        ),
        (
            f"<= {TARGET_SECONDS:.0f} s per 2 h record",
            max(seconds) <= TARGET_SECONDS if seconds else None,
        ),
    ]
    for label, ok in targets:
        print(f"  {label}: {_mark(ok)}")


def _print_confusion(outcomes: list[TrialOutcome]) -> None:
    """The confusion matrix: rows the hidden effect, columns the answered one."""
    confusion: dict[str, Counter] = defaultdict(Counter)
    for o in outcomes:
        confusion[o.hidden][o.answer] += 1
    answered = {o.answer for o in outcomes} - set(OTHER_ANSWERS)
    columns = [e for e in EFFECTS if e in answered] + sorted(answered - set(EFFECTS))
    columns += list(OTHER_ANSWERS)
    rows = [e for e in EFFECTS if e in confusion] + sorted(set(confusion) - {*EFFECTS, "none"})
    rows += ["none"] if "none" in confusion else []
    print("\nconfusion matrix (rows hidden effect, columns answered effect)")
    print(f"{'':24s}" + "".join(f"{c[:8]:>9s}" for c in columns))
    for t in rows:
        print(f"{t:24s}" + "".join(f"{confusion[t][c]:9d}" for c in columns))


def _print_accuracy(hidden: list[TrialOutcome]) -> list[bool | None]:
    """Top-1 accuracy per effect-size band; whether each band with a target meets it."""
    print("\ntop-1 accuracy by effect size (rms_over_noise)")
    band_ok: list[bool | None] = []
    for label, lo, hi, target in SIZE_BANDS:
        band = [o for o in hidden if lo <= o.rms_over_noise < hi]
        hits = sum(o.answer == o.hidden for o in band)
        goal = f" (target >= {target:.0%})" if target is not None else " (no target)"
        print(f"  {label:12s} {_share(hits, len(band))}{goal}")
        if target is not None:
            band_ok.append(hits >= target * len(band) if band else None)
    return band_ok


def _print_variance_removed(hidden: list[TrialOutcome]) -> float | None:
    """The median share of the hidden effect's variance the added effect removed over
    the trials named right (None without any)."""
    right = [o.variance_removed for o in hidden if o.answer == o.hidden]
    right = [v for v in right if v is not None]
    all_vr = [(o.variance_removed or 0.0) if o.answer == o.hidden else 0.0 for o in hidden]
    med_right = float(np.median(right)) if right else float("nan")
    print(
        "median share of the hidden effect's variance removed by the added effect, "
        "(gap_before^2 - gap_after^2) / effect_rms^2: "
        + (f"{med_right:.0%} over the {len(right)} trials named right" if right else "no hits")
        + (f"; {np.median(all_vr):.0%} over all {len(all_vr)} (miss = 0)" if all_vr else "")
    )
    own = [o.effect_share for o in hidden if o.answer == o.hidden and o.effect_share is not None]
    if own:
        print(
            "  the added effect's own share, (gap_without_effect^2 - gap_after^2) / "
            f"effect_rms^2 (the baseline's payloads took each trip's mean of it): "
            f"{np.median(own):.0%} over the {len(own)} named"
        )
    return med_right if right else None


def _print_seconds(outcomes: list[TrialOutcome]) -> list[float]:
    """Seconds per record (discover wall and CPU, ingest); the finite wall times."""
    seconds = [o.discover_s for o in outcomes if np.isfinite(o.discover_s)]
    cpu = [o.discover_cpu_s for o in outcomes if np.isfinite(o.discover_cpu_s)]
    ingest = [o.ingest_s for o in outcomes if np.isfinite(o.ingest_s)]
    if seconds:
        print(
            f"seconds per record (discover, wall): median {np.median(seconds):.1f}, max "
            f"{max(seconds):.1f}; CPU median {np.median(cpu):.1f}, max {max(cpu):.1f}; "
            f"ingest median {np.median(ingest):.1f} s"
        )
    return seconds


def evaluate_trials(
    trials: Path, only: list[str] | None, work: Path, parts: int = 1, variant: str = ""
) -> None:
    """Run every trial of ``trials`` (or those named in ``only``) under ``work``, each
    record whole or cut into ``parts``, as logged or as logger ``variant`` would have
    logged it (:func:`run_trial`)."""
    key = json.loads((trials / "answers.json").read_text())
    by_name = {t["trial"]: t for t in key["trials"]}
    folders = sorted(p for p in trials.glob("trial_*") if p.is_dir())
    if only:
        unknown = sorted(set(only) - {p.name for p in folders})
        if unknown:
            raise SystemExit(f"eval_discovery: no such trial in {trials}: {', '.join(unknown)}")
        folders = [p for p in folders if p.name in only]
    width = 10 if parts <= 1 else len(f"trial_000 {parts}/{parts}")  # the names' column
    print(
        f"{'trial':{width}s} {'hidden effect':22s} {'rms/nse':>7s}    {'answer':26s}"
        f"{'gap0':>8s}{'gap1':>8s}{'noise':>8s} {'h':>4s} {'ingest':>6s} {'disc':>6s} {'cpu':>6s}"
    )
    outcomes = []
    if variant:
        print(f"every record as logger variant {variant!r} would have written it")
    print(
        f"{'':{width}s} {'':22s} {'':7s}    {'':26s}{'kPa':>8s}{'kPa':>8s}{'kPa':>8s} {'':4s}"
        f" {'s':>6s} {'s':>6s} {'s':>6s}   (gap0/gap1: gap_before/after_pa, h: record hours)"
    )
    for folder in folders:
        if folder.name not in by_name:
            print(f"{folder.name}: not in answers.json, skipped")
            continue
        for outcome in run_trial(folder, by_name[folder.name], work, parts, variant):
            outcomes.append(outcome)
            print(_trial_line(outcome, width), flush=True)
    if outcomes:
        trials_summary(outcomes, float(key.get("sensor_noise_pa", 5e3)))


def run_trials(
    trials: Path, only: list[str] | None, keep: Path | None, parts: int = 1, variant: str = ""
) -> None:
    started = time.perf_counter()
    if keep is not None:
        keep.mkdir(parents=True, exist_ok=True)
        evaluate_trials(trials, only, keep.absolute(), parts, variant)
    else:
        with tempfile.TemporaryDirectory(prefix="ropeload-trials-") as tmp:
            evaluate_trials(trials, only, Path(tmp), parts, variant)
    print(f"\nwall time {time.perf_counter() - started:.0f} s")
