"""``ingest_paths``: files in, lake partitions + manifest + quarantine out.

For each file, in one serialised warehouse writer (:func:`warehouse.store.open_writer`,
published every ``commit_every`` files):

0. A 0-byte file is refused (it has no header), whatever its format.
1. sha256 of the content; already in the manifest as a landed or partial file of the
   same format -> ``skipped`` (no-op, even renamed). A refused content, or the same
   bytes under another format, is read again: a refusal is said every time, and the
   manifest row is replaced by the new outcome. A CSV whose size no manifest row has
   (so certainly new) is opened and its first batch read while the hash runs on a
   thread.
2. An earlier version that this file extends (partial, or landed under the same path)
   -> resume after its ``bytes_consumed`` (:mod:`.manifest`), in the place of a
   daylight-saving change's repeated hour that version ended in
   (:func:`.field_csv.prefix_ambiguity`), with the logger clock where it left it (a
   clock step back it ended inside goes on: :mod:`.clock`, kept in the manifest).
3. The format's reader yields batches (:mod:`.field_csv`, :mod:`.field_tdms`,
   :mod:`.rig_mcap`); rejected rows go to ``quarantine``, samples are landed with dedup
   (:mod:`.landing`), conflicts quarantined. Batch N lands on a worker thread while
   batch N+1 is read (one batch in flight; see :func:`_land_all`).
4. One manifest row with the accounting; the lake parts of the file are on disk before
   its manifest row is published. A CSV with a header and a column line but no data
   rows lands 0 rows (status ``landed``, a note says so): an empty export is not an
   error.

Crash in the middle: the lake may hold part of a file whose manifest row was never
published. Re-ingesting it lands nothing twice, and the rows the crashed attempt left
are counted as landed by the file (:mod:`.landing`: the same rows of the same
``source_sha256``), not as duplicates.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import itertools
import logging
from collections import Counter
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import duckdb
import polars as pl
from polars.exceptions import PanicException

from pipelines.exits import received_signal
from pipelines.ingest.batch import Batch, Reading, RefusedFile
from pipelines.ingest.csv_scan import warm_up_in_background
from pipelines.ingest.field_checks import REASON_CONFLICT, ForeignHoistError, HoistLookup
from pipelines.ingest.field_csv import DEFAULT_BATCH_BYTES, open_csv
from pipelines.ingest.landing import LakeTable, Landed
from pipelines.ingest.manifest import (
    Earlier,
    file_digests,
    find_earlier,
    forget,
    partial_resume,
    record,
    record_alias,
    resume_candidates,
    size_seen,
    with_earlier_counts,
)
from pipelines.ingest.quarantine import insert_quarantine
from pipelines.ingest.report import FileResult, IngestReport
from pipelines.ingest.sources import detect_format, expand_paths
from schemas.names import undecodable
from warehouse.store import DataRoot, open_writer

__all__ = ["ingest_paths"]

_EMPTY_SHA256 = hashlib.sha256(b"").hexdigest()

logger = logging.getLogger(__name__)


def ingest_paths(
    paths: Sequence[str | Path],
    *,
    data: DataRoot,
    hoist_lookup: HoistLookup | None = None,
    batch_bytes: int = DEFAULT_BATCH_BYTES,
    commit_every: int = 20,
    complete: bool = False,
) -> IngestReport:
    """Ingest files and folders (CSV, TDMS, MCAP in any mix) into ``data``.

    ``complete``: the CSV files are finished exports: a last line without a line end is
    their last row, not a line still being written (held back, the file ``partial``
    until it grows). A file an earlier ingest left ``partial`` that has not grown since
    is then read on from where it stopped.

    ``hoist_lookup(site, hoist)`` may return the hoist description of a field log, used
    for the depth-in-shaft check (:func:`.field_checks.hoist_lookup_from_files`); a file
    whose hoist it does not know says so in its message. Refused files are reported (and
    recorded in the manifest), not raised; check ``report.ok`` and
    ``report.refusal_lines()``.
    """
    files = expand_paths(paths)
    report = IngestReport()
    for start in range(0, len(files), max(commit_every, 1)):
        with open_writer(data) as con:
            lakes: dict[str, LakeTable] = {}
            for path in files[start : start + max(commit_every, 1)]:
                result, earlier = _ingest_file(
                    path, con, data, lakes, hoist_lookup, batch_bytes, complete
                )
                if result.status != "skipped" and result.sha256:
                    _record(con, result, earlier)
                elif earlier is not None and earlier.path != str(path):
                    record_alias(con, result)  # the same content under another path
                report.files.append(result)
                _log_file(result)
    return report


def _log_file(result: FileResult) -> None:
    """What became of one file (a refusal: also the command's stderr line)."""
    level = logging.DEBUG if result.status == "skipped" else logging.INFO
    logger.log(
        level,
        "%s %s: %d rows read, %d landed, %d quarantined, %d duplicates%s",
        result.status,
        result.shown_path,
        result.rows_read,
        result.rows_landed,
        result.rows_quarantined,
        result.rows_duplicate,
        f" ({result.reason})" if result.message else "",
    )


def _record(con: duckdb.DuckDBPyConnection, result: FileResult, earlier: Earlier | None) -> None:
    """The manifest row of ``result``, replacing an earlier refusal of the same content."""
    if earlier is not None:
        finished = earlier.status == "partial" and earlier.format == result.format
        if earlier.status != "refused" and not finished:
            # the same bytes were landed as another format (one row per content): keep
            # that row; this file's outcome is in the report only
            note = (
                f"not recorded in the manifest: the same bytes are recorded as the "
                f"{earlier.format} file {earlier.path} ({earlier.status})"
            )
            result.message = "; ".join(m for m in (result.message, note) if m)
            return
        if finished:  # read on from its partial row: one row counts the whole file
            result = with_earlier_counts(con, result)
        forget(con, result.sha256)
    record(con, result)


def _ingest_file(
    path: Path,
    con: duckdb.DuckDBPyConnection,
    data: DataRoot,
    lakes: dict[str, LakeTable],
    hoist_lookup: HoistLookup | None,
    batch_bytes: int,
    complete: bool = False,
) -> tuple[FileResult, Earlier | None]:
    """The outcome of one file, and the manifest row of its content if there was one."""
    if not path.is_file():
        what = "not a regular file" if path.exists() else "no such file"
        return FileResult(path, "", "unknown", "refused", message=f"{path}: {what}"), None
    undecodable = _undecodable_name(path)
    if undecodable is not None:
        # not recorded (no sha256): the manifest holds paths as UTF-8 text
        result = FileResult(
            path, "", detect_format(path), "refused", size_bytes=path.stat().st_size
        )
        result.message = f"{result.shown_path}: {undecodable}"
        return result, None
    size = path.stat().st_size
    fmt = detect_format(path)
    if size == 0:
        result = FileResult(path, _EMPTY_SHA256, fmt, "refused")
        result.message = f"{path}: empty file (0 bytes): no header, no data"
        return result, find_earlier(con, _EMPTY_SHA256)
    notes: list[str] = []
    if hoist_lookup is not None:
        hoist_lookup = _noting_misses(hoist_lookup, notes, path)
    if fmt == "csv":
        warm_up_in_background()
    candidates = resume_candidates(con, max_size=size, path=path) if fmt == "csv" else []
    started: _Started | None = None
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="ropeload-hash") as hasher:
        digests = hasher.submit(file_digests, path, [c.size_bytes for c in candidates])
        if fmt == "csv" and not candidates and not size_seen(con, size):
            # certainly new content (no manifest row of this size) and no earlier
            # partial version to resume from: read the header and the first batch
            # while the file is hashed
            started = _start_csv(path, hoist_lookup, batch_bytes, complete)
        sha256, prefixes = digests.result()
    result = FileResult(path, sha256, fmt, "landed", size_bytes=size)
    earlier = find_earlier(con, sha256)
    resume = None
    if complete and earlier is not None and earlier.status == "partial" and fmt == "csv":
        resume = partial_resume(con, sha256)  # the same bytes, now said to be finished
    if (
        earlier is not None
        and earlier.status != "refused"
        and earlier.format == fmt
        and resume is None
    ):
        if started is not None:
            started.close()
        result.status = "skipped"
        same = "this name" if earlier.path == str(path) else earlier.path
        result.message = f"already ingested ({earlier.status}) as {same}; nothing to do"
        return result, earlier
    if resume is None:  # an earlier, shorter version this file extends
        for candidate in reversed(candidates):  # the longest prefix first
            if prefixes.get(candidate.size_bytes) == candidate.sha256:
                resume = candidate
                break
    try:
        if started is not None:
            reading = started.reading_or_raise()
        else:
            reading = _open(path, fmt, hoist_lookup, batch_bytes, resume, notes, complete)
        result.site, result.hoist = reading.site, reading.hoist
        _land_all(reading, result, con, data, lakes)
    except RefusedFile as exc:
        result.status = "refused"
        result.message = str(exc)
        return result, earlier
    except (OSError, duckdb.Error):
        raise  # the data root's own trouble (disk, warehouse): not this file's
    except (Exception, PanicException) as exc:  # a reader's parse error the checks did
        # not foresee (a bug too; a panic in polars' Rust is a BaseException, caught by
        # name so that a cancellation's signal still ends the run): this file's
        if received_signal() is not None:  # a signal a library wrapped: the command's end
            raise
        logger.debug("reading %s failed", path, exc_info=True)
        first = (str(exc).splitlines() or [""])[0][:200]
        what = f"{path}: unreadable ({type(exc).__name__}: {first})"
        # refused, so that the next ingest tries it again (what landed before the error
        # stays landed and counted, and is then counted as this file's when it is
        # read again: :mod:`.landing`)
        result.status = "refused"
        result.message = what + (
            f"; stopped after {result.rows_read} rows" if result.rows_read else ""
        )
        return result, earlier
    notes[:0] = reading.notes
    result.bytes_consumed = reading.bytes_consumed
    result.clock = reading.clock
    if reading.partial:
        result.status = "partial"
        notes.append(f"partial: {reading.partial}")
    elif result.rows_read == 0 and resume is None and fmt == "csv":
        notes.insert(0, "no data rows (header and column line only): 0 rows landed")
    result.message = "; ".join(notes)
    return result, earlier


