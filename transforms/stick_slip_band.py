"""The identified ropes and the stick-slip estimate's band: which solutions, how far.

:func:`transforms.stick_slip.stick_slip` gives each piston's friction from the ropes'
constants (:class:`RopeSprings`, identified per record by
:mod:`transforms.rope_identification`) and the seals' law. Its 95 % band
(:mod:`transforms.uncertainty`) is the spread of the same solution over members that each
stand for one independent source of uncertainty (:data:`BAND_SOURCES`): the law's
capacity and the bristles' stiffness (:func:`band_members`, the bristles' members also
starting the record with the seals at their extremes, :data:`START_MEMBERS`), the ropes
as identified on parts of the record (:meth:`RopeSprings.member`, :func:`parts_reach`:
Student's t over the parts) and, where the seals drift, the ringing's travel
(:data:`RINGING_MEMBERS`). :func:`band_solutions` lists them, the estimate first.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = [
    "BAND_SOURCES",
    "MAX_ALTERNATIVES",
    "MAX_SOLUTIONS",
    "MEMBER_STIFFNESS_LIMITS",
    "PRIOR_ROPES",
    "RINGING_MEMBERS",
    "START_MEMBERS",
    "BandSolution",
    "RopeSprings",
    "band_groups",
    "band_members",
    "band_solutions",
    "parts_reach",
    "prior_rope_springs",
    "prior_sigma_points",
]

#: The most alternatives of the ropes a :class:`RopeSprings` carries (one per part of
#: the record the identification repeats on, :data:`transforms.rope_identification.SPLITS`).
MAX_ALTERNATIVES = 4
#: Factors on the ringing's drift travel of the band's ringing members
#: (:func:`band_solutions`; ``drift_ringing_pa`` of
#: :func:`~transforms.stick_slip.stick_slip`): halved and
#: doubled, as the bristle stiffness's (:func:`band_members`).
RINGING_MEMBERS = (0.5, 2.0)
#: The independent sources of uncertainty the band's members stand for
#: (:func:`band_solutions`), in the order of :func:`transforms.uncertainty.ensemble_band`'s
#: groups: the law's capacity first (the seals' own departure from the law);
#: ``stiffness``: the ropes' stiffness spread where no record identified them
#: (:func:`prior_rope_springs`; each of its directions a source of its own,
#: :func:`band_groups`).
BAND_SOURCES = ("law", "bristles", "ropes", "ringing", "stiffness")
#: The head ropes whose prior sigma points :data:`MAX_SOLUTIONS` makes room for: the
#: compensation's four (:data:`transforms.compensation_record.ROPES`).
PRIOR_ROPES = 4
#: The most solutions :func:`band_solutions` gives: the estimate, the four of
#: :func:`band_members`, one per alternative of the ropes (identified, or the prior's
#: 2 (n - 1) sigma points) and the ringing's two.
MAX_SOLUTIONS = 5 + max(MAX_ALTERNATIVES, 2 * (PRIOR_ROPES - 1)) + len(RINGING_MEMBERS)
#: ``start_at_capacity`` of the members of :func:`band_members`, in its order: the softer
#: bristles start the record with the seals down, the stiffer with them up (both of the
#: law's capacity: the extremes +-F_s; the capacity members keep their own role).
START_MEMBERS = (0.0, 0.0, -1.0, 1.0)
#: A member's rope stiffness factors are kept within these (the identification searches
#: 0.9-1.1; a part's deviation taken t x as far could otherwise reach a slack rope).
MEMBER_STIFFNESS_LIMITS = (0.5, 1.5)


class BandSolution(NamedTuple):
    """One solution of :func:`band_solutions`: :func:`~transforms.stick_slip.stick_slip`'s
    ``capacity_scale``, ``sigma0_scale``, ropes and ``start_at_capacity``, the factor on
    its ``drift_ringing_pa``, and the source of uncertainty it stands for (one of
    :data:`BAND_SOURCES`; the estimate's ``"estimate"``)."""

    capacity_scale: float
    sigma0_scale: float
    ropes: RopeSprings
    start_at_capacity: float
    ringing_scale: float
    source: str


def band_solutions(
    springs: RopeSprings, friction_relative_sigma: float, *, ringing: bool = False
) -> list[BandSolution]:
    """The estimate (first) and each member of the 95 % band: the friction law's members
    (:func:`band_members`) on the identified ropes, the softer and the stiffer bristles
    also starting the record with every seal as far down or up as the ropes let it
    (``start_at_capacity`` of :func:`~transforms.stick_slip.stick_slip`,
    :data:`START_MEMBERS`: nothing tells
    the seals' friction where a record starts), then the estimate's law on each
    alternative of the ropes (the constants identified on part of the record, taken
    :func:`parts_reach` x as far; one part alone also mirrored, both sides of the whole).
    With LuGre seals the bristle stiffness also sets how fast they drift
    (:func:`~transforms.stick_slip.stick_slip`), so its members span the drift too.

    ``ringing`` (the seals drift, so the ringing the drift's play hides counts,
    :func:`transforms.seal_drift.ringing_travel`): last, the estimate with that travel
    halved and doubled (:data:`RINGING_MEMBERS`). It is inferred, not measured: counted
    only where the ringing stands above the noise (a decaying ringing's tail below it
    is not), and taken as the oil's common motion shared by the pistons' compliance,
    where each piston's own path in a bounce can be longer. On validation day 104 (a
    ringing hoist) the estimate's seals kept ~1.6 x the friction the truth's kept at
    the pithead's stops (the travel doubled in the estimate: worst stop window 0.96 ->
    0.71 %, coverage 90 %; a diagnosis, not a setting: the members' factors are the
    bristles' halving and doubling). Members: coverage 74 -> 77 %, with the sources
    in quadrature 90 % (:func:`transforms.uncertainty.ensemble_band`).

    Ropes no record identified (:func:`prior_rope_springs`, ``prior_sigma`` > 0): the
    prior's sigma points instead, each as it is (source ``stiffness``); the compensation
    takes their solutions' mean for the estimate (:func:`prior_sigma_points`).

    One half of a record gave ropes (rope 2 0.01 stiffer than the whole's), the other
    none: the members reach t_1 = 12.7 x as far, on both sides.

    Each member is a 95 % extreme of one of the independent sources of
    :data:`BAND_SOURCES` (the bristles' stiffness and the record's start together);
    :func:`transforms.uncertainty.ensemble_band` combines the sources in quadrature.

    >>> springs = RopeSprings((1.0, 1.02), (0.0, 1e-3), 1e-4, 100,
    ...                       (((1.0, 1.03), (0.0, 2e-3)),), parts=2)
    >>> for c, s, r, start, ring, source in band_solutions(springs, 0.1, ringing=True)[-6:]:
    ...     print(c, s, round(r.stiffness_factors[1], 4), start, ring, source)
    1.0 0.5 1.02 -1.0 1.0 bristles
    1.0 2.0 1.02 1.0 1.0 bristles
    1.0 1.0 1.1471 0.0 1.0 ropes
    1.0 1.0 0.8929 0.0 1.0 ropes
    1.0 1.0 1.02 0.0 0.5 ringing
    1.0 1.0 1.02 0.0 2.0 ringing
    """
    most = 2 * (PRIOR_ROPES - 1) if springs.prior_sigma > 0 else MAX_ALTERNATIVES
    if len(springs.alternatives) > most:  # the carried state has no rows
        raise ValueError(f"{len(springs.alternatives)} alternatives of the ropes: at most "
                         f"{most} (MAX_ALTERNATIVES; a prior's: of PRIOR_ROPES)")  # fmt: skip
    solutions = [BandSolution(1.0, 1.0, springs, 0.0, 1.0, "estimate")]
    solutions += [
        BandSolution(c, s, springs, start, 1.0, "law" if s == 1.0 else "bristles")
        for (c, s), start in zip(band_members(friction_relative_sigma), START_MEMBERS, strict=True)
    ]
    alternatives = range(len(springs.alternatives))
    if springs.prior_sigma > 0:  # the prior's sigma points, as they are
        solutions += [
            BandSolution(1.0, 1.0, springs.member(k, 1.0), 0.0, 1.0, "stiffness")
            for k in alternatives
        ]
    elif springs.alternatives:
        reach = parts_reach(len(springs.alternatives), springs.splits)
        solutions += [
            BandSolution(1.0, 1.0, springs.member(k, reach), 0.0, 1.0, "ropes")
            for k in alternatives
        ]
        if len(springs.alternatives) == 1:  # its deviation's sign says nothing: both sides
            solutions.append(BandSolution(1.0, 1.0, springs.member(0, -reach), 0.0, 1.0, "ropes"))
    if ringing:
        solutions += [
            BandSolution(1.0, 1.0, springs, 0.0, factor, "ringing") for factor in RINGING_MEMBERS
        ]
    return solutions


def parts_reach(identified: int, splits: int = MAX_ALTERNATIVES) -> float:
    """How far the band's rope members go from the whole record's constants, as a
    multiple of each part's deviation (:meth:`RopeSprings.member`), when the
    identification ran on ``splits`` = K equal parts and J = ``identified`` of them gave
    ropes.

    A part's error has K x the variance of the whole's (a K-th of the data), and the
    whole is about the parts' mean: a part less the whole spreads (K - 1)^(1/2) x the
    whole's standard deviation sigma, which the J = K parts estimate with K - 1 degrees
    of freedom. A 95 % interval is Student's t_{K-1} x sigma (3.18 for four quarters,
    12.7 for two halves); the deviations sum to about zero, so the members lie on both
    sides of the whole, and the largest is at least their RMS: the reach is
    t_{K-1} / (K - 1)^(1/2). Where the parts disagree with the whole on one side (short
    parts biased), the members keep that bias in the band.
    Where only J < K parts gave ropes, their deviations from their own mean (both
    sides) estimate sigma with J - 1 degrees of freedom: the reach is
    t_{J-1} (J / (K (J - 1)))^(1/2). One part alone: its deviation from the whole at
    t_1 / (K - 1)^(1/2), on both sides of the whole (:func:`band_solutions`: the
    deviation is independent of the whole's error, so one side would hold the truth
    half the time), and wide: little data.

    >>> round(parts_reach(4), 3), round(parts_reach(3), 3), round(parts_reach(1), 2)
    (1.837, 2.635, 7.34)
    """
    # imported here, not with the module: scipy.special adds ~0.3 s to every start of a
    # run, which a record without identified ropes never uses
    from scipy.special import stdtrit

    if splits < 2:
        raise ValueError(f"splits {splits}: a spread needs at least two parts")
    if identified < 2:
        return float(stdtrit(1, 0.975) / np.sqrt(splits - 1))
    dof = identified - 1
    return float(stdtrit(dof, 0.975) * np.sqrt(identified / (splits * dof)))


def band_members(friction_relative_sigma: float) -> tuple[tuple[float, float], ...]:
    """(capacity, bristle stiffness) factors of the solutions whose spread is the
    friction's part of the 95 % band (:mod:`transforms.uncertainty`): the law's capacity
    +-1.96 x its relative standard uncertainty, and the bristle stiffness (a default the
    mine does not measure, F_s / 0.05 mm) halved and doubled.

    >>> band_members(0.1)
    ((0.804, 1.0), (1.196, 1.0), (1.0, 0.5), (1.0, 2.0))
    """
    reach = round(1.96 * friction_relative_sigma, 6)
    return ((1.0 - reach, 1.0), (1.0 + reach, 1.0), (1.0, 0.5), (1.0, 2.0))


@dataclass(frozen=True)
class RopeSprings:
    """Constants of the head ropes identified from a record
    (:func:`transforms.rope_identification.identify_rope_springs`).

    Attributes
    ----------
    stiffness_factors : tuple of float
        a_i, each rope's stiffness relative to the nominal EA (a_1 = 1: the gauge).
    length_offsets_m : tuple of float
        c_i, each rope's length offset [m] (c_1 = 0).
    mismatch_m : float
        RMS of the model's x minus the logged x over the identification samples [m];
        NaN: not identified from the record (the description's ropes or their prior,
        :func:`prior_rope_springs`), whose logged x the solution does not start from.
    samples : int
        Samples the identification used.
    alternatives : tuple of (a, c)
        The constants identified on each of the parts of those samples
        (:data:`transforms.rope_identification.SPLITS`): how far the record's data pin
        the ropes down. Their solutions are members of the uncertainty band
        (:func:`band_solutions`).
    parts : int
        How many parts the identification ran on (those that gave no ropes have no
        alternative); 0: as many as :attr:`alternatives`.
    prior_sigma : float
        0: identified. > 0: no record identified these ropes (no logged x): the
        constants are the description's and :attr:`alternatives` the sigma points of a
        relative stiffness spread of this standard deviation about them
        (:func:`prior_rope_springs`).
    """

    stiffness_factors: tuple[float, ...]
    length_offsets_m: tuple[float, ...]
    mismatch_m: float
    samples: int
    alternatives: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...] = ()
    parts: int = 0
    prior_sigma: float = 0.0

    def __post_init__(self) -> None:
        if self.parts and len(self.alternatives) > self.parts:
            raise ValueError(f"{len(self.alternatives)} alternatives of {self.parts} parts")
        if self.alternatives and self.splits < 2:
            raise ValueError("alternatives need the identification on two parts at least")

    @property
    def splits(self) -> int:
        """How many parts the identification ran on (:attr:`parts`, else as many as
        :attr:`alternatives`)."""
        return self.parts or len(self.alternatives)

    def member(self, k: int, reach: float) -> RopeSprings:
        """Ropes of their own at these constants plus ``reach`` times the k-th of
        :attr:`alternatives` less these constants, or less the alternatives' mean where
        fewer than :attr:`splits` but more than one part gave ropes
        (:func:`parts_reach`), the stiffness factors within
        :data:`MEMBER_STIFFNESS_LIMITS`: a member of the band (:func:`band_solutions`).

        >>> RopeSprings((1.0, 1.02), (0.0, 1e-3), 0.0, 0,
        ...             (((1.0, 1.03), (0.0, 2e-3)), ((1.0, 1.01), (0.0, 0.0)))
        ...             ).member(0, 2.0).length_offsets_m
        (0.0, 0.003)
        """
        here = np.r_[self.stiffness_factors, self.length_offsets_m]
        parts = np.array([np.r_[a, c] for a, c in self.alternatives])
        center = parts.mean(axis=0) if 1 < len(parts) < self.splits else here
        values = here + reach * (parts[k] - center)
        n = len(self.stiffness_factors)
        values[:n] = np.clip(values[:n], *MEMBER_STIFFNESS_LIMITS)
        return RopeSprings(
            tuple(float(v) for v in values[:n]),
            tuple(float(v) for v in values[n:]),
            self.mismatch_m,
            self.samples,
        )


