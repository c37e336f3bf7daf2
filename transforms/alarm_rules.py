"""The alarm rules: their regulations, thresholds and the deterministic alarm id.

Contents
--------
Rules (:data:`ALARM_RULES`: name -> citation, unit)
    ``rope_imbalance``, ``slack_rope``, ``tight_rope``, ``overload``, ``underload``,
    ``reconciliation_residual``, ``sensor_flatline``, ``sensor_stuck``,
    ``sensor_out_of_range``, ``sensor_dropout``, ``sensor_disagreement``.
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
- **Underload** -- project rule, the overload's mirror: the static-equivalent load falls
  below the empty conveyance with its hanging tail rope, (m_conveyance + m_tail(z)) g,
  by more than ``reconciliation_tolerance_fraction``. The head ropes then carry less
  than the conveyance weighs: it rests on something (the keps or loading chairs, a skip
  caught in the shaft), which unloads all four ropes together, so the per-rope slack
  rule (60 % of the empty share) only sees it once it is nearly complete; or the
  description's masses or the sensors are off (a trip reconciled to a negative
  payload). Before it (session 66) a description's conveyance too heavy for its record
  reconciled its trips to negative payloads and raised no alarm (an earlier adversarial
  probe, ``CHANGELOG.md``). Its hysteresis band, as the overload's, is a fraction of the
  tolerance's margin (:func:`transforms.alarm_checks._band_of_margin`).
- **Reconciliation residual** -- project rule: at standstill (|speed| < 0.05 m/s) the
  measured load differs from the expected load for the trip's payload by more than
  ``reconciliation_tolerance_fraction``.
- **Sensor faults** -- project rules (IEC 61508-style diagnostics, no regulation):
  ``sensor_flatline`` (a pressure repeats the same value for ``flatline_duration``
  while another sensor moves), ``sensor_stuck`` (all four repeat while the conveyance
  travels: a frozen logger), ``sensor_out_of_range`` (below 0 or above the sensor's
  ``full_scale``), ``sensor_dropout`` (a logging gap longer than ``dropout_duration``,
  or one sensor missing for that long; and longer than one and a half of the logger's
  steps, :func:`transforms.alarm_checks.dropout_gap_s`), ``sensor_disagreement`` (at standstill one
  calibrated sensor departs from the median of the four by more than
  :data:`SENSOR_DISAGREEMENT_FRACTION` for ``flatline_duration``: the pipes equalise the chambers at
  rest, contract 1a, so that is the sensor, not the oil; the stick-slip compensation
  takes the others' mean for it at those samples, :func:`transforms.compensation_record.
  disagreeing_as_unknown`, and its rope's tension still shows the reading, its band and
  the load's reaching the others' reading too, :func:`transforms.uncertainty.
  disagreeing_sensor_shifts`).

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
from dataclasses import dataclass

from physics.tension import expected_load_n
from schemas.hoist import G_STANDARD, HoistDescription

__all__ = [
    "ALARM_RULES",
    "SENSOR_DISAGREEMENT_FRACTION",
    "STANDSTILL_SPEED_M_S",
    "AlarmRule",
    "RuleThresholds",
    "alarm_id",
    "rule_thresholds",
]

#: Below this |speed| the conveyance counts as standing still [m/s].
STANDSTILL_SPEED_M_S = 0.05

#: A sensor this far off the median of the four at standstill (a fraction of it) is the
#: sensor, not the oil: the pipes equalise the chambers at rest (contract 1a). Not an
#: alarm setting: the stick-slip compensation drops such readings too
#: (:func:`transforms.compensation_record.disagreeing_as_unknown`), so an imbalance
#: threshold tightened for a study does not change the tensions. Five times the largest
#: departure at rest on the independent validation days (0.9 %, sensor noise and the
#: last of the flows after loading), a quarter of the 20 % step a probe's faulty sensor
#: made.
SENSOR_DISAGREEMENT_FRACTION = 0.05


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
            "underload", "ropeload: static-equivalent load below the empty conveyance", "N", False
        ),
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
        AlarmRule(
            "sensor_disagreement",
            "ropeload sensor diagnostics: one sensor off the others at rest (contract 1a)",
            "1",
            True,
        ),
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
    #: a sensor this far off the median of the four at rest is the sensor, not the oil
    #: (``sensor_disagreement``, :data:`SENSOR_DISAGREEMENT_FRACTION`)
    disagreement_fraction: float = SENSOR_DISAGREEMENT_FRACTION
    #: ... where the median is at least this [Pa]: the slack threshold's pressure (below
    #: it, a hoist off its ropes or depressurised, a fraction of nearly nothing is noise)
    disagreement_floor_pa: float = 0.0


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
        disagreement_fraction=SENSOR_DISAGREEMENT_FRACTION,
        disagreement_floor_pa=alarms.slack_fraction_of_empty
        * empty_share_n
        / hoist.cylinders.bore_area_m2,
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
