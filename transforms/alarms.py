"""Safety alarms on compensated rope tensions: rules, debounce, one event per alarm.

Contents
--------
Rules (:data:`ALARM_RULES`: name -> citation, unit)
    ``rope_imbalance``, ``slack_rope``, ``tight_rope``, ``overload``,
    ``reconciliation_residual``, ``sensor_flatline``, ``sensor_stuck``,
    ``sensor_out_of_range``, ``sensor_dropout``.
Entry point
    :func:`evaluate_alarms` -- ROPE_TENSIONS-shaped samples in, ALARMS frame out.
Helpers
    :func:`alarm_id` -- the deterministic id (re-runs replace, never duplicate).
    :func:`rule_thresholds` -- the thresholds a hoist description implies, in SI.

Thresholds come from the hoist description's ``[alarms]`` section.

Reading of the regulations (paraphrased; check the current text before relying on it):

- **Rope imbalance** -- China, Coal Mine Safety Regulations (煤矿安全规程), multi-rope
  friction hoists: the tension of each head rope shall not differ from the mean tension
  of the ropes by more than +-10 %. Evaluated per sample as (T_i - mean_j T_j) / mean.
- **Slack rope** -- Quebec, Regulation respecting occupational health and safety in mines
  (chapter S-2.1, r. 14), s. 253.2: a friction hoist must detect a rope whose tension
  falls below 60 % of the tension due to the empty conveyance. Read here per rope as
  0.60 x m_conveyance g / n_head_ropes: the empty conveyance's weight shared equally,
  tail ropes excluded. That is the static per-rope tension of the empty conveyance at
  the shaft bottom (where the hanging tail rope is shortest), the smallest tension a
  healthy rope carries at rest, so the threshold does not depend on depth.
- **Tight rope** -- same section: a rope whose tension exceeds the maximum static load
  by more than 10 % of the rope's breaking strength. Read per rope as
  (m_conveyance + m_rated_payload + m_tail,max) g / n_head_ropes + 0.10 x F_break,
  with m_tail,max the tail rope hanging below the conveyance at the pithead.
- **Overload** -- project rule against the rated payload: the static-equivalent load
  (acceleration removed) exceeds (m_conveyance + m_rated_payload + m_tail(z)) g by more
  than ``reconciliation_tolerance_fraction`` (the load measurement's uncertainty).
- **Reconciliation residual** -- project rule: at standstill (|speed| < 0.05 m/s) the
  measured load differs from the expected load for the trip's payload by more than
  ``reconciliation_tolerance_fraction``.
- **Sensor faults** -- project rules (IEC 61508-style diagnostics, no regulation):
  ``sensor_flatline`` (a pressure repeats the same value for ``flatline_duration``
  while another sensor moves), ``sensor_stuck`` (all four repeat while the conveyance
  travels: a frozen logger), ``sensor_out_of_range`` (below 0 or above the sensor's
  ``full_scale``), ``sensor_dropout`` (a logging gap longer than ``dropout_duration``,
  or one sensor missing for that long).

Debounce: a condition must hold ``min_duration`` before an alarm starts (the reported
start is where the condition began); once started, the alarm lasts while the condition
holds with a hysteresis band (release at ``1 - hysteresis_fraction`` of the threshold's
margin), and alarms of the same rule and rope closer than ``merge_gap_s`` merge: one
event is one alarm. All detection is vectorised over samples (numpy run-lengths); the
only Python loops run over rules, ropes and detected events.
"""

from __future__ import annotations

import datetime as dt
import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl

from physics.tension import expected_load_n
from schemas.hoist import G_STANDARD, HoistDescription
from schemas.tables import ALARMS, ROPES, conform
from transforms.reconciliation import expected_load_expr, tail_rope_weight_expr

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

#: Below this |speed| the conveyance counts as standing still [m/s].
STANDSTILL_SPEED_M_S = 0.05


@dataclass(frozen=True)
class AlarmRule:
    """One alarm rule: its name (the ``rule`` column), citation and unit of its values."""

    name: str
    citation: str
    unit: str
    per_rope: bool


_CHINA = "China Coal Mine Safety Regulations (煤矿安全规程), multi-rope friction hoist"
_QUEBEC = "Quebec S-2.1, r. 14, s. 253.2"

