"""Replay measured hoist trips through the device simulation.

The discovery workflow (issue 8) and the nightly sanity check (issue 7) compare what the
pressure sensors logged with what the device simulation (:func:`sims.device.simulate`)
predicts for the same trips. The trips come prepared from the log
(:func:`discovery.planning.plan_replay`: a :class:`~sims.replay_plan.ReplayPlan` with
motion, payload, oil temperature, loading ramps and the samples to score); here they
are simulated:

:func:`replay`
    Simulates the planned trips with a given effect set and parameters and returns the
    simulated sensor pressures at the scored measured timestamps. The trips of a block
    are one continuous history: each continues from the previous one's final state
    (``simulate(..., initial_state=...)``), as the field-day generator and a real hoist
    do. A block starts at rest with its pistons where the record logged them and the
    seals holding what the ropes leave them when the plan has the ropes' identified
    length offsets (:func:`block_pistons`), else in static equilibrium (equal
    tensions); its first trip is scored only after its loading ramp.
:func:`replay_fitted`
    :func:`replay` with the payloads fitted: the payload is the log's free input. It is
    inferred from the static pressure after loading, then corrected once from the
    per-trip mean common-mode residual (the pressure is linear in the payload to ~3 %
    through the pressure dependence of the seal friction, so a second pass leaves
    < 0.1 % of the first correction) and the trips re-simulated.

A trip the record cuts is simulated as planned (``ReplayTrip.cut``); one the simulation
refuses gets its reason in ``ReplayResult.trip_messages``, and the later trips of its
block are not simulated. A trip is driven by the logged motion when the plan holds it
(``ReplayTrip.motion_knots``, :mod:`sims.logged_motion`), else by the winder profile
(:func:`replay_profile`).

Speed: the blocks are independent histories and replay on :data:`REPLAY_THREADS`
threads (the integrator releases the GIL); :func:`replay_many` replays several runs of
one plan with all their blocks on one pool, the longest first (a discovery term's
finite-difference steps, its candidates switched on); :func:`side_by_side` runs a
choice's candidate fits side by side; :func:`replay_fitted`'s passes run as a
pipeline, each trip's next pass as soon as its own pass is done (a whole day's chain of
66 trips on validation day 104, three passes: 22.4 -> 11.9 s, the result the same to the
last bit; session 48); the Jacobian is refreshed every :data:`REPLAY_JACOBIAN_EVERY`
steps. On the independent simulator's trials records
(2 h, 12 trips in 4 blocks, 2 cores; ``benchmarks/eval_discovery.py --trials``)
``ropeload discover`` took a median 33.6 s, at most 48.2 s, a record on a machine ~2x slower
than session 43's (session 46: the device's ROS2 solve over the LU factors' nonzeros,
:func:`sims.hydraulics.lu_solve`; 64.8 s alone for trial_002 before, 47.7 s after); a
median 28.1 s, at most 43.5 s, at session 29 (the
device held where it is still at rest, :data:`sims.device_solver.QUIET_FRACTION`, and
the profile's segment found by bisection: one replay of validation trial_002's plan on
one thread 1.87 -> 1.02 s; 45.4 and 74.3 s at
session 28, on a machine ~20 % slower than at session 27); 37.7 and 63.1 s at session 27,
the Jacobian every 40th step and a walk stopped at a step the noise does not show; 36.5-39.1
and 62.5-68.9 s in three runs before that stop, the machine's CPU time wandering 10 %;
39.5 and 67.6 s at session 26, with the oil's bulk modulus walked down as well; 38.7
and 65.1 s before that walk; 58.8 and 106 s at session 25, with the branch losses walked
out from the description's, measured beside other work; 45.1 and 141 s at session 24,
when one record's second iteration refined a groove wear along its coordinates, 8
refitted replays one after the other, before refusing it; 44.6 and 72 s at session 23, with
discovery's columns reused after an effect is added, :mod:`discovery.record_rereading`;
49.5 and 94 s at session 22; 66.6 and 190 s with a Jacobian every 10th step and each
replay's blocks alone on the threads, 168 and 372 s on one thread).

Accuracy note: the device simulation's sensor pressures change by ~13 kPa RMS between
``dt_s`` = 2 ms and 5 ms (friction stick-slip transitions), so replaying synthetic data
at another step than it was generated with leaves a systematic gap of that size. The
default ``dt_s = 2 ms`` is the field-day generator's.
"""

from __future__ import annotations

import collections
import concurrent.futures
import contextlib
import contextvars
import dataclasses
import functools
import threading
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import AbstractContextManager
from itertools import pairwise
from typing import Any, TypeVar

import numpy as np

