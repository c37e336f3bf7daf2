"""The two digital filters the pipeline designs, in numpy: Savitzky-Golay and Butterworth.

Not an equation of the paper; the coefficients :func:`physics.conveyance.smoothed_derivative`
(a Savitzky-Golay derivative) and :func:`transforms.lowpass.lowpass` (a zero-phase
Butterworth low-pass) filter with, computed as ``scipy.signal`` computes them, so that a
run does not import ``scipy.signal``: its package brings ``scipy.stats`` and took ~1 s of
every ``ropeload run`` start on these machines (``python -X importtime``), against
milliseconds for the arithmetic below. ``tests/physics/test_filter_design.py`` holds them
to ``scipy.signal``'s results.

Functions
    :func:`savgol_coeffs` -- the convolution coefficients of a centred Savitzky-Golay
    filter (``scipy.signal.savgol_coeffs``).
    :func:`savgol_filter` -- that filter with polynomial-fitted edges
    (``scipy.signal.savgol_filter(..., mode="interp")``).
    :func:`butter_lowpass_sos` -- a digital Butterworth low-pass of even order as
    second-order sections (``scipy.signal.butter(..., btype="low", fs=..., output="sos")``).
    :func:`sosfilt_zi` -- the sections' steady-state initial conditions for a unit step
    (``scipy.signal.sosfilt_zi``).

References
----------
Savitzky, A., Golay, M. J. E. (1964), Smoothing and differentiation of data by
simplified least squares procedures, Anal. Chem. 36(8), 1627-1639,
doi:10.1021/ac60214a047.
Oppenheim, A. V., Schafer, R. W. (2010), Discrete-Time Signal Processing, 3rd ed.,
section 7.2 (the bilinear transform with pre-warped cut-off) and 6.3 (cascades of
second-order sections).
"""

from __future__ import annotations

from math import factorial

import numpy as np

__all__ = ["butter_lowpass_sos", "savgol_coeffs", "savgol_filter", "sosfilt_zi"]


def savgol_coeffs(window: int, polyorder: int, deriv: int = 0, delta: float = 1.0) -> np.ndarray:
    """Convolution coefficients of a centred Savitzky-Golay filter of an odd ``window``.

    The least-squares polynomial of degree ``polyorder`` through ``window`` samples,
    its ``deriv``-th derivative at the centre sample, as a linear combination of the
    samples: ``c = pinv(A)[deriv] deriv! / delta**deriv`` with ``A[k, j] = x_j**k`` and
    ``x`` the offsets ``h, ..., -h`` (convolution order: ``numpy.convolve(y, c)`` gives
    the filter).

    >>> bool(np.allclose(savgol_coeffs(5, 2), [-3, 12, 17, 12, -3] / np.float64(35)))
    True
    >>> bool(np.allclose(savgol_coeffs(5, 2, deriv=1), [0.2, 0.1, 0.0, -0.1, -0.2]))
    True
    """
    if window % 2 == 0 or window < 1:
        raise ValueError(f"window {window}: a positive odd number of samples")
    if not 0 <= polyorder < window:
        raise ValueError(f"polyorder {polyorder}: from 0 to window - 1 ({window - 1})")
    if deriv > polyorder:
        return np.zeros(window)
    half = window // 2
    x = np.arange(half, -half - 1, -1, dtype=np.float64)
    design = x ** np.arange(polyorder + 1, dtype=np.float64).reshape(-1, 1)
    target = np.zeros(polyorder + 1)
    target[deriv] = factorial(deriv) / delta**deriv
    rcond = np.finfo(np.float64).eps * max(design.shape)
    return np.linalg.lstsq(design, target, rcond=rcond)[0]


def savgol_filter(
    y: np.ndarray, window: int, polyorder: int, deriv: int = 0, delta: float = 1.0
) -> np.ndarray:
    """Savitzky-Golay filter of ``y`` (1-D, at least ``window`` samples): the centred
    filter of :func:`savgol_coeffs` where the window fits, and at each end the
    ``deriv``-th derivative of the polynomial fitted to the first / last ``window``
    samples (scipy's ``mode="interp"``).

    >>> t = np.arange(20) * 0.1
    >>> bool(np.allclose(savgol_filter(t**2, 7, 2, deriv=1, delta=0.1), 2 * t))
    True
    """
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1 or y.size < window:
        raise ValueError(f"{y.size} samples: a 1-D signal of at least the window ({window})")
    out = np.convolve(y, savgol_coeffs(window, polyorder, deriv, delta), mode="same")
    half = window // 2
    positions = np.arange(window, dtype=np.float64)
    for lo, at in ((0, slice(0, half)), (y.size - window, slice(window - half, window))):
        poly = np.polyder(np.polyfit(positions, y[lo : lo + window], polyorder), deriv)
        values = np.polyval(poly, positions[at]) / delta**deriv
        out[lo + at.start : lo + at.stop] = values
    return out


