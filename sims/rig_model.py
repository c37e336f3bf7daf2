"""The rig's compiled model: port modes and the right-hand side (see :mod:`sims.rig`).

State ``y = (x, v, z, p_A, p_B, p_L, y_A, y_B)``: rod position and velocity, LuGre
bristle deflection, rodless, rod-side and loading-cylinder pressures, the two overflow
valves' openings. :func:`rhs` is dy/dt for one program segment's port modes and
settings; :mod:`sims.rig_solver` integrates it.
"""

from __future__ import annotations

import math

from numba import njit

from physics.friction_law import friction_law_at, stribeck_g
from physics.lugre import lugre_force_at, lugre_z_rate

# Port modes of the program (per segment, per chamber port).
PORT_FLOW = 0  # flow servo into the chamber (velocity control)
PORT_RELIEF = 1  # outlet through the branch to an overflow / back-pressure valve
PORT_TANK = 2  # open to tank (p = 0 gauge)
PORT_PRESSURE = 3  # pressure-regulated supply through the branch (setting = its pressure)

N_STATE = 8  # state: x, v, z, pA, pB, pL, yA, yB
P_FLOOR = -0.09e6  # gauge pressure floor (vacuum): cavitation is not modelled


@njit(cache=True)
def _line_flow(dp, r_lam, r_loc):  # pragma: no cover - compiled
    # flow through the branch for a pressure difference: R_lam q + R_loc q|q| = dp
    a = abs(dp)
    q = 2.0 * a / (r_lam + math.sqrt(r_lam * r_lam + 4.0 * r_loc * a))
    return q if dp >= 0.0 else -q


@njit(cache=True)
def rhs(y, out, c, law, seg):  # pragma: no cover - compiled
    """dy/dt into ``out``; returns the seal friction [N].

    Longer than 80 lines on purpose: the compiled right-hand side the integrator calls
    nine times a step (state and finite-difference Jacobian); the seal, both ports, the
    loading cylinder and the force balance share their locals and stay one function for
    speed.
    """
    # c: constants; seg: current segment values; law: physics.friction_law.law_array
    x, v, z, pa, pb, pl_, ya, yb = y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7]
    ab, aa, al, m, stroke, v_dead, beta = c[0], c[1], c[2], c[3], c[4], c[5], c[6]
    r_lam, r_loc, q_rated, dp_ov, tau_v = c[7], c[8], c[9], c[10], c[11]
    sigma0, sigma1, has_friction = c[12], c[13], c[14]
    v_load0, pump_crack, pump_ov, k_pos = c[15], c[16], c[17], c[18]
    mode_a, mode_b, set_a, set_b, q_pump, v_cmd, x_ref, coupled = (
        seg[0],
        seg[1],
        seg[2],
        seg[3],
        seg[4],
        seg[5],
        seg[6],
        seg[7],
    )
    # --- seal friction, LuGre (eq 15) with eq 17 parameters at p_A
    if has_friction > 0.5:
        fc, fs, vs, kv = friction_law_at(pa, law)
        zdot = lugre_z_rate(z, v, sigma0, stribeck_g(v, fc, fs, vs))
        friction = lugre_force_at(z, zdot, v, sigma0, sigma1, kv)
    else:
        zdot = -z * 1e3
        friction = 0.0
    # --- chamber volumes (x = 0 mid-stroke)
    half = 0.5 * stroke
    va = v_dead + ab * (half + x)
    vb = v_dead + aa * (half - x)
    # --- port A flow into the chamber
    dya = -ya / tau_v
    if mode_a == PORT_FLOW:
        qa = ab * (v_cmd + k_pos * (x_ref - x))
    elif mode_a == PORT_RELIEF:
        qv = q_rated * max(ya, 0.0) * min(max(pa / 0.2e6, 0.0), 1.0)
        p_port = pa - (r_lam * qv + r_loc * qv * qv)
        dya = ((p_port - set_a) / dp_ov - ya) / tau_v
        if ya <= 0.0 and dya < 0.0:
            dya = 0.0
        qa = -qv
    elif mode_a == PORT_PRESSURE:
        qa = _line_flow(set_a - pa, r_lam, r_loc)
    else:
        qa = 0.0
    dya_out = dya
    dyb = -yb / tau_v
    if mode_b == PORT_FLOW:
        qb = aa * (-v_cmd - k_pos * (x_ref - x))
    elif mode_b == PORT_RELIEF:
        qv = q_rated * max(yb, 0.0) * min(max(pb / 0.2e6, 0.0), 1.0)
        p_port = pb - (r_lam * qv + r_loc * qv * qv)
        dyb = ((p_port - set_b) / dp_ov - yb) / tau_v
        if yb <= 0.0 and dyb < 0.0:
            dyb = 0.0
        qb = -qv
    elif mode_b == PORT_PRESSURE:
        qb = _line_flow(set_b - pb, r_lam, r_loc)
    else:
        qb = 0.0
    # --- loading cylinder (paper Fig. 4 item 8), pushing the rod in (x decreasing)
    if coupled > 0.5:
        vl = v_load0 + al * (half - x)
        q_rel = max(pl_ - pump_crack, 0.0) * max(q_pump, 1e-6) / pump_ov
        dpl = beta / vl * (q_pump - q_rel + al * v)
        f_load = pl_ * al
    else:
        dpl = -pl_ * 1e3
        f_load = 0.0
    out[0] = v
    out[1] = (pa * ab - pb * aa - friction - f_load) / m
    out[2] = zdot
    out[3] = 0.0 if mode_a == PORT_TANK else beta / va * (qa - ab * v)
    out[4] = 0.0 if mode_b == PORT_TANK else beta / vb * (qb + aa * v)
    out[5] = dpl
    out[6] = dya_out
    out[7] = dyb
    return friction
