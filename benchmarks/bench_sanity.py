"""Benchmark: the simulation sanity check of a hoist-day, every trip against a sample.

Writes a simulated 100 Hz field day (ropeload's own simulator, 120 trips a day, as
``bench_day.py``), ingests it and runs it without the check, then times, one after the
other in this process (numba caches warmed by a first short check):

* every trip in one chain (``check_sanity``'s default, what ``ropeload run`` lands);
* the same with the chain's fit on one thread, its passes one after the other (as
  before session 48, when one block's replay ran on one thread: the baseline of
  :func:`sims.replay.replay_fitted`'s pipelined passes, measured in the same run; the
  replays that choose the ropes and the motion run as in the default);
* a sample of 20 trips in four blocks (``ropeload run --sanity-trips 20``).

It prints the seconds and verdicts of each and the ratios. The check's verdicts are the
same on one thread and on many (``tests/sims/test_replay.py``): the figure is speed.

    uv run python benchmarks/bench_sanity.py --hours 6
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from bench_day import HOIST, generate  # the sibling script

import pipelines.sanity as sanity_module
import sims.replay as replay_module
from pipelines.cli import main as ropeload
from pipelines.hoist_day import check_sanity
from schemas.hoist import load_hoist
from warehouse.store import DataRoot, open_reader


@contextlib.contextmanager
def chain_on_one_thread() -> Iterator[None]:
    """The sanity check's fit of its chain on one thread, the passes one after the other
    (``_ONE_THREAD`` set around :func:`pipelines.sanity.sanity_check`'s call of it)."""
    pipelined = sanity_module.replay_fitted

    def fitted(*args: Any, **kwargs: Any) -> Any:
        token = replay_module._ONE_THREAD.set(True)
        try:
            return pipelined(*args, **kwargs)
        finally:
            replay_module._ONE_THREAD.reset(token)

    sanity_module.replay_fitted = fitted
    try:
        yield
    finally:
        sanity_module.replay_fitted = pipelined


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--rate-hz", type=float, default=100.0)
    args = parser.parse_args()
    hoist = load_hoist(HOIST)
    with tempfile.TemporaryDirectory() as tmp:
        csv, data = Path(tmp) / "day.csv", DataRoot.resolve(Path(tmp) / "data")
        rows = generate(csv, args.hours, args.rate_hz)
        for command in (["ingest", str(csv)], ["run", "--no-sanity"]):
            if ropeload(
                [command[0], "--data", str(data.path), "--hoist", str(HOIST), *command[1:]]
            ):
                sys.exit(f"ropeload {command[0]} failed")
        with open_reader(data) as con:
            run_id, start, end = con.sql(
                "SELECT run_id, period_start_utc, period_end_utc FROM runs "
                "WHERE command = 'run' ORDER BY started_at_utc DESC LIMIT 1"
            ).fetchall()[0]

        def check(max_trips: int | None) -> tuple[float, str]:
            started = time.perf_counter()
            found = check_sanity(hoist_path=HOIST, data=data, run_id=run_id, start=start,
                                 end=end, max_trips=max_trips, hoist=hoist)  # fmt: skip
            return time.perf_counter() - started, found.words()

        check(2)  # warm-up: imports, numba caches
        every = check(None)
        with chain_on_one_thread():
            single = check(None)
        sample = check(20)
    print(f"{args.hours:g} h at {args.rate_hz:g} Hz, {rows:,} rows")
    for name, (seconds, words) in (("every trip", every), ("every trip, fit pass by pass", single),
                                   ("20 sampled", sample)):  # fmt: skip
        print(f"  {name:<30}{seconds:8.1f} s   {words}")
    print(f"every trip, passes pipelined vs pass by pass: {single[0] / every[0]:.2f}x faster; "
          f"every trip vs 20 sampled: {every[0] / sample[0]:.2f}x the time")  # fmt: skip


if __name__ == "__main__":
    main()
