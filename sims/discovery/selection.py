"""Selecting the missing effect: residual test, scoring with re-tuning, BIC + bootstrap.

Problem. Measured sensor pressures y (trips x samples x sensors, scored at
``score_rate_hz``) and the device simulation s(E, theta) of the same trips
(:mod:`sims.replay`) with the hoist's model effects E and parameters theta. Is an
effect of contract section 4 missing from E, and which?

Method (one iteration)
----------------------
1. *Nuisance and re-tuning.* The residual r = y - s is fitted by least squares on the
   columns of a design matrix: one common-mode column per trip (the payload, the log's
   free input) and the finite-difference columns ``ds/dphi`` of every coordinate phi of
   the effects already in the model (:mod:`sims.discovery.library`): the calibrated
   parameters may re-adjust. Its residual sum of squares is RSS_0.
2. *Is anything missing?* With the noise variance sigma^2 estimated from the data
   (second differences at standstill, :func:`sims.replay.estimate_noise_sigma`), the
   variance ratio ``RSS_0 / (N sigma^2)`` is ~1 when the model is complete (the
   residual is the sensor noise). Below ``variance_threshold`` the answer is ``none``.
   The residual's integrated autocorrelation time tau (whiteness; 1 for white noise)
   is reported and sets the effective sample count ``N_eff = N / tau`` used below.
3. *Scoring.* Every candidate c (an effect not in the model, its requirements in it)
   is switched on at its default parameters (a fixed column Delta_c = s_c - s) and its
   coordinates get finite-difference columns J_c; the joint least squares of r -
   Delta_c on [re-tuning, J_c, nuisance] gives RSS_c. A candidate is credited only for
   what re-tuning cannot explain: its score is the BIC difference (Schwarz 1978, Ann.
   Stat. 6(2) 461-464)

   .. math:: \\Delta BIC_c = N_{eff} \\ln(RSS_0 / RSS_c) - k_c \\ln N_{eff}

   with k_c its number of coordinates.
4. *Stability.* Trips are resampled with replacement (``bootstrap`` times; Efron 1979)
   and the winner counted per resample from the per-trip normal equations; the
   winner's share is the reported confidence.
5. *Decision.* The best candidate wins when its score is positive, it explains at least
   ``explain_fraction`` of the excess variance ``RSS_0 - N sigma^2`` and it wins at
   least ``stability`` of the resamples. When the runner-up's RSS is within
   ``ambiguity`` of the best's explained variance, or the resamples split between the
   two, the answer is ``ambiguous`` with both names and the excitations that would
   separate them.
6. *Add, refit, re-simulate.* The winner is switched on at its fitted coordinates (and
   the re-tuned parameters updated), the trips re-simulated with payloads re-fitted,
   and the gap (RMS of y - s) before and after reported overall and per region (trip
   phase, direction, shaft position, oil temperature, pressure level, cylinder). A
   term that is null and strongly nonlinear at its default (groove wear: it starts from
   a scan along the residual's differential signature, ``_Engine.start``) is then
   fitted along its coordinates with payloads refitted (Brent, :func:`_refine_along`)
   while the gap is above the noise: payloads fitted without it are biased, so the
   linear step alone stops short. A Gauss-Newton step on the winner's coordinates
   follows when the re-simulated gap is more than 10 % above the linear prediction.

The loop repeats while a further effect passes (``max_iterations``); the columns of
candidates are linearisations around the first base and are reused (each costs one
chained replay per coordinate).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize

from schemas.effects import NO_EFFECT
from schemas.hoist import HoistDescription
from sims.discovery.library import EFFECT_LIBRARY, EffectLibrary, EffectTerm, term_parameters
from sims.effects import parameters_json, resolve_effects
from sims.replay import (
    ReplayPlan,
    ReplayResult,
    payload_from_pressure,
    replay,
    replay_fitted,
)

__all__ = ["AMBIGUOUS", "DiscoveryResult", "Finding", "discover_effects", "locate_gap"]

#: What a finding says when two candidates cannot be told apart.
AMBIGUOUS = "ambiguous"

Params = dict[str, dict[str, Any]]


@dataclass(frozen=True)
class Finding:
    """One iteration's answer (one row of ``discovery_findings``)."""

    iteration: int
    effect: str
    parameters: dict[str, Any]
    retuned: dict[str, dict[str, Any]]
    confidence: float
    gap_before_pa: float
    gap_after_pa: float
    noise_pa: float
    variance_ratio: float
    autocorrelation_time: float
    ranking: list[dict[str, Any]]
    where: list[dict[str, Any]]
    ambiguous_between: tuple[str, ...] = ()
    excitation: str = ""
    message: str = ""


@dataclass
class DiscoveryResult:
    """All iterations of :func:`discover_effects` and the model they lead to."""

    plan: ReplayPlan
    findings: list[Finding]
    effects_before: tuple[str, ...]
    effects_after: tuple[str, ...]
    parameters_after: Params
    before: ReplayResult
    after: ReplayResult
    replays: int = 0
    notes: list[str] = field(default_factory=list)

    @property
    def effects_found(self) -> list[str]:
        return [f.effect for f in self.findings if f.effect not in (NO_EFFECT, AMBIGUOUS)]


