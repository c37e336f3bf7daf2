"""Two cylinders joined by a pipe: the analytic second-order model of paper section 2.2.

Cylinder 1's rodless-chamber pressure ``p1`` is the input; oil flows through one pipe
into cylinder 2, whose piston is held, so its chamber is a fixed volume ``V2`` of
compressible oil. Continuity (eq 5), the oil column's momentum (eq 7) and the laminar
loss (eq 6) combine into eq 8, a second-order lag

.. math::

    G(s) = \\frac{P_2}{P_1} = \\frac{1}{s^2/\\omega_n^2 + 2 \\xi s / \\omega_n + 1}
    \\quad \\text{(eq 11, corrected)}

with :func:`natural_frequency` (eq 9) and :func:`damping_ratio` (eq 10, corrected).

Errata (NOTES.md): the paper prints eq 10 with ``pi d beta`` under the root (not even
dimensionless; eq 8's coefficients give the form used here) and eq 11 with
``1/omega_n`` for the ``s^2`` coefficient.

Constants (paper 2.2): rho 900 kg/m3, nu 46 mm2/s, mu 0.0414 kg/(m s), piston 80 mm,
cylinder 800 mm (V2 = pi 0.08^2 / 4 x 0.8 m = 4.02 L), pipe 6 mm x 1000 mm. The paper
gives no bulk modulus; 1.5 GPa (mineral oil without air, NOTES.md).
:mod:`sims.two_cylinder` integrates the two ODEs and fits its step response against
these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "PAPER_2_2",
    "TwoCylinderConstants",
    "damping_ratio",
    "natural_frequency",
    "transfer_function",
]


@dataclass(frozen=True)
class TwoCylinderConstants:
    """Constants of the two-cylinder model, SI."""

    density_kg_m3: float = 900.0
    dynamic_viscosity_pa_s: float = 0.0414
    piston_diameter_m: float = 0.080
    cylinder_length_m: float = 0.800
    pipe_bore_m: float = 0.006
    pipe_length_m: float = 1.000
    bulk_modulus_pa: float = 1.5e9  # not given in the paper; NOTES.md

    @property
    def volume2_m3(self) -> float:
        """Chamber volume of cylinder 2, pi D^2 / 4 x L [m3]."""
        return math.pi * self.piston_diameter_m**2 / 4.0 * self.cylinder_length_m


#: The constants of paper section 2.2 with a 1.5 GPa bulk modulus.
PAPER_2_2 = TwoCylinderConstants()


def natural_frequency(c: TwoCylinderConstants = PAPER_2_2) -> float:
    """Undamped natural frequency, paper eq 9 [rad/s].

    .. math:: \\omega_n = \\frac{d}{2} \\sqrt{\\frac{\\pi \\beta}{\\rho l V_2}}

    >>> round(natural_frequency(), 2)
    108.25
    """
    return (
        c.pipe_bore_m
        / 2.0
        * math.sqrt(
            math.pi * c.bulk_modulus_pa / (c.density_kg_m3 * c.pipe_length_m * c.volume2_m3)
        )
    )


def damping_ratio(c: TwoCylinderConstants = PAPER_2_2) -> float:
    """Damping ratio, paper eq 10 in its corrected form (NOTES.md errata) [-].

    .. math:: \\xi = \\frac{32 \\mu}{d^3} \\sqrt{\\frac{l V_2}{\\pi \\beta \\rho}}

    The printed eq 10 has ``pi d beta`` under the root; that does not follow from eq 8
    (and is not even dimensionless).

    >>> round(damping_ratio(), 4)
    0.1889
    """
    return (
        32.0
        * c.dynamic_viscosity_pa_s
        / c.pipe_bore_m**3
        * math.sqrt(
            c.pipe_length_m * c.volume2_m3 / (math.pi * c.bulk_modulus_pa * c.density_kg_m3)
        )
    )


def transfer_function(s: complex | np.ndarray, c: TwoCylinderConstants = PAPER_2_2):
    """P2(s)/P1(s), paper eq 11 with the corrected ``1/omega_n^2`` coefficient [-].

    .. math:: G(s) = \\frac{1}{s^2/\\omega_n^2 + 2 \\xi s/\\omega_n + 1}

    >>> abs(transfer_function(0.0))
    1.0
    """
    wn = natural_frequency(c)
    xi = damping_ratio(c)
    return 1.0 / (s * s / wn**2 + 2.0 * xi * s / wn + 1.0)
