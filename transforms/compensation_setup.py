"""The set-up of one block's compensation: its times, bounds, friction mode and oil.

:class:`BlockSetup` reads what the steps of :class:`transforms.compensation_block.
BlockCompensation` need before any of them runs: the settings at the record's sample
rate, the times and gap-free segments, the conveyance's speed (from its depth where the
log lacks it), the block's core, first-stage span and hand-over
(the bounds the carried state is saved at), the friction mode with its law and
presliding elements, the logged oil temperature and one seal's presliding range.
"""

from __future__ import annotations

import datetime as dt
import threading
from dataclasses import replace

import numpy as np
import polars as pl

from physics.conveyance import conveyance_speed
from physics.friction_law import friction_law_at, law_array
from physics.maxwell_slip import maxwell_slip_elements
from physics.sensor_branch import sensor_branch
from schemas.hoist import HoistDescription
from transforms.alarm_rules import rule_thresholds
from transforms.compensation_kernels import long_segments
from transforms.compensation_record import (
    CompensationCarry,
    CompensationContext,
    CompensationSettings,
    compensation_margins_s,
    flatlined_samples,
    float_column,
)
from transforms.filtering import pressure_cutoff_at, segment_ids
from transforms.seal_drift import seal_elements, seals_drift

__all__ = ["BlockSetup", "epoch_us"]


def epoch_us(at: dt.datetime) -> int:
    """Microseconds since the epoch of a datetime (naive: UTC)."""
    at = at.replace(tzinfo=dt.UTC) if at.tzinfo is None else at
    delta = at - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
    return (delta.days * 86_400 + delta.seconds) * 1_000_000 + delta.microseconds


