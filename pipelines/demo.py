"""``ropeload demo``: the whole job on built-in synthetic data, nothing to configure.

1. simulate a short day of hoist trips for the paper's field-test hoist
   (``schemas/hoists/paper_field_test.toml``) with the device model of ``sims/`` and
   write it as the mine's logger would (CSV and TDMS, with noise, jitter and dropouts);
2. ingest the files into the Parquet lake;
3. compensate, reconcile and alarm the period, check its trips against the hoist's
   simulation, land it in the warehouse and write its HTML report (``<data>/reports/``);
4. print, per hoist position, the measured (uncompensated), compensated and expected
   load, and, because the data are synthetic, the true load the simulation applied.
"""

from __future__ import annotations

import datetime as dt
import logging
import shutil
from pathlib import Path

import polars as pl

from pipelines.ingest import ingest_paths
from pipelines.run_period import RunResult, run_checked
from schemas.hoist import EXAMPLE_HOIST, HoistDescription, load_hoist
from sims.accuracy import position_accuracy
from sims.field_day import generate_field_day, write_field_day
from warehouse.store import DataRoot

__all__ = ["DEMO_DATE", "demo_summary", "run_demo"]

logger = logging.getLogger(__name__)

DEMO_DATE = dt.date(2026, 3, 2)


def demo_summary(result: RunResult, truth: pl.DataFrame, hoist: HoistDescription) -> str:
    """Per-position text table: measured vs compensated vs expected load.

    The demo's data are simulated, so the expected load is the one the simulation applied
    (conveyance, payload, tail rope, dynamics). Visits are the steady ones: at rest at a
    position, or passing it at constant speed; errors are the worst visit's.
    """
    visits = position_accuracy(result.rope_tensions.lazy().collect(), truth, min_samples=50).filter(
        pl.col("phase").is_in(["standstill", "run"])
    )
    order = {name: k for k, name in enumerate(hoist.shaft.positions_m)}
    by_position = (
        visits.group_by("position")
        .agg(
            pl.len().alias("visits"),
            (pl.col("load_before_n").mean() / 1e3).alias("measured_kn"),
            (pl.col("load_after_n").mean() / 1e3).alias("compensated_kn"),
            (pl.col("true_load_n").mean() / 1e3).alias("expected_kn"),
            (pl.col("error_before_fraction").abs().max() * 100).alias("err_before_pct"),
            (pl.col("error_after_fraction").abs().max() * 100).alias("err_after_pct"),
            (pl.col("rope_error_after_fraction").max() * 100).alias("rope_err_after_pct"),
        )
        .sort(pl.col("position").replace_strict(order, default=len(order)))
    )
    trips = result.trip_summary
    lines = [
        f"ropeload demo: {hoist.hoist.site}/{hoist.hoist.name}, run {result.run_id}",
        f"  period {result.period_start_utc:%Y-%m-%d %H:%M} .. "
        f"{result.period_end_utc:%H:%M} UTC, {result.samples} samples, "
        f"{trips.height} trips, {result.alarms.height} alarms",
        "",
        "  total load on the four ropes per hoist position (kN, mean of steady visits;",
        "  errors: worst visit against the load the simulation applied)",
        f"  {'position':<9} {'visits':>6} {'measured':>9} {'compens.':>9} {'expected':>9}"
        f" {'err before':>10} {'err after':>9} {'worst rope after':>16}",
    ]
    for row in by_position.iter_rows(named=True):
        lines.append(
            f"  {row['position']:<9} {row['visits']:>6} {row['measured_kn']:>9.2f}"
            f" {row['compensated_kn']:>9.2f} {row['expected_kn']:>9.2f}"
            f" {row['err_before_pct']:>9.2f}% {row['err_after_pct']:>8.2f}%"
            f" {row['rope_err_after_pct']:>15.2f}%"
        )
    if trips.height:
        spread = trips["payload_spread_kg"].drop_nulls()
        lines += [
            "",
            f"  reconciliation: payload inferred per trip {trips['payload_kg'].min():.0f} .. "
            f"{trips['payload_kg'].max():.0f} kg; spread across positions within a trip "
            f"<= {spread.max() if spread.len() else float('nan'):.0f} kg",
        ]
    return "\n".join(lines) + "\n"


def _write_logs(day, incoming: Path, seed: int) -> list[Path]:
    """Write the simulated day's files into ``incoming`` (beside it first): refused
    where a demo log of the same name there differs, another seed's (its samples are
    landed for the same times: this seed's would conflict, and the run would compare
    the old samples with the new simulation's truth)."""
    staging = incoming.with_name(f".{incoming.name}-next")
    shutil.rmtree(staging, ignore_errors=True)
    try:
        written = write_field_day(day, staging, formats=("csv",))
        for path in written:
            old = incoming / path.name
            if path.suffix == ".csv" and old.exists() and old.read_bytes() != path.read_bytes():
                raise ValueError(
                    f"{incoming.parent.parent} already holds the demo of another seed "
                    f"({old.name} differs): run the demo with --seed {seed} in a fresh "
                    "--data folder"
                )
        incoming.mkdir(parents=True, exist_ok=True)
        return [path.replace(incoming / path.name) for path in written]
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def run_demo(*, data: DataRoot, seed: int = 7, hours: float = 1.0) -> str:
    """Generate, ingest, compensate, reconcile and land a synthetic day; return a summary."""
    hoist = load_hoist(EXAMPLE_HOIST)
    trips = max(2, round(6 * hours))
    day = generate_field_day(
        hoist, date=DEMO_DATE, seed=seed, trips=trips, hours=hours, start_hour=6.0
    )
    incoming = data.path / "incoming" / "demo"
    written = _write_logs(day, incoming, seed)
    logs = [p for p in written if p.suffix == ".csv"]
    logger.info("demo: %d synthetic log file(s) written to %s", len(logs), incoming)
    report = ingest_paths(logs, data=data, hoist_lookup=lambda site, name: hoist)
    if not report.ok:
        refused = "; ".join(f"{f.path.name}: {f.message}" for f in report.refused)
        raise RuntimeError(f"demo logs were refused by ingest: {refused}")
    # whole seconds around the log: the CSV keeps milliseconds, the simulation microseconds
    start = day.sensors["time_utc"].min().replace(microsecond=0)
    end = day.sensors["time_utc"].max().replace(microsecond=0) + dt.timedelta(seconds=1)
    checked = run_checked(
        hoist_path=EXAMPLE_HOIST, data=data, start=start, end=end, hoist=hoist, command="demo"
    )
    result = checked.result
    totals = report.totals()
    header = (
        f"ingested {len(logs)} file(s) from {Path(incoming)}: {totals['rows_read']} rows read, "
        f"{totals['rows_landed']} landed, {totals['rows_quarantined']} quarantined, "
        f"{totals['rows_duplicate']} duplicates\n"
    )
    footer = (
        f"\n  {checked.sanity_words}\n"
        f"  report: {checked.report or 'not written (its run_steps row says why)'}\n"
        f"  warehouse: {data.warehouse}\n"
        f'  try: ropeload query --data {data.path} "select * from position_summary"\n'
    )
    if checked.sanity_error is not None:
        raise checked.sanity_error
    return header + demo_summary(result, day.truth, hoist) + footer
