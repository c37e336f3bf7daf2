"""Benchmark: nightly run and backfill as plain functions and as Prefect flows.

Cases (synthetic logs from :func:`pipelines.deploy.write_example_mine`, CSV, 100 Hz):

* ``nightly``: one hoist-day (``--night-hours`` of logs, default 24: 8.64 M samples)
  through ingest + compensation + reconciliation + alarms + sanity check;
* ``backfill``: ``--days`` (30) days x 2 hoists, each day ``--backfill-minutes`` (10) of
  logs, one partition per hoist-day (the sanity check off, as for history).

Each case runs twice on fresh data roots from the same raw files: the plain functions
(``pipelines.nightly.nightly`` / ``pipelines.backfill.backfill``) and the flow (a
Prefect server started beforehand, as in production, so its start-up is not counted).
Both with ``--workers`` (1) partitions at a time, so the plain functions' walls add up.
Orchestration overhead = flow wall - (sum of the plain functions' walls inside the
flow: ingest + partitions + report); target < 10 % of the flow wall.

    .venv/bin/python benchmarks/bench_flows.py                        # full sizes
    .venv/bin/python benchmarks/bench_flows.py --night-hours 2 --days 10   # quicker
"""

from __future__ import annotations

import argparse
import datetime as dt
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipelines.prefect_env import apply_prefect_defaults

apply_prefect_defaults()

from pipelines.backfill import backfill  # noqa: E402
from pipelines.deploy import write_example_mine  # noqa: E402
from pipelines.hoists import load_hoists  # noqa: E402
from pipelines.ledger import fingerprint  # noqa: E402
from pipelines.nightly import nightly  # noqa: E402
from pipelines.reports import write_fleet_report  # noqa: E402
from warehouse.store import DataRoot  # noqa: E402


def _line(name: str, wall: float, rows: int, work: float | None = None) -> str:
    text = f"  {name:<28} wall {wall:8.2f} s  {rows / wall:12,.0f} rows/s"
    if work is not None:
        overhead = wall - work
        text += f"  plain functions {work:7.2f} s  orchestration {overhead:6.2f} s"
        text += f" = {100 * overhead / wall:5.1f} %"
    return text


def _compare(plain: DataRoot, flowed: DataRoot) -> None:
    a, b = fingerprint(plain), fingerprint(flowed)
    differ = sorted(k for k in a if a[k] != b[k])
    print(f"  flow rows == plain rows (counts + checksums): {not differ} {differ or ''}")


def bench_nightly(root: Path, hours: float, workers: int) -> None:
    from pipelines.flows import run_nightly_flow

    t0 = time.perf_counter()
    hoists, incoming = write_example_mine(
        root / "mine",
        hoists=1,
        days=1,
        hours=hours,
        trips=max(2, round(5 * hours)),
        start_hour=0.0,
    )
    print(
        f"nightly: 1 hoist-day, {hours:g} h at 100 Hz (generated in "
        f"{time.perf_counter() - t0:.0f} s)"
    )
    plain_data = DataRoot.resolve(root / "plain-night")
    sources = load_hoists(hoists, data=plain_data, incoming=incoming)
    t0 = time.perf_counter()
    plain = nightly(sources, data=plain_data, max_workers=workers)
    plain_wall = time.perf_counter() - t0
    rows = plain.runs.samples
    print(_line("plain nightly()", plain_wall, rows))
    flow_data = root / "flow-night"
    t0 = time.perf_counter()
    flowed = run_nightly_flow(hoists, data=flow_data, incoming=incoming, max_workers=workers)
    flow_wall = time.perf_counter() - t0
    t1 = time.perf_counter()
    write_fleet_report(
        DataRoot.resolve(flow_data), kind="nightly", outcomes=flowed.runs.outcomes,
        sources=sources, sanity=True,
    )  # fmt: skip
    report_s = time.perf_counter() - t1
    print(_line("nightly flow", flow_wall, rows, flowed.work_s + report_s))
    print(
        f"  (report + plots {report_s:.2f} s; partitions {flowed.runs.work_s:.2f} s; "
        f"per-hoist ingest {sum(n.ingest_s for n in flowed.hoists):.2f} s)"
    )
    _compare(plain_data, DataRoot.resolve(flow_data))


def bench_backfill(root: Path, days: int, minutes: float, workers: int) -> None:
    from pipelines.flows import run_backfill_flow

    t0 = time.perf_counter()
    first = dt.date(2026, 1, 1)
    hoists, incoming = write_example_mine(
        root / "mine-b", hoists=2, days=days, first_day=first, hours=minutes / 60, trips=2
    )
    print(
        f"backfill: {days} days x 2 hoists, {minutes:g} min/day at 100 Hz (generated in "
        f"{time.perf_counter() - t0:.0f} s)"
    )
    last = first + dt.timedelta(days=days - 1)
    plain_data = DataRoot.resolve(root / "plain-backfill")
    sources = load_hoists(hoists, data=plain_data, incoming=incoming)
    t0 = time.perf_counter()
    plain = backfill(sources, data=plain_data, start=first, end=last, max_workers=workers)
    plain_wall = time.perf_counter() - t0
    rows = plain.samples
    print(_line("plain backfill()", plain_wall, rows))
    flow_data = root / "flow-backfill"
    t0 = time.perf_counter()
    flowed = run_backfill_flow(
        [hoists], start=first, end=last, data=flow_data, incoming=incoming, max_workers=workers
    )
    flow_wall = time.perf_counter() - t0
    t1 = time.perf_counter()
    write_fleet_report(
        DataRoot.resolve(flow_data), kind="backfill", outcomes=flowed.outcomes,
        sources=sources, sanity=False,
    )  # fmt: skip
    report_s = time.perf_counter() - t1
    print(_line("backfill flow", flow_wall, rows, flowed.work_s + report_s))
    print(f"  ({flowed.count('succeeded')} partitions run, report + plots {report_s:.2f} s)")
    _compare(plain_data, DataRoot.resolve(flow_data))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--night-hours", type=float, default=24.0)
    parser.add_argument("--days", type=int, default=30)
    parser.add_argument("--backfill-minutes", type=float, default=10.0)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()
    from prefect.testing.utilities import prefect_test_harness

    root = Path(tempfile.mkdtemp(prefix="ropeload-bench-flows-"))
    try:
        t0 = time.perf_counter()
        with prefect_test_harness(server_startup_timeout=120):
            print(f"local Prefect server up in {time.perf_counter() - t0:.1f} s (not counted)")
            bench_nightly(root, args.night_hours, args.workers)
            bench_backfill(root, args.days, args.backfill_minutes, args.workers)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
