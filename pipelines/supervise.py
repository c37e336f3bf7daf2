"""Failures a process cannot report itself: memory exhaustion, and children that outlive it.

Measured on a 2-core machine (2026-11): ``ropeload demo`` maps 5.3-5.8 GiB of address
space for 1.1 GiB resident (thread arenas of glibc, Arrow's jemalloc pool, polars and
numba reservations), so under ``ulimit -v 4000000`` it dies in polars' Rust allocator:
``memory allocation of N bytes failed``, a backtrace, SIGABRT, exit 134. Lower limits
fail at import (``ImportError: ... failed to map segment from shared object``) or with a
``SystemError`` from C code that could not allocate. A cgroup memory limit ends in the
kernel's SIGKILL. None of these can be caught in the dying process.

So when a memory limit is set (:func:`pipelines.exits.memory_limit`), or the command
starts servers
and worker processes (Prefect's temporary server, a Dask ``LocalCluster``), the CLI
runs the command in a forked child and this process stays as its supervisor
(:func:`run_supervised`):

- it becomes a child subreaper: whatever the child starts and leaves behind (the
  Prefect server, Dask workers) is re-parented to it, and is terminated (SIGTERM, then
  SIGKILL after a grace period) when the child has ended, however it ended;
- the child gets SIGTERM when the supervisor dies (``PR_SET_PDEATHSIG``), even by
  SIGKILL, and SIGTERM ends a command cleanly
  (:func:`~pipelines.exits.terminate_on_signals`: Prefect stops its server at exit, the
  flow closes its cluster, writers remove their temporary files); SIGTERM, SIGHUP and
  SIGINT sent to the supervisor are passed on;
- under a memory limit it reads the child's stderr (a pseudo-terminal when stderr is
  one) and passes it through until the allocator's dying words, which it swallows; a
  death by SIGABRT under an address-space limit, or by SIGKILL with the cgroup's OOM
  counter raised, becomes the one line of :func:`~pipelines.exits.out_of_memory`.

A normal command (no limit, no ``--prefect``/``--dask``) does not fork, nor import this
module: its start-up cost is a ``getrlimit`` and two small reads under ``/proc``.
"""

from __future__ import annotations

import contextlib
import os
import re
import select
import signal
import sys
import time
from pathlib import Path
from types import FrameType

from pipelines.exits import MemoryLimit, out_of_memory

__all__ = ["can_supervise", "end_children", "run_supervised"]

_PR_SET_PDEATHSIG = 1
_PR_SET_CHILD_SUBREAPER = 36
#: What a starving allocator or loader writes before it aborts (Rust's std, C++'s
#: terminate handler, glibc's loader, glibc's thread exit), measured under ``ulimit -v``
#: (the last in session 32: the demo at 1.8 GB, once in a clone's suite).
_DYING_WORDS = (
    b"memory allocation of ",
    b"std::bad_alloc",
    b"cannot allocate memory for thread-local data",
    b"Fatal glibc error: failed to register TLS destructor: out of memory",
)
#: A Rust thread's panic at the start of a line whose next line says the process is
#: starved (a thread that could not be spawned under ``ulimit -v``, measured: polars'
#: executor panics on ``Os { code: 11, kind: WouldBlock, message: "Resource temporarily
#: unavailable" }``, after a blank line, before the allocator's own words): dying words
#: from the panic's line on (from the blank line before it, if any). Until its next line
#: has ended, a panic's line is held.
_PANIC_AT = re.compile(rb"thread '[^'\n]*'[^\n]* panicked at ")
_PANIC_START = b"thread '"
_STARVED = (
    b"kind: WouldBlock",
    b"kind: OutOfMemory",
    b"Resource temporarily unavailable",
    b"Cannot allocate memory",
)
#: What a starving allocator writes and goes on (a line each time).
_NOISE = (b"<jemalloc>: ",)
_GRACE_S = 5.0


def _dying_words_at(data: bytes) -> int:
    """Where the first of :data:`_DYING_WORDS` starts in ``data``; -1 for none."""
    return min((i for w in _DYING_WORDS if (i := data.find(w)) >= 0), default=-1)


