r"""Each piston's motion from the closed oil volume and the logged displacements (issue 13).

Since session 12 the compensation's fallback: where the head ropes are identified from
the record, each piston's motion and friction come from its rope spring
(:mod:`transforms.stick_slip`, without a logged x on the ropes' prior spread); this
share-out runs when the logged x do not identify the ropes, or with
``CompensationSettings(rope_springs=False)``, or without a logged x with
``rope_stiffness_sigma=0``.

The seal friction of a piston depends on the history of *its own* motion (paper eq 15:
the bristle state follows the piston's increments), so the compensation needs each
piston's displacement, not just the four pistons' mean. Two observables carry it:

- the oil: the chambers, pipes and manifold are one closed volume V, so the *sum* of the
  four displacements follows the common pressure, A sum_i dx_i = V dp / beta_e(p)
  (NOTES.md; :func:`physics.closed_volume.common_mode_displacement` gives the per-piston
  mean). With 5 kPa of pressure noise that is a micrometre-class sensor of the sum,
  fast;
- the logged x_i: each piston's own position, but to a 0.1 mm step with ~0.02 mm of
  noise, so only its slow, millimetre-scale part is usable (Gaussian-smoothed, then a
  play operator of three noise sigmas, as
  :func:`transforms.compensation_kernels.differential_smooth` computes it).

How the sum is shared out is the crux. A real hoist's pistons stick and slip: at a
payload change at rest one piston usually slides millimetres while the others stick
(micrometres of presliding), and on a trip the piston with the least friction margin
slides while the rest hold. Splitting the fast sum equally and correcting the split
later with the slow logged difference (the first wave's estimate) makes the sticking
pistons go one way and come back: their friction changes sign, the error of a stop
after a payload change grows from ~6 % to ~8 % (issue 13). A Gaussian smoother or a
Kalman/RTS smoother with random-walk pistons does the same: their minimum-energy
allocation spreads the correction over time, which is a reversal for a piston that
never moved. Stick-slip motion is *sparse* per piston.

So the fast increments of the sum go to the pistons the logged record shows moving
*at that time*, in proportion to how fast they move (sliding weights), and the logged
motion that the sum does not explain (pistons exchanging oil through the manifold while
the sum stays put) is kept as it is:

.. math::
    u_{i,t} = \Delta D_{i,t} + w_{i,t} \bigl(\Delta S_t - \sum_j \Delta D_{j,t}\bigr),
    \qquad w_{i,t} = \frac{|\Delta D_{i,t}| + \epsilon}{\sum_j (|\Delta D_{j,t}| + \epsilon)}

with D_i the smoothed, played logged position, S the pressure-derived sum and epsilon a
floor that makes the split equal when nothing is seen moving (all pistons stuck: each
takes a quarter of the presliding, as elastic bristles of equal stiffness do). By
construction sum_i u_i = Delta S exactly (the oil is conserved), a piston whose
smoothed record does not move gets no share of the sum (no reversal), and where the
logged motion and the sum agree the estimate is the logged motion itself. Without a
logged x every piston takes a quarter of the sum, as before.

What it cannot do: tell which piston slid when the motion is below the play band
(a tenth of a millimetre): the compensation's uncertainty band covers that case
(:mod:`transforms.uncertainty`). It does not use the rope springs (that is
:mod:`transforms.stick_slip`, on constants identified from the record), nor the
sensor-to-sensor pressure differences while oil flows.

Measured (``benchmarks/eval_compensation.py``, stop windows of the independent
validation days, load error |after| worst / median; the first wave's in brackets):
days 101-103 2.2 / 0.23, 2.1 / 0.27, 2.5 / 0.29 % (8.4 / 0.51, 8.0 / 0.48,
3.3 / 0.24 %); day 104, whose ropes ring and whose seals the ringing relaxes, 5.3 /
1.5 % (2.4 / 0.81 %): the estimate keeps the friction a slide left, the ringing world
lost about half of it. Tried and dropped: sharing the oil's motion by each seal's room
to its static capacity (elastic-plastic, one common demand) without the rope springs:
1.6-1.8 % median, the wrong piston saturates first.

Without a logged x (``eval_compensation.py --without-x``, session 33; since session 37
the stick-slip solution on the ropes' prior spread runs there instead), the quarter
shares on the validation days 101-104: worst 2.93 / 2.93 / 3.38 / 2.66 %, median 1.40 /
1.45 / 1.40 / 0.48 % (raw 2.75 / 2.69 / 2.85 / 0.74 %), 23 / 24 / 23 / 24 windows worse
than raw by > 0.2 points, the band (+-5.5-6.0 %) holding every window; on ropeload's own
simulation, whose pistons move alike, worst 0.43-1.42 %, median 0.08-0.21 %, one window
worse. LuGre seals drift there along the ringing at rest that the shared-out x's
deadband hides (:meth:`transforms.compensation_block.BlockCompensation.ringing_drift`;
day 104 was 5.86 / 2.85 %, 110 windows, without it; own LuGre sims 0.98 -> 1.07 /
1.26 % worst, median 0.15 / 0.12 -> 0.08 / 0.10 %). The stick-slip solution on the
description's nominal ropes instead (tried before the drift, not kept: its band has no
rope members) gave medians of 1.00-1.06 % and 0.33 % on day 104, worst still
2.8-3.2 %, 14-26 windows worse than raw.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["share_out_common_motion", "share_state"]


def share_out_common_motion(
    common_m: np.ndarray,
    logged: tuple[np.ndarray, ...],
    segment_id: np.ndarray,
    *,
    elastic_half_width_m: float = 0.0,
    seen_reset_m: float = np.inf,
    blind_deadband_m: float = 2e-6,
    floor_m: float = 1e-9,
    overwrite_logged: bool = False,
    state: np.ndarray | None = None,
) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    """Per-piston displacement estimates [m] from the common mode and the logged motion.

    Longer than 80 lines on purpose: most of it is this docstring (every parameter and
    the result documented); the code is 31 lines.

    Parameters
    ----------
    common_m : ndarray
        Mean piston displacement from the closed oil volume [m] (per sample, restarting
        at segment starts; :func:`physics.closed_volume.common_mode_displacement`).
    logged : tuple of ndarray
        Smoothed and played logged displacement of each piston [m] (NaN where unknown).
    segment_id : ndarray of int
        Gap-free segment of each sample; the estimates restart at the logged value.
    elastic_half_width_m : float
        Half-width h of the play operator on the sum [m]: motion of the sum within
        +-h of its last turning point is elastic (presliding of every seal, shared
        equally); only motion beyond it is shared out by the sliding weights. The
        presliding range of n seals, n F_s / sigma_0 (the hoist's bristle stiffness).
    seen_reset_m : float
        A piston whose motion *seen* in the logged record (since the last reset) exceeds
        this [m] has slid through its presliding range: its friction state is known
        (up to the law's own uncertainty) and its blind motion restarts at 0. The
        presliding range F_s / sigma_0.
    blind_deadband_m : float
        Half-width of a play operator on each piston's blind motion before its path
        length is summed [m]: the pressure noise's nanometres do not add up, a ringing
        hoist's tens of micrometres of oscillation do (they shake the seals).
    floor_m : float
        epsilon of the sliding weights [m per sample]: below it a piston counts as not
        seen moving.
    overwrite_logged : bool
        Write the displacements over the ``logged`` arrays (contiguous float64): no new
        day-long arrays, whose page faults cost more than the arithmetic.
    state : ndarray, optional
        The estimator's state carried from the previous block of the same record
        (:func:`share_state`; updated in place), so that blocks give the result of the
        whole record (issue 16). Default: a fresh start.

    Returns
    -------
    (displacements, blind) : tuple of tuple of ndarray
        One displacement per piston [m], their increments summing to n x the common
        mode's; and per piston the path length of its *blind* motion [m] since it was
        last seen sliding (back and forth both count): the part that came from the oil
        alone (the elastic share, or an equal split when no piston was seen moving),
        which the logged record could not attribute. It is infinite until the piston
        is first seen sliding (the friction state at the start of a record is
        unknown). The uncertainty band (:mod:`transforms.uncertainty`) turns it into a
        friction range.

    Examples
    --------
    A payload change at rest that one piston of four takes alone: the sum of the
    increments (4 x 0.5 mm) goes to piston 1, the others stay put.

    >>> import numpy as np
    >>> common = np.array([0.0, 0.0, 0.5e-3, 0.5e-3])
    >>> x1 = np.array([0.0, 1e-3, 2e-3, 2e-3])  # the smoothed record leads the step
    >>> still = np.zeros(4)
    >>> out, _ = share_out_common_motion(common, (x1, still, still, still), np.zeros(4, int))
    >>> [round(float(v) * 1e3, 3) for v in out[0]], [abs(round(float(v) * 1e3, 3)) for v in out[1]]
    ([0.0, 0.0, 2.0, 2.0], [0.0, 0.0, 0.0, 0.0])
    """
    n = common_m.shape[0]
    if overwrite_logged:
        out = tuple(logged)
    else:
        out = tuple(np.array(values, dtype=np.float64) for values in logged)
    blind = tuple(np.empty(n) for _ in out)
    if n:
        _share_kernel(
            np.ascontiguousarray(common_m, dtype=np.float64),
            np.ascontiguousarray(segment_id, dtype=np.int64),
            float(elastic_half_width_m),
            float(seen_reset_m),
            float(blind_deadband_m),
            float(floor_m),
            out,
            blind,
            share_state(len(out)) if state is None else state,
        )
    return out, blind


def share_state(pistons: int) -> np.ndarray:
    """Fresh state of the share-out for ``pistons`` pistons (see :func:`_share_kernel`)."""
    return np.zeros(4 + 6 * pistons)


@njit(cache=True, nogil=True, error_model="numpy")
def _share_kernel(
    common, segment, half_width, seen_reset, deadband, floor, out, blind, state
):  # pragma: no cover - numba
    """u_i = dD_i + w_i (dY - sum_j dD_j) + dE / m, w_i ∝ |dD_i| + floor (module docstring).

    ``out`` holds the logged displacements D_i on entry and the estimates on return
    (sample t is read before it is written). S = m x the common mode; Y = play(S,
    half_width) its sliding part, E = S - Y its elastic part. A NaN logged increment
    counts as 0 (the piston is not seen moving); each segment starts at the logged value
    (0 if unknown). ``blind``: path length of play(net blind motion, deadband) since the
    piston's seen motion last exceeded ``seen_reset`` (inf before). ``state`` = [ran,
    continues segment, slide, elastic, then per piston: last logged value, position,
    seen, unseen, played, path] (:func:`transforms.filtering.fresh_state`).
    One function over 80 lines on purpose: the per-sample, per-piston loop of a numba
    kernel whose running sums stay in registers; split into calls it passes them all.
    """
    m = len(out)
    n = common.shape[0]
    weights = np.empty(m)
    increments = np.empty(m)
    last_logged = np.empty(m)
    position = np.empty(m)
    seen = np.zeros(m)
    unseen = np.zeros(m)
    played = np.zeros(m)
    path = np.full(m, np.inf)
    slide = 0.0
    elastic = 0.0
    ran = state[0] != 0.0
    resume = ran and state[1] != 0.0
    if ran:
        slide, elastic = state[2], state[3]
        for i in range(m):
            last_logged[i] = state[4 + i]
            position[i] = state[4 + m + i]
            seen[i] = state[4 + 2 * m + i]
            unseen[i] = state[4 + 3 * m + i]
            played[i] = state[4 + 4 * m + i]
            path[i] = state[4 + 5 * m + i]
    for t in range(n):
        total = m * common[t]
        if (t == 0 and not resume) or (t > 0 and segment[t] != segment[t - 1]):
            slide = total if np.isfinite(total) else 0.0
            elastic = 0.0
            for i in range(m):
                value = out[i][t]
                last_logged[i] = value
                position[i] = value if np.isfinite(value) else 0.0
                out[i][t] = position[i]
                blind[i][t] = path[i]
            continue
        slide_before, elastic_before = slide, elastic
        if np.isfinite(total):
            if total > slide + half_width:
                slide = total - half_width
            elif total < slide - half_width:
                slide = total + half_width
            elastic = total - slide
        d_sum = slide - slide_before
        d_elastic = (elastic - elastic_before) / m
        logged_sum = 0.0
        weight_sum = 0.0
        for i in range(m):
            value = out[i][t]
            d = value - last_logged[i]
            last_logged[i] = value
            if not np.isfinite(d):
                d = 0.0
            increments[i] = d
            logged_sum += d
            weights[i] = abs(d) + floor
            weight_sum += weights[i]
        unexplained = (d_sum - logged_sum) / weight_sum
        informed = weight_sum > m * floor * (1.0 + 1e-9)  # some piston seen moving
        for i in range(m):
            shared = weights[i] * unexplained
            position[i] += increments[i] + shared + d_elastic
            out[i][t] = position[i]
            if informed:
                seen[i] += increments[i] + shared
                unseen[i] += d_elastic
            else:
                seen[i] += increments[i]
                unseen[i] += d_elastic + shared
            if unseen[i] > played[i] + deadband:
                path[i] += unseen[i] - deadband - played[i]
                played[i] = unseen[i] - deadband
            elif unseen[i] < played[i] - deadband:
                path[i] += played[i] - deadband - unseen[i]
                played[i] = unseen[i] + deadband
            if abs(seen[i]) > seen_reset:
                seen[i] = 0.0
                unseen[i] = 0.0
                played[i] = 0.0
                path[i] = 0.0
            blind[i][t] = path[i]
    if n:
        state[0] = 1.0
        state[2], state[3] = slide, elastic
        for i in range(m):
            state[4 + i] = last_logged[i]
            state[4 + m + i] = position[i]
            state[4 + 2 * m + i] = seen[i]
            state[4 + 3 * m + i] = unseen[i]
            state[4 + 4 * m + i] = played[i]
            state[4 + 5 * m + i] = path[i]
