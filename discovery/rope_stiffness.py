"""The head ropes' stiffness spread a replay uses: read off the record.

Real head ropes differ in axial stiffness by several percent (manufacture, wear,
re-terminations); a mine's description gives one EA for all. The spread decides how the
seals carry a load change: while the pistons stick, rope i takes ``k_i / sum(k)`` of it,
so the pistons' friction forces part ways until the one pushed hardest breaks away and
takes the closed oil volume's change (paper eq 5) alone while the others stay stuck
with what they carry. With equal ropes all four slide together, each at its sliding
friction: the seals' summed force, and with it the common-mode sensor pressure
(``n A p = sum T_i + sum F_i``), differs by thousands of newtons. On the validation days
(an independent simulator whose ropes differ, unknown to its description) the logged
pistons show it: one piston slides millimetres per trip while three move less than the
logger's 0.1 mm step, and the replay with equal ropes leaves a common-mode gap of
~50 kPa against 5 kPa of noise.

The record does not give the stiffnesses directly (a stuck piston does not move), but
what the replay needs is the size of the spread: the spread ``s`` of factors
``1 + s (-1.5, -0.5, 0.5, 1.5)`` (evenly spaced, mean 1, for four ropes) whose replay of
the first trips leaves the smallest gap (:func:`with_rope_stiffness`, a grid and a
parabola through the best three), kept only when it beats equal ropes by 10 % (as
:mod:`discovery.rope_damping` keeps the description's damping) and the gap has its
minimum inside the grid: a gap that still falls at the largest spread tried is
something else (a hidden groove wear of 0.4 mm in ropeload's own trials pulled the
search to the grid's end, where the spread took 28 % of its gap). Which rope is which is
not read: the common-mode pressure is the same for any order of the same factors
(on validation day 101 the common-mode RMS gap of three orders agreed to 1e-10) and the
differential one stays at the noise, so the sensors cannot tell; the factors go in rope
order, and the replayed pistons may slide where the logged ones stuck. A record whose
pistons all slid alike (:func:`piston_slides_m`) keeps equal ropes without a search.

One parameter is a simplification: real spreads are not evenly spaced. It is a
nuisance parameter (like the payloads and the ropes' damping), fitted to the baseline
model before any candidate effect is tried.

Where the compensation has identified the ropes from the logged x
(:mod:`transforms.rope_identification`: each rope's stiffness factor, which rope is
which, to the logger's step), those factors are used instead of the spread: they are a
measurement from data the pressure gap does not use, and they name the ropes. The
identification fixes rope 1 at the description's EA (a gauge: the stick-slip model
barely sees the ropes' common stiffness); the replay scales the factors to a mean of
1, as the spread's. On validation day 101 (24 trips) the replay gap fell from 16.3 kPa
with the spread to 15.0 kPa (14.7 kPa unscaled); on an independent record with a
hidden throttled valve, whose spread search kept equal ropes, from 49.5 to 36.9 kPa
(12 trips); on day 104, whose ropes ring, from 19.5 to 19.1 kPa (19.7 kPa unscaled:
stiffer ropes ring faster). The first trips' gap cannot tell them apart (13.0 against
13.2 kPa on day 101), so the spread is still searched and the identified factors are
refused only when they replay the first trips more than 10 % further off than the
spread's choice (e.g. a rope re-terminated since the identification's record).
The caller brings them (``plan_replay(identified_ropes=...)``): discovery imports no
transforms. Brought with their length offsets (:class:`IdentifiedRopes`), the plan
keeps those too once the factors are kept, and each replay block starts with its pistons
where the record logged them (:func:`sims.replay.block_pistons`): on an independent record
with nothing hidden (validation trial_010, 12 trips in 4 blocks) the replay gap fell
from 25.9 to 11.6 kPa, the blocks started at the middle level no longer sliding their
pistons 7-10 mm apart on the way up where the record's moved 1-3 mm. The factors are
weighed against the spread's choice in both starts, from equal tensions (as the spread's
replays start) and at the offsets (as they are replayed once kept), the better gap
counting: each start alone misjudged an independent simulator's records. From equal
tensions alone, validation day 102 cut at its second hour (the record starting where
the seals held the pistons millimetres from equal tensions) replayed its first trips
38.3 kPa off with them against the spread's 27.3 kPa; the factors were refused and the
damping chosen with the spread, and all 34 trips of the hour failed the sanity check
(3.3-8.0 x the noise); at the offsets they replay 14.6 kPa off, are kept, and the
damping chosen with them takes the gap to 11.6 kPa. At the offsets alone, day 101,
whose record starts where the world's seals start at zero friction and the offsets put
~300 N in them, replayed 14.3 against 13.0 kPa and lost its factors (session 25).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np
import polars as pl

from schemas.hoist import HoistDescription
from sims.replay import CLOSER_SHARE, first_trips_gaps
from sims.replay_plan import ReplayPlan

__all__ = [
    "SLIDE_DEADBAND_M",
    "SPREAD_GRID",
    "IdentifiedFactors",
    "IdentifiedRopes",
    "piston_slides_m",
    "spread_factors",
    "with_rope_stiffness",
    "with_stiffness_factors",
]


class IdentifiedRopes(Protocol):
    """The head ropes' constants as the compensation identifies them from the logged x
    (``transforms.stick_slip_band.RopeSprings`` is one): rope i pulls its piston with
    a_i k (s - x_i - c_i)."""

    @property
    def stiffness_factors(self) -> Sequence[float]: ...  # a_i

    @property
    def length_offsets_m(self) -> Sequence[float]: ...  # c_i [m]


#: The ropes' stiffness factors as the compensation identified them (alone, or with their
#: length offsets: :class:`IdentifiedRopes`), None, or a function of no argument
#: returning one of those (called after the spread's grid, or at once when the pistons
#: slid alike, so that the identification can run beside the record's first replays:
#: ``concurrent.futures.Future.result``).
Identified = Sequence[float] | IdentifiedRopes | None
IdentifiedFactors = Identified | Callable[[], Identified]

#: Spreads tried (factor step between neighbouring ropes, sorted by stiffness); the
#: validation days' gap is smallest near 0.025 and rises steeply either side.
SPREAD_GRID = (0.0, 0.01, 0.02, 0.03, 0.045)

#: Moves of a piston's 1-second median position below this [m] do not count as a slide
#: (1.5 steps of a logger quantising to 0.1 mm; presliding is ~0.05 mm).
SLIDE_DEADBAND_M = 0.15e-3

#: Trips of the first block replayed per candidate.
_TRIPS = 3

#: Identified factors whose first trips replay more than this many times the gap of the
#: spread's choice are refused (10 % worse).
_REFUSED_ABOVE = 1.1

#: Pistons whose slides over the record are within this ratio slid alike: equal ropes
#: (a spread makes one piston take the closed volume's change alone).
_ALIKE_RATIO = 1.5


def piston_slides_m(samples: pl.DataFrame, n: int) -> np.ndarray | None:
    """How far each piston slid over the record [m]; None without logged positions.

    The path of 1-second medians of ``x{i}_m`` through a dead band of
    :data:`SLIDE_DEADBAND_M` (a move counts once the reading is that far from where the
    last counted one left it): a sticking piston whose reading toggles between two of
    the logger's 0.1 mm steps adds nothing, a sliding one its millimetres.
    """
    cols = [f"x{i}_m" for i in range(1, n + 1)]
    if not set(cols) <= set(samples.columns):
        return None
    per_second = (
        samples.sort("time_utc")
        .group_by_dynamic("time_utc", every="1s")
        .agg([pl.col(c).median() for c in cols])
    )
    x = per_second.select(cols).to_numpy().astype(float)
    if x.shape[0] < 3 or not np.isfinite(x).any():
        return None
    return np.array([_deadband_path(x[:, i]) for i in range(n)])


def _deadband_path(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    if x.size == 0:
        return 0.0
    anchor, path = x[0], 0.0
    for value in x[1:]:
        if abs(value - anchor) >= SLIDE_DEADBAND_M:
            path += abs(value - anchor)
            anchor = value
    return float(path)


def spread_factors(spread: float, n: int) -> list[float]:
    """Stiffness factors (mean 1) of ``n`` ropes ``spread`` apart, in rope order (the
    sensor pressures do not tell which rope is which: see the module docstring)."""
    return [float(1.0 + (i - (n - 1) / 2.0) * spread) for i in range(n)]


def with_stiffness_factors(
    hoist: HoistDescription, factors: list[float] | None
) -> HoistDescription:
    """``hoist`` with its head ropes' stiffness factors replaced (None: all alike)."""
    ropes = hoist.ropes.model_copy(update={"head_rope_stiffness_factors": factors})
    return hoist.model_copy(update={"ropes": ropes})