def _undecodable_name(path: Path) -> str | None:
    """Why ``path`` cannot be stored as text (a file name's bytes that are not UTF-8,
    which Python keeps as lone surrogates: ``b'k\\xff.csv'``), or None."""
    what = undecodable(str(path))
    if what is None:
        return None
    return f"the file name is not UTF-8 text ({what}); rename the file to ingest it"


def _noting_misses(lookup: HoistLookup, notes: list[str], path: Path) -> HoistLookup:
    """``lookup`` that adds a note when it has no description for a file's hoist, and
    refuses the file (naming it) where the lookup says it belongs to no hoist expected
    here (:class:`.field_checks.ForeignHoistError`)."""

    def noting(site: str, hoist: str):
        try:
            found = lookup(site, hoist)
        except ForeignHoistError as exc:
            raise RefusedFile(f"{path}: {exc}") from None
        if found is None:
            notes.append(
                f"no hoist description for {site}/{hoist}: depth checked against the "
                "pithead only, not the shaft"
            )
        return found

    return noting


@dataclass
class _Started:
    """A CSV opened (and its first batch read) while the file was being hashed."""

    reading: Reading | None = None
    first: Batch | None = None
    #: what opening it raised, raised again inside the file's guard (:func:`_ingest_file`):
    #: a refusal, or a reader's error that refuses this file alone, as it would unstarted
    refusal: BaseException | None = None

    def reading_or_raise(self) -> Reading:
        if self.refusal is not None:
            raise self.refusal
        assert self.reading is not None
        if self.first is not None:
            self.reading.batches = itertools.chain([self.first], self.reading.batches)
        return self.reading

    def close(self) -> None:
        if self.reading is not None:
            close = getattr(self.reading.batches, "close", None)
            if close is not None:
                close()


