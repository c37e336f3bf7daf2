"""A 95 % band for each compensated rope tension and for the load (issue 13).

The compensated tension is T_i = p_chamber,i A + F_i (paper eq 2), with F_i the seal
friction that the friction model (paper eq 15-17) gives for the estimated piston motion
(:mod:`transforms.piston_motion`). Three things make it uncertain, and the band says by
how much instead of guessing:

1. **The friction state.** A piston's friction depends on its own motion since it last
   slid. Where the logged record showed the piston sliding (more than its presliding
   range F_s / sigma_0), the sign and level of its friction are known. Motion that only
   the oil saw (the elastic share of the common motion, or an equal split when no
   piston was seen moving) could have gone to any piston: its *blind* motion (path
   length b_i, back and forth) moves the bristles by up to b_i, so the friction may lie
   anywhere within +- sigma_0 b_i of the estimate, and never beyond the seal's static capacity
   +-F_s(p) (eq 17). Until a piston is first seen sliding, its friction state is
   unknown: the whole +-F_s. This part is a range, not a Gaussian: it is added whole.
   A hoist that rings at rest shakes its seals (the oil sees the oscillation, the
   logged x does not), so its friction range widens with the ringing, as it should:
   the seals may have relaxed.
2. **The friction law.** Calibrated on a rig (eq 17 lines), the law holds to a
   relative standard uncertainty: 1.96 x that x |F_i|. It is the hoist's stated one
   (``[friction] relative_uncertainty``, which ``ropeload calibrate`` writes from its
   lines' scatter, :func:`transforms.friction_lines.law_relative_sigma`; the example
   hoist's, paper Table 1's, 4.7 %), else 10 %; ``CompensationSettings
   .friction_relative_sigma`` overrides it
   (:meth:`transforms.compensation_record.CompensationSettings.friction_sigma`).
3. **The pressure sensor.** ``CompensationSettings.pressure_sigma_pa`` of white noise
   on the raw reading, reduced by the low-pass to sigma x sqrt(2 f_c / f_s): 1.96 x that x A.

Parts 2 and 3 are independent Gaussians (added in quadrature); part 1 is added to them.
For the load, the friction ranges of the four pistons add (the same blind motion may
have gone to any of them), and the Gaussian parts add in quadrature.

Where x is not logged, no piston is ever seen sliding: the band is the seals' whole
static range, the honest answer of a pressure-only record.

Where the ropes are identified (:mod:`transforms.stick_slip`), the forces decide which
piston slides: there is no blind motion. The friction's part of the band is then the
spread of the stick-slip solution over what the mine does not know well
(:func:`transforms.stick_slip_band.band_solutions`: the law's capacity +-1.96 x its
uncertainty, the bristle stiffness halved and doubled (with LuGre seals also their
drift's rate), the seals' unknown friction where the record starts (every seal as far
down or up as the ropes let it, forgotten as the pistons slide), and the ropes'
constants as identified on each quarter of the record, Student's t of their spread,
and with LuGre seals the ringing's drift travel halved and doubled), for each rope and,
member by member summed, for the load (:func:`ensemble_band`); the sensor's noise is
added as above. Each member is a 95 % extreme of one independent source (the law, the
bristles with the record's start, the ropes, the ringing): per source its members'
range either side of the estimate, the sources combined in quadrature (JCGM 100:2008,
the GUM, eq 10: independent inputs; their one-at-a-time extremes for c_i U_i). The
members move every seal alike: a sliding piston's friction by the capacity member's
+-1.96 x the law's uncertainty, which is part 2 whole, but a sticking piston's, set by
the ropes and its history, hardly at all, though its seal departs from the law as
much. So each rope's band, and the load's, add the law's part 2 (for the load, the
seals' in quadrature) less what the law's members already span, in quadrature
(:func:`ensemble_band`).
Session 15, validation days 101-104: coverage 95 / 87 / 84 / 73 % with it, 95 / 81 /
80 / 68 % without, at the same load half-width (the members span the load's part).
Session 32: until then the band took the widest single member either side, as if one
source at a time were off; on day 104 (a ringing hoist) the capacity members and the
ringing's each reached part of the way to the truth's friction and neither alone
covered it. Coverage 97 / 96 / 91 / 74 % -> 97 / 98 / 95 / 90 % at median load
half-widths 0.84 / 0.82 / 0.76 / 0.43 -> 0.92 / 0.89 / 0.84 / 0.55 % (the estimate
unchanged).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "Z95",
    "disagreeing_sensor_shifts",
    "ensemble_band",
    "load_band",
    "rope_band",
    "widen_for_shifts",
]

#: Two-sided 95 % coverage factor of a normal distribution.
Z95 = 1.959963984540054


def rope_band(
    tension_n: np.ndarray,
    friction_n: np.ndarray,
    p_chamber_pa: np.ndarray,
    blind_m: np.ndarray,
    *,
    static_law_n: tuple[float, float],
    bristle_stiffness_n_m: float,
    gaussian_sigma_n: tuple[float, float],
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """95 % band of one rope's tension (module docstring).

    Parameters
    ----------
    tension_n, friction_n, p_chamber_pa : ndarray
        The compensated tension, its seal friction and the chamber pressure per sample.
    blind_m : ndarray
        Path length of the piston's blind motion since it was last seen sliding [m]
        (inf: never).
    static_law_n : (float, float)
        F_s = a + b p [N, N/Pa] (eq 17's static line).
    bristle_stiffness_n_m : float
        sigma_0 [N/m].
    gaussian_sigma_n : (float, float)
        (relative friction sigma, pressure-noise sigma x A [N]).
    out : (ndarray, ndarray), optional
        Arrays for (lo, hi); ``hi`` may be ``blind_m`` itself (read before written).

    Returns
    -------
    (lo, hi) : ndarray
        The band's bounds [N].

    Examples
    --------
    A piston seen sliding (blind motion 0): only the law and the sensor, 1.96 x
    sqrt((0.1 x 1000)^2 + 20^2) = 199.9 N either side; one never seen: +- F_s more.

    >>> import numpy as np
    >>> lo, hi = rope_band(
    ...     np.array([30_000.0, 30_000.0]), np.array([1000.0, 1000.0]),
    ...     np.full(2, 3e6), np.array([0.0, np.inf]),
    ...     static_law_n=(1000.0, 2e-4), bristle_stiffness_n_m=3e7,
    ...     gaussian_sigma_n=(0.1, 20.0))
    >>> [round(float(v), 1) for v in hi - 30_000.0]
    [199.9, 799.9]
    >>> [round(float(v), 1) for v in 30_000.0 - lo]
    [199.9, 2799.9]
    """
    n = tension_n.shape[0]
    lo, hi = out if out is not None else (np.empty(n), np.empty(n))
    _rope_band_kernel(
        np.ascontiguousarray(tension_n, dtype=np.float64),
        np.ascontiguousarray(friction_n, dtype=np.float64),
        np.ascontiguousarray(p_chamber_pa, dtype=np.float64),
        np.ascontiguousarray(blind_m, dtype=np.float64),
        float(static_law_n[0]),
        float(static_law_n[1]),
        float(bristle_stiffness_n_m),
        float(gaussian_sigma_n[0]),
        float(gaussian_sigma_n[1]),
        lo,
        hi,
    )
    return lo, hi


@njit(cache=True, nogil=True)
def _rope_band_kernel(
    tension,
    friction,
    p_chamber,
    blind,
    static_a,
    static_b,
    sigma0,
    rel,
    p_noise,
    lo,
    hi,
):  # pragma: no cover - numba
    """Per sample: friction range [max(F - s0 b, -cap), min(F + s0 b, cap)] plus
    1.96 x the Gaussian part; cap = max(F_s(p), |F|) (kinetic friction with its viscous
    part can exceed F_s while sliding)."""
    for t in range(tension.shape[0]):
        f = friction[t]
        p = p_chamber[t]
        if not (np.isfinite(tension[t]) and np.isfinite(f) and np.isfinite(p)):
            lo[t] = np.nan
            hi[t] = np.nan
            continue
        capacity = max(max(static_a + static_b * p, 0.0), abs(f))
        reach = sigma0 * blind[t] if sigma0 > 0.0 else np.inf
        f_lo = max(f - reach, -capacity)
        f_hi = min(f + reach, capacity)
        sigma = np.sqrt((rel * f) ** 2 + p_noise**2)
        lo[t] = tension[t] - (f - f_lo) - Z95 * sigma
        hi[t] = tension[t] + (f_hi - f) + Z95 * sigma


def load_band(
    load_n: np.ndarray,
    rope_lo: list[np.ndarray],
    rope_hi: list[np.ndarray],
    rope_tension: list[np.ndarray],
    rope_friction: list[np.ndarray],
    *,
    gaussian_sigma_n: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """95 % band of the load: the ropes' friction ranges add, their Gaussian parts add
    in quadrature (module docstring). ``gaussian_sigma_n`` as for :func:`rope_band`
    (the Gaussian part of each rope is recomputed from its friction, not stored).

    Examples
    --------
    Two ropes with 1000 N of friction (10 % law uncertainty, no sensor noise) and 100 N
    of friction range below and above: 200 + 1.96 x 100 sqrt(2) = 477.2 N either side.

    >>> import numpy as np
    >>> t = [np.array([10_000.0]), np.array([10_000.0])]
    >>> f = [np.array([1000.0]), np.array([1000.0])]
    >>> half = 100.0 + 1.959963984540054 * 100.0
    >>> lo, hi = load_band(
    ...     np.array([20_000.0]), [x - half for x in t], [x + half for x in t], t, f,
    ...     gaussian_sigma_n=(0.1, 0.0))
    >>> round(float(hi[0] - 20_000.0), 1), round(float(20_000.0 - lo[0]), 1)
    (477.2, 477.2)
    """
    lo, hi = np.empty_like(load_n), np.empty_like(load_n)
    _load_band_kernel(
        np.ascontiguousarray(load_n, dtype=np.float64),
        tuple(rope_lo),
        tuple(rope_hi),
        tuple(rope_tension),
        tuple(rope_friction),
        float(gaussian_sigma_n[0]),
        float(gaussian_sigma_n[1]),
        lo,
        hi,
    )
    return lo, hi


@njit(cache=True, nogil=True)
def _load_band_kernel(
    load, rope_lo, rope_hi, tension, friction, rel, p_noise, lo, hi
):  # pragma: no cover - numba
    """Per sample: load -/+ (sum of the ropes' ranges + 1.96 sqrt(sum of sigma^2))."""
    for t in range(load.shape[0]):
        below = 0.0
        above = 0.0
        variance = 0.0
        for k in range(len(tension)):
            f = friction[k][t]
            sigma = np.sqrt((rel * f) ** 2 + p_noise**2)
            gaussian = Z95 * sigma
            below += tension[k][t] - rope_lo[k][t] - gaussian
            above += rope_hi[k][t] - tension[k][t] - gaussian
            variance += sigma * sigma
        spread = Z95 * np.sqrt(variance)
        lo[t] = load[t] - below - spread
        hi[t] = load[t] + above + spread


def ensemble_band(
    value_n: np.ndarray,
    friction_n: np.ndarray,
    members_n: list[np.ndarray],
    noise_sigma_n: float,
    *,
    seal_sigma_n: np.ndarray | None = None,
    groups: tuple[int, ...] | None = None,
    law_group: int = 0,
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """95 % band of a tension or load whose friction ``friction_n`` has the alternative
    solutions ``members_n``, each a 95 % extreme of one of independent sources
    (``groups``: each member's source, numbered from 0; None: one source): per source,
    the members' lowest and highest friction less the estimate's (its range either
    side, the estimate's own side 0), the sources' combined in quadrature either side
    (root-sum-square, as independent uncertainties combine: JCGM 100:2008 (GUM) eq 10,
    each source's one-at-a-time extreme for c_i U_i), added whole to the value; then
    -/+ 1.96 sqrt(``noise_sigma_n``^2 + s^2): the sensor, and per sample the part of
    the seals' own departure from the law (``seal_sigma_n``, sigma_seal) that the
    ``law_group`` source's range (the law's capacity members) does not span,
    s^2 = max(sigma_seal^2 - (range / 2 / 1.96)^2, 0) (module docstring). A NaN
    ``seal_sigma_n`` gives a NaN band.

    >>> import numpy as np
    >>> lo, hi = ensemble_band(np.array([10_000.0]), np.array([500.0]),
    ...                        [np.array([400.0]), np.array([800.0])], 10.0)
    >>> round(float(lo[0]), 1), round(float(hi[0]), 1)
    (9880.4, 10319.6)

    A seal's own sigma of 150 N, of which the members' range of 400 N spans 102 N: the
    rest, sqrt(150^2 - 102^2) = 110 N, with the sensor's 10 N, 1.96 x 110.4 N each side

    >>> lo, hi = ensemble_band(np.array([10_000.0]), np.array([500.0]),
    ...                        [np.array([400.0]), np.array([800.0])], 10.0,
    ...                        seal_sigma_n=np.array([150.0]))
    >>> round(float(lo[0]), 1), round(float(hi[0]), 1)
    (9683.6, 10516.4)

    Two sources, each 300 N down and 400 N up of the estimate: 424 N down and 566 N up
    together, not the 300 / 400 N of either alone (the sensor's 1.96 x 10 N beside)

    >>> lo, hi = ensemble_band(np.array([10_000.0]), np.array([500.0]),
    ...                        [np.array([200.0]), np.array([900.0])] * 2, 10.0,
    ...                        groups=(0, 0, 1, 1))
    >>> round(float(10_000.0 - lo[0] - 19.6), 1), round(float(hi[0] - 10_000.0 - 19.6), 1)
    (424.3, 565.7)
    """
    sources = tuple(groups) if groups is not None else (0,) * len(members_n)
    if len(sources) != len(members_n) or any(g < 0 for g in sources):
        raise ValueError(f"groups {groups}: one source (>= 0) per member of {len(members_n)}")
    if not 0 <= law_group <= max(sources, default=0):
        raise ValueError(f"law_group {law_group}: not one of the groups' sources {sources}")
    n = value_n.shape[0]
    lo, hi = out if out is not None else (np.empty(n), np.empty(n))
    seal = np.zeros(1) if seal_sigma_n is None else np.ascontiguousarray(seal_sigma_n, np.float64)
    if seal_sigma_n is not None and seal.shape != (n,):
        raise ValueError(f"seal_sigma_n has {seal.shape} samples, value_n {n}")
    _ensemble_band_kernel(
        np.ascontiguousarray(value_n, dtype=np.float64),
        np.ascontiguousarray(friction_n, dtype=np.float64),
        tuple(np.ascontiguousarray(m, dtype=np.float64) for m in members_n),
        np.asarray(sources, dtype=np.int64),
        max(sources, default=0) + 1,
        int(law_group),
        float(noise_sigma_n),
        seal_sigma_n is not None,
        seal,
        lo,
        hi,
    )
    return lo, hi


@njit(cache=True, nogil=True)
def _ensemble_band_kernel(
    value, friction, members, groups, sources, law_group, noise_sigma, with_seal, seal, lo, hi
):  # pragma: no cover - numba
    below = np.zeros(sources)  # each source's reach below and above the estimate
    above = np.zeros(sources)
    for t in range(value.shape[0]):
        f = friction[t]
        below[:] = 0.0
        above[:] = 0.0
        finite = np.isfinite(value[t]) and np.isfinite(f)
        for j, m in enumerate(members):
            d = m[t] - f
            if not np.isfinite(d):  # a member without a value there spans nothing
                continue
            g = groups[j]
            below[g] = max(below[g], -d)
            above[g] = max(above[g], d)
        if not finite:
            lo[t] = np.nan
            hi[t] = np.nan
            continue
        down = 0.0
        up = 0.0
        for g in range(sources):
            down += below[g] * below[g]
            up += above[g] * above[g]
        sigma = noise_sigma
        if with_seal:  # the seal's own sigma, less what the law's members already span
            spanned = (below[law_group] + above[law_group]) / (2.0 * Z95)
            own = max(seal[t] * seal[t] - spanned * spanned, 0.0)
            sigma = np.sqrt(noise_sigma * noise_sigma + own)
        noise = Z95 * sigma
        lo[t] = value[t] - np.sqrt(down) - noise
        hi[t] = value[t] + np.sqrt(up) + noise


def disagreeing_sensor_shifts(
    pressures: list[np.ndarray], off: list[np.ndarray], area_m2: float
) -> list[np.ndarray]:
    """Each rope's tension shift [N] were its sensor, where it departs from the others at
    rest (``off``: :func:`transforms.compensation_record.disagreeing_as_unknown`'s
    samples), reading the mean of those that do not: the pipes equalise the chambers at
    rest (contract 1a), so it is the sensor or the oil, and the record cannot say which
    (the ``sensor_disagreement`` alarm names it). The rope's tension keeps its reading;
    its band, and the load's, reach the other answer too (:func:`widen_for_shifts`).
    Where every known sensor is flagged (two apart, two against two), the mean of the
    other known ones; 0 where the sensor agrees, or no other is known.

    >>> p = [np.full(3, 4e6), np.full(3, 4e6), np.array([4e6, 4.4e6, 4e6])]
    >>> off = [np.zeros(3, bool), np.zeros(3, bool), np.array([False, True, False])]
    >>> [float(v) for v in disagreeing_sensor_shifts(p, off, 0.01)[2]]
    [0.0, -4000.0, 0.0]
    >>> both = [np.array([4e6]), np.array([4.4e6])]  # two known, both flagged
    >>> [float(v[0]) for v in disagreeing_sensor_shifts(both, [np.ones(1, bool)] * 2, 0.01)]
    [4000.0, -4000.0]
    """
    p = np.vstack(pressures)
    flagged = np.vstack(off)
    known = np.isfinite(p)
    good = ~flagged & known
    count = good.sum(axis=0)
    others = np.where(good, p, 0.0).sum(axis=0) / np.maximum(count, 1)
    shifts = []
    for k in range(p.shape[0]):
        # every known sensor flagged (two apart, or two against two): the other ones'
        rest = known & (np.arange(p.shape[0]) != k)[:, None]
        n_rest = rest.sum(axis=0)
        rest_mean = np.where(rest, p, 0.0).sum(axis=0) / np.maximum(n_rest, 1)
        other = np.where(count > 0, others, rest_mean)
        usable = flagged[k] & known[k] & ((count > 0) | (n_rest > 0))
        shifts.append(np.where(usable, (other - p[k]) * area_m2, 0.0))
    return shifts


def widen_for_shifts(
    value: np.ndarray, lo: np.ndarray, hi: np.ndarray, shift: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``lo``, ``hi`` reaching ``value + shift`` too (an alternative the record cannot rule
    out, e.g. :func:`disagreeing_sensor_shifts`); as they are where ``shift`` is 0.

    >>> lo, hi = widen_for_shifts(np.array([10.0, 10.0]), np.array([9.0, 9.0]),
    ...                           np.array([11.0, 11.0]), np.array([0.0, -3.0]))
    >>> lo.tolist(), hi.tolist()
    ([9.0, 7.0], [11.0, 11.0])
    """
    other = value + shift
    moved = shift != 0.0
    return np.where(moved, np.fmin(lo, other), lo), np.where(moved, np.fmax(hi, other), hi)
