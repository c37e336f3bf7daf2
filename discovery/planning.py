"""Planning the replay of measured hoist trips: the trips of a record, ready to simulate.

Discovery (:mod:`discovery.selection`) and the nightly sanity check compare what the
pressure sensors logged with what the device simulation predicts for the same trips
(:func:`sims.replay.replay`). The simulation needs its inputs -- commanded motion,
payload, oil temperature -- and these come from the log itself:

:func:`plan_replay`
    Segments a landed sample frame (``FIELD_SAMPLES`` columns: ``time_utc``,
    ``p{i}_pa``, ``depth_m``, ``speed_m_s``, ``oil_temp_c``) into trips and builds, per
    trip, everything a simulation needs: start and stop depth (median encoder depth at
    the standstills), motion start (least squares on the encoder speed of the
    accelerating phase: ``|v| = a (t - t_m)``), top speed, oil temperature (median),
    the loading ramp before the motion (from the common-mode pressure) and the samples
    to score (sub-sampled to ``score_rate_hz``, loading ramps masked, spikes masked).
    The logger's pressure noise is estimated from second differences of the
    pressures at standstill (:func:`discovery.segmentation.estimate_noise_sigma`).

Records are cut anywhere (a logger stops mid-trip, a day ends at UTC midnight), and a
replay never crashes on that: a trip the record starts or ends in is completed by the
winder profile fitted to its logged depth (:func:`sims.trips.fit_cut_trip`) and marked
``cut``; cut at its end it is simulated and scored up to the record's end, cut at its
start it is simulated from rest before the record and only loads the seals' state. A
trip that cannot be prepared is listed in ``ReplayPlan.skipped`` with the reason, one
the simulation refuses gets its reason in ``ReplayResult.trip_messages``. A load change
after the last stop (loading for a trip the record does not hold) ends the last window.

The ropes' ringing is read off the record, not taken on trust from the description
(whose ``head_rope_damping_ratio`` is a default a mine cannot know): a model that rings
at ~1 Hz where the hoist does not leaves a common-mode gap of ~0.1 MPa. The description's
ratio stays unless the record contradicts it; then the ratio read from the ringing's decay
(or, with no ringing seen 3-7 s after the stops, 0.1 / 0.3 / 1.0) is chosen by the replay
gap (:mod:`sims.logged_motion`, ``ReplayPlan.rope_bounce``). So is the ropes' stiffness
spread (:mod:`discovery.rope_stiffness`: which piston slides when the load changes decides
the seals' summed force, ~50 kPa of common-mode pressure on the validation days). The
trips are driven by the encoder's logged speed or by the winder profile, whichever
replays the first trips closer (``plan_replay(motion="auto")``, the default; the order
of these choices is :mod:`discovery.replay_choices`'s).

Long records are analysed on at most ``max_trips`` trips in ``blocks`` blocks of
consecutive trips spread evenly over the record (temperature and payload ranges
covered, simulation cost bounded: ~0.2 s per 2-minute trip at ``dt_s = 2 ms``); each
block after the first starts with the trip before it (unless that trip ends the block
before or cannot be replayed), simulated but not compared (it loads the seals' state).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections.abc import Mapping
from typing import Any

import numpy as np
import polars as pl

from discovery.record import (
    RAMP_MARGIN_S,
    RecordArrays,
    read_record,
    trailing_ramp_start,
    trip_timing,
    window_end,
)
from discovery.replay_choices import choose_motion, read_ropes
from discovery.rope_stiffness import IdentifiedFactors, piston_slides_m
from discovery.segmentation import (
    CUT_WORDS,
    chosen_trips,
    median_in,
    profile_phases,
    ramp_samples,
    scored_samples,
    time_span,
)
from physics.trip_rule import TRIP_BRIDGE_S
from schemas.hoist import HoistDescription
from sims.device import CONTINUATION_DEPTH_TOLERANCE_M
from sims.logged_motion import (
    motion_knots,
    profile_from_knots,
    rope_bounce_unseen,
    rope_damping_from_record,
)
from sims.replay import replay_profile
from sims.replay_plan import ReplayPlan, ReplayTrip, SkippedTrip
from sims.trips import TripProfile

__all__ = ["plan_replay"]


def _driving_motion(
    rec: RecordArrays,
    tm: dict[str, Any],
    profile: TripProfile,
    win_end: float,
    logged: bool,
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray] | None, TripProfile]:
    """(logged motion knots or None, the profile the simulation follows) of a trip with
    pass-1 timing ``tm`` and winder ``profile``; ``logged``: driven by the logged speed."""
    t = rec.t
    r0, d0, d1 = tm["r0"], tm["d0"], tm["d1"]
    # the logged motion drives the simulation (sims.logged_motion); a trip cut at
    # its start is simulated from rest before the record: the fitted profile
    knots = None
    if logged and tm["cut"] != "start":
        knots = motion_knots(
            t,
            rec.speed,
            tm["a_t"] - 1.5,
            rec.end_t + 1e-6 if tm["cut"] == "end" else min(tm["b_t"] + 1.5, rec.end_t + 1e-6),
            d0,
            d1,
            at_rest_after=tm["cut"] != "end",
            knot_s=rec.knot_s,
            depth_m=rec.depth,
        )
    driven = profile
    if knots is not None:
        driven = profile_from_knots(
            *knots,
            start_s=r0,
            duration_s=max(win_end - r0, 1.0),
            payload_time_s=np.array([0.0]),
            payload_kg=np.array([0.0]),
            oil_temp_c=None,
            direction="down" if d1 > d0 else "up",
        )
    return knots, driven


def _planned_trip(
    rec: RecordArrays,
    hoist: HoistDescription,
    k: int,
    tm: dict[str, Any],
    block: tuple[int, bool],
    win_end: float,
    score_rate_hz: float,
    logged: bool,
    notes: list[str],
) -> ReplayTrip:
    """Pass 2, analysed trip ``k`` (its pass-1 timing ``tm``; ``block``: its block and
    whether it starts the block's history; its window ending at ``win_end``): the scored
    and ramp samples, the motion that drives it (``logged``: the logged speed) and its
    phases; notes on its profile fit and cut."""
    t, depth = rec.t, rec.depth
    t_m, t_e, vmax_arg = tm["t_m"], tm["t_e"], tm["vmax"]
    r0, r1, p_pre, p_post = tm["r0"], tm["r1"], tm["p_pre"], tm["p_post"]
    d0, d1 = tm["d0"], tm["d1"]
    # scored samples: after the ramp, within the window, every 1/score_rate s
    idx, meas, valid = scored_samples(
        t, rec.p, rec.sigma, r1 + RAMP_MARGIN_S, win_end, score_rate_hz, tm["cut"]
    )
    ridx = ramp_samples(t, r0, r1, t_m, score_rate_hz)
    profile = replay_profile(
        hoist, d0, d1, t_m - r0, max(win_end - r0, 1.0), vmax_arg, 20.0, (0.0, 1.0), 0.0
    )
    knots, driven = _driving_motion(rec, tm, profile, win_end, logged)
    tau = t[idx] - r0
    motion = time_span(t, t_m, t_e)
    fit = float(np.sqrt(np.nanmean((profile.depth(t[motion] - r0) - depth[motion]) ** 2)))
    if fit > 0.5:
        notes.append(
            f"trip {tm['trip_id']}: encoder depth departs {fit:.2f} m RMS from the winder profile"
        )
    if tm["cut"]:
        notes.append(
            f"trip {tm['trip_id']}: {CUT_WORDS[tm['cut']]}: completed by the winder profile "
            f"fitted to the logged depth ({d0:.1f} -> {d1:.1f} m)"
        )
    oil = median_in(t, rec.temp, max(r0, float(t[0])), win_end)
    return ReplayTrip(
        trip_id=tm["trip_id"],
        block=block[0],
        first_in_block=block[1],
        window_start_s=r0,
        window_end_s=win_end,
        ramp_start_s=r0,
        ramp_end_s=r1,
        motion_start_s=t_m,
        motion_end_s=t_e,
        rule_start_s=tm["a_t"],
        start_depth_m=d0,
        end_depth_m=d1,
        max_speed_m_s=vmax_arg,
        direction="down" if d1 > d0 else "up",
        oil_temp_c=oil if np.isfinite(oil) else hoist.oil.reference_temperature_c,
        p_before_pa=p_pre if np.isfinite(p_pre) else p_post,
        p_after_pa=p_post,
        levels_depth_m=tm["levels_depth"] if np.isfinite(tm["levels_depth"]) else d0,
        time_s=t[idx],
        measured_pa=meas,
        valid=valid,
        phase=profile_phases(driven, tau, hoist.winder.creep_speed_m_s),
        depth_m=driven.depth(tau),
        ramp_time_s=t[ridx],
        ramp_measured_pa=np.nanmedian(rec.p[ridx], axis=1),
        profile_fit_m=fit,
        cut=tm["cut"],
        motion_knots=knots,
        # a trip cut at its start: over the first seconds the record holds of it
        x_start_m=_pistons_before(
            rec, r0 if tm["cut"] != "start" else tm["a_t"] + PISTONS_BEFORE_S
        ),
    )


#: The logged piston positions a block starts from are their median over this long
#: before the trip's window [s] (the logger's 0.1 mm step and ~0.02 mm noise).
PISTONS_BEFORE_S = 2.0


def _pistons_before(rec: RecordArrays, t0: float) -> np.ndarray | None:
    """Each piston's logged position [m], the median over :data:`PISTONS_BEFORE_S`
    before ``t0`` (the first as long after it where the record starts there); None
    without a logged position of every piston there."""
    if rec.x is None:
        return None
    x = rec.x[time_span(rec.t, t0 - PISTONS_BEFORE_S, t0)]
    if not np.isfinite(x).any(axis=0).all():
        x = rec.x[time_span(rec.t, t0, t0 + PISTONS_BEFORE_S)]
    if x.shape[0] == 0 or not np.isfinite(x).any(axis=0).all():
        return None
    return np.nanmedian(x, axis=0)


def _planned_trips(
    rec: RecordArrays,
    hoist: HoistDescription,
    timing: list[dict[str, Any]],
    chosen: list[list[int]],
    trailing_ramp: float,
    rates: tuple[float, float],
    motion: str,
    notes: list[str],
) -> tuple[list[ReplayTrip], list[SkippedTrip]]:
    """Pass 2 over the ``chosen`` blocks: the planned trips and the skipped ones
    (``rates``: ``settle_s`` and ``score_rate_hz`` of :func:`plan_replay`).

    A block that does not start at the record's first trip (or right after the block
    before it) is preceded by its previous trip, simulated from rest but not compared:
    a block started from rest leaves the seals without the forces the trips before
    left in them, which with ropes of unequal stiffness decides which piston slides (on
    a validation trial with nothing hidden, a block's first trip replayed 61 kPa from
    rest and 8 kPa in a chain of 22 trips). A logger gap longer than the trip rule
    bridges (:data:`physics.trip_rule.TRIP_BRIDGE_S`) ends the window of a trip that ran
    into it, and a trip that does not start where the one before it ended (by more than the
    simulation's continuation tolerance) starts a new history, as a warm-up not compared:
    what happened in the gap is not logged. A trip is compared only up to a logger gap in
    the standstill after it that could hide a round trip or across which the depth
    changed, and a record holding less than :data:`~discovery.record.STANDSTILL_SEEN_S`
    before its first motion makes that trip a warm-up too
    (:func:`~discovery.record.trip_timing`)."""
    settle_s, score_rate_hz = rates
    motions = rec.motions
    trips: list[ReplayTrip] = []
    skipped: list[SkippedTrip] = []
    logged = motion == "logged"  # every planned trip follows the logged speed
    # a logger gap the trip rule did not bridge: what the conveyance did in it is not
    # logged, so the window of a trip that ran into it ends there (discovery.record:
    # cut) and the history restarts after it
    gap_starts = np.flatnonzero(np.diff(rec.t) > TRIP_BRIDGE_S)
    for b, block in enumerate(chosen):
        restart = True  # the next planned trip starts the block's history
        end_depth = float("nan")
        into_gap = False  # the last planned trip ran into a logger gap
        # the trip before the block, unless it is the previous block's last
        before = block[0] - 1
        warm_up = before if before >= 0 and (b == 0 or before > chosen[b - 1][-1]) else None
        for k in ([warm_up] if warm_up is not None else []) + block:
            tm = timing[k]
            if tm["skip"]:
                if k != warm_up:
                    skipped.append(SkippedTrip(tm["trip_id"], tm["a_t"], tm["skip"]))
                restart = True
                continue
            # after a trip that ran into a gap (its simulation stops there, wherever its
            # completion ends), or not where the last planned trip left the conveyance
            after_gap = (
                into_gap
                or tm["gap_before"]
                or tm["cut"] == "start"  # the record starts, or resumes, while it moves
                or tm["standstill_unseen"]  # ... or just before it moves
                or (
                    bool(np.isfinite(end_depth))
                    and not abs(tm["d0"] - end_depth) <= CONTINUATION_DEPTH_TOLERANCE_M
                )
            )
            restart = restart or after_gap
            next_ramp = timing[k + 1]["r0"] if k + 1 < len(motions) else trailing_ramp
            next_ramp = min(next_ramp, tm["ramp_before_gap"])
            win_end = window_end(tm["t_e"], next_ramp, settle_s, rec.end_t)
            ran_into_gap = bool(np.isin(motions[k][1], gap_starts))
            if ran_into_gap:  # compared up to the gap
                win_end = min(win_end, float(rec.t[motions[k][1]]))
            trip = _planned_trip(
                rec, hoist, k, tm, (b, restart), win_end, score_rate_hz, logged, notes
            )
            if np.isfinite(tm["gap_after"]):
                # a logger gap in the standstill after it that ends what is known of it:
                # compared up to the gap; the simulation still settles over the whole
                # window, as the next trip's history continues from where it settled
                before_gap = (trip.time_s <= tm["gap_after"])[:, None]
                trip = dataclasses.replace(trip, valid=trip.valid & before_gap)
            if k == warm_up or after_gap:
                # the trip before the block (or the first after a logger gap): simulated
                # from rest to load the seals' state (which pistons stick with what
                # force), not compared
                trip = dataclasses.replace(trip, valid=np.zeros_like(trip.valid))
            trips.append(trip)
            restart = False
            end_depth = tm["d1"]
            into_gap = ran_into_gap
    return trips, skipped


def _first_trip_id(rec: RecordArrays, number_from: dt.datetime | None) -> int:
    """The trip rule's id of the first trip with a sample at or after ``number_from``
    (the record's first trip without it; one past the last when none is)."""
    if number_from is None:
        return 0
    since = (number_from - rec.t_ref).total_seconds()
    spans = [(i, b) for (_, b), i in zip(rec.motions, rec.trip_ids, strict=True)]
    spans += [(i, b) for _, b, i in rec.short_trips]
    later = [i for i, b in spans if rec.t[b] >= since]
    return min(later) if later else max(i for i, _ in spans) + 1


def _short_trips(rec: RecordArrays, chosen: list[list[int]], first_id: int) -> list[SkippedTrip]:
    """The trips too short to replay (a jog), skipped with the reason: all of them when
    every trip is analysed, else those inside an analysed block."""
    t, motions = rec.t, rec.motions
    whole = sum(map(len, chosen)) == len(motions)
    spans = [(t[motions[block[0]][0]], t[motions[block[-1]][1]]) for block in chosen]
    return [
        SkippedTrip(
            trip_id - first_id, float(t[a]), f"moves {t[b] - t[a]:.1f} s: too short to replay"
        )
        for a, b, trip_id in rec.short_trips
        if whole or any(lo <= t[a] <= hi for lo, hi in spans)
    ]


def plan_replay(
    samples: pl.DataFrame,
    hoist: HoistDescription,
    *,
    max_trips: int | None = 12,
    blocks: int = 4,
    score_rate_hz: float = 20.0,
    settle_s: float = 30.0,
    dt_s: float = 2e-3,
    motion: str = "auto",
    number_from: dt.datetime | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    identified_ropes: IdentifiedFactors = None,
) -> ReplayPlan:
    """Segment ``samples`` of one hoist into trips and prepare their simulation.

    Longer than 80 lines on purpose: most of it is this docstring (every parameter
    documented); the code is its two passes over the trips, about 50 lines.

    Parameters
    ----------
    samples : polars.DataFrame
        Landed field samples (``time_utc``, ``p{i}_pa``, ``depth_m``, ``speed_m_s``,
        ``oil_temp_c``; SI), one hoist, any order.
    hoist : HoistDescription
        The hoist (winder limits, shaft, cylinders).
    max_trips, blocks : int (``max_trips`` also None)
        Analyse at most ``max_trips`` trips in ``blocks`` runs of consecutive trips
        (``max_trips`` None: every trip, one chain).
    score_rate_hz : float
        Rate of the scored samples and of the simulation output [Hz].
    settle_s : float
        Standstill simulated and scored after each stop [s].
    dt_s : float
        Integrator step of the replays [s].
    number_from : datetime, optional
        Number the trips as a run from this time numbers them: the first trip with a
        sample at or after it is trip 0 (earlier ones get negative ids); default the
        record's first sample. Either way the trips and their order are the pipeline's
        trip rule's (:mod:`physics.trip_rule`), so a check of the period
        ``[number_from, ...)`` names each trip as that period's ``trip_summary`` does.
    motion : {"auto", "winder", "logged"}
        What drives each trip's simulation: the hoist description's winder profile
        (constant acceleration, the top speed logged when it is 5 % off the described
        one), the encoder's logged speed (:mod:`sims.logged_motion`; jerk, per-trip
        acceleration and top speed as they were), or (``"auto"``, the default)
        whichever replays the first trips closer, chosen after the ropes' damping and
        stiffness spread (:func:`discovery.replay_choices.choose_motion`).
    parameters : mapping, optional
        Effect parameters (``{effect: {parameter: value}}``) of the hoist's
        ``[model] effects`` beyond its description's: the model the choices read off the
        record (ropes, motion) are made with, kept as ``ReplayPlan.parameters``
        (discovery re-reads them once an effect joins the model,
        :func:`discovery.record_rereading.discover_in_record`).
    identified_ropes : sequence of float, identified ropes or callable, optional
        The head ropes' stiffness factors as the compensation identified them from the
        logged piston positions (``RopeSprings.stiffness_factors``,
        :mod:`transforms.rope_identification`), scaled to a mean of 1; used instead of
        the stiffness spread unless they replay the first trips more than 10 % worse
        than the spread's choice (:func:`discovery.rope_stiffness.with_rope_stiffness`).
        Given with their length offsets (a ``RopeSprings``,
        :class:`discovery.rope_stiffness.IdentifiedRopes`), the plan keeps those
        (``ReplayPlan.rope_offsets_m``) and each block starts with its pistons where the
        record logged them (:func:`sims.replay.block_pistons`). None: the spread. Or a
        function of no argument returning one of those (or None), called after the
        spread's grid: the identification can run meanwhile
        (:data:`discovery.rope_stiffness.IdentifiedFactors`).

    Raises
    ------
    ValueError
        Required columns missing, no trip (motion of >= 3 s) in the record, or
        stiffness factors not one per rope.
    Exception
        Whatever an ``identified_ropes`` function raises.
    """
    if motion not in ("auto", "winder", "logged"):
        raise ValueError(f"motion: 'auto', 'winder' or 'logged', not {motion!r}")
    rec = read_record(samples, hoist)
    motions, t = rec.motions, rec.t
    # the ropes' damping as the record shows it (a hoist that rings and one that does not
    # both replay to the noise; the description's ratio is a default a mine cannot know)
    zeta, zeta_how = rope_damping_from_record(
        t, rec.pc_filled, [float(t[b_i]) for _, b_i in motions], rec.quiet
    )
    if zeta is None and rope_bounce_unseen(t):
        # logged too slowly to see the bounce (10 Hz and less): the record neither
        # confirms the description's ratio nor contradicts it, and that ratio is a default;
        # the replay gap decides among it and 0.1 / 0.3 / 1.0, as where no ringing is seen
        # (kept, the description's 0.02 rang where a 10 Hz validation trial does not and
        # failed every trip's sanity check, 27-58 kPa against 7-11 kPa at 50 Hz)
        zeta = 1.0
    notes: list[str] = []
    if max_trips is None:
        max_trips = len(motions)
    chosen = chosen_trips(len(motions), max_trips, blocks)
    if len(motions) > max_trips:
        notes.append(
            f"{len(motions)} trips in the record; analysed {sum(map(len, chosen))} in "
            f"{len(chosen)} blocks of consecutive trips, each later one after a warm-up trip"
        )
    # pass 1, every motion: start / stop times, top speed, loading ramp before it
    timing = [trip_timing(rec, hoist, k) for k in range(len(motions))]
    first_id = _first_trip_id(rec, number_from)
    for tm, trip_id in zip(timing, rec.trip_ids, strict=True):
        tm["trip_id"] = trip_id - first_id
    trailing_ramp = trailing_ramp_start(rec, timing, notes)

    def planned(kind: str) -> ReplayPlan:
        # pass 2, the analysed trips: windows, scored samples, the motion driving each
        said = list(notes)
        trips, skipped = _planned_trips(
            rec, hoist, timing, chosen, trailing_ramp, (settle_s, score_rate_hz), kind, said
        )
        return ReplayPlan(
            hoist=hoist,
            t_ref=rec.t_ref,
            trips=tuple(trips),
            noise_sigma_pa=rec.sigma,
            score_rate_hz=score_rate_hz,
            dt_s=dt_s,
            trips_found=len(motions),
            notes=tuple(said),
            skipped=(*skipped, *_short_trips(rec, chosen, first_id)),
            rope_bounce=zeta_how,
            parameters={k: dict(v) for k, v in (parameters or {}).items()},
        )

    # the ropes as the record shows them (discovery.replay_choices), then the motion
    plan = read_ropes(
        planned("winder" if motion == "winder" else "logged"),
        zeta,
        piston_slides_m(samples, hoist.ropes_n),
        identified_ropes,
    )
    return choose_motion(plan, planned("winder")) if motion == "auto" else plan
