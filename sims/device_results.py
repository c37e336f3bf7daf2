"""What a device simulation returns: its output columns, result and continuable state.

:class:`SimulationResult` (status, message, frame of :data:`OUTPUT_COLUMNS`, solver
record) and :class:`DeviceState` (every integrator state, from which the next run
continues), with the helpers that build both from the integrator's record. Public
through :mod:`sims.device`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import polars as pl

from sims.device_params import CYL0, ETA, ETAD, PER, PM, Setup, T
from sims.effects import ResolvedEffects
from sims.trips import TripProfile

#: Columns of :attr:`SimulationResult.frame`, in order (n = 4 ropes).
OUTPUT_COLUMNS: tuple[str, ...] = (
    "time_s",
    "depth_m",
    "speed_m_s",
    "acceleration_up_m_s2",
    "payload_kg",
    "oil_temp_c",
    *[
        f"{name}{i}_{unit}"
        for i in range(1, 5)
        for name, unit in (
            ("p_chamber", "pa"),
            ("p_sensor", "pa"),
            ("x", "m"),
            ("v", "m_s"),
            ("q", "m3_s"),
            ("friction", "n"),
            ("tension", "n"),
        )
    ],
    "load_n",
    "p_manifold_pa",
    "oil_volume_m3",
)


def _frozen(values: Any, shape: tuple[int, ...] | None = None) -> np.ndarray:
    arr = np.array(values, dtype=float)
    if shape is not None:
        arr = arr.reshape(shape)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class DeviceState:
    """Every integrator state of the device at one instant: what a run continues from.

    :attr:`SimulationResult.final_state` holds it at the end of a successful run;
    :func:`simulate` (``initial_state=``) starts another run from it, so a sequence of
    runs (the trips of a day) is one continuous history: the seals keep the friction
    they hold, nothing steps. Arrays are read-only; n = number of ropes.

    Attributes
    ----------
    time_s : the state's time on the clock of the run it comes from [s]
        (informational; the continuing run starts at its profile's first time).
    depth_m, speed_m_s : commanded conveyance depth [m] and speed [m/s, + down].
    payload_kg : payload at that instant [kg].
    eta_m, eta_rate_m_s : conveyance displacement below the commanded depth (the rope
        stretch; with the piston positions and the depth this is the head ropes' whole
        state, the ropes being massless spring-dampers) [m] and its rate [m/s].
    p_manifold_pa : manifold pressure [Pa].
    p_chamber_pa, x_m, v_m_s, q_m3_s : (n,) chamber pressures [Pa], piston positions [m]
        and velocities [m/s], branch flows [m3/s, reference volume, out of the chamber].
    lugre_z_m : (n,) LuGre bristle deflections [m] (zero unless ``seal_friction`` is on
        without ``presliding_hysteresis``).
    maxwell_slip_m : (n, elements) Maxwell-slip element deflections [m] (zero unless
        ``presliding_hysteresis`` is on).
    bulk_modulus_pa : the (effective) bulk modulus the run integrated with; kept by a
        continuing run so the oil inventory (``oil_volume_m3``) stays continuous.
    effects : the resolved effects and parameters of the run (a continuing run must use
        the same).
    """

    time_s: float
    depth_m: float
    speed_m_s: float
    payload_kg: float
    eta_m: float
    eta_rate_m_s: float
    p_manifold_pa: float
    p_chamber_pa: np.ndarray
    x_m: np.ndarray
    v_m_s: np.ndarray
    q_m3_s: np.ndarray
    lugre_z_m: np.ndarray
    maxwell_slip_m: np.ndarray
    bulk_modulus_pa: float
    effects: ResolvedEffects

    @property
    def ropes_n(self) -> int:
        return int(self.p_chamber_pa.shape[0])

    def _vector(self, t_s: float) -> np.ndarray:
        """The integrator's state vector at time ``t_s``."""
        n = self.ropes_n
        y = np.zeros(CYL0 + PER * n)
        y[T] = t_s
        y[ETA] = self.eta_m
        y[ETAD] = self.eta_rate_m_s
        y[PM] = self.p_manifold_pa
        for i in range(n):
            b = CYL0 + PER * i
            y[b : b + PER] = (self.p_chamber_pa[i], self.x_m[i], self.v_m_s[i], self.q_m3_s[i])
        return y


@dataclass(frozen=True)
class SimulationResult:
    """Outcome of a device simulation.

    Attributes
    ----------
    status : "success" or "failed"
    message : what happened (the reason when failed, stroke-end contacts, accuracy)
    frame : polars DataFrame of true states per output sample, columns
        :data:`OUTPUT_COLUMNS` (``p{i}``/``x{i}``... per rope i = 1..n); when failed,
        the samples up to the failure
    effects : the resolved effects and parameters used
    solver : method, step, tolerances, steps taken, error_ratio_max, wall times
    final_state : every integrator state at the last sample (:class:`DeviceState`),
        to continue from with ``simulate(..., initial_state=...)``; None when failed
    """

    status: str
    message: str
    frame: pl.DataFrame
    effects: ResolvedEffects
    solver: dict[str, Any] = field(default_factory=dict)
    final_state: DeviceState | None = None

    @property
    def ok(self) -> bool:
        return self.status == "success"


def result_frame(
    setup: Setup,
    rec_y: np.ndarray,
    rec_aux: np.ndarray,
    rec_vol: np.ndarray,
    profile: TripProfile | None,
) -> pl.DataFrame:
    """The :data:`OUTPUT_COLUMNS` frame of the recorded (finite) samples."""
    n = setup.groove.shape[0]
    t = rec_y[:, T]
    if profile is not None:
        depth = profile.depth(t)
        speed = profile.speed(t)
        acc_up = -profile.acceleration(t)
        payload = profile.payload(t)
    else:
        depth = speed = acc_up = payload = np.zeros_like(t)
    cols: dict[str, np.ndarray] = {
        "time_s": t,
        "depth_m": depth,
        "speed_m_s": speed,
        "acceleration_up_m_s2": acc_up,
        "payload_kg": payload,
        "oil_temp_c": np.full_like(t, setup.oil_temp_c),
    }
    tensions = np.zeros_like(t)
    for i in range(n):
        b = CYL0 + PER * i
        p = rec_y[:, b]
        p_tee = p - rec_aux[:, i, 3]
        cols[f"p_chamber{i + 1}_pa"] = p
        cols[f"p_sensor{i + 1}_pa"] = setup.sensor_gain[i] * p_tee + setup.sensor_offset[i]
        cols[f"x{i + 1}_m"] = rec_y[:, b + 1]
        cols[f"v{i + 1}_m_s"] = rec_y[:, b + 2]
        cols[f"q{i + 1}_m3_s"] = rec_y[:, b + 3]
        cols[f"friction{i + 1}_n"] = rec_aux[:, i, 0]
        cols[f"tension{i + 1}_n"] = rec_aux[:, i, 1]
        tensions = tensions + rec_aux[:, i, 1]
    cols["load_n"] = tensions
    cols["p_manifold_pa"] = rec_y[:, PM]
    cols["oil_volume_m3"] = rec_vol
    return pl.DataFrame(cols)


def device_state(
    y_end: np.ndarray,
    z_end: np.ndarray,
    deltas_end: np.ndarray,
    bulk_modulus_pa: float,
    eff: ResolvedEffects,
    profile: TripProfile | None,
) -> DeviceState:
    """The :class:`DeviceState` at the end of a successful run."""
    n = z_end.shape[0]
    t_end = float(y_end[T])
    return DeviceState(
        time_s=t_end,
        depth_m=float(profile.depth(t_end)) if profile is not None else 0.0,
        speed_m_s=float(profile.speed(t_end)) if profile is not None else 0.0,
        payload_kg=float(profile.payload(t_end)) if profile is not None else 0.0,
        eta_m=float(y_end[ETA]),
        eta_rate_m_s=float(y_end[ETAD]),
        p_manifold_pa=float(y_end[PM]),
        p_chamber_pa=_frozen([y_end[CYL0 + PER * i] for i in range(n)]),
        x_m=_frozen([y_end[CYL0 + PER * i + 1] for i in range(n)]),
        v_m_s=_frozen([y_end[CYL0 + PER * i + 2] for i in range(n)]),
        q_m3_s=_frozen([y_end[CYL0 + PER * i + 3] for i in range(n)]),
        lugre_z_m=_frozen(z_end),
        maxwell_slip_m=_frozen(deltas_end),
        bulk_modulus_pa=bulk_modulus_pa,
        effects=eff,
    )
