"""A writer's cost against the size of the lake (issue 16: landing costs).

Usage: ``uv run python benchmarks/bench_writer.py [--files 1,300,1500] [--repeat 3]``

Every run, ingest and night opens the warehouse for writing
(:func:`warehouse.store.open_writer`) a few times. Until session 51 each open made every
view again, twice (on the way in and before publishing): a view over a lake table's
glob reads every file's footer when it is made (``union_by_name``), and the models over
it read them again, so a writer's cost grew with the lake. Now a view is made again only
when what is under it changed (:func:`warehouse.views.refresh_views`), and each open
tests each lake file's magic bytes instead.

Prints, per number of files in each of the two lake tables that grow (field samples and
rope tensions; copies of one landed hour of a simulated day), the median wall time of
an empty writer (open + publish) as it is and with its views made twice as before (their
fingerprints cleared, so both refreshes make them), and the ratio.
"""

from __future__ import annotations

import argparse
import datetime as dt
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from warehouse.store import DataRoot, open_writer
from warehouse.views import refresh_views

TABLES = ("field_samples", "rope_tensions")


def _landed_root(folder: Path) -> DataRoot:
    """A data root with one simulated 10-minute day ingested and run (no sanity check)."""
    from pipelines.cli import main
    from sims.field_day import generate_field_day, write_field_day

    hoist = load_hoist(EXAMPLE_HOIST)
    day = generate_field_day(hoist, date="2026-03-02", seed=1, trips=2, hours=1 / 6)
    csv = next(
        p for p in write_field_day(day, folder / "logs", formats=("csv",)) if p.suffix == ".csv"
    )
    data = folder / "data"
    for argv in (["ingest", str(csv)], ["run", "--hoist", str(EXAMPLE_HOIST), "--no-sanity"]):
        if main([argv[0], "--data", str(data), *argv[1:]]) != 0:
            raise SystemExit(f"bench_writer: ropeload {argv[0]} failed")
    return DataRoot.resolve(data)


def _grow(root: DataRoot, files: int) -> None:
    """Copies of each table's first file, one a day back from 2020-01-02, up to
    ``files`` files a table."""
    for table in TABLES:
        landed = sorted(root.table_dir(table).rglob("*.parquet"))
        first = landed[0]
        hoist_dir = first.parent.parent
        for k in range(len(landed), files):
            day = dt.date(2020, 1, 1) + dt.timedelta(days=k)
            target = hoist_dir / f"date={day.isoformat()}" / first.name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(first, target)


def _forget_fingerprints(con) -> None:
    """Clear every view's fingerprint: the next refresh makes them all again."""
    names = con.sql("SELECT view_name FROM duckdb_views() WHERE NOT internal").fetchall()
    for (name,) in names:
        con.execute(f"COMMENT ON VIEW {name} IS NULL")


def _open_as_it_is(root: DataRoot) -> float:
    started = time.perf_counter()
    with open_writer(root):
        pass
    return time.perf_counter() - started


def _open_as_before(root: DataRoot) -> float:
    """Both refreshes make every view, as each writer did before session 51."""
    started = time.perf_counter()
    with open_writer(root) as con:
        # the way-in refresh (open_writer's, above) found them current: make them again
        _forget_fingerprints(con)
        refresh_views(con, root)
        _forget_fingerprints(con)  # so open_writer's refresh before publishing makes them
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", default="1,300,1500", help="files a table, comma-separated")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each; medians reported")
    args = parser.parse_args()
    counts = sorted(int(n) for n in args.files.split(","))
    with tempfile.TemporaryDirectory() as tmp:
        root = _landed_root(Path(tmp))
        print("files a table   writer as it is   views made twice (before)   ratio")
        for files in counts:
            _grow(root, files)
            _open_as_it_is(root)  # the first open after new files: fingerprints settle
            now, before = [], []
            for _ in range(args.repeat):  # alternating, so a burst of load hits both
                before.append(_open_as_before(root))
                now.append(_open_as_it_is(root))
            a, b = float(np.median(now)), float(np.median(before))
            print(f"{files:13d}   {a:13.3f} s   {b:23.3f} s   {b / a:5.1f}x")


if __name__ == "__main__":
    main()