from physics.rope_spring import groove_payout_m
from schemas.hoist import G_STANDARD, HoistDescription
from sims.cores import usable_cores
from sims.device import DeviceState, SimulationResult, simulate
from sims.effects import resolve_effects
from sims.logged_motion import profile_from_knots
from sims.replay_inputs import (
    payload_from_pressure,
    replay_inputs,
    replay_profile,
    sensor_gain_offset,
)
from sims.replay_plan import ReplayPlan, ReplayResult, ReplayTrip, loading_threshold_pa

__all__ = [
    "CLOSER_SHARE",
    "first_trips_gap",
    "first_trips_gaps",
    "payload_from_pressure",
    "replay",
    "replay_fitted",
    "replay_many",
    "replay_profile",
    "side_by_side",
]

T = TypeVar("T")


def _simulate_trip(
    plan: ReplayPlan,
    tr: ReplayTrip,
    names: frozenset[str],
    prm: dict[str, dict[str, Any]],
    start: float,
    ramp_end: float,
    payloads: tuple[float, float],
    state: DeviceState | None,
) -> SimulationResult:
    """Simulate trip ``tr`` from ``start`` [s after ``t_ref``] on, from ``state`` (None:
    at rest, the pistons where :func:`block_pistons` puts them), its payload
    ``payloads`` (before, after) loaded until ``ramp_end``; driven by its logged motion
    when the plan holds it. Raises ``ValueError`` when the simulation refuses the trip."""
    if tr.motion_knots is not None and tr.motion_knots[0][-1] > start:
        profile = profile_from_knots(
            *tr.motion_knots,
            start_s=start,
            duration_s=max(tr.window_end_s - start, 1e-3),
            payload_time_s=np.array([0.0, ramp_end - start]),
            payload_kg=np.array([payloads[0], payloads[1]]),
            oil_temp_c=tr.oil_temp_c,
            direction=tr.direction,
        )
    else:
        profile = replay_profile(
            plan.hoist,
            tr.start_depth_m,
            tr.end_depth_m,
            tr.motion_start_s - start,
            tr.window_end_s - start,
            tr.max_speed_m_s,
            tr.oil_temp_c,
            (0.0, ramp_end - start),
            payloads[0],
            payloads[1],
        )
    return simulate(
        plan.hoist,
        profile,
        effects=names,
        parameters=prm,
        output_rate_hz=plan.score_rate_hz,
        dt_s=plan.dt_s,
        jacobian_every=REPLAY_JACOBIAN_EVERY,
        initial_state=state,
        pistons_m=(
            block_pistons(plan, tr, names, prm, float(profile.depth(profile.t0_s)))
            if state is None
            else None
        ),
    )


def block_pistons(
    plan: ReplayPlan,
    tr: ReplayTrip,
    names: frozenset[str],
    prm: Mapping[str, Mapping[str, Any]],
    depth_m: float,
) -> np.ndarray | None:
    """Where a block that starts with trip ``tr`` at ``depth_m`` puts its pistons [m,
    the ropes' frame]: where the record logged them, shifted by the ropes' identified
    length offsets and, with ``groove_wear`` among the simulation's effects ``names``,
    by each groove's payout there (x_i + c_i + z dr_i / R: rope i pulls with
    k_i (s - x_i - c_i - z dr_i / R), :func:`physics.rope_spring.groove_payout_m`, as
    the compensation's identification reads it; the radii as the simulation resolves
    them from ``prm`` and the description, :func:`sims.effects.resolve_effects`), so
    the ropes' imbalance, and with it what each seal holds, is the record's; None (where
    equal tensions put them) without the offsets or the logged positions.

    The groove's payout counts from the pithead, not from where a block starts: without
    it a block that starts deep in the shaft (a record cut mid-day, the up trips' blocks)
    started its grooves' ropes at the lengths of ropes without wear there, and a groove
    wear re-planned with the ropes identified under it replayed validation trial_009's
    second half at 35 kPa against 12.7 without it, both ways (session 57).

    Why: the seals hold the pistons wherever the history left them. Deep in the shaft
    the ropes are long and soft (their rate falls thirteen-fold from the pithead to the
    bottom of the validation shaft), so a seal's static friction holds a piston
    millimetres away from equal tensions; only near the pithead do the ropes move it.
    A block started with equal tensions at the middle level then slid its pistons
    7-10 mm apart on its first way up, where the record's moved 1-3 mm, and the seals'
    summed friction, sliding apart instead of presliding together, replayed the run's
    common-mode pressure up to 170 kPa off (an independent record with nothing hidden,
    validation trial_010).
    """
    if plan.rope_offsets_m is None or tr.x_start_m is None:
        return None
    x = np.asarray(tr.x_start_m, dtype=float) + np.asarray(plan.rope_offsets_m, dtype=float)
    if "groove_wear" in names:
        resolved = resolve_effects(plan.hoist, names, prm).parameters["groove_wear"]
        deviation = np.asarray(resolved["groove_radius_deviation_m"], dtype=float)
        x = x + groove_payout_m(depth_m, deviation / plan.hoist.drum.radius_m)
    return x if np.all(np.isfinite(x)) else None


