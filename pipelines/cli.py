"""The ``ropeload`` console script (contract section 6).

Every command parses its arguments (:mod:`pipelines.cli_parser`) and its handler
(:mod:`pipelines.cli_commands`) calls the same plain function that the Prefect flow of
that command wraps (``pipelines/flows.py``), so the CLI and the flows share one
implementation. This module is :func:`main`: the data-root check, supervision, and the
exit status of every outcome. Exit status: 0 on success (also when rows were quarantined),
1 with a one-line reason on stderr when an input is refused or a run fails, 2 for a
usage error.
"""

from __future__ import annotations

import argparse
import errno
import logging
import os
import signal
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from pipelines.cli_commands import RopeloadError
from pipelines.cli_parser import build_parser
from pipelines.log import configure_logging

__all__ = ["main"]


def _stdout_open() -> bool:
    """Whether stdout still has a reader: a pipe whose reader left polls as an error
    (POLLERR) on its writing end; a file, a terminal or a pipe still read do not."""
    import select

    try:
        poll = select.poll()
        poll.register(sys.stdout.fileno(), select.POLLOUT)
        events = poll.poll(0)
    except (OSError, ValueError):  # no stdout to poll
        return False
    return not any(flags & (select.POLLERR | select.POLLHUP) for _, flags in events)


def _known_errors() -> tuple[type[BaseException], ...]:
    """Errors the user can cause: their message is the one line (no traceback).

    Only evaluated when an exception reaches :func:`main`, and without importing: the
    error classes of a module are taken only if it is loaded (if it is not, it raised
    nothing), so an import under a tight memory limit cannot fail the error's own line.
    """
    known: list[type[BaseException]] = [RopeloadError, FileNotFoundError, ValueError]
    for module, name in (
        ("schemas.hoist", "HoistDescriptionError"),
        ("duckdb", "Error"),
        ("warehouse.lock", "LockTimeoutError"),
        ("pipelines.run_period", "NoSamplesError"),
        ("pipelines.nightly", "NightRunningError"),
        # the hoist's model cannot replay the record's trips (discover)
        ("discovery.selection", "ModelDoesNotSimulate"),
        # a lake file polars cannot read (damaged, not Parquet): its words, one line
        ("polars.exceptions", "ComputeError"),
    ):
        loaded = sys.modules.get(module)
        if loaded is not None:
            known.append(getattr(loaded, name))
    return tuple(known)


#: OSError numbers the user causes (permissions, full disk, a file where a folder
#: belongs, ulimit -n): one line naming the file. Others are bugs: traceback.
_USER_ERRNOS = frozenset(
    getattr(errno, name)
    for name in (
        "EACCES", "EPERM", "EROFS", "ENOSPC", "EDQUOT", "ENOTDIR", "EISDIR", "EEXIST",
        "ENAMETOOLONG", "ELOOP", "EMFILE", "ENFILE", "EFBIG",
    )
    if hasattr(errno, name)
)  # fmt: skip


def _os_error_line(exc: OSError) -> str:
    """``Permission denied: /data/.warehouse.lock`` (with the second path of a rename)."""
    reason = exc.strerror or type(exc).__name__
    paths = [str(p) for p in (exc.filename, exc.filename2) if p is not None]
    return f"{reason}: {' -> '.join(paths)}" if paths else reason


def _data_root_problem(args: argparse.Namespace) -> str | None:
    """Why the command's data root cannot be used, or None.

    A data root that exists must be a folder; a command that writes (all but ``query``,
    ``calibrate --table1`` and ``paper --out``) needs it writable, or creatable: its
    nearest existing ancestor a writable folder. (As root, permission bits do not stop writes, and
    ``os.access`` says so too; a read-only file system still does.)
    """
    if not hasattr(args, "data") or (args.command == "calibrate" and args.table1):
        return None
    if args.command == "paper" and args.out is not None:  # the data root is not used
        return None
    from schemas.names import printable
    from warehouse.store import DATA_ENV, DataRoot, data_root_problem

    path = DataRoot.resolve(args.data).path
    origin = "--data" if args.data is not None else f"${DATA_ENV}"
    if args.data is None and not os.environ.get(DATA_ENV):
        origin = "the default"
    unreadable = data_root_problem(path)
    if unreadable is not None:
        return f"data root {printable(path)} ({origin}): {unreadable}"
    writes = args.command != "query"
    existing = path
    while not os.path.lexists(existing) and existing != existing.parent:
        existing = existing.parent
    what = f"data root {path} ({origin})"
    if existing == path:
        if not path.is_dir():
            return f"{what} is {'a file, ' if path.is_file() else ''}not a folder"
        if writes and not os.access(path, os.W_OK | os.X_OK):
            return f"{what} is not writable ({_why_not_writable(path)})"
        return None
    if not existing.is_dir():
        return f"{what} cannot be created: {existing} is a file, not a folder"
    if writes and not os.access(existing, os.W_OK | os.X_OK):
        why = _why_not_writable(existing)
        return f"{what} cannot be created: {existing} is not writable ({why})"
    if writes:  # tried, and undone: a path the system refuses says so now (/proc/x:
        # writable by its bits, no folder can be made there), and a command that then
        # fails leaves no empty data root behind
        made = []
        try:
            for folder in reversed([path, *path.parents]):
                if not os.path.lexists(folder):
                    folder.mkdir()
                    made.append(folder)
        except OSError as exc:
            return f"{what} cannot be created: {exc.strerror or type(exc).__name__}"
        finally:
            for folder in reversed(made):
                folder.rmdir()
    return None


