"""Two cylinders joined by a pipe: the analytic check model of paper section 2.2.

Cylinder 1's rodless-chamber pressure ``p1`` is the input (a step); oil flows through
one pipe into cylinder 2, whose piston is held, so its chamber is a fixed volume
``V2`` of compressible oil. With ``q`` the pipe flow and ``a = pi d^2 / 4``:

.. math::

    \\frac{V_2}{\\beta} \\frac{dp_2}{dt} = q
        \\qquad \\text{(eq 5, with } q = a \\bar u\\text{)} \\\\
    \\frac{\\rho l}{a} \\frac{dq}{dt} = p_1 - p_2 - \\frac{128 \\mu l}{\\pi d^4} q
        \\qquad \\text{(eq 7 divided by } a \\text{, eq 6 laminar loss)}

which combine into eq 8, a second-order lag ``P2/P1 = 1 / (s^2/omega_n^2 +
2 xi s / omega_n + 1)`` (eq 11, corrected: the paper prints ``1/omega_n`` for the
``s^2`` coefficient) with

.. math::

    \\omega_n = \\frac{d}{2} \\sqrt{\\frac{\\pi \\beta}{\\rho l V_2}} \\quad \\text{(eq 9)},
    \\qquad
    \\xi = \\frac{32 \\mu}{d^3} \\sqrt{\\frac{l V_2}{\\pi \\beta \\rho}}
    \\quad \\text{(eq 10, corrected)}.

Erratum (NOTES.md): the paper prints eq 10 with ``pi d beta`` under the root; eq 8's
coefficients give the form above. Eq 5's inline "F = sigma0 z + ..." is misplaced:
``u-bar`` is the mean oil velocity in the pipe.

Constants (paper 2.2): rho 900 kg/m3, nu 46 mm2/s, mu 0.0414 kg/(m s), piston 80 mm,
cylinder 800 mm (V2 = pi 0.08^2 / 4 x 0.8 m = 4.02 L), pipe 6 mm x 1000 mm. The paper
gives no bulk modulus; we use 1.5 GPa (mineral oil without air, NOTES.md).

The simulation integrates the two ODEs above with the shared ROS2 integrator
(:func:`sims.hydraulics.ros2_integrate`), so the fit of its step response against
eq 9/10 checks the integrator, not only the algebra.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.optimize import curve_fit

from physics.branch_loss import laminar_resistance
from physics.two_cylinder import PAPER_2_2, TwoCylinderConstants
from sims.hydraulics import ros2_integrate

__all__ = [
    "StepResponse",
    "fit_second_order_step",
    "simulate_step",
]


@dataclass(frozen=True)
class StepResponse:
    """Simulated step response of the two-cylinder model.

    ``status`` is ``"success"`` or ``"failed"`` (then ``message`` says why and the
    arrays end in NaN); ``error_ratio_max`` is the largest weighted RMS local error
    estimate of the integrator (below 1: within ``atol``/``rtol``).
    """

    time_s: np.ndarray
    p2_pa: np.ndarray
    q_m3_s: np.ndarray
    p1_pa: float
    p0_pa: float
    status: str
    message: str
    error_ratio_max: float


@njit(cache=True)
def _rhs(y: np.ndarray, par: np.ndarray, out: np.ndarray) -> None:
    # y = [t, p2, q]; par = [p1, beta, V2, inertance rho l / a, R laminar]
    out[0] = 1.0
    out[1] = par[1] / par[2] * y[2]  # eq 5
    out[2] = (par[0] - y[1] - par[4] * y[2]) / par[3]  # eq 7 / a with eq 6


def simulate_step(
    c: TwoCylinderConstants = PAPER_2_2,
    *,
    p0_pa: float = 1.0e6,
    p1_pa: float = 1.1e6,
    duration_s: float = 0.3,
    dt_s: float = 1.0e-5,
    output_dt_s: float = 1.0e-4,
) -> StepResponse:
    """Step of cylinder 1's pressure from ``p0_pa`` to ``p1_pa`` at t = 0.

    Solver: ROS2 (Verwer et al. 1999), fixed step ``dt_s`` (default 10 us, omega_n dt
    = 1e-3), per-state atol (1 Pa, 1e-12 m3/s), rtol 1e-6 for the reported error
    estimate. A 0.1 MPa step keeps the peak pipe Reynolds number near 100 (laminar,
    where eq 6 holds).
    """
    if not dt_s > 0 or not output_dt_s >= dt_s:
        raise ValueError("need 0 < dt_s <= output_dt_s")
    record_every = round(output_dt_s / dt_s)
    if not math.isclose(record_every * dt_s, output_dt_s, rel_tol=1e-9):
        raise ValueError("output_dt_s must be a whole multiple of dt_s")
    n_steps = record_every * math.ceil(duration_s / output_dt_s)
    area = math.pi * c.pipe_bore_m**2 / 4.0
    par = np.array(
        [
            p1_pa,
            c.bulk_modulus_pa,
            c.volume2_m3,
            c.density_kg_m3 * c.pipe_length_m / area,
            laminar_resistance(c.dynamic_viscosity_pa_s, c.pipe_length_m, c.pipe_bore_m),
        ]
    )
    y0 = np.array([0.0, p0_pa, 0.0])
    atol = np.array([1e-9, 1.0, 1e-12])
    states, err, ok = ros2_integrate(_rhs, y0, par, dt_s, n_steps, record_every, atol, 1e-6)
    status, message = "success", "ROS2 fixed step completed"
    if not ok:
        status, message = "failed", "state went non-finite or the iteration matrix was singular"
    return StepResponse(
        time_s=states[:, 0],
        p2_pa=states[:, 1],
        q_m3_s=states[:, 2],
        p1_pa=p1_pa,
        p0_pa=p0_pa,
        status=status,
        message=message,
        error_ratio_max=float(err),
    )


def _step_model(t: np.ndarray, wn: float, xi: float) -> np.ndarray:
    wd = wn * math.sqrt(max(1.0 - xi * xi, 1e-12))
    return 1.0 - np.exp(-xi * wn * t) * (np.cos(wd * t) + xi * wn / wd * np.sin(wd * t))


def fit_second_order_step(response: StepResponse) -> tuple[float, float]:
    """Fit ``omega_n`` [rad/s] and ``xi`` [-] of an underdamped 2nd-order step response.

    Least squares (scipy ``curve_fit``) of the normalised response
    ``(p2 - p0)/(p1 - p0)`` against ``1 - e^{-xi wn t}(cos wd t + xi wn/wd sin wd t)``,
    ``wd = wn sqrt(1 - xi^2)``, started from the period and log decrement of the first
    two overshoot peaks (so the fit does not depend on eq 9/10).
    """
    if response.status != "success":
        raise ValueError(f"cannot fit a failed simulation: {response.message}")
    t = response.time_s
    y = (response.p2_pa - response.p0_pa) / (response.p1_pa - response.p0_pa)
    e = y - 1.0
    peaks = [i for i in range(1, len(e) - 1) if e[i] > e[i - 1] and e[i] >= e[i + 1] and e[i] > 0]
    if len(peaks) < 2:
        raise ValueError("response has fewer than two overshoot peaks; not underdamped")
    period = t[peaks[1]] - t[peaks[0]]
    delta = math.log(e[peaks[0]] / e[peaks[1]])
    xi0 = delta / math.sqrt(4.0 * math.pi**2 + delta**2)
    wn0 = 2.0 * math.pi / period / math.sqrt(1.0 - xi0**2)
    (wn, xi), _ = curve_fit(_step_model, t, y, p0=(wn0, xi0))
    return float(wn), float(xi)
