"""Diagnosis (issue 14): the seals' friction at each departure, as the sanity check's
replay holds it, as the compensation estimates it and as the truth has it.

Not a test and not a target figure. For each validation day named (``../shared/
validation/days``, evaluation data, nothing tuned to it) the day is ingested, run and
sanity-checked as ``benchmarks/eval_sanity.py`` does (every trip in one chain of
replays), and for every compared trip it prints the check's gap over the noise beside
the seals' friction just before the trip moves:

- the truth's: ``friction_n`` of the last window of the stop the trip departs from;
- the compensation's: the landed ``friction{i}_n`` averaged over that window;
- the replay's: its simulated seals at the sample before the trip's motion starts, in
  the sanity check's last pass (read by wrapping ``sims.replay._simulate_trip`` for the
  script's run: the replay keeps only the scored pressures).

and per departure position and direction the RMS of each estimate's summed friction
less the truth's, per piston, and the correlation of the gap ratio with the replay's
summed error.

Session 52 found with it (days 101 and 104):

- the replay's seals are far from the truth's at the departures: the summed friction's
  error RMS 2341 / 1325 N from the pithead / bottom of day 104 (596 / 334 N a piston),
  2414 / 1597 N on day 101, where the compensation's estimate at the same windows is
  129 / 188 N (231 / 210 N on day 101) off a spread of 1.4-3.8 kN: the compensation
  knows the seals' state ten times better than the check's chain of replays;
- but the departure's common-mode residual (measured less replayed, the first 12 s of
  motion) is systematic by where and which way the trip leaves, whatever the seals:
  from the pithead down +18.0 kPa (sd 10.5) on day 104 and +15.9 kPa (sd 4.0) on day
  101, from the middle up -5.7 / -11.2 kPa, from the middle down -2.0 / +4.2 kPa, from
  the bottom up -1.3 / -0.6 kPa. The record's pressure changes less than the replay's
  where the tail rope below the conveyance is long, as if the replay counted some
  4-12 % more of the tail rope's inertia (~190 kPa at a pithead departure, ~95 kPa at
  the middle) than the record shows; the conveyance's own inertia (the bottom's
  departures) replays to ~1 kPa.
- That residual is what fails the trips (its correlation with the gap ratio +0.67 on
  day 104, +0.89 on day 101); the seals' start only modulates it on day 101
  (correlation with the replay's summed error +0.59) and not on the ringing day 104
  (-0.07). Its sign follows the replay's seal error, though: at the pithead the
  replay's seals sit nearer their capacity on the side the falling load pushes them
  (its sum ~1.8-2.4 kN more negative than the truth's), so they take up less of the
  fall and its pressure falls more; from the middle up they sit nearer the other side.
- Tried and not kept (a temporary patch of the replay, not in this script): every
  chained trip started afresh from the compensation's seals (pressures and pistons set
  so that each seal holds its estimate) at the start of its simulation, before its
  loading ramp. The check got worse (day 101 96.9 -> 78.5 %, day 104 87.7 -> 84.6 %)
  and the replay's seals at the departure were as far off as before (2548 N summed
  RMS from the pithead of day 101): the replayed payload change at rest drives the
  seals away from the truth's again, where the compensation follows them through the
  logged x. The seals would have to be taken from the record after the loading ramp,
  at the departure itself, or the replay's loading made to move the pistons as the
  logged x do.

    uv run python benchmarks/diagnose_departure_seals.py mine_day104 [mine_day101 ...]
"""

from __future__ import annotations

import datetime as dt
import json
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np
import polars as pl

import pipelines.sanity as sanity_module
import sims.replay as replay_module
from warehouse.store import DataRoot, open_reader

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_compensation import DEFAULT_DAYS, validation_case
from eval_sanity import check_day

ROPES = range(1, 5)


def _utc(text: str) -> dt.datetime:
    return dt.datetime.fromisoformat(text.replace("Z", "+00:00"))


#: The departure's stretch of each trip whose common-mode residual is averaged [s from
#: the motion's start]: the acceleration of a trip of the validation shaft.
DEPARTURE_S = 12.0


class ReplaySeals:
    """The replayed seals' friction just before each trip moves (the last pass's), and
    each trip's mean common-mode residual (measured less replayed, over the sensors)
    over its first :data:`DEPARTURE_S` of motion: wraps ``sims.replay._simulate_trip``
    and the sanity check's ``replay_fitted`` while in use."""

    def __init__(self) -> None:
        self.at_departure: dict[int, np.ndarray] = {}
        self.departure_residual_pa: dict[int, float] = {}
        self._lock = threading.Lock()
        self._original = replay_module._simulate_trip
        self._fitted = sanity_module.replay_fitted

    def _residuals(self, plan, *args, **kwargs):
        result = self._fitted(plan, *args, **kwargs)
        for tr, residual in zip(plan.trips, result.residuals(plan), strict=True):
            moving = (tr.time_s >= tr.motion_start_s) & (
                tr.time_s < tr.motion_start_s + DEPARTURE_S
            )
            common = np.nanmean(residual[moving], axis=1) if moving.any() else np.array([])
            if common.size and np.isfinite(common).any():
                self.departure_residual_pa[tr.trip_id] = float(np.nanmean(common))
        return result

    def __enter__(self) -> ReplaySeals:
        def recorded(plan, tr, names, prm, start, ramp_end, payloads, state):
            result = self._original(plan, tr, names, prm, start, ramp_end, payloads, state)
            t = start + result.frame["time_s"].to_numpy()
            i = max(int(np.searchsorted(t, tr.motion_start_s)) - 1, 0)
            seals = np.array([result.frame[f"friction{k}_n"][i] for k in ROPES])
            with self._lock:
                self.at_departure[tr.trip_id] = seals
            return result

        replay_module._simulate_trip = recorded
        sanity_module.replay_fitted = self._residuals
        return self

    def __exit__(self, *exc: object) -> None:
        replay_module._simulate_trip = self._original
        sanity_module.replay_fitted = self._fitted


