"""Compensation of a long record in time blocks, in memory bounded by the block (issue 16).

:func:`transforms.compensation.compensate` holds a whole record in memory: a 100 Hz day
is 8.6 M samples, ~40 day-long arrays of work and a 40-column result, 7-8 GB. Here the
record is read and compensated block by block:

1. the record's statistics (logger rate, noise sigmas, typical pressure) are read once
   from a sparse, evenly spread sample of it (:func:`record_context`: a first pass over
   the blocks keeps about 3 x 200 k rows whatever the record's length), so every block
   uses the record's values, not its own;
2. each block ``[t_k, t_k+1)`` is read with a margin either side
   (:func:`transforms.compensation.compensation_margins_s`: 30 s or more, so the
   zero-phase filters have forgotten the window's edges) and the stop continuity's
   look-ahead more after its end
   (:func:`transforms.compensation.compensation_look_ahead_s`: the next trip's run that
   predicts a stop's load), and compensated by
   :func:`transforms.compensation.compensate_window`, which resumes every sequential
   kernel (oil common mode, pistons' share-out, play operators, seal friction, trip
   labels) from the state the previous block left (:class:`CompensationCarry`).

Equivalence. The sequential kernels carry their exact state, so the only differences
from the whole record come from the non-causal filters at the window's edges, 30 s or
more away from the block: the Butterworth low-pass's start-up transient has decayed by
then to far below a rounding error, the Savitzky-Golay and Gaussian smoothers have
finite support. Running sums in the smoother add rounding at the 1e-13 relative level.
``tests/transforms/test_blocks.py`` checks a day with gaps, stops on block edges and
a trip across one against the whole-record result (every column within 1e-9 relative
or 1e-6 absolute in its unit, labels equal). Not equal: a logged displacement missing
for longer than the margin inside one 120 s-bridged segment (the whole record
interpolates across it, a block sees no neighbour), the oil temperature's leading
nulls of a block (filled from inside the window, not from before it), and a stuck
sensor's stretch whose other sensors froze too, or on a logger that rounds coarsely
moved by more than the steps only more than the margin away from the block (the whole
record takes the stretch as not logged, the block as a pressure:
:func:`transforms.alarm_events.flatline_runs`; a sensor stuck at rest on a logger
rounding to 50 kPa, the others moving 150 kPa a few minutes away: 75.7 k samples null
whole, 24.0 k in 4-minute blocks, session 40's review), and a pressure missing for
longer than the margin inside one segment (a dead sensor, or one stuck long enough for
the flatline rule): the low-pass bridges the run linearly to its far end, which a
block does not see, so the filtered samples at the run's edge differ by up to ~15 Pa
and the stick-slip solutions then by ~0.05 N a rope for the rest of the record (the
load by up to 1.1 N with all four missing for 400 s; session 43's review; the run's own
samples are returned not logged either way).

Block edges are whole multiples of ``block`` from midnight UTC (an hour by default), so
a re-run of part of a day computes the same blocks.
"""

from __future__ import annotations

import datetime as dt
import itertools
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import polars as pl

from physics.conveyance import reading_turns
from schemas.hoist import HoistDescription
from transforms.compensation import (
    CompensationCarry,
    CompensationContext,
    CompensationSettings,
    compensate_window,
    compensation_context,
    compensation_look_ahead_s,
    compensation_margins_s,
    context_sample,
    context_stride,
)
from transforms.compensation_record import float_column, identification_means
from transforms.rope_identification import IDENTIFY_SPAN

__all__ = ["DEFAULT_BLOCK", "block_edges", "compensate_blocks", "record_context"]

#: Default block length of ``ropeload run`` (360 k samples of a 100 Hz logger).
DEFAULT_BLOCK = dt.timedelta(hours=1)

Reader = Callable[[dt.datetime, dt.datetime], pl.DataFrame]


def block_edges(
    start: dt.datetime, end: dt.datetime, block: dt.timedelta = DEFAULT_BLOCK
) -> list[tuple[dt.datetime, dt.datetime]]:
    """Blocks ``[lo, hi)`` covering ``[start, end)``, inner edges on multiples of ``block``
    counted from midnight UTC of ``start``'s day.

    >>> utc = dt.timezone.utc
    >>> edges = block_edges(dt.datetime(2026, 3, 1, 22, 30, tzinfo=utc),
    ...                     dt.datetime(2026, 3, 2, 0, 10, tzinfo=utc))
    >>> [(lo.strftime("%H:%M"), hi.strftime("%H:%M")) for lo, hi in edges]
    [('22:30', '23:00'), ('23:00', '00:00'), ('00:00', '00:10')]
    """
    if block <= dt.timedelta(0):
        raise ValueError(f"block must be positive, got {block}")
    midnight = dt.datetime.combine(start.astimezone(dt.UTC).date(), dt.time(), dt.UTC)
    k = (start - midnight) // block + 1
    edges = [start]
    while midnight + k * block < end:
        edges.append(midnight + k * block)
        k += 1
    edges.append(end)
    return list(itertools.pairwise(edges))