def prior_sigma_points(ropes: int, sigma: float) -> np.ndarray:
    r"""Stiffness deviations of the unscented transform's sigma points for ``ropes`` head
    ropes whose stiffnesses scatter independently by the relative standard deviation
    ``sigma`` about the description's, (2 (n - 1), n).

    Only the ropes' differences move the pistons apart (a common factor is the
    description's EA), so the points span the n - 1 directions of zero sum: an
    orthonormal basis :math:`v_j` of that subspace (the normalised Hadamard contrasts
    where n is a power of two, every rope moved alike, else Helmert's), each point
    :math:`\pm\sqrt{n-1}\,\sigma\, v_j` with weight 1 / (2 (n - 1)) (Julier and
    Uhlmann 1997, kappa = 0): their mean is 0 and their covariance
    :math:`\sigma^2 (I - 11^T / n)`, the independent scatter's less its common part;
    a smooth function's mean over them is its expectation to second order.

    >>> points = prior_sigma_points(4, 0.05)
    >>> points.shape, float(abs(points).max().round(5))
    ((6, 4), 0.0433)
    >>> np.allclose(points.T @ points / 6, 0.05**2 * (np.eye(4) - 1 / 4))
    True
    """
    if ropes < 2 or not 0.0 < sigma < np.inf:
        raise ValueError(
            f"prior sigma points of {ropes} ropes at {sigma}: two ropes and a sigma > 0"
        )
    if ropes & (ropes - 1) == 0:  # Sylvester's Hadamard matrix, its first row dropped
        basis = np.ones((1, 1))
        while basis.shape[0] < ropes:
            basis = np.block([[basis, basis], [basis, -basis]])
        directions = basis[1:] / np.sqrt(ropes)
    else:  # Helmert's contrasts
        directions = np.zeros((ropes - 1, ropes))
        for j in range(1, ropes):
            directions[j - 1, :j] = 1.0
            directions[j - 1, j] = -float(j)
            directions[j - 1] /= np.sqrt(j * (j + 1.0))
    step = np.sqrt(ropes - 1.0) * sigma * directions
    return np.stack([side * row for row in step for side in (1.0, -1.0)])