def _start_csv(
    path: Path, hoist_lookup: HoistLookup | None, batch_bytes: int, complete: bool = False
) -> _Started:
    try:
        reading = open_csv(
            path, hoist_lookup=hoist_lookup, batch_bytes=batch_bytes, complete=complete
        )
        return _Started(reading, next(reading.batches, None))
    except (Exception, PanicException) as exc:  # judged inside the file's guard
        return _Started(refusal=exc)


def _open(
    path: Path,
    fmt: str,
    hoist_lookup: HoistLookup | None,
    batch_bytes: int,
    resume,
    notes: list[str],
    complete: bool = False,
) -> Reading:
    if fmt == "csv":
        if resume is not None:
            start = resume.bytes_consumed
            with path.open("rb") as handle:
                line = 1 + _count_newlines(handle, start)
                handle.seek(max(start - 1, 0))
                if start > 0 and handle.read(1) != b"\n":
                    # the earlier version ended without a line end and its last line was
                    # read as a row (ingest --complete): what follows up to the next line
                    # end continues that row, landed already
                    tail = _through_line_end(handle)
                    notes.append(
                        f"bytes {start}-{start + tail} continue line {line}, which an "
                        "ingest --complete read as the file's last row: not read again"
                    )
                    start, line = start + tail, line + 1
            notes.append(
                f"resumed at byte {start} (line {line}) after the earlier "
                f"version {resume.sha256[:12]}"
            )
            return open_csv(
                path,
                hoist_lookup=hoist_lookup,
                start_offset=start,
                start_line=line,
                batch_bytes=batch_bytes,
                start_clock=resume.clock,
                complete=complete,
            )
        return open_csv(path, hoist_lookup=hoist_lookup, batch_bytes=batch_bytes, complete=complete)
    if fmt == "tdms":
        from pipelines.ingest.field_tdms import open_tdms

        return open_tdms(path, hoist_lookup=hoist_lookup)
    from pipelines.ingest.rig_mcap import open_mcap

    return open_mcap(path)


