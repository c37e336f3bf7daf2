"""Throughput of the seal-friction state updates (physics.lugre, physics.maxwell_slip).

Run: ``uv run python benchmarks/bench_friction.py [steps]``. Prints steps per second of

* the LuGre state update (:func:`physics.lugre.lugre_friction`, per-sample
  pressure-dependent parameters, exact exponential update), 10 M+ steps, in chunks of
  2 M with the state carried across chunks (as a pipeline would process a day);
* the Maxwell-slip model with 4 elements (:func:`maxwell_slip_friction`);
* references: the vectorised numpy steady-state Stribeck map (eq 16, no state) over the
  same samples, and a pure-Python loop of the LuGre update (on 200 k steps).

Target (issue 5): LuGre >= 50 M steps/s on the 2-core project machine.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from physics.friction_law import friction_parameters, stribeck_friction
from physics.lugre import lugre_friction
from physics.maxwell_slip import maxwell_slip_elements, maxwell_slip_friction
from schemas.hoist import EXAMPLE_HOIST, load_hoist

CHUNK = 2_000_000


def _inputs(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    v = 0.004 * np.sin(0.2 * t) + rng.normal(0, 2e-4, n)  # piston velocity [m/s]
    p = 4e6 + 1e6 * np.sin(0.01 * t)  # chamber pressure [Pa]
    return v, p


def _rate(n: int, seconds: float) -> str:
    return f"{n / seconds / 1e6:8.1f} M steps/s ({seconds:.3f} s for {n / 1e6:.1f} M)"


def main(total: int = 10_000_000) -> None:
    law = load_hoist(EXAMPLE_HOIST).friction_law
    sigma0, sigma1 = law.bristle_stiffness_n_m, law.bristle_damping_n_s_m
    v, p = _inputs(CHUNK)
    fc, fs, vs, kv = friction_parameters(p, law)
    dt = np.full(CHUNK, 0.01)
    k, w = maxwell_slip_elements(law.presliding_elements, sigma0)
    chunks = -(-total // CHUNK)
    n = chunks * CHUNK

    lugre_friction(v[:10], dt[:10], fc[:10], fs[:10], vs[:10], kv[:10], sigma0, sigma1)
    maxwell_slip_friction(v[:10], dt[:10], fc[:10], fs[:10], vs[:10], kv[:10], k, w)

    z = 0.0
    start = time.perf_counter()
    for _ in range(chunks):
        _, z_arr = lugre_friction(v, dt, fc, fs, vs, kv, sigma0, sigma1, z0=z)
        z = float(z_arr[-1])
    lugre_s = time.perf_counter() - start

    deltas = None
    start = time.perf_counter()
    for _ in range(chunks):
        _, deltas = maxwell_slip_friction(v, dt, fc, fs, vs, kv, k, w, deltas)
    maxwell_s = time.perf_counter() - start

    start = time.perf_counter()
    for _ in range(chunks):
        stribeck_friction(v, fc, fs, vs, kv)
    numpy_s = time.perf_counter() - start

    m = 200_000
    start = time.perf_counter()
    zp = 0.0
    for i in range(m):
        g = fc[i] + (fs[i] - fc[i]) * np.exp(-((v[i] / vs[i]) ** 2))
        if v[i] != 0.0:
            zss = np.sign(v[i]) * g / sigma0
            zp = zss + (zp - zss) * np.exp(-sigma0 * abs(v[i]) * 0.01 / g)
    python_s = time.perf_counter() - start

    print(f"LuGre (numba, exact exponential update): {_rate(n, lugre_s)}")
    print(f"Maxwell-slip, {len(k)} elements (numba):       {_rate(n, maxwell_s)}")
    print(f"numpy steady-state Stribeck map (eq 16):  {_rate(n, numpy_s)}")
    print(f"pure-Python LuGre loop:                   {_rate(m, python_s)}")
    print(
        f"LuGre vs numpy stateless map: {numpy_s / lugre_s:.2f}x; "
        f"vs pure Python: {(python_s / m) / (lugre_s / n):.0f}x; "
        f"target 50 M steps/s: {'met' if n / lugre_s >= 50e6 else 'NOT met'}"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10_000_000)
