"""The ingest manifest in the warehouse: one row per distinct source content (sha256).

Content, not names, is the key: a file re-exported under a new name has the same
sha256 and is skipped, when it was landed (or partial) in the same format. A refused
content is read again on every ingest and its row replaced by the new outcome
(:func:`forget` + :func:`record`); bytes of another format (an empty ``.mcap`` after
an empty ``.csv``) are not "the same file" either.

A CSV that was still growing (``status = 'partial'``, ``bytes_consumed < size_bytes``)
is resumed when a longer file arrives whose first ``size_bytes`` bytes hash to that
row's ``source_sha256``: appending keeps the old content as a prefix, so the prefix
hash identifies it without storing anything extra.
Ingest then starts at the old ``bytes_consumed`` (the first line not yet landed), with
the logger clock where that row left it (``clock_latest_utc``, ``clock_step_line``,
``clock_step_s``; :mod:`.clock`): a clock step back the old part ended inside goes on.
A landed CSV (it ended with a whole line) that grows later under the same path is
resumed the same way after all it held, so its rows are not read again (its rejects
not quarantined twice); a landed content under another name is not looked for, so a
new file of a backfill keeps reading while it is hashed.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
from dataclasses import dataclass
from pathlib import Path

import duckdb

from pipelines.ingest.clock import ClockState
from pipelines.ingest.report import FileResult

__all__ = [
    "Earlier",
    "Resume",
    "file_digests",
    "find_earlier",
    "forget",
    "record",
    "record_alias",
    "resume_candidates",
    "size_seen",
]

_BLOCK = 8 << 20


@dataclass(frozen=True)
class Earlier:
    """A manifest row for the same content."""

    path: str
    format: str
    status: str
    message: str | None


@dataclass(frozen=True)
class Resume:
    """An earlier version of a growing file (partial, or landed whole): where to pick up."""

    sha256: str
    size_bytes: int
    bytes_consumed: int
    clock_latest_utc: dt.datetime | None = None
    clock_step_line: int | None = None
    clock_step_s: float | None = None

    @property
    def clock(self) -> ClockState | None:
        """The clock state the earlier version's reading ended with; None where its row
        has none (ingested before the manifest kept it)."""
        if self.clock_latest_utc is None:
            return None
        return ClockState.carried(self.clock_latest_utc, self.clock_step_line, self.clock_step_s)


def find_earlier(con: duckdb.DuckDBPyConnection, sha256: str) -> Earlier | None:
    rows = con.execute(
        "SELECT source_path, format, status, message FROM manifest WHERE source_sha256 = ?",
        [sha256],
    ).fetchall()
    return Earlier(*rows[0]) if rows else None


def forget(con: duckdb.DuckDBPyConnection, sha256: str) -> None:
    """Delete the manifest row of ``sha256`` (a refusal about to be replaced)."""
    con.execute("DELETE FROM manifest WHERE source_sha256 = ?", [sha256])


#: The manifest's columns of a :class:`Resume`, in its fields' order.
_RESUME_COLUMNS = (
    "source_sha256, size_bytes, bytes_consumed, clock_latest_utc, clock_step_line, clock_step_s"
)


def partial_resume(con: duckdb.DuckDBPyConnection, sha256: str) -> Resume | None:
    """Where the ``partial`` CSV row of ``sha256`` stopped: the same bytes read on, now
    that the file is said to be finished (``ingest --complete``); None if there is none."""
    rows = con.execute(
        f"SELECT {_RESUME_COLUMNS} FROM manifest WHERE source_sha256 = ? AND format = 'csv' "
        "AND status = 'partial' AND bytes_consumed IS NOT NULL",
        [sha256],
    ).fetchall()
    return Resume(*rows[0]) if rows else None


def with_earlier_counts(con: duckdb.DuckDBPyConnection, result: FileResult) -> FileResult:
    """``result`` (the rest of a file read on from its ``partial`` row) with that row's
    accounting added: the manifest's one row of the content counts the whole file."""
    (row,) = con.execute(
        "SELECT rows_read, rows_landed, rows_quarantined, rows_duplicate, "
        "quarantined_by_reason, time_start_utc, time_end_utc FROM manifest "
        "WHERE source_sha256 = ?",
        [result.sha256],
    ).fetchall()
    read, landed, quarantined, duplicate, reasons, start, end = row
    merged = dict(reasons or {})
    for reason, count in result.quarantined_by_reason.items():
        merged[reason] = merged.get(reason, 0) + count
    times = [t for t in (start, result.time_start_utc) if t is not None]
    ends = [t for t in (end, result.time_end_utc) if t is not None]
    return dataclasses.replace(
        result,
        rows_read=read + result.rows_read,
        rows_landed=landed + result.rows_landed,
        rows_quarantined=quarantined + result.rows_quarantined,
        rows_duplicate=duplicate + result.rows_duplicate,
        quarantined_by_reason=merged,
        time_start_utc=min(times) if times else None,
        time_end_utc=max(ends) if ends else None,
    )


