"""A writer's cost against the size of the lake (issue 16: landing costs).

Usage: ``uv run python benchmarks/bench_writer.py [--files 1,300,1500] [--repeat 3]``

Every run, ingest and night opens the warehouse for writing
(:func:`warehouse.store.open_writer`) a few times. Until session 51 each open made every
view again, twice (on the way in and before publishing): a view over a lake table's
glob reads every file's footer when it is made (``union_by_name``), and the models over
it read them again, so a writer's cost grew with the lake. Now a view is made again only
when what is under it changed (:func:`warehouse.views.refresh_views`), and each open
tests each lake file's magic bytes and reads the footers of the files new since the last
check instead.

Prints, per number of files in each of the two lake tables that grow (field samples and
rope tensions; copies of the first rows of one landed hour of a simulated day), the
median wall time of an empty writer (open + publish) as it is, of making every view
once inside a writer (the lake views over their globs, then the models: what each of a
writer's two refreshes did before), the writer as before reckoned from them (its open
and publish as now, plus two makings) and the ratio.
"""

from __future__ import annotations

import argparse
import datetime as dt
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from warehouse.store import DataRoot, open_writer
from warehouse.views import LAKE_VIEWS, model_files, raw_view_sql

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
    """Copies of each table's first file cut to its first 1,000 rows (the footer a view
    reads is alike; ~10 MB a copy of the whole hour), one a day back from 2020-01-02, up
    to ``files`` files a table. Copies, not links: each file its own modification time,
    as files landed by runs."""
    for table in TABLES:
        landed = sorted(root.table_dir(table).rglob("*.parquet"))
        first = landed[0]
        small = root.path / f"{table}-first-rows.parquet"
        if not small.exists():
            pq.write_table(pq.read_table(first).slice(0, 1000), small)
        hoist_dir = first.parent.parent
        for k in range(len(landed), files):
            day = dt.date(2020, 1, 1) + dt.timedelta(days=k)
            target = hoist_dir / f"date={day.isoformat()}" / first.name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(small, target)


def _make_every_view(con, root: DataRoot) -> None:
    """What each refresh did before session 51: every view made again (the lake views
    over their globs, then the models)."""
    for view, table in LAKE_VIEWS.items():
        con.execute(f"CREATE OR REPLACE VIEW {view} AS {raw_view_sql(root, table)}")
    for path in model_files():
        body = path.read_text(encoding="utf-8").strip().rstrip(";")
        con.execute(f"CREATE OR REPLACE VIEW {path.stem} AS\n{body}")


def _open_as_it_is(root: DataRoot) -> float:
    started = time.perf_counter()
    with open_writer(root):
        pass
    return time.perf_counter() - started


def _time_making(root: DataRoot) -> float:
    """The time of one :func:`_make_every_view` inside a writer (its open and publish
    left out; the views it publishes carry no fingerprint, so the next writer makes
    them again)."""
    with open_writer(root) as con:
        started = time.perf_counter()
        _make_every_view(con, root)
        return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", default="1,300,1500", help="files a table, comma-separated")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each; medians reported")
    args = parser.parse_args()
    counts = sorted(int(n) for n in args.files.split(","))
    with tempfile.TemporaryDirectory() as tmp:
        root = _landed_root(Path(tmp))
        print(
            "files a table   empty writer as it is   every view made once   "
            "writer as before (its open + 2 makings)   ratio"
        )
        for files in counts:
            _grow(root, files)
            _open_as_it_is(root)  # the first open after new files reads their footers
            now, making = [], []
            for _ in range(args.repeat):  # alternating, so a burst of load hits both
                making.append(_time_making(root))
                _open_as_it_is(root)  # the views made above carry no fingerprint
                now.append(_open_as_it_is(root))
            a, m = float(np.median(now)), float(np.median(making))
            print(f"{files:13d}   {a:19.3f} s   {m:18.3f} s   {a + 2 * m:37.3f} s   "
                  f"{(a + 2 * m) / a:5.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
