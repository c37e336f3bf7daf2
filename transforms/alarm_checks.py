"""The alarm rules' checks: each family of rules evaluated on the prepared samples.

:func:`rope_alarms` (imbalance, slack and tight rope), :func:`load_alarms` (overload,
underload and the reconciliation residual at rest) and :func:`sensor_alarms` (flat line, stuck,
out of range, dropout, disagreement at rest) return the event rows of their rules;
:func:`transforms.alarms.evaluate_alarms` prepares the samples and calls them. The
thresholds are :mod:`transforms.alarm_rules`'s, the debounce :mod:`transforms.alarm_events`'.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from schemas.hoist import HoistDescription
from schemas.tables import ROPES
from transforms.alarm_events import (
    EventContext,
    column,
    debounced,
    event_rows,
    flatline_runs,
    frozen_runs,
    merge_events,
    runs,
    threshold_events,
)
from transforms.alarm_rules import STANDSTILL_SPEED_M_S, RuleThresholds
from transforms.compensation_record import departure_from_median

__all__ = ["LOGGED_PRESSURE", "load_alarms", "pressures_pa", "rope_alarms", "sensor_alarms"]


#: The sensor rules' column of each sensor's logged pressure (as ingest landed it, not
#: calibrated, despiked or low-passed): a flat line repeats the logged value, which no
#: filtered value does, and a reading outside the sensor's scale is the logged one.
LOGGED_PRESSURE = "logged_p{i}_pa"


def pressures_pa(
    frame: pl.DataFrame, hoist: HoistDescription, *, calibrate: bool = False
) -> list[np.ndarray]:
    """Sensor pressure per rope: the logged ``logged_p{i}_pa`` where the frame has it
    (:data:`LOGGED_PRESSURE`; with ``calibrate``, the sensor's calibration applied),
    else the calibrated ``p{i}_pa``, else raw tension / bore area."""
    area = hoist.cylinders.bore_area_m2
    sensors = {sensor.cylinder: sensor for sensor in hoist.sensors}
    out = []
    for i in ROPES:
        logged = LOGGED_PRESSURE.format(i=i)
        if logged in frame.columns:
            p = column(frame, logged)
            if calibrate and i in sensors:
                p = sensors[i].calibrated(p)
        else:
            p = column(frame, f"p{i}_pa")
        if np.all(np.isnan(p)):
            p = column(frame, f"tension_raw{i}_n") / area
        out.append(p)
    return out


def rope_alarms(
    ctx: EventContext,
    frame: pl.DataFrame,
    hoist: HoistDescription,
    thresholds: RuleThresholds,
    common: dict[str, float],
) -> list[dict[str, object]]:
    """Imbalance, slack and tight rope events of each rope."""
    alarms, t_s, rows = hoist.alarms, ctx.t_s, []
    tensions = [column(frame, f"tension{i}_n") for i in ROPES]
    mean = np.mean(np.vstack(tensions), axis=0)
    # imbalance is judged only while the ropes carry at least the slack threshold on
    # average (a hoist off its ropes has no meaningful balance); peak value is signed
    for i, tension in zip(ROPES, tensions, strict=True):
        with np.errstate(invalid="ignore", divide="ignore"):
            deviation = np.where(mean > thresholds.slack_n, (tension - mean) / mean, np.nan)
        s, e = threshold_events(
            t_s, np.abs(deviation), thresholds.imbalance_fraction, above=True, **common
        )
        rows += event_rows(
            ctx, "rope_imbalance", i, s, e, peak_of=np.abs(deviation), peak_max=True,
            report=deviation, threshold=thresholds.imbalance_fraction,
            message=f"rope {i} tension differs from the mean of the ropes by more than "
            f"{thresholds.imbalance_fraction:.0%}",
        )  # fmt: skip
        s, e = threshold_events(t_s, tension, thresholds.slack_n, above=False, **common)
        rows += event_rows(
            ctx, "slack_rope", i, s, e, peak_of=tension, peak_max=False,
            threshold=thresholds.slack_n,
            message=f"rope {i} tension below {thresholds.slack_n / 1e3:.1f} kN "
            f"({alarms.slack_fraction_of_empty:.0%} of the empty conveyance's per-rope weight)",
        )  # fmt: skip
        s, e = threshold_events(t_s, tension, thresholds.tight_n, above=True, **common)
        rows += event_rows(
            ctx, "tight_rope", i, s, e, peak_of=tension, peak_max=True,
            threshold=thresholds.tight_n,
            message=f"rope {i} tension above {thresholds.tight_n / 1e3:.1f} kN "
            f"(max static load + {alarms.tight_fraction_of_breaking:.0%} of breaking strength)",
        )  # fmt: skip
    return rows


def load_alarms(
    ctx: EventContext, frame: pl.DataFrame, thresholds: RuleThresholds, common: dict[str, float]
) -> list[dict[str, object]]:
    """Overload and underload (static-equivalent load) and reconciliation-residual (at
    rest) events."""
    t_s = ctx.t_s
    static = column(frame, "_static_load_n")
    tol = thresholds.overload_tolerance_fraction
    overload_threshold = column(frame, "_rated_load_n") * (1.0 + tol)
    s, e = threshold_events(
        t_s, static, overload_threshold, above=True, **_band_of_margin(common, tol, above=True)
    )
    rows = event_rows(
        ctx, "overload", None, s, e, peak_of=static, peak_max=True,
        threshold=overload_threshold,
        message="static-equivalent load above (conveyance + rated payload + tail rope) g "
        f"+ {tol:.0%}",
    )  # fmt: skip
    underload_threshold = column(frame, "_empty_load_n") * (1.0 - tol)
    s, e = threshold_events(
        t_s, static, underload_threshold, above=False, **_band_of_margin(common, tol, above=False)
    )
    rows += event_rows(
        ctx, "underload", None, s, e, peak_of=static, peak_max=False,
        threshold=underload_threshold,
        message=f"static-equivalent load below the empty conveyance with its tail rope - {tol:.0%}"
        ": resting on something, or the description's masses or the sensors off",
    )  # fmt: skip
    speed = column(frame, "speed_m_s")
    expected = column(frame, "_expected_n")
    with np.errstate(invalid="ignore", divide="ignore"):
        residual = np.abs(column(frame, "load_n") / expected - 1.0)
        residual[~(np.abs(speed) < STANDSTILL_SPEED_M_S)] = np.nan
    tol = thresholds.reconciliation_tolerance_fraction
    s, e = threshold_events(t_s, residual, tol, above=True, **common)
    return rows + event_rows(
        ctx, "reconciliation_residual", None, s, e, peak_of=residual, peak_max=True,
        threshold=tol,
        message=f"load at standstill differs from the expected load by more than {tol:.0%}",
    )  # fmt: skip


def _band_of_margin(common: dict[str, float], tol: float, *, above: bool) -> dict[str, float]:
    """The debounce settings ``common`` for a load rule whose threshold is (1 +- ``tol``)
    x a reference load: its hysteresis band the ``hysteresis_fraction`` of the margin
    (tol x the reference), not of the threshold (session 66). A band of 5 % of the
    threshold held an overload alarm through a trip at 98 % of the rated load, and an
    underload at the empty load itself, 3 % above its threshold, until a payload came on.

    Below an empty load of 100 kN the band is 5 % of its 3 kN margin:

    >>> band = _band_of_margin({"hysteresis_fraction": 0.05}, 0.03, above=False)
    >>> round(band["hysteresis_fraction"] * 0.97 * 100e3, 6)
    150.0
    """
    scale = tol / (1.0 + tol) if above else tol / (1.0 - tol)
    return {**common, "hysteresis_fraction": common["hysteresis_fraction"] * scale}


def dropout_gap_s(dropout_duration_s: float, sample_step_s: float) -> float:
    """The spacing of the samples [s] beyond which ``sensor_dropout`` names a gap: the
    hoist's ``dropout_duration``, and more than one and a half of the logger's steps, so
    that a slow logger's own step, which jitters past it, is not one (a 1 Hz record's
    1.001 s steps raised 26 425 alarms in 72 h against a duration of 1 s; its one
    sample missing, a 2 s spacing, is named).

    >>> dropout_gap_s(1.0, 0.02), dropout_gap_s(1.0, 1.0)
    (1.0, 1.5)
    """
    return max(dropout_duration_s, 1.5 * sample_step_s)


def sensor_alarms(
    ctx: EventContext,
    frame: pl.DataFrame,
    hoist: HoistDescription,
    thresholds: RuleThresholds,
    *,
    merge_gap_s: float,
    dt_s: float,
) -> list[dict[str, object]]:
    """Flat-line, stuck, out-of-range, dropout and disagreement rules (the module
    docstring of :mod:`transforms.alarm_rules`), on the logged pressures where the
    frame has them (:func:`pressures_pa`)."""
    alarms = hoist.alarms
    t_s = ctx.t_s
    rows: list[dict[str, object]] = []
    pressures = pressures_pa(frame, hoist)
    depth = column(frame, "depth_m")
    flat = flatline_runs(pressures, t_s, alarms.flatline_duration_s)
    gap_s = dropout_gap_s(alarms.dropout_duration_s, dt_s)

    for k, i in enumerate(ROPES):
        s, e = merge_events(t_s, *flat[k], merge_gap_s)
        rows += event_rows(
            ctx, "sensor_flatline", i, s, e, peak_of=None, peak_max=True,
            peak_values=t_s[e] - t_s[s], threshold=alarms.flatline_duration_s,
            message=f"pressure sensor {i} repeats one value while the others move",
        )  # fmt: skip

        p = pressures[k]
        full_scale = thresholds.full_scale_pa[k]
        with np.errstate(invalid="ignore"):
            out = (p < 0.0) | (p > full_scale)
        s, e = debounced(
            t_s, out, out, min_duration_s=alarms.min_duration_s, merge_gap_s=merge_gap_s, dt_s=dt_s
        )
        rows += event_rows(
            ctx, "sensor_out_of_range", i, s, e, peak_of=np.abs(p - full_scale / 2.0),
            peak_max=True, report=p, threshold=full_scale,
            message=f"pressure sensor {i} outside 0..{full_scale / 1e6:g} MPa",
        )  # fmt: skip

        missing = ~np.isfinite(p)
        s, e = runs(missing)
        start = np.maximum(s - 1, 0)  # last good sample before the gap
        stop = np.minimum(e + 1, t_s.size - 1)  # first good sample after it
        keep = (t_s[stop] - t_s[start]) > gap_s
        rows += event_rows(
            ctx, "sensor_dropout", i, start[keep], stop[keep], peak_of=None, peak_max=True,
            peak_values=(t_s[stop] - t_s[start])[keep], threshold=gap_s,
            message=f"pressure sensor {i} missing",
        )  # fmt: skip

    s, e = frozen_runs(
        pressures, t_s, depth, alarms.flatline_duration_s, hoist.shaft.position_window_m
    )
    rows += event_rows(
        ctx, "sensor_stuck", None, s, e, peak_of=None, peak_max=True,
        peak_values=t_s[e] - t_s[s], threshold=alarms.flatline_duration_s,
        message="all pressure sensors repeat their values while the conveyance travels",
    )  # fmt: skip

    rows += _disagreement_alarms(
        ctx, frame, hoist, pressures_pa(frame, hoist, calibrate=True), thresholds,
        merge_gap_s=merge_gap_s, dt_s=dt_s,
    )  # fmt: skip
    gaps = np.diff(t_s)
    gap_at = np.flatnonzero(gaps > gap_s)
    rows += event_rows(
        ctx, "sensor_dropout", None, gap_at, gap_at + 1, peak_of=None, peak_max=True,
        peak_values=gaps[gap_at], threshold=gap_s,
        message="no samples logged",
    )  # fmt: skip
    return rows


def _disagreement_alarms(
    ctx: EventContext,
    frame: pl.DataFrame,
    hoist: HoistDescription,
    calibrated: list[np.ndarray],
    thresholds: RuleThresholds,
    *,
    merge_gap_s: float,
    dt_s: float,
) -> list[dict[str, object]]:
    """``sensor_disagreement``: at standstill a calibrated sensor departs from the
    median of the four by more than the thresholds' fraction of it for
    ``flatline_duration`` (the module docstring of :mod:`transforms.alarm_rules`); the
    peak is the signed departure."""
    departure = departure_from_median(calibrated, floor_pa=thresholds.disagreement_floor_pa)
    at_rest = np.abs(column(frame, "speed_m_s")) < STANDSTILL_SPEED_M_S
    limit = thresholds.disagreement_fraction
    rows: list[dict[str, object]] = []
    for k, i in enumerate(ROPES):
        with np.errstate(invalid="ignore"):
            off = at_rest & (np.abs(departure[k]) > limit)
        s, e = debounced(
            ctx.t_s, off, off, min_duration_s=hoist.alarms.flatline_duration_s,
            merge_gap_s=merge_gap_s, dt_s=dt_s,
        )  # fmt: skip
        rows += event_rows(
            ctx, "sensor_disagreement", i, s, e, peak_of=np.abs(departure[k]),
            peak_max=True, report=departure[k], threshold=limit,
            message=f"pressure sensor {i} reads {limit:.0%}+ off the others at rest: the "
            "sensor, not the oil (the pipes equalise the chambers); the stick-slip "
            "compensation leaves its readings that far off out, its rope's tension "
            "shows them",
        )  # fmt: skip
    return rows
