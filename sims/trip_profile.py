"""A trip profile and the winder's trip: the device simulation's input (see :mod:`sims.trips`).

:class:`TripProfile` (constant-acceleration segments, piecewise-linear payload, oil
temperature), :func:`trip` (one Koepe winder trip within the ``[winder]`` limits) and
:func:`hold` (the conveyance at rest). Public through :mod:`sims.trips`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from schemas.hoist import HoistDescription


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
