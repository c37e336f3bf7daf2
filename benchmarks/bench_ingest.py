"""Benchmark: CSV ingest of a synthetic 100 Hz hoist-day next to a bare polars floor.

Generates a contract-1a CSV (8.64 M rows, ~720 MB; ``--scale 4`` = four consecutive
days in one file) with numpy/polars, then runs, each in its own subprocess so peak RSS
is the child's own (``ru_maxrss`` of the child, via ``resource.getrusage``):

* floor: ``polars.read_csv`` (header lines skipped, types inferred) + ``write_parquet``
  (zstd) of the same file, nothing else;
* ropeload: ``ingest_paths`` into a fresh data root (hash, parse, UTC, checks,
  dedup, partitioned atomic Parquet, manifest).

Prints MB/s, rows/s and peak RSS for both and the ratio. Target: ropeload within 2x of
the floor's time; peak RSS flat between ``--scale 1`` and ``--scale 4`` (run both with
``--compare-scales``). On a shared machine the times move with the load: ``--repeat N``
runs N floor/ropeload pairs back to back on the same file and reports the median ratio.

    uv run python benchmarks/bench_ingest.py                  # 1x day
    uv run python benchmarks/bench_ingest.py --compare-scales # 1x and 4x
    uv run python benchmarks/bench_ingest.py --repeat 3       # 1x day, 3 pairs
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl

ROWS_PER_DAY = 8_640_000
HEADER = (
    "# site: bench-mine\n# hoist: main-shaft-1\n# timezone: Asia/Shanghai\n"
    "# sample_rate_hz: 100\n# units: p=MPa, x=mm, depth=m, speed=m/s, oil_temp=degC\n"
)


def generate(path: Path, days: int, *, block: int = 2_000_000) -> int:
    """Write ``days`` hoist-days of 100 Hz samples; returns rows written."""
    rng = np.random.default_rng(1)
    total = days * ROWS_PER_DAY
    start = np.datetime64("2026-03-02T00:00:00.000", "ms")
    with path.open("wb") as handle:
        handle.write(HEADER.encode())
        first = True
        for offset in range(0, total, block):
            n = min(block, total - offset)
            index = np.arange(offset, offset + n)
            t = start + (index * 10).astype("timedelta64[ms]")
            depth = 310 + 300 * np.sin(index / 6000.0)
            frame = pl.DataFrame(
                {
                    "timestamp": pl.Series(t).dt.strftime("%Y-%m-%d %H:%M:%S%.3f"),
                    **{f"p{i}": np.round(4.8 + rng.normal(0, 0.05, n), 3) for i in range(1, 5)},
                    **{f"x{i}": np.round(rng.normal(0, 5, n), 1) for i in range(1, 5)},
                    "depth": np.round(depth, 2),
                    "speed": np.round(np.cos(index / 6000.0) * 0.05, 3),
                    "oil_temp": np.round(30 + rng.normal(0, 1, n), 1),
                }
            )
            frame.write_csv(handle, include_header=first)
            first = False
    return total


def _floor(csv: Path, out: Path) -> None:
    frame = pl.read_csv(csv, skip_rows=5)
    frame.write_parquet(out, compression="zstd")


def _ropeload(csv: Path, data: Path) -> None:
    from pipelines.ingest import ingest_paths
    from warehouse.store import DataRoot

    report = ingest_paths([csv], data=DataRoot.resolve(data))
    result = report.files[0]
    if result.status != "landed" or not result.balanced:
        raise SystemExit(f"ingest did not land the file: {result}")


def _child(kind: str, csv: Path, out: Path) -> None:
    start = time.perf_counter()
    (_floor if kind == "floor" else _ropeload)(csv, out)
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps({"seconds": seconds, "peak_rss_bytes": peak}))


def measure(kind: str, csv: Path, out: Path) -> dict:
    done = subprocess.run(
        [sys.executable, __file__, "--child", kind, str(csv), str(out)],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def run(days: int, workdir: Path, repeat: int = 1) -> dict:
    csv = workdir / f"day-x{days}.csv"
    rows = generate(csv, days)
    size = csv.stat().st_size
    os.sync()  # the generated file's dirty pages would otherwise be written back mid-run
    pairs = []
    for i in range(repeat):  # floor and ropeload alternate, so both see the same load
        data = workdir / f"data-x{days}-{i}"
        pairs.append(
            {
                "floor": measure("floor", csv, workdir / f"floor-x{days}.parquet"),
                "ropeload": measure("ropeload", csv, data),
            }
        )
        shutil.rmtree(data, ignore_errors=True)
    print(f"\nsynthetic 100 Hz CSV x{days}: {rows:,} rows, {size / 1e6:,.0f} MB")
    print(f"{'':<10}{'seconds':>9}{'MB/s':>9}{'Mrows/s':>9}{'peak RSS MB':>13}{'ratio':>8}")
    ratios = []
    for pair in pairs:
        ratio = pair["ropeload"]["seconds"] / pair["floor"]["seconds"]
        ratios.append(ratio)
        for name, r in pair.items():
            print(
                f"{name:<10}{r['seconds']:>9.2f}{size / 1e6 / r['seconds']:>9.1f}"
                f"{rows / 1e6 / r['seconds']:>9.2f}{r['peak_rss_bytes'] / 1e6:>13.0f}"
                + (f"{ratio:>7.2f}x" if name == "ropeload" else "")
            )
    label = "median of " + str(repeat) + " pairs" if repeat > 1 else "one pair"
    print(f"ropeload / floor time: {statistics.median(ratios):.2f}x ({label}; target <= 2x)")
    csv.unlink()
    return {
        "ropeload": {
            "peak_rss_bytes": max(p["ropeload"]["peak_rss_bytes"] for p in pairs),
        }
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=int, default=1, help="days in the file")
    parser.add_argument("--compare-scales", action="store_true", help="run 1x and 4x")
    parser.add_argument(
        "--repeat", type=int, default=1, help="floor/ropeload pairs per scale (median ratio)"
    )
    parser.add_argument("--child", nargs=3, metavar=("KIND", "CSV", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        kind, csv, out = args.child
        _child(kind, Path(csv), Path(out))
        return
    with tempfile.TemporaryDirectory(prefix="ropeload-bench-") as tmp:
        scales = (1, 4) if args.compare_scales else (args.scale,)
        peaks = {s: run(s, Path(tmp), args.repeat)["ropeload"]["peak_rss_bytes"] for s in scales}
        if len(peaks) == 2:
            print(
                f"\nropeload peak RSS: x1 {peaks[1] / 1e6:.0f} MB, x4 {peaks[4] / 1e6:.0f} MB "
                f"(ratio {peaks[4] / peaks[1]:.2f}; flat = ~1)"
            )


if __name__ == "__main__":
    main()