def prior_rope_springs(stiffness_factors: tuple[float, ...], sigma: float) -> RopeSprings:
    """Head ropes no record identified (no logged piston x): the description's stiffness
    factors (``stiffness_factors``: 1 each where it states none) with no length offsets
    (without a logged x the pistons start where equal tensions put them, and a rope's
    length offset only shifts its piston), and as :attr:`RopeSprings.alternatives` the
    sigma points (:func:`prior_sigma_points`) of a relative stiffness spread ``sigma``.

    Why: the pistons slide apart where the ropes' rates differ (a rope's stretch
    T / (a_i k) changes with the load and the hanging length, most at the pithead), and
    those that slide apart hold friction of opposite signs. Ropes taken alike move
    every piston alike and put every seal at the same friction: their sum is the most
    the seals can hold, about twice what independent simulators' and real seals keep
    (issue 13: with x left out, the validation days' pithead stops after a payload
    change were compensated to -2.7 % against a raw +2.4 %). The mean over the sigma
    points is the estimate, their spread a source of its band.

    >>> springs = prior_rope_springs((1.0,) * 4, 0.05)
    >>> springs.prior_sigma, len(springs.alternatives)
    (0.05, 6)
    >>> [round(a, 4) for a in springs.alternatives[0][0]]
    [1.0433, 0.9567, 1.0433, 0.9567]
    """
    base = np.asarray(stiffness_factors, dtype=float)
    points = base + prior_sigma_points(base.size, sigma) * base
    offsets = (0.0,) * base.size
    return RopeSprings(
        tuple(float(a) for a in base),
        offsets,
        float("nan"),
        0,
        tuple((tuple(round(float(a), 12) for a in row), offsets) for row in points),
        parts=len(points),
        prior_sigma=float(sigma),
    )


def band_groups(solutions: list[BandSolution]) -> tuple[int, ...]:
    """Each band member's source as :func:`transforms.uncertainty.ensemble_band`'s
    ``groups`` (``solutions`` as :func:`band_solutions` gives them, the estimate first
    and left out): its index in :data:`BAND_SOURCES`, but each pair of a prior's sigma
    points (one direction of the ropes' spread, :func:`prior_sigma_points`) a source of
    its own, numbered after them: the directions are independent and combine in
    quadrature.

    >>> springs = prior_rope_springs((1.0,) * 4, 0.05)
    >>> band_groups(band_solutions(springs, 0.1))
    (0, 0, 1, 1, 4, 4, 5, 5, 6, 6)
    """
    groups = []
    pair = 0
    for member in solutions[1:]:
        if member.source == "stiffness":
            groups.append(
                BAND_SOURCES.index("stiffness") if pair < 2 else len(BAND_SOURCES) + pair // 2 - 1
            )
            pair += 1
        else:
            groups.append(BAND_SOURCES.index(member.source))
    return tuple(groups)
