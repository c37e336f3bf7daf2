"""Diagnosis (issue 13): where the seals' friction at stops goes wrong, and what the
conveyance's load continuity from a trip to its stop could correct.

Not a test and not a target figure: a look at the data roots that
``benchmarks/eval_compensation.py --keep DIR`` leaves (``DIR/data/<day>``, its landed
``rope_tensions``, beside ``DIR/inputs/<day>/<day>.hoist.toml``) against each validation
day's truth JSON. It prints, per day:

1. the estimate's friction less the truth's at the stop windows (per piston and summed
   over the four), by position, window kind and the direction the conveyance arrived;
2. the same over each trip's run phase (``trips[].run_phase`` of the truth), by
   direction, with the load error there;
3. what a load-continuity update at each arrival would make of the windows' load
   errors: the payload does not change while the conveyance travels, so the load the
   compensation gives over the trip's run phase, plus the tail rope's weight the
   conveyance leaves behind or takes on between there and the stop (``tail_rope_mass_kg``:
   the tail ropes below it), predicts the load at rest; the estimate at the arrival
   window and that prediction are combined by the inverse squares of their band
   half-widths (a Kalman update of the common mode, the run phase's band standing for
   the prediction's), and the shift is carried to the next window of the stop unless
   the load moved by more than 2 % there (a payload change that slides pistons sets
   the seals' friction again).

Session 41 found with it: at arrivals after up trips every day's estimate holds more
friction summed than the truth (+370 / +186 / +192 / +668 N mean at the pithead,
+344 / +346 / +403 / +87 N at the middle on days 101-104), after down trips less
(-61 / -106 / -274 / +21 N at the bottom), while over the run phases the estimate is
within 0.18 % of the true load (friction summed -138 to +218 N). The update of (3)
took the median window error 0.180 / 0.133 / 0.158 / 0.221 % to 0.103 / 0.095 /
0.134 / 0.196 %, day 104's windows worse than raw 4 -> 2 (worst unchanged: the
bottom's after-payload windows), with weights 0.11-0.38 from today's bands; with the
gain 1 (the run's load taken whole) none worse than raw on any day. Built in session
42 as :mod:`transforms.stop_continuity` (each band member continuing its own run, in
the compensation's blocks); run on a kept run of today's code, section 3 shows what
is left after it.

    uv run python benchmarks/eval_compensation.py --sims 0 --keep /tmp/kept
    uv run python benchmarks/diagnose_stop_continuity.py /tmp/kept
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
from pathlib import Path

import numpy as np
import polars as pl

from physics.tension import tail_rope_mass_kg
from schemas.hoist import G_STANDARD, load_hoist

DEFAULT_DAYS = Path(__file__).resolve().parents[1].parent / "shared" / "validation" / "days"
#: A window after a payload change keeps the arrival's shift where the load moved by
#: less than this share of it (no piston slid: the seals' state is the arrival's).
CARRY_SHARE = 0.02


def _utc(text: str) -> dt.datetime:
    return dt.datetime.fromisoformat(text.replace("Z", "+00:00"))


def _rows(tensions: pl.DataFrame, t0: str, t1: str) -> pl.DataFrame:
    return tensions.filter((pl.col("time_utc") >= _utc(t0)) & (pl.col("time_utc") < _utc(t1)))


def _friction(rows: pl.DataFrame) -> np.ndarray:
    return np.array([rows[f"friction{i}_n"].mean() for i in range(1, 5)])


def _table(frame: pl.DataFrame, keys: list[str], values: list[str]) -> None:
    summary = frame.group_by(keys).agg(
        pl.len().alias("n"), *(pl.col(v).mean().round(2) for v in values)
    )
    with pl.Config(tbl_rows=40, tbl_cols=20, tbl_hide_dataframe_shape=True):
        print(summary.sort(keys))


def diagnose(kept: Path, day: str, days: Path) -> None:
    hoist = load_hoist(kept / "inputs" / day / f"{day}.hoist.toml")
    truth = json.loads((days / f"{day}.truth.json").read_text(encoding="utf-8"))
    lake = kept / "data" / day / "lake" / "rope_tensions"
    tensions = pl.concat([pl.read_parquet(f) for f in sorted(lake.rglob("*.parquet"))])
    tensions = tensions.sort("time_utc")
    print(f"== {day}")

    stops = []
    for stop in truth["stops"]:
        for window in stop["windows"]:
            rows = _rows(tensions, window["t0_utc"], window["t1_utc"])
            if rows.height:
                d = _friction(rows) - np.array(window["friction_n"])
                stops.append((stop["position"], window["kind"], stop.get("arrived_by"),
                              *d, d.sum()))  # fmt: skip
    names = ["position", "kind", "arrived_by", "d1_n", "d2_n", "d3_n", "d4_n", "d_sum_n"]
    print("1. friction less the truth's at the stop windows [N]")
    _table(pl.DataFrame(stops, schema=names, orient="row"), names[:3], names[3:])

    runs = []
    for trip in truth["trips"]:
        phase = trip["run_phase"]
        rows = _rows(tensions, phase["t0_utc"], phase["t1_utc"])
        if rows.height:
            d = _friction(rows).sum() - sum(phase["friction_n"])
            error = rows["load_n"].mean() / phase["true_load_n"] - 1.0
            runs.append((trip["direction"], d, 100.0 * error))
    print("2. over the run phases: friction summed less the truth's [N], load error [%]")
    _table(pl.DataFrame(runs, schema=["direction", "d_sum_n", "load_error_pct"],
                        orient="row"), ["direction"], ["d_sum_n", "load_error_pct"])  # fmt: skip

    run_rows = tensions.filter(pl.col("phase") == "run")
    per_trip = run_rows.group_by("trip_id").agg(
        pl.col("load_n").mean().alias("load"),
        pl.col("depth_m").mean().alias("depth"),
        ((pl.col("load_hi_n") - pl.col("load_lo_n")) / 2).mean().alias("half_width"),
        pl.col("time_utc").max().alias("end"),
    )
    fused = []
    for stop in truth["stops"]:
        windows = stop["windows"]
        arrival_start = _utc(windows[0]["t0_utc"])
        before = per_trip.filter(pl.col("end") < arrival_start).sort("end")
        if before.height == 0:
            continue
        trip = before.row(-1, named=True)
        if (arrival_start - trip["end"]).total_seconds() > 60.0:  # paused on the way
            continue
        tail = tail_rope_mass_kg(hoist, stop["depth_m"]) - tail_rope_mass_kg(hoist, trip["depth"])
        predicted = trip["load"] + float(tail) * G_STANDARD
        first = _rows(tensions, windows[0]["t0_utc"], windows[0]["t1_utc"])
        if first.height == 0:  # the record starts or ends within the stop
            continue
        estimate = first["load_n"].mean()
        sigma_e = ((first["load_hi_n"] - first["load_lo_n"]) / 2).mean()
        weight = sigma_e**2 / (sigma_e**2 + trip["half_width"] ** 2)
        shift = weight * (predicted - estimate)
        for k, window in enumerate(windows):
            rows = _rows(tensions, window["t0_utc"], window["t1_utc"])
            if rows.height == 0:
                continue
            load, true = rows["load_n"].mean(), window["true_load_n"]
            carried = k == 0 or abs(load - estimate) < CARRY_SHARE * estimate
            raw = rows["load_raw_n"].mean() / true - 1.0
            updated = (load + (shift if carried else 0.0)) / true - 1.0
            fused.append(
                (stop["position"], window["kind"], weight, 100 * (load / true - 1),
                 100 * updated, 100 * raw)
            )  # fmt: skip
    frame = pl.DataFrame(fused, schema=["position", "kind", "weight", "error_pct", "updated_pct",
                                        "raw_pct"], orient="row")  # fmt: skip
    worse = [
        int((frame[c].abs() > frame["raw_pct"].abs() + 0.2).sum())
        for c in ("error_pct", "updated_pct")
    ]
    print("3. the load-continuity update at arrivals: |error| [%]")
    before, after = frame["error_pct"].abs(), frame["updated_pct"].abs()
    print(f"   windows {frame.height}, median {before.median():.3f} -> {after.median():.3f}, "
          f"worst {before.max():.2f} -> {after.max():.2f}, "
          f"worse than raw {worse[0]} -> {worse[1]}")  # fmt: skip
    _table(frame.with_columns(pl.col("error_pct", "updated_pct").abs()),
           ["position", "kind"], ["weight", "error_pct", "updated_pct"])  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("kept", type=Path, help="eval_compensation.py --keep DIR")
    ap.add_argument("--days", type=Path, default=DEFAULT_DAYS, help="the truth JSONs")
    args = ap.parse_args()
    for data in sorted((args.kept / "data").iterdir()):
        if (args.days / f"{data.name}.truth.json").exists():
            diagnose(args.kept, data.name, args.days)


if __name__ == "__main__":
    main()
