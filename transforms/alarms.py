"""Safety alarms on compensated rope tensions: one event per alarm.

Contents
--------
Entry points
    :func:`evaluate_alarms` -- ROPE_TENSIONS-shaped samples in, ALARMS frame out.
    :func:`evaluate_alarms_in_blocks` -- the same on a long record read block by block,
    with :func:`merge_alarm_pieces` joining an event cut by a block edge.
Rules
    :mod:`transforms.alarm_rules` (the regulations read, thresholds, ids), re-exported
    here; the debounce: :mod:`transforms.alarm_events`.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Sequence

import numpy as np
import polars as pl

from schemas.hoist import G_STANDARD, HoistDescription
from schemas.tables import ALARMS, ROPES, conform
from transforms.alarm_events import (
    EventContext,
    column,
    debounced,
    event_rows,
    merge_events,
    runs,
    threshold_events,
    unchanged,
)
from transforms.alarm_rules import (
    ALARM_RULES,
    STANDSTILL_SPEED_M_S,
    AlarmRule,
    RuleThresholds,
    alarm_id,
    rule_thresholds,
)
from transforms.reconciliation import expected_load_expr, tail_rope_weight_expr

# the rules are part of this module's interface (transforms.alarm_rules defines them)
__all__ = [
    "ALARM_MARGIN_S",
    "ALARM_RULES",
    "STANDSTILL_SPEED_M_S",
    "AlarmRule",
    "RuleThresholds",
    "alarm_id",
    "evaluate_alarms",
    "evaluate_alarms_in_blocks",
    "merge_alarm_pieces",
    "rule_thresholds",
]


def _pressures_pa(frame: pl.DataFrame, hoist: HoistDescription) -> list[np.ndarray]:
    """Sensor pressure per rope: ``p{i}_pa``, else raw tension / bore area."""
    area = hoist.cylinders.bore_area_m2
    out = []
    for i in ROPES:
        p = column(frame, f"p{i}_pa")
        if np.all(np.isnan(p)):
            p = column(frame, f"tension_raw{i}_n") / area
        out.append(p)
    return out


def evaluate_alarms(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    hoist: HoistDescription,
    *,
    run_id: str,
    site: str | None = None,
    hoist_name: str | None = None,
    trip_payloads: pl.DataFrame | None = None,
    payload_kg: float | None = None,
    hysteresis_fraction: float = 0.05,
    merge_gap_s: float = 2.0,
) -> pl.DataFrame:
    """Evaluate every rule of :data:`ALARM_RULES` on ROPE_TENSIONS-shaped samples.

    The reconciliation-residual rule needs the payload: per trip from
    ``trip_payloads`` (``trip_id``, ``payload_kg``; a TRIP_SUMMARY frame will do), else
    ``payload_kg`` for every standstill sample; samples with neither are not checked.
    Trip segmentation (``transforms.kinematics``) leaves ``trip_id`` null at standstill,
    where loading happens, so there a known payload (e.g. 0 for a conveyance parked
    empty) is what makes the check possible.
    Returns the ALARMS schema, one row per debounced event, sorted by start.
    """
    frame = _alarm_frame(rope_tensions, hoist, trip_payloads, payload_kg)
    if frame.height == 0:
        return conform(pl.DataFrame(), ALARMS)
    time = frame.get_column("time_utc").dt.replace_time_zone(None).to_numpy()
    t_s = (time - time[0]) / np.timedelta64(1, "s")
    dt_s = float(np.median(np.diff(t_s))) if t_s.size > 1 else 0.0
    site = site or hoist.hoist.site
    ctx = EventContext(site, hoist_name or hoist.hoist.name, run_id, time, t_s)
    thresholds = rule_thresholds(hoist)
    common = {
        "hysteresis_fraction": hysteresis_fraction,
        "min_duration_s": hoist.alarms.min_duration_s,
        "merge_gap_s": merge_gap_s,
        "dt_s": dt_s,
    }
    rows = _rope_alarms(ctx, frame, hoist, thresholds, common)
    rows += _load_alarms(ctx, frame, thresholds, common)
    rows += _sensor_alarms(ctx, frame, hoist, thresholds, merge_gap_s=merge_gap_s, dt_s=dt_s)
    if not rows:
        return conform(pl.DataFrame(), ALARMS)
    result = pl.DataFrame(rows, schema_overrides={"rope": pl.Int32}, infer_schema_length=None)
    return conform(result, ALARMS).sort("start_utc", "rule", "rope", nulls_last=True)


def _alarm_frame(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    hoist: HoistDescription,
    trip_payloads: pl.DataFrame | None,
    payload_kg: float | None,
) -> pl.DataFrame:
    """The samples sorted by time, with the payload known per trip or at rest and the
    static-equivalent, rated and expected loads the load rules compare."""
    lazy = rope_tensions.lazy() if isinstance(rope_tensions, pl.DataFrame) else rope_tensions
    if trip_payloads is not None:
        known = trip_payloads.select(
            pl.col("trip_id").cast(pl.Int64), pl.col("payload_kg").alias("_payload_kg")
        )
        lazy = lazy.with_columns(pl.col("trip_id").cast(pl.Int64)).join(
            known.lazy(), on="trip_id", how="left"
        )
    else:
        lazy = lazy.with_columns(_payload_kg=pl.lit(None, dtype=pl.Float64))
    if payload_kg is not None:
        lazy = lazy.with_columns(pl.col("_payload_kg").fill_null(float(payload_kg)))
    tail_n = tail_rope_weight_expr(hoist)
    rated_n = (hoist.conveyance.mass_kg + hoist.conveyance.rated_payload_kg) * G_STANDARD
    accel = pl.col("acceleration_up_m_s2").fill_null(0.0)
    return (
        lazy.sort("time_utc")
        .with_columns(
            # the tail ropes accelerate with the conveyance (reconciliation docstring)
            _static_load_n=pl.col("load_n") * G_STANDARD / (G_STANDARD + accel),
            _rated_load_n=tail_n + rated_n,
            _expected_n=expected_load_expr(hoist, payload_kg=pl.col("_payload_kg")),
        )
        .collect()
    )


def _rope_alarms(
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


def _load_alarms(
    ctx: EventContext, frame: pl.DataFrame, thresholds: RuleThresholds, common: dict[str, float]
) -> list[dict[str, object]]:
    """Overload (static-equivalent load) and reconciliation-residual (at rest) events."""
    t_s = ctx.t_s
    static = column(frame, "_static_load_n")
    overload_threshold = column(frame, "_rated_load_n") * (
        1.0 + thresholds.overload_tolerance_fraction
    )
    s, e = threshold_events(t_s, static, overload_threshold, above=True, **common)
    rows = event_rows(
        ctx, "overload", None, s, e, peak_of=static, peak_max=True,
        threshold=overload_threshold,
        message="static-equivalent load above (conveyance + rated payload + tail rope) g "
        f"+ {thresholds.overload_tolerance_fraction:.0%}",
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


def _sensor_alarms(
    ctx: EventContext,
    frame: pl.DataFrame,
    hoist: HoistDescription,
    thresholds: RuleThresholds,
    *,
    merge_gap_s: float,
    dt_s: float,
) -> list[dict[str, object]]:
    """Flat-line, stuck, out-of-range and dropout rules (see the module docstring)."""
    alarms = hoist.alarms
    t_s = ctx.t_s
    rows: list[dict[str, object]] = []
    pressures = _pressures_pa(frame, hoist)
    repeats = [unchanged(p) for p in pressures]
    moving = [~u & np.isfinite(p) for u, p in zip(repeats, pressures, strict=True)]
    depth = column(frame, "depth_m")

    for k, i in enumerate(ROPES):
        others_moving = np.cumsum(np.any(np.vstack(moving[:k] + moving[k + 1 :]), axis=0))
        s, e = runs(repeats[k] & np.isfinite(pressures[k]))
        s = np.maximum(s - 1, 0)  # the run starts at the sample that is then repeated
        duration = t_s[e] - t_s[s]
        others = others_moving[e] - others_moving[s]
        keep = (duration >= alarms.flatline_duration_s) & (others > 0)
        s, e = merge_events(t_s, s[keep], e[keep], merge_gap_s)
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
        keep = (t_s[stop] - t_s[start]) > alarms.dropout_duration_s
        rows += event_rows(
            ctx, "sensor_dropout", i, start[keep], stop[keep], peak_of=None, peak_max=True,
            peak_values=(t_s[stop] - t_s[start])[keep], threshold=alarms.dropout_duration_s,
            message=f"pressure sensor {i} missing",
        )  # fmt: skip

    all_frozen = np.logical_and.reduce(repeats)
    s, e = runs(all_frozen)
    s = np.maximum(s - 1, 0)
    with np.errstate(invalid="ignore"):
        travelled = np.abs(depth[e] - depth[s])
    keep = (t_s[e] - t_s[s] >= alarms.flatline_duration_s) & (
        travelled > hoist.shaft.position_window_m
    )
    rows += event_rows(
        ctx, "sensor_stuck", None, s[keep], e[keep], peak_of=None, peak_max=True,
        peak_values=(t_s[e] - t_s[s])[keep], threshold=alarms.flatline_duration_s,
        message="all pressure sensors repeat their values while the conveyance travels",
    )  # fmt: skip

    gaps = np.diff(t_s)
    gap_at = np.flatnonzero(gaps > alarms.dropout_duration_s)
    rows += event_rows(
        ctx, "sensor_dropout", None, gap_at, gap_at + 1, peak_of=None, peak_max=True,
        peak_values=gaps[gap_at], threshold=alarms.dropout_duration_s,
        message="no samples logged",
    )  # fmt: skip
    return rows


#: Margin [s] around a block when alarms are evaluated block by block
#: (:func:`merge_alarm_pieces`): longer than a debounce plus a merge gap, so an event
#: shorter than it is seen whole in at least one window.
ALARM_MARGIN_S = 120.0

#: Rules whose peak is the smallest value (the others: the largest; rope imbalance: the
#: largest magnitude, its sign kept; durations are recomputed).
_PEAK_MIN = {"slack_rope"}
_PEAK_DURATION = {"sensor_flatline", "sensor_stuck", "sensor_dropout"}


def evaluate_alarms_in_blocks(
    read: Callable[[dt.datetime, dt.datetime], pl.DataFrame],
    blocks: Sequence[tuple[dt.datetime, dt.datetime]],
    hoist: HoistDescription,
    *,
    run_id: str,
    trip_payloads: pl.DataFrame | None = None,
    payload_kg: float | None = None,
) -> pl.DataFrame:
    """:func:`evaluate_alarms` of a long record, one block at a time (issue 16).

    ``read(lo, hi)`` returns the ROPE_TENSIONS rows ``lo <= t < hi``; each block of
    ``blocks`` is read with :data:`ALARM_MARGIN_S` either side and the alarms of all the
    windows are merged (:func:`merge_alarm_pieces`). A logger gap longer than two
    margins has no window holding both its sides: its two bounding samples are checked
    on their own, so its "no samples logged" alarm is raised as on the whole record.
    """
    margin = dt.timedelta(seconds=ALARM_MARGIN_S)
    pieces = []
    tail: pl.DataFrame | None = None
    for lo, hi in blocks:
        window = read(lo - margin, hi + margin)
        if window.height == 0:
            continue
        pieces.append(
            evaluate_alarms(
                window, hoist, run_id=run_id, trip_payloads=trip_payloads, payload_kg=payload_kg
            )
        )
        if tail is not None and window["time_utc"][0] > tail["time_utc"][0]:
            # only the gap itself: two samples say nothing else (their spacing would
            # pass any single sample as lasting the debounce time)
            pair = pl.concat([tail, window.head(1)], how="vertical_relaxed")
            pieces.append(
                evaluate_alarms(pair, hoist, run_id=run_id).filter(
                    (pl.col("rule") == "sensor_dropout") & pl.col("rope").is_null()
                )
            )
        tail = window.tail(1)
    if not pieces:
        return conform(pl.DataFrame(), ALARMS)
    return merge_alarm_pieces(pl.concat(pieces), site=hoist.hoist.site, hoist=hoist.hoist.name)


def merge_alarm_pieces(
    pieces: pl.DataFrame, *, site: str, hoist: str, merge_gap_s: float = 2.0
) -> pl.DataFrame:
    """Alarms of overlapping windows of one record, merged into the record's alarms.

    Block processing (issue 16) evaluates :func:`evaluate_alarms` on each block with
    :data:`ALARM_MARGIN_S` either side. An event is then seen whole in one window,
    twice (in an overlap) or in pieces cut at window edges. Pieces of the same rule and
    rope that overlap or are at most ``merge_gap_s`` apart become one alarm: the earliest
    start, the latest end, the most extreme peak of the pieces (durations recomputed),
    ``alarm_id`` from the merged start. What differs from evaluating the whole record at
    once: an event whose value stays between the hysteresis band's two thresholds across
    a whole window overlap can come out as two alarms instead of one.
    """
    if pieces.height == 0:
        return conform(pl.DataFrame(), ALARMS)
    rows: list[dict[str, object]] = []
    ordered = pieces.sort("rule", "rope", "start_utc", "end_utc", nulls_last=True)
    gap = dt.timedelta(seconds=merge_gap_s)
    current: dict[str, object] | None = None
    for row in ordered.iter_rows(named=True):
        if (
            current is not None
            and row["rule"] == current["rule"]
            and row["rope"] == current["rope"]
            and row["start_utc"] <= current["end_utc"] + gap
        ):
            current["end_utc"] = max(current["end_utc"], row["end_utc"])
            if _more_extreme(row, current):
                for key in ("peak_time_utc", "peak_value", "threshold"):
                    current[key] = row[key]
            continue
        if current is not None:
            rows.append(current)
        current = dict(row)
    assert current is not None
    rows.append(current)
    for row in rows:
        if row["rule"] in _PEAK_DURATION:
            row["peak_value"] = (row["end_utc"] - row["start_utc"]).total_seconds()
        row["alarm_id"] = alarm_id(site, hoist, row["rule"], row["rope"], row["start_utc"])
    result = pl.DataFrame(rows, schema=pieces.schema)
    return conform(result, ALARMS).sort("start_utc", "rule", "rope", nulls_last=True)


def _more_extreme(row: dict[str, object], current: dict[str, object]) -> bool:
    new, old = row["peak_value"], current["peak_value"]
    if new is None or old is None or new != new or old != old:  # NaN
        return old is None or old != old
    if row["rule"] in _PEAK_MIN:
        return new < old
    if row["rule"] == "rope_imbalance":
        return abs(new) > abs(old)
    if row["rule"] == "sensor_out_of_range":
        return abs(new - row["threshold"] / 2.0) > abs(old - current["threshold"] / 2.0)
    return new > old
