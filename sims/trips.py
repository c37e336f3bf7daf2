"""Hoist trip profiles: the input of the device simulation.

A :class:`TripProfile` is the conveyance's commanded motion as constant-acceleration
segments (depth, speed, acceleration piecewise; speed positive downwards, as in the
field logs), plus the payload as a piecewise-linear function of time and the oil
temperature. :func:`trip` builds one trip the way a Koepe winder runs it:

    rest -> accelerate -> run at max speed -> decelerate to creep speed -> creep over
    the creep distance -> stop (at the deceleration) -> rest

with the winder's ``[winder]`` limits (a short trip that never reaches full speed gets
a triangular profile). :func:`day_schedule` strings trips into a working day with
loading and unloading at the stops, and :func:`hold` is a conveyance at rest (load
changes only), for static checks. :func:`fit_cut_trip` completes a trip a record cuts
(logging starts or stops while the conveyance moves): the winder trip whose motion best
matches the logged encoder depth, with the unseen end (or start) depth fitted.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from schemas.hoist import HoistDescription

__all__ = ["CutTripFit", "TripProfile", "day_schedule", "fit_cut_trip", "hold", "trip"]


@dataclass(frozen=True)
class TripProfile:
    """Commanded conveyance motion, payload and oil temperature over one run.

    Attributes
    ----------
    segment_start_s : (k,) start time of each constant-acceleration segment [s]; the
        first is the profile start, they increase.
    segment_depth_m, segment_speed_m_s : (k,) depth [m] and speed [m/s, + down] at each
        segment start.
    segment_acceleration_m_s2 : (k,) acceleration in the segment [m/s2, + down].
    duration_s : end of the profile, measured from ``segment_start_s[0]`` [s].
    payload_time_s, payload_kg : knots of the piecewise-linear payload [s], [kg];
        constant before the first and after the last knot.
    oil_temp_c : oil temperature during the run [degC], None = the oil's reference.
    start_time_s : when the profile starts on the day's clock [s] (informational).
    direction : "down", "up" or "rest".
    """

    segment_start_s: np.ndarray
    segment_depth_m: np.ndarray
    segment_speed_m_s: np.ndarray
    segment_acceleration_m_s2: np.ndarray
    duration_s: float
    payload_time_s: np.ndarray
    payload_kg: np.ndarray
    oil_temp_c: float | None = None
    start_time_s: float = 0.0
    direction: str = "rest"

    def __post_init__(self) -> None:
        k = len(self.segment_start_s)
        for name in ("segment_depth_m", "segment_speed_m_s", "segment_acceleration_m_s2"):
            if len(getattr(self, name)) != k:
                raise ValueError(f"{name}: need {k} values, got {len(getattr(self, name))}")
        if k == 0 or np.any(np.diff(self.segment_start_s) <= 0):
            raise ValueError("segment_start_s: need at least one segment, strictly increasing")
        if len(self.payload_time_s) != len(self.payload_kg) or len(self.payload_kg) == 0:
            raise ValueError("payload_time_s and payload_kg: need equal, non-zero lengths")
        if np.any(np.diff(self.payload_time_s) < 0):
            raise ValueError("payload_time_s must not decrease")
        if not self.duration_s > 0:
            raise ValueError("duration_s must be positive")

    @property
    def t0_s(self) -> float:
        return float(self.segment_start_s[0])

    def _segment(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        idx = np.clip(np.searchsorted(self.segment_start_s, t, side="right") - 1, 0, None)
        return idx, np.maximum(t - self.segment_start_s[idx], 0.0)

    def depth(self, t_s: np.ndarray | float) -> np.ndarray:
        """Depth [m] at times ``t_s`` [s]."""
        i, tau = self._segment(np.asarray(t_s, dtype=float))
        return (
            self.segment_depth_m[i]
            + self.segment_speed_m_s[i] * tau
            + 0.5 * self.segment_acceleration_m_s2[i] * tau**2
        )

    def speed(self, t_s: np.ndarray | float) -> np.ndarray:
        """Speed [m/s, + down] at times ``t_s`` [s]."""
        i, tau = self._segment(np.asarray(t_s, dtype=float))
        return self.segment_speed_m_s[i] + self.segment_acceleration_m_s2[i] * tau

    def acceleration(self, t_s: np.ndarray | float) -> np.ndarray:
        """Acceleration [m/s2, + down] at times ``t_s`` [s]."""
        i, _ = self._segment(np.asarray(t_s, dtype=float))
        return self.segment_acceleration_m_s2[i].astype(float)

    def payload(self, t_s: np.ndarray | float) -> np.ndarray:
        """Payload [kg] at times ``t_s`` [s]."""
        return np.interp(np.asarray(t_s, dtype=float), self.payload_time_s, self.payload_kg)


def _build(
    phases: list[tuple[float, float]],
    depth0: float,
    *,
    t0: float,
    payload_time: list[float],
    payload_kg: list[float],
    oil_temp_c: float | None,
    start_time_s: float,
    direction: str,
) -> TripProfile:
    starts, depths, speeds, accs = [], [], [], []
    t, d, v = t0, depth0, 0.0
    for duration, acc in phases:
        if duration <= 1e-9:  # also float dust (a run of 1e-15 s): segments must advance
            continue
        starts.append(t)
        depths.append(d)
        speeds.append(v)
        accs.append(acc)
        d += v * duration + 0.5 * acc * duration**2
        v += acc * duration
        t += duration
    if abs(v) > 1e-9:
        raise AssertionError(f"trip does not end at rest (speed {v:g} m/s)")
    starts.append(t)  # final rest segment, exactly at rest
    depths.append(d)
    speeds.append(0.0)
    accs.append(0.0)
    return TripProfile(
        segment_start_s=np.array(starts),
        segment_depth_m=np.array(depths),
        segment_speed_m_s=np.array(speeds),
        segment_acceleration_m_s2=np.array(accs),
        duration_s=t - t0,
        payload_time_s=np.array(payload_time, dtype=float),
        payload_kg=np.array(payload_kg, dtype=float),
        oil_temp_c=oil_temp_c,
        start_time_s=start_time_s,
        direction=direction,
    )


def trip(
    hoist: HoistDescription,
    *,
    start_depth_m: float,
    end_depth_m: float,
    payload_kg: float = 0.0,
    rest_before_s: float = 2.0,
    rest_after_s: float = 2.0,
    max_speed_m_s: float | None = None,
    oil_temp_c: float | None = None,
    start_time_s: float = 0.0,
) -> TripProfile:
    """One trip from ``start_depth_m`` to ``end_depth_m`` with the hoist's winder limits.

    Phases: rest, accelerate (``winder.acceleration``), run, decelerate
    (``winder.deceleration``) to ``creep_speed``, creep over ``creep_distance``, stop at
    the deceleration, rest. The payload is constant. Times start at 0.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> p = trip(load_hoist(EXAMPLE_HOIST), start_depth_m=0.0, end_depth_m=620.0)
    >>> round(float(p.depth(p.duration_s)), 6), round(p.duration_s, 1)
    (620.0, 88.8)
    """
    w = hoist.winder
    for name, depth in (("start_depth_m", start_depth_m), ("end_depth_m", end_depth_m)):
        if not 0.0 <= depth <= hoist.shaft.depth_m:
            raise ValueError(
                f"{name}: {depth:g} m is outside the shaft (0..{hoist.shaft.depth_m:g} m)"
            )
    distance = abs(end_depth_m - start_depth_m)
    sign = 1.0 if end_depth_m >= start_depth_m else -1.0
    vmax = w.max_speed_m_s if max_speed_m_s is None else max_speed_m_s
    acc, dec, vc = w.acceleration_m_s2, w.deceleration_m_s2, w.creep_speed_m_s
    creep = min(w.creep_distance_m, distance)
    stop_dist = vc * vc / (2.0 * dec)
    main = distance - creep - stop_dist
    phases: list[tuple[float, float]] = [(rest_before_s, 0.0)]
    if distance == 0.0:
        pass
    elif main <= 0.0:  # too short for creep: accelerate to the creep-limited triangle
        vpk = math.sqrt(distance * 2.0 * acc * dec / (acc + dec))
        phases += [(vpk / acc, sign * acc), (vpk / dec, -sign * dec)]
    else:
        # accelerate 0 -> v, run, decelerate v -> vc; v limited by the distance `main`
        # (the creep speed is reached by the end of `main`).
        v_top = math.sqrt((2.0 * acc * dec * main + acc * vc * vc) / (acc + dec))
        v = min(vmax, max(v_top, vc))
        d_acc = v * v / (2.0 * acc)
        d_dec = (v * v - vc * vc) / (2.0 * dec)
        run = max(main - d_acc - d_dec, 0.0)
        phases += [
            (v / acc, sign * acc),
            (run / v, 0.0),
            ((v - vc) / dec, -sign * dec),
            (creep / vc, 0.0),
            (vc / dec, -sign * dec),
        ]
    phases.append((rest_after_s, 0.0))
    direction = "rest" if distance == 0 else ("down" if sign > 0 else "up")
    return _build(
        phases,
        start_depth_m,
        t0=0.0,
        payload_time=[0.0],
        payload_kg=[payload_kg],
        oil_temp_c=oil_temp_c,
        start_time_s=start_time_s,
        direction=direction,
    )


def hold(
    *,
    depth_m: float,
    duration_s: float,
    payload_time_s: list[float] | np.ndarray = (0.0,),
    payload_kg: list[float] | np.ndarray = (0.0,),
    oil_temp_c: float | None = None,
) -> TripProfile:
    """The conveyance at rest at ``depth_m`` with a piecewise-linear payload (loading)."""
    return TripProfile(
        segment_start_s=np.array([0.0]),
        segment_depth_m=np.array([float(depth_m)]),
        segment_speed_m_s=np.array([0.0]),
        segment_acceleration_m_s2=np.array([0.0]),
        duration_s=float(duration_s),
        payload_time_s=np.asarray(payload_time_s, dtype=float),
        payload_kg=np.asarray(payload_kg, dtype=float),
        oil_temp_c=oil_temp_c,
        direction="rest",
    )


def day_schedule(
    hoist: HoistDescription,
    *,
    round_trips: int = 20,
    start_time_s: float = 6 * 3600.0,
    dwell_s: float = 60.0,
    loading_s: float = 20.0,
    payload_kg: float | None = None,
    loaded_at: str = "bottom",
    oil_temp_c: float | tuple[float, float] | None = None,
) -> list[TripProfile]:
    """A working day: ``round_trips`` x (down trip, up trip) between pithead and bottom.

    Each trip profile starts with the conveyance at rest; the load change at a stop is
    part of the trip that leaves it (``loading_s`` ramp at the start). With
    ``loaded_at="bottom"`` (ore hoisting) the up trip leaves loaded and the down trip
    empty; ``"pithead"`` the reverse. ``oil_temp_c`` is one value or a (morning,
    afternoon) pair warmed linearly over the day. ``start_time_s`` of each profile is its
    start on the day's clock.
    """
    if round_trips < 1:
        raise ValueError("round_trips must be at least 1")
    if loaded_at not in ("bottom", "pithead"):
        raise ValueError("loaded_at must be 'bottom' or 'pithead'")
    payload = hoist.conveyance.rated_payload_kg if payload_kg is None else payload_kg
    top = hoist.shaft.positions_m.get("pithead", 0.0)
    bottom = hoist.shaft.positions_m.get("bottom", hoist.shaft.depth_m)
    trips_out: list[TripProfile] = []
    clock = start_time_s
    n = 2 * round_trips
    for k in range(n):
        down = k % 2 == 0
        loaded = (not down) if loaded_at == "bottom" else down
        before = 0.0 if loaded else payload  # the load at the previous stop
        after = payload if loaded else 0.0
        if isinstance(oil_temp_c, tuple):
            temp = oil_temp_c[0] + (oil_temp_c[1] - oil_temp_c[0]) * k / max(n - 1, 1)
        else:
            temp = oil_temp_c
        base = trip(
            hoist,
            start_depth_m=top if down else bottom,
            end_depth_m=bottom if down else top,
            rest_before_s=loading_s + 5.0,
            rest_after_s=dwell_s,
            oil_temp_c=temp,
            start_time_s=clock,
        )
        profile = TripProfile(
            segment_start_s=base.segment_start_s,
            segment_depth_m=base.segment_depth_m,
            segment_speed_m_s=base.segment_speed_m_s,
            segment_acceleration_m_s2=base.segment_acceleration_m_s2,
            duration_s=base.duration_s,
            payload_time_s=np.array([0.0, loading_s]),
            payload_kg=np.array([before, after]),
            oil_temp_c=temp,
            start_time_s=clock,
            direction=base.direction,
        )
        trips_out.append(profile)
        clock += profile.duration_s
    return trips_out


# ---------------------------------------------------------------------------------------
# trips a record cuts
# ---------------------------------------------------------------------------------------
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
    # direction of travel, and the logged depth farthest from the known end
    far = float(d[np.argmax(np.abs(d - anchor))])
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
