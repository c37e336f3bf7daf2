"""How a command ends: memory limits, the one line for running out, signals that end it.

Imported by every ``ropeload`` start (:func:`pipelines.cli.main`), so it stays small;
the supervising parent of :mod:`pipelines.supervise` is imported only when it is used.

Memory exhaustion has many faces (measured under ``ulimit -v`` on a 2-core machine,
2026-11; see :mod:`pipelines.supervise`): a MemoryError, an ImportError of a library
that cannot be mapped, a SystemError or "can't start new thread" from C code, or a
death by signal that only a parent sees. :func:`memory_exhausted` recognises the
Python ones, :func:`out_of_memory` words the line.
"""

from __future__ import annotations

import contextlib
import errno
import resource
import signal
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

__all__ = [
    "MemoryLimit",
    "Terminated",
    "memory_exhausted",
    "memory_limit",
    "out_of_memory",
    "received_signal",
    "terminate_on_signals",
]

_ADVICE = {
    "run": "try a shorter period (--from/--to)",
    "discover": "try a shorter period (--from/--to)",
    "backfill": "try fewer --workers",
    "nightly": "try fewer --workers",
    "demo": "try fewer --hours",
    "ingest": "ingest fewer or smaller files at a time",
    "calibrate": "calibrate from fewer recordings at a time",
    "query": "try a narrower query",
}


@dataclass(frozen=True)
class MemoryLimit:
    """A finite memory limit on this process: what kind, how many bytes, how it is set."""

    kind: str  # "address-space", "data-segment" or "cgroup memory"
    bytes: int
    how: str  # "ulimit -v", "ulimit -d", or the cgroup file

    @property
    def counts_mappings(self) -> bool:
        """Whether mere reservations count (rlimits), not only resident memory (cgroups)."""
        return self.kind != "cgroup memory"

    def __str__(self) -> str:
        return f"{self.kind} limit {self.bytes / 2**30:.1f} GiB, {self.how}"


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived: unwinds the command like Ctrl-C (cleanups run)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _cgroup_limit() -> MemoryLimit | None:
    """The smallest finite ``memory.max`` of this process's cgroup (v2) and its parents."""
    try:
        lines = Path("/proc/self/cgroup").read_text().splitlines()
    except OSError:
        return None
    relative = next((line[3:] for line in lines if line.startswith("0::")), None)
    if relative is None:
        return None
    base = Path("/sys/fs/cgroup")
    found = None
    folder = base / relative.lstrip("/")
    while True:
        try:
            text = (folder / "memory.max").read_text().strip()
        except OSError:
            text = "max"
        if text != "max" and (found is None or int(text) < found.bytes):
            found = MemoryLimit("cgroup memory", int(text), str(folder / "memory.max"))
        if folder == base or base not in folder.parents:
            return found
        folder = folder.parent


def memory_limit() -> MemoryLimit | None:
    """The tightest finite memory limit on this process, if any.

    The soft ``RLIMIT_AS`` (``ulimit -v``) or ``RLIMIT_DATA`` (``ulimit -d``, which also
    counts private mappings since Linux 4.7), else a cgroup v2 ``memory.max``.
    """
    for kind, which, how in (
        ("address-space", resource.RLIMIT_AS, "ulimit -v"),
        ("data-segment", resource.RLIMIT_DATA, "ulimit -d"),
    ):
        soft, _ = resource.getrlimit(which)
        if soft != resource.RLIM_INFINITY:
            return MemoryLimit(kind, soft, how)
    return _cgroup_limit()


def out_of_memory(command: str, limit: MemoryLimit | None, *, what: str = "out of memory") -> str:
    """The one-line reason for a command that ran out of memory (without the prefix)."""
    advice = _ADVICE.get(command, "process less at a time")
    if limit is None:
        return f"{what}: {advice}"
    note = ""
    if limit.counts_mappings:
        note = "; ropeload maps about 6 GiB of address space even for an hour of data"
    return f"{what} ({limit}): {advice}, or raise the limit{note}"


def memory_exhausted(exc: BaseException, limit: MemoryLimit | None) -> bool:
    """Whether ``exc`` is the Python face of memory exhaustion.

    MemoryError (numpy, pyarrow's ArrowMemoryError), DuckDB's OutOfMemoryException, an
    OSError ENOMEM, an ImportError of a library that could not be mapped; under a finite
    limit also a SystemError (C code that failed to allocate and did not say so) and
    "can't start new thread" (no room for its stack), both measured under ``ulimit -v``.
    """
    if isinstance(exc, MemoryError):
        return True
    if type(exc).__name__ == "OutOfMemoryException" and type(exc).__module__ in (
        "duckdb",
        "_duckdb",
    ):  # DuckDB's (an OperationalError, not a MemoryError): seen under ulimit -v 1.8 GiB
        return True
    if isinstance(exc, OSError) and exc.errno == errno.ENOMEM:
        return True
    if isinstance(exc, ImportError):
        text = str(exc)
        return "failed to map segment" in text or "Cannot allocate memory" in text
    if limit is None:
        return False
    return isinstance(exc, SystemError) or (
        isinstance(exc, RuntimeError) and "can't start new thread" in str(exc)
    )


# ---------------------------------------------------------------------------- signals


#: The signals :func:`terminate_on_signals` turned into :class:`Terminated` since it was
#: entered: a library may wrap that exception in its own (DuckDB, inside an insert that
#: reads a Python frame, raises ``RuntimeError('Query interrupted')`` or an
#: ``InvalidInputException``), and the command must still end as interrupted.
_received: list[int] = []


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    _received.append(signum)
    raise Terminated(signum)


def received_signal() -> int | None:
    """The last signal :func:`terminate_on_signals` raised :class:`Terminated` for, or
    None: whatever exception a library made of it, the command was interrupted."""
    return _received[-1] if _received else None


@contextlib.contextmanager
def terminate_on_signals() -> Iterator[None]:
    """SIGTERM and SIGHUP raise :class:`Terminated` in the main thread while inside.

    Python's default for SIGTERM ends the process at once: no ``finally``, no
    ``atexit`` (Prefect's temporary server then outlives the command). Outside the
    main thread this does nothing.
    """
    _received.clear()  # an earlier command of this process was another
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = {s: signal.signal(s, _raise_terminated) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, handler)