class BlockSetup:
    """A block's constants and bounds, read once before the steps run.

    ``frame`` holds the block and its margins (time-sorted, the columns
    :func:`transforms.compensation.compensate_window` reads, at least one row);
    ``carry`` the state the previous block left (None: the record's first block);
    ``nxt`` the state for the next block, which the steps fill in.
    """

    def __init__(
        self,
        frame: pl.DataFrame,
        hoist: HoistDescription,
        *,
        context: CompensationContext,
        settings: CompensationSettings,
        effects: set[str],
        carry: CompensationCarry | None,
        block_start_utc: dt.datetime | None,
        block_end_utc: dt.datetime | None,
    ) -> None:
        self.frame, self.hoist, self.context, self.n = frame, hoist, context, frame.height
        self.law = hoist.friction_law
        self.law_sigma = settings.friction_sigma(hoist)  # the law's relative uncertainty
        if settings.displacement_deadband_m < 0:
            raise ValueError(
                f"displacement_deadband_m must be >= 0, got {settings.displacement_deadband_m}"
            )
        self._friction_setup(effects)
        self.resuming = carry is not None  # a block after the record's first
        self.carry = carry or CompensationCarry.fresh(self.weights.shape[0])
        self.nxt = replace(
            self.carry,
            differential=list(self.carry.differential),
            played=list(self.carry.played),
            rope=list(self.carry.rope),
        )
        rate_hz = context.sample_rate_hz
        self.settings = replace(
            settings,
            sample_rate_hz=rate_hz,
            pressure_cutoff_hz=pressure_cutoff_at(settings.pressure_cutoff_hz, rate_hz),
        )
        self.dt_nominal = 1.0 / rate_hz
        self._time_setup(block_start_utc, block_end_utc)
        self.t_oil = self._oil_temperature(effects)
        self.with_branch_loss = bool({"pipe_laminar_loss", "local_loss"} & effects)
        self.branch = sensor_branch(hoist)
        self.local = threading.local()
        self.presliding_range_m = self._presliding_range_m()
        # a sensor this far off the others at rest is not a pressure (contract 1a)
        self.disagreement = rule_thresholds(hoist)  # its sensor_disagreement fraction, floor

    # -- set-up ---------------------------------------------------------------------------
    def _friction_setup(self, effects: set[str]) -> None:
        """Friction mode (0 none, 1 Maxwell-slip, 2 LuGre, 3 stick-slip on the identified
        rope springs, :mod:`transforms.stick_slip`), the law and the elements."""
        law = self.law
        presliding = "presliding_hysteresis" in effects
        if presliding:
            self.stiffness, self.weights = maxwell_slip_elements(
                seal_elements(effects, self.hoist), law.bristle_stiffness_n_m
            )
        else:
            self.stiffness, self.weights = np.ones(1), np.ones(1)
        self.mode = 0 if "seal_friction" not in effects else (1 if presliding else 2)
        self.lugre_seals = seals_drift(effects)  # one bristle per seal: it drifts (LuGre)
        if self.mode and self.context.rope_springs is not None:
            self.mode = 3  # the seals' friction from the ropes (transforms.stick_slip)
        self.law_lines = law_array(law)

    def _time_setup(self, start: dt.datetime | None, end: dt.datetime | None) -> None:
        """Times, segments and the block's bounds: the core [core_lo, core_hi) whose rows
        are returned, the first stage's span [stage_lo, stage_hi) and its hand-over."""
        # epoch microseconds x 1e-6 (the arithmetic of .astype(float) * 1e-6), by chunk
        epoch = self.frame["time_utc"].dt.cast_time_unit("us").to_physical()
        self.time_s = float_column(epoch, scale=1e-6)
        resume_s, _ = compensation_margins_s(self.settings)
        micros = epoch.to_numpy()
        self.epoch_us = micros

        def index(at: dt.datetime | None, shift_s: float, default: int) -> int:
            if at is None:
                return default
            target = epoch_us(at) + round(shift_s * 1e6)
            return int(np.searchsorted(micros, target, side="left"))

        n = self.n
        self.core_lo, self.core_hi = index(start, 0.0, 0), index(end, 0.0, n)
        self.stage_lo = index(start, -resume_s, 0) if self.resuming else 0
        self.handover = index(end, -resume_s, n)
        self.stage_hi = index(end, resume_s, n)
        self.segment = segment_ids(
            self.time_s, gap_factor=self.settings.gap_factor, nominal_dt_s=self.dt_nominal
        )
        self.long_segment, self.long_bounds = long_segments(
            self.time_s, self.settings.differential_bridge_s
        )
        self.speed = self._conveyance_speed()
        self.flatlined = flatlined_samples(self.frame, self.time_s, self.hoist)

    def _conveyance_speed(self) -> np.ndarray:
        """The conveyance's speed (NaN where unknown): the logged one, where it is missing
        the depth's derivative or an isolated hole interpolated
        (:func:`physics.conveyance.conveyance_speed`). The frame's ``speed_m_s`` becomes it,
        so the rest standstill, the output and the alarms read the same speed as the trip
        labels; a record logging its speed throughout is left as it is."""
        logged = self.frame["speed_m_s"]
        speed = float_column(logged)
        if not np.isnan(speed).any():
            return speed
        speed = conveyance_speed(
            self.time_s, speed, float_column(self.frame["depth_m"]), self.segment,
            dt_s=self.dt_nominal, window_s=self.settings.acceleration_window_s,
            depth_sigma_m=self.context.depth_sigma_m,
            depth_quantum_m=self.context.depth_quantum_m,
        )  # fmt: skip
        filled = pl.Series("speed_m_s", speed, dtype=pl.Float64).fill_nan(None)
        self.frame = self.frame.with_columns(filled.cast(logged.dtype))
        return speed

    def _oil_temperature(self, effects: set[str]) -> np.ndarray | None:
        """The logged oil temperature (gaps filled), when the viscosity follows it."""
        frame = self.frame
        if "viscosity_temperature" not in effects or frame["oil_temp_c"].null_count() == self.n:
            return None
        temperature = frame["oil_temp_c"]
        if temperature.null_count():
            temperature = temperature.fill_null(strategy="forward").fill_null(strategy="backward")
        return float_column(temperature)

    def _presliding_range_m(self) -> float:
        """F_s / sigma_0 at the record's median pressure: one seal's presliding range."""
        if self.mode == 0 or not self.law.bristle_stiffness_n_m > 0:
            return 0.0
        p_typical = self.context.typical_pressure_pa
        static = friction_law_at(p_typical if np.isfinite(p_typical) else 0.0, self.law_lines)[1]
        return static / float(self.law.bristle_stiffness_n_m)
