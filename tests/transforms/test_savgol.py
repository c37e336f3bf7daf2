"""The direct Savitzky-Golay derivative of transforms.kinematics against scipy's."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from physics.conveyance import _savgol_derivative


@pytest.mark.parametrize("n_win", [5, 21, 51])
def test_direct_savgol_matches_scipy(n_win: int) -> None:
    rng = np.random.default_rng(n_win)
    y = np.cumsum(rng.normal(0.0, 1e-4, 10 * n_win + 7))
    expected = signal.savgol_filter(y, n_win, 2, deriv=1, delta=0.01, mode="interp")
    got = _savgol_derivative(y, n_win, 2, 0.01)
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-12 * np.max(np.abs(expected)))


def test_direct_savgol_of_a_flat_signal_is_exactly_zero() -> None:
    """A piston at rest has no velocity: not ~1e-14 of its position, which scipy's
    least-squares coefficients (odd only to ~1e-14) would give, and which would put a
    tiny flow, and a branch-loss evaluation, on every sample at standstill."""
    y = np.full(500, 0.0123)
    y[300:] = 0.0125  # a step between two rests
    got = _savgol_derivative(y, 21, 2, 0.01)
    # the interior (the first and last 10 samples are scipy's end-window polynomials)
    assert np.all(got[10:289] == 0.0)
    assert np.all(got[311:-10] == 0.0)
    assert np.all(got[290:310] > 0.0)