ALARM_RULES: dict[str, AlarmRule] = {
    rule.name: rule
    for rule in (
        AlarmRule("rope_imbalance", f"{_CHINA}: rope tension within +-10 % of mean", "1", True),
        AlarmRule("slack_rope", f"{_QUEBEC}: below 60 % of empty-conveyance tension", "N", True),
        AlarmRule(
            "tight_rope", f"{_QUEBEC}: above max static load + 10 % breaking strength", "N", True
        ),
        AlarmRule("overload", "ropeload: static-equivalent load above rated load", "N", False),
        AlarmRule(
            "reconciliation_residual",
            "ropeload: load at standstill differs from expected beyond tolerance",
            "1",
            False,
        ),
        AlarmRule("sensor_flatline", "ropeload sensor diagnostics: flat-line", "s", True),
        AlarmRule("sensor_stuck", "ropeload sensor diagnostics: all sensors frozen", "s", False),
        AlarmRule("sensor_out_of_range", "ropeload sensor diagnostics: out of range", "Pa", True),
        AlarmRule("sensor_dropout", "ropeload sensor diagnostics: data gap", "s", False),
    )
}


@dataclass(frozen=True)
class RuleThresholds:
    """Thresholds in SI that a hoist description implies (see the module docstring)."""

    imbalance_fraction: float
    slack_n: float
    tight_n: float
    overload_tolerance_fraction: float
    reconciliation_tolerance_fraction: float
    full_scale_pa: tuple[float, ...]


def rule_thresholds(hoist: HoistDescription) -> RuleThresholds:
    """Per-rope slack and tight thresholds [N] and the fractions, from ``hoist``."""
    alarms = hoist.alarms
    n = hoist.ropes_n
    empty_share_n = hoist.conveyance.mass_kg * G_STANDARD / n
    max_static_per_rope_n = (
        expected_load_n(hoist, 0.0, hoist.conveyance.rated_payload_kg) / n
    )  # pithead: longest hanging tail rope
    sensors = sorted(hoist.sensors, key=lambda s: s.cylinder)
    return RuleThresholds(
        imbalance_fraction=alarms.imbalance_fraction,
        slack_n=alarms.slack_fraction_of_empty * empty_share_n,
        tight_n=max_static_per_rope_n
        + alarms.tight_fraction_of_breaking * hoist.ropes.head_rope_breaking_strength_n,
        overload_tolerance_fraction=alarms.reconciliation_tolerance_fraction,
        reconciliation_tolerance_fraction=alarms.reconciliation_tolerance_fraction,
        full_scale_pa=tuple(s.full_scale_pa for s in sensors),
    )


def alarm_id(site: str, hoist: str, rule: str, rope: int | None, start_utc: dt.datetime) -> str:
    """Deterministic alarm id: sha256 of site, hoist, rule, rope and start (32 hex).

    The start is normalised to UTC, so the same instant in another zone gives the same id:

    >>> utc = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    >>> shanghai = dt.datetime(2026, 3, 2, 8, tzinfo=dt.timezone(dt.timedelta(hours=8)))
    >>> alarm_id("s", "h", "slack_rope", 2, utc) == alarm_id("s", "h", "slack_rope", 2, shanghai)
    True
    """
    start = start_utc.astimezone(dt.UTC).isoformat(timespec="microseconds")
    key = "\x1f".join([site, hoist, rule, "" if rope is None else str(rope), start])
    return hashlib.sha256(key.encode()).hexdigest()[:32]


