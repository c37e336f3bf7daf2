"""The single-cylinder test rig of paper sections 3.1 and 4.2.1, and its MCAP recordings.

One lumped model serves both experiments of the paper:

* **Pressure-loss test (section 3.1, Fig. 4-5).** The loading cylinder (Fig. 4 item 8),
  fed by the pump (rated 12 MPa, 20 L/min) through the directional valve, pushes the
  tested cylinder's rod in; the tested rodless chamber expels its oil through its branch
  (directional valve + hose) to the overflow valve (item 10) that sets the load pressure.
  The rodless chamber then reads the load pressure plus the branch loss (eq 12-14) plus
  the valve's flow override: a loss that depends on flow only, not on the load
  (:func:`pressure_loss_test`). A relief valve's opening lag makes the start overshoot.
* **Friction test (section 4.2.1, Fig. 15).** The tested cylinder alone, driven at a
  controlled velocity by a flow servo into one chamber, while the pressure-control
  (back-pressure) valve on the other chamber's outlet holds the oil pressure at the
  setpoint, 2..12 MPa, in both directions (:func:`friction_test_program`,
  :func:`simulate_rig`). Friction is what the pressures do not explain (contract 3):
  ``F = p_rodless A_bore - p_rod (A_bore - A_rod) - m a``.

Model (SI; x positive rod out, the rodless chamber growing):

.. math::
    m \\dot v = p_A A_b - p_B A_a - F_{LuGre}(v, z, p_A) - p_L A_L \\\\
    \\dot p_A = \\frac{\\beta}{V_A(x)}(Q_A - A_b v), \\quad
    \\dot p_B = \\frac{\\beta}{V_B(x)}(Q_B + A_a v), \\quad
    \\dot p_L = \\frac{\\beta}{V_L(x)}(Q_{pump} - Q_{relief} + A_L v)

with LuGre (paper eq 15) for the seal, its parameters linear in the rodless pressure
p_A (eq 17 form, a :class:`~schemas.hoist.FrictionLaw`), and an overflow valve per
outlet whose opening y lags its static characteristic by a first-order time constant:
``Q = Q_rated y``, ``tau dy/dt = (p_port - p_set)/dp_override - y``. Branch lines are
resistive: ``p_chamber - p_port = R_lam Q + R_loc Q|Q|`` (eq 6/12 laminar, eq 13 local).

Integrator: ROS2 (two-stage, second-order, L-stable Rosenbrock-W, Verwer et al. 1999;
:func:`sims.hydraulics.ros2_step`) at a fixed step with a finite-difference Jacobian
every step: a bulk modulus of 1.5 GPa on a 0.2 L dead volume (hydraulic stiffness
~5e8 N/m) and a bristle stiffness of 2.5e7 N/m stay stable at any step; transients are
second order in dt (a step is split where a program segment starts), steady states
exact. Until issue 17 this was a first-order Rosenbrock-Euler step, whose numerical
damping hid the stick-slip limit cycle of the rod at 2 MPa and 8 mm/s. Compiled with
numba: ~0.33 M steps/s on one core, ~80x real time at the default 0.25 ms step.

Code: this module is the public face; the parts live in :mod:`sims.rig_design`
(:class:`RigDesign`, :class:`RigProgram`, :class:`RigRecording`), :mod:`sims.rig_model`
(port modes, the compiled right-hand side), :mod:`sims.rig_solver` (the integrator,
:func:`simulate_rig`), :mod:`sims.rig_programs` (the paper's tests) and
:mod:`sims.rig_mcap` (:func:`write_rig_mcap`).
"""

from __future__ import annotations

from sims.rig_design import (
    PAPER_LOSS_PA,
    RigDesign,
    RigProgram,
    RigRecording,
    default_friction_law,
)
from sims.rig_mcap import RigSensors, write_rig_mcap
from sims.rig_model import PORT_FLOW, PORT_PRESSURE, PORT_RELIEF, PORT_TANK
from sims.rig_programs import (
    LossTestResult,
    friction_test_program,
    pressure_loss_test,
    small_friction_test_program,
)
from sims.rig_solver import simulate_rig

__all__ = [
    "PAPER_LOSS_PA",
    "PORT_FLOW",
    "PORT_PRESSURE",
    "PORT_RELIEF",
    "PORT_TANK",
    "LossTestResult",
    "RigDesign",
    "RigProgram",
    "RigRecording",
    "RigSensors",
    "default_friction_law",
    "friction_test_program",
    "pressure_loss_test",
    "simulate_rig",
    "small_friction_test_program",
    "write_rig_mcap",
]
