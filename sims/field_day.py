"""Synthetic field days: what a mine's monitoring computer logs, with the truth beside it.

:func:`generate_field_day` runs the device simulation (:func:`sims.device.simulate`,
paper sections 2-3) for each trip of a day's schedule -- payload varying per trip,
standstill between trips, oil temperature drifting over the day -- stitches the trips on
one UTC timeline, applies the logger's sensor model (:mod:`sims.noise`) and returns a
:class:`FieldDay`: the sensor-level frame (what the logger records, SI), the truth frame
(true rope tensions, chamber pressures, load, payload, trip ids, phases) and a truth
dict (effects on and their parameters, seed, noise model, trips).

:func:`write_field_day` writes the sensor frame as a mine exports it (contract 1a CSV
and/or 1b TDMS, one file per day or per local hour, named
``<site>_<hoist>_<YYYYMMDD>[_<HH>00].<ext>``) and the truth as Parquet + JSON beside it.

The day is one continuous history. The first trip starts from the static equilibrium
:func:`sims.device.simulate` starts in (empty conveyance at the pithead) and begins with
its loading phase; every later trip continues from the previous trip's final state
(:attr:`sims.device.SimulationResult.final_state`: pressures, pistons, flows,
conveyance, and the seals' friction memory -- LuGre bristles or Maxwell-slip
deflections). Between trips the conveyance stands still and that state is held
(nothing moves, the friction stays in the seals, as real seals hold it through a
standstill), so neither friction nor pressures step at a trip start.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import zoneinfo
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import polars as pl

from schemas.hoist import HoistDescription
from sims.device import simulate
from sims.effects import parameters_json
from sims.field_logs import write_csv, write_tdms
from sims.noise import NoiseModel, apply_sensor_noise
from sims.trips import TripProfile, trip

__all__ = ["FieldDay", "generate_field_day", "write_field_day"]

_MOVING = ("speed_m_s", "acceleration_up_m_s2")  # zero while standing still


@dataclass
class FieldDay:
    """A generated field day.

    ``sensors``: the logged frame in SI (``time_utc``, ``p{i}_pa``, ``x{i}_m``,
    ``depth_m``, ``speed_m_s``, ``oil_temp_c``), noisy, jittered, with dropped samples.
    ``truth``: one row per nominal sample (``time_utc``, ``trip_id`` (null at
    standstill between trips), ``phase``, ``direction``, and the device simulation's
    true states: ``depth_m, speed_m_s, acceleration_up_m_s2, payload_kg, oil_temp_c,
    p_chamber{i}_pa, p_sensor{i}_pa, x{i}_m, v{i}_m_s, q{i}_m3_s, friction{i}_n,
    tension{i}_n, load_n, p_manifold_pa, oil_volume_m3``).
    ``info``: seed, effects and parameters, noise model, trips, solver notes.
    """

    hoist: HoistDescription
    sensors: pl.DataFrame
    truth: pl.DataFrame
    info: dict[str, Any] = field(default_factory=dict)


def _phase_expr(creep_m_s: float) -> pl.Expr:
    speed = pl.col("speed_m_s").abs()
    acc_down = -pl.col("acceleration_up_m_s2") * pl.col("speed_m_s").sign()
    return (
        pl.when(speed < 1e-6)
        .then(pl.lit("standstill"))
        .when(acc_down > 1e-6)
        .then(pl.lit("accelerate"))
        .when(acc_down < -1e-6)
        .then(pl.lit("decelerate"))
        .when(speed <= creep_m_s * 1.01)
        .then(pl.lit("creep"))
        .otherwise(pl.lit("run"))
        .alias("phase")
    )


def _start_utc(hoist: HoistDescription, date: dt.date | str, start_hour: float) -> dt.datetime:
    day = dt.date.fromisoformat(date) if isinstance(date, str) else date
    local = dt.datetime.combine(day, dt.time(0), tzinfo=zoneinfo.ZoneInfo(hoist.hoist.timezone))
    return (local + dt.timedelta(hours=start_hour)).astimezone(dt.UTC)


def generate_field_day(
    hoist: HoistDescription,
    *,
    date: dt.date | str,
    seed: int,
    trips: int = 120,
    hours: float = 24.0,
    start_hour: float = 0.0,
    effects: Sequence[str] | None = None,
    parameters: dict[str, dict[str, Any]] | None = None,
    sample_rate_hz: float = 100.0,
    noise: NoiseModel | None = None,
    oil_temp_c: tuple[float, float] = (28.0, 38.0),
    loading_s: float = 20.0,
    rest_after_s: float = 45.0,
    dt_s: float = 2e-3,
    max_speeds_m_s: Sequence[float] | None = None,
) -> FieldDay:
    """Generate a synthetic field day for ``hoist``.

    Longer than 80 lines on purpose: most of it is this docstring (every parameter and
    the result documented); the code is 55 lines.

    Parameters
    ----------
    hoist : HoistDescription
        The hoist (contract section 2).
    date : date or ISO string
        Local calendar date of the log (the hoist's time zone).
    seed : int
        Seeds payloads and the sensor model: same seed, same day.
    trips : int
        One-way trips, alternating down (from the pithead, empty) and up (from the
        bottom, loaded with 60-100 % of the rated payload), started at equal intervals.
    hours : float
        Length of the logged period [h] from ``start_hour`` local time.
    effects, parameters
        Passed to :func:`sims.device.simulate` (default the hoist's ``[model] effects``).
    sample_rate_hz : float
        Logger rate [Hz]; the simulation's output rate.
    noise : NoiseModel, optional
        Sensor model; default :class:`~sims.noise.NoiseModel()`. ``NoiseModel.none()``
        for a perfect logger.
    oil_temp_c : (float, float)
        Oil temperature at the start and end of the period [degC] (per trip constant
        in the simulation, linear over the period).
    loading_s : float
        Duration of the payload change at the start of each trip [s].
    rest_after_s : float
        Simulated standstill after each stop [s], long enough for the rope bounce to
        decay (head-rope damping ratio 0.02); after it the state is held.
    dt_s : float
        Integrator step of the device simulation [s].
    max_speeds_m_s : sequence of float, optional
        Full (winding) speed of each trip [m/s], cycled over the trips (trip ``k`` runs
        at ``max_speeds_m_s[k % len]``); default the winder's ``max_speed_m_s`` for all.

    Returns
    -------
    FieldDay
    """
    noise = NoiseModel() if noise is None else noise
    speeds = None if max_speeds_m_s is None else [float(v) for v in max_speeds_m_s]
    if speeds is not None and (not speeds or min(speeds) <= 0.0):
        raise ValueError(f"max_speeds_m_s: need positive speeds, got {max_speeds_m_s!r}")
    rng = np.random.default_rng(seed)  # payloads first, then the sensor noise
    plan = _DayPlan(hours, trips, loading_s, rest_after_s, oil_temp_c, speeds)
    run = {"effects": effects, "parameters": parameters, "output_rate_hz": sample_rate_hz}
    pieces, trip_rows, resolved = _simulate_trips(hoist, plan, rng, dict(run, dt_s=dt_s))
    start = _start_utc(hoist, date, start_hour)
    truth = _truth(hoist, pieces, start, round(hours * 3600.0 * sample_rate_hz), sample_rate_hz)
    n = hoist.ropes_n
    sensor = truth.select(
        "time_utc",
        *[pl.col(f"p_sensor{i}_pa").alias(f"p{i}_pa") for i in range(1, n + 1)],
        *[pl.col(f"x{i}_m") for i in range(1, n + 1)],
        "depth_m",
        "speed_m_s",
        "oil_temp_c",
    )
    sensor = apply_sensor_noise(sensor, noise, rng, sample_rate_hz=sample_rate_hz)
    info: dict[str, Any] = {
        "site": hoist.hoist.site,
        "hoist": hoist.hoist.name,
        "timezone": hoist.hoist.timezone,
        "date": str(date),
        "start_utc": start.isoformat(),
        "hours": hours,
        "seed": seed,
        "sample_rate_hz": sample_rate_hz,
        "effects": sorted(resolved.enabled) if resolved is not None else [],
        "parameters": parameters_json(resolved.parameters) if resolved is not None else {},
        "noise": dataclasses.asdict(noise),
        "trips": trip_rows,
        "dt_s": dt_s,
        "friction_law_si": dataclasses.asdict(hoist.friction_law),
    }
    return FieldDay(hoist=hoist, sensors=sensor, truth=truth, info=info)


@dataclasses.dataclass(frozen=True)
class _DayPlan:
    """The day's trips: how many in how long, loading and rest, oil warming, speeds."""

    hours: float
    trips: int
    loading_s: float
    rest_after_s: float
    oil_temp_c: tuple[float, float]
    speeds: list[float] | None

    @property
    def period_s(self) -> float:
        return self.hours * 3600.0 / max(self.trips, 1)


def _trip_profile(
    hoist: HoistDescription, plan: _DayPlan, k: int, payload_before: float, payload: float
) -> TripProfile:
    """Trip k: down from the pithead (even k) or up from the bottom, at its start time,
    with the payload changed over ``loading_s`` at its start and the oil's temperature."""
    down = k % 2 == 0
    top = hoist.shaft.positions_m.get("pithead", 0.0)
    bottom = hoist.shaft.positions_m.get("bottom", hoist.shaft.depth_m)
    start_s = k * plan.period_s
    t0, t1 = plan.oil_temp_c
    temp = t0 + (t1 - t0) * (start_s + 0.5 * plan.period_s) / (plan.hours * 3600.0)
    base = trip(
        hoist,
        start_depth_m=top if down else bottom,
        end_depth_m=bottom if down else top,
        rest_before_s=plan.loading_s + 5.0,
        rest_after_s=plan.rest_after_s,
        max_speed_m_s=None if plan.speeds is None else plan.speeds[k % len(plan.speeds)],
        oil_temp_c=temp,
        start_time_s=start_s,
    )
    profile: TripProfile = dataclasses.replace(
        base,
        payload_time_s=np.array([0.0, plan.loading_s]),
        payload_kg=np.array([payload_before, payload]),
    )
    if profile.duration_s > plan.period_s:
        raise ValueError(
            f"trips: {plan.trips} trips of {profile.duration_s:.0f} s do not fit in "
            f"{plan.hours:g} h (period {plan.period_s:.0f} s)"
        )
    return profile


def _simulate_trips(
    hoist: HoistDescription, plan: _DayPlan, rng: np.random.Generator, run: dict[str, Any]
) -> tuple[list[pl.DataFrame], list[dict[str, Any]], Any]:
    """Each trip simulated from the previous one's final state: the frames (numbered by
    output sample), one row per trip, and the resolved effects."""
    rated = hoist.conveyance.rated_payload_kg
    pieces: list[pl.DataFrame] = []
    trip_rows: list[dict[str, Any]] = []
    resolved, state, payload_before = None, None, 0.0
    for k in range(plan.trips):
        low, high = (0.0, 0.05) if k % 2 == 0 else (0.6, 1.0)
        payload = float(rng.uniform(low, high) * rated)
        profile = _trip_profile(hoist, plan, k, payload_before, payload)
        result = simulate(hoist, profile, initial_state=state, **run)
        if not result.ok:
            raise RuntimeError(f"trip {k}: device simulation failed: {result.message}")
        resolved, state = result.effects, result.final_state
        start_s = k * plan.period_s
        i0 = round(start_s * run["output_rate_hz"])
        pieces.append(
            result.frame.with_columns(
                (pl.int_range(pl.len(), dtype=pl.Int64) + i0).alias("sample"),
                pl.lit(k, dtype=pl.Int64).alias("trip_id"),
                pl.lit(profile.direction).alias("direction"),
            ).drop("time_s")
        )
        trip_rows.append(
            {
                "trip_id": k,
                "direction": profile.direction,
                "start_s": start_s,
                "duration_s": profile.duration_s,
                "payload_before_kg": payload_before,
                "payload_kg": payload,
                "oil_temp_c": float(profile.oil_temp_c),
                "start_depth_m": float(profile.segment_depth_m[0]),
                "end_depth_m": float(profile.segment_depth_m[-1]),
            }
        )
        payload_before = payload
    return pieces, trip_rows, resolved


def _truth(
    hoist: HoistDescription,
    pieces: list[pl.DataFrame],
    start: dt.datetime,
    n_total: int,
    sample_rate_hz: float,
) -> pl.DataFrame:
    """The trips on the day's sample grid: the state held between trips, times in UTC,
    direction and phase labels."""
    stitched = pl.concat(pieces, how="vertical").filter(pl.col("sample") < n_total)
    grid = pl.DataFrame({"sample": np.arange(n_total, dtype=np.int64)})
    value_cols = [c for c in stitched.columns if c not in ("sample", "trip_id", "direction")]
    truth = grid.join(stitched, on="sample", how="left")
    in_trip = truth["trip_id"].is_not_null()
    truth = truth.with_columns(pl.col(value_cols).forward_fill())
    # standstill between trips: hold the last state, nothing moves
    moving = [c for c in value_cols if c in _MOVING or c.startswith(("v", "q"))]
    truth = truth.with_columns(
        [pl.when(pl.Series(in_trip)).then(pl.col(c)).otherwise(0.0).alias(c) for c in moving]
    )
    t_ns = (truth["sample"].to_numpy() * (1e9 / sample_rate_hz)).round().astype(np.int64)
    start_ns = int(start.timestamp()) * 1_000_000_000 + start.microsecond * 1000
    time_utc = pl.Series("time_utc", start_ns + t_ns).cast(pl.Datetime("ns", "UTC"))
    truth = truth.with_columns(
        time_utc.cast(pl.Datetime("us", "UTC")),
        pl.col("direction").fill_null("rest"),
    )
    truth = truth.with_columns(
        pl.when(pl.col("speed_m_s").abs() < 1e-6)
        .then(pl.lit("rest"))
        .otherwise(pl.col("direction"))
        .alias("direction"),
        _phase_expr(hoist.winder.creep_speed_m_s),
    )
    front = ["time_utc", "trip_id", "phase", "direction"]
    return truth.select(front + [c for c in truth.columns if c not in front and c != "sample"])


def write_field_day(
    day: FieldDay,
    directory: str | Path,
    *,
    formats: Sequence[Literal["csv", "tdms"]] = ("csv", "tdms"),
    split: Literal["day", "hour"] = "day",
    csv_options: dict[str, Any] | None = None,
) -> list[Path]:
    """Write ``day`` as a mine exports it, plus the truth beside it.

    Files: ``<site>_<hoist>_<YYYYMMDD>.<ext>`` (``split="day"``) or
    ``<site>_<hoist>_<YYYYMMDD>_<HH>00.<ext>`` (``split="hour"``, local time of the
    hoist), and ``<site>_<hoist>_<YYYYMMDD>_truth.parquet`` / ``_truth.json`` (truth
    frame and truth dict). ``csv_options`` go to :func:`sims.field_logs.write_csv`
    (``units``, ``delimiter``, ``decimal``, ``missing``, ``with_offset``).

    Returns the written paths (logs first, then the truth files).
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    hoist = day.hoist
    tz = hoist.hoist.timezone
    stem = f"{hoist.hoist.site}_{hoist.hoist.name}"
    rate = float(day.info.get("sample_rate_hz", 100.0))
    fmt = "%Y%m%d" if split == "day" else "%Y%m%d_%H00"
    keyed = day.sensors.with_columns(
        pl.col("time_utc").dt.convert_time_zone(tz).dt.strftime(fmt).alias("_key")
    )
    paths: list[Path] = []
    for (key,), part in keyed.partition_by("_key", as_dict=True, maintain_order=True).items():
        part = part.drop("_key")
        for kind in formats:
            target = directory / f"{stem}_{key}.{kind}"
            if kind == "csv":
                write_csv(part, target, hoist=hoist, sample_rate_hz=rate, **(csv_options or {}))
            elif kind == "tdms":
                write_tdms(part, target, hoist=hoist, sample_rate_hz=rate)
            else:
                raise ValueError(f"formats: unknown format {kind!r}; use 'csv' or 'tdms'")
            paths.append(target)
    first = day.truth["time_utc"][0].astimezone(zoneinfo.ZoneInfo(tz)).strftime("%Y%m%d")
    truth_parquet = directory / f"{stem}_{first}_truth.parquet"
    truth_json = directory / f"{stem}_{first}_truth.json"
    day.truth.write_parquet(truth_parquet, compression="zstd")
    truth_json.write_text(json.dumps(day.info, indent=2, default=str))
    return [*paths, truth_parquet, truth_json]