def departures(name: str, work: Path) -> pl.DataFrame:
    """One row per compared trip of day ``name``: its gap ratio, where it departs, and
    the seals' friction before it (truth, compensation, replay)."""
    gz = Path(DEFAULT_DAYS) / f"{name}.csv.gz"
    case = validation_case(gz, work)
    with ReplaySeals() as seals:
        day = check_day(case, work, 200, "auto")
    truth = json.loads(gz.with_name(f"{name}.truth.json").read_text())
    data = DataRoot.resolve(work / f"{case.csv.stem}_data")
    with open_reader(data) as con:
        trips = con.sql("SELECT trip_id, time_start_utc FROM trip_summary").pl()
        friction = ", ".join(f"friction{i}_n" for i in ROPES)
        landed = con.sql(f"SELECT time_utc, {friction} FROM rope_tensions").pl()
    landed = landed.with_columns(pl.col("time_utc").dt.convert_time_zone("UTC"))
    checks = day["checks"].join(trips, on="trip_id", how="left")
    rows = []
    for trip in checks.iter_rows(named=True):
        moved = trip["time_start_utc"]
        if (
            trip["status"] == "skipped"
            or moved is None
            or trip["trip_id"] not in seals.at_departure
        ):
            continue
        stops = [
            s
            for s in truth["stops"]
            if s["windows"] and _utc(s["t1_utc"]) <= moved + dt.timedelta(seconds=5)
        ]
        if not stops:
            continue
        window = stops[-1]["windows"][-1]
        inside = landed.filter(
            (pl.col("time_utc") >= _utc(window["t0_utc"]))
            & (pl.col("time_utc") < _utc(window["t1_utc"]))
        )
        estimate = [float(inside[f"friction{i}_n"].mean()) for i in ROPES]
        rows.append(
            {
                "trip_id": trip["trip_id"],
                "status": trip["status"],
                "ratio": trip["ratio"],
                "direction": trip["direction"],
                "from": stops[-1]["position"],
                "truth_n": [float(f) for f in window["friction_n"]],
                "compensation_n": estimate,
                "replay_n": seals.at_departure[trip["trip_id"]].tolist(),
                "departure_kpa": seals.departure_residual_pa.get(trip["trip_id"], np.nan) / 1e3,
            }
        )
    return pl.DataFrame(rows)


def _summary(frame: pl.DataFrame) -> None:
    truth = np.array(frame["truth_n"].to_list())
    for name in ("compensation_n", "replay_n"):
        frame = frame.with_columns(
            pl.Series(f"{name}_error_sum", np.array(frame[name].to_list()).sum(1) - truth.sum(1))
        )
    print(
        f"{'trip':>4} {'status':7} {'ratio':>5} {'dir':4} {'from':8} "
        f"{'sum truth':>9} {'sum comp':>9} {'sum repl':>9} [N] {'departure':>9} [kPa]"
    )
    for row in frame.iter_rows(named=True):
        print(
            f"{row['trip_id']:4d} {row['status']:7} {row['ratio']:5.2f} {row['direction']:4} "
            f"{row['from']:8} {sum(row['truth_n']):9.0f} {sum(row['compensation_n']):9.0f} "
            f"{sum(row['replay_n']):9.0f}     {row['departure_kpa']:9.1f}"
        )
    for (place, way), part in frame.group_by("from", "direction", maintain_order=True):
        if part.height < 4:
            continue
        t = np.array(part["truth_n"].to_list())
        r = np.array(part["replay_n"].to_list())
        c = np.array(part["compensation_n"].to_list())
        replay_sum = r.sum(1) - t.sum(1)

        def rms(v: np.ndarray) -> float:
            return float(np.sqrt(np.mean(v**2)))

        departure = part["departure_kpa"].to_numpy()
        print(
            f"from the {place} {way} ({part.height} trips): summed friction's error RMS: "
            f"replay {rms(replay_sum):.0f} N ({rms(r - t):.0f} N a piston), compensation "
            f"{rms(c.sum(1) - t.sum(1)):.0f} N ({rms(c - t):.0f} N a piston), the truth's "
            f"spread {rms(t.sum(1)):.0f} N; correlation of the gap ratio with |replay's "
            f"error| {np.corrcoef(part['ratio'].to_numpy(), np.abs(replay_sum))[0, 1]:+.2f}; "
            f"departure residual mean {np.nanmean(departure):+.1f} kPa (sd "
            f"{np.nanstd(departure):.1f}), its correlation with the replay's summed error "
            f"{np.corrcoef(departure, replay_sum)[0, 1]:+.2f}, with the truth's sum "
            f"{np.corrcoef(departure, t.sum(1))[0, 1]:+.2f}, with the gap ratio "
            f"{np.corrcoef(departure, part['ratio'].to_numpy())[0, 1]:+.2f}"
        )


def main() -> None:
    names = sys.argv[1:] or ["mine_day104"]
    with tempfile.TemporaryDirectory(prefix="ropeload-departure-seals-") as tmp:
        for name in names:
            print(f"\n== {name}")
            _summary(departures(name, Path(tmp)))


if __name__ == "__main__":
    main()