def _through_line_end(handle) -> int:
    """Bytes from the handle's position through the next newline (to the end if none)."""
    count = 0
    while block := handle.read(1 << 16):
        found = block.find(b"\n")
        if found >= 0:
            return count + found + 1
        count += len(block)
    return count


def _count_newlines(handle, limit: int) -> int:
    count, remaining = 0, limit
    while remaining > 0:
        block = handle.read(min(remaining, 8 << 20))
        if not block:
            break
        count += block.count(b"\n")
        remaining -= len(block)
    return count


def _land_all(
    reading: Reading,
    result: FileResult,
    con: duckdb.DuckDBPyConnection,
    data: DataRoot,
    lakes: dict[str, LakeTable],
) -> None:
    """Land the batches of ``reading``: batch N lands while batch N+1 is being read.

    Landing (dedup, Parquet write, fsync) runs on one worker thread, parsing on this
    one (polars, pyarrow, numba and the fsync release the GIL). At most one batch is in
    flight and the next one is handed over only after it has landed, so dedup sees
    every earlier part; the warehouse connection is used from this thread only.
    """
    lake = lakes.get(reading.table)
    if lake is None:
        lake = lakes[reading.table] = LakeTable(data, reading.table)
    reasons: Counter[str] = Counter()
    has_lines = result.format == "csv"

    def land(batch: Batch) -> tuple[Landed, pl.DataFrame | None]:
        """Land the samples, then sort the held rows: exact duplicates of landed samples
        (counted so) or quarantined with their reason (the rows returned)."""
        landed = lake.land(
            batch.samples, site=reading.site, hoist=reading.hoist, source_sha256=result.sha256
        )
        held = batch.held
        if held is None or held.height == 0:
            return landed, None
        same = lake.landed_duplicates(held.drop("_reason"), site=reading.site, hoist=reading.hoist)
        landed.duplicate += len(same)
        return landed, held.filter(~pl.col("_row").is_in(same))

    def account(batch: Batch, landing: Future[tuple[Landed, pl.DataFrame | None]]) -> None:
        landed, held = landing.result()
        rejected = batch.rejected
        auxiliary = _auxiliary(rejected)  # quarantined, but not rows: neither read nor held
        result.rows_read += batch.rows_read - auxiliary
        if held is not None and held.height:
            rows = held["_row"].to_list()
            stepped = pl.DataFrame(
                {"row": rows, "topic": None, "reason": held["_reason"], "raw": batch.raw_of(rows)},
                schema=rejected.schema,
            )
            rejected = pl.concat([rejected, stepped])
        if landed.conflicts:
            conflicts = pl.DataFrame(
                {
                    "row": landed.conflicts,
                    "topic": None,
                    "reason": REASON_CONFLICT,
                    "raw": batch.raw_of(landed.conflicts),
                },
                schema=rejected.schema,
            )
            rejected = pl.concat([rejected, conflicts])
        insert_quarantine(
            con, rejected, source_sha256=result.sha256, source_path=result.path, has_lines=has_lines
        )
        reasons.update(dict(rejected.group_by("reason").len().iter_rows()))
        result.rows_landed += landed.landed
        result.rows_duplicate += landed.duplicate
        result.rows_quarantined += rejected.height - auxiliary
        if batch.samples.height:
            low, high = batch.samples["time_utc"].min(), batch.samples["time_utc"].max()
            assert isinstance(low, dt.datetime)
            assert isinstance(high, dt.datetime)
            result.time_start_utc = min(low, result.time_start_utc or low)
            result.time_end_utc = max(high, result.time_end_utc or high)

    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="ropeload-land") as worker:
        pending: tuple[Batch, Future[tuple[Landed, pl.DataFrame | None]]] | None = None
        try:
            for batch in reading.batches:
                if pending is not None:
                    landing, pending = pending, None
                    account(*landing)
                pending = (batch, worker.submit(land, batch))
        finally:
            if pending is not None:  # also when reading failed: the landed part counts
                account(*pending)
    result.quarantined_by_reason = dict(sorted(reasons.items()))


def _auxiliary(rejected: pl.DataFrame) -> int:
    """Rejected MCAP messages of topics other than /rig/pressure: quarantined, not rows."""
    if rejected.height == 0:
        return 0
    return rejected.filter(
        pl.col("topic").is_not_null() & (pl.col("topic") != "/rig/pressure")
    ).height
