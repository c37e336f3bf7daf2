"""Safety alarms on compensated rope tensions: one event per alarm.

Contents
--------
Entry points
    :func:`evaluate_alarms` -- ROPE_TENSIONS-shaped samples in, ALARMS frame out.
    :func:`evaluate_alarms_in_blocks` -- the same on a long record read block by block,
    with :func:`merge_alarm_pieces` joining an event cut by a block edge.
Rules
    :mod:`transforms.alarm_rules` (the regulations read, thresholds, ids), re-exported
    here; their checks: :mod:`transforms.alarm_checks`; the debounce:
    :mod:`transforms.alarm_events`.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Sequence

import numpy as np
import polars as pl

from schemas.hoist import G_STANDARD, HoistDescription
from schemas.tables import ALARMS, conform
from transforms.alarm_checks import load_alarms, rope_alarms, sensor_alarms
from transforms.alarm_events import EventContext
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
    "alarm_margin_s",
    "evaluate_alarms",
    "evaluate_alarms_in_blocks",
    "merge_alarm_pieces",
    "rule_thresholds",
]


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
    sample_step_s: float | None = None,
) -> pl.DataFrame:
    """Evaluate every rule of :data:`ALARM_RULES` on ROPE_TENSIONS-shaped samples.

    ``sample_step_s``: the logger's step [s] (a record's, e.g. ``1 / CompensationContext.
    sample_rate_hz``, so that every block of it reads the same); None: the samples'
    median spacing. A slow logger's own step is not a dropout
    (:func:`transforms.alarm_checks.dropout_gap_s`).

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
    if sample_step_s is not None:
        dt_s = sample_step_s
    else:
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
    rows = rope_alarms(ctx, frame, hoist, thresholds, common)
    rows += load_alarms(ctx, frame, thresholds, common)
    rows += sensor_alarms(ctx, frame, hoist, thresholds, merge_gap_s=merge_gap_s, dt_s=dt_s)
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
    empty_n = hoist.conveyance.mass_kg * G_STANDARD
    accel = pl.col("acceleration_up_m_s2").fill_null(0.0)
    return (
        lazy.sort("time_utc")
        .with_columns(
            # the tail ropes accelerate with the conveyance (reconciliation docstring)
            _static_load_n=pl.col("load_n") * G_STANDARD / (G_STANDARD + accel),
            _rated_load_n=tail_n + rated_n,
            _empty_load_n=tail_n + empty_n,
            _expected_n=expected_load_expr(hoist, payload_kg=pl.col("_payload_kg")),
        )
        .collect()
    )


#: Margin [s] around a block when alarms are evaluated block by block
#: (:func:`merge_alarm_pieces`): longer than a debounce plus a merge gap, so an event
#: shorter than it is seen whole in at least one window. At least; a hoist whose
#: ``[alarms]`` durations are longer gets a longer one (:func:`alarm_margin_s`).
ALARM_MARGIN_S = 120.0


def alarm_margin_s(hoist: HoistDescription, merge_gap_s: float = 2.0) -> float:
    """The margin around a block for ``hoist``: :data:`ALARM_MARGIN_S`, or the longest of
    its ``[alarms]`` durations (``min_duration``, ``flatline_duration``,
    ``dropout_duration``) plus the merge gap, twice over, if that is longer.

    An event across a block edge is then seen in one of the two windows for at least
    the duration its rule asks (a window reaches past its edge by more than that), so
    ``--block-minutes`` does not decide whether it is raised (a 5-minute
    ``min_duration`` lost an event of 340 s across an edge).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> alarm_margin_s(load_hoist(EXAMPLE_HOIST))
    120.0
    """
    alarms = hoist.alarms
    longest = max(alarms.min_duration_s, alarms.flatline_duration_s, alarms.dropout_duration_s)
    return max(ALARM_MARGIN_S, 2.0 * (longest + merge_gap_s))


#: Rules whose peak is the smallest value (the others: the largest; rope imbalance: the
#: largest magnitude, its sign kept; durations are recomputed).
_PEAK_MIN = {"slack_rope", "underload"}
_PEAK_DURATION = {"sensor_flatline", "sensor_stuck", "sensor_dropout"}


def evaluate_alarms_in_blocks(
    read: Callable[[dt.datetime, dt.datetime], pl.DataFrame],
    blocks: Sequence[tuple[dt.datetime, dt.datetime]],
    hoist: HoistDescription,
    *,
    run_id: str,
    trip_payloads: pl.DataFrame | None = None,
    payload_kg: float | None = None,
    sample_step_s: float | None = None,
) -> pl.DataFrame:
    """:func:`evaluate_alarms` of a long record, one block at a time (issue 16).

    ``read(lo, hi)`` returns the ROPE_TENSIONS rows ``lo <= t < hi``; each block of
    ``blocks`` is read with :func:`alarm_margin_s` either side and the alarms of all the
    windows are merged (:func:`merge_alarm_pieces`). A logger gap longer than two
    margins has no window holding both its sides: its two bounding samples are checked
    on their own, so its "no samples logged" alarm is raised as on the whole record.
    ``sample_step_s``: the record's logger step (:func:`evaluate_alarms`); None: the
    first block's median spacing, for every block.
    """
    margin = dt.timedelta(seconds=alarm_margin_s(hoist))
    pieces = []
    tail: pl.DataFrame | None = None
    for lo, hi in blocks:
        window = read(lo - margin, hi + margin)
        if window.height == 0:
            continue
        if sample_step_s is None and window.height > 1:
            spacing = window["time_utc"].diff().dt.total_microseconds().drop_nulls()
            sample_step_s = float(spacing.median()) / 1e6
        found = evaluate_alarms(
            window, hoist, run_id=run_id, trip_payloads=trip_payloads,
            payload_kg=payload_kg, sample_step_s=sample_step_s,
        )  # fmt: skip
        pieces.append(found)
        if tail is not None and window["time_utc"][0] > tail["time_utc"][0]:
            # only the gap itself: two samples say nothing else (their spacing would
            # pass any single sample as lasting the debounce time)
            pair = pl.concat([tail, window.head(1)], how="vertical_relaxed")
            pieces.append(
                evaluate_alarms(pair, hoist, run_id=run_id, sample_step_s=sample_step_s).filter(
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
    :func:`alarm_margin_s` either side. An event is then seen whole in one window,
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
    if row["rule"] in ("rope_imbalance", "sensor_disagreement"):  # signed peaks
        return abs(new) > abs(old)
    if row["rule"] == "sensor_out_of_range":
        return abs(new - row["threshold"] / 2.0) > abs(old - current["threshold"] / 2.0)
    return new > old
