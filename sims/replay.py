"""Replay measured hoist trips through the device simulation.

The discovery workflow (issue 8) and the nightly sanity check (issue 7) compare what the
pressure sensors logged with what the device simulation (:func:`sims.device.simulate`)
predicts for the same trips. The simulation needs its inputs -- commanded motion,
payload, oil temperature -- and these come from the log itself:

:func:`plan_replay`
    Segments a landed sample frame (``FIELD_SAMPLES`` columns: ``time_utc``,
    ``p{i}_pa``, ``depth_m``, ``speed_m_s``, ``oil_temp_c``) into trips and builds, per
    trip, everything a simulation needs: start and stop depth (median encoder depth at
    the standstills), motion start (least squares on the encoder speed of the
    accelerating phase: ``|v| = a (t - t_m)``), top speed, oil temperature (median),
    the loading ramp before the motion (from the common-mode pressure) and the samples
    to score (sub-sampled to ``score_rate_hz``, loading ramps masked, spikes masked).
    The logger's pressure noise is estimated from second differences of the
    pressures at standstill (robust MAD; white noise of variance s^2 gives second
    differences of variance 6 s^2).
:func:`replay`
    Simulates the planned trips with a given effect set and parameters and returns the
    simulated sensor pressures at the scored measured timestamps. The trips of a block
    are one continuous history: each continues from the previous one's final state
    (``simulate(..., initial_state=...)``), as the field-day generator and a real hoist
    do; a block starts in static equilibrium, and its first trip is scored only after
    its loading ramp (the friction stored before it is unknown).
:func:`replay_fitted`
    :func:`replay` with the payloads fitted: the payload is the log's free input. It is
    inferred from the static pressure after loading, then corrected once from the
    per-trip mean common-mode residual (the pressure is linear in the payload to ~3 %
    through the pressure dependence of the seal friction, so a second pass leaves
    < 0.1 % of the first correction) and the trips re-simulated.

Records are cut anywhere (a logger stops mid-trip, a day ends at UTC midnight), and a
replay never crashes on that: a trip the record starts or ends in is completed by the
winder profile fitted to its logged depth (:func:`sims.trips.fit_cut_trip`) and marked
``cut``; cut at its end it is simulated and scored up to the record's end, cut at its
start it is simulated from rest before the record and only loads the seals' state. A
trip that cannot be prepared is listed in ``ReplayPlan.skipped`` with the reason, one
the simulation refuses gets its reason in ``ReplayResult.trip_messages``. A load change
after the last stop (loading for a trip the record does not hold) ends the last window.

The ropes' ringing is read off the record, not taken on trust from the description
(whose ``head_rope_damping_ratio`` is a default a mine cannot know): a model that rings
at ~1 Hz where the hoist does not leaves a common-mode gap of ~0.1 MPa. The description's
ratio stays unless the record contradicts it; then the ratio read from the ringing's decay
(or, with no ringing seen 3-7 s after the stops, 0.1 / 0.3 / 1.0) is chosen by the replay
gap (:mod:`sims.logged_motion`, ``ReplayPlan.rope_bounce``). The trips can also be driven
by the encoder's logged speed instead of the winder profile (``plan_replay(motion=
"logged")``).

Long records are analysed on at most ``max_trips`` trips in ``blocks`` blocks of
consecutive trips spread evenly over the record (temperature and payload ranges
covered, simulation cost bounded: ~0.2 s per 2-minute trip at ``dt_s = 2 ms``).

Accuracy note: the device simulation's sensor pressures change by ~13 kPa RMS between
``dt_s`` = 2 ms and 5 ms (friction stick-slip transitions), so replaying synthetic data
at another step than it was generated with leaves a systematic gap of that size. The
default ``dt_s = 2 ms`` is the field-day generator's.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import polars as pl
from scipy import ndimage, optimize

from physics.tension import tail_rope_length_m
from schemas.hoist import G_STANDARD, HoistDescription
from sims.device import simulate
from sims.effects import resolve_effects
from sims.logged_motion import motion_knots, profile_from_knots, rope_damping_from_record
from sims.trips import TripProfile, fit_cut_trip, trip

__all__ = [
    "ReplayPlan",
    "ReplayResult",
    "ReplayTrip",
    "SkippedTrip",
    "estimate_noise_sigma",
    "payload_from_pressure",
    "plan_replay",
    "replay",
    "replay_fitted",
    "replay_frame",
]

_MOVING_M_S = 0.05  # encoder speed above which the conveyance moves
_MIN_MOTION_S = 3.0
_RAMP_MARGIN_S = 2.0  # scored samples start this long after a loading ramp ends


@dataclass(frozen=True)
class ReplayTrip:
    """One measured trip prepared for simulation (times in s after ``ReplayPlan.t_ref``).

    ``time_s``, ``measured_pa`` ((m, n)), ``valid`` ((m, n)), ``phase``, ``direction``,
    ``depth_m`` are the scored samples; the rest are the simulation inputs. ``cut`` is
    ``"start"`` or ``"end"`` for a trip the record cuts (it starts or ends while the
    conveyance moves; the unseen end is fitted, :func:`sims.trips.fit_cut_trip`): a trip
    cut at its start is simulated from rest before the record but none of its samples is
    valid (it only loads the seals' state for the next trip); one cut at its end is
    simulated and scored up to the record's end. ``motion_knots`` (time [s after
    ``t_ref``], speed [m/s, + down], depth [m]) is the logged motion that drives the
    simulation (:mod:`sims.logged_motion`); None for a trip cut at its start (driven by
    the fitted winder profile).
    """

    trip_id: int
    block: int
    first_in_block: bool
    window_start_s: float
    window_end_s: float
    ramp_start_s: float
    ramp_end_s: float
    motion_start_s: float
    motion_end_s: float
    start_depth_m: float
    end_depth_m: float
    max_speed_m_s: float | None
    direction: str
    oil_temp_c: float
    p_before_pa: float
    p_after_pa: float
    time_s: np.ndarray
    measured_pa: np.ndarray
    valid: np.ndarray
    phase: np.ndarray
    depth_m: np.ndarray
    ramp_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ramp_measured_pa: np.ndarray = field(default_factory=lambda: np.zeros(0))
    profile_fit_m: float = 0.0
    cut: str = ""
    motion_knots: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None


@dataclass(frozen=True)
class SkippedTrip:
    """A trip of the record that :func:`plan_replay` could not prepare, and why."""

    trip_id: int
    motion_start_s: float
    reason: str


@dataclass(frozen=True)
class ReplayPlan:
    """Trips of one hoist's record prepared for replay; see :func:`plan_replay`.

    ``skipped`` lists the analysed trips that could not be prepared, with the reason;
    the trip after a skipped one starts its block's history again. ``rope_bounce`` says
    what the record shows of the ropes' ringing (:func:`sims.logged_motion.
    rope_damping_from_record`); ``hoist`` carries the damping ratio the replay uses
    (the description's unless the record contradicts it, also said in ``notes``).
    """

    hoist: HoistDescription
    t_ref: dt.datetime
    trips: tuple[ReplayTrip, ...]
    noise_sigma_pa: float
    score_rate_hz: float
    dt_s: float
    trips_found: int
    notes: tuple[str, ...] = ()
    skipped: tuple[SkippedTrip, ...] = ()
    rope_bounce: str = ""

    @property
    def n_sensors(self) -> int:
        return self.hoist.ropes_n

    def time_utc(self, seconds: np.ndarray) -> pl.Series:
        """Absolute UTC timestamps of ``seconds`` after ``t_ref``."""
        base = int(self.t_ref.timestamp() * 1e6)
        return pl.Series(
            "time_utc", base + np.round(np.asarray(seconds) * 1e6).astype(np.int64)
        ).cast(pl.Datetime("us", "UTC"))


@dataclass(frozen=True)
class ReplayResult:
    """Simulated sensor pressures at the scored samples of each planned trip.

    ``simulated[k]`` is (m_k, n) [Pa] (NaN where the simulation failed);
    ``payload_kg[k]`` the payload after trip k's loading, ``payload_before_kg[k]``
    before it; ``status`` "success" or "failed" with ``message``; ``trip_messages[k]``
    says why trip k was not simulated ("" when it was).
    """

    simulated: tuple[np.ndarray, ...]
    payload_kg: np.ndarray
    payload_before_kg: np.ndarray
    effects: frozenset[str]
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    status: str = "success"
    message: str = ""
    ramp_simulated: tuple[np.ndarray, ...] = ()
    ramps_s: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    trip_messages: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.status == "success"

    def residuals(self, plan: ReplayPlan) -> tuple[np.ndarray, ...]:
        """Measured minus simulated [Pa] per trip, NaN where not valid."""
        return tuple(
            np.where(tr.valid, tr.measured_pa - sim, np.nan)
            for tr, sim in zip(plan.trips, self.simulated, strict=True)
        )

    def rms_gap_pa(self, plan: ReplayPlan) -> float:
        """RMS of measured minus simulated over every valid sample [Pa]; NaN if none."""
        r = np.concatenate([x[np.isfinite(x)] for x in self.residuals(plan)])
        return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


# ---------------------------------------------------------------------------------------
# planning
# ---------------------------------------------------------------------------------------
def estimate_noise_sigma(pressures: np.ndarray, moving: np.ndarray) -> float:
    """Pressure noise standard deviation [Pa] from second differences at standstill.

    For white noise of standard deviation s, ``p[k+1] - 2 p[k] + p[k-1]`` has standard
    deviation ``sqrt(6) s``; a slow signal (loading ramp, held state) contributes almost
    nothing. Robust: MAD / 0.6745 over every sensor's standstill triplets, spikes and
    transients do not move it.

    >>> rng = np.random.default_rng(0)
    >>> p = 5e6 + np.linspace(0, 1e5, 20000)[:, None] + rng.normal(0, 5e3, (20000, 4))
    >>> round(estimate_noise_sigma(p, np.zeros(20000, bool)) / 5e3, 1)
    1.0
    """
    p = np.asarray(pressures, dtype=float)
    if p.ndim == 1:
        p = p[:, None]
    still = ~np.asarray(moving, dtype=bool)
    ok = still[2:] & still[1:-1] & still[:-2]
    if ok.sum() < 20:
        ok = np.ones(p.shape[0] - 2, dtype=bool)
    d2 = (p[2:] - 2.0 * p[1:-1] + p[:-2])[ok]
    d2 = d2[np.isfinite(d2)]
    if d2.size == 0:
        return float("nan")
    mad = np.median(np.abs(d2 - np.median(d2)))
    return float(mad / 0.6745 / np.sqrt(6.0))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1, strict=True))


def _motions(t: np.ndarray, speed: np.ndarray) -> list[tuple[int, int]]:
    moving = np.abs(ndimage.median_filter(np.nan_to_num(speed), size=5)) >= _MOVING_M_S
    runs = _runs(moving)
    merged: list[tuple[int, int]] = []
    for a, b in runs:
        if merged and t[a] - t[merged[-1][1]] < 2.0:
            merged[-1] = (merged[-1][0], b)
        else:
            merged.append((a, b))
    return [(a, b) for a, b in merged if t[b] - t[a] >= _MIN_MOTION_S]


def _median_in(t: np.ndarray, values: np.ndarray, lo: float, hi: float) -> float:
    part = values[_span(t, lo, hi)]
    part = part[np.isfinite(part)]
    return float(np.median(part)) if part.size else float("nan")


def _plateau_median(
    t: np.ndarray, values: np.ndarray, lo: float, hi: float, width_s: float, *, from_start: bool
) -> float:
    """Median of ``values`` over the first (``from_start``) or last ``width_s`` seconds of
    logged samples within [lo, hi]: a logger gap at the edge of the interval shifts the
    window to the nearest samples instead of leaving it empty."""
    part = _span(t, lo, hi)
    if part.stop <= part.start:
        return float("nan")
    if from_start:
        first = float(t[part.start])
        return _median_in(t, values, first, min(first + width_s, hi))
    last = float(t[part.stop - 1])
    return _median_in(t, values, max(last - width_s, lo), last)


def _span(t: np.ndarray, lo: float, hi: float) -> slice:
    """Index range of sorted ``t`` within [lo, hi] (binary search, no full-array mask)."""
    return slice(int(np.searchsorted(t, lo, "left")), int(np.searchsorted(t, hi, "right")))


def _fit_ramp(
    t: np.ndarray, pc: np.ndarray, r0: float, r1: float, p_pre: float, p_post: float
) -> tuple[float, float]:
    """Least-squares plateau-ramp-plateau fit of the common-mode pressure (loading).

    The rope bounce a ramp excites oscillates about the ramp, so the kinks' times are
    unbiased; a robust loss (soft L1) ignores spikes. Returns (start, end) [s].
    """
    ok = np.isfinite(pc)
    if ok.sum() < 8:
        return r0, r1
    tt, yy = t[ok], pc[ok]
    scale = max(abs(p_post - p_pre), 1.0)

    def resid(x: np.ndarray) -> np.ndarray:
        a, b = x[0], max(x[1], x[0] + 1e-3)
        u = np.clip((tt - a) / (b - a), 0.0, 1.0)
        return (x[2] + (x[3] - x[2]) * u - yy) / scale

    x0 = np.array([r0, r1, p_pre, p_post])
    try:
        sol = optimize.least_squares(
            resid, x0, loss="soft_l1", f_scale=0.02, x_scale=[1.0, 1.0, scale, scale]
        )
    except ValueError:  # pragma: no cover - degenerate data
        return r0, r1
    a, b = float(sol.x[0]), float(sol.x[1])
    if not (np.isfinite(a) and np.isfinite(b)) or b <= a:
        return r0, r1
    return a, b


def _chosen_trips(count: int, max_trips: int, blocks: int) -> list[list[int]]:
    """Blocks of consecutive trip indices: all when they fit, else spread evenly."""
    if count <= max_trips:
        return [list(range(count))] if count else []
    blocks = max(1, min(blocks, max_trips))
    size = max(1, max_trips // blocks)
    starts = np.linspace(0, count - size, blocks).round().astype(int)
    out: list[list[int]] = []
    for s in starts:
        idx = [k for k in range(s, s + size) if not out or k > out[-1][-1]]
        if idx:
            out.append(idx)
    return out


def plan_replay(
    samples: pl.DataFrame,
    hoist: HoistDescription,
    *,
    max_trips: int = 12,
    blocks: int = 4,
    score_rate_hz: float = 20.0,
    settle_s: float = 30.0,
    dt_s: float = 2e-3,
    motion: str = "winder",
) -> ReplayPlan:
    """Segment ``samples`` of one hoist into trips and prepare their simulation.

    Parameters
    ----------
    samples : polars.DataFrame
        Landed field samples (``time_utc``, ``p{i}_pa``, ``depth_m``, ``speed_m_s``,
        ``oil_temp_c``; SI), one hoist, any order.
    hoist : HoistDescription
        The hoist (winder limits, shaft, cylinders).
    max_trips, blocks : int
        Analyse at most ``max_trips`` trips in ``blocks`` runs of consecutive trips.
    score_rate_hz : float
        Rate of the scored samples and of the simulation output [Hz].
    settle_s : float
        Standstill simulated and scored after each stop [s].
    dt_s : float
        Integrator step of the replays [s].
    motion : {"winder", "logged"}
        What drives each trip's simulation: the hoist description's winder profile
        (constant acceleration, the top speed logged when it is 5 % off the described
        one) or the encoder's logged speed (:mod:`sims.logged_motion`; jerk, per-trip
        acceleration and top speed as they were). "winder" is the default because it
        replays the validation trials closer today (48 / 51 kPa against 60 / 56 kPa on
        two records with nothing hidden): the gap left is the seal friction's state,
        which the input motion moves either way (README, issue 14).

    Raises
    ------
    ValueError
        Required columns missing, or no trip (motion of >= 3 s) in the record.
    """
    if motion not in ("winder", "logged"):
        raise ValueError(f"motion: 'winder' or 'logged', not {motion!r}")
    n = hoist.ropes_n
    pcols = [f"p{i}_pa" for i in range(1, n + 1)]
    need = {"time_utc", "depth_m", "speed_m_s", *pcols}
    missing = need - set(samples.columns)
    if missing:
        raise ValueError(f"samples: missing columns {sorted(missing)}")
    frame = samples.sort("time_utc").unique("time_utc", keep="first", maintain_order=True)
    t_ref = frame["time_utc"][0]
    t = (frame["time_utc"].dt.epoch("us").to_numpy() - int(t_ref.timestamp() * 1e6)) / 1e6
    p = frame.select(pcols).to_numpy().astype(float)
    depth = frame["depth_m"].to_numpy().astype(float)
    speed = frame["speed_m_s"].to_numpy().astype(float)
    temp = (
        frame["oil_temp_c"].to_numpy().astype(float)
        if "oil_temp_c" in frame.columns
        else np.full(t.size, np.nan)
    )
    motions = _motions(t, speed)
    if not motions:
        raise ValueError("samples: no trip (no encoder motion of at least 3 s) in the record")
    # noise from quiet standstill: >= 25 s after a stop (the rope bounce has decayed)
    quiet = np.ones(t.size, dtype=bool)
    for a_i, b_i in motions:
        quiet[_span(t, t[a_i] - 1.0, t[b_i] + 25.0)] = False
    if quiet.sum() < 50:
        quiet = np.abs(np.nan_to_num(speed)) < 0.02
    sigma = estimate_noise_sigma(p, ~quiet)
    pc = np.nanmean(p, axis=1)
    rate = 1.0 / max(float(np.median(np.diff(t))), 1e-6)
    # 1-s moving average of the common-mode pressure (O(n); a median over a day at 100 Hz
    # costs tens of seconds); spikes are rare and the ramp fit below is robust to them
    # missing values (dropped samples) interpolated in time, not filled with a constant
    known = np.isfinite(pc)
    pc_filled = np.interp(t, t[known], pc[known]) if known.any() else np.zeros_like(pc)
    pcs = ndimage.uniform_filter1d(pc_filled, size=max(3, int(rate) | 1))
    # the ropes' damping as the record shows it (a hoist that rings and one that does not
    # both replay to the noise; the description's ratio is a default a mine cannot know)
    zeta, zeta_how = rope_damping_from_record(
        t, pc_filled, [float(t[b_i]) for _, b_i in motions], quiet
    )
    w = hoist.winder
    shaft = hoist.shaft.depth_m
    # standstill depths between motions: shared by the trip before and after (chaining);
    # NaN where the record holds no standstill (it starts or ends while moving)
    stops = []
    bounds = (
        [(-np.inf, t[motions[0][0]])]
        + [(t[motions[k][1]], t[motions[k + 1][0]]) for k in range(len(motions) - 1)]
        + [(t[motions[-1][1]], np.inf)]
    )
    for lo, hi in bounds:
        d = _median_in(t, depth, lo + 1.0, hi - 0.5)
        if not np.isfinite(d):  # a standstill shorter than 1.5 s at the record's edge
            d = _median_in(t, depth, lo + 0.05, hi - 0.05)
        stops.append(float(np.clip(d, 0.0, shaft)) if np.isfinite(d) else float("nan"))
    notes: list[str] = []
    chosen = _chosen_trips(len(motions), max_trips, blocks)
    if len(motions) > max_trips:
        notes.append(
            f"{len(motions)} trips in the record; analysed {sum(map(len, chosen))} in "
            f"{len(chosen)} blocks of consecutive trips"
        )
    end_t = float(t[-1])
    ramp_threshold = max(10.0 * sigma, 2e4) if np.isfinite(sigma) else 2e4
    # pass 1, every motion: start / stop times, top speed, loading ramp before it
    timing: list[dict[str, Any]] = []
    for k, (a_i, b_i) in enumerate(motions):
        prev_end = float(t[motions[k - 1][1]]) if k > 0 else float(t[0]) - 2.0
        next_start = float(t[motions[k + 1][0]]) if k + 1 < len(motions) else end_t
        sp = _span(t, t[a_i] - 1.0, t[a_i] + 4.0)
        tw, vw = t[sp], np.abs(speed[sp])
        sel = (vw > 0.1) & (vw < 0.8 * w.acceleration_m_s2 * 4.0)
        t_m = (
            float(np.median(tw[sel] - vw[sel] / w.acceleration_m_s2))
            if sel.sum() >= 3
            else float(t[a_i])
        )
        sp = _span(t, t[b_i] - 0.6, t[b_i] + 0.2)
        tw, vw = t[sp], np.abs(speed[sp])
        sel = vw > 0.05
        t_e = (
            float(np.median(tw[sel] + vw[sel] / w.deceleration_m_s2))
            if sel.sum() >= 3
            else float(t[b_i])
        )
        top = np.abs(speed[a_i : b_i + 1])
        vmax = float(np.nanmedian(top[top > 0.9 * np.nanmax(top)]))
        vmax_arg = None if abs(vmax - w.max_speed_m_s) < 0.05 * w.max_speed_m_s else vmax
        d0, d1 = stops[k], stops[k + 1]
        cut, skip = "", ""
        if not (np.isfinite(d0) and np.isfinite(d1)):
            # the record starts or ends while the conveyance moves (or the encoder depth
            # is missing at a stop): the winder profile fitted to the logged depth
            # completes the trip; both ends unknown: nothing anchors it
            cut = "start" if not np.isfinite(d0) else "end"
            try:
                t_m, t_e, d0, d1, vmax_arg = _complete_cut_trip(
                    hoist, t, depth, a_i, b_i, d0, d1, t_m, t_e, vmax_arg
                )
            except ValueError as exc:
                skip = f"{_CUT_WORDS[cut]}: {exc}"
        if cut == "start":
            # no loading seen: the simulation starts at rest shortly before the motion
            r0, r1 = t_m - 2.0, t_m - 1.5
            p_pre = p_post = float("nan")
        else:
            s_lo = max(prev_end + 2.0, float(t[0]))
            r0, r1, p_pre, p_post = _loading_ramp(t, pc, pcs, s_lo, t_m - 0.3, ramp_threshold)
        if not np.isfinite(p_post):
            # no standstill before the motion in the record: the payload does not change
            # during a trip, so the level after its stop (or, cut there too, while moving)
            p_post = _plateau_median(t, pcs, t_e + 2.0, next_start - 0.3, 2.0, from_start=True)
            if not np.isfinite(p_post):
                p_post = _median_in(t, pc, t[a_i], t[b_i])
            if not np.isfinite(p_post) and not skip:
                skip = "no pressure logged to infer the payload from"
        timing.append(
            {
                "t_m": t_m,
                "t_e": t_e,
                "vmax": vmax_arg,
                "r0": r0,
                "r1": r1,
                "p_pre": p_pre,
                "p_post": p_post,
                "d0": d0,
                "d1": d1,
                "cut": cut,
                "skip": skip,
                "a_t": float(t[a_i]),
                "b_t": float(t[b_i]),
            }
        )
    # a payload change after the last stop (loading for a trip the record does not
    # hold): the last trip's window ends where it begins
    trailing_ramp = np.inf
    if timing and not timing[-1]["cut"]:
        r0, _, p_a, p_b = _loading_ramp(
            t, pc, pcs, timing[-1]["t_e"] + 2.0, end_t, ramp_threshold, fallback=False
        )
        if np.isfinite(r0) and abs(p_b - p_a) > ramp_threshold:
            # the pressure shows the load change late (seal friction, rope bounce): stop
            # short of the fitted ramp start, as scoring starts after a ramp's end
            trailing_ramp = r0 - 0.5 * _RAMP_MARGIN_S
            notes.append(
                f"the payload changes after the last stop (from {r0:.0f} s): "
                "the last trip's window ends there"
            )
    # pass 2, the analysed trips: windows, scored samples
    trips: list[ReplayTrip] = []
    skipped: list[SkippedTrip] = []
    for b, block in enumerate(chosen):
        restart = True  # the next planned trip starts the block's history
        for k in block:
            tm = timing[k]
            if tm["skip"]:
                skipped.append(SkippedTrip(k, tm["t_m"], tm["skip"]))
                restart = True
                continue
            t_m, t_e, vmax_arg = tm["t_m"], tm["t_e"], tm["vmax"]
            r0, r1, p_pre, p_post = tm["r0"], tm["r1"], tm["p_pre"], tm["p_post"]
            d0, d1 = tm["d0"], tm["d1"]
            next_ramp = timing[k + 1]["r0"] if k + 1 < len(motions) else trailing_ramp
            win_end = min(t_e + settle_s, next_ramp, end_t)
            # scored samples: after the ramp, within the window, every 1/score_rate s
            lo = r1 + _RAMP_MARGIN_S
            sp = _span(t, lo, win_end)
            idx = np.arange(sp.start, sp.stop)
            if idx.size:
                bins = np.floor((t[idx] - lo) * score_rate_hz).astype(np.int64)
                idx = idx[np.concatenate([[True], bins[1:] != bins[:-1]])]
            meas = p[idx]
            valid = np.isfinite(meas)
            if idx.size >= 5:
                med = ndimage.median_filter(np.nan_to_num(meas), size=(5, 1), mode="nearest")
                valid &= np.abs(meas - med) <= max(10.0 * sigma, 2e4)
            if tm["cut"] == "start":
                # simulated from rest with a fitted start: it loads the seals' state for
                # the trips after it, its own pressures are not compared
                valid[:] = False
            sp = _span(t, r0 - 1.0, min(r1 + 3.0, t_m - 0.3))
            ridx = np.arange(sp.start, sp.stop)
            if ridx.size:
                rb = np.floor((t[ridx] - t[ridx[0]]) * score_rate_hz).astype(np.int64)
                ridx = ridx[np.concatenate([[True], rb[1:] != rb[:-1]])]
            profile = _profile_of(
                hoist, d0, d1, t_m - r0, max(win_end - r0, 1.0), vmax_arg, 20.0, (0.0, 1.0), 0.0
            )
            # the logged motion drives the simulation (sims.logged_motion); a trip cut at
            # its start is simulated from rest before the record: the fitted profile
            knots = None
            if motion == "logged" and tm["cut"] != "start":
                knots = motion_knots(
                    t,
                    speed,
                    tm["a_t"] - 1.5,
                    end_t + 1e-6 if tm["cut"] == "end" else min(tm["b_t"] + 1.5, end_t + 1e-6),
                    d0,
                    d1,
                    at_rest_after=tm["cut"] != "end",
                )
            tau = t[idx] - r0
            # phases of the motion the simulation follows (|a| > 0.05 m/s2: above the
            # logged speed's 1 mm/s steps over a 0.1 s knot)
            driven = profile
            if knots is not None:
                driven = profile_from_knots(
                    *knots,
                    start_s=r0,
                    duration_s=max(win_end - r0, 1.0),
                    payload_time_s=np.array([0.0]),
                    payload_kg=np.array([0.0]),
                    oil_temp_c=None,
                    direction="down" if d1 > d0 else "up",
                )
            spd = driven.speed(tau)
            acc = driven.acceleration(tau) * np.sign(spd)
            phase = np.select(
                [
                    np.abs(spd) < 0.01,
                    acc > 0.05,
                    acc < -0.05,
                    np.abs(spd) <= 1.01 * w.creep_speed_m_s,
                ],
                ["standstill", "accelerate", "decelerate", "creep"],
                default="run",
            )
            motion = _span(t, t_m, t_e)
            fit = float(np.sqrt(np.nanmean((profile.depth(t[motion] - r0) - depth[motion]) ** 2)))
            if fit > 0.5:
                notes.append(
                    f"trip {k}: encoder depth departs {fit:.2f} m RMS from the winder profile"
                )
            if tm["cut"]:
                notes.append(
                    f"trip {k}: {_CUT_WORDS[tm['cut']]}: completed by the winder profile "
                    f"fitted to the logged depth ({d0:.1f} -> {d1:.1f} m)"
                )
            oil = _median_in(t, temp, max(r0, float(t[0])), win_end)
            trips.append(
                ReplayTrip(
                    trip_id=k,
                    block=b,
                    first_in_block=restart,
                    window_start_s=r0,
                    window_end_s=win_end,
                    ramp_start_s=r0,
                    ramp_end_s=r1,
                    motion_start_s=t_m,
                    motion_end_s=t_e,
                    start_depth_m=d0,
                    end_depth_m=d1,
                    max_speed_m_s=vmax_arg,
                    direction="down" if d1 > d0 else "up",
                    oil_temp_c=oil if np.isfinite(oil) else hoist.oil.reference_temperature_c,
                    p_before_pa=p_pre if np.isfinite(p_pre) else p_post,
                    p_after_pa=p_post,
                    time_s=t[idx],
                    measured_pa=meas,
                    valid=valid,
                    phase=phase,
                    depth_m=driven.depth(tau),
                    ramp_time_s=t[ridx],
                    ramp_measured_pa=np.nanmedian(p[ridx], axis=1),
                    profile_fit_m=fit,
                    cut=tm["cut"],
                    motion_knots=knots,
                )
            )
            restart = False
    plan = ReplayPlan(
        hoist=hoist,
        t_ref=t_ref,
        trips=tuple(trips),
        noise_sigma_pa=sigma,
        score_rate_hz=score_rate_hz,
        dt_s=dt_s,
        trips_found=len(motions),
        notes=tuple(notes),
        skipped=tuple(skipped),
        rope_bounce=zeta_how,
    )
    return _with_rope_damping(plan, zeta)


def _with_damping(hoist: HoistDescription, zeta: float) -> HoistDescription:
    ropes = hoist.ropes.model_copy(update={"head_rope_damping_ratio": zeta})
    return hoist.model_copy(update={"ropes": ropes})


def _with_rope_damping(plan: ReplayPlan, zeta_read: float | None) -> ReplayPlan:
    """The plan with the head ropes' damping ratio the record supports.

    The description's ratio stays unless the record contradicts it: ringing read at a
    ratio more than a factor 2 off it, or no ringing 3-7 s after the stops where the
    description's ropes would still ring (``zeta_read`` 1.0, which only bounds the
    ratio from below: 0.3 and 1.0 both leave nothing after 3 s). Then the candidates
    (the description's, the read one or 0.1 / 0.3 / 1.0 above the description's) are
    replayed on the first block's first three trips (payloads fitted, two passes) and
    the one with the smallest gap is used if it beats the description's by 10 %.
    """
    described = plan.hoist.ropes.head_rope_damping_ratio
    if zeta_read is None or not plan.trips:
        return plan
    if zeta_read < 1.0:
        if 0.5 <= zeta_read / max(described, 1e-9) <= 2.0:
            how = f"{plan.rope_bounce}; consistent with the description's {described:g}"
            return dataclasses.replace(plan, rope_bounce=how)
        candidates = [described, zeta_read]
    else:
        candidates = [described] + [c for c in (0.1, 0.3, 1.0) if c > 1.5 * described]
        if len(candidates) == 1:
            return plan
    block = [tr for tr in plan.trips if tr.block == plan.trips[0].block][:3]
    gaps = []
    for zeta in candidates:
        trial = dataclasses.replace(plan, hoist=_with_damping(plan.hoist, zeta), trips=block)
        gap = replay_fitted(trial, passes=2).rms_gap_pa(trial)
        gaps.append(gap if np.isfinite(gap) else np.inf)
    best = int(np.argmin(gaps))
    said = ", ".join(f"{z:g}: {g / 1e3:.1f} kPa" for z, g in zip(candidates, gaps, strict=True))
    if best == 0 or not gaps[best] < 0.9 * gaps[0]:
        how = f"{plan.rope_bounce}; the description's {described:g} kept (replay gap {said})"
        return dataclasses.replace(plan, rope_bounce=how)
    how = (
        f"{plan.rope_bounce}; damping ratio {candidates[best]:g} replaces the "
        f"description's {described:g} (replay gap on {len(block)} trips {said})"
    )
    return dataclasses.replace(
        plan,
        hoist=_with_damping(plan.hoist, candidates[best]),
        rope_bounce=how,
        notes=(*plan.notes, f"rope bounce: {how}"),
    )


#: How a trip the record cuts is named in notes and reasons.
_CUT_WORDS = {"start": "the record starts during this trip", "end": "the record ends during it"}


def _complete_cut_trip(
    hoist: HoistDescription,
    t: np.ndarray,
    depth: np.ndarray,
    a_i: int,
    b_i: int,
    d0: float,
    d1: float,
    t_m: float,
    t_e: float,
    vmax: float | None,
) -> tuple[float, float, float, float, float | None]:
    """(motion start, motion end, start depth, end depth, max speed) of a trip with one
    unknown end: :func:`sims.trips.fit_cut_trip` on the logged depth of its motion."""
    if not (np.isfinite(d0) or np.isfinite(d1)):
        raise ValueError("the record holds neither its start nor its stop")
    motion = slice(a_i, b_i + 1)
    speeds = (None,) if vmax is None else (None, vmax)
    if np.isfinite(d0):
        fit = fit_cut_trip(
            hoist, t[motion], depth[motion], start_depth_m=d0, motion_start_s=t_m,
            max_speeds_m_s=speeds,
        )  # fmt: skip
    else:
        fit = fit_cut_trip(
            hoist, t[motion], depth[motion], end_depth_m=d1, motion_end_s=t_e,
            max_speeds_m_s=speeds,
        )  # fmt: skip
    return (
        fit.motion_start_s,
        fit.motion_end_s,
        fit.start_depth_m,
        fit.end_depth_m,
        fit.max_speed_m_s,
    )


def _loading_ramp(
    t: np.ndarray,
    pc: np.ndarray,
    pcs: np.ndarray,
    s_lo: float,
    s_hi: float,
    threshold_pa: float,
    *,
    fallback: bool = True,
) -> tuple[float, float, float, float]:
    """(ramp start, ramp end, level before, level after) of a load change in the
    standstill ``[s_lo, s_hi]`` (common-mode pressure ``pc``, its 1-s mean ``pcs``).

    A change of the level by more than ``threshold_pa`` is located from its 10-90 %
    crossing and refined by :func:`_fit_ramp`. Without one the ramp is a nominal 0.5 s
    just before ``s_hi + 0.3`` (the motion start), or, with ``fallback=False``, NaN.
    """
    p_pre = _plateau_median(t, pcs, s_lo, s_hi, 2.0, from_start=True)
    p_post = _plateau_median(t, pcs, s_lo, s_hi, 3.0, from_start=False)
    change = p_post - p_pre
    in_s = _span(t, s_lo, s_hi)
    if np.isfinite(change) and abs(change) > threshold_pa and in_s.stop - in_s.start > 4:
        u = (pcs[in_s] - p_pre) / change
        ts = t[in_s]
        above = np.flatnonzero(u > 0.1)
        below = np.flatnonzero(u < 0.9)
        t10 = float(ts[above[0]]) if above.size else float(ts[0])
        t90 = float(ts[below[-1]]) if below.size else float(ts[-1])
        dur = max((t90 - t10) / 0.8, 0.5)
        r0, r1 = _fit_ramp(
            ts,
            pc[in_s],
            max(s_lo, t10 - 0.1 * dur),
            min(t10 - 0.1 * dur + dur, s_hi),
            p_pre,
            p_post,
        )
        return max(s_lo, r0), min(r1, s_hi), p_pre, p_post
    if not fallback:
        return float("nan"), float("nan"), p_pre, p_post
    r0 = max(s_lo, s_hi + 0.3 - 6.0)
    return r0, min(r0 + 0.5, s_hi), p_pre, p_post


def _profile_of(
    hoist: HoistDescription,
    d0: float,
    d1: float,
    rest_before_s: float,
    duration_s: float,
    vmax: float | None,
    oil_temp_c: float,
    ramp: tuple[float, float],
    payload_before: float,
    payload_after: float | None = None,
) -> TripProfile:
    base = trip(
        hoist,
        start_depth_m=d0,
        end_depth_m=d1,
        rest_before_s=max(rest_before_s, 0.0),
        rest_after_s=0.0,
        max_speed_m_s=vmax,
        oil_temp_c=oil_temp_c,
    )
    rest_after = max(duration_s - base.duration_s, 0.5)
    prof = trip(
        hoist,
        start_depth_m=d0,
        end_depth_m=d1,
        rest_before_s=max(rest_before_s, 0.0),
        rest_after_s=rest_after,
        max_speed_m_s=vmax,
        oil_temp_c=oil_temp_c,
    )
    after = payload_before if payload_after is None else payload_after
    return dataclasses.replace(
        prof,
        # a trip the record cuts at its end is simulated up to the end of the record
        duration_s=min(prof.duration_s, max(duration_s, 1e-3)),
        payload_time_s=np.array([ramp[0], max(ramp[1], ramp[0] + 1e-3)]),
        payload_kg=np.array([payload_before, after]),
    )


# ---------------------------------------------------------------------------------------
# simulation
# ---------------------------------------------------------------------------------------
def _sensor_calibration(
    hoist: HoistDescription, effects: Iterable[str], parameters: Mapping[str, Any] | None
) -> tuple[np.ndarray, np.ndarray]:
    eff = resolve_effects(hoist, effects, parameters)
    n = hoist.ropes_n
    gain = (
        np.asarray(eff.parameters["sensor_gain"]["gains"], float)
        if eff.on("sensor_gain")
        else np.ones(n)
    )
    off = (
        np.asarray(eff.parameters["sensor_offset"]["offsets_pa"], float)
        if eff.on("sensor_offset")
        else np.zeros(n)
    )
    return gain, off


def payload_from_pressure(
    hoist: HoistDescription,
    effects: Iterable[str],
    parameters: Mapping[str, Any] | None,
    readings_pa: float,
    depth_m: float,
) -> float:
    """Payload [kg] the model needs for the mean sensor reading ``readings_pa`` at rest.

    ``W = n A p`` with ``p = (reading - offset) / gain`` (the model's sensor
    calibration), minus the conveyance and (with ``tail_rope_weight``) the hanging tail
    rope at ``depth_m``; seal friction held at rest is ignored (see
    :func:`replay_fitted`).
    """
    eff = resolve_effects(hoist, effects, parameters)
    gain, off = _sensor_calibration(hoist, effects, parameters)
    p = (readings_pa - off.mean()) / gain.mean()
    tail = 0.0
    if eff.on("tail_rope_weight"):
        prm = eff.parameters["tail_rope_weight"]
        tail = prm["tail_ropes"] * prm["mass_per_length_kg_m"] * tail_rope_length_m(hoist, depth_m)
    area = hoist.cylinders.bore_area_m2
    return max(p * hoist.ropes_n * area / G_STANDARD - hoist.conveyance.mass_kg - tail, 0.0)


def replay(
    plan: ReplayPlan,
    *,
    effects: Iterable[str] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    payload_kg: Sequence[float] | np.ndarray | None = None,
    payload_before_kg: Sequence[float] | np.ndarray | None = None,
    ramps_s: np.ndarray | None = None,
) -> ReplayResult:
    """Simulate the planned trips; simulated sensor pressures at the scored samples.

    Parameters
    ----------
    plan : ReplayPlan
        From :func:`plan_replay`.
    effects, parameters
        As :func:`sims.device.simulate` (default the hoist's ``[model] effects``).
    payload_kg : per-trip payload after loading [kg]; default inferred from the static
        pressure after loading (no friction correction: see :func:`replay_fitted`).
    payload_before_kg : per-trip payload before loading [kg]; only the first trip of a
        block uses it (later trips continue with the previous trip's payload).
    ramps_s : (m, 2) loading ramp start and end per trip [s after ``t_ref``]; default
        the plan's. A trip's simulation starts at its ramp start.

    Returns
    -------
    ReplayResult
        ``status="failed"`` with the reason when a trip's simulation failed (its and the
        block's later trips' pressures are NaN).
    """
    hoist = plan.hoist
    names = frozenset(hoist.model.effects if effects is None else effects)
    prm = {k: dict(v) for k, v in (parameters or {}).items()}
    if payload_kg is None:
        payload_kg = [
            payload_from_pressure(hoist, names, prm, tr.p_after_pa, tr.start_depth_m)
            for tr in plan.trips
        ]
    if payload_before_kg is None:
        payload_before_kg = [
            payload_from_pressure(hoist, names, prm, tr.p_before_pa, tr.start_depth_m)
            for tr in plan.trips
        ]
    if ramps_s is None:
        ramps_s = np.array([[tr.ramp_start_s, tr.ramp_end_s] for tr in plan.trips])
    ramps = np.asarray(ramps_s, dtype=float).reshape(-1, 2)
    pay = np.asarray(payload_kg, dtype=float)
    pay_before = np.asarray(payload_before_kg, dtype=float).copy()
    n = hoist.ropes_n
    out: list[np.ndarray] = []
    ramp_out: list[np.ndarray] = []
    failures: list[str] = []
    reasons: list[str] = []
    state = None
    broken = ""
    prev_end = -np.inf
    for k, tr in enumerate(plan.trips):
        if tr.first_in_block:
            state = None
            broken = ""
            prev_end = -np.inf
        else:
            pay_before[k] = pay[k - 1]
        nan_block = np.full((tr.time_s.size, n), np.nan)
        if broken:
            out.append(nan_block)
            ramp_out.append(np.full(tr.ramp_time_s.size, np.nan))
            reasons.append(f"not simulated: {broken}")
            continue
        start = float(max(ramps[k, 0], prev_end))
        ramp_end = float(max(ramps[k, 1], start + 1e-3))
        try:
            if tr.motion_knots is not None and tr.motion_knots[0][-1] > start:
                profile = profile_from_knots(
                    *tr.motion_knots,
                    start_s=start,
                    duration_s=max(tr.window_end_s - start, 1e-3),
                    payload_time_s=np.array([0.0, ramp_end - start]),
                    payload_kg=np.array([float(pay_before[k]), float(pay[k])]),
                    oil_temp_c=tr.oil_temp_c,
                    direction=tr.direction,
                )
            else:
                profile = _profile_of(
                    hoist,
                    tr.start_depth_m,
                    tr.end_depth_m,
                    tr.motion_start_s - start,
                    tr.window_end_s - start,
                    tr.max_speed_m_s,
                    tr.oil_temp_c,
                    (0.0, ramp_end - start),
                    float(pay_before[k]),
                    float(pay[k]),
                )
            res = simulate(
                hoist,
                profile,
                effects=names,
                parameters=prm,
                output_rate_hz=plan.score_rate_hz,
                dt_s=plan.dt_s,
                initial_state=state,
            )
        except ValueError as exc:
            failures.append(f"trip {tr.trip_id}: {exc}")
            reasons.append(f"simulation failed: {exc}")
            broken = f"trip {tr.trip_id} before it could not be simulated ({exc})"
            out.append(nan_block)
            ramp_out.append(np.full(tr.ramp_time_s.size, np.nan))
            continue
        reasons.append("")
        if not res.ok:
            failures.append(f"trip {tr.trip_id}: {res.message}")
            reasons[-1] = f"simulation failed: {res.message}"
            broken = f"trip {tr.trip_id} before it could not be simulated ({res.message})"
        state = res.final_state
        t_sim = start + res.frame["time_s"].to_numpy()
        prev_end = float(t_sim[-1]) if t_sim.size else prev_end
        if t_sim.size:
            sims = [res.frame[f"p_sensor{i}_pa"].to_numpy() for i in range(1, n + 1)]
            out.append(
                np.column_stack([np.interp(tr.time_s, t_sim, s, right=np.nan) for s in sims])
            )
            common = np.mean(sims, axis=0)
            ramp_out.append(np.interp(tr.ramp_time_s, t_sim, common, left=common[0], right=np.nan))
        else:
            out.append(nan_block)
            ramp_out.append(np.full(tr.ramp_time_s.size, np.nan))
    return ReplayResult(
        simulated=tuple(out),
        payload_kg=pay,
        payload_before_kg=pay_before,
        effects=names,
        parameters=prm,
        status="failed" if failures else "success",
        message="; ".join(failures),
        ramp_simulated=tuple(ramp_out),
        ramps_s=ramps,
        trip_messages=tuple(reasons),
    )


def _refine_ramp(
    tr: ReplayTrip, sim_ramp: np.ndarray, ramp: np.ndarray, dp_pay: float
) -> np.ndarray:
    """Gauss-Newton step on the loading ramp's start and end from the ramp residual.

    Shifting the ramp start by d0 and its end by d1 changes the simulated common-mode
    pressure by ``-dp/dt ((1 - u) d0 + u d1)`` (u: fraction of the ramp done); the
    payload correction ``dp_pay`` enters as ``u dp_pay``.
    """
    t = tr.ramp_time_s
    ok = np.isfinite(sim_ramp) & np.isfinite(tr.ramp_measured_pa)
    if ok.sum() < 6:
        return ramp
    dur = max(ramp[1] - ramp[0], 1e-3)
    u = np.clip((t - ramp[0]) / dur, 0.0, 1.0)
    slope = np.gradient(sim_ramp, t) if t.size > 1 else np.zeros_like(t)
    r = tr.ramp_measured_pa - sim_ramp - u * dp_pay
    jac = np.column_stack([-slope * (1.0 - u), -slope * u])[ok]
    if not np.all(np.isfinite(jac)) or np.linalg.norm(jac) == 0:
        return ramp
    step, *_ = np.linalg.lstsq(jac, r[ok], rcond=None)
    step = np.clip(step, -2.0, 2.0)
    new = ramp + step
    if new[1] <= new[0]:
        return ramp
    return new


def replay_fitted(
    plan: ReplayPlan,
    *,
    effects: Iterable[str] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    passes: int = 2,
    payload_kg: Sequence[float] | np.ndarray | None = None,
    ramps_s: np.ndarray | None = None,
) -> ReplayResult:
    """:func:`replay` with each trip's payload and loading-ramp timing fitted.

    The payload and the moment it was loaded are the log's free inputs. Pass 1 uses
    ``payload_kg`` (default: inferred from the static pressure) and the plan's ramps;
    each further pass adds ``mean common-mode residual x n A / g`` per trip to the
    payload (least squares for a common offset on every sensor), moves the ramp ends by a
    Gauss-Newton step on the common-mode residual over the ramp (the seal friction and
    the rope bounce delay the pressure behind the load, so the ramp seen in the pressure
    is not the load's) and re-simulates.
    """
    hoist = plan.hoist
    names = frozenset(hoist.model.effects if effects is None else effects)
    gain, _ = _sensor_calibration(hoist, names, parameters)
    scale = hoist.ropes_n * hoist.cylinders.bore_area_m2 / G_STANDARD / float(gain.mean())
    result = replay(
        plan, effects=names, parameters=parameters, payload_kg=payload_kg, ramps_s=ramps_s
    )
    for _ in range(passes - 1):
        if not any(np.isfinite(sim).any() for sim in result.simulated):
            break  # nothing simulated: nothing to fit (a failed trip leaves the others)
        dp = np.array(
            [float(np.nanmean(r)) if np.isfinite(r).any() else 0.0 for r in result.residuals(plan)]
        )
        pay = np.maximum(result.payload_kg + dp * scale, 0.0)
        ramps = np.array(
            [
                _refine_ramp(tr, sr, rp, d)
                for tr, sr, rp, d in zip(
                    plan.trips, result.ramp_simulated, result.ramps_s, dp, strict=True
                )
            ]
        )
        result = replay(
            plan,
            effects=names,
            parameters=parameters,
            payload_kg=pay,
            payload_before_kg=result.payload_before_kg,
            ramps_s=ramps,
        )
    return result


def replay_frame(plan: ReplayPlan, result: ReplayResult) -> pl.DataFrame:
    """Scored samples as a frame: ``time_utc, trip_id, phase, direction, depth_m,
    oil_temp_c, p{i}_pa`` (measured, NaN where masked) and ``p_sim{i}_pa``."""
    n = plan.n_sensors
    parts = []
    for tr, sim in zip(plan.trips, result.simulated, strict=True):
        cols: dict[str, Any] = {
            "time_utc": plan.time_utc(tr.time_s),
            "trip_id": np.full(tr.time_s.size, tr.trip_id, dtype=np.int64),
            "phase": tr.phase.astype(str),
            "direction": np.where(tr.phase == "standstill", "rest", tr.direction),
            "depth_m": tr.depth_m,
            "oil_temp_c": np.full(tr.time_s.size, tr.oil_temp_c),
        }
        for i in range(n):
            cols[f"p{i + 1}_pa"] = np.where(tr.valid[:, i], tr.measured_pa[:, i], np.nan)
            cols[f"p_sim{i + 1}_pa"] = sim[:, i]
        parts.append(pl.DataFrame(cols))
    return pl.concat(parts) if parts else pl.DataFrame()