def _prctl(option: int, value: int) -> bool:
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(option, value, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _single_threaded() -> bool:
    try:
        with Path("/proc/self/status").open(encoding="ascii") as handle:
            for line in handle:
                if line.startswith("Threads:"):
                    return int(line.split()[1]) == 1
    except OSError:
        pass
    return False


def can_supervise() -> bool:
    """Whether forking here is safe and useful: Linux, one thread (nothing heavy loaded yet)."""
    return sys.platform.startswith("linux") and _single_threaded()


def _oom_kills(limit: MemoryLimit | None) -> int:
    if limit is None or limit.counts_mappings:
        return 0
    events = Path(limit.how).with_name("memory.events")
    try:
        for line in events.read_text().splitlines():
            if line.startswith("oom_kill "):
                return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 0


def _children() -> list[int]:
    """Pids whose parent is this process (reparented orphans included)."""
    me, found = os.getpid(), []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            text = (entry / "stat").read_text(encoding="ascii", errors="replace")
            fields = text.rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == me and fields[0] != "Z":
            found.append(int(entry.name))
    return found


def _reap() -> None:
    with contextlib.suppress(ChildProcessError):
        while os.waitpid(-1, os.WNOHANG)[0] > 0:
            pass


def end_children(grace_s: float = _GRACE_S) -> list[int]:
    """Terminate every child of this process (SIGTERM, SIGKILL after ``grace_s``); reap them.

    Repeated until none is left, as a dying child's own children are re-parented here
    (this process is a subreaper). Returns the pids that had to be ended.
    """
    ended: list[int] = []
    for _ in range(5):
        _reap()
        pids = _children()
        if not pids:
            break
        ended += pids
        for pid in pids:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGTERM)
        deadline = time.monotonic() + grace_s
        while time.monotonic() < deadline:
            _reap()
            if not any(pid in pids for pid in _children()):
                break
            time.sleep(0.05)
        for pid in _children():
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    _reap()
    return ended


def _stderr_channel() -> tuple[int, int]:
    """(read end, write end) for the child's stderr: a pty if stderr is a terminal."""
    if os.isatty(2):
        import fcntl
        import pty
        import termios
        import tty

        master, slave = pty.openpty()
        tty.setraw(slave)  # pass bytes as they are (no CR/LF translation)
        with contextlib.suppress(OSError):
            size = fcntl.ioctl(2, termios.TIOCGWINSZ, b"\0" * 8)
            fcntl.ioctl(slave, termios.TIOCSWINSZ, size)
        return master, slave
    return os.pipe()


class _Relay:
    """Copies the child's stderr to ours, without what starving allocators say.

    From an allocator's or loader's dying words on (:data:`_DYING_WORDS`, anywhere in a
    line, or a thread's panic that says the process is starved, :data:`_PANIC_AT`)
    nothing more is copied; lines of :data:`_NOISE` (jemalloc complaining, once
    per attempt: 400 000 lines measured under ``ulimit -v 1500000``) are dropped one by
    one. Text is copied as soon as it arrives (progress bars redraw without a newline),
    except a tail that may be the start of such words, held until it is decided.
    """

    def __init__(self, fd: int | None, said: bytes = b"") -> None:
        self.fd = fd
        self.dying = False
        self.noisy = False
        #: whether a line starting with ``said`` was copied: the child's own line that
        #: it ran out of memory (``ropeload <command>: out of memory``)
        self.said = False
        self._said = said
        self._held = b""
        self._line_start = True  # what was copied ended a line (or nothing was)

    def _filter(self, data: bytes) -> bytes:
        out = self._decide(data)
        if out:
            if self._said:  # a line of ``out`` starting with it
                text = (b"\n" if self._line_start else b"") + out
                self.said |= b"\n" + self._said in text
            self._line_start = out.endswith(b"\n")
        return out

    def _blank_before(self, data: bytes, at: int) -> int:
        """``at``, or ``at - 1`` where a blank line ends there (its newline at ``at - 1``
        follows another newline, or the start of a line already copied)."""
        if at < 1 or data[at - 1 : at] != b"\n":
            return at
        line_started = data[at - 2 : at - 1] == b"\n" if at >= 2 else self._line_start
        return at - 1 if line_started else at

    def _panic(self, data: bytes) -> tuple[int, bool | None]:
        """(where it starts, whether it is starved; None: undecided) of the first panic
        at the start of a line that is starved or undecided; (-1, False) for none."""
        for found in _PANIC_AT.finditer(data):
            at = found.start()
            if not (data[at - 1 : at] == b"\n" if at else self._line_start):
                continue  # within a line: the program's own text
            end = data.find(b"\n", at)
            after = data.find(b"\n", end + 1) if end >= 0 else -1
            following = data[end + 1 : after if after >= 0 else len(data)] if end >= 0 else b""
            if any(word in following for word in _STARVED):
                return self._blank_before(data, at), True
            if after < 0:
                return self._blank_before(data, at), None
        return -1, False

    def _decide(self, data: bytes) -> bytes:
        data, self._held = self._held + data, b""
        if self.dying:
            return b""
        cut = _dying_words_at(data)
        undecided = b""
        at, starved = self._panic(data)
        if at >= 0 and (cut < 0 or at < cut):
            if starved:
                cut = at
            else:  # its next line has not ended: the panic waits for it
                data, undecided, cut = data[:at], data[at:], -1
        if cut >= 0:
            self.dying, data = True, data[:cut]
        *lines, tail = data.split(b"\n")
        out = bytearray()
        for line in lines:
            if line.startswith(_NOISE):
                self.noisy = True
            else:
                out += line + b"\n"
        if self.dying:
            return bytes(out + tail)
        if undecided:  # data ends where the panic's line starts: no tail to hold
            self._held = undecided
            return bytes(out + tail)
        starts = (*_NOISE, _PANIC_START)
        hold = tail.startswith(starts) or any(n.startswith(tail) for n in starts if tail)
        blank = out.endswith(b"\n\n") or (out == b"\n" and self._line_start)
        if (hold or not tail) and blank:  # a panic's blank line, maybe
            out, tail, hold = out[:-1], b"\n" + tail, True
        if hold:
            self._held = tail  # decided by the rest of its line (and the next)
            return bytes(out)
        keep = max(
            (k for w in _DYING_WORDS for k in range(1, len(w)) if tail.endswith(w[:k])),
            default=0,
        )
        if keep:
            self._held, tail = tail[-keep:], tail[:-keep]
        return bytes(out + tail)

    def pump(self, timeout_s: float) -> None:
        if self.fd is None:
            time.sleep(timeout_s)
            return
        ready, _, _ = select.select([self.fd], [], [], timeout_s)
        if not ready:
            return
        try:
            chunk = os.read(self.fd, 65536)
        except OSError:  # EIO: the pty's last writer closed it
            chunk = b""
        if not chunk:
            self._close()
            return
        self._write(self._filter(chunk))

    def _write(self, data: bytes) -> None:
        if data:
            with contextlib.suppress(OSError):
                os.write(2, data)

    def _close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
        held, self._held = self._held, b""
        if self.dying or not held:
            return
        cut = _dying_words_at(held)
        if cut >= 0:
            self.dying, held = True, held[:cut]
        text = held.lstrip(b"\n")
        if text.startswith(_NOISE):  # the blank lines before it are the program's
            held = held[: len(held) - len(text)]
        self._write(held)

    def drain(self) -> None:
        """What is left once the child has ended (processes it started may hold it open)."""
        while self.fd is not None and select.select([self.fd], [], [], 0.05)[0]:
            self.pump(0.0)
        self._close()