def _at_scored_samples(
    tr: ReplayTrip, res: SimulationResult, start: float, n: int, prev_end: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """(sensor pressures at the scored samples (m, n), common-mode pressure at the ramp
    samples, end of the simulated time) of a trip simulated from ``start``."""
    t_sim = start + res.frame["time_s"].to_numpy()
    prev_end = float(t_sim[-1]) if t_sim.size else prev_end
    if not t_sim.size:
        return (*_not_simulated(tr, n), prev_end)
    sims = [res.frame[f"p_sensor{i}_pa"].to_numpy() for i in range(1, n + 1)]
    scored = np.column_stack([np.interp(tr.time_s, t_sim, s, right=np.nan) for s in sims])
    common = np.mean(sims, axis=0)
    ramp = np.interp(tr.ramp_time_s, t_sim, common, left=common[0], right=np.nan)
    return scored, ramp, prev_end


def replay(
    plan: ReplayPlan,
    *,
    effects: Iterable[str] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    payload_kg: Sequence[float] | np.ndarray | None = None,
    payload_before_kg: Sequence[float] | np.ndarray | None = None,
    ramps_s: np.ndarray | None = None,
) -> ReplayResult:
    """Simulate the planned trips; simulated sensor pressures at the scored samples.

    Parameters
    ----------
    plan : ReplayPlan
        From :func:`discovery.planning.plan_replay`.
    effects, parameters
        As :func:`sims.device.simulate` (default the hoist's ``[model] effects``).
    payload_kg : per-trip payload after loading [kg]; default inferred from the static
        pressure after loading (no friction correction: see :func:`replay_fitted`).
    payload_before_kg : per-trip payload before loading [kg]; only the first trip of a
        block uses it (later trips continue with the previous trip's payload).
    ramps_s : (m, 2) loading ramp start and end per trip [s after ``t_ref``]; default
        the plan's. A trip's simulation starts at its ramp start.

    Returns
    -------
    ReplayResult
        ``status="failed"`` with the reason when a trip's simulation failed (its and the
        block's later trips' pressures are NaN).
    """
    return replay_many(
        plan,
        [
            {
                "effects": effects,
                "parameters": parameters,
                "payload_kg": payload_kg,
                "payload_before_kg": payload_before_kg,
                "ramps_s": ramps_s,
            }
        ],
    )[0]


def replay_many(plan: ReplayPlan, runs: Sequence[Mapping[str, Any]]) -> list[ReplayResult]:
    """:func:`replay` of the plan with each keyword set of ``runs`` (``effects``,
    ``parameters``, ``payload_kg``, ``payload_before_kg``, ``ramps_s``; absent: the
    default), in order.

    The blocks of all the runs share one pool of :data:`REPLAY_THREADS` threads: a
    plan of a few blocks keeps both cores busy only while its longest block lasts, a
    dozen blocks of three runs keep them busy to the end. Each run's result is what
    :func:`replay` alone gives (each block is its own history, :func:`_block_runs`).
    """
    prepared = []
    for kw in runs:
        names = frozenset(plan.hoist.model.effects if kw.get("effects") is None else kw["effects"])
        prm = _parameters(plan, names, kw.get("parameters"))
        pay, pay_before, ramps = replay_inputs(
            plan, names, prm, kw.get("payload_kg"), kw.get("payload_before_kg"), kw.get("ramps_s")
        )
        prepared.append((names, prm, pay, pay_before, ramps))
    blocks = _blocks(plan)
    tasks = [_block_runs(plan, blocks, *p) for p in prepared]
    # a block's cost: its simulated seconds, from its first loading ramp to its last window
    costs = [
        plan.trips[block[-1]].window_end_s - plan.trips[block.start].ramp_start_s
        for block in blocks
    ]
    done = iter(_run_tasks([t for blocks in tasks for t in blocks], costs * len(tasks)))
    results = []
    for (names, prm, pay, pay_before, ramps), blocks in zip(prepared, tasks, strict=True):
        ran = [next(done) for _ in blocks]
        rows = [row for block_rows, _ in ran for row in block_rows]
        failures = [f for _, block_failures in ran for f in block_failures]
        results.append(_result(rows, failures, names, prm, (pay, pay_before, ramps)))
    return results


def _result(
    rows: Sequence[tuple[np.ndarray, np.ndarray, str]],
    failures: Sequence[str],
    names: frozenset[str],
    prm: dict[str, dict[str, Any]],
    inputs: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> ReplayResult:
    """A replay's result from its trips' rows (:func:`_block_runs`), in trip order, its
    blocks' failures and its inputs (payloads after and before loading, ramps)."""
    pay, pay_before, ramps = inputs
    return ReplayResult(
        simulated=tuple(r[0] for r in rows),
        payload_kg=pay,
        payload_before_kg=pay_before,
        effects=names,
        parameters=prm,
        status="failed" if failures else "success",
        message="; ".join(failures),
        ramp_simulated=tuple(r[1] for r in rows),
        ramps_s=ramps,
        trip_messages=tuple(r[2] for r in rows),
    )


def _parameters(
    plan: ReplayPlan,
    names: frozenset[str],
    parameters: Mapping[str, Mapping[str, Any]] | None,
) -> dict[str, dict[str, Any]]:
    """The effect parameters a replay uses: those given, else the plan's for the effects
    switched on (a replay of fewer effects leaves the others' out)."""
    given = plan.parameters if parameters is None else parameters
    return {k: dict(v) for k, v in given.items() if parameters is not None or k in names}


def _not_simulated(tr: ReplayTrip, n: int) -> tuple[np.ndarray, np.ndarray]:
    """NaN pressures at a trip's scored samples (m, n) and ramp samples."""
    return np.full((tr.time_s.size, n), np.nan), np.full(tr.ramp_time_s.size, np.nan)


_BlockRun = tuple[list[tuple[np.ndarray, np.ndarray, str]], list[str]]


def _block_runs(
    plan: ReplayPlan,
    blocks: list[range],
    names: frozenset[str],
    prm: dict[str, dict[str, Any]],
    pay: np.ndarray,
    pay_before: np.ndarray,
    ramps: np.ndarray,
    before: Callable[[int], None] | None = None,
    after: Callable[[int, tuple[np.ndarray, np.ndarray, str]], None] | None = None,
    gate: AbstractContextManager[Any] | None = None,
) -> list[Callable[[], _BlockRun]]:
    """One task per block of the plan (``blocks``, :func:`_blocks`), in trip order: each
    simulates its block's trips as one chained history and returns, per trip, (scored
    pressures, ramp common-mode pressure, why it was not simulated or "") and the
    block's failures. ``pay_before`` is updated in place: a block's later trips start
    with the previous trip's payload. ``before(k)`` is called before trip k reads its
    inputs (``pay[k]``, ``ramps[k]``: they may be filled in then), ``after(k, row)``
    with each trip's row, and each trip is simulated inside ``gate`` (a semaphore that
    bounds the simulations running at once; :func:`replay_fitted`'s passes).

    The blocks are independent histories, so the tasks may run on threads in any order
    (the integrator releases the GIL, :func:`sims.device_solver._run`); each block's
    result is what it is alone, so a replay is the same on any number of threads.
    """
    n = plan.hoist.ropes_n
    gate = contextlib.nullcontext() if gate is None else gate

    def run(block: range) -> _BlockRun:
        """One block's trips (indices ``block``), in order."""
        rows: list[tuple[np.ndarray, np.ndarray, str]] = []
        failures: list[str] = []
        state = None
        broken = ""
        prev_end = -np.inf
        for k in block:
            tr = plan.trips[k]
            if before is not None:
                before(k)
            if k != block.start:
                pay_before[k] = pay[k - 1]
            if broken:
                row = (*_not_simulated(tr, n), f"not simulated: {broken}")
            else:
                start = float(max(ramps[k, 0], prev_end))
                ramp_end = float(max(ramps[k, 1], start + 1e-3))
                try:
                    payloads = (float(pay_before[k]), float(pay[k]))
                    with gate:
                        res = _simulate_trip(plan, tr, names, prm, start, ramp_end, payloads, state)
                except ValueError as exc:
                    failures.append(f"trip {tr.trip_id}: {exc}")
                    broken = f"trip {tr.trip_id} before it could not be simulated ({exc})"
                    row = (*_not_simulated(tr, n), f"simulation failed: {exc}")
                else:
                    reason = ""
                    if not res.ok:
                        failures.append(f"trip {tr.trip_id}: {res.message}")
                        reason = f"simulation failed: {res.message}"
                        broken = (
                            f"trip {tr.trip_id} before it could not be simulated ({res.message})"
                        )
                    state = res.final_state
                    scored, ramp_sim, prev_end = _at_scored_samples(tr, res, start, n, prev_end)
                    row = (scored, ramp_sim, reason)
            rows.append(row)
            if after is not None:
                after(k, row)
        return rows, failures

    return [functools.partial(run, block) for block in blocks]


def _blocks(plan: ReplayPlan) -> list[range]:
    """The trip indices of each replay block, in order."""
    starts = [k for k, tr in enumerate(plan.trips) if k == 0 or tr.first_in_block]
    return [range(a, b) for a, b in pairwise([*starts, len(plan.trips)])]


def _run_tasks(tasks: Sequence[Callable[[], T]], costs: Sequence[float]) -> list[T]:
    """The tasks' results in order, on up to :data:`REPLAY_THREADS` threads (one in a
    thread that already takes a core, :data:`_ONE_THREAD`), the costliest started first
    (so that a long block does not start last and run alone)."""
    threads = 1 if _ONE_THREAD.get() else min(REPLAY_THREADS, len(tasks))
    if threads <= 1:
        return [task() for task in tasks]
    order = sorted(range(len(tasks)), key=lambda k: -costs[k])
    with ThreadPoolExecutor(max_workers=threads) as pool:
        futures = {k: pool.submit(tasks[k]) for k in order}
        try:
            return [futures[k].result() for k in range(len(tasks))]
        except BaseException:
            pool.shutdown(cancel_futures=True)  # the queued blocks would be thrown away
            raise


#: A replay refreshes the device simulation's finite-difference Jacobian every this many
#: steps (:func:`sims.device.simulate`; its own default is 10). ROS2 is a W-method,
#: second order for any Jacobian, and a step whose error jumps is retaken with a fresh
#: one, so an older Jacobian costs accuracy only through the error constant. Measured on
#: the first 8 trips of each validation day at ``dt_s`` = 2 ms, one thread, against a
#: Jacobian every step (session 22): every 10th step 1.9-6.1 Pa RMS in 2.36-2.55 s;
#: every 20th 3.7-13.0 Pa RMS (at most 204 Pa from every 10th, on the ringing day) in
#: 1.63-1.82 s; every 40th 5.9-27.8 Pa RMS in 1.39-1.73 s. Again in session 27 (2 h of
#: each day, 8 trips in 2 blocks, CPU seconds): every 20th 4.7-17.4 Pa RMS in 1.12-1.27 s,
#: every 40th 6.9-31.8 Pa RMS (at most 2.6 kPa in one sample, on the throttled valve of
#: day 103) in 1.00-1.19 s, every 80th 12.8-69.9 Pa RMS in 0.98-1.08 s. Against ~5 kPa of
#: sensor noise, and kPa that ``dt_s`` itself moves (module docstring), every 40th step
#: makes replays ~40 % faster than every 10th for nothing measurable; a discovery of a
#: 2 h record that adds an effect (validation trial_002) took 60 s instead of 67 s with
#: every 20th (one run each, back to back).
REPLAY_JACOBIAN_EVERY = 40

#: Threads a replay runs its blocks on (a fitted replay's pipelined passes simulate one
#: more at once, :class:`_FittedPasses`): the cores this process may use
#: (:func:`usable_cores`).
REPLAY_THREADS = usable_cores()


def _refine_ramp(
    tr: ReplayTrip, sim_ramp: np.ndarray, ramp: np.ndarray, dp_pay: float
) -> np.ndarray:
    """Gauss-Newton step on the loading ramp's start and end from the ramp residual.

    Shifting the ramp start by d0 and its end by d1 changes the simulated common-mode
    pressure by ``-dp/dt ((1 - u) d0 + u d1)`` (u: fraction of the ramp done); the
    payload correction ``dp_pay`` enters as ``u dp_pay``.
    """
    t = tr.ramp_time_s
    ok = np.isfinite(sim_ramp) & np.isfinite(tr.ramp_measured_pa)
    if ok.sum() < 6:
        return ramp
    dur = max(ramp[1] - ramp[0], 1e-3)
    u = np.clip((t - ramp[0]) / dur, 0.0, 1.0)
    slope = np.gradient(sim_ramp, t) if t.size > 1 else np.zeros_like(t)
    r = tr.ramp_measured_pa - sim_ramp - u * dp_pay
    jac = np.column_stack([-slope * (1.0 - u), -slope * u])[ok]
    if not np.all(np.isfinite(jac)) or np.linalg.norm(jac) == 0:
        return ramp
    step, *_ = np.linalg.lstsq(jac, r[ok], rcond=None)
    step = np.clip(step, -2.0, 2.0)
    new = ramp + step
    if new[1] <= new[0]:
        return ramp
    return new


def replay_fitted(
    plan: ReplayPlan,
    *,
    effects: Iterable[str] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    passes: int = 2,
    payload_kg: Sequence[float] | np.ndarray | None = None,
    ramps_s: np.ndarray | None = None,
) -> ReplayResult:
    """:func:`replay` with each trip's payload and loading-ramp timing fitted.

    The payload and the moment it was loaded are the log's free inputs. Pass 1 uses
    ``payload_kg`` (default: inferred from the static pressure) and the plan's ramps;
    each further pass adds ``mean common-mode residual x n A / g`` per trip to the
    payload (least squares for a common offset on every sensor), moves the ramp ends by a
    Gauss-Newton step on the common-mode residual over the ramp (the seal friction and
    the rope bounce delay the pressure behind the load, so the ramp seen in the pressure
    is not the load's) and re-simulates. When a pass simulates nothing, it is the result.
    A trip with no scored sample (a block's warm-up) has no residual to fit: where the
    scored trip after it stopped without a loading, it carries that trip's fitted
    payload from the second pass on (:meth:`_FittedPasses._warm_up_tie`), not the
    payload its own levels at rest imply, which hold what the seals held there.

    A trip's inputs in a pass are its own answer in the pass before (and the state its
    block's previous trip left in this pass), so the passes run as a pipeline
    (:class:`_FittedPasses`): a block's second pass follows its first a trip behind,
    on the cores a single long block (the sanity check's chain of a whole day) left
    idle. The result is the same as pass after pass, to the last bit.
    """
    hoist = plan.hoist
    names = frozenset(hoist.model.effects if effects is None else effects)
    parameters = _parameters(plan, names, parameters)
    gain, _ = sensor_gain_offset(hoist, names, parameters)
    scale = hoist.ropes_n * hoist.cylinders.bore_area_m2 / G_STANDARD / float(gain.mean())
    first = replay_inputs(plan, names, parameters, payload_kg, None, ramps_s)
    return _FittedPasses(plan, names, parameters, first, max(passes, 1), scale).run()


_Row = tuple[np.ndarray, np.ndarray, str]


class _Abandoned(RuntimeError):
    """A pass given up because another task of the same fit raised."""


class _FittedPasses:
    """Every pass of :func:`replay_fitted` (``first``: pass 1's payloads after and before
    loading and ramps; ``scale``: kg per Pa of common-mode residual), each block of each
    pass a task. Pass j's trip k waits for pass j-1's trip k, whose residual sets its
    payload and ramp. The tasks are queued pass by pass, so a task's inputs come from
    tasks queued before it: one thread (:data:`_ONE_THREAD`, or one core) runs them in
    that order, else each task has a thread and a semaphore lets at most
    :data:`REPLAY_THREADS` + 1 of them simulate at once (a task waiting for the pass
    before holds none; one more than the cores, as a trip's simulation holds the GIL
    while it prepares and reads out: validation day 104's chain of 66 trips, three passes,
    15.4 s with two, 11.9 s with three, 22.4 s pass after pass). A pass's rows are let
    go once the next pass has read them and the pass has simulated something (else it
    may be the result); a task that raises stops the others at their next trip, and its
    error is the one raised."""

    def __init__(
        self,
        plan: ReplayPlan,
        names: frozenset[str],
        prm: dict[str, dict[str, Any]],
        first: tuple[np.ndarray, np.ndarray, np.ndarray],
        passes: int,
        scale: float,
    ) -> None:
        self.plan, self.names, self.prm, self.scale = plan, names, prm, scale
        count = len(plan.trips)
        pay, pay_before, ramps = first
        self.inputs = [(pay, pay_before.copy(), ramps)] + [
            (np.full(count, np.nan), pay_before.copy(), np.full((count, 2), np.nan))
            for _ in range(passes - 1)
        ]
        self.rows: list[list[_Row | None]] = [[None] * count for _ in range(passes)]
        self.done = [[threading.Event() for _ in range(count)] for _ in range(passes)]
        self.finite = [False] * passes  # the pass simulated something (read by the next)
        self.stop = threading.Event()
        self.errors: list[BaseException] = []
        self.ties = [self._warm_up_tie(k) for k in range(count)]  # read by every pass

    def _wait(self, j: int, k: int, for_trip: int) -> None:
        """Until pass j's trip ``for_trip`` is done (none for j < 0); _Abandoned for pass
        j + 1's trip k when a task of the fit raised."""
        if j >= 0:
            self.done[j][for_trip].wait()
        if self.stop.is_set():
            raise _Abandoned(f"replay pass {j + 2} of trip {k} given up")

    def before(self, j: int, k: int) -> None:
        """Pass j's payload and ramp of trip k from pass j-1's answer for it."""
        self._wait(j - 1, k, k)
        if not j:
            return
        row = self.rows[j - 1][k]
        assert row is not None  # set before its event, freed only after this read
        tr = self.plan.trips[k]
        dp = self._offset(j - 1, k)
        pay, _, ramps = self.inputs[j]
        pay[k] = np.maximum(self.inputs[j - 1][0][k] + dp * self.scale, 0.0)
        if self.ties[k]:  # the scored trip after it, no loading between: its fitted
            # payload, as before(j, k + 1) will set it
            self._wait(j - 1, k, k + 1)
            fitted = self.inputs[j - 1][0][k + 1] + self._offset(j - 1, k + 1) * self.scale
            pay[k] = np.maximum(fitted, 0.0)
        ramps[k] = _refine_ramp(tr, row[1], self.inputs[j - 1][2][k], dp)
        if np.isfinite(row[0]).any():
            self.finite[j - 1] = True
        if self.finite[j - 1]:  # not this pass's result: let its rows go
            self.rows[j - 1][k] = None

    def _offset(self, j: int, k: int) -> float:
        """Pass j's mean common-mode residual of trip k over its scored samples [Pa] (0
        where it has none)."""
        row = self.rows[j][k]
        assert row is not None  # read before the next pass lets it go
        tr = self.plan.trips[k]
        r = np.where(tr.valid, tr.measured_pa - row[0], np.nan)
        return float(np.nanmean(r)) if np.isfinite(r).any() else 0.0

    def _warm_up_tie(self, k: int) -> bool:
        """Whether trip k only loads the seals' state (no scored sample: a block's
        warm-up) and the scored trip after it in its block stopped without a loading
        (its levels at rest before and after within :func:`sims.replay_plan.
        loading_threshold_pa` of each other): the payload is the same on both sides of
        that stop, so the warm-up's is the scored trip's fitted one.

        A warm-up's own payload is no fit's: read from its levels at rest
        (:func:`sims.replay_inputs.static_payloads_kg`), it holds whatever the seals held
        there (up to ~4 x F_s, some 800 kg on the validation hoist), and the scored trip
        after it starts from it: its fitted payload then differs by a loading the record
        does not show, which the replay plays at its window's start (validation
        trial_001 with a 5 min outage: a block's second trip, stopped at the middle
        without a loading, 137 kPa off at its window's start and 36.5 kPa RMS over the
        trip, 9.6 kPa tied). Where the stop shows a loading, its level change is no
        better a measure of it than the warm-up's levels (the seals take part of a
        loading at rest too: tied across such stops, validation trial_004's gap went
        9.8 -> 10.8 kPa), and the warm-up keeps its own."""
        trips = self.plan.trips
        if k + 1 >= len(trips) or trips[k + 1].first_in_block:
            return False
        warm, scored = trips[k], trips[k + 1]
        if warm.valid.any() or not scored.valid.any():
            return False
        change = abs(scored.p_after_pa - scored.p_before_pa)
        return bool(change <= loading_threshold_pa(self.plan.noise_sigma_pa))

    def after(self, j: int, k: int, row: _Row) -> None:
        self.rows[j][k] = row
        self.done[j][k].set()

    def task(self, j: int, run: Callable[[], _BlockRun], block: range) -> list[str]:
        """Block ``block`` of pass j; its failures (its rows are kept by :meth:`after`)."""
        try:
            return run()[1]
        except _Abandoned:
            raise
        except BaseException as error:
            self.errors.append(error)
            self.stop.set()
            raise
        finally:  # a task that raised: the next pass's waits end (and give up)
            for k in block:
                self.done[j][k].set()

    def run(self) -> ReplayResult:
        blocks = _blocks(self.plan)
        gate = threading.BoundedSemaphore(REPLAY_THREADS + 1)
        tasks = []
        for j, (pay, pay_before, ramps) in enumerate(self.inputs):
            hooks = (functools.partial(self.before, j), functools.partial(self.after, j), gate)
            runs = _block_runs(self.plan, blocks, self.names, self.prm, pay, pay_before, ramps,
                               *hooks)  # fmt: skip
            tasks += [
                functools.partial(self.task, j, *job) for job in zip(runs, blocks, strict=True)
            ]
        if _ONE_THREAD.get() or REPLAY_THREADS <= 1 or len(tasks) <= 1:
            failures = [task() for task in tasks]
        else:  # every task its thread: those waiting take no core, the gate bounds the rest
            with ThreadPoolExecutor(max_workers=len(tasks)) as pool:
                futures = [pool.submit(task) for task in tasks]
                try:
                    concurrent.futures.wait(futures)
                except BaseException:  # interrupted: the tasks give up at their next trip
                    self.stop.set()
                    raise
            if self.errors:
                raise self.errors[0]
            failures = [future.result() for future in futures]
        last = len(self.inputs) - 1
        # the first pass that simulated nothing is the result: nothing to fit
        j = next((j for j in range(last) if not self.finite[j]), last)
        of_pass = failures[j * len(blocks) : (j + 1) * len(blocks)]
        return self.result(j, [failure for block in of_pass for failure in block])

    def result(self, j: int, failures: list[str]) -> ReplayResult:
        """Pass j's result (every row of it still held: its last, or it simulated nothing)."""
        rows = [row for row in self.rows[j] if row is not None]
        assert len(rows) == len(self.plan.trips)
        return _result(rows, failures, self.names, self.prm, self.inputs[j])


#: A choice the replay reads off the record (the ropes' damping and stiffness spread, the
#: motion driving the trips) replaces the description's default only when the first
#: trips' replay gap falls below this share of the default's.
CLOSER_SHARE = 0.9


def first_trips_gap(
    plan: ReplayPlan, hoist: HoistDescription | None = None, trips: int = 3
) -> float:
    """RMS gap [Pa] of the plan's first block's first ``trips`` compared trips (and the
    warm-ups among them, :func:`_first_compared`) replayed with
    ``hoist`` (default the plan's), payloads fitted (two passes); inf when nothing was
    simulated. The yardstick the replay's choices from the record use (the ropes'
    damping and stiffness spread, the motion that drives the trips).

    The choices of one plan ask for the same replay more than once (the ropes they
    kept, then the motion with them; the damping again with the stiffness chosen), so
    the last :data:`_REMEMBERED_GAPS` answers are remembered, keyed by the very trip
    objects (frozen, their arrays read-only) and an equal hoist and replay settings.
    """
    block = _first_compared(plan, trips)
    trial = dataclasses.replace(plan, hoist=plan.hoist if hoist is None else hoist, trips=block)
    with _GAPS_LOCK:
        for known, gap in _GAPS:
            if _same_replay(known, trial):
                return gap
    gap = replay_fitted(trial, passes=2).rms_gap_pa(trial)
    gap = gap if np.isfinite(gap) else float("inf")
    with _GAPS_LOCK:
        _GAPS.append((trial, gap))
    return gap


def _first_compared(plan: ReplayPlan, trips: int) -> tuple[ReplayTrip, ...]:
    """The first block's trips up to its ``trips``-th compared one (a warm-up after a
    logger gap, whose samples are not compared, is replayed but not counted: three
    trips with one warm-up among them judged a choice on two)."""
    chosen: list[ReplayTrip] = []
    compared = 0
    for tr in plan.trips:
        if tr.block != plan.trips[0].block or compared >= trips:
            break
        chosen.append(tr)
        compared += bool(tr.valid.any())
    return tuple(chosen)


def first_trips_gaps(
    replays: Sequence[tuple[ReplayPlan, HoistDescription | None]], trips: int = 3
) -> list[float]:
    """:func:`first_trips_gap` of each ``(plan, hoist)``, side by side
    (:func:`side_by_side`: the candidates of a choice are independent replays)."""
    return side_by_side([functools.partial(first_trips_gap, p, h, trips) for p, h in replays])


def side_by_side(calls: Sequence[Callable[[], T]]) -> list[T]:
    """The results of ``calls`` (each a function of no argument running replays), in
    order, computed on up to :data:`REPLAY_THREADS` threads, each call's replays running
    their blocks one after the other (the cores are taken by the calls); one after the
    other in a thread that already takes a core (:data:`_ONE_THREAD`).

    For fits of several passes each (the candidates of a replay choice, on a few
    trips of one block; a discovery refit's starts, when more than one is replayed):
    side by side they use the cores that one fit's replays leave idle. (Replays of one
    plan in one pass share their blocks' threads instead: :func:`replay_many`.) Each
    replay's result is the same either way.
    """
    return _run_tasks([functools.partial(_alone, call) for call in calls], [0.0] * len(calls))


def _alone(call: Callable[[], T]) -> T:
    """``call()`` with its replays' blocks one after the other (:data:`_ONE_THREAD`)."""
    token = _ONE_THREAD.set(True)
    try:
        return call()
    finally:
        _ONE_THREAD.reset(token)


#: Set in a thread that already takes a core of its own: its replays run their blocks
#: one after the other.
_ONE_THREAD: contextvars.ContextVar[bool] = contextvars.ContextVar("one_thread", default=False)


#: How many first-trips gaps :func:`first_trips_gap` remembers (a plan's choices ask
#: for a dozen at most; each keeps its few trips alive).
_REMEMBERED_GAPS = 16
_GAPS: collections.deque[tuple[ReplayPlan, float]] = collections.deque(maxlen=_REMEMBERED_GAPS)
_GAPS_LOCK = threading.Lock()


def _same_replay(a: ReplayPlan, b: ReplayPlan) -> bool:
    """The two plans replay alike: the same trip objects, equal hoists and settings."""
    return (
        len(a.trips) == len(b.trips)
        and all(x is y for x, y in zip(a.trips, b.trips, strict=True))
        and (a.t_ref, a.dt_s, a.score_rate_hz, a.noise_sigma_pa)
        == (b.t_ref, b.dt_s, b.score_rate_hz, b.noise_sigma_pa)
        and a.parameters == b.parameters
        and a.hoist == b.hoist
        and a.rope_offsets_m == b.rope_offsets_m
    )
