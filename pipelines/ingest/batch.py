"""What a reader hands to landing: :class:`Reading` (one file) made of :class:`Batch` es.

Readers (``field_csv``, ``field_tdms``, ``rig_mcap``) turn raw bytes into batches of
clean SI samples plus the rows they rejected; they never touch the lake or the
warehouse. A file that cannot be read at all raises :class:`RefusedFile`, whose
message names the file and the line, channel or topic.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import polars as pl

from pipelines.ingest.clock import ClockState

__all__ = ["REJECTED_SCHEMA", "Batch", "Reading", "RefusedFile", "rejected_frame"]

#: Rows a reader rejected: ``row`` is the 1-based line (CSV), the sample index (TDMS)
#: or the message index (MCAP) - the same identity as the samples' ``_row``.
REJECTED_SCHEMA = {"row": pl.Int64, "topic": pl.String, "reason": pl.String, "raw": pl.String}


class RefusedFile(ValueError):
    """The whole file is refused; nothing of it lands."""


def rejected_frame(rows: list[tuple[int | None, str | None, str, str | None]]) -> pl.DataFrame:
    """Rejected rows from Python tuples ``(row, topic, reason, raw)``."""
    return pl.DataFrame(rows, schema=REJECTED_SCHEMA, orient="row")


@dataclass
class Batch:
    """Clean samples and rejected rows of one slice of a file.

    ``samples`` has the landed table's columns (SI) plus ``_row``; ``rows_read``
    counts both (plus nothing else), so ``rows_read = samples + rejected``.
    ``raw_of`` gives the raw text of rows by ``_row`` (for rows quarantined later,
    e.g. conflicts found while landing).

    ``held``: rows of a logger clock's step back (:mod:`.clock`), with the samples'
    columns and their ``_reason``. They land nowhere: after the batch's samples have
    landed, each one equal in every value to a landed sample of its time is an exact
    duplicate (a logger that wrote a stretch again), the others are quarantined with
    their reason (:meth:`.landing.LakeTable.landed_duplicates`).
    """

    samples: pl.DataFrame
    rejected: pl.DataFrame
    raw_of: Callable[[list[int]], list[str | None]]
    held: pl.DataFrame | None = None

    @property
    def rows_read(self) -> int:
        held = 0 if self.held is None else self.held.height
        return self.samples.height + self.rejected.height + held


@dataclass
class Reading:
    """An opened source file: identity, lake table and its batches.

    After ``batches`` is exhausted, ``bytes_consumed`` and ``partial`` describe how far
    the file could be read, and ``clock`` where the logger's clock stood there (field
    logs; :mod:`.clock`); ``notes`` collect things the report should say.
    """

    table: str
    site: str
    hoist: str
    batches: Iterator[Batch]
    notes: list[str] = field(default_factory=list)
    bytes_consumed: int | None = None
    partial: str | None = None
    clock: ClockState | None = None