# ---------------------------------------------------------------------------------------
# flat layout of the scored entries
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Layout:
    mask: tuple[np.ndarray, ...]  # per trip (m_k, n) entries used
    trip: np.ndarray
    sensor: np.ndarray
    time_s: np.ndarray
    phase: np.ndarray
    direction: np.ndarray
    depth_m: np.ndarray
    oil_temp_c: np.ndarray
    level_pa: np.ndarray
    y: np.ndarray

    def flat(self, arrays: Iterable[np.ndarray]) -> np.ndarray:
        return np.concatenate([a[m] for a, m in zip(arrays, self.mask, strict=True)])


def _layout(plan: ReplayPlan, base: ReplayResult) -> _Layout:
    masks, cols = [], {k: [] for k in ("trip", "sensor", "t", "ph", "dir", "d", "oil", "lvl")}
    for k, (tr, sim) in enumerate(zip(plan.trips, base.simulated, strict=True)):
        m = tr.valid & np.isfinite(sim) & np.isfinite(tr.measured_pa)
        masks.append(m)
        rows, sens = np.nonzero(m)
        n_s = m.shape[1]
        level = np.nanmean(tr.measured_pa, axis=1)
        cols["trip"].append(np.full(rows.size, k))
        cols["sensor"].append(sens)
        cols["t"].append(tr.time_s[rows])
        cols["ph"].append(tr.phase[rows])
        direction = np.where(tr.phase == "standstill", "rest", tr.direction)
        cols["dir"].append(direction[rows])
        cols["d"].append(tr.depth_m[rows])
        cols["oil"].append(np.full(rows.size, tr.oil_temp_c))
        cols["lvl"].append(level[rows])
        del n_s
    cat = {k: np.concatenate(v) if v else np.zeros(0) for k, v in cols.items()}
    y = np.concatenate([tr.measured_pa[m] for tr, m in zip(plan.trips, masks, strict=True)])
    return _Layout(
        tuple(masks),
        cat["trip"].astype(int),
        cat["sensor"].astype(int),
        cat["t"],
        cat["ph"],
        cat["dir"],
        cat["d"],
        cat["oil"],
        cat["lvl"],
        y,
    )


# ---------------------------------------------------------------------------------------
# least squares with per-trip normal equations (for the trip bootstrap)
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Normal:
    gram: np.ndarray  # (m, p, p) per trip
    rhs: np.ndarray  # (m, p)
    tt: np.ndarray  # (m,)
    scale: np.ndarray  # (p,) column scales
    penalty: np.ndarray  # (p,) ridge on the scaled coefficients (Gaussian prior)


def _normal(
    x: np.ndarray,
    target: np.ndarray,
    trip: np.ndarray,
    m: int,
    penalty: np.ndarray | None = None,
) -> _Normal:
    """Per-trip normal equations of ``x b = target`` with columns scaled to unit RMS.

    ``penalty`` (per column, in target units squared per coefficient unit squared:
    sigma^2 / prior_sd^2) is the Gaussian prior of re-tuned coordinates.
    """
    scale = np.sqrt(np.mean(x**2, axis=0)) if x.size else np.zeros(0)
    scale = np.where(scale > 0, scale, 1.0)
    xs = x / scale
    p = xs.shape[1]
    gram = np.zeros((m, p, p))
    rhs = np.zeros((m, p))
    tt = np.zeros(m)
    for k in range(m):
        sel = trip == k
        xk, tk = xs[sel], target[sel]
        gram[k] = xk.T @ xk
        rhs[k] = xk.T @ tk
        tt[k] = tk @ tk
    pen = np.zeros(p) if penalty is None else np.asarray(penalty, float) / scale**2
    return _Normal(gram, rhs, tt, scale, pen)


