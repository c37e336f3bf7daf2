"""Research prototype (issue 13, not used by the pipeline): quasi-static stick-slip piston
estimation with a rope model, evaluated on ../shared/validation/days.

What it tries. The current compensation takes the common piston motion from the pressure
(closed oil volume) and the differential motion from a 0.1 Hz smoothing of the logged x.
On the independent validation days that attributes volume to the wrong pistons (issue 13).
Here, per sample and quasi-statically (25 kg pistons, 50-100 Hz):

- rope i: T_i = a_i k(z) (s - x_i - c_i), k(z) = EA / (headframe + depth); s is one
  unknown common stretch per sample (the load), a_i (stiffness ratio) and c_i (length
  offset) are per-rope constants of the hoist, unknown to the mine;
- piston i: T_i = p_i A + F_i with an elasto-plastic seal F' = clip(F + sigma0 dx, -g, g)
  (g the eq 17 Stribeck capacity at the piston's last speed, sigma0 the bristle
  stiffness of the hoist TOML);
- oil: A sum dx_i = V dp / beta (the pressure gives the sum of the displacements to
  micrometres): each dx_i is a monotone piecewise-linear function of s, so s is the
  root of one equation per sample (Newton, exact in a few steps);
- theta = (a_2..a_4, c_2..c_4) identified per record by differential evolution, making
  the model's x_i match the logged x_i (decimated to 5 Hz).

Findings (session 4; the closing note has them too). A least-squares fit to the
validation truth windows shows the rope model holds there to 12 N RMS (a = 1, 1.0785,
1.0492, 1.0328; c = 0, 8.5, 10.9, -3.6 mm, the same on days 101, 102 and 104). With those
(``--oracle``) constants, stop-window load error worst / median, worst rope:
day 101 1.77 / 0.30 %, 1.89 % (production 8.36 / 0.51 %, 12.7 %); day 102 1.63 / 0.33 %,
1.87 %; day 103 1.78 / 0.60 %, 3.59 % (branch losses are left out here; fed to the
production LuGre kernel as the piston motion: 2.15 / 0.43 %); day 104 (ropes ring)
4.62 / 1.97 %, worse than production's 2.39 / 0.81 %. On 104 the pressure creeps up for
~10 s after each payload change at rest while the load is constant: the ringing relaxes
the seals (LuGre's drift under dither) and the model reads the creep as more load.
Identified (not oracle) theta on day 101: a = 1, 1.083, 1.028, 1.049, c = 0, 8.7, 9.5,
-2.3 mm, giving 4.03 / 0.34 % before the gap fix; a is weakly determined by the
x-mismatch objective (it varies between days). Open: an identification objective that
pins a_i (branch-flow pressure differences), friction relaxation at rest, the band.

    uv run python benchmarks/research/stick_slip_prototype.py [--oracle] [--days DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import polars as pl
from numba import njit
from scipy.optimize import differential_evolution

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import eval_compensation as ev

from physics.friction_law import friction_law_at, law_array, stribeck_g
from physics.oil import ATMOSPHERIC_PRESSURE_PA, effective_bulk_modulus_at
from schemas.hoist import HoistDescription, load_hoist
from transforms.filtering import segment_ids
from transforms.lowpass import lowpass

#: Rope constants fitted to the validation truth windows (for --oracle only).
ORACLE_A = (1.0, 1.0785, 1.0492, 1.0328)
ORACLE_C_M = (0.0, 8.49e-3, 10.86e-3, -3.63e-3)


@njit(cache=True)
def _piston(demand, f, sigma0, ka, g):  # pragma: no cover - numba
    """F' + ka dx = demand with F' = clip(F + sigma0 dx, -g, g): (dx, F', d dx / d demand)."""
    dx = (demand - f) / (sigma0 + ka)
    fn = f + sigma0 * dx
    if fn > g:
        return (demand - g) / ka, g, 1.0 / ka
    if fn < -g:
        return (demand + g) / ka, -g, 1.0 / ka
    return dx, fn, 1.0 / (sigma0 + ka)


@njit(cache=True)
def _kernel(
    p_mean,
    p_each,
    xl,
    has_x,
    depth,
    seg,
    dt,
    volume,
    area,
    oil,
    ea,
    headframe,
    sigma0,
    law,
    a,
    c,
    xout,
    fout,
):  # pragma: no cover - numba
    m, n = xout.shape
    f = np.zeros(m)
    x = np.zeros(m)
    v = np.zeros(m)
    cap = np.zeros(m)
    s = 0.0
    for j in range(n):
        k = ea / (headframe + depth[j])
        pj = max(p_mean[j], 1e5)
        if j == 0:  # the record's start; across a logger gap the state is carried
            num = 0.0
            den = 0.0
            for i in range(m):
                x[i] = xl[i, j] if has_x else 0.0
                num += p_each[i, j] * area + a[i] * k * (x[i] + c[i])
                den += a[i] * k
            s = num / den  # zero mean friction at a start: unknown
            g0 = friction_law_at(pj, law)[1]
            for i in range(m):
                f[i] = min(max(a[i] * k * (s - x[i] - c[i]) - p_each[i, j] * area, -g0), g0)
                v[i] = 0.0
                xout[i, j] = x[i]
                fout[i, j] = f[i]
            continue
        beta = effective_bulk_modulus_at(pj, oil[0], oil[1], oil[2], 1.0)
        dp = p_mean[j] - p_mean[j - 1]
        target = volume / (beta * area) * dp if np.isfinite(dp) else 0.0
        if seg[j] != seg[j - 1]:
            for i in range(m):
                v[i] = 0.0  # at rest across a gap: static capacity
        fc, fs, vs, kv = friction_law_at(pj, law)
        for i in range(m):
            cap[i] = stribeck_g(v[i], fc, fs, vs) + kv * abs(v[i])
        ds = 0.0
        for _ in range(40):
            total = 0.0
            slope = 0.0
            for i in range(m):
                ka = a[i] * k
                dx, fn, d = _piston(
                    ka * (s + ds - x[i] - c[i]) - p_each[i, j] * area, f[i], sigma0, ka, cap[i]
                )
                total += dx
                slope += d * ka
            err = total - target
            if abs(err) < 1e-13 or slope == 0.0:
                break
            ds -= err / slope
        s += ds
        for i in range(m):
            ka = a[i] * k
            dx, fn, d = _piston(
                ka * (s - x[i] - c[i]) - p_each[i, j] * area, f[i], sigma0, ka, cap[i]
            )
            x[i] += dx
            f[i] = fn
            v[i] = dx / dt
            xout[i, j] = x[i]
            fout[i, j] = f[i]


def run_model(frame: pl.DataFrame, hoist: HoistDescription, a, c, *, every: int = 1):
    """(x, F, p_each) of the prototype on a landed field-samples frame."""
    t = frame["time_utc"].dt.epoch("us").to_numpy() * 1e-6
    rate = 1.0 / float(np.median(np.diff(t)))
    seg = segment_ids(t - t[0], gap_factor=3.0, nominal_dt_s=1.0 / rate)
    p_each = np.vstack(
        [
            lowpass(
                frame[f"p{i}_pa"].to_numpy().astype(float).copy(),
                seg,
                sample_rate_hz=rate,
                cutoff_hz=min(10.0, 0.4 * rate),
            )
            for i in range(1, 5)
        ]
    )[:, ::every]
    xl = np.vstack([frame[f"x{i}_m"].to_numpy().astype(float) for i in range(1, 5)])[:, ::every]
    has_x = bool(np.isfinite(xl).any())
    depth = frame["depth_m"].fill_null(0.0).to_numpy().astype(float)[::every]
    seg = np.ascontiguousarray(seg[::every])
    law = hoist.friction_law
    n = depth.size
    x, f = np.empty((4, n)), np.empty((4, n))
    _kernel(
        np.ascontiguousarray(p_each.mean(0)),
        np.ascontiguousarray(p_each),
        np.ascontiguousarray(xl),
        has_x,
        depth,
        seg,
        every / rate,
        hoist.oil_volume_m3,
        hoist.cylinders.bore_area_m2,
        np.array([hoist.oil.bulk_modulus_pa, hoist.oil.air_fraction, ATMOSPHERIC_PRESSURE_PA]),
        hoist.ropes.head_rope_axial_stiffness_n,
        hoist.shaft.headframe_height_m,
        float(law.bristle_stiffness_n_m),
        law_array(law),
        np.asarray(a, float),
        np.asarray(c, float),
        x,
        f,
    )
    return x, f, p_each, xl


def identify(frame: pl.DataFrame, hoist: HoistDescription) -> tuple[np.ndarray, np.ndarray]:
    """theta by differential evolution on the x mismatch at 5 Hz (gauge: a_1 = 1, c_1 = 0)."""
    step_s = float(np.median(np.diff(frame["time_utc"].dt.epoch("us").to_numpy() * 1e-6)))
    every = max(round(1.0 / (5.0 * step_s)), 1)

    def mismatch(q: np.ndarray) -> float:
        x, _, _, xl = run_model(
            frame, hoist, np.r_[1.0, q[:3]], np.r_[0.0, q[3:]] * 1e-3, every=every
        )
        return float(np.nanmean((x - xl) ** 2)) * 1e6

    res = differential_evolution(
        mismatch,
        [(0.9, 1.1)] * 3 + [(-15.0, 15.0)] * 3,
        popsize=10,
        maxiter=40,
        tol=1e-8,
        seed=1,
        polish=False,
    )
    return np.r_[1.0, res.x[:3]], np.r_[0.0, res.x[3:]] * 1e-3


def evaluate(gz: Path, work: Path, oracle: bool) -> None:
    case = ev.validation_case(gz, work)
    hoist = load_hoist(case.hoist_path)
    # ingest into a private data root, read the landed samples back
    from pipelines.ingest import ingest_paths
    from pipelines.lake import scan_lake
    from warehouse.store import DataRoot

    data = DataRoot.resolve(work / f"root_{case.name}")
    ingest_paths([case.csv], data=data, hoist_lookup=lambda site, name: hoist)
    frame = scan_lake(
        data, "field_samples", site=hoist.hoist.site, hoist=hoist.hoist.name
    ).collect()
    a, c = (np.array(ORACLE_A), np.array(ORACLE_C_M)) if oracle else identify(frame, hoist)
    _, f, p_each, _ = run_model(frame, hoist, a, c)
    area = hoist.cylinders.bore_area_m2
    truth = json.loads(gz.with_name(f"{case.name}.truth.json").read_text())
    t_ns = frame["time_utc"].dt.epoch("ns").to_numpy()
    after, before, rope = [], [], []
    for stop in truth["stops"]:
        for w in stop["windows"]:
            lo, hi = np.searchsorted(
                t_ns, [ev._utc(w[k]).timestamp() * 1e9 for k in ("t0_utc", "t1_utc")]
            )
            if hi - lo < ev.MIN_SAMPLES:
                continue
            tension = [p_each[i, lo:hi].mean() * area + f[i, lo:hi].mean() for i in range(4)]
            after.append(abs(100 * (sum(tension) / w["true_load_n"] - 1)))
            before.append(abs(w["uncompensated_error_measured_pct"]))
            rope.append(max(abs(100 * (tension[i] / w["true_tension_n"][i] - 1)) for i in range(4)))
    after, before = np.array(after), np.array(before)
    print(
        f"{case.name}: theta a={np.round(a, 4)} c_mm={np.round(c * 1e3, 2)}; after worst "
        f"{after.max():.2f} % median {np.median(after):.2f} %; worst rope {max(rope):.2f} %; "
        f"worse than raw +0.2 pp {(after > before + 0.2).sum()}/{after.size}"
    )


def main() -> None:
    import tempfile

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=Path, default=ev.DEFAULT_DAYS)
    parser.add_argument("--oracle", action="store_true", help="rope constants from the truth fit")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="ropeload-proto-") as tmp:
        for gz in sorted(args.days.glob("*.csv.gz")):
            evaluate(gz, Path(tmp), args.oracle)


if __name__ == "__main__":
    main()