def compensate_blocks(
    read: Reader,
    hoist: HoistDescription,
    *,
    start: dt.datetime,
    end: dt.datetime,
    context: CompensationContext,
    settings: CompensationSettings | None = None,
    block: dt.timedelta = DEFAULT_BLOCK,
) -> Iterator[pl.DataFrame]:
    """``ROPE_TENSIONS`` rows of ``start <= t < end``, one frame per block, in time order.

    ``read(lo, hi)`` returns the record's samples ``lo <= t < hi`` (FIELD_SAMPLES columns,
    sorted by time); ``start`` must be the record's first sample time (the friction state
    starts there, as in :func:`transforms.compensation.compensate`). ``context``: the
    whole record's statistics (:func:`transforms.compensation.compensation_context`).
    Concatenated, the frames are the whole record's compensation (module docstring).
    """
    settings = settings or CompensationSettings()
    resume_s, halo_s = compensation_margins_s(settings, hoist)
    margin = dt.timedelta(seconds=resume_s + halo_s)
    ahead = margin + dt.timedelta(seconds=compensation_look_ahead_s(settings))
    carry: CompensationCarry | None = None
    for lo, hi in block_edges(start, end, block):
        window = read(max(start, lo - margin), min(end, hi + ahead))
        if window.height == 0:
            continue
        rows, carry = compensate_window(
            window,
            hoist,
            context=context,
            settings=settings,
            carry=carry,
            block_start_utc=lo,
            block_end_utc=hi if hi < end else None,
        )
        if rows.height:
            yield rows


def record_context(
    read: Reader,
    hoist: HoistDescription,
    *,
    start: dt.datetime,
    end: dt.datetime,
    rows: int,
    settings: CompensationSettings | None = None,
    block: dt.timedelta = DEFAULT_BLOCK,
    cache_dir: Path | None = None,
) -> CompensationContext:
    """The record's statistics for :func:`compensate_blocks`, read block by block.

    ``read(lo, hi)`` as for :func:`compensate_blocks` (``time_utc``, the ``p`` and ``x``
    columns, and for the ropes' identification over the first
    :data:`~transforms.rope_identification.IDENTIFY_SPAN` ``depth_m``, ``speed_m_s`` and
    ``oil_temp_c``),
    ``rows`` the record's number of samples. Rows are numbered across the blocks, so the
    sample is the one :func:`transforms.compensation.compensate` takes of the whole record
    in memory, and so are the statistics; the identification's means are taken of its
    first rows joined (a 0.2 s window may straddle a block's edge); the identified ropes
    are remembered in ``cache_dir`` (:func:`~transforms.compensation_record.
    compensation_context`).
    """
    settings = settings or CompensationSettings()
    stride = context_stride(rows)
    parts, early, offset = [], [], 0
    sizes, counts = [], []  # the depth's reversals, block by block: each block's changes
    # led by the previous block's last depth and its last non-zero change, so a change
    # across an edge, and a turn there, count as they do in the whole record
    last_depth, last_change = np.empty(0), np.empty(0)
    for lo, hi in block_edges(start, end, block):
        frame = read(lo, hi)
        if "depth_m" in frame.columns:
            depth = float_column(frame["depth_m"])
            changes = np.concatenate([last_change, np.diff(np.concatenate([last_depth, depth]))])
            turns = reading_turns(changes)
            sizes.append(turns[0])
            counts.append(turns[1])
            if depth.size:
                last_depth = depth[-1:]
            moved = changes[np.isfinite(changes) & (changes != 0.0)]
            last_change = moved[-1:] if moved.size else last_change
        parts.append(context_sample(frame, stride, offset=offset).collect())
        if settings.rope_springs and lo < start + IDENTIFY_SPAN:  # averaged once below
            early.append(frame.filter(pl.col("time_utc") < start + IDENTIFY_SPAN))
        offset += frame.height
    means = (
        identification_means(pl.concat(early, how="vertical_relaxed"), start, hoist, settings)
        if early
        else None
    )
    return compensation_context(
        pl.concat(parts, how="vertical_relaxed"), hoist, settings, stride, means=means,
        cache_dir=cache_dir,
        depth_turns=(np.concatenate(sizes), np.concatenate(counts)) if sizes else None,
    )  # fmt: skip
