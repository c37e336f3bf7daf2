"""The warehouse writers' lock: an exclusive ``flock`` with a time-out and a named holder.

Writers of one data root are serialised on ``<data>/.warehouse.lock``
(:func:`warehouse.store.open_writer`). The holder writes one JSON line into the file
when it gets the lock -- its pid, host, command line and start time -- and replaces it
with ``released`` when it lets go. So

- a writer that has to wait says once on stderr who holds the lock (not when the
  holder is part of the same ropeload command, e.g. a sibling thread or Dask worker of
  one backfill), and gives up after a time-out (``ROPELOAD_LOCK_TIMEOUT`` seconds,
  default :data:`DEFAULT_LOCK_TIMEOUT_S`) with :class:`LockTimeoutError` naming the
  holder;
- a writer that finds a holder line on acquiring knows that the previous holder died
  holding the lock (killed, power cut): :attr:`WarehouseLock.previous_crashed` tells
  :func:`~warehouse.store.open_writer` to sweep the temporary files it may have left.
  An empty file (a new data root, or one locked by an older ropeload) counts as a
  crash too: the sweep is cheap and runs once.

The lock is advisory and per open file description: threads of one process that each
open the lock (as every :func:`~warehouse.store.open_writer` does) exclude each other.
"""

from __future__ import annotations

import datetime as dt
import errno
import fcntl
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType

__all__ = [
    "DEFAULT_LOCK_TIMEOUT_S",
    "INVOCATION_ENV",
    "LOCK_TIMEOUT_ENV",
    "LockTimeoutError",
    "WarehouseLock",
    "describe_holder",
    "lock_timeout_s",
    "read_holder",
]

#: Environment variable with the lock time-out in seconds (``0``: do not wait).
LOCK_TIMEOUT_ENV = "ROPELOAD_LOCK_TIMEOUT"
#: Default lock time-out [s]: a long run lands in well under this.
DEFAULT_LOCK_TIMEOUT_S = 600.0
#: Identifies one ropeload command and every process it starts (set by the CLI, and
#: inherited by Dask workers): a holder with the same value is a sibling, not a stranger.
INVOCATION_ENV = "ROPELOAD_INVOCATION"
_RELEASED = "released\n"
_POLL_S = (0.01, 0.5)  # first and longest pause between attempts
_announced: set[tuple[int, str]] = set()  # (pid, started) of holders already named


class LockTimeoutError(TimeoutError):
    """The warehouse lock stayed held by another writer for the whole time-out."""


def lock_timeout_s(value: str | None = None) -> float:
    """The lock time-out [s] from ``value`` or ``$ROPELOAD_LOCK_TIMEOUT`` (default 600).

    Raises ValueError naming the variable for anything but a number >= 0.
    """
    text = os.environ.get(LOCK_TIMEOUT_ENV) if value is None else value
    if text is None or not text.strip():
        return DEFAULT_LOCK_TIMEOUT_S
    try:
        seconds = float(text)
    except ValueError:
        seconds = -1.0
    if not seconds >= 0.0 or seconds == float("inf"):
        raise ValueError(f"{LOCK_TIMEOUT_ENV}={text!r} is not a number of seconds >= 0")
    return seconds


def _this_command() -> str:
    argv = list(sys.argv) or ["python"]
    argv[0] = Path(argv[0]).name
    return " ".join(argv)


def read_holder(path: Path) -> dict | None:
    """The holder recorded in the lock file ``path``; None if released, empty or unreadable."""
    import json

    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return None
    line = text.lstrip().split("\n", 1)[0]
    if not line.startswith("{"):
        return None
    try:
        holder = json.loads(line)
    except ValueError:
        return None
    return holder if isinstance(holder, dict) else None


def describe_holder(holder: dict | None) -> str:
    """``pid 123 on host (ropeload run --hoist h.toml, since 2026-03-01 10:00:00 UTC)``."""
    import socket

    if not holder:
        return "another process (it recorded no name)"
    host = holder.get("host")
    where = f" on {host}" if host not in (None, socket.gethostname()) else ""
    return (
        f"pid {holder.get('pid', '?')}{where} "
        f"({holder.get('command', '?')}, since {holder.get('started_utc', '?')})"
    )


