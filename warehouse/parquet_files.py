"""Atomic Parquet files: what a reader can see is always a whole file or none.

Used by ingest for the lake tables and by the warehouse for compensated samples: the
file is written to a hidden temporary name in the target folder, fsynced, and renamed
over the target; the folder is fsynced after the rename.

The temporary name is ``.<target stem>.<pid>.tmp`` (hidden: the ``*.parquet`` globs of
readers never match it). A writer that raises removes its own; one that is killed
cannot, so :func:`remove_stale_temporaries` removes those whose writer is gone -- the
pid is dead, or now names a process started after the file was last written (a
reused pid) -- and leaves a live writer's alone. The warehouse lock runs it over the
lake after a writer died holding the lock (:func:`warehouse.store.open_writer`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from functools import cache
from pathlib import Path

import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq

__all__ = [
    "SORTED_COLUMNS",
    "remove_stale_temporaries",
    "temporary_path",
    "write_parquet_atomic",
    "writer_alive",
]

_ROW_GROUP_ROWS = 256 * 1024
#: Lake columns that are sorted or nearly so in every file (each file is sorted by time;
#: a part's source lines rise with it): stored DELTA_BINARY_PACKED by default.
SORTED_COLUMNS = ("time_utc", "source_line")
_TEMPORARY = re.compile(r"^\..+\.(\d+)\.tmp$")


def temporary_path(target: Path, pid: int | None = None) -> Path:
    """The hidden temporary file a writer ``pid`` (default: this process) writes ``target`` to."""
    return target.with_name(f".{target.stem}.{os.getpid() if pid is None else pid}.tmp")


@cache
def _boot_time_s() -> float:
    with Path("/proc/stat").open(encoding="ascii") as handle:
        for line in handle:
            if line.startswith("btime "):
                return float(line.split()[1])
    raise OSError("no btime in /proc/stat")


def _process_start_s(pid: int) -> float | None:
    """Start time of process ``pid`` [s since the epoch]; None if unknown (not Linux)."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text(encoding="ascii", errors="replace")
        fields = text.rsplit(")", 1)[1].split()
        return _boot_time_s() + int(fields[19]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


def writer_alive(pid: int, written_s: float) -> bool:
    """Whether the process that wrote a file at ``written_s`` (epoch s) as ``pid`` still runs.

    False when no process has that pid, or when the process with it started after the
    file was written (the pid was reused; 2 s of slack for clock ticks).
    """
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # exists, another user's
    started = _process_start_s(pid)
    return started is None or started <= written_s + 2.0


def remove_stale_temporaries(folder: Path) -> list[Path]:
    """Remove the temporary files of dead writers below ``folder`` (recursively).

    Only names of the form ``.<stem>.<pid>.tmp`` (:func:`temporary_path`) whose writer
    is gone (:func:`writer_alive`); a live writer's file is left alone. Folders directly
    in ``folder`` may be symlinks (a lake table on another disk); deeper ones are not
    followed. Returns the files removed.
    """
    removed = []
    tops = [folder] + [p for p in folder.iterdir() if p.is_symlink() and p.is_dir()]
    walks = (os.walk(top) for top in tops)
    for directory, _, names in (entry for walk in walks for entry in walk):
        for name in names:
            match = _TEMPORARY.match(name)
            if match is None:
                continue
            path = Path(directory, name)
            try:
                written = path.stat().st_mtime
            except FileNotFoundError:
                continue
            if not writer_alive(int(match.group(1)), written):
                path.unlink(missing_ok=True)
                removed.append(path)
    return removed


def write_parquet_atomic(
    frame: pl.DataFrame,
    target: Path,
    schema: pa.Schema,
    *,
    delta: Sequence[str] | None = None,
) -> None:
    """Write ``frame`` as ``target`` (zstd, ``schema``) via temp file, fsync, ``os.replace``.

    ``delta``: integer or timestamp columns (sorted or nearly so: time, source line) to
    store with DELTA_BINARY_PACKED instead of trying a dictionary first, which for
    all-distinct values only costs time (a third less CPU and size for a field batch;
    for a 100 Hz day of rope tensions the time column is written in 0.05 s instead of
    0.66 s, and takes 0.1 MB instead of 34 MB). Default: the ``SORTED_COLUMNS`` of
    ``schema``.

    Floating-point columns are stored BYTE_STREAM_SPLIT (no dictionary attempt): the
    bytes of equal significance side by side, which zstd compresses far better than
    interleaved noisy mantissas -- for a 100 Hz day of rope tensions about 2x faster
    to write and 30 % smaller than a dictionary attempt falling back to PLAIN. Lossless.
    """
    if delta is None:
        delta = [name for name in SORTED_COLUMNS if name in schema.names]
    target.parent.mkdir(parents=True, exist_ok=True)
    table = frame.to_arrow().cast(schema)
    temporary = temporary_path(target)
    floats = [f.name for f in schema if pa.types.is_floating(f.type) and f.name not in delta]
    encoding: dict = {
        "use_dictionary": [n for n in schema.names if n not in delta and n not in floats],
        "use_byte_stream_split": floats,
    }
    if delta:
        encoding["column_encoding"] = dict.fromkeys(delta, "DELTA_BINARY_PACKED")
    try:
        with temporary.open("wb") as handle:
            pq.write_table(
                table,
                handle,
                compression="zstd",
                compression_level=1,
                row_group_size=_ROW_GROUP_ROWS,
                **encoding,
            )
            handle.flush()
            os.fsync(handle.fileno())
        temporary.replace(target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    directory = os.open(target.parent, os.O_RDONLY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)