def size_seen(con: duckdb.DuckDBPyConnection, size: int) -> bool:
    """Whether any manifest row has this size (same content implies same size)."""
    rows = con.execute("SELECT 1 FROM manifest WHERE size_bytes = ? LIMIT 1", [size]).fetchall()
    return bool(rows)


def resume_candidates(
    con: duckdb.DuckDBPyConnection, *, max_size: int, path: Path | None = None
) -> list[Resume]:
    """CSV manifest rows that a file of ``max_size`` bytes could extend: the partial ones,
    and the landed ones of the same ``path`` (module docstring)."""
    rows = con.execute(
        f"SELECT {_RESUME_COLUMNS} FROM manifest "
        "WHERE format = 'csv' AND bytes_consumed IS NOT NULL AND size_bytes < ? AND ("
        "(status = 'partial' AND bytes_consumed < size_bytes) OR "
        "(status = 'landed' AND bytes_consumed = size_bytes AND source_path = ?)) "
        "ORDER BY size_bytes",
        [max_size, None if path is None else str(path)],
    ).fetchall()
    return [Resume(*row) for row in rows]


def file_digests(path: Path, prefixes: list[int]) -> tuple[str, dict[int, str]]:
    """sha256 of the whole file and of its first ``n`` bytes for each ``n`` in ``prefixes``."""
    digest = hashlib.sha256()
    wanted = sorted(set(prefixes))
    found: dict[int, str] = {}
    position = 0
    with path.open("rb") as handle:
        while block := handle.read(_BLOCK):
            start = 0
            while wanted and wanted[0] <= position + len(block):
                cut = wanted.pop(0) - position
                digest.update(block[start:cut])
                found[position + cut] = digest.copy().hexdigest()
                start = cut
            digest.update(block[start:])
            position += len(block)
    return digest.hexdigest(), found


def record_alias(con: duckdb.DuckDBPyConnection, result: FileResult) -> None:
    """Record a skipped file's (path, size) as another path of content the manifest
    holds (``manifest_aliases``): the nightly's new-file test (:func:`pipelines.hoists.
    known_files`) then knows it, and does not read and hash it again every night."""
    con.execute(
        "INSERT OR REPLACE INTO manifest_aliases VALUES (?, ?, ?, ?)",
        [str(result.path), result.size_bytes, result.sha256, dt.datetime.now(dt.UTC)],
    )


def record(con: duckdb.DuckDBPyConnection, result: FileResult) -> None:
    """Insert the manifest row of ``result`` (not for ``skipped``)."""
    reasons = result.quarantined_by_reason
    con.execute(
        "INSERT INTO manifest VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
        "MAP(?::VARCHAR[], ?::BIGINT[]), ?, ?, ?, ?, ?, ?, ?, ?)",
        [
            result.sha256,
            str(result.path),
            result.format,
            result.size_bytes,
            result.bytes_consumed,
            result.site,
            result.hoist,
            result.rows_read,
            result.rows_landed,
            result.rows_quarantined,
            result.rows_duplicate,
            list(reasons),
            list(reasons.values()),
            result.time_start_utc,
            result.time_end_utc,
            result.status,
            result.message or None,
            dt.datetime.now(dt.UTC),
            result.clock.latest_utc if result.clock is not None else None,
            result.clock.step_line if result.clock is not None else None,
            result.clock.step_s if result.clock is not None else None,
        ],
    )
