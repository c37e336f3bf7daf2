"""Simulation sanity check: do the hoist's measured trips agree with its model?

The nightly run (issue 7) calls :func:`sanity_check` after compensation. Per trip, the
measured sensor pressures are compared with the device simulation of the same trip
(:func:`sims.replay.replay_fitted`: motion, payload and oil temperature from the log,
the hoist's ``[model] effects``), and the RMS of measured minus simulated pressure is
set against the logger's pressure noise estimated from the data
(:func:`sims.replay.estimate_noise_sigma`). A trip passes when

.. math:: RMS(p_{meas} - p_{sim}) \\le k \\, \\sigma_{noise}

with ``k = threshold`` (default 1.5: a complete model leaves the noise, ~1.0-1.1 here;
an effect of the size of the noise doubles the variance). A failed check is recorded
and should trigger discovery (:mod:`pipelines.discover`) for the hoist.

Input: landed field samples (``FIELD_SAMPLES``) or rope tensions (``ROPE_TENSIONS``):
both carry ``time_utc``, ``p{i}_pa``, ``depth_m``, ``speed_m_s`` and ``oil_temp_c``.
``trip_id`` in the result is the trip's index in the record (the replay's
segmentation; the same rule as :func:`transforms.kinematics.with_trip_phases`: a trip is
a continuous motion).
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl

from schemas.hoist import HoistDescription
from schemas.tables import SANITY_CHECKS
from sims.replay import plan_replay, replay_fitted
from transforms.reconciliation import conform

__all__ = ["sanity_check"]


def sanity_check(
    samples: pl.DataFrame | pl.LazyFrame,
    hoist: HoistDescription,
    *,
    run_id: str,
    threshold: float = 1.5,
    max_trips: int = 200,
    dt_s: float = 2e-3,
    settle_s: float = 45.0,
    report_from: dt.datetime | None = None,
) -> pl.DataFrame:
    """Per-trip RMS gap between measured and simulated sensor pressure (``SANITY_CHECKS``).

    The first trip of each replay block starts from rest, with no friction stored in the
    seals, where the real seals carry what the previous trip left (hundreds of newtons:
    a few kPa of sensor pressure). It only loads the simulated state and is not
    reported; give samples from before the period (and ``report_from``) so that the
    period's first trip follows a replayed one.

    Parameters
    ----------
    samples : DataFrame or LazyFrame
        One hoist's samples (``time_utc``, ``p{i}_pa``, ``depth_m``, ``speed_m_s``,
        ``oil_temp_c``).
    hoist : HoistDescription
        The hoist and its model.
    run_id : str
        Written to every row.
    threshold : float
        Pass when the RMS gap is at most ``threshold`` x the estimated noise.
    max_trips : int
        Trips checked at most (spread over the record in blocks).
    dt_s, settle_s : float
        Replay integrator step [s] and standstill simulated after each stop [s].
    report_from : datetime, optional
        Trips that start moving before this time are replayed (state warm-up) but not
        reported.

    Returns
    -------
    polars.DataFrame
        ``SANITY_CHECKS`` rows; an empty frame when the record holds no trip.
    """
    if threshold <= 1.0:
        raise ValueError("threshold must exceed 1 (the noise alone gives 1)")
    frame = samples.collect() if isinstance(samples, pl.LazyFrame) else samples
    empty = conform(pl.DataFrame(), SANITY_CHECKS).clear()
    try:
        plan = plan_replay(frame, hoist, max_trips=max_trips, dt_s=dt_s, settle_s=settle_s)
    except ValueError as exc:
        if "no trip" in str(exc):
            return empty
        raise
    result = replay_fitted(plan, passes=3)
    sigma = plan.noise_sigma_pa
    rows = []
    for tr, res in zip(plan.trips, result.residuals(plan), strict=True):
        started = plan.t_ref + dt.timedelta(seconds=tr.motion_start_s)
        if tr.first_in_block or (report_from is not None and started < report_from):
            continue  # warm-up: the seals' friction state is being loaded
        finite = res[np.isfinite(res)]
        rms = float(np.sqrt(np.mean(finite**2))) if finite.size else float("nan")
        ok = bool(np.isfinite(rms) and rms <= threshold * sigma)
        if not finite.size:
            message = f"simulation failed: {result.message}"
        else:
            message = (
                f"{tr.direction} trip, oil {tr.oil_temp_c:.1f} degC: gap {rms / 1e3:.1f} kPa vs "
                f"noise {sigma / 1e3:.1f} kPa ({rms / sigma:.2f} x, limit {threshold:g} x)"
            )
        rows.append(
            {
                "run_id": run_id,
                "site": hoist.hoist.site,
                "hoist": hoist.hoist.name,
                "trip_id": tr.trip_id,
                "rms_gap_pa": rms,
                "noise_pa": sigma,
                "passed": ok,
                "message": message,
            }
        )
    return conform(pl.DataFrame(rows), SANITY_CHECKS) if rows else empty