def run_supervised(command: str, limit: MemoryLimit | None) -> int | None:
    """Fork; in the child return None (run the command), in the parent its exit status.

    The parent waits for the child (relaying its stderr under a memory limit), passes
    on SIGTERM/SIGHUP/SIGINT, ends whatever the child left running, and turns a death
    by memory exhaustion or a signal into one line on stderr.
    """
    capture = limit is not None
    read_end, write_end = _stderr_channel() if capture else (-1, -1)
    supervisor = os.getpid()
    _prctl(_PR_SET_CHILD_SUBREAPER, 1)
    oom_before = _oom_kills(limit)
    sys.stdout.flush()
    sys.stderr.flush()
    child = os.fork()
    if child == 0:
        _prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != supervisor:  # the supervisor died before the line above
            os.kill(os.getpid(), signal.SIGTERM)
        if capture:
            os.dup2(write_end, 2)
            os.close(write_end)
            os.close(read_end)
        return None

    if capture:
        os.close(write_end)
    relay = _Relay(read_end if capture else None, f"ropeload {command}: out of memory".encode())
    foreground = _in_foreground()

    def forward(signum: int, frame: FrameType | None) -> None:
        if signum == signal.SIGINT and foreground:
            return  # the terminal sent Ctrl-C to the child as well
        with contextlib.suppress(ProcessLookupError):
            os.kill(child, signum)

    for signum in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        signal.signal(signum, forward)
    if capture:
        status = None
        while status is None:
            relay.pump(0.2)
            pid, raw = os.waitpid(child, os.WNOHANG)
            status = raw if pid == child else None
        relay.drain()
    else:
        status = os.waitpid(child, 0)[1]  # a signal handler runs, then the wait resumes
    end_children()
    if os.WIFEXITED(status):
        if os.WEXITSTATUS(status) != 0 and relay.dying:  # its last words were swallowed
            if not relay.said:  # the child's own out-of-memory line, if any, is the line
                sys.stderr.write(f"ropeload {command}: {out_of_memory(command, limit)}\n")
            return 1
        return os.WEXITSTATUS(status)
    signum = os.WTERMSIG(status)
    name = signal.Signals(signum).name
    mapped = limit is not None and limit.counts_mappings
    if relay.dying or (signum == signal.SIGABRT and mapped):
        message = out_of_memory(command, limit)
    elif signum == signal.SIGKILL and _oom_kills(limit) > oom_before:
        message = out_of_memory(command, limit)
    elif mapped and signum in (signal.SIGSEGV, signal.SIGBUS):
        message = out_of_memory(command, limit, what=f"crashed ({name}), probably out of memory")
    else:
        sys.stderr.write(f"ropeload {command}: killed by {name}\n")
        return 128 + signum
    if not relay.said:  # a child that said it ran out of memory, then crashed: its line
        sys.stderr.write(f"ropeload {command}: {message}\n")
    return 1


def _in_foreground() -> bool:
    """Whether this process group owns the terminal (then Ctrl-C reaches the child too)."""
    for fd in (0, 1, 2):
        with contextlib.suppress(OSError):
            if os.isatty(fd):
                return os.tcgetpgrp(fd) == os.getpgrp()
    return False
