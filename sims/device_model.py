"""The device simulation's compiled model: the right-hand side and its kernels.

The equations (chamber continuity, branch flow with the sensor tee, pistons with seal
friction and end stops, head ropes, conveyance) are written out in :mod:`sims.device`;
here they are the numba kernels :func:`rhs` (dy/dt), :func:`friction_step` (LuGre or
Maxwell-slip over a step), :func:`_line_loss` (branch part loss) and
:func:`oil_volume` (the conserved oil inventory), reading the flat parameter vector
of :mod:`sims.device_params`.

The kernels allocate nothing and are compiled without numba's reference-counted runtime
(``_nrt=False``): the arrays they receive are borrowed from the caller for the call,
and neither they nor the views made of them are reference counted. Each count is an
atomic add or subtract; the device loop calls :func:`rhs` about four times a step, and
the counts on its arrays, its views and those of its four :func:`friction_step` calls
took ~20 % of the device benchmark's wall time (see :mod:`sims.device_solver`). A
kernel that needed a temporary would not compile ("NRT required but not enabled"), so
array copies are loops (numba may compile ``a[:] = b`` to a temporary copy).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from physics.branch_loss import BLASIUS, pipe_loss_pa
from physics.friction_law import friction_law_at, stribeck_g
from physics.lugre import lugre_force, lugre_z_step
from physics.maxwell_slip import maxwell_slip_step
from physics.rope_spring import groove_payout_m
from sims.device_params import (
    BETA,
    CROPE,
    CSTOP,
    CYL0,
    DLOSS,
    EA,
    ETA,
    ETAD,
    FC0,
    FIXED,
    FRIC_ON,
    INERT,
    INERT1,
    INERTIA_ON,
    K1,
    K2,
    KF0,
    KSTOP,
    KV1,
    L1,
    L2,
    LAM_ON,
    LBASE,
    LOC_ON,
    LOOP,
    MCONV,
    MINERT,
    MP,
    MU,
    PER,
    PM,
    PRE_ON,
    RDRUM,
    RHO,
    SHAFT,
    SIG0,
    SIG1,
    TAIL_KG_M,
    TAIL_ON,
    VM,
    VMID,
    VPIPES,
    XMAX,
    ZETA,
    A,
    G,
    T,
)


@njit(cache=True, _nrt=False)
def _segment_at(t: float, seg: np.ndarray) -> int:
    """The profile segment holding ``t``: the last whose start is at or before it (the
    first before them all), by bisection (the starts increase,
    :class:`sims.trip_profile.TripProfile`; a logged trip has ~800 segments and
    :func:`rhs` asks ~4 times a step)."""
    lo, hi = 0, seg.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if seg[mid, 0] <= t:
            lo = mid + 1
        else:
            hi = mid
    return max(lo - 1, 0)


@njit(cache=True, _nrt=False)
def _profile(t: float, seg: np.ndarray) -> tuple[float, float, float]:
    k = _segment_at(t, seg)
    tau = max(t - seg[k, 0], 0.0)
    a = seg[k, 3]
    return seg[k, 1] + seg[k, 2] * tau + 0.5 * a * tau * tau, seg[k, 2] + a * tau, a


@njit(cache=True, _nrt=False)
def _knot_interval(t: float, knots_t: np.ndarray) -> int:
    """The knot interval ``(knots_t[j], knots_t[j + 1]]`` holding ``t``, for ``t``
    strictly inside the knots (at a repeated knot, a step: the interval before it)."""
    j = 0
    while knots_t[j + 1] < t:
        j += 1
    return j


@njit(cache=True, _nrt=False)
def _interp(t: float, knots_t: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """Piecewise-linear value and slope, constant outside the knots."""
    m = knots_t.shape[0]
    if t <= knots_t[0]:
        return values[0], 0.0
    if t >= knots_t[m - 1]:
        return values[m - 1], 0.0
    j = _knot_interval(t, knots_t)
    span = knots_t[j + 1] - knots_t[j]
    if span <= 0.0:
        return values[j + 1], 0.0
    slope = (values[j + 1] - values[j]) / span
    return values[j] + slope * (t - knots_t[j]), slope


@njit(cache=True, _nrt=False)
def _knots_constant_until(t: float, knots_t: np.ndarray, values: np.ndarray) -> float:
    """Up to when :func:`_interp`'s value stays what it is at ``t`` (``t`` if it is
    changing there, ``inf`` if it never changes again), its knot interval found as
    :func:`_interp` finds it (:func:`_knot_interval`)."""
    m = knots_t.shape[0]
    if t >= knots_t[m - 1]:
        return math.inf
    first = 0  # the first interval that may change the value after t
    if t > knots_t[0]:
        j = _knot_interval(t, knots_t)
        if values[j + 1] != values[j]:
            return t
        first = j + 1
    for k in range(first, m - 1):
        if values[k + 1] != values[k]:
            return knots_t[k]
    return math.inf


@njit(cache=True, _nrt=False)
def constant_until(
    t: float,
    seg: np.ndarray,
    pay: np.ndarray,
    src_t: np.ndarray,
    src_s: np.ndarray,
) -> float:
    """Up to when the forcing :func:`rhs` reads at ``t`` stays what it is: the winder
    at rest (its profile segment with zero speed and acceleration) until the next
    segment that is not at rest at the same depth (a logged motion's rest is a run of
    0.1 s segments), the payload and each rope's source offset until their next
    changing knot; ``t`` itself where any of them changes there."""
    k = _segment_at(t, seg)
    if seg[k, 2] != 0.0 or seg[k, 3] != 0.0:
        return t
    last = seg.shape[0] - 1
    j = k
    while j < last and seg[j + 1, 1] == seg[k, 1] and seg[j + 1, 2] == 0.0 and seg[j + 1, 3] == 0.0:
        j += 1
    end = seg[j + 1, 0] if j < last else math.inf
    end = min(end, _knots_constant_until(t, pay[:, 0], pay[:, 1]))
    for i in range(src_s.shape[1]):
        end = min(end, _knots_constant_until(t, src_t, src_s[:, i]))
    return end


@njit(cache=True, _nrt=False)
def friction_step(
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
    if par[FRIC_ON] == 0.0:
        return 0.0, z
    v = dx / h
    fc, fs, vs, kv = friction_law_at(max(p, 0.0), par[FC0 : KV1 + 1])
    g = stribeck_g(v, fc, fs, vs)
    if par[PRE_ON] != 0.0:
        n_el = ms_k.shape[0]
        if commit:
            force = maxwell_slip_step(deltas, dx, ms_k, ms_w, g)
        else:
            trial = cap[:n_el]
            for j in range(n_el):
                trial[j] = deltas[j]
            force = maxwell_slip_step(trial, dx, ms_k, ms_w, g)
        return force + kv * v, z
    z_new = lugre_z_step(z, v, h, par[SIG0], g)
    return lugre_force(z, z_new, v, h, par[SIG0], par[SIG1], kv), z_new


@njit(cache=True, _nrt=False)
def _line_loss(q: float, length_m: float, k_local: float, par: np.ndarray) -> float:
    """Loss of one branch part at flow ``q`` [m3/s], signed with it (paper eq 6, 12-14:
    :func:`physics.branch_loss.pipe_loss_pa`, Blasius when turbulent, smooth pipe);
    ``pipe_laminar_loss`` / ``local_loss`` off drop the part along the pipe / at the
    fittings."""
    bore = par[DLOSS]
    u = q / (0.25 * math.pi * bore * bore)
    length = length_m if par[LAM_ON] != 0.0 else 0.0
    k = k_local if par[LOC_ON] != 0.0 else 0.0
    return pipe_loss_pa(u, bore, length, par[MU] / par[RHO], par[RHO], k, 0.0, BLASIUS)


@njit(cache=True, _nrt=False)
def rhs(y: np.ndarray, args: tuple, out: np.ndarray) -> None:
    """dy/dt of the device at ``y`` into ``out``, in the ``rhs(y, args, out)`` form of
    the ROS2 functions (:mod:`sims.hydraulics`); ``aux[i] = (friction, tension, dq/dt,
    sensor drop)``.

    ``args = (par, groove, seg, pay, src_t, src_s, ms_k, ms_w, z, deltas, x_start, h,
    cap, aux)``: a :class:`~sims.device_params.Setup`'s arrays, the friction memory (z,
    Maxwell-slip deflections, the pistons' positions at the step's start), the step
    ``h``, the scratch ``cap`` and the output ``aux``. Unpacked here, in a kernel
    without reference counting, rather than by the caller at each call.

    Longer than 80 lines on purpose: it is the compiled right-hand side the ROS2 loop
    calls 2 + n_state times per Jacobian step; the two passes over the cylinders (forces
    and hydraulics, then the piston accelerations once the conveyance's is known) share
    their locals and stay one function for speed.
    """
    par, groove, seg, pay, src_t, src_s, ms_k, ms_w, z, deltas, x_start, h, cap, aux = args
    n = groove.shape[0]
    t = y[T]
    eta = y[ETA]
    etad = y[ETAD]
    pm = y[PM]
    beta = par[BETA]
    area = par[A]
    u, ud, ua = _profile(t, seg)
    payload, _ = _interp(t, pay[:, 0], pay[:, 1])
    tail_kg = 0.0
    if par[TAIL_ON] != 0.0:
        tail_kg = par[TAIL_KG_M] * max(par[SHAFT] - u + par[LOOP], 0.0)
    weight = (par[MCONV] + payload + tail_kg) * par[G]
    m_in = par[MINERT] + payload + tail_kg
    k_rope = par[EA] / (par[LBASE] + u)
    c_rope = par[CROPE]
    if c_rope <= 0.0:
        c_rope = 2.0 * par[ZETA] * math.sqrt(k_rope * m_in / n)
    sum_g = 0.0
    sum_q = 0.0
    out[T] = 1.0
    # first pass: forces piston -> body, rope tensions, hydraulics
    for i in range(n):
        b = CYL0 + PER * i
        p = y[b]
        x = y[b + 1]
        v = y[b + 2]
        q = y[b + 3]
        s_off, s_rate = _interp(t, src_t, src_s[:, i])
        worn = groove[i] / par[RDRUM]  # a groove's payout and its rate
        e = eta - x - groove_payout_m(u, worn) - s_off
        ed = etad - v - groove_payout_m(ud, worn) - s_rate
        tension = k_rope * par[KF0 + i] * e + c_rope * ed  # rope i's EA factor
        ff, _ = friction_step(p, x - x_start[i], h, par, z[i], deltas[i], ms_k, ms_w, cap, False)
        f_stop = 0.0
        if x > par[XMAX]:
            f_stop = par[KSTOP] * (x - par[XMAX]) + par[CSTOP] * v
        elif x < -par[XMAX]:
            f_stop = par[KSTOP] * (x + par[XMAX]) + par[CSTOP] * v
        g_i = p * area + ff + f_stop
        sum_g += g_i
        volume = par[VMID] - area * x
        out[b] = beta / volume * (area * v - q * math.exp(-p / beta))
        out[b + 1] = v
        loss1 = _line_loss(q, par[L1], par[K1], par)
        loss2 = _line_loss(q, par[L2], par[K2], par)
        qdot = (p - pm - loss1 - loss2) / par[INERT]
        out[b + 3] = qdot
        sum_q += q
        aux[i, 0] = ff
        aux[i, 1] = tension
        aux[i, 2] = qdot
        aux[i, 3] = par[INERT1] * qdot + loss1
        out[b + 2] = tension - g_i  # divided by m_p and body acceleration added below
    out[PM] = beta / par[VM] * sum_q * math.exp(-pm / beta)
    if par[FIXED] != 0.0:
        out[ETA] = 0.0
        out[ETAD] = 0.0
        body_acc = 0.0
    else:
        etadd = (weight - sum_g) / m_in - par[INERTIA_ON] * ua
        out[ETA] = etad
        out[ETAD] = etadd
        body_acc = etadd + par[INERTIA_ON] * ua
    for i in range(n):
        b = CYL0 + PER * i
        out[b + 2] = out[b + 2] / par[MP] + body_acc


@njit(cache=True, _nrt=False)
def oil_volume(y: np.ndarray, par: np.ndarray, n: int) -> float:
    beta = par[BETA]
    total = par[VPIPES] + par[VM] * math.exp(y[PM] / beta)
    for i in range(n):
        b = CYL0 + PER * i
        total += (par[VMID] - par[A] * y[b + 1]) * math.exp(y[b] / beta)
    return total