def with_rope_stiffness(
    plan: ReplayPlan,
    slides_m: np.ndarray | None,
    identified: IdentifiedFactors = None,
) -> ReplayPlan:
    """The plan with the head ropes' stiffness spread its first trips replay closest.

    ``slides_m``: each piston's slide over the record (:func:`piston_slides_m`; None
    when the record has no piston positions). ``identified``: the ropes' stiffness
    factors identified from the logged x (module docstring; or a function returning
    them, called after the spread's grid, or at once when the pistons slid alike,
    :data:`IdentifiedFactors`), scaled to a mean of 1 and used unless the first trips
    replay more than 10 % further from the record with them than with the spread's
    choice. They replay beside the spread's refinement, when there is one, or beside
    equal ropes when the pistons slid alike, each on a core of its own.

    The spread: a description that states its ropes' factors keeps them, and so does a
    record whose pistons all slid, and alike (within a factor 1.5: equal ropes move them
    together; pistons that never left the logger's dead band say nothing). Otherwise
    each spread of :data:`SPREAD_GRID` is replayed on the first block's first three
    trips (payloads fitted, two passes), a parabola through the best one and its
    neighbours refines it, and the result replaces equal ropes when its gap is below
    90 % of theirs. The choice and the gaps are stated in the plan's notes.
    """
    hoist = plan.hoist
    n = hoist.ropes_n
    if hoist.ropes.head_rope_stiffness_factors is not None or not plan.trips or n < 2:
        return plan
    if identified is not None and not callable(identified):
        _check_count(_factors_of(identified), n)  # before any replay
    alike = _slid_alike(slides_m)
    grid = None if alike else _spread_grid(plan)
    if callable(identified):
        identified = identified()
    beside: list[ReplayPlan] = []
    if identified is not None:
        raw = _factors_of(identified)
        _check_count(raw, n)
        # the identification's gauge (rope 1 at the description's EA) is arbitrary: the
        # description's EA is taken as the ropes' mean, as for the spread
        factors = [float(f) / float(np.mean(raw)) for f in raw]
        offsets = getattr(identified, "length_offsets_m", None)
        if offsets is not None:
            _check_count(offsets, n, "length offsets")
            offsets = tuple(float(c) for c in offsets)
        # compared with the spread like with like, started with equal tensions, and as
        # they are replayed once kept, their offsets placing the pistons where the record
        # had them: the better start weighs (either alone misjudged an independent
        # simulator's records, by where its seals and pistons happen to start)
        identified_hoist = with_stiffness_factors(hoist, factors)
        beside = [dataclasses.replace(plan, hoist=identified_hoist, rope_offsets_m=None)]
        if offsets is not None:
            beside.append(dataclasses.replace(beside[0], rope_offsets_m=offsets))
    # the identified ropes replay beside the spread's last replay (its refinement, or
    # equal ropes when the pistons slid alike), side by side on the cores
    if alike:
        searched = dataclasses.replace(plan, notes=(*plan.notes, alike))
        if not beside:
            return searched
        searched_gap, *gaps = first_trips_gaps([(plan, None), *[(b, None) for b in beside]], _TRIPS)
    else:
        searched, searched_gap, gaps = _spread_chosen(plan, *grid, beside)
        if not beside:
            return searched
    gap = min(gaps)
    starts = (
        f" (started from equal tensions {gaps[0] / 1e3:.1f} kPa, at the offsets' "
        f"{gaps[1] / 1e3:.1f} kPa)"
        if len(gaps) > 1
        else ""
    )
    said = (
        f"{', '.join(f'{f:.3f}' for f in factors)} (replay gap on the first {_TRIPS} trips "
        f"{gap / 1e3:.1f} kPa{starts}, the spread's choice {searched_gap / 1e3:.1f} kPa)"
    )
    if gap <= _REFUSED_ABOVE * searched_gap:
        note = f"rope stiffness: as identified from the logged piston positions, {said}"
        return dataclasses.replace(beside[0], rope_offsets_m=offsets, notes=(*plan.notes, note))
    note = f"rope stiffness: the identified factors refused, {said}"
    return dataclasses.replace(searched, notes=(*searched.notes, note))