def _solve(ne: _Normal, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Weighted (per trip) ridge solution: data RSS and coefficients (column units)."""
    g = np.tensordot(w, ne.gram, axes=1)
    b = w @ ne.rhs
    tt = float(w @ ne.tt)
    p = g.shape[0]
    if p == 0:
        return tt, np.zeros(0)
    lam = 1e-9 * max(np.trace(g) / p, 1e-30)
    beta = np.linalg.solve(g + np.diag(ne.penalty * w.sum() / w.size) + lam * np.eye(p), b)
    rss = tt - 2.0 * float(b @ beta) + float(beta @ g @ beta)
    return max(rss, 1e-30), beta / ne.scale


def _autocorrelation_time(resid: np.ndarray, layout: _Layout, max_lag: int = 40) -> float:
    """Integrated autocorrelation time 1 + 2 sum(rho_l), summed to the first rho < 0.05."""
    num = np.zeros(max_lag + 1)
    den = 0.0
    for k in np.unique(layout.trip):
        for i in np.unique(layout.sensor):
            sel = (layout.trip == k) & (layout.sensor == i)
            x = resid[sel]
            if x.size <= max_lag + 2:
                continue
            x = x - x.mean()
            den += float(x @ x)
            for lag in range(1, max_lag + 1):
                num[lag] += float(x[:-lag] @ x[lag:])
    if den <= 0:
        return 1.0
    rho = num / den
    tau = 1.0
    for lag in range(1, max_lag + 1):
        if rho[lag] < 0.05:
            break
        tau += 2.0 * rho[lag]
    return float(tau)


#: The groove-wear start scan runs when a sensor's direction-signed differential
#: residual is at least this many standard errors from zero ...
_SIGNATURE_Z = 5.0
#: ... the standard error taken with this autocorrelation time [samples] (white sensor
#: noise gives 1; the margin covers filtered loggers).
_SIGNATURE_TAU = 2.0


# ---------------------------------------------------------------------------------------
# columns
# ---------------------------------------------------------------------------------------
@dataclass
class _Columns:
    name: str
    jac: np.ndarray  # (N, k) d s / d coordinate
    delta: np.ndarray  # (N,) switching the effect on at its default coordinates
    theta0: np.ndarray  # coordinates the columns are taken at
    ok: bool = True
    note: str = ""


class _Engine:
    """Replays with fixed payloads / ramps and the columns built from them."""

    def __init__(self, plan: ReplayPlan, library: EffectLibrary, base: ReplayResult) -> None:
        self.plan = plan
        self.hoist = plan.hoist
        self.lib = library
        self.base = base
        self.layout = _layout(plan, base)
        self.replays = 0
        self.cache: dict[str, _Columns] = {}
        self.base_static = np.zeros((len(plan.trips), 2))

    def _static_payloads(self, effects: list[str], params: Params) -> np.ndarray:
        prm = term_parameters(self.hoist, params, effects)
        return np.array(
            [
                [
                    payload_from_pressure(
                        self.hoist, effects, prm, tr.p_after_pa, tr.start_depth_m
                    ),
                    payload_from_pressure(
                        self.hoist, effects, prm, tr.p_before_pa, tr.start_depth_m
                    ),
                ]
                for tr in self.plan.trips
            ]
        )

    def sim(self, effects: Iterable[str], params: Params) -> np.ndarray:
        """Replay with the base's payloads and ramps, the payloads shifted by what the
        changed model implies statically (tail rope at the start depth, sensor
        calibration), so a column shows the effect, not a payload mismatch."""
        self.replays += 1
        eff = list(effects)
        shift = self._static_payloads(eff, params) - self.base_static
        res = replay(
            self.plan,
            effects=eff,
            parameters=term_parameters(self.hoist, params, eff),
            payload_kg=np.maximum(self.base.payload_kg + shift[:, 0], 0.0),
            payload_before_kg=np.maximum(self.base.payload_before_kg + shift[:, 1], 0.0),
            ramps_s=self.base.ramps_s,
        )
        return self.layout.flat(res.simulated)

    def rebase(self, base: ReplayResult, effects: list[str], params: Params) -> None:
        self.base = base
        self.base_static = self._static_payloads(effects, params)

    def analytic(self, term: EffectTerm, s0: np.ndarray, params: Params, on: bool) -> _Columns:
        lay = self.layout
        n = self.hoist.ropes_n
        eff = resolve_effects(
            self.hoist, [term.name], term_parameters(self.hoist, params, [term.name])
        )
        theta = term.coordinates(self.hoist, params)
        gains = np.ones(n)
        offs = np.zeros(n)
        if term.name == "sensor_gain":
            gains = np.asarray(eff.parameters["sensor_gain"]["gains"], float)
        else:
            offs = np.asarray(eff.parameters["sensor_offset"]["offsets_pa"], float)
        jac = np.zeros((s0.size, n))
        delta = np.zeros(s0.size)
        for i in range(n):
            sel = lay.sensor == i
            if term.name == "sensor_offset":
                jac[sel, i] = 1.0
                if not on:
                    delta[sel] = offs[i]
            else:
                p_raw = s0[sel] / (gains[i] if on else 1.0)
                jac[sel, i] = p_raw
                if not on:
                    delta[sel] = (gains[i] - 1.0) * s0[sel]
        return _Columns(term.name, jac, delta, theta)

    def fd(
        self, term: EffectTerm, effects: list[str], params: Params, s_at: np.ndarray
    ) -> _Columns:
        theta = term.coordinates(self.hoist, params)
        cols = []
        for j, step in enumerate(term.steps):
            th = theta.copy()
            th[j] += step
            p2 = {k: dict(v) for k, v in params.items()}
            p2[term.name] = {**p2.get(term.name, {}), **term.parameters(self.hoist, th)}
            s = self.sim(effects, p2)
            if not np.all(np.isfinite(s)):
                return _Columns(
                    term.name,
                    np.zeros((s_at.size, 0)),
                    np.zeros(s_at.size),
                    theta,
                    ok=False,
                    note="simulation failed at a finite-difference step",
                )
            cols.append((s - s_at) / step)
        return _Columns(term.name, np.column_stack(cols), np.zeros(s_at.size), theta)

    def retune(self, name: str, effects: list[str], params: Params, s0: np.ndarray) -> _Columns:
        term = self.lib[name]
        if term.analytic:
            return self.analytic(term, s0, params, on=True)
        if name not in self.cache:
            self.cache[name] = self.fd(term, effects, params, s0)
        return self.cache[name]

    def _rss_trip_offsets(self, resid: np.ndarray) -> float:
        """Residual sum of squares after a per-trip common offset (the payload)."""
        if not np.all(np.isfinite(resid)):
            return np.inf
        trip = self.layout.trip
        m = int(trip.max()) + 1 if trip.size else 0
        mean = np.bincount(trip, resid, m) / np.maximum(np.bincount(trip, minlength=m), 1)
        return float(np.sum((resid - mean[trip]) ** 2))

    def start(
        self, term: EffectTerm, effects: list[str], params: Params, s0: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """A non-zero start for a term that is null and nonlinear at its default.

        Direction: the differential signature of the residual while the conveyance
        moves -- per sensor, the mean of ``direction x (r_i - mean_j r_j)`` (groove wear
        makes the pistons drift apart one way going down and back going up, and each
        sliding piston's seal friction offsets its sensor by the sign of its motion);
        the coordinates (ropes 2..n relative to rope 1) along it, largest 1. Scan:
        both signs times ``term.start_amplitudes``, the best amplitude (per-trip offsets
        removed) refined between its grid neighbours (Brent), then up to three damped
        Gauss-Newton steps on all coordinates. None when the signature is within
        ``_SIGNATURE_Z`` standard errors of zero (a fixed fraction of the noise would
        ignore a signature that many samples make certain), or when nothing beats zero by
        more than 25 noise variances.
        """
        lay = self.layout
        n = self.hoist.ropes_n
        r = lay.y - s0
        moving = lay.direction != "rest"
        if term.name != "groove_wear" or moving.sum() < 10 * n:
            return None
        sgn = np.where(lay.direction == "down", 1.0, -1.0)
        sig = np.array(
            [np.mean((sgn * r)[moving & (lay.sensor == i)]) for i in range(n)], dtype=float
        )
        sig -= sig.mean()
        # no differential signature beyond its standard error: nothing for a scan to find.
        # The signature is a mean over n_i moving samples of a sensor's deviation from
        # the mean of the sensors, whose noise variance is (1 - 1/n) sigma^2; the
        # standard error allows an autocorrelation time of _SIGNATURE_TAU samples.
        counts = np.array([np.sum(moving & (lay.sensor == i)) for i in range(n)])
        se = self.plan.noise_sigma_pa * np.sqrt(
            _SIGNATURE_TAU * (1.0 - 1.0 / n) / np.maximum(counts, 1)
        )
        if np.max(np.abs(sig) / se) < _SIGNATURE_Z:
            return None
        g = sig[1:] - sig[0]
        if not np.any(g) or not np.all(np.isfinite(g)):
            return None
        g = g / np.max(np.abs(g))
        r0 = self._rss_trip_offsets(r)
        tried: dict[float, tuple[float, np.ndarray]] = {0.0: (r0, s0)}

        def along(a: float) -> float:
            """RSS (per-trip offsets removed) at coordinates ``a g``; remembered."""
            if a not in tried:
                s = self.sim(effects, _merge(params, term.name, term.parameters(self.hoist, a * g)))
                tried[a] = (self._rss_trip_offsets(lay.y - s), s)
            return tried[a][0]

        grid = sorted({sign * amp for amp in term.start_amplitudes for sign in (1.0, -1.0)})
        for a in grid:
            along(a)
        # refine between the grid neighbours of the best amplitude (Brent's bounded
        # method): the RSS along the signature is V-shaped about the true deviation
        points = sorted(tried)
        k = points.index(min(tried, key=lambda a: tried[a][0]))
        if points[k] != 0.0:
            lo, hi = points[max(k - 1, 0)], points[min(k + 1, len(points) - 1)]
            optimize.minimize_scalar(
                along,
                bounds=(lo, hi),
                method="bounded",
                options={"maxiter": 6, "xatol": 0.02 * (hi - lo)},
            )
        a_best = min(tried, key=lambda a: tried[a][0])
        best_rss, best_s = tried[a_best]
        best_theta = a_best * g
        # nothing beats zero by more than a few noise variances: no start (the plain
        # finite-difference column at zero is then as good as any)
        if a_best == 0.0 or r0 - best_rss < 25.0 * self.plan.noise_sigma_pa**2:
            return None
        m = int(lay.trip.max()) + 1
        nuis = np.zeros((lay.y.size, m))
        nuis[np.arange(lay.y.size), lay.trip] = 1.0
        for _ in range(3):
            p_at = _merge(params, term.name, term.parameters(self.hoist, best_theta))
            cols = self.fd(term, effects, p_at, best_s)
            if not cols.ok:
                break
            x = np.column_stack([cols.jac, nuis])
            _, b = _solve(_normal(x, lay.y - best_s, lay.trip, m), np.ones(m))
            step = b[: cols.jac.shape[1]]
            # the response is piecewise (seal friction flips as pistons drift apart):
            # a full step can overshoot, so it is halved up to twice before giving up
            for fraction in (1.0, 0.5, 0.25):
                th = best_theta + fraction * step
                s = self.sim(effects, _merge(params, term.name, term.parameters(self.hoist, th)))
                rss = self._rss_trip_offsets(lay.y - s)
                if rss < best_rss:
                    break
            if not rss < best_rss:
                break
            improved = (best_rss - rss) / best_rss
            best_theta, best_s, best_rss = th, s, rss
            if improved < 0.02:
                break
        return best_theta, best_s

    def candidate(self, name: str, effects: list[str], params: Params, s0: np.ndarray) -> _Columns:
        term = self.lib[name]
        if term.analytic:
            return self.analytic(term, s0, params, on=False)
        if name in self.cache:
            return self.cache[name]
        eff = [*effects, name]
        start = None
        if term.null_at_default(self.hoist):
            s_on = s0
            if term.start_amplitudes:
                start = self.start(term, eff, params, s0)
        else:
            s_on = self.sim(eff, params)
        if start is not None:
            params = _merge(params, name, term.parameters(self.hoist, start[0]))
            s_on = start[1]
        if not np.all(np.isfinite(s_on)):
            cols = _Columns(
                name,
                np.zeros((s0.size, 0)),
                np.zeros(s0.size),
                term.coordinates(self.hoist, params),
                ok=False,
                note="simulation failed with the effect switched on",
            )
        else:
            cols = self.fd(term, eff, params, s_on)
            cols.delta = s_on - s0
        self.cache[name] = cols
        return cols


# ---------------------------------------------------------------------------------------
# locating the gap
# ---------------------------------------------------------------------------------------
def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def locate_gap(
    plan: ReplayPlan,
    layout_or_none: Any,
    before: np.ndarray,
    after: np.ndarray | None = None,
    *,
    top: int = 6,
    min_entries: int = 40,
) -> list[dict[str, Any]]:
    """Regions where the residual is large: RMS per trip phase, direction, shaft position,
    oil temperature band, pressure level band and cylinder, largest first.

    Each region: ``start``/``end`` (UTC ISO of its first and last sample), ``regime``
    (e.g. ``"phase=accelerate"``), ``gap_pa`` (RMS before), ``gap_after_pa`` and
    ``entries``.
    """
    lay: _Layout = layout_or_none
    hoist = plan.hoist
    labels: dict[str, np.ndarray] = {
        "phase": lay.phase.astype(str),
        "direction": lay.direction.astype(str),
        "cylinder": np.array([f"{i + 1}" for i in range(hoist.ropes_n)])[lay.sensor],
    }
    pos = np.full(lay.depth_m.size, "shaft", dtype=object)
    for name, d in hoist.shaft.positions_m.items():
        pos[np.abs(lay.depth_m - d) <= hoist.shaft.position_window_m] = name
    labels["position"] = pos.astype(str)
    oil = lay.oil_temp_c
    if oil.size and np.ptp(oil) > 2.0:
        edges = np.linspace(oil.min(), oil.max(), 4)
        band = np.clip(np.digitize(oil, edges[1:-1]), 0, 2)
        names = [f"{edges[b]:.0f}-{edges[b + 1]:.0f} degC" for b in range(3)]
        labels["oil_temp"] = np.array(names)[band]
    lvl = lay.level_pa
    if lvl.size:
        q = np.quantile(lvl, [1 / 3, 2 / 3])
        band = np.digitize(lvl, q)
        names = [
            f"low (< {q[0] / 1e6:.2f} MPa)",
            f"mid ({q[0] / 1e6:.2f}-{q[1] / 1e6:.2f} MPa)",
            f"high (> {q[1] / 1e6:.2f} MPa)",
        ]
        labels["pressure"] = np.array(names)[band]
    regions = []
    for dim, lab in labels.items():
        for value in np.unique(lab):
            sel = lab == value
            if sel.sum() < min_entries:
                continue
            times = plan.time_utc(lay.time_s[sel])
            regions.append(
                {
                    "start": times.min().isoformat(),
                    "end": times.max().isoformat(),
                    "regime": f"{dim}={value}",
                    "gap_pa": round(_rms(before[sel]), 1),
                    "gap_after_pa": None if after is None else round(_rms(after[sel]), 1),
                    "entries": int(sel.sum()),
                }
            )
    regions.sort(key=lambda r: -r["gap_pa"])
    return regions[:top]


# ---------------------------------------------------------------------------------------
# the workflow
# ---------------------------------------------------------------------------------------
def _excitation(lib: EffectLibrary, a: str, b: str) -> str:
    return f"to separate {a} from {b}: for {a}, {lib[a].excitation}; for {b}, {lib[b].excitation}"


def _merge(params: Params, name: str, values: Mapping[str, Any]) -> Params:
    out = {k: dict(v) for k, v in params.items()}
    out[name] = {**out.get(name, {}), **values}
    return out


def discover_effects(
    plan: ReplayPlan,
    *,
    effects: Iterable[str] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    library: EffectLibrary | None = None,
    candidates: Iterable[str] | None = None,
    max_iterations: int = 3,
    bootstrap: int = 200,
    seed: int = 0,
    variance_threshold: float = 1.3,
    explain_fraction: float = 0.5,
    stability: float = 0.6,
    ambiguity: float = 0.05,
    passes: int = 3,
) -> DiscoveryResult:
    """Find the effects missing from a hoist's model (module docstring for the method).

    Parameters
    ----------
    plan : ReplayPlan
        The measured trips (:func:`sims.replay.plan_replay`).
    effects, parameters
        The model: effect names (default the hoist's ``[model] effects``) and parameter
        overrides ``{effect: {parameter: value}}``.
    library : EffectLibrary
        Candidate terms (default :data:`~sims.discovery.library.EFFECT_LIBRARY`).
    candidates : names, optional
        Restrict the candidates (default every library term not in the model).
    max_iterations : int
        Effects added at most.
    bootstrap, seed : int
        Trip resamples for the stability and their random seed.
    variance_threshold : float
        Residual variance / noise variance above which something is missing.
    explain_fraction : float
        Share of the excess variance the winner must explain.
    stability : float
        Share of bootstrap resamples the winner must win.
    ambiguity : float
        Runner-up within this share of the winner's explained variance: ambiguous.
    passes : int
        Payload / loading-ramp fitting passes of the base replays.
    """
    if not 0 < explain_fraction <= 1 or not 0 < stability <= 1:
        raise ValueError("explain_fraction and stability must be in (0, 1]")
    if variance_threshold <= 1.0:
        raise ValueError("variance_threshold must exceed 1 (the noise alone gives 1)")
    if max_iterations < 1 or bootstrap < 1:
        raise ValueError("max_iterations and bootstrap must be at least 1")
    hoist: HoistDescription = plan.hoist
    lib = (library or EFFECT_LIBRARY).fit(hoist)
    model = list(hoist.model.effects if effects is None else effects)
    params: Params = {k: dict(v) for k, v in (parameters or {}).items()}
    allowed = set(lib.get_feature_names() if candidates is None else candidates)
    base = replay_fitted(
        plan, effects=model, parameters=term_parameters(hoist, params, model), passes=passes
    )
    if not base.ok:
        raise RuntimeError(
            f"the hoist's model does not simulate the measured trips: {base.message}"
        )
    eng = _Engine(plan, lib, base)
    eng.rebase(base, model, params)
    lay = eng.layout
    m = len(plan.trips)
    sigma2 = plan.noise_sigma_pa**2
    n_entries = lay.y.size
    nuis = np.zeros((n_entries, m))
    nuis[np.arange(n_entries), lay.trip] = 1.0
    s0 = lay.flat(base.simulated)
    first = base
    current = base
    rng = np.random.default_rng(seed)
    weights = rng.multinomial(m, np.full(m, 1.0 / m), size=bootstrap).astype(float)
    findings: list[Finding] = []
    notes: list[str] = []

    def no_addition(effect: str, confidence: float, ranked: list, message: str, **extra) -> Finding:
        """A finding that adds nothing (none / ambiguous) at this iteration's state."""
        return Finding(
            iteration,
            effect,
            {},
            {},
            confidence,
            gap_before,
            gap_before,
            plan.noise_sigma_pa,
            ratio,
            tau,
            ranked,
            where,
            message=message,
            **extra,
        )

    for iteration in range(1, max_iterations + 1):
        r = lay.y - s0
        retune_names = [e for e in model if e in lib]
        retune_cols = [eng.retune(e, model, params, s0) for e in retune_names]
        retune_cols = [c for c in retune_cols if c.ok and c.jac.shape[1]]
        x0 = np.column_stack([*(c.jac for c in retune_cols), nuis])
        pen0 = np.concatenate(
            [*(sigma2 / lib[c.name].prior(c.theta0) ** 2 for c in retune_cols), np.zeros(m)]
        )
        ne0 = _normal(x0, r, lay.trip, m, pen0)
        rss0, beta0 = _solve(ne0, np.ones(m))
        ratio = rss0 / (n_entries * sigma2)
        gap_before = _rms(r)
        cand = [c for c in lib.candidates(model) if c in allowed]
        scores: dict[str, dict[str, Any]] = {}
        for name in cand if ratio >= variance_threshold else []:
            cols = eng.candidate(name, model, params, s0)
            if not cols.ok:
                notes.append(f"iteration {iteration}: candidate {name} skipped: {cols.note}")
                continue
            x = np.column_stack([cols.jac, x0])
            target = r - cols.delta
            ne = _normal(
                x, target, lay.trip, m, np.concatenate([np.zeros(x.shape[1] - pen0.size), pen0])
            )
            rss, beta = _solve(ne, np.ones(m))
            scores[name] = {
                "rss": rss,
                "beta": beta,
                "ne": ne,
                "cols": cols,
                "k": cols.jac.shape[1],
            }
        resid0 = r - x0 @ beta0
        tau = _autocorrelation_time(resid0, lay)
        where = locate_gap(plan, lay, r)
        if not scores:
            msg = (
                f"residual variance {ratio:.2f} x the noise variance: nothing missing"
                if ratio < variance_threshold
                else "the residual exceeds the noise but no candidate could be scored"
            )
            findings.append(
                no_addition(
                    NO_EFFECT,
                    1.0 - min(1.0, max(ratio - 1.0, 0.0)),
                    [],
                    message=msg,
                )
            )
            break
        best_name = min(scores, key=lambda c: scores[c]["rss"])
        best = scores[best_name]
        resid_best = r - best["cols"].delta - np.column_stack([best["cols"].jac, x0]) @ best["beta"]
        tau = _autocorrelation_time(resid_best, lay)
        n_eff = max(n_entries / tau, 2.0)
        for sc in scores.values():
            sc["dbic"] = n_eff * np.log(rss0 / sc["rss"]) - sc["k"] * np.log(n_eff)
        wins = {c: 0 for c in scores}
        wins[NO_EFFECT] = 0
        for w in weights:
            r0b, _ = _solve(ne0, w)
            nb = n_eff * float(w @ np.bincount(lay.trip, minlength=m)) / n_entries
            best_b, best_v = NO_EFFECT, 0.0
            for c, sc in scores.items():
                rb, _ = _solve(sc["ne"], w)
                v = nb * np.log(r0b / rb) - sc["k"] * np.log(max(nb, 2.0))
                if v > best_v:
                    best_b, best_v = c, v
            wins[best_b] += 1
        share = {c: wins[c] / bootstrap for c in wins}
        ranking = sorted(
            (
                {
                    "effect": c,
                    "score": round(float(sc["dbic"]), 1),
                    "explained_pa": round(
                        float(np.sqrt(max(rss0 - sc["rss"], 0.0) / n_entries)), 1
                    ),
                    "bootstrap_share": share[c],
                }
                for c, sc in scores.items()
            ),
            key=lambda d: -d["score"],
        )
        excess = max(rss0 - n_entries * sigma2, 1e-30)
        explained = (rss0 - best["rss"]) / excess
        top = ranking[0]["effect"]
        runner = ranking[1]["effect"] if len(ranking) > 1 else None
        if ratio < variance_threshold or scores[top]["dbic"] <= 0 or explained < explain_fraction:
            msg = (
                f"residual variance {ratio:.2f} x the noise variance: nothing missing"
                if ratio < variance_threshold
                else f"residual variance {ratio:.2f} x the noise variance, but the best candidate "
                f"({top}) explains only {explained:.0%} of the excess"
            )
            findings.append(
                no_addition(
                    NO_EFFECT,
                    1.0 - share.get(top, 0.0),
                    ranking,
                    message=msg,
                )
            )
            break
        close = (
            runner is not None
            and scores[runner]["dbic"] > 0
            and (scores[runner]["rss"] - scores[top]["rss"])
            < ambiguity * (rss0 - scores[top]["rss"])
        )
        split = share[top] < stability
        if close or split:
            other = runner if runner is not None else NO_EFFECT
            if split and not close:
                others = {c: v for c, v in share.items() if c != top}
                other = max(others, key=others.get) if others else NO_EFFECT
            pair = (top, other)
            findings.append(
                no_addition(
                    AMBIGUOUS,
                    share[top],
                    ranking,
                    ambiguous_between=pair,
                    excitation=_excitation(lib, *pair) if other in lib else lib[top].excitation,
                    message=f"{top} and {other} cannot be told apart on these trips",
                )
            )
            break
        # add the winner at its fitted coordinates, re-tuned parameters updated
        cols: _Columns = best["cols"]
        k_c = cols.jac.shape[1]
        beta = best["beta"]
        term = lib[top]
        theta = cols.theta0 + beta[:k_c]
        if top == "sensor_offset":  # the common part is the payload's: relative to the median
            theta = theta - np.median(theta)
        elif top == "sensor_gain":
            theta = theta / np.median(theta)
        new_model = [*model, top]
        winner_only = _merge(params, top, term.parameters(hoist, theta))
        retuned: Params = {}  # what re-tuning moved while scoring (reported, not applied)
        pos = k_c
        for c in retune_cols:
            kk = c.jac.shape[1]
            t_new = c.theta0 + beta[pos : pos + kk]
            pos += kk
            values = lib[c.name].parameters(hoist, t_new)
            retuned[c.name] = values
        predicted = np.sqrt(best["rss"] / n_entries)
        new_params = winner_only
        after = _refit(plan, eng, new_model, new_params, current)
        gap_after = _rms(lay.y - lay.flat(after.simulated)) if after.ok else np.inf
        if term.start_amplitudes and gap_after > 1.1 * plan.noise_sigma_pa:
            after, gap_after, new_params = _refine_along(
                plan, eng, new_model, params, term, [theta, cols.theta0], current
            )
        if gap_after > 1.1 * predicted and not term.analytic:
            # Gauss-Newton step on the winner's coordinates at the refitted point
            eng.rebase(after, new_model, new_params)
            s_new = lay.flat(after.simulated)
            g_cols = eng.fd(term, new_model, new_params, s_new)
            if g_cols.ok:
                xg = np.column_stack([g_cols.jac, nuis])
                _, bg = _solve(_normal(xg, lay.y - s_new, lay.trip, m), np.ones(m))
                th2 = g_cols.theta0 + bg[: g_cols.jac.shape[1]]
                p2 = _merge(new_params, top, term.parameters(hoist, th2))
                alt = _refit(plan, eng, new_model, p2, current)
                gap_alt = _rms(lay.y - lay.flat(alt.simulated)) if alt.ok else np.inf
                if gap_alt < gap_after:
                    after, gap_after, new_params = alt, gap_alt, p2
        if not after.ok or not gap_after < gap_before:
            findings.append(
                no_addition(
                    NO_EFFECT,
                    0.0,
                    ranking,
                    message=f"{top} scored best but adding it did not shrink the gap "
                    f"({gap_before:.0f} -> {gap_after:.0f} Pa)",
                )
            )
            break
        s_after = lay.flat(after.simulated)
        where = locate_gap(plan, lay, r, lay.y - s_after)
        findings.append(
            Finding(
                iteration,
                top,
                parameters_json(new_params.get(top, {}), significant_digits=6),
                {k: parameters_json(v, significant_digits=6) for k, v in retuned.items()},
                float(share[top]),
                gap_before,
                gap_after,
                plan.noise_sigma_pa,
                ratio,
                tau,
                ranking,
                where,
                message=f"added {top}; explains {explained:.0%} of the excess variance",
            )
        )
        model, params, current, s0 = new_model, new_params, after, s_after
        eng.rebase(after, model, params)
        if not [c for c in lib.candidates(model) if c in allowed]:
            break
    return DiscoveryResult(
        plan=plan,
        findings=findings,
        effects_before=tuple(hoist.model.effects if effects is None else effects),
        effects_after=tuple(model),
        parameters_after=params,
        before=first,
        after=current,
        replays=eng.replays + 0,
        notes=notes,
    )


def _refine_along(
    plan: ReplayPlan,
    eng: _Engine,
    effects: list[str],
    params: Params,
    term: EffectTerm,
    starts: list[np.ndarray],
    current: ReplayResult,
    *,
    evaluations: int = 8,
) -> tuple[ReplayResult, float, Params]:
    """Refitted gap minimised along the coordinates of a strongly nonlinear term.

    A linear step from the scan's start (``term.start_amplitudes``) can land on the far
    side of a kink in the response (seal friction flipping as the pistons drift apart)
    and the payloads fitted without the term are biased; so the gap with payloads and
    ramps refitted (:func:`_refit`) is minimised over the scale ``c`` of the better of
    ``starts`` (Brent's bounded method on ``0.5 <= c <= 1.5``). Returns the best replay,
    its gap and parameters.
    """
    lay = eng.layout
    seen: dict[float, tuple[float, ReplayResult, Params]] = {}

    def at(theta: np.ndarray) -> tuple[float, ReplayResult, Params]:
        prm = _merge(params, term.name, term.parameters(plan.hoist, theta))
        res = _refit(plan, eng, effects, prm, current)
        gap = _rms(lay.y - lay.flat(res.simulated)) if res.ok else np.inf
        return gap, res, prm

    first = [at(np.asarray(t, float)) for t in starts]
    k = int(np.argmin([f[0] for f in first]))
    direction = np.asarray(starts[k], float)
    seen[1.0] = first[k]

    def gap_of(c: float) -> float:
        if c not in seen:
            seen[c] = at(c * direction)
        return seen[c][0]

    optimize.minimize_scalar(
        gap_of, bounds=(0.5, 1.5), method="bounded", options={"maxiter": evaluations}
    )
    gap, res, prm = seen[min(seen, key=lambda c: seen[c][0])]
    return res, gap, prm


def _refit(
    plan: ReplayPlan, eng: _Engine, effects: list[str], params: Params, start: ReplayResult
) -> ReplayResult:
    eng.replays += 3
    return replay_fitted(
        plan,
        effects=effects,
        parameters=term_parameters(plan.hoist, params, effects),
        passes=3,
        ramps_s=start.ramps_s,
    )
