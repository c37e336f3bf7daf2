"""The four-cylinder hydraulic connection device of a Koepe hoist, with ropes and conveyance.

The open, scriptable equivalent of the paper's AMESim model (Song et al., sections 2
and 3.2, Figures 1, 2, 9 and 22). Entry points:

:func:`simulate` -- one hoist trip (:mod:`sims.trips`) of a hoist description with
    effects switched by contract name (:mod:`sims.effects`); returns a
    :class:`SimulationResult` with a status, a polars frame of true states and the
    final :class:`DeviceState`, from which the next trip continues
    (``initial_state=``) with the seals' friction memory intact.
:func:`paper_scenario_3_2` -- the paper's section 3.2 load-source scenario.

Model (SI; x positive when the rope pulls the rod out, contract 1a)
------------------------------------------------------------------
Per cylinder i (bore area A, chamber volume ``V_i = V_mid - A x_i``):

* Chamber continuity with a finite bulk modulus beta (paper eq 5 generalised to a
  moving piston). Oil mass is tracked as its volume at reference (zero gauge)
  pressure, ``m_i = V_i exp(p_i / beta)`` (isothermal, constant beta), so

  .. math:: \\frac{dp_i}{dt} = \\frac{\\beta}{V_i}\\left(A v_i - q_i e^{-p_i/\\beta}\\right)

  with ``q_i`` the branch flow out of the chamber counted as reference volume per
  second; the manifold likewise, ``dp_m/dt = beta / V_m * sum(q_i) e^{-p_m/beta}``.
  The total ``sum(m_i) + m_m + V_pipes`` is the conserved oil volume (reported as
  ``oil_volume_m3``). The pipe oil is incompressible at reference density.
  ``oil_compressibility`` off: beta x 1000 (1.5 TPa for mineral oil), i.e. practically
  rigid oil, integrated by the same L-stable scheme. Entrained air: beta is replaced by
  the effective bulk modulus (:func:`physics.oil.effective_bulk_modulus`) at the
  initial static pressure, held constant.
* Branch flow (paper eq 7, divided by the pipe area a), chamber -> globe valve + part 1
  -> sensor tee -> part 2 -> manifold, one oil column of length l1 + l2:

  .. math:: \\frac{\\rho (l_1 + l_2)}{a}\\frac{dq_i}{dt} = p_i - p_m - \\Delta p_1(q_i)
            - \\Delta p_2(q_i)

  ``Delta p_k`` = loss along the pipe (laminar eq 6, turbulent eq 12 with Blasius) +
  local loss (eq 13, K rho v|v|/2; K_1 = globe valve + fittings of part 1), see
  :func:`physics.branch_loss.pipe_loss_pa`. The sensor reads the pressure at the tee,

  .. math:: p_{sensor,i} = p_i - \\frac{\\rho l_1}{a} \\frac{dq_i}{dt} - \\Delta p_1(q_i)

  (low while oil flows out, high while it flows in, equal at rest: contract 1a), then
  ``gain_i p + offset_i`` with ``sensor_gain`` / ``sensor_offset`` on.
* Piston (mass m_p) between rope and oil, paper eq 1 with friction:

  .. math:: m_p (\\ddot x_i - \\ddot y) = T_i - p_i A - F_{f,i} - F_{stop,i}

  so ``T_i = p_i A + F_f,i (+ inertia)`` (contract eq 2), F_f positive while the rod
  moves out. The piston's weight is counted in the conveyance mass. End stops at
  +-stroke/2 are stiff penalty spring-dampers (1e9 N/m, critically damped).
* Seal friction (``seal_friction``): LuGre, paper eq 15, parameters from the pressure
  law eq 17 (the hoist's ``FrictionLaw``), using :func:`physics.friction_law.stribeck_g`,
  :func:`physics.lugre.lugre_z_step` (exact exponential bristle update) and
  :func:`~physics.lugre.lugre_force`. With ``presliding_hysteresis`` the bristle
  is replaced by Maxwell-slip elements with capacities ``alpha_j g(v)`` (the Leuven /
  Generalized Maxwell-Slip structure, :func:`physics.maxwell_slip.maxwell_slip_step`)
  plus the viscous term; ``presliding_hysteresis`` needs ``seal_friction``.
* Head rope i: massless spring-damper (paper 2.1 neglects rope mass), stiffness
  ``k = EA / (h_headframe + depth)`` and damping ``c = 2 zeta sqrt(k M / n)``:
  ``T_i = k e_i + c de_i/dt``, ``e_i = eta - x_i - depth * dr_i / R`` where ``eta`` is
  the conveyance's displacement below the commanded depth (rope stretch) and
  ``dr_i / R`` the relative groove radius deviation (``groove_wear``: rope i pays out
  ``depth (1 + dr_i/R)``; lengths are equal at the pithead).

Conveyance: ``M (a_cmd + d2eta/dt2) = W - sum(p_i A + F_f,i + F_stop,i)`` with
``W = (m_conv + payload + m_tail(depth)) g`` (tail = n_tail x kg/m x hanging length,
``tail_rope_weight``) and ``M = m_inertia + payload + m_tail``. ``conveyance_inertia``
off: the commanded acceleration term ``M a_cmd`` is dropped (equations written
relative to the winder's motion), so the ropes carry W without the hoist's
acceleration load, while the bounce of the conveyance on the rope springs is kept
(no algebraic constraint, no DAE).

Solver
------
ROS2 (two-stage, second-order, L-stable Rosenbrock-W; Verwer et al. 1999, see
:mod:`sims.hydraulics`) at a fixed step (default 1 ms), finite-difference Jacobian
refreshed every ``jacobian_every`` steps (default 10; ROS2 is a W-method, second order
for any Jacobian approximation: on the 90 s trip with all effects, refreshing every
step or every 10th changes the load by < 0.01 N, while halving dt to 0.25 ms changes
it by ~110 N of 156 kN and the sensor pressures by ~2 kPa).
Friction memory (LuGre z, Maxwell-slip deflections)
is frozen over a step: inside the step the friction is evaluated for the trial
displacement increment ``dx = x - x_n`` (velocity ``dx/h``), i.e. implicitly, and
committed exactly with the accepted increment. Local error estimate ``h (k1 + k2)/2``
with per-state atol (time 1e-6 s, eta 1e-6 m, deta/dt 1e-5 m/s, p_m 100 Pa; per
cylinder p 100 Pa, x 1e-7 m, v 1e-5 m/s, q 1e-9 m3/s) and rtol 1e-4; its largest
weighted RMS norm is reported (``error_ratio_max``; it is an indicator, the step is
not adapted). Failure -- a non-finite state, a singular iteration matrix, a chamber
pressure below zero gauge (cavitation, not modelled) -- ends the run with
``status="failed"``, the reason and the frame up to the last good sample.

References
----------
Song et al., Research on dynamic characteristics and compensation of wire rope tension
and load measurement based on hydraulic connection device (the paper, eq 1-17).
Canudas de Wit et al. (1995), IEEE TAC 40(3) 419-425 (LuGre). Al-Bender et al. (2005),
IEEE TAC 50(11) 1883-1887 (GMS).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import polars as pl
from numba import njit

from physics.branch_loss import BLASIUS, pipe_loss_pa
from physics.friction_law import friction_law_at, stribeck_g
from physics.lugre import lugre_force, lugre_z_step
from physics.maxwell_slip import maxwell_slip_elements, maxwell_slip_step
from physics.oil import (
    ATMOSPHERIC_PRESSURE_PA,
    effective_bulk_modulus,
    kinematic_viscosity_walther,
    walther_coefficients,
)
from physics.tension import tail_rope_length_m
from schemas.hoist import EXAMPLE_HOIST, G_STANDARD, Cylinders, HoistDescription, Piping, load_hoist
from sims.effects import ResolvedEffects, resolve_effects
from sims.hydraulics import ROS2_GAMMA, lu_factor, lu_solve
from sims.trips import TripProfile

__all__ = [
    "CONTINUATION_DEPTH_TOLERANCE_M",
    "OUTPUT_COLUMNS",
    "DeviceState",
    "SimulationResult",
    "paper_scenario_3_2",
    "simulate",
]

# ---- parameter vector layout (numba reads these module constants as literals) --------
_A, _VMID, _MP, _XMAX, _KSTOP, _CSTOP, _BETA, _VM, _RHO, _MU = range(10)
_INERT, _L1, _L2, _DLOSS, _K1, _K2, _LAM_ON, _LOC_ON, _FRIC_ON, _PRE_ON = range(10, 20)
_FC0, _FC1, _FS0, _FS1, _VS0, _VS1, _KV0, _KV1, _SIG0, _SIG1 = range(20, 30)
_MINERT, _MCONV, _INERTIA_ON, _TAIL_ON, _TAIL_KG_M, _SHAFT, _LOOP, _G = range(30, 38)
_EA, _LBASE, _ZETA, _RDRUM, _FIXED, _INERT1, _CROPE, _VPIPES = range(38, 46)
_NPAR = 46

# state layout: [t, eta, deta/dt, p_manifold, (p, x, v, q) per cylinder]
_T, _ETA, _ETAD, _PM = range(4)
_CYL0 = 4
_PER = 4

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
        y = np.zeros(_CYL0 + _PER * n)
        y[_T] = t_s
        y[_ETA] = self.eta_m
        y[_ETAD] = self.eta_rate_m_s
        y[_PM] = self.p_manifold_pa
        for i in range(n):
            b = _CYL0 + _PER * i
            y[b : b + _PER] = (self.p_chamber_pa[i], self.x_m[i], self.v_m_s[i], self.q_m3_s[i])
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


# ---------------------------------------------------------------------------------------
# njit kernels
# ---------------------------------------------------------------------------------------
@njit(cache=True)
def _profile(t: float, seg: np.ndarray) -> tuple[float, float, float]:
    k = 0
    for j in range(seg.shape[0]):
        if seg[j, 0] <= t:
            k = j
    tau = max(t - seg[k, 0], 0.0)
    a = seg[k, 3]
    return seg[k, 1] + seg[k, 2] * tau + 0.5 * a * tau * tau, seg[k, 2] + a * tau, a


@njit(cache=True)
def _interp(t: float, knots_t: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """Piecewise-linear value and slope, constant outside the knots."""
    m = knots_t.shape[0]
    if t <= knots_t[0]:
        return values[0], 0.0
    if t >= knots_t[m - 1]:
        return values[m - 1], 0.0
    j = 0
    while knots_t[j + 1] < t:
        j += 1
    span = knots_t[j + 1] - knots_t[j]
    if span <= 0.0:
        return values[j + 1], 0.0
    slope = (values[j + 1] - values[j]) / span
    return values[j] + slope * (t - knots_t[j]), slope


@njit(cache=True)
def _friction(
    p: float,
    dx: float,
    h: float,
    par: np.ndarray,
    z: float,
    deltas: np.ndarray,
    ms_k: np.ndarray,
    ms_w: np.ndarray,
    cap: np.ndarray,
    commit: bool,
) -> tuple[float, float]:
    """Seal friction over a step with displacement increment ``dx``; (force, z_new).

    The eq 17 law at the chamber pressure (:func:`physics.friction_law.friction_law_at`),
    then Maxwell-slip (:func:`physics.maxwell_slip.maxwell_slip_step`) plus Kv v, or
    LuGre (:mod:`physics.lugre`). ``commit=False`` leaves ``deltas`` untouched (works
    on a copy in the scratch array ``cap``).
    """
    if par[_FRIC_ON] == 0.0:
        return 0.0, z
    v = dx / h
    fc, fs, vs, kv = friction_law_at(max(p, 0.0), par[_FC0 : _KV1 + 1])
    g = stribeck_g(v, fc, fs, vs)
    if par[_PRE_ON] != 0.0:
        n_el = ms_k.shape[0]
        if commit:
            force = maxwell_slip_step(deltas, dx, ms_k, ms_w, g)
        else:
            trial = cap[:n_el]
            trial[:] = deltas
            force = maxwell_slip_step(trial, dx, ms_k, ms_w, g)
        return force + kv * v, z
    z_new = lugre_z_step(z, v, h, par[_SIG0], g)
    return lugre_force(z, z_new, v, h, par[_SIG0], par[_SIG1], kv), z_new


@njit(cache=True)
def _line_loss(q: float, length_m: float, k_local: float, par: np.ndarray) -> float:
    """Loss of one branch part at flow ``q`` [m3/s], signed with it (paper eq 6, 12-14:
    :func:`physics.branch_loss.pipe_loss_pa`, Blasius when turbulent, smooth pipe);
    ``pipe_laminar_loss`` / ``local_loss`` off drop the part along the pipe / at the
    fittings."""
    bore = par[_DLOSS]
    u = q / (0.25 * math.pi * bore * bore)
    length = length_m if par[_LAM_ON] != 0.0 else 0.0
    k = k_local if par[_LOC_ON] != 0.0 else 0.0
    return pipe_loss_pa(u, bore, length, par[_MU] / par[_RHO], par[_RHO], k, 0.0, BLASIUS)


@njit(cache=True)
def _rhs(
    y: np.ndarray,
    par: np.ndarray,
    groove: np.ndarray,
    seg: np.ndarray,
    pay: np.ndarray,
    src_t: np.ndarray,
    src_s: np.ndarray,
    ms_k: np.ndarray,
    ms_w: np.ndarray,
    z: np.ndarray,
    deltas: np.ndarray,
    x_start: np.ndarray,
    h: float,
    cap: np.ndarray,
    out: np.ndarray,
    aux: np.ndarray,
) -> None:
    """dy/dt of the device; ``aux[i] = (friction, tension, dq/dt, sensor drop)``."""
    n = groove.shape[0]
    t = y[_T]
    eta = y[_ETA]
    etad = y[_ETAD]
    pm = y[_PM]
    beta = par[_BETA]
    area = par[_A]
    u, ud, ua = _profile(t, seg)
    payload, _ = _interp(t, pay[:, 0], pay[:, 1])
    tail_kg = 0.0
    if par[_TAIL_ON] != 0.0:
        tail_kg = par[_TAIL_KG_M] * max(par[_SHAFT] - u + par[_LOOP], 0.0)
    weight = (par[_MCONV] + payload + tail_kg) * par[_G]
    m_in = par[_MINERT] + payload + tail_kg
    k_rope = par[_EA] / (par[_LBASE] + u)
    c_rope = par[_CROPE]
    if c_rope <= 0.0:
        c_rope = 2.0 * par[_ZETA] * math.sqrt(k_rope * m_in / n)
    sum_g = 0.0
    sum_q = 0.0
    out[_T] = 1.0
    # first pass: forces piston -> body, rope tensions, hydraulics
    for i in range(n):
        b = _CYL0 + _PER * i
        p = y[b]
        x = y[b + 1]
        v = y[b + 2]
        q = y[b + 3]
        s_off, s_rate = _interp(t, src_t, src_s[:, i])
        e = eta - x - u * groove[i] / par[_RDRUM] - s_off
        ed = etad - v - ud * groove[i] / par[_RDRUM] - s_rate
        tension = k_rope * e + c_rope * ed
        ff, _ = _friction(p, x - x_start[i], h, par, z[i], deltas[i], ms_k, ms_w, cap, False)
        f_stop = 0.0
        if x > par[_XMAX]:
            f_stop = par[_KSTOP] * (x - par[_XMAX]) + par[_CSTOP] * v
        elif x < -par[_XMAX]:
            f_stop = par[_KSTOP] * (x + par[_XMAX]) + par[_CSTOP] * v
        g_i = p * area + ff + f_stop
        sum_g += g_i
        volume = par[_VMID] - area * x
        out[b] = beta / volume * (area * v - q * math.exp(-p / beta))
        out[b + 1] = v
        loss1 = _line_loss(q, par[_L1], par[_K1], par)
        loss2 = _line_loss(q, par[_L2], par[_K2], par)
        qdot = (p - pm - loss1 - loss2) / par[_INERT]
        out[b + 3] = qdot
        sum_q += q
        aux[i, 0] = ff
        aux[i, 1] = tension
        aux[i, 2] = qdot
        aux[i, 3] = par[_INERT1] * qdot + loss1
        out[b + 2] = tension - g_i  # divided by m_p and body acceleration added below
    out[_PM] = beta / par[_VM] * sum_q * math.exp(-pm / beta)
    if par[_FIXED] != 0.0:
        out[_ETA] = 0.0
        out[_ETAD] = 0.0
        body_acc = 0.0
    else:
        etadd = (weight - sum_g) / m_in - par[_INERTIA_ON] * ua
        out[_ETA] = etad
        out[_ETAD] = etadd
        body_acc = etadd + par[_INERTIA_ON] * ua
    for i in range(n):
        b = _CYL0 + _PER * i
        out[b + 2] = out[b + 2] / par[_MP] + body_acc


@njit(cache=True)
def _oil_volume(y: np.ndarray, par: np.ndarray, n: int) -> float:
    beta = par[_BETA]
    total = par[_VPIPES] + par[_VM] * math.exp(y[_PM] / beta)
    for i in range(n):
        b = _CYL0 + _PER * i
        total += (par[_VMID] - par[_A] * y[b + 1]) * math.exp(y[b] / beta)
    return total


@njit(cache=True)
def _run(
    y0,
    par,
    groove,
    seg,
    pay,
    src_t,
    src_s,
    ms_k,
    ms_w,
    z0,
    deltas0,
    dt,
    n_steps,
    record_every,
    jacobian_every,
    atol,
    rtol,
):  # pragma: no cover - compiled
    n_state = y0.shape[0]
    n = groove.shape[0]
    n_el = ms_k.shape[0]
    n_rec = n_steps // record_every + 1
    rec_y = np.full((n_rec, n_state), np.nan)
    rec_aux = np.full((n_rec, n, 4), np.nan)
    rec_vol = np.full(n_rec, np.nan)
    y = y0.copy()
    z = z0.copy()  # friction memory carried in (zero from static equilibrium)
    deltas = deltas0.copy()
    x_start = np.empty(n)
    for i in range(n):
        x_start[i] = y[_CYL0 + _PER * i + 1]
    cap = np.empty(2 * max(n_el, 1))
    aux = np.zeros((n, 4))
    f0 = np.empty(n_state)
    f1 = np.empty(n_state)
    k1 = np.empty(n_state)
    k2 = np.empty(n_state)
    yt = np.empty(n_state)
    w = np.empty((n_state, n_state))
    piv = np.empty(n_state, dtype=np.int64)
    err_max = 0.0
    err_at = np.zeros(2, dtype=np.int64)  # step and state index of the largest error
    stop_hits = np.zeros(n, dtype=np.int64)
    # record the initial state
    _rhs(y, par, groove, seg, pay, src_t, src_s, ms_k, ms_w, z, deltas, x_start, dt, cap, f0, aux)
    rec_y[0] = y
    rec_aux[0] = aux
    rec_vol[0] = _oil_volume(y, par, n)
    code = 0  # 0 ok, 1 singular, 2 non-finite, 3 cavitation
    fail_step = -1
    for step in range(n_steps):
        _rhs(
            y, par, groove, seg, pay, src_t, src_s, ms_k, ms_w, z, deltas, x_start, dt, cap, f0, aux
        )
        if step % jacobian_every == 0:
            # column of t left zero: the forcing (profile, payload, load sources) is
            # piecewise and an FD across a kink would poison W; any J is admissible
            # for the W-method ROS2, which keeps its order.
            for r in range(n_state):
                w[r, _T] = 0.0
            w[_T, _T] = 1.0
            for j in range(1, n_state):
                delta = 1e-7 * max(abs(y[j]), 1e3 * atol[j])
                yt[:] = y
                yt[j] += delta
                _rhs(
                    yt,
                    par,
                    groove,
                    seg,
                    pay,
                    src_t,
                    src_s,
                    ms_k,
                    ms_w,
                    z,
                    deltas,
                    x_start,
                    dt,
                    cap,
                    f1,
                    aux,
                )
                for r in range(n_state):
                    w[r, j] = -ROS2_GAMMA * dt * (f1[r] - f0[r]) / delta
                w[j, j] += 1.0
            if not lu_factor(w, piv):
                code = 1
                fail_step = step
                break
        k1[:] = f0
        lu_solve(w, piv, k1)
        for r in range(n_state):
            yt[r] = y[r] + dt * k1[r]
        _rhs(
            yt,
            par,
            groove,
            seg,
            pay,
            src_t,
            src_s,
            ms_k,
            ms_w,
            z,
            deltas,
            x_start,
            dt,
            cap,
            f1,
            aux,
        )
        for r in range(n_state):
            k2[r] = f1[r] - 2.0 * k1[r]
        lu_solve(w, piv, k2)
        acc = 0.0
        worst = 0
        worst_e = 0.0
        for r in range(n_state):
            y_new = y[r] + 1.5 * dt * k1[r] + 0.5 * dt * k2[r]
            e = 0.5 * dt * (k1[r] + k2[r]) / (atol[r] + rtol * abs(y_new))
            acc += e * e
            if abs(e) > worst_e:
                worst_e = abs(e)
                worst = r
            y[r] = y_new
        err = math.sqrt(acc / n_state)
        if not math.isfinite(err):
            code = 2
            fail_step = step
            break
        if err > err_max:
            err_max = err
            err_at[0] = step
            err_at[1] = worst
        # commit the friction memory with the accepted displacement increments
        for i in range(n):
            b = _CYL0 + _PER * i
            ff, z_new = _friction(
                y[b], y[b + 1] - x_start[i], dt, par, z[i], deltas[i], ms_k, ms_w, cap, True
            )
            z[i] = z_new
            aux[i, 0] = ff
            x_start[i] = y[b + 1]
            if abs(y[b + 1]) > par[_XMAX]:
                stop_hits[i] += 1
            if y[b] < 0.0:
                code = 3
                fail_step = step
        if code != 0:
            break
        if (step + 1) % record_every == 0:
            committed = aux[:, 0].copy()
            _rhs(
                y,
                par,
                groove,
                seg,
                pay,
                src_t,
                src_s,
                ms_k,
                ms_w,
                z,
                deltas,
                x_start,
                dt,
                cap,
                f1,
                aux,
            )
            aux[:, 0] = committed
            kr = (step + 1) // record_every
            rec_y[kr] = y
            rec_aux[kr] = aux
            rec_vol[kr] = _oil_volume(y, par, n)
    return rec_y, rec_aux, rec_vol, err_max, err_at, code, fail_step, stop_hits, y, z, deltas


# ---------------------------------------------------------------------------------------
# set-up in Python
# ---------------------------------------------------------------------------------------
_STIFF_OIL_FACTOR = 1000.0
_K_STOP_N_M = 1e9


@dataclass(frozen=True)
class _Setup:
    par: np.ndarray
    groove: np.ndarray
    seg: np.ndarray
    pay: np.ndarray
    src_t: np.ndarray
    src_s: np.ndarray
    ms_k: np.ndarray
    ms_w: np.ndarray
    sensor_gain: np.ndarray
    sensor_offset: np.ndarray
    oil_temp_c: float


def _build_par(
    hoist: HoistDescription,
    eff: ResolvedEffects,
    *,
    oil_temp_c: float,
    p_static_pa: float,
    fixed_body: bool = False,
    rope_damping_n_s_m: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    prm = eff.parameters
    cyl, piping, oil = hoist.cylinders, hoist.piping, hoist.oil
    par = np.zeros(_NPAR)
    par[_A] = cyl.bore_area_m2
    par[_VMID] = cyl.chamber_volume_mid_m3
    par[_MP] = cyl.piston_mass_kg
    par[_XMAX] = cyl.stroke_m / 2.0
    par[_KSTOP] = _K_STOP_N_M
    par[_CSTOP] = 2.0 * math.sqrt(_K_STOP_N_M * cyl.piston_mass_kg)
    comp = prm["oil_compressibility"]
    beta = float(comp["bulk_modulus_pa"])
    if comp["air_fraction"] > 0.0:
        beta = float(
            effective_bulk_modulus(
                p_static_pa + ATMOSPHERIC_PRESSURE_PA, beta, float(comp["air_fraction"])
            )
        )
    if not eff.on("oil_compressibility"):
        beta *= _STIFF_OIL_FACTOR
    par[_BETA] = beta
    par[_VM] = piping.manifold_volume_m3
    if par[_VM] <= 0.0:
        raise ValueError("piping.manifold_volume must be positive for the device simulation")
    par[_RHO] = oil.density_kg_m3
    visc = prm["viscosity_temperature"]
    if eff.on("viscosity_temperature"):
        a, b = walther_coefficients(
            visc["kinematic_viscosity_40c_m2_s"], 40.0, visc["kinematic_viscosity_100c_m2_s"], 100.0
        )
        nu = float(kinematic_viscosity_walther(oil_temp_c, a, b))
    else:
        a, b = walther_coefficients(
            oil.kinematic_viscosity_40c_m2_s, 40.0, oil.kinematic_viscosity_100c_m2_s, 100.0
        )
        nu = float(kinematic_viscosity_walther(oil.reference_temperature_c, a, b))
    par[_MU] = nu * oil.density_kg_m3
    l1, l2 = piping.length_chamber_to_sensor_m, piping.length_sensor_to_manifold_m
    par[_INERT] = oil.density_kg_m3 * (l1 + l2) / piping.area_m2
    par[_INERT1] = oil.density_kg_m3 * l1 / piping.area_m2
    par[_VPIPES] = hoist.ropes_n * piping.area_m2 * (l1 + l2)
    lam = prm["pipe_laminar_loss"]
    par[_L1] = lam["length_chamber_to_sensor_m"]
    par[_L2] = lam["length_sensor_to_manifold_m"]
    par[_DLOSS] = lam["bore_m"]
    loc = prm["local_loss"]
    par[_K1] = loc["valve_loss_coefficient"] + loc["fittings_chamber_to_sensor"]
    par[_K2] = loc["fittings_sensor_to_manifold"]
    par[_LAM_ON] = float(eff.on("pipe_laminar_loss"))
    par[_LOC_ON] = float(eff.on("local_loss"))
    par[_FRIC_ON] = float(eff.on("seal_friction"))
    par[_PRE_ON] = float(eff.on("presliding_hysteresis"))
    if eff.on("presliding_hysteresis") and not eff.on("seal_friction"):
        raise ValueError(
            "effect 'presliding_hysteresis' needs 'seal_friction' (its element capacities "
            "are the seal's Stribeck friction g(v))"
        )
    fr = prm["seal_friction"]
    par[_FC0], par[_FC1] = fr["coulomb_n"]
    par[_FS0], par[_FS1] = fr["static_n"]
    par[_VS0], par[_VS1] = fr["stribeck_speed_m_s"]
    par[_KV0], par[_KV1] = fr["viscous_n_s_m"]
    par[_SIG0] = fr["bristle_stiffness_n_m"]
    par[_SIG1] = fr["bristle_damping_n_s_m"]
    par[_MINERT] = prm["conveyance_inertia"]["mass_kg"]
    par[_MCONV] = hoist.conveyance.mass_kg
    par[_INERTIA_ON] = float(eff.on("conveyance_inertia"))
    tail = prm["tail_rope_weight"]
    par[_TAIL_ON] = float(eff.on("tail_rope_weight"))
    par[_TAIL_KG_M] = tail["tail_ropes"] * tail["mass_per_length_kg_m"]
    par[_SHAFT] = hoist.shaft.depth_m
    par[_LOOP] = hoist.shaft.tail_rope_loop_m
    par[_G] = G_STANDARD
    par[_EA] = hoist.ropes.head_rope_axial_stiffness_n
    par[_LBASE] = hoist.shaft.headframe_height_m
    par[_ZETA] = hoist.ropes.head_rope_damping_ratio
    par[_RDRUM] = hoist.drum.radius_m
    par[_FIXED] = float(fixed_body)
    par[_CROPE] = rope_damping_n_s_m
    groove = (
        np.array(prm["groove_wear"]["groove_radius_deviation_m"], dtype=float)
        if eff.on("groove_wear")
        else np.zeros(hoist.ropes_n)
    )
    if eff.on("presliding_hysteresis"):
        ms_k, ms_w = maxwell_slip_elements(
            int(prm["presliding_hysteresis"]["elements"]),
            float(prm["presliding_hysteresis"]["stiffness_n_m"]),
        )
    else:
        ms_k, ms_w = np.ones(1), np.ones(1)
    return par, groove, (ms_k, ms_w)


def _sensor_calibration(eff: ResolvedEffects, n: int) -> tuple[np.ndarray, np.ndarray]:
    gain = (
        np.array(eff.parameters["sensor_gain"]["gains"], dtype=float)
        if eff.on("sensor_gain")
        else np.ones(n)
    )
    offset = (
        np.array(eff.parameters["sensor_offset"]["offsets_pa"], dtype=float)
        if eff.on("sensor_offset")
        else np.zeros(n)
    )
    return gain, offset


def _atol(n: int) -> np.ndarray:
    head = [1e-6, 1e-6, 1e-5, 100.0]
    return np.array(head + [100.0, 1e-7, 1e-5, 1e-9] * n)


def _integrate(
    setup: _Setup,
    y0: np.ndarray,
    *,
    duration_s: float,
    dt_s: float,
    output_rate_hz: float,
    jacobian_every: int,
    eff: ResolvedEffects,
    profile: TripProfile | None,
    rtol: float = 1e-4,
    z0: np.ndarray | None = None,
    deltas0: np.ndarray | None = None,
) -> SimulationResult:
    if not dt_s > 0 or not output_rate_hz > 0:
        raise ValueError("dt_s and output_rate_hz must be positive")
    record_every = round(1.0 / (output_rate_hz * dt_s))
    if record_every < 1 or not math.isclose(
        record_every * dt_s * output_rate_hz, 1.0, rel_tol=1e-9
    ):
        raise ValueError(
            f"the output interval 1/output_rate_hz = {1 / output_rate_hz:g} s must be a whole "
            f"multiple of dt_s = {dt_s:g} s"
        )
    if jacobian_every < 1:
        raise ValueError("jacobian_every must be at least 1")
    n_steps = record_every * math.ceil(duration_s * output_rate_hz - 1e-9)
    n = setup.groove.shape[0]
    n_el = max(setup.ms_k.shape[0], 1)
    z0 = np.zeros(n) if z0 is None else np.array(z0, dtype=float)
    deltas0 = np.zeros((n, n_el)) if deltas0 is None else np.array(deltas0, dtype=float)
    if z0.shape != (n,) or deltas0.shape != (n, n_el):
        raise ValueError(
            f"friction memory: need z of shape ({n},) and Maxwell-slip deflections of shape "
            f"({n}, {n_el}), got {z0.shape} and {deltas0.shape}"
        )
    atol = _atol(n)
    wall0 = time.perf_counter()
    (
        rec_y,
        rec_aux,
        rec_vol,
        err_max,
        err_at,
        code,
        fail_step,
        stop_hits,
        y_end,
        z_end,
        deltas_end,
    ) = _run(
        y0,
        setup.par,
        setup.groove,
        setup.seg,
        setup.pay,
        setup.src_t,
        setup.src_s,
        setup.ms_k,
        setup.ms_w,
        np.ascontiguousarray(z0),
        np.ascontiguousarray(deltas0),
        dt_s,
        n_steps,
        record_every,
        jacobian_every,
        atol,
        rtol,
    )
    wall = time.perf_counter() - wall0
    good = np.isfinite(rec_vol)
    rec_y, rec_aux, rec_vol = rec_y[good], rec_aux[good], rec_vol[good]
    t = rec_y[:, _T]
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
        b = _CYL0 + _PER * i
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
    cols["p_manifold_pa"] = rec_y[:, _PM]
    cols["oil_volume_m3"] = rec_vol
    frame = pl.DataFrame(cols)
    t_fail = y0[_T] + (fail_step + 1) * dt_s
    reasons = {
        1: f"iteration matrix singular at t = {t_fail:.4f} s",
        2: f"state went non-finite at t = {t_fail:.4f} s (step {dt_s:g} s too large?)",
        3: f"chamber pressure fell below zero gauge at t = {t_fail:.4f} s (cavitation is "
        "not modelled; slack rope?)",
    }
    notes = [f"ROS2 fixed step {dt_s:g} s, {n_steps if code == 0 else fail_step + 1} steps"]
    hits = [str(i + 1) for i in range(n) if stop_hits[i] > 0]
    if hits:
        notes.append(f"pistons {', '.join(hits)} reached the stroke end stops")
    state_names = ["t", "eta", "deta/dt", "p_manifold"] + [
        f"{name}{i + 1}" for i in range(n) for name in ("p", "x", "v", "q")
    ]
    err_where = f"t = {y0[_T] + (err_at[0] + 1) * dt_s:.3f} s, state {state_names[err_at[1]]}"
    if err_max > 1.0:
        notes.append(
            f"local error estimate up to {err_max:.3g} x tolerance at {err_where} (fixed "
            "step, not adapted; reduce dt_s where that matters)"
        )
    status = "success" if code == 0 else "failed"
    message = "; ".join(([reasons[code]] if code else []) + notes)
    solver = {
        "method": "ROS2 (Verwer et al. 1999), L-stable Rosenbrock-W, FD Jacobian",
        "dt_s": dt_s,
        "jacobian_every": jacobian_every,
        "atol": atol,
        "rtol": rtol,
        "steps": n_steps if code == 0 else fail_step + 1,
        "error_ratio_max": float(err_max),
        "error_ratio_max_at": err_where,
        "wall_s": wall,
    }
    final_state = None
    if code == 0:
        t_end = float(y_end[_T])
        final_state = DeviceState(
            time_s=t_end,
            depth_m=float(profile.depth(t_end)) if profile is not None else 0.0,
            speed_m_s=float(profile.speed(t_end)) if profile is not None else 0.0,
            payload_kg=float(profile.payload(t_end)) if profile is not None else 0.0,
            eta_m=float(y_end[_ETA]),
            eta_rate_m_s=float(y_end[_ETAD]),
            p_manifold_pa=float(y_end[_PM]),
            p_chamber_pa=_frozen([y_end[_CYL0 + _PER * i] for i in range(n)]),
            x_m=_frozen([y_end[_CYL0 + _PER * i + 1] for i in range(n)]),
            v_m_s=_frozen([y_end[_CYL0 + _PER * i + 2] for i in range(n)]),
            q_m3_s=_frozen([y_end[_CYL0 + _PER * i + 3] for i in range(n)]),
            lugre_z_m=_frozen(z_end),
            maxwell_slip_m=_frozen(deltas_end),
            bulk_modulus_pa=float(setup.par[_BETA]),
            effects=eff,
        )
    return SimulationResult(
        status=status,
        message=message,
        frame=frame,
        effects=eff,
        solver=solver,
        final_state=final_state,
    )


def simulate(
    hoist: HoistDescription,
    profile: TripProfile,
    *,
    effects: set[str] | list[str] | tuple[str, ...] | frozenset[str] | None = None,
    parameters: dict[str, dict[str, Any]] | None = None,
    output_rate_hz: float = 100.0,
    dt_s: float = 1e-3,
    jacobian_every: int = 10,
    initial_state: DeviceState | None = None,
) -> SimulationResult:
    """Simulate the connection device, ropes and conveyance over one trip profile.

    Parameters
    ----------
    hoist : HoistDescription
        The hoist (contract section 2).
    profile : TripProfile
        Commanded motion, payload and oil temperature (:mod:`sims.trips`).
    effects : collection of effect names, optional
        Contract section 4 names to switch on; default ``hoist.model.effects``.
    parameters : dict, optional
        ``{effect: {parameter: value}}`` overrides, see :mod:`sims.effects`.
    output_rate_hz : float
        Output samples per second (1/rate must be a multiple of ``dt_s``).
    dt_s : float
        Integrator step [s].
    jacobian_every : int
        Refresh the finite-difference Jacobian every this many steps.
    initial_state : DeviceState, optional
        Continue from this state (the :attr:`SimulationResult.final_state` of a previous
        run): pressures, pistons, flows, conveyance and the seals' friction memory
        (LuGre z, Maxwell-slip deflections) carry over, so nothing steps. The profile
        must start where the state is: depth within
        :data:`CONTINUATION_DEPTH_TOLERANCE_M`, the same payload and commanded speed,
        and the same effects and parameters (the state's bulk modulus is kept).

    Returns
    -------
    SimulationResult
        ``status`` "success" or "failed" (with the reason in ``message``); ``frame`` with
        :data:`OUTPUT_COLUMNS`; ``final_state`` to continue from.

    Raises
    ------
    ValueError
        ``initial_state`` does not fit the profile's start or the run's effects.

    Without ``initial_state`` the run starts in static equilibrium at the profile's first
    depth and payload: equal chamber pressures ``W / (n A)``, pistons placed so that the
    ropes (with any groove offsets) carry equal tensions, no friction stored, oil at rest.
    """
    eff = resolve_effects(hoist, effects, parameters)
    n = hoist.ropes_n
    if initial_state is not None:
        _check_continuation(initial_state, profile, eff, n)
    oil_temp = (
        hoist.oil.reference_temperature_c if profile.oil_temp_c is None else profile.oil_temp_c
    )
    t0 = profile.t0_s
    u0 = float(profile.depth(t0))
    pay0 = float(profile.payload(t0))
    tail0 = (
        eff.parameters["tail_rope_weight"]["tail_ropes"]
        * eff.parameters["tail_rope_weight"]["mass_per_length_kg_m"]
        * max(tail_rope_length_m(hoist, u0), 0.0)
        if eff.on("tail_rope_weight")
        else 0.0
    )
    weight0 = (hoist.conveyance.mass_kg + pay0 + tail0) * G_STANDARD
    area = hoist.cylinders.bore_area_m2
    p0 = weight0 / (n * area)
    par, groove, (ms_k, ms_w) = _build_par(hoist, eff, oil_temp_c=oil_temp, p_static_pa=p0)
    seg = np.column_stack(
        [
            profile.segment_start_s,
            profile.segment_depth_m,
            profile.segment_speed_m_s,
            profile.segment_acceleration_m_s2,
        ]
    ).astype(float)
    pay = np.column_stack([profile.payload_time_s, profile.payload_kg]).astype(float)
    gain, offset = _sensor_calibration(eff, n)
    setup = _Setup(
        par=par,
        groove=groove,
        seg=np.ascontiguousarray(seg),
        pay=np.ascontiguousarray(pay),
        src_t=np.array([t0]),
        src_s=np.zeros((1, n)),
        ms_k=np.ascontiguousarray(ms_k),
        ms_w=np.ascontiguousarray(ms_w),
        sensor_gain=gain,
        sensor_offset=offset,
        oil_temp_c=float(oil_temp),
    )
    k0 = par[_EA] / (par[_LBASE] + u0)
    offsets = u0 * groove / par[_RDRUM]
    x0 = -(offsets - offsets.mean())
    y0 = np.zeros(_CYL0 + _PER * n)
    y0[_T] = t0
    y0[_ETA] = weight0 / (n * k0) + offsets.mean()
    y0[_PM] = p0
    for i in range(n):
        b = _CYL0 + _PER * i
        y0[b] = p0
        y0[b + 1] = x0[i]
    z0 = deltas0 = None
    if initial_state is not None:
        # continue: every state, the friction memory and the oil's bulk modulus carry over
        y0 = initial_state._vector(t0)
        par[_BETA] = initial_state.bulk_modulus_pa
        z0 = initial_state.lugre_z_m
        deltas0 = initial_state.maxwell_slip_m
    elif np.any(np.abs(x0) > hoist.cylinders.stroke_m / 2):
        raise ValueError("groove offsets at the start depth exceed the stroke")
    return _integrate(
        setup,
        y0,
        duration_s=profile.duration_s,
        dt_s=dt_s,
        output_rate_hz=output_rate_hz,
        jacobian_every=jacobian_every,
        eff=eff,
        profile=profile,
        z0=z0,
        deltas0=deltas0,
    )


#: How far [m] a continuing profile's start depth may lie from the state's depth.
CONTINUATION_DEPTH_TOLERANCE_M = 0.05


def _same_parameters(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same_parameters(a[k], b[k]) for k in a)
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    try:
        x, y = np.asarray(a), np.asarray(b)
        return x.shape == y.shape and bool(np.all(x == y))
    except (TypeError, ValueError):  # pragma: no cover - exotic parameter values
        return a == b


def _check_continuation(
    state: DeviceState, profile: TripProfile, eff: ResolvedEffects, n: int
) -> None:
    """Raise ValueError unless ``profile`` can start from ``state`` with effects ``eff``."""
    if not isinstance(state, DeviceState):
        raise ValueError(
            f"initial_state: need a DeviceState (SimulationResult.final_state), got "
            f"{type(state).__name__}"
        )
    if state.ropes_n != n:
        raise ValueError(f"initial_state has {state.ropes_n} ropes, the hoist {n}")
    if state.effects.enabled != eff.enabled:
        raise ValueError(
            "initial_state was simulated with other effects: "
            f"{sorted(state.effects.enabled)} vs {sorted(eff.enabled)}"
        )
    if not _same_parameters(state.effects.parameters, eff.parameters):
        raise ValueError("initial_state was simulated with other effect parameters")
    t0 = profile.t0_s
    depth = float(profile.depth(t0))
    if abs(depth - state.depth_m) > CONTINUATION_DEPTH_TOLERANCE_M:
        raise ValueError(
            f"initial_state is at depth {state.depth_m:.3f} m, the profile starts at "
            f"{depth:.3f} m (more than {CONTINUATION_DEPTH_TOLERANCE_M:g} m apart)"
        )
    payload = float(profile.payload(t0))
    if abs(payload - state.payload_kg) > 1e-6 * max(1.0, abs(state.payload_kg)):
        raise ValueError(
            f"initial_state carries a payload of {state.payload_kg:g} kg, the profile starts "
            f"with {payload:g} kg (the payload is held between runs; change it in the profile)"
        )
    speed = float(profile.speed(t0))
    if abs(speed - state.speed_m_s) > 1e-6:
        raise ValueError(
            f"initial_state moves at {state.speed_m_s:g} m/s, the profile starts at {speed:g} m/s"
        )


# ---------------------------------------------------------------------------------------
# Paper section 3.2
# ---------------------------------------------------------------------------------------
#: Load-source knots of the section 3.2 scenario (Figure 10): time [s] and load per
#: cylinder [N]. Ramps from about 2000 N to about 5000 N over 0-3 s with different
#: slopes, then a sudden change (10 ms) to more than 6000 N, cylinder 2 largest and 1
#: smallest (section 3.2.2 (5)).
SCENARIO_3_2_TIME_S = np.array([0.0, 3.0, 3.01, 6.0])
SCENARIO_3_2_LOAD_N = np.array(
    [
        [2100.0, 1900.0, 2000.0, 2200.0],
        [5500.0, 4500.0, 4100.0, 6000.0],
        [6200.0, 7500.0, 6900.0, 6600.0],
        [6200.0, 7500.0, 6900.0, 6600.0],
    ]
)


def paper_scenario_3_2(
    *,
    pipe_characteristics: bool = True,
    seal_friction: bool = False,
    rope_stiffness_n_m: float = 5.0e4,
    rope_damping_n_s_m: float = 2.0e3,
    stop_valve_loss_coefficient: float = 10.0,
    duration_s: float = 6.0,
    dt_s: float = 1e-4,
    output_rate_hz: float = 1000.0,
) -> SimulationResult:
    """The four-cylinder scenario of paper section 3.2 (Figures 9-14).

    Four balancing cylinders (the paper 2.2 cylinder: 80 mm bore, 800 mm long) with
    fixed bodies; each rod is pulled through a spring-damper ("rope", paper Fig. 9
    item 6) by a load source (item 2) that would produce the load
    :data:`SCENARIO_3_2_LOAD_N` if the piston stood still (rope end displaced by
    ``-load / k``). The branches are the paper 2.2 pipe (6 mm, 1 m: 0.3 m to the sensor,
    0.7 m on) with a stop valve (``stop_valve_loss_coefficient``, open) on each bypass
    tube, into a 0.1 L manifold; VG 46 oil at 40 degC, 1.5 GPa.

    ``pipe_characteristics=False`` is the paper's case (2), "the characteristic of oil
    tube is not considered": no losses along the pipes nor at the valves (inertia and
    compressibility stay). With ``pipe_characteristics=True`` (case 3) the four
    pressures are equalised by the connection after each load change, with a pressure
    shock after the sudden change at 3 s that decays. At rest the pistons sit at
    ``(load_i - mean load) / k``: the spread of loads is taken up by piston travel.

    Solver as :func:`simulate` (ROS2), default step 0.1 ms, output 1 kHz.
    """
    base = load_hoist(EXAMPLE_HOIST)
    cylinders = Cylinders(
        bore="80 mm", rod="45 mm", stroke="800 mm", dead_volume="0.05 L", piston_mass="5 kg"
    )
    piping = Piping(
        bore="6 mm",
        length_chamber_to_sensor="0.3 m",
        length_sensor_to_manifold="0.7 m",
        valve_loss_coefficient=stop_valve_loss_coefficient,
        fittings_loss_coefficient_chamber_to_sensor=0.0,
        fittings_loss_coefficient_sensor_to_manifold=0.0,
        manifold_volume="0.1 L",
    )
    hoist = base.model_copy(update={"cylinders": cylinders, "piping": piping})
    hoist.__dict__.pop("friction_law", None)  # cached for the base bore; recompute
    effects = {"oil_compressibility"}
    if pipe_characteristics:
        effects |= {"pipe_laminar_loss", "local_loss"}
    if seal_friction:
        effects.add("seal_friction")
    eff = resolve_effects(hoist, effects)
    n = 4
    area = cylinders.bore_area_m2
    loads = SCENARIO_3_2_LOAD_N
    p0 = float(loads[0].mean() / area)
    par, _groove, (ms_k, ms_w) = _build_par(
        hoist,
        eff,
        oil_temp_c=40.0,
        p_static_pa=p0,
        fixed_body=True,
        rope_damping_n_s_m=rope_damping_n_s_m,
    )
    par[_EA] = rope_stiffness_n_m  # k = EA / (L_base + depth) with L_base = 1 m, depth 0
    par[_LBASE] = 1.0
    setup = _Setup(
        par=par,
        groove=np.zeros(n),
        seg=np.array([[0.0, 0.0, 0.0, 0.0]]),
        pay=np.array([[0.0, 0.0]]),
        src_t=SCENARIO_3_2_TIME_S.astype(float),
        src_s=np.ascontiguousarray(-loads / rope_stiffness_n_m),
        ms_k=np.ascontiguousarray(ms_k),
        ms_w=np.ascontiguousarray(ms_w),
        sensor_gain=np.ones(n),
        sensor_offset=np.zeros(n),
        oil_temp_c=40.0,
    )
    y0 = np.zeros(_CYL0 + _PER * n)
    y0[_PM] = p0
    for i in range(n):
        b = _CYL0 + _PER * i
        y0[b] = p0
        y0[b + 1] = (loads[0, i] - loads[0].mean()) / rope_stiffness_n_m
    return _integrate(
        setup,
        y0,
        duration_s=duration_s,
        dt_s=dt_s,
        output_rate_hz=output_rate_hz,
        jacobian_every=1,
        eff=eff,
        profile=None,
    )
