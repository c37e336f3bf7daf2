"""Trips a record cuts: the winder trip that best explains the logged part.

:func:`fit_cut_trip` (public through :mod:`sims.trips`) completes a trip whose record
starts or stops while the conveyance moves, fitting the unseen end (or start) depth and,
among given candidates, the top speed, to the logged encoder depth.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from schemas.hoist import HoistDescription
from sims.trip_profile import TripProfile, trip


@dataclass(frozen=True)
class CutTripFit:
    """The winder trip that best explains the logged part of a cut trip.

    ``motion_start_s`` and ``motion_end_s`` are on the caller's clock; ``max_speed_m_s``
    is None for the winder's own full speed; ``rms_m`` is the RMS difference between the
    profile's depth and the logged depth over the logged samples [m].
    """

    start_depth_m: float
    end_depth_m: float
    motion_start_s: float
    motion_end_s: float
    max_speed_m_s: float | None
    rms_m: float


def _motion_only(
    hoist: HoistDescription, start_depth_m: float, end_depth_m: float, vmax: float | None
) -> TripProfile:
    return trip(
        hoist,
        start_depth_m=start_depth_m,
        end_depth_m=end_depth_m,
        rest_before_s=0.0,
        rest_after_s=0.0,
        max_speed_m_s=vmax,
    )


def fit_cut_trip(
    hoist: HoistDescription,
    time_s: np.ndarray,
    depth_m: np.ndarray,
    *,
    start_depth_m: float | None = None,
    motion_start_s: float | None = None,
    end_depth_m: float | None = None,
    motion_end_s: float | None = None,
    max_speeds_m_s: Sequence[float | None] = (None,),
) -> CutTripFit:
    """Complete a trip that a record cuts, from its logged encoder depth.

    A record that ends while the conveyance moves knows where and when the trip started
    (``start_depth_m``, ``motion_start_s``) but not where it stops; one that starts while
    it moves knows the stop (``end_depth_m``, ``motion_end_s``) but not the start. Give
    one pair. The unknown depth is searched between the logged depth farthest along the
    trip and the end of the shaft in the direction of travel (the shaft's named
    positions among the candidates), for each of ``max_speeds_m_s`` (None: the winder's
    full speed), as the :func:`trip` profile whose depth is closest (least squares) to
    the logged ``depth_m`` at ``time_s``. Where the logged part does not decide (a record
    cut while the conveyance still runs at full speed: every far enough stop fits the
    same), the nearest named position, then the winder's full speed, win ties within
    2 cm.

    Raises
    ------
    ValueError
        Not exactly one known end, fewer than 3 logged depths, or no net motion in them.
    """
    known_start = start_depth_m is not None and motion_start_s is not None
    known_end = end_depth_m is not None and motion_end_s is not None
    if known_start == known_end:
        raise ValueError("fit_cut_trip: give the start (depth, time) or the end, not both")
    t = np.asarray(time_s, dtype=float)
    d = np.asarray(depth_m, dtype=float)
    ok = np.isfinite(t) & np.isfinite(d)
    if ok.sum() < 3:
        raise ValueError("no encoder depth logged in the trip's recorded part")
    t, d = t[ok], d[ok]
    shaft = hoist.shaft.depth_m
    anchor = float(start_depth_m if known_start else end_depth_m)  # type: ignore[arg-type]
    if not 0.0 <= anchor <= shaft:
        raise ValueError(f"trip depth {anchor:g} m is outside the shaft (0..{shaft:g} m)")
    named, grid = _search_grid(hoist, d, anchor)

    def profile_of(other: float, vmax: float | None) -> tuple[TripProfile, float]:
        if known_start:
            prof = _motion_only(hoist, anchor, other, vmax)
            return prof, float(motion_start_s)  # type: ignore[arg-type]
        prof = _motion_only(hoist, other, anchor, vmax)
        return prof, float(motion_end_s) - prof.duration_s  # type: ignore[operator]

    def rms(other: float, vmax: float | None) -> float:
        prof, t_m = profile_of(other, vmax)
        return float(np.sqrt(np.mean((prof.depth(t - t_m) - d) ** 2)))

    best: tuple[float, float, float | None] | None = None  # (rms, depth, vmax)
    for vmax in max_speeds_m_s:
        cand, score = _best_depth(rms, grid, named, anchor, vmax)
        if best is None or score < best[0] - 0.02:
            best = (score, cand, vmax)
    assert best is not None
    score, other, vmax = best
    prof, t_m = profile_of(other, vmax)
    d0, d1 = (anchor, other) if known_start else (other, anchor)
    return CutTripFit(
        start_depth_m=d0,
        end_depth_m=d1,
        motion_start_s=t_m,
        motion_end_s=t_m + prof.duration_s,
        max_speed_m_s=vmax,
        rms_m=score,
    )


def _search_grid(
    hoist: HoistDescription, d: np.ndarray, anchor: float
) -> tuple[list[float], np.ndarray]:
    """The shaft's named positions and the candidate depths of the unknown end: between
    the logged depth farthest from ``anchor`` and the shaft's end beyond it."""
    shaft = hoist.shaft.depth_m
    # direction of travel, and the logged depth farthest from the known end
    # (clipped to the shaft: an encoder reading -1 mm at the pithead had made every
    # candidate above it, and the trip was refused as outside the shaft)
    far = float(np.clip(d[np.argmax(np.abs(d - anchor))], 0.0, shaft))
    if abs(far - anchor) < 0.1:
        raise ValueError("no net motion in the trip's recorded part")
    sign = 1.0 if far > anchor else -1.0  # + : the unknown end lies deeper than `anchor`
    lo, hi = (far, shaft) if sign > 0 else (0.0, far)
    lo, hi = max(lo, 0.0), min(hi, shaft)
    named = [p for p in hoist.shaft.positions_m.values() if lo <= p <= hi]
    grid = np.unique(np.concatenate([np.linspace(lo, hi, 49), named, [lo, hi]]))
    grid = grid[np.abs(grid - anchor) >= 0.1]
    if grid.size == 0:
        raise ValueError("no net motion in the trip's recorded part")
    return named, grid


def _best_depth(
    rms: Callable[[float, float | None], float],
    grid: np.ndarray,
    named: list[float],
    anchor: float,
    vmax: float | None,
) -> tuple[float, float]:
    """``(depth, rms)`` of the best unknown end at top speed ``vmax``: the grid's best,
    refined between its neighbours, unless a named position fits within 2 cm."""
    scores = np.array([rms(float(g), vmax) for g in grid])
    j = int(np.argmin(scores))
    a, b = float(grid[max(j - 1, 0)]), float(grid[min(j + 1, grid.size - 1)])
    cand, score = float(grid[j]), float(scores[j])
    if b > a:
        sol = optimize.minimize_scalar(
            lambda x, v=vmax: rms(x, v), bounds=(a, b), method="bounded",
            options={"xatol": 1e-3},
        )  # fmt: skip
        if sol.success and float(sol.fun) < score:
            cand, score = float(sol.x), float(sol.fun)
    # a named position that fits as well wins (the logged part may not decide)
    for p in sorted(named, key=lambda p: abs(p - cand)):
        if abs(p - anchor) >= 0.1 and rms(p, vmax) <= score + 0.02:
            cand, score = p, min(score, rms(p, vmax))
            break
    return cand, score
