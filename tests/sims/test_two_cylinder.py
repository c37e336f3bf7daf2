"""Two cylinders joined by a pipe (paper 2.2): simulated step response vs eq 9/10."""

from __future__ import annotations

import math

import pytest

from physics.two_cylinder import PAPER_2_2, damping_ratio, natural_frequency, transfer_function
from sims.two_cylinder import fit_second_order_step, simulate_step

# Hand-computed from the paper 2.2 constants (rho 900, mu 0.0414, d 6 mm, l 1 m,
# V2 = pi 0.08^2/4 x 0.8 m) with beta = 1.5 GPa, independent of the module:
V2 = math.pi * 0.08**2 / 4 * 0.8
OMEGA_N = 0.003 * math.sqrt(math.pi * 1.5e9 / (900 * 1.0 * V2))  # eq 9
XI = 32 * 0.0414 / 0.006**3 * math.sqrt(1.0 * V2 / (math.pi * 1.5e9 * 900))  # eq 10 corr.


def test_analytic_values_match_hand_computation():
    assert natural_frequency() == pytest.approx(OMEGA_N, rel=1e-12)
    assert damping_ratio() == pytest.approx(XI, rel=1e-12)
    assert OMEGA_N == pytest.approx(108.26, abs=0.01)
    assert XI == pytest.approx(0.1889, abs=1e-4)


def test_eq11_resonance_peak():
    # corrected eq 11: |G(j omega_n)| = 1 / (2 xi)
    assert abs(transfer_function(1j * OMEGA_N)) == pytest.approx(1 / (2 * XI), rel=1e-12)


@pytest.fixture(scope="module")
def response():
    return simulate_step(PAPER_2_2)


def test_step_response_succeeds_and_settles(response):
    assert response.status == "success"
    assert response.p2_pa[-1] == pytest.approx(response.p1_pa, rel=1e-3)


def test_fitted_frequency_and_damping_within_3_percent(response):
    wn, xi = fit_second_order_step(response)
    assert wn == pytest.approx(OMEGA_N, rel=0.03)
    assert xi == pytest.approx(XI, rel=0.03)


def test_printed_eq10_is_not_what_the_simulation_shows(response):
    # the paper's printed eq 10 (pi d beta under the root, no rho) gives another number
    printed = 32 * 0.0414 / 0.006**3 * math.sqrt(V2 * 1.0 / (math.pi * 0.006 * 1.5e9))
    _, xi = fit_second_order_step(response)
    assert abs(xi - printed) / printed > 0.5


def test_failed_simulation_refuses_fit(response):
    from dataclasses import replace

    with pytest.raises(ValueError, match="failed"):
        fit_second_order_step(replace(response, status="failed", message="x"))
