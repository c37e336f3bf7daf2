"""A CSV field log read in byte chunks that end at a newline (:func:`iter_chunks`).

Memory stays bounded by ``batch_bytes`` however large the file; a last line without a
newline is held back and said in :class:`ChunkProgress` (the file may still be growing),
unless the file is said to be complete (a finished export whose last row has no line
end: ``ropeload ingest --complete``), when it is read as the last row.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipelines.ingest.csv_scan import count_newlines
from pipelines.ingest.local_time import AmbiguityState

__all__ = ["ChunkProgress", "iter_chunks"]


@dataclass
class ChunkProgress:
    """Bytes consumed so far, the held-back last line, the DST ambiguity state."""

    bytes_consumed: int
    partial: str | None = None
    ambiguity: AmbiguityState = field(default_factory=AmbiguityState)


def iter_chunks(
    path: Path,
    offset: int,
    line: int,
    batch_bytes: int,
    progress: ChunkProgress,
    *,
    complete: bool = False,
) -> Iterator[tuple[bytes, int, int]]:
    """``(chunk, first line number, lines in it)``; each chunk ends with a newline.

    ``complete``: the file is finished, so a last line without a newline is its last
    row: yielded as a chunk of its own with the newline added (``bytes_consumed`` then
    counts the file's bytes, not the added one), not held back.

    A chunk is ``batch_bytes`` plus the rest of the line it ends in: a small probe at
    the nominal end finds that newline, then one ``read`` of exactly that length gives
    the chunk (no carry, no copy). Near the end of the file the rest is read at once.
    """
    with path.open("rb") as handle:
        position = offset
        while True:
            length = _through_newline(handle, position, batch_bytes)
            handle.seek(position)
            if length is not None:
                chunk = handle.read(length)
                carry = b""
            else:
                rest = handle.read()
                cut = rest.rfind(b"\n")
                chunk = rest if cut == len(rest) - 1 else rest[: cut + 1]
                carry = rest[cut + 1 :]
                del rest
            if not chunk:
                break
            n_lines = count_newlines(np.frombuffer(chunk, np.uint8))
            yield chunk, line, n_lines
            line += n_lines
            position += len(chunk)
            progress.bytes_consumed += len(chunk)
            if carry:
                break
        if carry and complete:
            yield carry + b"\n", line, 1
            progress.bytes_consumed += len(carry)
        elif carry:
            progress.partial = (
                f"line {line} is cut off ({len(carry)} bytes without a newline at the end): "
                "held back until the file grows (a finished export: ingest --complete)"
            )


def _through_newline(handle, position: int, batch_bytes: int) -> int | None:
    """Bytes from ``position`` through the first newline at or after its ``batch_bytes``-th
    byte, or ``None`` when the file ends before such a newline."""
    probe_at = position + max(batch_bytes, 1) - 1
    handle.seek(probe_at)
    while probe := handle.read(1 << 16):
        found = probe.find(b"\n")
        if found >= 0:
            return probe_at + found + 1 - position
        probe_at += len(probe)
    return None
