"""The pipeline's own Savitzky-Golay and Butterworth designs (physics.filter_design):
analytic properties, and scipy.signal's results (the reference they replace on the run's
import path) for the windows, orders and cut-offs the pipeline uses and beyond."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from physics.filter_design import butter_lowpass_sos, savgol_coeffs, savgol_filter, sosfilt_zi


def _response(sos: np.ndarray, f_hz: np.ndarray, fs_hz: float) -> np.ndarray:
    """|H| of the section cascade at frequencies f (z = exp(i 2 pi f / fs))."""
    z1 = np.exp(-2j * np.pi * f_hz / fs_hz)  # z^-1
    h = np.ones_like(z1)
    for b0, b1, b2, a0, a1, a2 in sos:
        h *= (b0 + b1 * z1 + b2 * z1**2) / (a0 + a1 * z1 + a2 * z1**2)
    return np.abs(h)


@pytest.mark.parametrize("order", [2, 4, 6, 8])
@pytest.mark.parametrize(("cutoff_hz", "fs_hz"), [(10.0, 100.0), (10.0, 50.0), (0.1, 100.0)])
def test_the_butterworth_response_is_maximally_flat_with_half_power_at_the_cutoff(
    order: int, cutoff_hz: float, fs_hz: float
):
    """|H(f)|^2 = 1 / (1 + (tan(pi f / fs) / tan(pi fc / fs))^(2N)): the bilinear
    transform's Butterworth, 1 at DC, 1/2 at the cut-off, 0 at Nyquist."""
    sos = butter_lowpass_sos(order, cutoff_hz, fs_hz)
    assert sos.shape == (order // 2, 6)
    f = np.linspace(0.0, 0.49 * fs_hz, 200)
    ratio = np.tan(np.pi * f / fs_hz) / np.tan(np.pi * cutoff_hz / fs_hz)
    expected = 1.0 / np.sqrt(1.0 + ratio ** (2 * order))
    np.testing.assert_allclose(_response(sos, f, fs_hz), expected, atol=1e-9)
    assert _response(sos, np.array([cutoff_hz]), fs_hz)[0] == pytest.approx(2**-0.5, rel=1e-9)


@pytest.mark.parametrize("order", [2, 4, 6, 12])
@pytest.mark.parametrize(
    ("cutoff_hz", "fs_hz"),
    [(10.0, 100.0), (10.0, 50.0), (3.0, 10.0), (0.1, 100.0), (24.0, 50.0), (0.01, 100.0)],
)
def test_the_sections_and_their_initial_state_are_scipys(order, cutoff_hz, fs_hz):
    """To the bit, in the same section order: the pipeline's low-pass is what it was with
    scipy.signal's design (the initial state's 2 x 2 solve is ill-conditioned where the
    poles crowd z = 1, so an ulp in a coefficient would show there as ~1e-9)."""
    theirs = signal.butter(order, cutoff_hz, btype="low", fs=fs_hz, output="sos")
    ours = butter_lowpass_sos(order, cutoff_hz, fs_hz)
    np.testing.assert_array_equal(ours, theirs)
    np.testing.assert_array_equal(sosfilt_zi(ours), signal.sosfilt_zi(theirs))


def test_a_step_through_the_sections_from_their_initial_state_stays_at_its_level():
    sos = butter_lowpass_sos(4, 10.0, 100.0)
    zi = sosfilt_zi(sos)
    level = 5.0e6
    y, _ = signal.sosfilt(sos, np.full(50, level), zi=zi * level)
    np.testing.assert_allclose(y, level, rtol=1e-12)


@pytest.mark.parametrize("order", [1, 3, 0])
def test_an_odd_or_zero_order_is_refused(order: int):
    with pytest.raises(ValueError, match="even Butterworth order"):
        butter_lowpass_sos(order, 10.0, 100.0)


def test_a_cutoff_beyond_nyquist_is_refused():
    with pytest.raises(ValueError, match="half the sample rate"):
        butter_lowpass_sos(4, 50.0, 100.0)


@pytest.mark.parametrize(
    ("window", "polyorder"),
    [(w, k) for w in (3, 5, 11, 21, 51, 101, 201) for k in (1, 2, 3) if k < w],
)
@pytest.mark.parametrize("deriv", [0, 1, 2])
def test_savitzky_golay_is_scipys(window: int, polyorder: int, deriv: int):
    delta = 0.02
    np.testing.assert_allclose(
        savgol_coeffs(window, polyorder, deriv, delta),
        signal.savgol_coeffs(window, polyorder, deriv=deriv, delta=delta),
        rtol=1e-12, atol=1e-12 / delta**deriv,
    )  # fmt: skip
    y = np.cumsum(np.random.default_rng(window * 10 + polyorder).normal(size=300))
    theirs = signal.savgol_filter(y, window, polyorder, deriv=deriv, delta=delta, mode="interp")
    ours = savgol_filter(y, window, polyorder, deriv, delta)
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12 * np.max(np.abs(theirs)))


def test_a_polynomial_within_the_order_is_differentiated_exactly_up_to_the_ends():
    """Least squares of degree 3 reproduce a cubic: its derivative everywhere, the ends'
    fitted polynomials included (Savitzky and Golay 1964)."""
    t = np.arange(40) * 0.01
    y = 2.0 - 3.0 * t + 5.0 * t**2 - 7.0 * t**3
    np.testing.assert_allclose(
        savgol_filter(y, 9, 3, deriv=1, delta=0.01), -3.0 + 10.0 * t - 21.0 * t**2, atol=1e-9
    )
    np.testing.assert_allclose(savgol_filter(y, 9, 3, deriv=2, delta=0.01), 10.0 - 42.0 * t,
                               atol=1e-6)  # fmt: skip


def test_an_even_window_or_a_short_signal_is_refused():
    with pytest.raises(ValueError, match="odd number"):
        savgol_coeffs(4, 2)
    with pytest.raises(ValueError, match="at least the window"):
        savgol_filter(np.zeros(4), 5, 2)