class WarehouseLock:
    """Exclusive lock on ``path`` (use as a context manager, or :meth:`acquire`/:meth:`release`).

    ``timeout_s``: how long to wait for another holder (default :func:`lock_timeout_s`);
    ``on_wait``: called once with a message when the lock is held by another command
    (default: print it on stderr).
    """

    def __init__(
        self,
        path: Path,
        *,
        timeout_s: float | None = None,
        on_wait: Callable[[str], None] | None = None,
    ) -> None:
        self.path = Path(path)
        self.timeout_s = lock_timeout_s() if timeout_s is None else timeout_s
        self.on_wait = on_wait or _to_stderr
        self.previous_crashed = False
        self.acquired_at: float | None = None
        self._fd: int | None = None

    def acquire(self) -> None:
        """Take the lock, waiting up to ``timeout_s``; raise LockTimeoutError after that."""
        import json  # (here: every command imports this module, few take the lock)
        import socket

        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            self._wait(fd)
            previous = os.pread(fd, 4096, 0).decode("utf-8", errors="replace")
            self.previous_crashed = previous != _RELEASED
            self.acquired_at = time.time()
            holder = {
                "pid": os.getpid(),
                "host": socket.gethostname(),
                "command": _this_command(),
                "started_utc": dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
                "invocation": os.environ.get(INVOCATION_ENV, str(os.getpid())),
            }
            _rewrite(fd, json.dumps(holder) + "\n")
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd

    def release(self) -> None:
        """Mark the lock released and let go (idempotent)."""
        fd, self._fd = self._fd, None
        if fd is None:
            return
        try:
            _rewrite(fd, _RELEASED)
        finally:
            os.close(fd)  # closing the last descriptor drops the flock

    def _wait(self, fd: int) -> None:
        started = time.monotonic()
        deadline = started + self.timeout_s
        pause = _POLL_S[0]
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return
            except OSError as exc:
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise
            holder = read_holder(self.path)
            if time.monotonic() >= deadline:
                raise LockTimeoutError(
                    f"timed out after {self.timeout_s:g} s waiting for the warehouse lock "
                    f"{self.path}, held by {describe_holder(holder)}: let it finish, or set "
                    f"{LOCK_TIMEOUT_ENV} to wait longer"
                )
            if holder is not None or time.monotonic() - started > 1.0:
                self._announce(holder)  # (a holder may be writing its line right now)
            time.sleep(min(pause, max(deadline - time.monotonic(), 0.0)))
            pause = min(pause * 2, _POLL_S[1])

    def _announce(self, holder: dict | None) -> None:
        ours = os.environ.get(INVOCATION_ENV, str(os.getpid()))
        if holder is not None and (
            holder.get("invocation") == ours or holder.get("pid") == os.getpid()
        ):
            return  # a sibling of this command: waiting is part of its plan
        key = (holder or {}).get("pid", 0), (holder or {}).get("started_utc", "")
        if key in _announced:
            return
        _announced.add(key)
        self.on_wait(
            f"warehouse lock {self.path} is held by {describe_holder(holder)}; "
            f"waiting up to {self.timeout_s:g} s ({LOCK_TIMEOUT_ENV})"
        )

    def __enter__(self) -> WarehouseLock:
        self.acquire()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.release()


def _rewrite(fd: int, text: str) -> None:
    """Replace the file's content; a reader sees the new first line whole, or the old."""
    data = text.encode()
    os.pwrite(fd, data, 0)
    os.ftruncate(fd, len(data))


def _to_stderr(message: str) -> None:
    argv = sys.argv
    label = "ropeload"
    if len(argv) > 1 and Path(argv[0]).name.startswith("ropeload"):
        label += f" {argv[1]}"
    sys.stderr.write(f"{label}: {message}\n")
    sys.stderr.flush()
