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
not adapted). Where the forcing (winder, payload, the ropes' source offsets) stays
constant until some ``t_end`` and every state's rate, extrapolated over ``t_end - t``,
stays within a tenth of its absolute tolerance, the state is held to ``t_end`` instead
of stepped (:data:`sims.device_solver.QUIET_FRACTION`; the solver record counts the
steps held, ``steps_held_at_rest``): a device at rest between trips costs next to
nothing (the extrapolation is an estimate of what a hold leaves out, not a bound; see
there for what it moved). Failure -- a non-finite
state, a singular iteration matrix, a chamber pressure below zero gauge (cavitation,
not modelled) -- ends the run with ``status="failed"``, the reason and the frame up to
the last good sample.

Code
----
This module holds :func:`simulate` and its continuation checks; the parts live in
private submodules: :mod:`sims.device_params` (the parameter vector and state layout,
packed from the hoist description), :mod:`sims.device_model` (the compiled right-hand
side and its kernels), :mod:`sims.device_solver` (the ROS2 loop),
:mod:`sims.device_results` (:class:`SimulationResult`, :class:`DeviceState`,
:data:`OUTPUT_COLUMNS`) and :mod:`sims.device_scenarios` (paper section 3.2).

References
----------
Song et al., Research on dynamic characteristics and compensation of wire rope tension
and load measurement based on hydraulic connection device (the paper, eq 1-17).
Canudas de Wit et al. (1995), IEEE TAC 40(3) 419-425 (LuGre). Al-Bender et al. (2005),
IEEE TAC 50(11) 1883-1887 (GMS).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from physics.friction_law import friction_law_at
from physics.rope_spring import groove_payout_m
from physics.tension import tail_rope_length_m
from schemas.hoist import G_STANDARD, HoistDescription
from sims.device_params import (
    BETA,
    CYL0,
    EA,
    ETA,
    FC0,
    FRIC_ON,
    KF0,
    KV1,
    LBASE,
    PER,
    PM,
    PRE_ON,
    RDRUM,
    SIG0,
    A,
    Setup,
    T,
    build_par,
    sensor_calibration,
)
from sims.device_results import OUTPUT_COLUMNS, DeviceState, SimulationResult
from sims.device_scenarios import SCENARIO_3_2_LOAD_N, SCENARIO_3_2_TIME_S, paper_scenario_3_2
from sims.device_solver import integrate
from sims.effects import ResolvedEffects, resolve_effects
from sims.trips import TripProfile

__all__ = [
    "CONTINUATION_DEPTH_TOLERANCE_M",
    "OUTPUT_COLUMNS",
    "SCENARIO_3_2_LOAD_N",
    "SCENARIO_3_2_TIME_S",
    "DeviceState",
    "SimulationResult",
    "paper_scenario_3_2",
    "simulate",
]


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
    pistons_m: np.ndarray | None = None,
    hold_at_rest: bool = True,
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
    pistons_m : (n,) array, optional
        Without ``initial_state``: start at rest with the pistons here [m, in the ropes'
        frame: rope i stretches by ``eta - pistons_m[i]``, any groove offset included;
        only the differences count], the seals holding what the ropes leave them
        (:func:`held_start`), instead of where equal tensions put them.
    hold_at_rest : bool
        Hold the state instead of stepping it where the forcing is constant and the
        device still (module docstring, Solver); False steps every ``dt_s``.

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
    setup, y0 = _static_start(hoist, eff, profile)
    z0 = deltas0 = None
    if initial_state is None and pistons_m is not None:
        y0, z0, deltas0 = held_start(
            setup, y0, np.asarray(pistons_m, dtype=float), float(profile.depth(profile.t0_s))
        )
    if initial_state is not None:
        # continue: every state, the friction memory and the oil's bulk modulus carry over
        y0 = initial_state._vector(profile.t0_s)
        setup.par[BETA] = initial_state.bulk_modulus_pa
        z0 = initial_state.lugre_z_m
        deltas0 = initial_state.maxwell_slip_m
    elif np.any(np.abs(y0[CYL0 + 1 :: PER]) > hoist.cylinders.stroke_m / 2):
        raise ValueError("groove offsets at the start depth exceed the stroke")
    return integrate(
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
        hold_at_rest=hold_at_rest,
    )


def _static_start(
    hoist: HoistDescription, eff: ResolvedEffects, profile: TripProfile
) -> tuple[Setup, np.ndarray]:
    """The run's set-up and its static equilibrium at the profile's first depth and
    payload: equal chamber pressures ``W / (n A)``, pistons placed so that the ropes
    (with any groove offsets) carry equal tensions, oil at rest."""
    n = hoist.ropes_n
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
    par, groove, (ms_k, ms_w) = build_par(hoist, eff, oil_temp_c=oil_temp, p_static_pa=p0)
    seg = np.column_stack(
        [
            profile.segment_start_s,
            profile.segment_depth_m,
            profile.segment_speed_m_s,
            profile.segment_acceleration_m_s2,
        ]
    ).astype(float)
    pay = np.column_stack([profile.payload_time_s, profile.payload_kg]).astype(float)
    gain, offset = sensor_calibration(eff, n)
    setup = Setup(
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
    k0 = par[EA] / (par[LBASE] + u0)
    offsets = groove_payout_m(u0, groove / par[RDRUM])
    # equal tensions weight0 / n: rope i stretches weight0 / (n k0 f_i); the pistons
    # take up the differences (mean zero)
    stretch = weight0 / (n * k0 * par[KF0 : KF0 + n])
    x0 = -(offsets + stretch - (offsets + stretch).mean())
    y0 = np.zeros(CYL0 + PER * n)
    y0[T] = t0
    y0[ETA] = (offsets + stretch).mean()
    y0[PM] = p0
    for i in range(n):
        b = CYL0 + PER * i
        y0[b] = p0
        y0[b + 1] = x0[i]
    return setup, y0


def held_start(
    setup: Setup, y0: np.ndarray, pistons_m: np.ndarray, depth_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A static start (``y0`` of :func:`_static_start`) with the pistons at ``pistons_m``
    (their mean taken as zero, so the oil inventory is the static start's; in the ropes'
    frame: rope i stretches by ``eta - pistons_m[i]``, any groove offset included, so a
    groove wear in the model moves the pistons by its offsets at ``depth_m``) and the seals
    holding what the ropes leave them at ``depth_m``: the state vector, LuGre z and Maxwell-slip
    deflections.

    At rest each piston's equation (paper eq 2) is T_i = p A + F_i. The ropes' common
    stretch is set so that they carry the static weight (sum T_i = n p A, p the static
    start's equal pressure), and each seal holds F_i = T_i - p A: zero in sum, the
    ropes' imbalance at these piston positions. A seal holds at most its static
    friction F_s at p (eq 17); beyond it the piston would have slid, so its friction is
    clipped there. The bristle that holds F at rest is z = F / sigma_0 (LuGre, eq 15);
    Maxwell-slip elements deflect together by the d that gives F (each clipped at its
    share of F_s; :func:`physics.maxwell_slip.maxwell_slip_step`). Without seal friction nothing
    holds a piston: the static start is returned unchanged.
    """
    par, groove = setup.par, setup.groove
    n = groove.shape[0]
    z0 = np.zeros(n)
    deltas0 = np.zeros((n, setup.ms_k.shape[0]))
    if par[FRIC_ON] == 0.0:
        return y0, z0, deltas0  # nothing holds a piston: equal tensions place them
    # rope i stretches by eta - x_i - o_i (o_i its groove offset at this depth), and the
    # given positions already hold the record's whole imbalance: the pistons go to
    # pistons_m - o (mean zero), so that rope i stretches by eta - pistons_m_i
    offsets = groove_payout_m(depth_m, groove / par[RDRUM])
    x = pistons_m - offsets
    x = x - x.mean()
    u = x + offsets  # each rope's stretch is eta - u_i
    y = y0.copy()
    p0 = float(y0[PM])
    area = par[A]
    weight = n * p0 * area
    factors = par[KF0 : KF0 + n]
    k0 = par[EA] / (par[LBASE] + depth_m)
    # sum_i k0 f_i (eta - u_i) = W
    eta = (weight / k0 + float(np.sum(factors * u))) / float(np.sum(factors))
    held = k0 * factors * (eta - u) - p0 * area
    _, fs, _, _ = friction_law_at(max(p0, 0.0), par[FC0 : KV1 + 1])
    held = np.clip(held, -fs, fs)
    if par[PRE_ON] != 0.0:
        deltas0 = np.array([_elements_holding(f, setup.ms_k, setup.ms_w * fs) for f in held])
    else:
        z0 = held / par[SIG0]
    y[ETA] = eta
    for i in range(n):
        y[CYL0 + PER * i + 1] = x[i]
    return y, z0, deltas0


def _elements_holding(force: float, k: np.ndarray, capacity: np.ndarray) -> np.ndarray:
    """Deflections of Maxwell-slip elements (stiffnesses ``k``, capacities ``capacity``)
    moved together from rest until their force is ``force`` (|force| <= sum capacity)."""
    lo, hi = 0.0, float(np.max(capacity / k))
    for _ in range(60):  # bisection on the common deflection (the force is monotone in it)
        mid = 0.5 * (lo + hi)
        if np.sum(np.minimum(k * mid, capacity)) < abs(force):
            lo = mid
        else:
            hi = mid
    return np.sign(force) * np.minimum(0.5 * (lo + hi), capacity / k)


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
