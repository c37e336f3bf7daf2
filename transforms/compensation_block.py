"""One call of :func:`transforms.compensation.compensate_window`: the steps on a block.

:class:`BlockCompensation` holds a block's arrays and runs the compensation's steps
(module docstring of :mod:`transforms.compensation`) as jobs on a thread pool: the
pressure filters, the displacements, the trip labels and the viscosity first; the
oil's common mode on the calling thread; each rope (its share of the piston motion,
play operator, branch flow, friction and tensions) as soon as its inputs are ready.
The numba kernels and large numpy operations release the GIL, so the jobs run side by
side. Each first-stage kernel runs twice, up to the hand-over of the next block and
beyond it (:meth:`BlockCompensation.staged`), so the carried state is the one the next
block resumes from. What the steps read before any of them runs (times, bounds,
friction mode, oil temperature) is set up in :mod:`transforms.compensation_setup`.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import polars as pl

from physics.closed_volume import common_mode_displacement, common_mode_per_pa
from physics.trip_rule import trip_label_codes, trip_label_columns
from schemas.tables import ROPES
from transforms.band_members import (
    STEADY_SIGMAS,
    group_mean,
    group_sum,
    held,
    mean_starts,
    mean_steps,
)
from transforms.compensation_kernels import (
    differential_smooth,
    rope_kernel,
    smoothed_noise,
    viscosity,
)
from transforms.compensation_output import block_frame
from transforms.compensation_record import (
    CompensationCarry,
    at_rest,
    calibrated,
    disagreeing_as_unknown,
    float_column,
    mean_horizontal,
    rope_cols,
)
from transforms.compensation_setup import BlockSetup
from transforms.filtering import despike_median3, despiked_lowpass, play_kernel
from transforms.kinematics import smoothed_derivative
from transforms.lowpass import lowpass_work_size
from transforms.piston_motion import share_out_common_motion
from transforms.seal_drift import (
    drift_cutoff_hz,
    drift_pressure,
    played_travels_into,
    ringing_travel,
)
from transforms.stick_slip import stick_slip
from transforms.stick_slip_band import BAND_SOURCES, BandSolution, band_groups, band_solutions
from transforms.stop_continuity import (
    LOOK_AHEAD_S,
    ContinuityInputs,
    apply_stop_continuity,
)
from transforms.uncertainty import ensemble_band, rope_band

__all__ = ["BlockCompensation", "prior_mean"]

Kernel = Callable[[int, int, np.ndarray], None]


@dataclass(frozen=True)
class _SpringInputs:
    """What :func:`~transforms.stick_slip.stick_slip` reads, per sample or per mean: the
    filtered pressures, the logged displacements, depth, segment, viscosity (one value or
    per sample), the drift's pressure and play half-width, the ringing's travel."""

    pressures: tuple[np.ndarray, ...]
    logged: tuple[np.ndarray, ...]
    depth: np.ndarray
    segment: np.ndarray
    nu: np.ndarray
    drift_p: np.ndarray | None
    drift_w: float
    ringing: np.ndarray | None


def _continues(segment: np.ndarray, at: int) -> float:
    """1.0 when sample ``at`` continues the gap-free segment of sample ``at - 1``."""
    return 1.0 if 0 < at < segment.size and segment[at] == segment[at - 1] else 0.0


class BlockCompensation(BlockSetup):
    """The compensation of one block: its arrays, its steps and their scheduling.

    ``frame`` holds the block and its margins (time-sorted, the columns
    :func:`transforms.compensation.compensate_window` reads, at least one row);
    ``carry`` the state the previous block left (None: the record's first block).
    :meth:`run` returns the block's ``ROPE_TENSIONS`` rows and the state for the next.
    The constructor and the block's constants are :class:`~transforms.compensation_setup.
    BlockSetup`'s.
    """

    # -- helpers --------------------------------------------------------------------------
    def buffer(self, name: str, size: int) -> np.ndarray:
        """A work array reused per thread: every fresh 70 MB array costs page faults, and
        freeing one interrupts the other thread (TLB shootdown), which cost more than the
        arithmetic of a rope."""
        arrays = self.local.__dict__.setdefault("arrays", {})
        if name not in arrays or arrays[name].size < size:
            arrays[name] = np.empty(size)
        return arrays[name][:size]

    def staged(
        self,
        run: Kernel,
        seg: np.ndarray,
        state: np.ndarray,
        bounds: tuple[int, int, int] | None = None,
    ) -> np.ndarray:
        """Run a first-stage kernel over [stage_lo, stage_hi) resuming ``state``; returns
        its state at the hand-over to the next block. ``bounds``: (stage_lo, hand-over,
        stage_hi) in other units than the samples (the band members' means)."""
        lo, handover, hi = bounds or (self.stage_lo, self.handover, self.stage_hi)
        state = state.copy()
        state[1] = _continues(seg, lo)
        run(lo, handover, state)
        saved = state.copy()
        state[1] = _continues(seg, handover)
        run(handover, hi, state)
        return saved

    # -- steps ----------------------------------------------------------------------------
    def pressure(self, column: str) -> np.ndarray:
        """Calibrated, despiked and low-passed, all in one new array; NaN where the
        sensor flat-lines (:func:`transforms.compensation_record.flatlined_samples`)."""
        values = calibrated(self.frame, column, self.hoist)
        if column in self.flatlined:
            values[self.flatlined[column]] = np.nan
        rate, cutoff = self.context.sample_rate_hz, self.settings.pressure_cutoff_hz
        work = self.buffer(
            "work_a", lowpass_work_size(self.n, sample_rate_hz=rate, cutoff_hz=cutoff)
        )
        return despiked_lowpass(
            values,
            self.segment,
            sample_rate_hz=rate,
            cutoff_hz=cutoff,
            spike_sigmas=self.settings.spike_sigmas,
            sigma=self.context.spike_sigma.get(column),
            work=work,
        )  # the work array: the rope jobs reuse it on this thread

    def displacement(self, column: str) -> np.ndarray:
        """A logged displacement, despiked (NaN where not logged)."""
        frame = self.frame
        values = float_column(frame[column]) if column in frame.columns else np.full(self.n, np.nan)
        sigma = self.context.spike_sigma.get(column)
        n_sigmas = self.settings.spike_sigmas
        return despike_median3(values, self.segment, n_sigmas=n_sigmas, out=values, sigma=sigma)[0]

    def kinematics(self) -> tuple[np.ndarray, dict[str, pl.Series]]:
        """Conveyance acceleration, then the trip labels that depend on it."""
        # unknown where neither speed nor depth is logged: standing still, as before
        speed = np.where(np.isnan(self.speed), 0.0, self.speed)
        accel = smoothed_derivative(
            speed, self.segment, dt_s=self.dt_nominal,
            window_s=self.settings.acceleration_window_s, time_s=self.time_s,
        )  # fmt: skip
        depth = float_column(self.frame["depth_m"])
        state = self.carry.labels.copy()
        state[1] = _continues(self.segment, self.core_lo)
        core = slice(self.core_lo, self.core_hi)
        labels = trip_label_columns(
            self.time_s[core], speed[core], depth[core], accel[core], self.segment[core],
            self.hoist, state,
        )  # fmt: skip
        self.nxt.labels = state
        return accel, labels

    def smoothed_logged(self, k: int) -> np.ndarray | None:
        """Rope k's logged displacement, smoothed and played (None without a logged x, or
        when the stick-slip solution on the identified ropes replaces the share-out)."""
        if not self.context.has_x or self.mode == 3:
            return None
        smooth = differential_smooth(
            self.x_jobs[k].result(), self.long_bounds, self.settings, buffer=self.buffer
        )
        # the result is a per-thread work array: played into a copy of its own
        played = np.empty(self.n)
        sigma = self.context.displacement_sigma_m[k]
        half_width = 3.0 * sigma * smoothed_noise(self.settings)
        long_segment = self.long_segment

        def run(lo: int, hi: int, state: np.ndarray) -> None:
            play_kernel(smooth[lo:hi], long_segment[lo:hi], half_width, played[lo:hi], state)

        self.nxt.differential[k] = self.staged(run, long_segment, self.carry.differential[k])
        return played

    def piston_motion(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """Each piston's displacement (the common mode shared out by the logged motion)
        and its blind motion since last seen sliding (:mod:`transforms.piston_motion`)."""
        if self.mode == 3:
            return self.stick_slip_motion()
        logged = [job.result() for job in self.smooth_jobs]
        common = self.common_mode.result()
        n = self.n
        if any(d is None for d in logged):
            never_seen = np.full(n, np.inf)  # pressure only: no piston is seen sliding
            # shared by the ropes: not overwritten
            return tuple(common for _ in ROPES), tuple(never_seen for _ in ROPES)
        blind = tuple(np.empty(n) for _ in ROPES)
        presliding_range_m, segment = self.presliding_range_m, self.segment

        def run(lo: int, hi: int, state: np.ndarray) -> None:
            _, parts = share_out_common_motion(
                common[lo:hi],
                tuple(d[lo:hi] for d in logged),
                segment[lo:hi],
                overwrite_logged=True,  # the smoothed copies are this job's own
                elastic_half_width_m=len(ROPES) * presliding_range_m,
                # from any state, a seal saturates once it has moved 2 F_s / sigma_0
                seen_reset_m=2.0 * presliding_range_m,
                state=state,
            )
            for whole, part in zip(blind, parts, strict=True):
                whole[lo:hi] = part

        self.nxt.share = self.staged(run, segment, self.carry.share)
        return tuple(logged), blind

    def stick_slip_motion(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """Each piston's displacement and friction from its identified rope spring
        (:mod:`transforms.stick_slip`; where nothing identifies the ropes the friction is
        the mean over their prior spread, :func:`prior_mean`, the displacement that of
        the ropes alike) over the first stage, and the frictions of the
        band's members (:func:`~transforms.stick_slip_band.band_solutions`; at the sensors'
        rate, or on means with ``band_member_step_s``: :meth:`member_spreads`); the
        frictions are kept for the ropes' jobs. NaN outside the stage and, with the stop
        continuity, the look-ahead past it that its rest windows and the next trips' runs
        read (``spring_hi``).
        Blind motion: none."""
        n, springs = self.n, self.context.rope_springs
        rest = at_rest(self.frame)
        # a filtered step reaches 3 / cut-off seconds either side
        reach = int(np.ceil(3.0 * self.settings.sample_rate_hz / self.settings.pressure_cutoff_hz))
        given = tuple(job.result() for job in self.p_jobs)
        pressures = disagreeing_as_unknown(
            given, rest, self.disagreement.disagreement_fraction, reach,
            self.disagreement.disagreement_floor_pa,
        )  # fmt: skip
        offset = self.offset_sensors()
        if any(offset):  # off the others at the record's rests: no pressure anywhere
            # (compensation_record.offset_sensors); the others carry the oil
            pressures = tuple(
                np.full(n, np.nan) if o else p for p, o in zip(pressures, offset, strict=True)
            )
        if any(p is not g for p, g in zip(pressures, given, strict=True)):
            # a sensor off the others at rest: the bands reach the others' reading too
            # (transforms.uncertainty.disagreeing_sensor_shifts); an offset sensor's rope
            # takes the others' reading instead (:meth:`rope`)
            self.off_sensors = tuple(
                np.isnan(p) & np.isfinite(g) & (not o)
                for p, g, o in zip(pressures, given, offset or (False,) * len(ROPES), strict=True)
            )
        logged = tuple(job.result() for job in self.x_jobs)
        if not np.isfinite(springs.mismatch_m):  # not identified from this record (the
            # description's ropes or their prior spread): no length offsets, so an x
            # logged for some ropes only would be a start without them
            logged = tuple(np.full(n, np.nan) for _ in logged)
        depth = float_column(self.frame["depth_m"])
        nu = np.atleast_1d(np.asarray(self.nu_job.result(), dtype=float))
        drift_p, drift_w = self.drift_pressure(pressures)
        ringing = None
        if drift_p is not None:
            ringing = ringing_travel(
                drift_p, self.segment, depth, rest, self.hoist,
                sample_rate_hz=self.context.sample_rate_hz,
                pressure_cutoff_hz=self.settings.pressure_cutoff_hz, half_width_pa=drift_w,
            )  # fmt: skip
        members = band_solutions(springs, self.law_sigma, ringing=ringing is not None)
        self.member_sources = band_groups(members)
        inputs = _SpringInputs(
            pressures, logged, depth, self.segment, nu, drift_p, drift_w, ringing
        )
        x = tuple(np.full(n, np.nan) for _ in ROPES)
        friction = tuple(np.full(n, np.nan) for _ in ROPES)

        # only on ropes identified from the record's x: with their prior the runs are
        # as far off as the stops (transforms.stop_continuity), whose shifts relax with
        # the estimate's drifting seals
        continuity = self.settings.stop_continuity and np.isfinite(springs.mismatch_m)
        relaxation = np.zeros((n, len(ROPES))) if continuity and drift_p is not None else None

        def run(lo: int, hi: int, state: np.ndarray) -> None:
            self.solve_springs(
                inputs, members[0], lo, hi, state, (x, friction), self.dt_nominal,
                relaxation=relaxation,
            )  # fmt: skip

        # the stop continuity looks this far past the stage: a departure within BACK_S
        # of it, the next trip's steady run after it (transforms.stop_continuity)
        self.spring_hi = self.stage_hi
        if continuity and self.stage_hi > self.stage_lo:
            reach = self.time_s[self.stage_hi - 1] + LOOK_AHEAD_S
            self.spring_hi = int(np.searchsorted(self.time_s, reach, side="right"))
        spring_bounds = (self.stage_lo, self.handover, self.spring_hi)

        step_s = self.settings.band_member_step_s
        self.nxt.springs = self.carry.springs.copy()
        spread = None
        on_means = step_s > 0 and len(members) > 1
        # a ringing member where nothing rings, resuming from the estimate's state, is
        # the estimate bit for bit (its travel x 0): copied, not solved
        others = range(1, len(members))
        copied = [] if on_means else [m for m in others if self.is_estimate(inputs, m, members)]
        solved = [m for m in others if m not in copied]
        # the prior's sigma points make the estimate (prior_mean): at the sensors' rate
        points = [m for m in others if members[m].source == "stiffness"]
        # the kernel releases the GIL: the members run beside the estimate
        with ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
            estimate = pool.submit(
                self.staged, run, self.segment, self.carry.estimate, spring_bounds
            )
            if on_means:
                spread = self.member_spreads(inputs, members, step_s, pool, at_rate=points)
            else:
                at_rate = functools.partial(self.member_at_rate, inputs)
                found = pool.map(at_rate, solved, [members[m] for m in solved])
                frictions = dict(zip(solved, found, strict=True))
            self.nxt.estimate = estimate.result()
        if not on_means:
            for m in copied:  # copies: the rope kernel writes the estimate's in place
                frictions[m] = tuple(f.copy() for f in friction)
                self.nxt.springs[m] = self.nxt.estimate.copy()
            self.member_friction = [frictions[m] for m in range(1, len(members))]
        if spread is not None:  # the estimate plus each member's difference
            self.member_friction = [
                deltas
                if m in points
                else tuple(f + d for f, d in zip(friction, deltas, strict=True))
                for m, deltas in zip(others, spread, strict=True)
            ]
        if springs.prior_sigma > 0:  # the description's ropes join the band as a member
            self.member_friction.append(prior_mean(friction, self.member_friction, members[1:]))
            self.member_sources += (BAND_SOURCES.index("stiffness"),)
        self.spring_friction = friction
        if continuity:  # ropes identified from the record's x: its runs hold the load
            self.stop_continuity(x, [friction, *self.member_friction], depth, pressures, relaxation)
        return x, tuple(np.zeros(n) for _ in ROPES)

    def stop_continuity(
        self,
        x: tuple[np.ndarray, ...],
        frictions: list[tuple[np.ndarray, ...]],
        depth: np.ndarray,
        pressures: tuple[np.ndarray, ...],
        relaxation: np.ndarray | None = None,
    ) -> None:
        """The seals' friction of every solution at each arrival set by the load's
        continuity from the trip's steady run, and before each departure by that to the
        next trip's (:mod:`transforms.stop_continuity`), in place, over the first stage;
        its state carried at the hand-over. ``relaxation``: the estimate's drift
        exponents (:func:`transforms.stick_slip.stick_slip`'s ``relaxation_out``)."""
        accel, _ = self.kinematics_job.result()
        speed = np.where(np.isnan(self.speed), 0.0, self.speed)
        phase, _, _ = trip_label_codes(self.time_s, speed, accel, self.segment, depth, self.hoist)
        area = self.hoist.cylinders.bore_area_m2
        springs = self.context.rope_springs
        factors = np.asarray(springs.stiffness_factors, dtype=float)
        inputs = ContinuityInputs(
            self.time_s, phase, depth, mean_horizontal(list(pressures)) * area * len(ROPES),
            x, factors / factors.sum(), self.presliding_range_m, self.dt_nominal,
            self.presliding_range_m * float(self.law.bristle_stiffness_n_m) or np.inf,
            relaxation,
        )  # fmt: skip

        def run(lo: int, hi: int, state: np.ndarray) -> None:
            apply_stop_continuity(inputs, frictions, lo, hi, state, self.hoist)

        self.nxt.continuity = self.staged(run, self.segment, self.carry.continuity)

    def is_estimate(self, inputs: _SpringInputs, m: int, members: list[BandSolution]) -> bool:
        """Member m solves as the estimate over this block's stage: it differs from it
        only by its ringing factor, nothing rings over the stage, and it resumes from
        the estimate's state (NaN where the estimate's is)."""
        member, estimate = members[m], members[0]
        if member._replace(ringing_scale=1.0, source="") != estimate._replace(source=""):
            return False
        ringing = inputs.ringing
        if ringing is not None and ringing[self.stage_lo : self.spring_hi].any():
            return False
        return np.array_equal(self.carry.springs[m], self.carry.estimate, equal_nan=True)

    def solve_springs(
        self,
        inputs: _SpringInputs,
        member: BandSolution,
        lo: int,
        hi: int,
        state: np.ndarray,
        out: tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]],
        dt_s: float | np.ndarray,
        travel: np.ndarray | None = None,
        relaxation: np.ndarray | None = None,
    ) -> None:
        """:func:`~transforms.stick_slip.stick_slip` of one solution over [lo, hi) of
        ``inputs`` (samples, or means with the drift's ``travel`` given, the member's
        ringing in it); ``relaxation`` (samples x pistons) takes its seals' drift exponents."""
        capacity_scale, sigma0_scale, ropes, start, ringing_factor, _ = member
        nu = inputs.nu
        drift_p = None if inputs.drift_p is None or travel is not None else inputs.drift_p[lo:hi]
        ringing = None
        if inputs.ringing is not None and drift_p is not None:
            ringing = inputs.ringing[lo:hi]
            ringing = ringing * ringing_factor if ringing_factor != 1.0 else ringing
        stick_slip(
            tuple(p[lo:hi] for p in inputs.pressures), tuple(v[lo:hi] for v in inputs.logged),
            inputs.depth[lo:hi], inputs.segment[lo:hi], self.hoist, ropes,
            dt_s=dt_s[lo:hi] if np.size(dt_s) > 1 else dt_s,
            nu_m2_s=nu[lo:hi] if nu.size > 1 else nu,
            branch=self.branch if self.with_branch_loss else None, state=state,
            capacity_scale=capacity_scale, sigma0_scale=sigma0_scale,
            start_at_capacity=start, drift_half_width_pa=inputs.drift_w,
            drift_pressure_pa=drift_p,
            drift_travel_pa=None if travel is None else travel[lo:hi],
            drift_ringing_pa=ringing,
            presliding_elements=self.weights.shape[0],
            out=(tuple(v[lo:hi] for v in out[0]), tuple(f[lo:hi] for f in out[1])),
            relaxation_out=None if relaxation is None else relaxation[lo:hi],
        )  # fmt: skip

    def member_means(
        self, inputs: _SpringInputs, step_s: float
    ) -> tuple[np.ndarray, _SpringInputs, Callable[[float], np.ndarray] | None]:
        """(first sample of each mean, the inputs' means, the drift's travel over each
        mean for a ringing factor, or None) of :mod:`transforms.band_members`: means of
        ``step_s`` since the epoch within each gap-free segment where the pressures stay
        within :data:`~transforms.band_members.STEADY_SIGMAS` x their low-passed noise,
        else of each sample; the drift's full-rate play resumed from the previous block
        and its travel (the ringing's included, x the factor) summed over each mean."""
        steady_pa = STEADY_SIGMAS * self.pressure_noise_n() / self.hoist.cylinders.bore_area_m2
        starts = mean_starts(self.epoch_us, self.segment, step_s, inputs.pressures, steady_pa)
        travel = None
        if inputs.drift_p is not None:
            per_sample = np.zeros(self.n)
            drift_p, segment, drift_w = inputs.drift_p, self.segment, inputs.drift_w

            def play(lo: int, hi: int, state: np.ndarray) -> None:
                played_travels_into(
                    drift_p[lo:hi], segment[lo:hi], drift_w, state, per_sample[lo:hi]
                )

            bounds = (self.stage_lo, self.handover, self.spring_hi)
            self.nxt.drift_play = self.staged(play, segment, self.carry.drift_play, bounds)
            ringing = None if inputs.ringing is None else np.nan_to_num(inputs.ringing)

            def travel(factor: float) -> np.ndarray:
                if ringing is None:
                    return group_sum(per_sample, starts)
                return group_sum(per_sample + factor * ringing, starts)

        nu = inputs.nu
        means = _SpringInputs(
            tuple(group_mean(p, starts) for p in inputs.pressures),
            tuple(group_mean(v, starts) for v in inputs.logged),
            group_mean(inputs.depth, starts), self.segment[starts],
            group_mean(nu, starts) if nu.size > 1 else nu, None, 0.0, None,
        )  # fmt: skip
        return starts, means, travel

    def member_at_rate(
        self, inputs: _SpringInputs, m: int, member: BandSolution
    ) -> tuple[np.ndarray, ...]:
        """Band member m's friction per rope, solved at the sensors' rate (NaN outside the
        stage); its displacements go to this thread's work arrays."""
        n = self.n
        x = tuple(self.buffer(f"member_x{k}", n) for k in range(len(ROPES)))
        f = tuple(np.full(n, np.nan) for _ in ROPES)
        run = functools.partial(
            self.solve_springs, inputs, member, out=(x, f), dt_s=self.dt_nominal
        )
        bounds = (self.stage_lo, self.handover, self.spring_hi)
        self.nxt.springs[m] = self.staged(run, self.segment, self.carry.springs[m], bounds)
        return f

    def member_spreads(
        self,
        inputs: _SpringInputs,
        members: list[BandSolution],
        step_s: float,
        pool: ThreadPoolExecutor,
        *,
        at_rate: Sequence[int] = (),
    ) -> list[tuple[np.ndarray, ...]]:
        """Each band member's friction less the estimate's, per rope, at the sensors' rate:
        both solved on the means of :meth:`member_means` (on ``pool``) and the difference
        held over each mean's samples (NaN outside the stage;
        :mod:`transforms.band_members`); the members ``at_rate`` are solved at the
        sensors' rate instead (:meth:`member_at_rate`), their own friction in the list."""
        n = self.n
        starts, means, travel = self.member_means(inputs, step_s)
        steps = mean_steps(starts, n, self.dt_nominal, means.segment)
        bounds = tuple(
            int(np.searchsorted(starts, i)) for i in (self.stage_lo, self.handover, self.spring_hi)
        )

        def solve(m: int) -> tuple[np.ndarray, ...]:
            # the displacements go to the solving thread's work arrays
            x = tuple(self.buffer(f"member_x{k}", starts.size) for k in range(len(ROPES)))
            f = tuple(np.full(starts.size, np.nan) for _ in ROPES)
            run = functools.partial(
                self.solve_springs, means, members[m], out=(x, f), dt_s=steps,
                travel=None if travel is None else travel(members[m].ringing_scale),
            )  # fmt: skip
            self.nxt.springs[m] = self.staged(run, means.segment, self.carry.springs[m], bounds)
            return f

        # on the pool: beside the estimate, then on both its threads
        on_means = [m for m in range(len(members)) if m not in at_rate]
        frictions = dict(zip(on_means, pool.map(solve, on_means), strict=True))
        rate = functools.partial(self.member_at_rate, inputs)
        solved = list(pool.map(rate, at_rate, [members[m] for m in at_rate]))
        frictions |= dict(zip(at_rate, solved, strict=True))

        def spread(m: int) -> tuple[np.ndarray, ...]:
            if m in at_rate:
                return frictions[m]
            f_0, f_m = frictions[0], frictions[m]
            return tuple(held(fm - f0, starts, n) for fm, f0 in zip(f_m, f_0, strict=True))

        return [spread(m) for m in range(1, len(members))]

    def drift_pressure(self, pressures: tuple[np.ndarray, ...]) -> tuple[np.ndarray | None, float]:
        """:func:`transforms.seal_drift.drift_pressure` when the seals drift (LuGre's single
        bristle, :func:`~transforms.seal_drift.seals_drift`), else (None, 0)."""
        if not self.lugre_seals:
            return None, 0.0
        settings, rate = self.settings, self.context.sample_rate_hz
        cutoff = drift_cutoff_hz(self.hoist, settings.pressure_cutoff_hz)
        work = self.buffer(
            "drift", lowpass_work_size(self.n, sample_rate_hz=rate, cutoff_hz=cutoff)
        )  # the lower cut-off's pad is the longer
        return drift_pressure(
            pressures, self.segment, self.hoist, sample_rate_hz=rate,
            pressure_sigma_pa=settings.pressure_sigma_pa,
            pressure_cutoff_hz=settings.pressure_cutoff_hz, work=work,
            reading_step_pa=self.context.pressure_step_pa,
        )  # fmt: skip

    def ringing_drift(self) -> np.ndarray:
        """Per sample, each piston's travel in a ringing at rest that its shared-out x
        does not show [m] (LuGre seals without the stick-slip solution, ``mode`` 2, with
        or without a logged x): a ringing whose amplitude, as the oil's motion, stays
        within the x's deadband (``displacement_deadband_m``: 5 um, ~26 kPa of the
        example hoist's oil) moves no played x, so its whole travel
        (:func:`transforms.seal_drift.ringing_travel`, counted above the noise as the
        stick-slip solution counts it) is the seals' drift path, a quarter a piston
        (eq 5, :func:`physics.closed_volume.common_mode_per_pa`); else a
        single 0. Waits for the pressures only (queued after their jobs)."""
        if self.mode != 2 or not self.lugre_seals:
            return np.zeros(1)
        pressures = tuple(job.result() for job in self.p_jobs)
        drift_p, drift_w = self.drift_pressure(pressures)
        # the deadband as the oil's pressure at the record's typical pressure (the same
        # in every block)
        typical = float(common_mode_per_pa(self.context.typical_pressure_pa, self.hoist))
        deadband_pa = self.settings.displacement_deadband_m / typical
        ringing = ringing_travel(
            drift_p, self.segment, float_column(self.frame["depth_m"]), at_rest(self.frame),
            self.hoist, sample_rate_hz=self.context.sample_rate_hz,
            pressure_cutoff_hz=self.settings.pressure_cutoff_hz, half_width_pa=drift_w,
            hidden_below_pa=max(deadband_pa, drift_w),
        )  # fmt: skip
        return ringing * common_mode_per_pa(drift_p, self.hoist)

    def played_motion(self, k: int) -> np.ndarray:
        """Rope k's piston displacement through the play operator of half-width
        ``displacement_deadband_m`` (:func:`transforms.filtering.play_operator`)."""
        played = self.buffer("work_b", self.n)
        estimate = self.motion_share.result()[0][k]  # not overwritten
        deadband, segment = self.settings.displacement_deadband_m, self.segment

        def run(lo: int, hi: int, state: np.ndarray) -> None:
            play_kernel(estimate[lo:hi], segment[lo:hi], deadband, played[lo:hi], state)

        self.nxt.played[k] = self.staged(run, segment, self.carry.played[k])
        return played

    def branch_flow(self, played: np.ndarray) -> np.ndarray:
        """Piston velocity driving the branch flow (Savitzky-Golay of the played motion)."""
        if not self.with_branch_loss:
            return np.zeros(1)
        lo, hi = self.stage_lo, self.stage_hi
        v_flow = np.zeros(self.n)
        v_flow[lo:hi] = smoothed_derivative(
            played[lo:hi],
            self.segment[lo:hi],
            dt_s=self.dt_nominal,
            window_s=self.settings.velocity_window_s,
            out=self.buffer("work_a", hi - lo),
            time_s=self.time_s[lo:hi],
        )
        return v_flow

    def offset_sensors(self) -> tuple[bool, ...]:
        """The record's offset sensors (``CompensationContext.offset_sensors``) where the
        stick-slip solution runs; else none."""
        return self.context.offset_sensors if self.mode == 3 else ()

    def rope(self, k: int) -> dict[str, np.ndarray]:
        """Tensions of rope k and their band; its inputs are futures of earlier jobs. An
        offset sensor's rope (:meth:`offset_sensors`) takes the mean of the others'
        readings for its chamber's (the pipes equalise the chambers at rest, contract
        1a: the sensor reads apart, not the oil); its raw tension keeps the reading."""
        n, core, law = self.n, slice(self.core_lo, self.core_hi), self.law
        played = self.played_motion(k)
        p_sensor = np.ascontiguousarray(self.p_jobs[k].result())
        reading = None
        offset = self.offset_sensors()
        if offset and offset[k]:
            others = [job.result() for job, o in zip(self.p_jobs, offset, strict=True) if not o]
            reading, p_sensor = p_sensor, mean_horizontal(others)
        nu = np.ascontiguousarray(np.atleast_1d(np.asarray(self.nu_job.result(), dtype=float)))
        out = {name: np.empty(n) for name in ("p_chamber", "tension_raw", "tension")}
        # this rope's despiked displacement is consumed (the differential is done): its
        # array takes the friction, one fresh day-long array fewer
        if self.mode == 3:  # the stick-slip solution's (its job is done: played above)
            out["friction"] = self.spring_friction[k]
        else:
            out["friction"] = self.x_jobs[k].result() if self.context.has_x else np.empty(n)
        v_flow = self.branch_flow(played)
        drift = self.ringing_job.result()
        state = self.carry.rope[k].copy()
        rope_kernel(
            played[core], self.time_s[core], self.settings.gap_factor * self.dt_nominal,
            self.dt_nominal, p_sensor[core], self.with_branch_loss,
            v_flow[core] if v_flow.size == n else v_flow, nu[core] if nu.size == n else nu,
            self.branch, self.law_lines, self.mode, self.stiffness, self.weights,
            float(law.bristle_stiffness_n_m), float(law.bristle_damping_n_s_m),
            self.hoist.cylinders.bore_area_m2, drift[core] if drift.size == n else drift,
            out["p_chamber"][core], out["friction"][core], out["tension_raw"][core],
            out["tension"][core], state,
        )  # fmt: skip
        self.nxt.rope[k] = state
        if reading is not None:  # the raw tension is the sensor's reading (eq 2, F = 0)
            area = self.hoist.cylinders.bore_area_m2
            out["tension_raw"][core] = reading[core] * area
        lo, hi = self.rope_band(k, out)
        i = ROPES[k]
        return {
            f"p_chamber{i}_pa": out["p_chamber"][core],
            f"friction{i}_n": out["friction"][core],
            f"tension_raw{i}_n": out["tension_raw"][core],
            f"tension{i}_n": out["tension"][core],
            f"tension{i}_lo_n": lo,
            f"tension{i}_hi_n": hi,
        }

    def pressure_noise_n(self) -> float:
        """The sensor's noise after the low-pass, as a force on the piston [N] (the band),
        with the logger's rounding (``CompensationContext.pressure_step_pa``, q / 12^0.5,
        which the low-pass does not average away at rest: a reading held a step off)."""
        settings = self.settings
        share = min(1.0, 2.0 * settings.pressure_cutoff_hz / self.context.sample_rate_hz)
        white = settings.pressure_sigma_pa * np.sqrt(share)
        rounding = self.context.pressure_step_pa / np.sqrt(12.0)
        return float(np.hypot(white, rounding)) * self.hoist.cylinders.bore_area_m2

    def rope_band(self, k: int, out: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The 95 % band of rope k's tension (:func:`transforms.uncertainty.rope_band`, or
        :func:`~transforms.uncertainty.ensemble_band` of the stick-slip solution's members)."""
        core, law, friction = slice(self.core_lo, self.core_hi), self.law, self.mode != 0
        if self.mode == 3:  # the members, and the seal's own law beyond what they span
            seal = out["friction"][core]
            return ensemble_band(
                out["tension"][core], seal,
                [member[k][core] for member in self.member_friction], self.pressure_noise_n(),
                seal_sigma_n=self.law_sigma * np.abs(seal),
                groups=self.member_sources, law_group=BAND_SOURCES.index("law"),
            )  # fmt: skip
        estimates, blind = self.motion_share.result()
        # rope k's estimate is consumed (played above) and its blind motion is read
        # before each hi is written: they take the band, unless shared by the ropes
        own = estimates[k] is not estimates[(k + 1) % len(ROPES)]
        return rope_band(
            out["tension"][core],
            out["friction"][core] if friction else np.zeros(self.core_hi - self.core_lo),
            out["p_chamber"][core],
            blind[k][core],
            static_law_n=tuple(law.static_n) if friction else (0.0, 0.0),
            bristle_stiffness_n_m=float(law.bristle_stiffness_n_m) if friction else 0.0,
            gaussian_sigma_n=(
                self.law_sigma if friction else 0.0,
                self.pressure_noise_n(),
            ),
            out=(estimates[k][core], blind[k][core]) if own else None,
        )

    def common_mode_into(self, pressures: list[np.ndarray]) -> np.ndarray:
        """The mean pressure; its common mode (:mod:`physics.closed_volume`) is set as the
        result of ``self.common_mode``, which the piston motion's share-out waits for
        (None on the stick-slip path, which does not use it)."""
        p_mean = mean_horizontal(pressures)
        if self.mode == 3:  # the stick-slip solution has its own oil: no share-out
            self.common_mode.set_result(None)
            return p_mean
        common = np.empty(self.n)
        segment, hoist = self.segment, self.hoist

        def run(lo: int, hi: int, state: np.ndarray) -> None:
            if hi > lo:
                common[lo:hi] = common_mode_displacement(
                    p_mean[lo:hi], segment[lo:hi], hoist, state=state
                )

        self.nxt.common = self.staged(run, segment, self.carry.common)
        self.common_mode.set_result(common)
        return p_mean

    # -- scheduling -----------------------------------------------------------------------
    def run(self) -> tuple[pl.DataFrame, CompensationCarry]:
        """All steps on a pool; the block's rows and the state for the next block.

        Every job waits only for jobs queued before it or for the common mode, which this
        thread computes. The trip labels go first: they are the longest job that does
        not wait for the pressures, so they overlap the pressure filters instead of
        running alone after the ropes. The ropes are queued right away: each starts on
        its differential displacement while the common mode is still being integrated.
        """
        self.common_mode: Future[np.ndarray] = Future()
        self.off_sensors: tuple[np.ndarray, ...] | None = None
        workers = min(len(ROPES), os.cpu_count() or 1)
        with ThreadPoolExecutor(max_workers=workers) as pool:
            self.kinematics_job = kinematics_job = pool.submit(self.kinematics)
            self.p_jobs = [pool.submit(self.pressure, c) for c in rope_cols("p{i}_pa")]
            self.x_jobs = [pool.submit(self.displacement, c) for c in rope_cols("x{i}_m")]
            self.nu_job = pool.submit(viscosity, self.t_oil, self.hoist)
            self.smooth_jobs = [pool.submit(self.smoothed_logged, k) for k in range(len(ROPES))]
            self.motion_share = pool.submit(self.piston_motion)
            self.ringing_job = pool.submit(self.ringing_drift)
            rope_jobs = [pool.submit(self.rope, k) for k in range(len(ROPES))]
            try:
                # NaN stands for null from here on (the frame version filled NaN with null)
                pressures = [job.result() for job in self.p_jobs]
                p_mean = self.common_mode_into(pressures)
            except BaseException as error:
                self.common_mode.set_exception(error)  # the rope jobs fail, not wait
                raise
            accel, labels = kinematics_job.result()
            per_rope = [job.result() for job in rope_jobs]
        columns = {name: values for part in per_rope for name, values in part.items()}
        core = slice(self.core_lo, self.core_hi)
        rows = self.frame.slice(self.core_lo, self.core_hi - self.core_lo)
        sigma_n = (
            self.law_sigma if self.mode != 0 else 0.0,
            self.pressure_noise_n(),
        )
        pressures = [p[core] for p in pressures]
        # the mean pressure's array takes the raw load sum
        members = None
        if self.mode == 3:  # the load's band: the members' frictions summed member by member
            members = [sum(f[k][core] for k in range(len(ROPES))) for f in self.member_friction]
        off = None if self.off_sensors is None else [o[core] for o in self.off_sensors]
        # a sensor apart from the others at every rest: each band reaches its rope's
        # tension were it reading the others (compensation_record.sensor_departures)
        departures, apart = self.context.sensor_departures, None
        if departures:
            area = self.hoist.cylinders.bore_area_m2
            apart = [-p * d / (1.0 + d) * area for p, d in zip(pressures, departures, strict=True)]
        frame = block_frame(rows, np.negative(accel[core]), labels, pressures, columns,
                            p_mean[core], sigma_n, load_members=members,
                            member_sources=self.member_sources if members else None,
                            off_sensors=off, area_m2=self.hoist.cylinders.bore_area_m2,
                            reading_shifts=apart)  # fmt: skip
        return frame, self.nxt


def prior_mean(
    friction: tuple[np.ndarray, ...],
    member_friction: list[tuple[np.ndarray, ...]],
    members: list[BandSolution],
) -> tuple[np.ndarray, ...]:
    """Ropes no record identified (:func:`transforms.stick_slip_band.prior_rope_springs`):
    the estimate's friction becomes the mean over the prior's sigma points' solutions
    (the unscented transform's, equal weights), in place; the other members keep their
    difference from the description's ropes' solution (shifted alike), and each sigma
    point's difference from the mean is stretched by 1.96 / sqrt(m / 2) (m points: each
    stands at sqrt(m / 2) standard deviations along its direction, a member of the band
    at 1.96). ``member_friction`` and ``members`` are the band's, the estimate left out.

    Returns the description's ropes' solution (the estimate's friction before): ropes
    alike, the spread's one end. The seals' friction summed over the pistons saturates
    as the ropes' differences grow (the pistons that slide apart end at opposite
    capacities), so the points, each as far out as the spread's standard deviations
    along its direction, cancel more of it than ropes that differ less would: the band
    takes that end as a member too."""
    points = [j for j, member in enumerate(members) if member.source == "stiffness"]
    stretch = 1.96 / np.sqrt(len(points) / 2.0)
    alike = tuple(f.copy() for f in friction)
    for k, estimate in enumerate(friction):
        mean = sum(member_friction[j][k] for j in points) / len(points)
        shift = mean - estimate
        for j, member in enumerate(member_friction):
            if j in points:
                member[k][:] = mean + stretch * (member[k] - mean)
            else:
                member[k][:] += shift
        estimate[:] = mean
    return alike
