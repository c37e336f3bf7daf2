"""Evaluate the compensation at stops against independent truth (issue 13, "Must show").

Not a unit test: a script. It measures how close the compensated load and rope
tensions come to the true ones in *stop windows* -- spans of steady payload while the
conveyance stands at a named position, after the first seconds following an arrival or
a payload change -- and whether compensation ever makes a window worse than the raw
reading (sum of p A).

Days evaluated:

- every ``*.csv.gz`` of ``../shared/validation/days/`` (an independent simulator of
  the paper's field-test hoist, described by ``<name>.hoist.toml``; truth in
  ``<name>.truth.json``, ``stops[].windows[]``). These files are **evaluation data**:
  nothing in ropeload is, or may be, tuned to them (other days of the same kind are
  used for judging). See ``../shared/validation/README.md``.
- ``--sims N`` synthetic days of ropeload's own generator
  (:func:`sims.field_day.generate_field_day`, the example hoist, 2 h at 50 Hz; these
  ring after each arrival), with windows built from the simulation's truth frame the
  same way: at rest at a named position with a steady payload, from 3 s after the
  arrival or the end of the payload change to 1 s before the next change or departure.
- ``--parts N``: each validation day cut into N consecutive records (:func:`in_parts`),
  each compensated cold as a day of its own: shorter records that start and end
  wherever the cut falls, more days of the same kind (the targets are judged on days
  not here; a target met on a whole day and missed on one of its halves is fragile).
- ``--sims-lugre N`` more synthetic days whose seals are LuGre's single bristle (the
  example hoist without ``presliding_hysteresis``, in the data and in its TOML): a
  second world where ringing shakes the seals loose (LuGre's drift, exactly integrated
  by :mod:`sims.device`), against which the estimate's drift is checked.

Each day goes the way a mine's data go: the CSV (decompressed into a temporary folder,
the hoist TOML beside it) is ingested into a fresh data root
(:func:`pipelines.ingest.ingest_paths`), the whole record is compensated and landed by
:func:`pipelines.run_period.run_period` (what ``ropeload run --no-sanity`` calls), and
the landed ``rope_tensions`` are read back from the lake
(:func:`pipelines.lake.scan_lake`).

Per window: the mean of the compensated load (``load_n``) and of the raw load
(``load_raw_n``) against ``true_load_n``, and each rope's mean ``tension{i}_n`` against
its true tension, errors in % of the true value. Per day it prints the window count,
the load error before / after (worst and median |.|), the worst rope after, the
windows where |after| > |before| + 0.2 %-points and the margin to that limit (the
largest |after| - |before| of the day, and how many windows exceed half the limit: a
day of the same kind fails the target by one window), the 95 % band coverage and median
half-width (from ``load_lo_n``/``load_hi_n`` and ``tension{i}_lo_n``/``tension{i}_hi_n``
when the landed table has them), the five worst windows, and the issue's targets.
On a validation day it also prints the seals' friction error per position (summed over
the pistons and per piston, RMS, against the truth's ``friction_n``) and the ropes'
constants the run identified
(:func:`pipelines.identified_ropes.identified_ropes`, from the data root's cache) against
those the truth's windows imply (:func:`truth_ropes`: the true tensions and piston
positions fitted to the spring law), with what each length offset's difference alone
makes of a rope's tension at the pithead at a fixed stretch (-a k dc; the stiffness's
difference adds about (da / a) T there, which the print leaves out).

``--variant NAME`` writes each record as another logger would have
(:data:`record_variants.VARIANTS`: no x, no oil temperature, 10 Hz, pressures on a
10 kPa step, a frozen sensor, an outage, repeated rows...) before it is ingested; the
truth is the record's own (only what was logged changed). ``--without-x`` is
``--variant no-x``.

    uv run python benchmarks/eval_compensation.py [--days DIR] [--sims N] [--sims-lugre N]
                                                  [--keep DIR] [--without-x] [--parts N]
                                                  [--variant NAME]
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import gzip
import json
import shutil
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from zoneinfo import ZoneInfo

import numpy as np
import polars as pl
from record_parts import split_record  # the sibling scripts
from record_variants import PAUSES, VARIANTS, make_variant, pause_row, read_log

from physics.rope_spring import head_rope_stiffness_n_m
from pipelines.identified_ropes import identified_ropes
from pipelines.ingest import ingest_paths
from pipelines.lake import scan_lake
from pipelines.run_period import run_period
from pipelines.steps import one_line
from schemas.hoist import EXAMPLE_HOIST, HoistDescription, load_hoist
from schemas.tables import ROPES
from sims.field_day import generate_field_day, write_field_day
from transforms.stick_slip_band import RopeSprings
from warehouse.store import DataRoot

DEFAULT_DAYS = Path(__file__).resolve().parents[1].parent / "shared" / "validation" / "days"

#: Stop windows: skip this long after an arrival or the end of a payload change [s] ...
SKIP_S = 3.0
#: ... and end this long before the next change or departure [s]; shorter ones dropped
#: (the generator rests 5 s between the end of a payload change and the departure, so
#: its after-change windows are 1 s long: 50 samples at 50 Hz).
TAIL_S = 1.0
MIN_WINDOW_S = 1.0
#: A window needs this many compensated samples to be evaluated (records end anywhere).
MIN_SAMPLES = 10
#: |after| > |before| + this counts as "worse than raw" [%-points].
WORSE_PP = 0.2
#: Issue 13 targets.
TARGET_WORST_PCT = 1.0
TARGET_MEDIAN_PCT = 0.3
TARGET_ROPE_PCT = 2.0
TARGET_COVERAGE = 0.90
TARGET_HALF_WIDTH_PCT = 1.0


@dataclass(frozen=True)
class Window:
    """A span ``[t0, t1)`` (UTC) of steady payload at a stop, with its true means."""

    kind: str  # "arrival" or "after_payload_change"
    position: str
    t0: dt.datetime
    t1: dt.datetime
    true_load_n: float
    true_tension_n: tuple[float, ...]
    #: The stop's depth [m] and each piston's true position [m] (validation days; the
    #: ropes the truth implies are fitted from them, :func:`truth_ropes`).
    depth_m: float = float("nan")
    true_piston_x_m: tuple[float, ...] = ()
    #: Each seal's true friction [N] (validation days: :func:`report_friction`).
    true_friction_n: tuple[float, ...] = ()


@dataclass(frozen=True)
class DayCase:
    """One day to evaluate: a field-log CSV, its hoist description and truth windows."""

    name: str
    csv: Path
    hoist_path: Path
    windows: list[Window]


def _utc(text: str) -> dt.datetime:
    return dt.datetime.fromisoformat(text.replace("Z", "+00:00")).astimezone(dt.UTC)


def validation_case(gz: Path, work: Path) -> DayCase:
    """Decompress ``<name>.csv.gz`` into ``work/<name>/`` with its hoist TOML beside it."""
    name = gz.name.removesuffix(".csv.gz")
    folder = work / name
    folder.mkdir(parents=True, exist_ok=True)
    csv = folder / f"{name}.csv"
    with gzip.open(gz, "rb") as src, csv.open("wb") as dst:
        shutil.copyfileobj(src, dst)
    hoist_path = folder / f"{name}.hoist.toml"
    shutil.copyfile(gz.with_name(f"{name}.hoist.toml"), hoist_path)
    truth = json.loads(gz.with_name(f"{name}.truth.json").read_text())
    windows = [
        Window(
            kind=w["kind"],
            position=stop["position"],
            t0=_utc(w["t0_utc"]),
            t1=_utc(w["t1_utc"]),
            true_load_n=float(w["true_load_n"]),
            true_tension_n=tuple(float(x) for x in w["true_tension_n"]),
            depth_m=float(stop["depth_m"]),
            true_piston_x_m=tuple(1e-3 * float(x) for x in w.get("piston_x_mm", ())),
            true_friction_n=tuple(float(f) for f in w.get("friction_n", ())),
        )
        for stop in truth["stops"]
        for w in stop["windows"]
    ]
    return DayCase(name, csv, hoist_path, windows)


def truth_ropes(
    windows: list[Window], hoist: HoistDescription
) -> tuple[tuple[float, ...], tuple[float, ...], float] | None:
    """The ropes' constants the truth's windows imply: (a, c [m], fit RMS [N]) in the
    identification's gauge (rope 1: a = 1, c = 0), or None without pistons' positions.

    Each window's true tensions and piston positions obey the spring law of
    :mod:`transforms.stick_slip`, T_i = a_i k (s - x_i - c_i) with k the head rope's
    rate at the stop's depth (:func:`physics.rope_spring.head_rope_stiffness_n_m`);
    rope 1 gives the window's s = T_1 / k + x_1, and each other rope's (a_i, a_i c_i)
    is a linear least-squares fit over the windows, in metres (T / k: the deep windows
    weigh more); the RMS is reported in newtons.
    """
    usable = [
        w for w in windows if len(w.true_piston_x_m) == hoist.ropes_n and np.isfinite(w.depth_m)
    ]
    if len(usable) < 3:
        return None
    rate = np.array([
        head_rope_stiffness_n_m(
            hoist.ropes.head_rope_axial_stiffness_n,
            hoist.shaft.headframe_height_m + max(w.depth_m, 0.0),
        )
        for w in usable
    ])  # fmt: skip
    tension = np.array([w.true_tension_n for w in usable])
    x = np.array([w.true_piston_x_m for w in usable])
    s = tension[:, 0] / rate + x[:, 0]
    a, c, squares = [1.0], [0.0], []
    for i in range(1, hoist.ropes_n):
        design = np.column_stack([s - x[:, i], -np.ones(len(usable))])
        (a_i, ac_i), *_ = np.linalg.lstsq(design, tension[:, i] / rate, rcond=None)
        a.append(float(a_i))
        c.append(float(ac_i / a_i))
        squares.append(np.mean(((design @ (a_i, ac_i)) - tension[:, i] / rate) ** 2 * rate**2))
    return tuple(a), tuple(c), float(np.sqrt(np.mean(squares)))


def report_friction(errors: pl.DataFrame) -> None:
    """Print, per position, the RMS over its windows of the seals' friction error summed
    over the pistons (the load's error from friction) and per piston [N], where the
    truth gives each seal's friction."""
    columns = [f"friction{i}_error_n" for i in ROPES]
    if not set(columns) <= set(errors.columns):
        return
    per_position = (
        errors.filter(pl.all_horizontal(pl.col(columns).is_finite()))  # truth and estimate
        .with_columns(pl.sum_horizontal(columns).alias("_sum"))
        .group_by("position")
        .agg(
            pl.len().alias("windows"),
            (pl.col("_sum") ** 2).mean().sqrt().alias("sum"),
            (pl.concat_list(columns).list.eval(pl.element() ** 2).list.mean())
            .mean()
            .sqrt()
            .alias("piston"),
        )
        .sort("position")
    )
    print("  seals' friction against the truth's (RMS over the windows):")
    for r in per_position.iter_rows(named=True):
        print(
            f"    {r['position']:<8} {r['windows']:>3} windows: summed {r['sum']:>5.0f} N, "
            f"per piston {r['piston']:>5.0f} N"
        )


def report_ropes(
    identified: RopeSprings | None,
    implied: tuple[tuple[float, ...], tuple[float, ...], float] | None,
    hoist: HoistDescription,
) -> None:
    """Print the identified ropes against those the truth implies, and what their
    length offsets' difference alone makes of a rope's tension at the pithead at a fixed
    stretch: -a k dc, the estimate minus the truth (the stiffness's part left out)."""
    if identified is None or implied is None:
        return
    a_true, c_true, rms = implied
    k_top = head_rope_stiffness_n_m(
        hoist.ropes.head_rope_axial_stiffness_n, hoist.shaft.headframe_height_m
    )
    print(f"  ropes identified vs implied by the truth windows (fit RMS {rms:.0f} N):")
    for i in range(1, hoist.ropes_n):
        a, c = identified.stiffness_factors[i], identified.length_offsets_m[i]
        print(
            f"    rope {i + 1}: a {a:.4f} vs {a_true[i]:.4f} ({a - a_true[i]:+.4f}), "
            f"c {1e3 * c:+.3f} vs {1e3 * c_true[i]:+.3f} mm ({1e3 * (c - c_true[i]):+.3f} mm: "
            f"{-a * k_top * (c - c_true[i]):+.0f} N at the pithead from dc)"
        )


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` index pairs of the maximal runs of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def truth_windows(truth: pl.DataFrame, hoist: HoistDescription) -> list[Window]:
    """Stop windows of a simulated day, built from its truth frame.

    A stop span is a maximal run of samples at rest (|speed| < 1 um/s) with the payload
    unchanged from the previous sample and the depth within the hoist's position
    window of a named position. The window is ``[start + SKIP_S, end - TAIL_S)``; its
    kind is ``after_payload_change`` when the sample before the span was at rest (the
    payload was changing), else ``arrival`` (also at the start of the record).
    """
    t = truth["time_utc"]
    speed = truth["speed_m_s"].to_numpy()
    payload = truth["payload_kg"].to_numpy()
    depth = truth["depth_m"].to_numpy()
    rest = np.abs(speed) < 1e-6
    steady = np.concatenate([[True], np.abs(np.diff(payload)) < 1e-9])
    load = truth["load_n"].to_numpy()
    tensions = [truth[f"tension{i}_n"].to_numpy() for i in ROPES]
    t_ns = t.dt.epoch("ns").to_numpy()
    windows = []
    for start, end in _runs(rest & steady):
        mean_depth = float(depth[start:end].mean())
        names = [
            name
            for name, z in hoist.shaft.positions_m.items()
            if abs(mean_depth - z) <= hoist.shaft.position_window_m
        ]
        if not names:
            continue
        kind = "after_payload_change" if start > 0 and rest[start - 1] else "arrival"
        t0_ns = t_ns[start] + int(SKIP_S * 1e9)
        t1_ns = (t_ns[end] if end < len(t_ns) else t_ns[-1]) - int(TAIL_S * 1e9)
        if t1_ns - t0_ns < MIN_WINDOW_S * 1e9:
            continue
        lo, hi = np.searchsorted(t_ns, [t0_ns, t1_ns])
        windows.append(
            Window(
                kind=kind,
                position=names[0],
                t0=t[int(lo)],
                t1=t[int(hi)] if hi < len(t) else t[-1],
                true_load_n=float(load[lo:hi].mean()),
                true_tension_n=tuple(float(x[lo:hi].mean()) for x in tensions),
            )
        )
    return windows


def sims_case(k: int, work: Path, *, lugre: bool = False) -> DayCase:
    """Synthetic day ``k``: 2 h at 50 Hz of the example hoist, written as a mine's CSV
    (``lugre``: its seals LuGre's single bristle, in the data and in the TOML)."""
    text = EXAMPLE_HOIST.read_text()
    if lugre:
        text = text.replace('"presliding_hysteresis",', "")
        if text == EXAMPLE_HOIST.read_text():
            raise RuntimeError(f"{EXAMPLE_HOIST}: no presliding_hysteresis effect to take out")
    # the simulator's ropes are the description's (sims.device_params: EA each): its
    # description says so, as a mine that measured its ropes would (without a logged x
    # the compensation then takes them as known, not their prior spread)
    stated = "head_rope_stiffness_factors = [1.0, 1.0, 1.0, 1.0]\n"
    text = text.replace("[ropes]\n", "[ropes]\n" + stated, 1)
    if stated not in text:
        raise RuntimeError(f"{EXAMPLE_HOIST}: no [ropes] section to state the factors in")
    name = f"sims_lugre_{k}" if lugre else f"sims_{k}"
    folder = work / name
    folder.mkdir(parents=True, exist_ok=True)
    hoist_path = folder / "sims.hoist.toml"
    hoist_path.write_text(text)
    hoist = load_hoist(hoist_path)
    date = dt.date(2026, 3, 12 if lugre else 2) + dt.timedelta(days=k)
    day = generate_field_day(
        hoist, date=date, seed=1000 + k, trips=40, hours=2.0, sample_rate_hz=50.0
    )
    written = write_field_day(day, folder, formats=("csv",))
    csv = next(p for p in written if p.suffix == ".csv")
    return DayCase(f"{name} (seed {1000 + k})", csv, hoist_path, truth_windows(day.truth, hoist))


def as_variant(case: DayCase, variant: str) -> DayCase:
    """The same day as a logger of ``variant`` would have written it
    (:func:`record_variants.make_variant`; ``no-x``: the pistons' displacement columns
    taken out, contract 1a: optional, so the compensation runs on the pressures alone,
    the ropes unidentified). The truth's windows are the day's."""
    if not variant:
        return case
    csv = make_variant(case.csv, variant)
    windows = case.windows
    if variant in PAUSES:  # the truth's windows after the pause are logged that much later
        table = read_log(case.csv)
        zone = ZoneInfo(table.key("timezone", "UTC"))
        resumed = table.rows[pause_row(table)][table.column("timestamp")]
        at, later = _logged_utc(resumed, zone), dt.timedelta(seconds=PAUSES[variant])
        # a window the pause falls in spans it: its rows before and after (none in it)
        windows = [
            dataclasses.replace(w, t0=w.t0 + later if w.t0 >= at else w.t0, t1=w.t1 + later)
            if w.t1 > at
            else w
            for w in windows
        ]
    return DayCase(f"{case.name} [{variant}]", csv, case.hoist_path, windows)


def _logged_utc(text: str, zone: ZoneInfo) -> dt.datetime:
    """A CSV timestamp (the header's time zone unless it carries an offset) in UTC."""
    stamp = dt.datetime.fromisoformat(text.strip())
    return (stamp if stamp.tzinfo else stamp.replace(tzinfo=zone)).astimezone(dt.UTC)


def in_parts(case: DayCase, parts: int) -> list[DayCase]:
    """The day cut into ``parts`` consecutive records of equal row counts, each a day of
    its own with the truth's windows that lie whole inside it: shorter records that
    start and end wherever the cut falls (mid-trip, mid-stop), as exports do. Each is
    compensated cold (its own data root, its own identification of the ropes), so the
    parts are more days of the same kind, not more windows of the same day."""
    if parts <= 1:
        return [case]
    cases = []
    for k, part in enumerate(split_record(case.csv, parts)):
        zone = ZoneInfo(part.header.get("timezone", "UTC"))
        first, last = (_logged_utc(s, zone) for s in (part.first_stamp, part.last_stamp))
        windows = [w for w in case.windows if first <= w.t0 and w.t1 <= last]
        label = f"{case.name} part {k + 1}/{parts}"
        cases.append(DayCase(label, part.path, case.hoist_path, windows))
    return cases


def compensate_day(case: DayCase, root: Path) -> pl.DataFrame:
    """Ingest the day into a fresh data root, run the whole record, read the landed rows."""
    data = DataRoot.resolve(root)
    hoist = load_hoist(case.hoist_path)
    report = ingest_paths([case.csv], data=data, hoist_lookup=lambda site, name: hoist)
    if not report.ok:
        raise RuntimeError(f"{case.csv.name} refused by ingest: {report}")
    run_period(hoist_path=case.hoist_path, data=data, hoist=hoist, command="eval")
    return scan_lake(data, "rope_tensions", site=hoist.hoist.site, hoist=hoist.hoist.name).collect()


def window_errors(tensions: pl.DataFrame, windows: list[Window]) -> pl.DataFrame:
    """One row per window with samples: errors before / after in % of the true value.

    Columns: ``kind``, ``position``, ``t0``, ``samples``, ``before_pct``,
    ``after_pct``, ``rope{i}_pct``, ``rope_max_pct`` (largest |rope error|), and, when
    the landed table has the band, ``covered`` (true load and every true rope tension
    inside the window-mean band) and ``half_width_pct`` (half the load band in % of
    the true load), and where the window has the truth's friction
    ``friction{i}_error_n`` (the window-mean landed friction less the truth's [N]).
    """
    t_ns = tensions["time_utc"].dt.epoch("ns").to_numpy()
    cols = {c: tensions[c].to_numpy() for c in tensions.columns if c.endswith("_n")}
    band = "load_lo_n" in cols and "load_hi_n" in cols
    rows = []
    for w in windows:
        lo, hi = np.searchsorted(t_ns, [w.t0.timestamp() * 1e9, w.t1.timestamp() * 1e9])
        if hi - lo < MIN_SAMPLES:
            continue

        def mean(column: str, lo: int = int(lo), hi: int = int(hi)) -> float:
            return float(np.nanmean(cols[column][lo:hi]))

        with warnings.catch_warnings():  # a withheld column's mean: NaN, said below
            warnings.simplefilter("ignore", RuntimeWarning)
            ropes = [100 * (mean(f"tension{i}_n") / w.true_tension_n[i - 1] - 1) for i in ROPES]
            after = 100 * (mean("load_n") / w.true_load_n - 1)
        row = {
            "kind": w.kind,
            "position": w.position,
            "t0": w.t0,
            "samples": int(hi - lo),
            "before_pct": 100 * (mean("load_raw_n") / w.true_load_n - 1),
            "after_pct": after,
            **{f"rope{i}_pct": ropes[i - 1] for i in ROPES},
            "rope_max_pct": float(np.nanmax(np.abs(ropes))) if np.isfinite(ropes).any() else np.nan,
            # the compensation withheld the load over the whole window (a sensor stuck or
            # not logged): not scored, counted
            "withheld": not np.isfinite(after),
        }
        if len(w.true_friction_n) == len(ROPES) and all(f"friction{i}_n" in cols for i in ROPES):
            for i in ROPES:  # the seals' part of each rope's error [N]
                row[f"friction{i}_error_n"] = mean(f"friction{i}_n") - w.true_friction_n[i - 1]
        if band and row["withheld"]:
            row["covered"], row["half_width_pct"] = None, None
        elif band:
            inside = mean("load_lo_n") <= w.true_load_n <= mean("load_hi_n")
            for i in ROPES:
                lo_i, hi_i = f"tension{i}_lo_n", f"tension{i}_hi_n"
                inside &= lo_i in cols and mean(lo_i) <= w.true_tension_n[i - 1] <= mean(hi_i)
            row["covered"] = bool(inside)
            row["half_width_pct"] = 50 * (mean("load_hi_n") - mean("load_lo_n")) / w.true_load_n
        rows.append(row)
    return pl.DataFrame(rows)


def _mark(ok: bool) -> str:
    return "met" if ok else "NOT met"


def _print_windows(title: str, rows: pl.DataFrame) -> None:
    print(f"  {title}:")
    print(
        f"    {'kind':<21} {'position':<8} {'t0 (UTC)':<19} {'before':>8} {'after':>8} "
        f"{'rope max':>8} {'band':>5}"
    )
    for r in rows.iter_rows(named=True):
        band = "" if r.get("covered") is None else ("in" if r["covered"] else "out")
        print(
            f"    {r['kind']:<21} {r['position']:<8} {r['t0']:%Y-%m-%d %H:%M:%S} "
            f"{r['before_pct']:>+7.2f}% {r['after_pct']:>+7.2f}% {r['rope_max_pct']:>7.2f}% "
            f"{band:>5}"
        )


def report_day(name: str, errors: pl.DataFrame, windows: int, seconds: float) -> dict:
    """Print the day's figures and targets; return them for the summary table. Windows
    whose load the compensation withheld (null over the whole window) are counted apart
    and left out of every figure."""
    withheld = int(errors["withheld"].sum()) if "withheld" in errors.columns else 0
    if withheld:
        errors = errors.filter(~pl.col("withheld"))
    before = errors["before_pct"].abs()
    after = errors["after_pct"].abs()
    flagged = errors.with_columns(after.alias("_abs"), (after > before + WORSE_PP).alias("_worse"))
    worse = int(flagged["_worse"].sum())
    rope = float(errors["rope_max_pct"].max())
    fig = {
        "name": name,
        "windows": errors.height,
        "worst_before": float(before.max()),
        "median_before": float(before.median()),
        "worst_after": float(after.max()),
        "median_after": float(after.median()),
        "rope_after": rope,
        "worse": worse,
        "excess": float("nan"),
        "coverage": None,
        "half_width": None,
    }
    print(
        f"\n== {name}: {errors.height} windows evaluated ({windows} in the truth), {seconds:.0f} s"
    )
    if withheld:
        print(f"  windows whose load was withheld (a sensor stuck or not logged): {withheld}")
    print(
        f"  load error |before|: worst {fig['worst_before']:.2f} %, median "
        f"{fig['median_before']:.2f} %"
    )
    print(
        f"  load error |after| : worst {fig['worst_after']:.2f} %, median "
        f"{fig['median_after']:.2f} %"
    )
    print(f"  worst rope after: {rope:.2f} %")
    print(f"  windows with |after| > |before| + {WORSE_PP} pp: {worse}/{errors.height}")
    excess = after - before
    fig["excess"] = float(excess.max())
    print(
        f"  margin: the largest |after| - |before| {fig['excess']:+.3f} pp (limit {WORSE_PP}); "
        f"windows above half the limit: {int((excess > WORSE_PP / 2).sum())}"
    )
    if "covered" in errors.columns:
        fig["coverage"] = float(errors["covered"].mean())
        fig["half_width"] = float(errors["half_width_pct"].median())
        print(
            f"  band coverage: {fig['coverage']:.1%}; median half-width "
            f"{fig['half_width']:.2f} % of the load"
        )
    else:
        print("  band coverage: n/a (no band); median half-width: n/a (no band)")
    ranked = flagged.sort("_abs", descending=True)
    _print_windows("worst 5 windows (by |after|)", ranked.head(5))
    if worse:
        _print_windows("windows worse than raw", ranked.filter(pl.col("_worse")))
    band = fig["coverage"] is not None
    targets = [
        f"worst <= {TARGET_WORST_PCT} %: {_mark(fig['worst_after'] <= TARGET_WORST_PCT)}",
        f"median <= {TARGET_MEDIAN_PCT} %: {_mark(fig['median_after'] <= TARGET_MEDIAN_PCT)}",
        f"worst rope <= {TARGET_ROPE_PCT} %: {_mark(rope <= TARGET_ROPE_PCT)}",
        f"none worse than raw by > {WORSE_PP} pp: {_mark(worse == 0)}",
        f"coverage >= {TARGET_COVERAGE:.0%}: "
        + (_mark(fig["coverage"] >= TARGET_COVERAGE) if band else "NOT met (no band)"),
        f"median half-width <= {TARGET_HALF_WIDTH_PCT} %: "
        + (_mark(fig["half_width"] <= TARGET_HALF_WIDTH_PCT) if band else "NOT met (no band)"),
    ]
    print("  targets: " + "; ".join(targets))
    return fig


def _summary(figures: list[dict]) -> None:
    print("\n== summary (load errors |.| in %, stop windows)")
    print(
        f"  {'day':<22} {'win':>4} {'worst bef':>9} {'med bef':>8} {'worst aft':>9} "
        f"{'med aft':>8} {'rope aft':>8} {'worse':>5} {'excess':>7} {'cover':>6} {'half-w':>6}"
    )
    for f in figures:
        cover = "n/a" if f["coverage"] is None else f"{f['coverage']:.0%}"
        half = "n/a" if f["half_width"] is None else f"{f['half_width']:.2f}"
        print(
            f"  {f['name']:<22} {f['windows']:>4} {f['worst_before']:>9.2f} "
            f"{f['median_before']:>8.2f} {f['worst_after']:>9.2f} {f['median_after']:>8.2f} "
            f"{f['rope_after']:>8.2f} {f['worse']:>5} {f['excess']:>+7.3f} {cover:>6} {half:>6}"
        )


def evaluate(
    days: Path, sims: int, work: Path, *, sims_lugre: int = 0, variant: str = "", parts: int = 1
) -> None:
    """Evaluate every validation day in ``days`` (each cut in ``parts``,
    :func:`in_parts`), ``sims`` synthetic days and ``sims_lugre`` synthetic days with
    LuGre seals under ``work`` (``variant``: each as another logger would have written
    it, :func:`as_variant`)."""
    figures = []
    gz_files = sorted(days.glob("*.csv.gz"))
    if not gz_files:
        print(f"no *.csv.gz in {days}")
    cases = [
        (gz.name, lambda gz=gz: in_parts(validation_case(gz, work / "inputs"), parts))
        for gz in gz_files
    ]
    cases += [(f"sims case {k}", lambda k=k: [sims_case(k, work / "inputs")]) for k in range(sims)]
    cases += [
        (f"LuGre sims case {k}", lambda k=k: [sims_case(k, work / "inputs", lugre=True)])
        for k in range(sims_lugre)
    ]
    failed = []
    for name, make in cases:
        try:
            days_of = make()
        except Exception as error:  # one day's failure is a finding, not the end
            failed.append(name)
            print(f"\n== {name}: FAILED, not evaluated: {one_line(error)}", flush=True)
            continue
        for day in days_of:
            _evaluate_case(day, work, variant, figures, failed)
    _summary(figures)
    if failed:
        print(f"  days that failed (target: none): {', '.join(failed)}")


def _evaluate_case(
    case: DayCase, work: Path, variant: str, figures: list[dict], failed: list[str]
) -> None:
    """Compensate one day, print its figures and append them to ``figures`` (its name to
    ``failed`` when it cannot be compensated)."""
    started = time.perf_counter()
    try:
        case = as_variant(case, variant)
        root = work / "data" / case.csv.stem
        tensions = compensate_day(case, root)
    except Exception as error:  # one day's failure is a finding, not the end
        failed.append(case.name)
        print(f"\n== {case.name}: FAILED, not evaluated: {one_line(error)}", flush=True)
        return
    errors = window_errors(tensions, case.windows)
    figures.append(report_day(case.name, errors, len(case.windows), time.perf_counter() - started))
    report_friction(errors)
    implied = truth_ropes(case.windows, hoist := load_hoist(case.hoist_path))
    if implied is not None:  # the identification's share of the errors
        data = DataRoot.resolve(root)
        samples = scan_lake(data, "field_samples", site=hoist.hoist.site, hoist=hoist.hoist.name)
        report_ropes(identified_ropes(samples.collect(), hoist, data=data), implied, hoist)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--days", type=Path, default=DEFAULT_DAYS, help=f"validation days (default {DEFAULT_DAYS})"
    )
    ap.add_argument("--sims", type=int, default=2, help="synthetic days to add (default 2)")
    ap.add_argument(
        "--sims-lugre", type=int, default=0, help="synthetic days with LuGre seals (default 0)"
    )
    ap.add_argument(
        "--keep", type=Path, default=None, help="work in DIR and keep it (inputs, data roots)"
    )
    ap.add_argument(
        "--without-x", action="store_true",
        help="take the pistons' displacements (x1..x4) out of every day's CSV first "
        "(--variant no-x)",
    )  # fmt: skip
    ap.add_argument(
        "--variant", choices=sorted(VARIANTS), default="",
        help="write every day as another logger would have: "
        + "; ".join(f"{k}: {v[0]}" for k, v in VARIANTS.items()).replace("%", "%%"),
    )  # fmt: skip
    ap.add_argument(
        "--parts", type=int, default=1,
        help="cut each validation day into N consecutive records, each evaluated cold as "
        "a day of its own (default 1: whole)",
    )  # fmt: skip
    args = ap.parse_args()
    started = time.perf_counter()
    if args.without_x and args.variant not in ("", "no-x"):
        ap.error("--without-x is --variant no-x: give one variant")
    variant = "no-x" if args.without_x else args.variant
    options = {"sims_lugre": args.sims_lugre, "variant": variant, "parts": args.parts}
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
        evaluate(args.days, args.sims, args.keep.absolute(), **options)
    else:
        with tempfile.TemporaryDirectory(prefix="ropeload-eval-") as tmp:
            evaluate(args.days, args.sims, Path(tmp), **options)
    print(f"\nwall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
