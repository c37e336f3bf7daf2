"""The band's members on means: the stick-slip solution's spread at a fraction of its cost.

Opt-in (``CompensationSettings(band_member_step_s=...)``; the default runs every member
at the sensors' rate). The friction's part of the 95 % band (:mod:`transforms.uncertainty`)
is the spread of :func:`transforms.stick_slip.stick_slip` over the members of
:func:`transforms.stick_slip_band.band_solutions`: the law's capacity, the bristles'
stiffness, the seals' unknown start and the ropes as identified on parts of the record.
At the sensors' rate each member costs what the estimate costs, and the eight of them
are most of the compensation's compute (2 h at 100 Hz of the example hoist, its seals
of Maxwell-slip elements, 386 ns a sample and solution: the compute took 1.34 s with
identified ropes, 0.17 s without the stick-slip solution; session 30).

The members run instead on windows of ``band_member_step_s`` since the epoch (within a
gap-free segment, so a record read block by block has the windows of the record read
whole) where no pressure moves by more than :data:`STEADY_SIGMAS` x its low-passed noise,
each window one mean; where a pressure moves, sample by sample (:func:`mean_starts`,
:func:`mean_steps`: the pistons' speed between two means). The estimate's own law runs
on the same means, and each member's friction at the sensors' rate is the estimate's
plus the member's difference from it on the means, held over each mean's samples
(:func:`held`). A LuGre seal's drift is driven by the full-rate play's travel summed over
each mean (:func:`transforms.seal_drift.played_travels_into`, the ringing the play hides
included), as in the ropes' identification. Where no window is steady the means are the
samples and the members match those at the sensors' rate (to 1e-5 of the load a minute
into the record, where the kernel's own play starts a sample later;
``tests/transforms/test_band_members.py``). The step is a whole fraction of the blocks'
resume margin, so that the windows start where a block's first stage does.

What it costs in accuracy, measured (session 30, 0.1 s windows): on a 1 h LuGre day of
ropeload's own generator at 50 Hz the load band's edges moved by 27 / 17 N RMS (99th
percentile 80 / 61 N) and the ropes' half-widths by 4 N RMS; on the independent
simulator's validation days (``benchmarks/eval_compensation.py``) the stop windows'
coverage went from 97.4 / 95.7 / 90.5 / 74.2 % to 98.3 / 96.6 / 89.7 / 73.3 % (days
101-104) at the same median half-width (0.84 / 0.82 / 0.76 / 0.43 % against
0.84 / 0.81 / 0.74 / 0.44 %), but at one stop of day 103 (the record's first arrival at
the pithead, a throttled valve) the band moved by 0.3 % of the load: a seal that the
noise-level wiggles of a merged window would have slid back and forth holds another
force there, and the estimate and the members do not answer alike. The compute of the
2 h, 100 Hz day (the bench's day, identified ropes; seven paired runs, medians) went
from 1.17 to 0.76 s of wall time and from 1.88 to 0.82 s of CPU: the estimate at the
sensors' rate and the steps around the stick-slip solution stay. A
backfill's choice, not the default.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "STEADY_SIGMAS",
    "group_mean",
    "group_sum",
    "held",
    "mean_starts",
    "mean_steps",
]

#: A window is one mean where no pressure moves by more than this many standard
#: deviations of its low-passed noise (:func:`mean_starts`): what the sensors cannot tell
#: from noise is merged, every real change is solved sample by sample.
STEADY_SIGMAS = 4.0


def mean_starts(
    epoch_us: np.ndarray,
    segment: np.ndarray,
    step_s: float,
    pressures: tuple[np.ndarray, ...] = (),
    steady_pa: float = np.inf,
) -> np.ndarray:
    """Index of each mean's first sample: windows of ``step_s`` since the epoch within each
    gap-free segment; a window in which some of ``pressures`` moves by more than
    ``steady_pa`` (its largest less its smallest value; or holds an unknown one) is split
    into its samples, each a mean of its own.

    >>> t, seg = np.arange(0, 600_000, 100_000), np.array([0, 0, 0, 1, 1, 1])
    >>> mean_starts(t, seg, 0.2).tolist()
    [0, 2, 3, 4]
    >>> mean_starts(t, seg, 0.2, (np.array([0.0, 1.0, 5.0, 5.0, 5.0, 9.0]),), 2.0).tolist()
    [0, 2, 3, 4, 5]
    """
    n = epoch_us.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    window = epoch_us // round(step_s * 1e6)
    new = np.empty(n, dtype=bool)
    new[0] = True
    new[1:] = (window[1:] != window[:-1]) | (segment[1:] != segment[:-1])
    starts = np.flatnonzero(new)
    if pressures:
        steady = np.ones(starts.size, dtype=bool)
        for p in pressures:  # NaN spreads compare False: split
            steady &= np.maximum.reduceat(p, starts) - np.minimum.reduceat(p, starts) <= steady_pa
        new |= np.repeat(~steady, np.diff(np.append(starts, n)))
        starts = np.flatnonzero(new)
    return starts


def mean_steps(
    starts: np.ndarray, n: int, dt_s: float, segment: np.ndarray | None = None
) -> np.ndarray:
    """Step from each mean's centre to the next's [s] on a grid of ``dt_s`` (the means of
    ``n`` samples starting at ``starts``): the pistons' speed between two means; the
    first's is ``dt_s``, and with ``segment`` (each mean's gap-free segment) so is the
    first of each segment's, as at the sensors' rate (no speed is known across a logger
    gap, and a block read from the gap's end has no mean before it). A mean of one
    sample after another steps by ``dt_s``, as the samples do.

    >>> mean_steps(np.array([0, 1, 2, 6]), 8, 0.01).round(3).tolist()
    [0.01, 0.01, 0.025, 0.03]
    >>> mean_steps(np.array([0, 1, 2, 6]), 8, 0.01, np.array([0, 0, 0, 1])).round(3).tolist()
    [0.01, 0.01, 0.025, 0.01]
    """
    centre = (starts + np.append(starts[1:], n) - 1) / 2.0
    steps = np.empty(starts.size)
    steps[:1] = dt_s
    steps[1:] = np.diff(centre) * dt_s
    if segment is not None:
        steps[1:][segment[1:] != segment[:-1]] = dt_s
    return steps


def group_mean(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Mean of each mean's known (finite) values; NaN where it has none.

    >>> group_mean(np.array([1.0, 3.0, np.nan, 4.0]), np.array([0, 2])).tolist()
    [2.0, 4.0]
    """
    known = np.isfinite(values)
    sums = np.add.reduceat(np.where(known, values, 0.0), starts)
    counts = np.add.reduceat(known.astype(np.float64), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / counts, np.nan)


def group_sum(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Sum over each mean's samples.

    >>> group_sum(np.array([1.0, 3.0, 0.5, 4.0]), np.array([0, 2])).tolist()
    [4.0, 4.5]
    """
    return np.add.reduceat(values, starts)


def held(per_mean: np.ndarray, starts: np.ndarray, n: int) -> np.ndarray:
    """Each mean's value on each of its samples (``n`` samples in all).

    >>> held(np.array([2.0, 4.0]), np.array([0, 2]), 3).tolist()
    [2.0, 2.0, 4.0]
    """
    return np.repeat(per_mean, np.diff(np.append(starts, n)))
