"""White-noise standard deviation of a sampled signal from its differences.

For white noise of standard deviation s on a signal, the k-th difference of consecutive
samples has variance C(2k, k) s^2 (2 s^2 for the first difference x[i+1] - x[i], 6 s^2
for the second x[i+2] - 2 x[i+1] + x[i]), while a smooth signal contributes little: a
ramp only a constant to the first, a slope nothing and a steady acceleration a dt^2 to
the second. The median absolute deviation about the median, x :data:`MAD_TO_SIGMA`,
estimates a normal distribution's standard deviation and ignores the few differences a
step, a spike or a transient makes (the breakdown point is 50 %).

The noise estimates from differences are this one: the pressures' spikes and the logged
x and depth (:mod:`transforms.compensation_record`, :mod:`transforms.filtering`,
:func:`physics.conveyance.depth_noise_m`) and the discovery's pressure noise at
standstill (:func:`discovery.segmentation.estimate_noise_sigma`, which picks the
differences and falls back to their RMS for a coarse quantisation). Not: the friction
rig's settling test (:mod:`transforms.rig_friction`, the median of |differences|
without centring, which the rig's calibration was measured with) and the ringing's
robust RMS of a band-passed signal (:mod:`sims.logged_motion`).

References
----------
Rousseeuw, P. J., Croux, C. (1993), Alternatives to the median absolute deviation,
J. Am. Stat. Assoc. 88(424), 1273-1283 (the MAD's consistency factor 1.4826).
von Neumann, J., Kent, R. H., Bellinson, H. R., Hart, B. I. (1941), The mean square
successive difference, Ann. Math. Stat. 12(2), 153-162 (noise from differences).
"""

from __future__ import annotations

from math import comb

import numpy as np

__all__ = ["MAD_TO_SIGMA", "difference_noise_sigma", "mad"]

#: Median absolute deviation to standard deviation of a normal distribution,
#: 1 / Phi^-1(3/4).
MAD_TO_SIGMA = 1.4826


def mad(values: np.ndarray) -> float:
    """Median absolute deviation about the median of the finite ``values`` (NaN if none).

    >>> mad(np.array([1.0, 2.0, 3.0, 4.0, 100.0, np.nan]))
    1.0
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan")
    return float(np.median(np.abs(v - np.median(v))))


def difference_noise_sigma(differences: np.ndarray, order: int) -> float:
    """White-noise sigma from the ``order``-th differences of a signal (module docstring):
    :data:`MAD_TO_SIGMA` x MAD / sqrt(C(2 order, order)).

    Non-finite differences are ignored; 0 when none is left.

    Parameters
    ----------
    differences : numpy.ndarray
        The signal's differences of that order (any subset of them, e.g. every k-th).
    order : int
        1 (x[i+1] - x[i], variance 2 s^2) or 2 (x[i+2] - 2 x[i+1] + x[i], 6 s^2), ...

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = np.linspace(0.0, 50.0, 100_000) + rng.normal(0.0, 0.2, 100_000)
    >>> [round(difference_noise_sigma(np.diff(x, k), k), 2) for k in (1, 2)]
    [0.2, 0.2]
    >>> difference_noise_sigma(np.array([np.nan]), 1)
    0.0
    """
    if order < 1:
        raise ValueError(f"order {order}: differences are of order 1 or more")
    spread = mad(differences)
    if not np.isfinite(spread):
        return 0.0
    return float(MAD_TO_SIGMA * spread / np.sqrt(float(comb(2 * order, order))))
