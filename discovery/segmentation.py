"""Reading a hoist's record for a replay: trips, standstills, loading ramps, noise.

The pieces :func:`discovery.planning.plan_replay` segments a landed sample frame with
(times in s after the record's first sample):

* the trips, by the pipeline's trip rule (:mod:`physics.trip_rule`), those moving at
  least 3 s replayed;
* medians of a signal over a time span, or over the first / last seconds logged in it;
* the loading ramp in a standstill: a change of the common-mode pressure located from
  its 10-90 % crossing and refined by a plateau-ramp-plateau least-squares fit;
* the logger's pressure noise from second differences at standstill (robust MAD; white
  noise of variance s^2 gives second differences of variance 6 s^2);
* which trips a long record is analysed on (blocks of consecutive trips spread evenly);
* a trip the record cuts, completed by the winder profile fitted to its logged depth
  (:func:`sims.trips.fit_cut_trip`).

Its names are the ``discovery`` package's own (the planning's), not an API outside it;
a leading underscore marks what only this module uses.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage, optimize

from physics.conveyance import conveyance_speed
from physics.trip_rule import segment_ids, trip_label_codes
from physics.white_noise import difference_noise_sigma
from schemas.hoist import HoistDescription, Winder
from sims.trips import TripProfile, fit_cut_trip

__all__ = [
    "CUT_WORDS",
    "chosen_trips",
    "complete_cut_trip",
    "estimate_noise_sigma",
    "loading_ramp",
    "median_in",
    "motion_times",
    "plateau_median",
    "profile_phases",
    "ramp_samples",
    "record_trips",
    "scored_samples",
    "time_span",
]

#: A trip moving less than this is numbered but not replayed [s].
_MIN_MOTION_S = 3.0


def estimate_noise_sigma(pressures: np.ndarray, moving: np.ndarray) -> float:
    """Pressure noise standard deviation [Pa] from second differences at standstill.

    For white noise of standard deviation s, ``p[k+1] - 2 p[k] + p[k-1]`` has standard
    deviation ``sqrt(6) s``; a slow signal (loading ramp, held state) contributes almost
    nothing. Robust: :func:`physics.white_noise.difference_noise_sigma` of every
    sensor's standstill triplets, spikes and transients do not move it.

    >>> rng = np.random.default_rng(0)
    >>> p = 5e6 + np.linspace(0, 1e5, 20000)[:, None] + rng.normal(0, 5e3, (20000, 4))
    >>> round(estimate_noise_sigma(p, np.zeros(20000, bool)) / 5e3, 1)
    1.0
    """
    p = np.asarray(pressures, dtype=float)
    if p.ndim == 1:
        p = p[:, None]
    still = ~np.asarray(moving, dtype=bool)
    parts = [_held_second_differences(p[:, j], still) for j in range(p.shape[1])]
    d2 = np.concatenate(parts) if parts else np.empty(0)
    if d2.size == 0:
        return float("nan")
    sigma = difference_noise_sigma(d2, 2)  # 0 where their MAD is 0 (d2 all finite)
    if sigma == 0.0:  # a quantisation coarse against the noise: most differences 0
        return float(np.sqrt(np.mean(d2**2) / 6.0))
    return sigma


def _held_second_differences(p: np.ndarray, still: np.ndarray) -> np.ndarray:
    """One sensor's finite second differences at standstill (all its samples when fewer
    than 20 triplets stand still). A sensor that updates slower than the logger logs
    (a 10 Hz transducer on a 50 Hz logger: each reading repeated about as often, most
    differences exactly 0, whose MAD is 0) is differenced over its readings, each run of
    repeats taken once. A reading quantised coarsely against its noise repeats too, but
    irregularly: its differences are kept (:func:`estimate_noise_sigma` then takes their
    RMS, the noise with the quantisation's q^2 / 12).

    >>> held = np.repeat(np.random.default_rng(1).normal(0, 5e3, 4000), 5)
    >>> d2 = _held_second_differences(held, np.ones(held.size, bool))
    >>> round(difference_noise_sigma(d2, 2) / 5e3, 1)
    1.0
    >>> float(np.abs(_held_second_differences(np.full(100, 5e6), np.ones(100, bool))).max())
    0.0
    """
    d1 = np.diff(p)
    changes = np.flatnonzero(np.isfinite(d1) & (d1 != 0.0))
    runs = np.diff(changes)  # samples from one change of reading to the next
    if runs.size > 10 and np.median(runs) >= 2:
        # held readings repeat a regular number of times (the rates' ratio); a coarse
        # quantisation's repeats are irregular (estimate_noise_sigma takes those)
        typical = np.bincount(runs).argmax()
        if np.mean(np.abs(runs - typical) <= 1) >= 0.8:
            keep = np.r_[True, d1 != 0.0]
            p, still = p[keep], still[keep]
    ok = still[2:] & still[1:-1] & still[:-2]
    if ok.sum() < 20:
        ok = np.ones(max(p.size - 2, 0), dtype=bool)
    d2 = (p[2:] - 2.0 * p[1:-1] + p[:-2])[ok]
    return d2[np.isfinite(d2)]


def record_trips(
    t: np.ndarray, speed: np.ndarray, depth: np.ndarray, hoist: HoistDescription
) -> tuple[list[tuple[int, int]], list[int], list[tuple[int, int, int]]]:
    """The record's trips by the pipeline's trip rule (:mod:`physics.trip_rule`: a trip
    is a run of samples with ``|v| >= 0.02 m/s``, a short logger gap bridged), numbered
    as the compensation numbers them from the record's first sample; where the speed is
    missing it is the conveyance's speed from its depth
    (:func:`physics.conveyance.conveyance_speed`, as the compensation reads it).

    Returns the (first, last) sample of each trip moving at least :data:`_MIN_MOTION_S`
    (the ones replayed), their trip ids, and (first, last, trip id) of the shorter ones
    (a jog: numbered, not replayed).
    """
    segment = segment_ids(t)
    steps = np.diff(t)
    speed = conveyance_speed(
        t, speed, depth, segment, dt_s=float(np.median(steps)) if steps.size else 1.0
    )  # where the log lacks it: an isolated hole interpolated, else the depth's derivative
    speed0 = np.nan_to_num(speed)
    _, _, trip = trip_label_codes(t, speed0, np.zeros(t.size), segment, depth, hoist)
    moving = np.flatnonzero(trip >= 0)
    if moving.size == 0:
        return [], [], []
    starts = np.concatenate([[0], np.flatnonzero(np.diff(trip[moving])) + 1])
    ends = np.concatenate([starts[1:] - 1, [moving.size - 1]])
    motions: list[tuple[int, int]] = []
    ids: list[int] = []
    short: list[tuple[int, int, int]] = []
    for first, last in zip(moving[starts], moving[ends], strict=True):
        if t[last] - t[first] >= _MIN_MOTION_S:
            motions.append((int(first), int(last)))
            ids.append(int(trip[first]))
        else:
            short.append((int(first), int(last), int(trip[first])))
    return motions, ids, short


def median_in(t: np.ndarray, values: np.ndarray, lo: float, hi: float) -> float:
    part = values[time_span(t, lo, hi)]
    part = part[np.isfinite(part)]
    return float(np.median(part)) if part.size else float("nan")


def plateau_median(
    t: np.ndarray, values: np.ndarray, lo: float, hi: float, width_s: float, *, from_start: bool
) -> float:
    """Median of ``values`` over the first (``from_start``) or last ``width_s`` seconds of
    logged samples within [lo, hi]: a logger gap at the edge of the interval shifts the
    window to the nearest samples instead of leaving it empty."""
    part = time_span(t, lo, hi)
    if part.stop <= part.start:
        return float("nan")
    if from_start:
        first = float(t[part.start])
        return median_in(t, values, first, min(first + width_s, hi))
    last = float(t[part.stop - 1])
    return median_in(t, values, max(last - width_s, lo), last)


def time_span(t: np.ndarray, lo: float, hi: float) -> slice:
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


def chosen_trips(count: int, max_trips: int, blocks: int) -> list[list[int]]:
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


#: How a trip the record cuts is named in notes and reasons.
CUT_WORDS = {
    "start": "the record starts (or resumes after a logger gap) during this trip",
    "end": "the record ends (or breaks off in a logger gap) during it",
}


def complete_cut_trip(
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


def loading_ramp(
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
    p_pre = plateau_median(t, pcs, s_lo, s_hi, 2.0, from_start=True)
    p_post = plateau_median(t, pcs, s_lo, s_hi, 3.0, from_start=False)
    change = p_post - p_pre
    in_s = time_span(t, s_lo, s_hi)
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


def motion_times(
    t: np.ndarray, speed: np.ndarray, w: Winder, a_i: int, b_i: int
) -> tuple[float, float, float | None]:
    """(motion start, motion end, top speed or None for the winder's) of one motion:
    least squares on the logged speed of its acceleration and deceleration."""
    sp = time_span(t, t[a_i] - 1.0, t[a_i] + 4.0)
    tw, vw = t[sp], np.abs(speed[sp])
    sel = (vw > 0.1) & (vw < 0.8 * w.acceleration_m_s2 * 4.0)
    t_m = (
        float(np.median(tw[sel] - vw[sel] / w.acceleration_m_s2))
        if sel.sum() >= 3
        else float(t[a_i])
    )
    sp = time_span(t, t[b_i] - 0.6, t[b_i] + 0.2)
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
    return t_m, t_e, vmax_arg


def scored_samples(
    t: np.ndarray,
    p: np.ndarray,
    sigma: float,
    lo: float,
    win_end: float,
    score_rate_hz: float,
    cut: str,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(indices, measured pressures, valid) of the samples scored in ``[lo, win_end]``,
    every 1/``score_rate_hz`` s, spikes masked; none valid for a trip cut at its start."""
    sp = time_span(t, lo, win_end)
    idx = np.arange(sp.start, sp.stop)
    if idx.size:
        bins = np.floor((t[idx] - lo) * score_rate_hz).astype(np.int64)
        idx = idx[np.concatenate([[True], bins[1:] != bins[:-1]])]
    meas = p[idx]
    valid = np.isfinite(meas)
    if idx.size >= 5:
        med = ndimage.median_filter(np.nan_to_num(meas), size=(5, 1), mode="nearest")
        valid &= np.abs(meas - med) <= max(10.0 * sigma, 2e4)
    if cut == "start":
        # simulated from rest with a fitted start: it loads the seals' state for
        # the trips after it, its own pressures are not compared
        valid[:] = False
    return idx, meas, valid


def ramp_samples(
    t: np.ndarray, r0: float, r1: float, t_m: float, score_rate_hz: float
) -> np.ndarray:
    """Indices of the samples around the loading ramp, every 1/``score_rate_hz`` s."""
    sp = time_span(t, r0 - 1.0, min(r1 + 3.0, t_m - 0.3))
    ridx = np.arange(sp.start, sp.stop)
    if ridx.size:
        rb = np.floor((t[ridx] - t[ridx[0]]) * score_rate_hz).astype(np.int64)
        ridx = ridx[np.concatenate([[True], rb[1:] != rb[:-1]])]
    return ridx


def profile_phases(driven: TripProfile, tau: np.ndarray, creep_speed_m_s: float) -> np.ndarray:
    """Phase of the motion the simulation follows at ``tau`` [s after its start]
    (|a| > 0.05 m/s2: above the logged speed's 1 mm/s steps over a 0.1 s knot)."""
    spd = driven.speed(tau)
    acc = driven.acceleration(tau) * np.sign(spd)
    return np.select(
        [
            np.abs(spd) < 0.01,
            acc > 0.05,
            acc < -0.05,
            np.abs(spd) <= 1.01 * creep_speed_m_s,
        ],
        ["standstill", "accelerate", "decelerate", "creep"],
        default="run",
    )
