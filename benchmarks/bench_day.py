"""Benchmark: a hoist-day end to end against the I/O floor and a plain pandas script (issue 16).

Writes a simulated 100 Hz field day (ropeload's own simulator, 120 trips a day; the
numbers do not matter here, only their shape) as a contract-1a CSV of ``--hours``
hours, then runs, each in its own subprocess so that peak RSS (``ru_maxrss`` of the
child) is the child's own:

* floor: ``polars.read_csv`` + ``write_parquet`` of the same file, nothing else;
* pandas: :mod:`benchmarks.pandas_static` -- the paper's static compensation (eq 2 with
  a constant friction and pipe loss) with pandas, the way a hoist engineer would script
  it: read the CSV, convert units, compute four tensions and the load, write Parquet;
* ropeload: ``ropeload ingest`` then ``ropeload run --no-sanity`` into a fresh data root
  (two processes, as a user runs them; peak RSS is the larger of the two).

For ``--hours 24`` and ``--double`` (a 24 h and a 48 h file in one run) it prints seconds,
peak RSS and the ratios the issue targets: ropeload <= 3x the floor, >= 2x the pandas
script's speed, peak <= 2 GB for a day and <= 1.1x when the day doubles. ``--small``
adds the 2 h, 50 Hz case (ropeload <= 1.5x the pandas script); ``--backfill 4`` a
``ropeload backfill --workers 4`` of four hoists with the same day each (<= 8 GB).
``--band-member-step S`` runs ropeload with its band's members on S-second means.

    uv run python benchmarks/bench_day.py                    # 24 h day
    uv run python benchmarks/bench_day.py --double --small   # 24 h, 48 h and 2 h 50 Hz
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HOIST = Path(__file__).resolve().parent.parent / "schemas" / "hoists" / "paper_field_test.toml"


def generate(path: Path, hours: float, rate_hz: float) -> int:
    """A simulated field day written as a CSV (contract 1a); returns its rows."""
    from schemas.hoist import load_hoist
    from sims.field_day import generate_field_day
    from sims.field_logs import write_csv

    hoist = load_hoist(HOIST)
    rows = 0
    with path.open("wb") as out:
        # one simulated day at a time (a 48 h file is two days back to back)
        for day in range(max(1, round(hours / 24.0))):
            span = min(24.0, hours)
            sim = generate_field_day(
                hoist,
                date=f"2026-03-{2 + day:02d}",
                seed=100 + day,
                hours=span,
                trips=max(2, int(120 * span / 24.0)),
                sample_rate_hz=rate_hz,
            )
            part = path.with_suffix(f".{day}.csv")
            write_csv(sim.sensors, part, hoist=hoist, sample_rate_hz=rate_hz)
            rows += sim.sensors.height
            del sim
            with part.open("rb") as src:
                if day:  # the header lines and column names are written once
                    for line in src:
                        if not line.startswith(b"#"):
                            break
                shutil.copyfileobj(src, out)
            part.unlink()
    return rows


def _floor(csv: Path, out: Path) -> None:
    import polars as pl

    header = sum(1 for line in csv.open("rb") if line.startswith(b"#"))
    pl.read_csv(csv, skip_rows=header).write_parquet(out / "floor.parquet", compression="zstd")


def _child(kind: str, csv: Path, out: Path) -> None:
    start = time.perf_counter()
    if kind == "floor":
        _floor(csv, out)
    elif kind == "pandas":
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from pandas_static import static_compensation

        static_compensation(csv, HOIST, out / "pandas.parquet")
    print(json.dumps({"seconds": time.perf_counter() - start}))


def _process(command: list[str]) -> dict:
    """Wall seconds and peak RSS of one child process (its own ``wait4`` rusage; Linux
    keeps ru_maxrss across exec, so RUSAGE_SELF in the child would include this one)."""
    start = time.perf_counter()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(child.pid, 0)
    seconds = time.perf_counter() - start
    if status != 0:
        raise SystemExit(f"{' '.join(command)} failed: {child.stderr.read().decode()[-2000:]}")
    return {"seconds": seconds, "peak_rss_bytes": usage.ru_maxrss * 1024}


def _measure(kind: str, csv: Path, out: Path) -> dict:
    return _process([sys.executable, __file__, "--child", kind, str(csv), str(out)])


def _ropeload(csv: Path, data: Path, run_options: tuple[str, ...] = ()) -> dict:
    """``ropeload ingest`` + ``ropeload run --no-sanity`` as two processes, wall and peak
    (``run_options`` added to the run's)."""
    run = ["run", "--data", str(data), "--hoist", str(HOIST), "--no-sanity", *run_options]
    steps = {
        name: _process([sys.executable, "-m", "pipelines.cli", *args])
        for name, args in (
            ("ingest", ["ingest", "--data", str(data), "--hoist", str(HOIST), str(csv)]),
            ("run", run),
        )
    }
    return {
        "seconds": sum(step["seconds"] for step in steps.values()),
        "peak_rss_bytes": max(step["peak_rss_bytes"] for step in steps.values()),
        "steps": steps,
    }


def case(hours: float, rate_hz: float, workdir: Path, run_options: tuple[str, ...] = ()) -> dict:
    csv = workdir / f"day-{hours:g}h-{rate_hz:g}hz.csv"
    if not csv.exists():  # in a child: the simulation's memory is not this process's
        _process([sys.executable, __file__, "--generate", str(hours), str(rate_hz), str(csv)])
    rows = sum(1 for line in csv.open("rb") if not line.startswith(b"#")) - 1
    os.sync()
    out = workdir / "out"
    out.mkdir(exist_ok=True)
    data = workdir / f"data-{hours:g}"
    shutil.rmtree(data, ignore_errors=True)
    result = {
        "floor": _measure("floor", csv, out),
        "pandas": _measure("pandas", csv, out),
        "ropeload": _ropeload(csv, data, run_options),
    }
    shutil.rmtree(data, ignore_errors=True)
    size = csv.stat().st_size
    print(f"\n{hours:g} h at {rate_hz:g} Hz: {rows:,} rows, {size / 1e6:,.0f} MB CSV")
    print(f"{'':<10}{'seconds':>9}{'peak RSS MB':>13}")
    for name, r in [*result.items(), *result["ropeload"]["steps"].items()]:
        label = name if name in result else f"  {name}"
        print(f"{label:<10}{r['seconds']:>9.2f}{r['peak_rss_bytes'] / 1e6:>13.0f}")
    rope, floor, pandas = result["ropeload"], result["floor"], result["pandas"]
    print(
        f"ropeload / floor time {rope['seconds'] / floor['seconds']:.2f}x (target <= 3); "
        f"speed vs pandas {pandas['seconds'] / rope['seconds']:.2f}x (target >= 2 for a "
        f"100 Hz day; >= 0.67, i.e. time <= 1.5x, for 2 h at 50 Hz); "
        f"peak {rope['peak_rss_bytes'] / 1e9:.2f} GB (target <= 2 GB)"
    )
    return result


def backfill_case(hours: float, hoists: int, workdir: Path) -> dict:
    """``ropeload backfill --workers N`` of N hoists with one simulated day each."""
    csv = workdir / f"day-{hours:g}h-100hz.csv"
    if not csv.exists():
        _process([sys.executable, __file__, "--generate", str(hours), "100", str(csv)])
    mine = workdir / "mine"
    shutil.rmtree(mine, ignore_errors=True)
    text = HOIST.read_text(encoding="utf-8")
    for k in range(1, hoists + 1):
        name = f"shaft-{k}"
        (mine / "hoists").mkdir(parents=True, exist_ok=True)
        (mine / "hoists" / f"{name}.toml").write_text(
            text.replace('name = "main-shaft"', f'name = "{name}"'), encoding="utf-8"
        )
        folder = mine / "incoming" / "paper-field-test" / name
        folder.mkdir(parents=True)
        with csv.open("rb") as src, (folder / f"paper-field-test_{name}.csv").open("wb") as out:
            for line in src:
                out.write(line.replace(b"# hoist: main-shaft", f"# hoist: {name}".encode()))
                if not line.startswith(b"#"):
                    break
            shutil.copyfileobj(src, out)
    os.sync()
    result = _process(
        [sys.executable, "-m", "pipelines.cli", "backfill", "--data", str(mine / "data"),
         "--hoists", str(mine / "hoists"), "--incoming", str(mine / "incoming"),
         "--from", "2026-02-28", "--to", "2026-03-05", "--workers", str(hoists),
         "--no-progress"]
    )  # fmt: skip
    shutil.rmtree(mine, ignore_errors=True)
    print(
        f"\nbackfill of {hoists} hoists x {hours:g} h at 100 Hz, --workers {hoists}: "
        f"{result['seconds']:.1f} s, peak RSS {result['peak_rss_bytes'] / 1e9:.2f} GB "
        "(target: 4 workers within 8 GB)"
    )
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--double", action="store_true", help="also a file twice as long")
    parser.add_argument("--small", action="store_true", help="also 2 h at 50 Hz")
    parser.add_argument(
        "--backfill", type=int, default=0, metavar="N", help="also a backfill of N hoist-days"
    )
    parser.add_argument("--workdir", type=Path, help="keep generated files here")
    parser.add_argument(
        "--band-member-step", type=float, default=0.0, metavar="S",
        help="ropeload run --band-member-step S (default 0: the band's members at the rate)",
    )  # fmt: skip
    parser.add_argument("--child", nargs=3, metavar=("KIND", "CSV", "OUT"), help=argparse.SUPPRESS)
    parser.add_argument("--generate", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.generate:
        hours, rate, csv = args.generate
        generate(Path(csv), float(hours), float(rate))
        return
    if args.child:
        kind, csv, out = args.child
        _child(kind, Path(csv), Path(out))
        return
    with tempfile.TemporaryDirectory(prefix="ropeload-bench-day-") as tmp:
        workdir = args.workdir or Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        options = ("--band-member-step", f"{args.band_member_step:g}")
        one = case(args.hours, 100.0, workdir, options)
        if args.double:
            two = case(2 * args.hours, 100.0, workdir, options)
            ratio = two["ropeload"]["peak_rss_bytes"] / one["ropeload"]["peak_rss_bytes"]
            print(f"\nropeload peak RSS x2 day / x1 day: {ratio:.2f} (target <= 1.1)")
        if args.small:
            case(2.0, 50.0, workdir, options)
        if args.backfill:
            backfill_case(args.hours, args.backfill, workdir)


if __name__ == "__main__":
    main()