# -- vectorised event detection ----------------------------------------------------------
def _runs(mask: np.ndarray, breaks: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """First and last (inclusive) index of every run of True in ``mask``; ``breaks[i]``
    True ends a run between samples i and i + 1 (a logger gap).

    >>> _runs(np.array([True, True, False, True, True, True]), np.array([0, 0, 0, 1, 0], bool))
    (array([0, 3, 4]), array([1, 3, 5]))
    """
    if breaks is None or mask.size < 2:
        edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
        return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    joined = mask[:-1] & mask[1:] & ~breaks  # sample i and i + 1 in one run
    starts = np.flatnonzero(mask & ~np.concatenate(([False], joined)))
    ends = np.flatnonzero(mask & ~np.concatenate((joined, [False])))
    return starts, ends


def _merge(
    t_s: np.ndarray, starts: np.ndarray, ends: np.ndarray, merge_gap_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Merge events (sorted) whose gap is at most ``merge_gap_s``."""
    if starts.size == 0:
        return starts, ends
    new = np.concatenate(([True], t_s[starts[1:]] - t_s[ends[:-1]] > merge_gap_s))
    last = np.concatenate((new[1:], [True]))
    return starts[new], ends[last]


def _debounced(
    t_s: np.ndarray,
    trigger: np.ndarray,
    hold: np.ndarray,
    *,
    min_duration_s: float,
    merge_gap_s: float,
    dt_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Events of a Schmitt trigger with a minimum on-time.

    An event starts where a run of ``trigger`` lasting ``min_duration_s`` begins and
    ends with the run of ``hold`` (the released condition, ``trigger`` implies it) that
    contains it; events closer than ``merge_gap_s`` merge. A run does not continue
    through a logger gap longer than ``merge_gap_s``: nothing is known in it (the gap
    is the dropout rule's), and the events on either side stay apart.
    """
    hold = hold | trigger
    breaks = np.diff(t_s) > merge_gap_s
    ts, te = _runs(trigger, breaks)
    keep = (t_s[te] - t_s[ts] + dt_s) >= min_duration_s - 1e-9
    ts = ts[keep]
    if ts.size == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty
    hs, he = _runs(hold, breaks)
    which = np.searchsorted(hs, ts, side="right") - 1
    held, first = np.unique(which, return_index=True)
    return _merge(t_s, ts[first], he[held], merge_gap_s)


def _threshold_events(
    t_s: np.ndarray,
    value: np.ndarray,
    threshold: np.ndarray | float,
    *,
    above: bool,
    hysteresis_fraction: float,
    min_duration_s: float,
    merge_gap_s: float,
    dt_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Events where ``value`` is above (or below) ``threshold``, with hysteresis."""
    finite = np.isfinite(value)
    band = np.abs(threshold) * hysteresis_fraction
    with np.errstate(invalid="ignore"):
        if above:
            trigger, hold = value > threshold, value > threshold - band
        else:
            trigger, hold = value < threshold, value < threshold + band
    return _debounced(
        t_s,
        trigger & finite,
        hold & finite,
        min_duration_s=min_duration_s,
        merge_gap_s=merge_gap_s,
        dt_s=dt_s,
    )


@dataclass(frozen=True)
class _Context:
    site: str
    hoist: str
    run_id: str
    time: np.ndarray  # datetime64[us], UTC
    t_s: np.ndarray


def _rows(
    ctx: _Context,
    rule: str,
    rope: int | None,
    starts: np.ndarray,
    ends: np.ndarray,
    *,
    peak_of: np.ndarray | None,
    peak_max: bool,
    threshold: np.ndarray | float,
    message: str,
    peak_values: np.ndarray | None = None,
    report: np.ndarray | None = None,
) -> list[dict[str, object]]:
    """Alarm rows for detected events (loop over events, not samples).

    The peak is where ``peak_of`` is largest (``peak_max``) or smallest; its value is
    read from ``report`` (default ``peak_of``). Without ``peak_of`` the peak is the start
    and ``peak_values`` gives one value per event.
    """
    rows = []
    thresholds = np.broadcast_to(np.asarray(threshold, dtype=float), ctx.t_s.shape)
    for k, (s, e) in enumerate(zip(starts.tolist(), ends.tolist(), strict=True)):
        if peak_of is not None:
            segment = peak_of[s : e + 1]
            offset = int(np.nanargmax(segment) if peak_max else np.nanargmin(segment))
            peak_index = s + offset
            peak_value = float((peak_of if report is None else report)[peak_index])
        else:
            peak_index = s
            peak_value = float(peak_values[k]) if peak_values is not None else float("nan")
        start = ctx.time[s].astype("datetime64[us]").item().replace(tzinfo=dt.UTC)
        rule_info = ALARM_RULES[rule]
        rows.append(
            {
                "alarm_id": alarm_id(ctx.site, ctx.hoist, rule, rope, start),
                "run_id": ctx.run_id,
                "site": ctx.site,
                "hoist": ctx.hoist,
                "rule": rule,
                "rope": rope,
                "start_utc": start,
                "end_utc": ctx.time[e].astype("datetime64[us]").item().replace(tzinfo=dt.UTC),
                "peak_time_utc": ctx.time[peak_index]
                .astype("datetime64[us]")
                .item()
                .replace(tzinfo=dt.UTC),
                "peak_value": peak_value,
                "threshold": float(thresholds[peak_index]),
                "unit": rule_info.unit,
                "message": f"{message} [{rule_info.citation}]",
            }
        )
    return rows


def _column(frame: pl.DataFrame, name: str) -> np.ndarray:
    if name not in frame.columns:
        return np.full(frame.height, np.nan)
    return frame.get_column(name).cast(pl.Float64).fill_null(np.nan).to_numpy()


def _pressures_pa(frame: pl.DataFrame, hoist: HoistDescription) -> list[np.ndarray]:
    """Sensor pressure per rope: ``p{i}_pa``, else raw tension / bore area."""
    area = hoist.cylinders.bore_area_m2
    out = []
    for i in ROPES:
        p = _column(frame, f"p{i}_pa")
        if np.all(np.isnan(p)):
            p = _column(frame, f"tension_raw{i}_n") / area
        out.append(p)
    return out


def _unchanged(x: np.ndarray) -> np.ndarray:
    """True where a sample repeats the previous one exactly (flat-line evidence)."""
    same = np.zeros(x.shape, dtype=bool)
    same[1:] = x[1:] == x[:-1]
    return same


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
    alarms = hoist.alarms
    site = site or hoist.hoist.site
    hoist_name = hoist_name or hoist.hoist.name
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
    frame = (
        lazy.sort("time_utc")
        .with_columns(
            # the tail ropes accelerate with the conveyance (reconciliation docstring)
            _static_load_n=pl.col("load_n") * G_STANDARD / (G_STANDARD + accel),
            _rated_load_n=tail_n + rated_n,
            _expected_n=expected_load_expr(hoist, payload_kg=pl.col("_payload_kg")),
        )
        .collect()
    )
    if frame.height == 0:
        return conform(pl.DataFrame(), ALARMS)
    time = frame.get_column("time_utc").dt.replace_time_zone(None).to_numpy()
    t_s = (time - time[0]) / np.timedelta64(1, "s")
    dt_s = float(np.median(np.diff(t_s))) if t_s.size > 1 else 0.0
    ctx = _Context(site, hoist_name, run_id, time, t_s)
    thresholds = rule_thresholds(hoist)
    common = {
        "hysteresis_fraction": hysteresis_fraction,
        "min_duration_s": alarms.min_duration_s,
        "merge_gap_s": merge_gap_s,
        "dt_s": dt_s,
    }
    rows: list[dict[str, object]] = []

    tensions = [_column(frame, f"tension{i}_n") for i in ROPES]
    mean = np.mean(np.vstack(tensions), axis=0)
    # imbalance is judged only while the ropes carry at least the slack threshold on
    # average (a hoist off its ropes has no meaningful balance); peak value is signed
    for i, tension in zip(ROPES, tensions, strict=True):
        with np.errstate(invalid="ignore", divide="ignore"):
            deviation = np.where(mean > thresholds.slack_n, (tension - mean) / mean, np.nan)
        s, e = _threshold_events(
            t_s, np.abs(deviation), thresholds.imbalance_fraction, above=True, **common
        )
        rows += _rows(
            ctx, "rope_imbalance", i, s, e, peak_of=np.abs(deviation), peak_max=True,
            report=deviation, threshold=thresholds.imbalance_fraction,
            message=f"rope {i} tension differs from the mean of the ropes by more than "
            f"{thresholds.imbalance_fraction:.0%}",
        )  # fmt: skip
        s, e = _threshold_events(t_s, tension, thresholds.slack_n, above=False, **common)
        rows += _rows(
            ctx, "slack_rope", i, s, e, peak_of=tension, peak_max=False,
            threshold=thresholds.slack_n,
            message=f"rope {i} tension below {thresholds.slack_n / 1e3:.1f} kN "
            f"({alarms.slack_fraction_of_empty:.0%} of the empty conveyance's per-rope weight)",
        )  # fmt: skip
        s, e = _threshold_events(t_s, tension, thresholds.tight_n, above=True, **common)
        rows += _rows(
            ctx, "tight_rope", i, s, e, peak_of=tension, peak_max=True,
            threshold=thresholds.tight_n,
            message=f"rope {i} tension above {thresholds.tight_n / 1e3:.1f} kN "
            f"(max static load + {alarms.tight_fraction_of_breaking:.0%} of breaking strength)",
        )  # fmt: skip

    static = _column(frame, "_static_load_n")
    overload_threshold = _column(frame, "_rated_load_n") * (
        1.0 + thresholds.overload_tolerance_fraction
    )
    s, e = _threshold_events(t_s, static, overload_threshold, above=True, **common)
    rows += _rows(
        ctx, "overload", None, s, e, peak_of=static, peak_max=True,
        threshold=overload_threshold,
        message="static-equivalent load above (conveyance + rated payload + tail rope) g "
        f"+ {thresholds.overload_tolerance_fraction:.0%}",
    )  # fmt: skip

    speed = _column(frame, "speed_m_s")
    expected = _column(frame, "_expected_n")
    with np.errstate(invalid="ignore", divide="ignore"):
        residual = np.abs(_column(frame, "load_n") / expected - 1.0)
        residual[~(np.abs(speed) < STANDSTILL_SPEED_M_S)] = np.nan
    tol = thresholds.reconciliation_tolerance_fraction
    s, e = _threshold_events(t_s, residual, tol, above=True, **common)
    rows += _rows(
        ctx, "reconciliation_residual", None, s, e, peak_of=residual, peak_max=True,
        threshold=tol,
        message=f"load at standstill differs from the expected load by more than {tol:.0%}",
    )  # fmt: skip

    rows += _sensor_alarms(ctx, frame, hoist, thresholds, merge_gap_s=merge_gap_s, dt_s=dt_s)
    if not rows:
        return conform(pl.DataFrame(), ALARMS)
    result = pl.DataFrame(rows, schema_overrides={"rope": pl.Int32}, infer_schema_length=None)
    return conform(result, ALARMS).sort("start_utc", "rule", "rope", nulls_last=True)


def _sensor_alarms(
    ctx: _Context,
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
    unchanged = [_unchanged(p) for p in pressures]
    moving = [~u & np.isfinite(p) for u, p in zip(unchanged, pressures, strict=True)]
    depth = _column(frame, "depth_m")

    for k, i in enumerate(ROPES):
        others_moving = np.cumsum(np.any(np.vstack(moving[:k] + moving[k + 1 :]), axis=0))
        s, e = _runs(unchanged[k] & np.isfinite(pressures[k]))
        s = np.maximum(s - 1, 0)  # the run starts at the sample that is then repeated
        duration = t_s[e] - t_s[s]
        others = others_moving[e] - others_moving[s]
        keep = (duration >= alarms.flatline_duration_s) & (others > 0)
        s, e = _merge(t_s, s[keep], e[keep], merge_gap_s)
        rows += _rows(
            ctx, "sensor_flatline", i, s, e, peak_of=None, peak_max=True,
            peak_values=t_s[e] - t_s[s], threshold=alarms.flatline_duration_s,
            message=f"pressure sensor {i} repeats one value while the others move",
        )  # fmt: skip

        p = pressures[k]
        full_scale = thresholds.full_scale_pa[k]
        with np.errstate(invalid="ignore"):
            out = (p < 0.0) | (p > full_scale)
        s, e = _debounced(
            t_s, out, out, min_duration_s=alarms.min_duration_s, merge_gap_s=merge_gap_s, dt_s=dt_s
        )
        rows += _rows(
            ctx, "sensor_out_of_range", i, s, e, peak_of=np.abs(p - full_scale / 2.0),
            peak_max=True, report=p, threshold=full_scale,
            message=f"pressure sensor {i} outside 0..{full_scale / 1e6:g} MPa",
        )  # fmt: skip

        missing = ~np.isfinite(p)
        s, e = _runs(missing)
        start = np.maximum(s - 1, 0)  # last good sample before the gap
        stop = np.minimum(e + 1, t_s.size - 1)  # first good sample after it
        keep = (t_s[stop] - t_s[start]) > alarms.dropout_duration_s
        rows += _rows(
            ctx, "sensor_dropout", i, start[keep], stop[keep], peak_of=None, peak_max=True,
            peak_values=(t_s[stop] - t_s[start])[keep], threshold=alarms.dropout_duration_s,
            message=f"pressure sensor {i} missing",
        )  # fmt: skip

    all_frozen = np.logical_and.reduce(unchanged)
    s, e = _runs(all_frozen)
    s = np.maximum(s - 1, 0)
    with np.errstate(invalid="ignore"):
        travelled = np.abs(depth[e] - depth[s])
    keep = (t_s[e] - t_s[s] >= alarms.flatline_duration_s) & (
        travelled > hoist.shaft.position_window_m
    )
    rows += _rows(
        ctx, "sensor_stuck", None, s[keep], e[keep], peak_of=None, peak_max=True,
        peak_values=(t_s[e] - t_s[s])[keep], threshold=alarms.flatline_duration_s,
        message="all pressure sensors repeat their values while the conveyance travels",
    )  # fmt: skip

    gaps = np.diff(t_s)
    gap_at = np.flatnonzero(gaps > alarms.dropout_duration_s)
    rows += _rows(
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
