"""What a replay of measured trips is given and what it gives back.

A :class:`ReplayPlan` (the trips of one hoist's record prepared for simulation, built by
:func:`discovery.planning.plan_replay`) goes into :func:`sims.replay.replay`, which
returns a :class:`ReplayResult` (the simulated sensor pressures at the plan's scored
samples); :func:`replay_frame` lays both out as one frame.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import polars as pl

from schemas.hoist import HoistDescription

__all__ = [
    "ReplayPlan",
    "ReplayResult",
    "ReplayTrip",
    "SkippedTrip",
    "loading_threshold_pa",
    "replay_frame",
]


def loading_threshold_pa(noise_sigma_pa: float) -> float:
    """The common-mode level change at a stop that counts as a load change [Pa]: 10 x
    the pressure noise, 20 kPa at least (20 kPa without a noise estimate).

    The pressure settles for seconds after a stop (ringing ropes shake the seals loose),
    and a lower threshold (2 x, tried) took that settling for a load change 2 s after 16
    of 66 stops on a validation day whose ropes ring; smaller changes go unseen (the
    seals hold them until the next trip moves).

    >>> loading_threshold_pa(5e3), loading_threshold_pa(1e3), loading_threshold_pa(float("nan"))
    (50000.0, 20000.0, 20000.0)
    """
    return max(10.0 * noise_sigma_pa, 2e4) if np.isfinite(noise_sigma_pa) else 2e4


@dataclass(frozen=True)
class ReplayTrip:
    """One measured trip prepared for simulation (times in s after ``ReplayPlan.t_ref``).

    ``time_s``, ``measured_pa`` ((m, n)), ``valid`` ((m, n)), ``phase``, ``direction``,
    ``depth_m`` are the scored samples; the rest are the simulation inputs. ``cut`` is
    ``"start"`` or ``"end"`` for a trip the record cuts (it starts or ends while the
    conveyance moves; the unseen end is fitted, :func:`sims.trips.fit_cut_trip`): a trip
    cut at its start is simulated from rest before the record but none of its samples is
    valid (it only loads the seals' state for the next trip); one cut at its end is
    simulated and scored up to the record's end. ``motion_knots`` (time [s after
    ``t_ref``], speed [m/s, + down], depth [m]) is the logged motion that drives the
    simulation (:mod:`sims.logged_motion`); None for a trip cut at its start (driven by
    the fitted winder profile). ``x_start_m`` (n,) the pistons' logged positions just
    before the window [m] (for a trip cut at its start, over the record's first seconds
    of it; None where they are not logged): where a block that starts with this trip
    puts them (:attr:`ReplayPlan.rope_offsets_m`). ``p_before_pa`` and ``p_after_pa``
    are the mean sensor levels at rest before and after the trip's loading, from which
    its payloads are first inferred (:func:`sims.replay_inputs.static_payloads_kg`),
    read at ``levels_depth_m``: the start's depth, or where a trip without a standstill
    before it in the record (cut at its start, or after a logger gap) stopped, the
    hanging tail rope's weight differing by its length between the two.
    ``motion_start_s`` is the fitted winder profile's start; ``rule_start_s`` the first
    sample the trip rule counts as moving (:mod:`physics.trip_rule`), the first of the
    trip's labelled rows: the period whose rows hold it reports the trip, as its
    ``trip_summary`` row (:mod:`pipelines.sanity`).
    """

    trip_id: int
    block: int
    first_in_block: bool
    window_start_s: float
    window_end_s: float
    ramp_start_s: float
    ramp_end_s: float
    motion_start_s: float
    motion_end_s: float
    rule_start_s: float
    start_depth_m: float
    end_depth_m: float
    max_speed_m_s: float | None
    direction: str
    oil_temp_c: float
    p_before_pa: float
    p_after_pa: float
    levels_depth_m: float
    time_s: np.ndarray
    measured_pa: np.ndarray
    valid: np.ndarray
    phase: np.ndarray
    depth_m: np.ndarray
    ramp_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ramp_measured_pa: np.ndarray = field(default_factory=lambda: np.zeros(0))
    profile_fit_m: float = 0.0
    cut: str = ""
    motion_knots: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    x_start_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        # frozen to the arrays too: a replay's answer is remembered by the very trip
        # (:func:`sims.replay.first_trips_gap`), so what it holds may not change
        for value in (*vars(self).values(), *(self.motion_knots or ())):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)


@dataclass(frozen=True)
class SkippedTrip:
    """A trip of the record that :func:`discovery.planning.plan_replay` could not prepare
    or does not replay, and why; ``rule_start_s`` as :attr:`ReplayTrip.rule_start_s`."""

    trip_id: int
    rule_start_s: float
    reason: str


@dataclass(frozen=True)
class ReplayPlan:
    """Trips of one hoist's record prepared for replay (:func:`discovery.planning.plan_replay`).

    ``skipped`` lists the analysed trips that could not be prepared, with the reason
    (the trip after such a one starts its block's history again), and the trips among
    them too short to replay (a jog of under 3 s). ``trip_id`` is the trip rule's
    (:mod:`physics.trip_rule`), so it names the trip as ``trip_summary`` does. ``rope_bounce`` says
    what the record shows of the ropes' ringing (:func:`sims.logged_motion.
    rope_damping_from_record`); ``hoist`` carries the damping ratio the replay uses
    (the description's unless the record contradicts it, also said in ``notes``).
    ``parameters`` are the effect parameters (``{effect: {parameter: value}}``) the
    plan's model is replayed with where a replay is not given its own (those the choices
    read off the record were made with; empty: the description's).
    """

    hoist: HoistDescription
    t_ref: dt.datetime
    trips: tuple[ReplayTrip, ...]
    noise_sigma_pa: float
    score_rate_hz: float
    dt_s: float
    trips_found: int
    notes: tuple[str, ...] = ()
    skipped: tuple[SkippedTrip, ...] = ()
    rope_bounce: str = ""
    parameters: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    #: The head ropes' length offsets [m] identified with the stiffness factors the
    #: hoist carries (``RopeSprings.length_offsets_m``: rope i pulls with
    #: k_i (s - x_i - c_i - z dr_i / R), the groove's payout only where the model has a
    #: groove wear, :func:`sims.replay.block_pistons`), or None. With them a block starts
    #: with its pistons where the record logged them (``ReplayTrip.x_start_m``), the seals
    #: holding what the ropes leave them (:func:`sims.device.held_start`); without, where
    #: equal tensions put them.
    rope_offsets_m: tuple[float, ...] | None = None

    @property
    def n_sensors(self) -> int:
        return self.hoist.ropes_n

    def time_utc(self, seconds: np.ndarray) -> pl.Series:
        """Absolute UTC timestamps of ``seconds`` after ``t_ref``."""
        base = int(self.t_ref.timestamp() * 1e6)
        return pl.Series(
            "time_utc", base + np.round(np.asarray(seconds) * 1e6).astype(np.int64)
        ).cast(pl.Datetime("us", "UTC"))


@dataclass(frozen=True)
class ReplayResult:
    """Simulated sensor pressures at the scored samples of each planned trip.

    ``simulated[k]`` is (m_k, n) [Pa] (NaN where the simulation failed);
    ``payload_kg[k]`` the payload after trip k's loading, ``payload_before_kg[k]``
    before it; ``status`` "success" or "failed" with ``message``; ``trip_messages[k]``
    says why trip k was not simulated ("" when it was).
    """

    simulated: tuple[np.ndarray, ...]
    payload_kg: np.ndarray
    payload_before_kg: np.ndarray
    effects: frozenset[str]
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    status: str = "success"
    message: str = ""
    ramp_simulated: tuple[np.ndarray, ...] = ()
    ramps_s: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    trip_messages: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.status == "success"

    def residuals(self, plan: ReplayPlan) -> tuple[np.ndarray, ...]:
        """Measured minus simulated [Pa] per trip, NaN where not valid."""
        return tuple(
            np.where(tr.valid, tr.measured_pa - sim, np.nan)
            for tr, sim in zip(plan.trips, self.simulated, strict=True)
        )

    def rms_gap_pa(self, plan: ReplayPlan) -> float:
        """RMS of measured minus simulated over every valid sample [Pa]; NaN if none."""
        r = np.concatenate([x[np.isfinite(x)] for x in self.residuals(plan)])
        return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


def replay_frame(plan: ReplayPlan, result: ReplayResult) -> pl.DataFrame:
    """Scored samples as a frame: ``time_utc, trip_id, phase, direction, depth_m,
    oil_temp_c, p{i}_pa`` (measured, NaN where masked) and ``p_sim{i}_pa``."""
    n = plan.n_sensors
    parts = []
    for tr, sim in zip(plan.trips, result.simulated, strict=True):
        cols: dict[str, Any] = {
            "time_utc": plan.time_utc(tr.time_s),
            "trip_id": np.full(tr.time_s.size, tr.trip_id, dtype=np.int64),
            "phase": tr.phase.astype(str),
            "direction": np.where(tr.phase == "standstill", "rest", tr.direction),
            "depth_m": tr.depth_m,
            "oil_temp_c": np.full(tr.time_s.size, tr.oil_temp_c),
        }
        for i in range(n):
            cols[f"p{i + 1}_pa"] = np.where(tr.valid[:, i], tr.measured_pa[:, i], np.nan)
            cols[f"p_sim{i + 1}_pa"] = sim[:, i]
        parts.append(pl.DataFrame(cols))
    return pl.concat(parts) if parts else pl.DataFrame()