def _factors_of(identified: Sequence[float] | IdentifiedRopes) -> Sequence[float]:
    """The stiffness factors of identified ropes (given alone or with their offsets)."""
    return getattr(identified, "stiffness_factors", identified)


def _check_count(identified: Sequence[float], n: int, what: str = "stiffness factors") -> None:
    if len(identified) != n:
        raise ValueError(f"identified: {len(identified)} {what} for {n} ropes")


def _slid_alike(slides_m: np.ndarray | None) -> str | None:
    """The note keeping equal ropes when every piston slid, and alike (no search); else
    None."""
    moved = slides_m is not None and np.min(slides_m) > SLIDE_DEADBAND_M
    if not (moved and np.max(slides_m) <= _ALIKE_RATIO * np.min(slides_m)):
        return None
    return "rope stiffness: equal ropes kept (the pistons slid alike, {} mm)".format(
        ", ".join(f"{1e3 * s:.1f}" for s in slides_m)
    )


def _spread_grid(plan: ReplayPlan) -> tuple[list[float], list[float]]:
    """Each spread of :data:`SPREAD_GRID` and the first trips' replay gap with it."""
    spreads = list(SPREAD_GRID)
    replays = [(plan, _with_spread(plan.hoist, s)) for s in spreads]
    return spreads, first_trips_gaps(replays, _TRIPS)


