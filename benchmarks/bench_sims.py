"""Benchmark: simulated seconds per wall second of the four-cylinder device.

One full-shaft trip (pithead -> 620 m, ~89 s) of the paper's field hoist with every
contract effect on, at the default solver settings (ROS2, 1 ms step, 100 Hz output).
Target: at least 100x real time on the project's 2-core machine. The first call's
time (numba compile, or loading the on-disk cache) is reported separately.

Run: ``uv run python benchmarks/bench_sims.py``
"""

from __future__ import annotations

import time

from schemas.effects import EFFECT_NAMES
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.device import simulate
from sims.trips import hold, trip


def main(repeats: int = 3) -> float:
    hoist = load_hoist(EXAMPLE_HOIST)
    effects = set(EFFECT_NAMES)
    t0 = time.perf_counter()
    simulate(hoist, hold(depth_m=0.0, duration_s=0.02), effects=effects)
    first = time.perf_counter() - t0
    profile = trip(hoist, start_depth_m=0.0, end_depth_m=hoist.shaft.depth_m)
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = simulate(hoist, profile, effects=effects)
        walls.append(time.perf_counter() - t0)
        if result.status != "success":
            raise SystemExit(f"simulation failed: {result.message}")
    best = min(walls)
    speed = profile.duration_s / best
    print(f"first call (numba compile or cache load): {first:.2f} s")
    print(
        f"trip {profile.duration_s:.1f} s simulated, all {len(effects)} effects, "
        f"dt {result.solver['dt_s'] * 1e3:g} ms, {result.frame.height} samples"
    )
    print(f"wall per run: {', '.join(f'{w:.3f}' for w in walls)} s (best {best:.3f} s)")
    print(f"speed: {speed:.0f} simulated s per wall s (target >= 100)")
    return speed


if __name__ == "__main__":
    main()