def _why_not_writable(path: Path) -> str:
    try:
        if os.statvfs(path).f_flag & os.ST_RDONLY:
            return "read-only file system"
    except OSError:
        pass
    return "permission denied"


class _UserErrorsInOneLine(logging.Filter):
    """On Prefect's flow- and task-run loggers: a run that failed on an error the user
    can cause (:func:`_known_errors`) is logged without its traceback; the command's
    own one line says why. Other errors keep theirs (a bug report)."""

    def filter(self, record: logging.LogRecord) -> bool:
        error = record.exc_info[1] if record.exc_info else None
        if error is not None and isinstance(error, _known_errors()):
            record.exc_info = None
            record.exc_text = None
        return True


def _quiet_user_errors_in_flow_logs() -> None:
    for name in ("prefect.flow_runs", "prefect.task_runs"):
        logger = logging.getLogger(name)
        if not any(isinstance(f, _UserErrorsInOneLine) for f in logger.filters):
            logger.addFilter(_UserErrorsInOneLine())


def _supervised(args: argparse.Namespace) -> bool:
    """Whether the command starts servers or worker processes (then it is supervised)."""
    return bool(getattr(args, "prefect", False) or getattr(args, "dask", None))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ropeload`` script; returns the exit status.

    Everything the user can cause ends as one line ``ropeload <command>: <reason>`` on
    stderr with status 1 (2 for usage): refused input, a data root that is a file or
    not writable, the warehouse lock timing out, memory exhaustion; SIGTERM/SIGHUP and
    Ctrl-C end the command cleanly (status 143/129/130). An unexpected internal error
    still prints its traceback: that is a bug report.

    As the console script (``argv`` None), a command under a memory limit, or one that
    starts servers and workers (``--prefect``, ``--dask``), runs in a child of this
    process (:func:`pipelines.supervise.run_supervised`), which reports the child's
    death by memory exhaustion and ends whatever it left running.
    """
    from pipelines import exits
    from warehouse.lock import INVOCATION_ENV, lock_timeout_s

    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # said by the command, as every other usage error is
        sys.stderr.write(
            f"ropeload {args.command}: unrecognized arguments: {' '.join(extra)} (see --help)\n"
        )
        return 2
    if getattr(args, "prefect", False):
        _quiet_user_errors_in_flow_logs()
    configure_logging(getattr(args, "log_level", None))  # stderr; stdout: the result
    command: str = args.command
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        lock_timeout_s()
    except ValueError as exc:
        sys.stderr.write(f"ropeload {command}: {exc}\n")
        return 2
    start, end = getattr(args, "start", None), getattr(args, "end", None)
    if command in ("run", "discover") and start is not None and end is not None:
        # --to (exclusive) not after --from: a bad value of the options, status 2
        from pipelines.run_period import check_period

        try:
            check_period(start, end)
        except ValueError as exc:
            sys.stderr.write(f"ropeload {command}: {exc}\n")
            return 2
    if command == "backfill" and end < start:  # days, --to included: a bad value, status 2
        sys.stderr.write(
            f"ropeload {command}: the range is empty: --to {end} is before --from {start}\n"
        )
        return 2
    problem = _data_root_problem(args)
    if problem is not None:
        sys.stderr.write(f"ropeload {command}: {problem}\n")
        return 1
    os.environ.setdefault(INVOCATION_ENV, f"{os.getpid()}-{time.time_ns()}")
    limit = exits.memory_limit()
    if argv is None and (limit is not None or _supervised(args)):
        from pipelines import supervise

        if supervise.can_supervise():
            status = supervise.run_supervised(command, limit)
            if status is not None:
                return status  # the supervisor; the child goes on below
    message: str
    try:
        with exits.terminate_on_signals():
            return handler(args)
    except _known_errors() as exc:
        if exits.received_signal() is not None:  # a library's words for the signal
            return _interrupted(command, exits.received_signal())
        message = " ".join(str(exc).split()) or type(exc).__name__
        if exits.memory_exhausted(exc, limit):  # DuckDB's own out-of-memory error
            message = exits.out_of_memory(command, limit)
    except BrokenPipeError:
        if _stdout_open():  # another pipe broke (a worker's): not the reader's leaving
            raise
        # stdout's reader left (`ropeload ingest ... | head -1`): what was asked is done
        # (landed, written), only the rest of the report has no reader. Quiet, with the
        # shell's status for a writer a closed pipe stopped (128 + SIGPIPE), and stdout
        # sent nowhere so that its flush at exit raises nothing more
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return 128 + signal.SIGPIPE
    except KeyboardInterrupt as exc:
        return _interrupted(command, getattr(exc, "signum", signal.SIGINT))
    except (MemoryError, ImportError, OSError, SystemError, RuntimeError) as exc:
        if exits.received_signal() is not None:  # DuckDB's RuntimeError('Query interrupted')
            return _interrupted(command, exits.received_signal())
        if exits.memory_exhausted(exc, limit):
            message = exits.out_of_memory(command, limit)
        elif isinstance(exc, OSError) and exc.errno in _USER_ERRNOS:
            message = _os_error_line(exc)
        else:
            raise
    sys.stderr.write(f"ropeload {command}: {message}\n")
    return 1


def _interrupted(command: str, signum: int) -> int:
    """The one line and the shell's status (128 + the signal) of an interrupted command."""
    sys.stderr.write(f"ropeload {command}: interrupted ({signal.Signals(signum).name})\n")
    return 128 + signum


if __name__ == "__main__":
    sys.exit(main())