def _with_spread(hoist: HoistDescription, width: float) -> HoistDescription:
    factors = spread_factors(width, hoist.ropes_n) if width > 0 else None
    return with_stiffness_factors(hoist, factors)


def _spread_chosen(
    plan: ReplayPlan,
    spreads: list[float],
    gaps: list[float],
    beside: Sequence[ReplayPlan],
) -> tuple[ReplayPlan, float, list[float]]:
    """The plan with the spread :func:`with_rope_stiffness` chooses from the grid's
    ``spreads`` and their ``gaps`` (refined by a parabola through the best one and its
    neighbours), the first trips' replay gap with it, and those of the plans ``beside``
    (the identified ropes), replayed beside the refinement."""
    hoist = plan.hoist
    best = int(np.argmin(gaps))
    refined = None
    if 0 < best < len(spreads) - 1 and np.all(np.isfinite(gaps[best - 1 : best + 2])):
        refined = _parabola_minimum(spreads[best - 1 : best + 2], gaps[best - 1 : best + 2])
    replays = [] if refined is None else [(plan, _with_spread(hoist, refined))]
    replays += [(b, None) for b in beside]
    ran = first_trips_gaps(replays, _TRIPS) if replays else []
    beside_gap = ran[len(ran) - len(beside) :]
    ran = ran[: len(ran) - len(beside)]
    if refined is not None:
        spreads, gaps = [*spreads, refined], [*gaps, ran[0]]
        best = int(np.argmin(gaps))
    said = ", ".join(
        f"{s:.3g}: {g / 1e3:.1f} kPa" for s, g in sorted(zip(spreads, gaps, strict=True))
    )
    if spreads[best] == 0.0 or not gaps[best] < CLOSER_SHARE * gaps[0]:
        note = f"rope stiffness: equal ropes kept (replay gap by spread {said})"
        return dataclasses.replace(plan, notes=(*plan.notes, note)), gaps[0], beside_gap
    if spreads[best] == SPREAD_GRID[-1]:
        # still falling at the largest spread real ropes plausibly have: the gap is
        # something else (a hidden effect), which a spread would only partly mimic
        note = (
            f"rope stiffness: equal ropes kept (the gap falls up to the largest spread "
            f"tried, {SPREAD_GRID[-1]:g}: not a spread; {said})"
        )
        return dataclasses.replace(plan, notes=(*plan.notes, note)), gaps[0], beside_gap
    factors = spread_factors(spreads[best], hoist.ropes_n)
    note = (
        f"rope stiffness: spread {spreads[best]:.3g} between neighbouring ropes, factors "
        f"{', '.join(f'{f:.3f}' for f in factors)} (replay gap on the first {_TRIPS} trips by "
        f"spread {said})"
    )
    chosen = dataclasses.replace(
        plan, hoist=with_stiffness_factors(hoist, factors), notes=(*plan.notes, note)
    )
    return chosen, gaps[best], beside_gap


def _parabola_minimum(xs: list[float], ys: list[float]) -> float | None:
    """Abscissa of the vertex of the parabola through three points, if it is a minimum
    inside their span."""
    a, b, _ = np.polyfit(np.asarray(xs), np.asarray(ys), 2)
    if a <= 0:
        return None
    vertex = float(-b / (2.0 * a))
    return vertex if xs[0] < vertex < xs[-1] and vertex not in xs else None