def butter_lowpass_sos(order: int, cutoff_hz: float, sample_rate_hz: float) -> np.ndarray:
    """Digital Butterworth low-pass of an even ``order`` as ``order / 2`` second-order
    sections, rows ``[b0, b1, b2, 1, a1, a2]``.

    The analog prototype's poles ``-exp(i pi (2k - order + 1) / (2 order))`` are scaled
    to the pre-warped cut-off ``4 tan(pi fc / fs)`` (in units of fs / 2) and mapped by
    the bilinear transform; its ``order`` zeros lie at z = -1. Each conjugate pair of
    poles makes a section with two of the zeros, the pairs nearest the unit circle last;
    the gain, which sets the response to 1 at DC, multiplies the first section (scipy's
    ``zpk2sos`` arrangement). An odd order's real pole would be paired by scipy with one
    zero or two depending on the cut-off; the pipeline filters with order 4, so odd
    orders are refused rather than arranged differently.

    >>> sos = butter_lowpass_sos(4, 10.0, 100.0)
    >>> from numpy.polynomial import polynomial as P
    >>> w = np.exp(1j * np.pi * np.array([0.0, 0.2]))  # DC and the 10 Hz cut-off
    >>> h = np.prod([P.polyval(1 / w, s[:3]) / P.polyval(1 / w, s[3:]) for s in sos], axis=0)
    >>> [round(float(v), 6) for v in np.abs(h)]
    [1.0, 0.707107]
    """
    if order < 2 or order % 2:
        raise ValueError(f"order {order}: an even Butterworth order (2, 4, 6, ...)")
    if not 0.0 < cutoff_hz < sample_rate_hz / 2.0:
        raise ValueError(
            f"cut-off {cutoff_hz} Hz: between 0 and half the sample rate ({sample_rate_hz} Hz)"
        )
    # scipy.signal.buttap, iirfilter's pre-warping (fs = 2 after normalising), lp2lp_zpk
    # and bilinear_zpk, in that order of operations
    analog = -np.exp(1j * np.pi * np.arange(-order + 1, order, 2) / (2 * order))
    warped = 2.0 * 2.0 * np.tan(np.pi * (2.0 * cutoff_hz / sample_rate_hz) / 2.0)
    analog = warped * analog
    fs2 = 2.0 * 2.0
    poles = (fs2 + analog) / (fs2 - analog)
    gain = warped**order * np.real(1.0 / np.prod(fs2 - analog))
    upper = poles[poles.imag > 0.0]
    upper = upper[np.argsort(-np.abs(1.0 - np.abs(upper)), kind="stable")]
    # a2 as numpy.poly multiplies the pair out (p p*, not |p|^2): scipy's to the bit
    sos = np.array([[1.0, 2.0, 1.0, 1.0, -2.0 * p.real, (p * p.conjugate()).real] for p in upper])
    sos[0, :3] *= gain
    return sos


def sosfilt_zi(sos: np.ndarray) -> np.ndarray:
    """Initial conditions of each section (transposed direct form II) at which a unit
    step input is at its steady state: section s's ``lfilter_zi`` scaled by the DC gain
    of the sections before it. Shape ``(n_sections, 2)``.

    >>> sos = butter_lowpass_sos(2, 10.0, 100.0)
    >>> zi = sosfilt_zi(sos)  # the first output of a unit step is then 1
    >>> b, a = sos[0, :3], sos[0, 3:]
    >>> round(float(b[0] * 1.0 + zi[0, 0]), 12)
    1.0
    """
    sos = np.asarray(sos, dtype=np.float64)
    zi = np.empty((sos.shape[0], 2))
    scale = 1.0
    for k, section in enumerate(sos):
        b, a = section[:3] / section[3], section[3:] / section[3]
        # scipy.signal.lfilter_zi: (I - companion(a).T) zi = b[1:] - a[1:] b[0]
        system = np.array([[1.0 + a[1], -1.0], [a[2], 1.0]])
        zi[k] = scale * np.linalg.solve(system, b[1:] - a[1:] * b[0])
        scale *= b.sum() / a.sum()
    return zi
