"""Where ropeload's log records go: stderr for the CLI, the run logs for Prefect flows.

Library code (``pipelines``, ``transforms``, ``sims``, ``warehouse``, ``schemas``) logs
through ``logging.getLogger(__name__)`` and never prints or imports Prefect. Levels:

- DEBUG: details (each file's accounting, each landing);
- INFO: what happened (files landed, a hoist-day run, a report written, a plan);
- WARNING: something the operator should look at that did not fail the command
  (a transient error retried).

A refused input or a failed run is not logged by the library: it is the command's
one-line error on stderr (contract section 6), or the failed task in Prefect, which
logs it itself.

Two ways out, set up once per process:

- :func:`configure_logging` (the CLI calls it with ``--log-level``): one handler on
  stderr at that level (default ``$ROPELOAD_LOG_LEVEL``, else WARNING). So by default
  a command's stdout holds its result and its stderr only the one-line reason of a
  refusal; ``--log-level info`` adds what happened, on stderr.
- Prefect's run logs: :mod:`pipelines.prefect_env` names these namespaces in
  ``PREFECT_LOGGING_EXTRA_LOGGERS``, so Prefect attaches its API handler to them when
  it is imported, and :func:`enable_run_logs` (called when :mod:`pipelines.tasks` is
  imported, as :mod:`pipelines.flows` does) lets INFO through to it. A record logged
  inside a flow or task run (its thread) then appears in that run's logs in the UI and
  ``prefect flow-run logs``; outside a run Prefect's handler drops it
  (``PREFECT_LOGGING_TO_API_WHEN_MISSING_FLOW =ignore``).

The namespace loggers do not propagate to the root logger: ropeload's records take
exactly these two ways, never also the root's console handler (Prefect installs one),
which would repeat every line on stderr.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys

__all__ = [
    "DEFAULT_LEVEL",
    "LEVEL_ENV",
    "NAMESPACES",
    "add_log_level_option",
    "configure_logging",
    "enable_run_logs",
    "parse_level",
]

#: Top-level packages whose module loggers are ropeload's.
NAMESPACES: tuple[str, ...] = ("pipelines", "transforms", "sims", "warehouse", "schemas")
#: Environment variable with the stderr level when ``--log-level`` is not given.
LEVEL_ENV = "ROPELOAD_LOG_LEVEL"
#: The stderr level when neither is given: the CLI's stderr stays its one-line errors.
DEFAULT_LEVEL = "WARNING"
#: What reaches Prefect's run logs (at least; a lower stderr level lowers it too).
RUN_LOG_LEVEL = logging.INFO

_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")
_FORMAT = "%(asctime)s %(levelname)-7s %(name)s: %(message)s"
_state: dict[str, int | bool | None] = {"stderr_level": None, "run_logs": False}


def parse_level(text: str) -> int:
    """``"info"`` -> ``logging.INFO``; one of debug, info, warning, error (any case)."""
    name = text.strip().upper()
    if name not in _LEVELS:
        raise ValueError(
            f"log level {text!r} is not one of {', '.join(n.lower() for n in _LEVELS)}"
        )
    return int(getattr(logging, name))


def _level_argument(text: str) -> int:
    try:
        return parse_level(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{exc} (--log-level or ${LEVEL_ENV})") from exc


def add_log_level_option(parser: argparse.ArgumentParser) -> None:
    """``--log-level LEVEL`` (default ``$ROPELOAD_LOG_LEVEL``, else warning).

    The environment's value is checked like the option's: a bad one is a usage error.
    """
    parser.add_argument(
        "--log-level",
        metavar="LEVEL",
        type=_level_argument,
        default=os.environ.get(LEVEL_ENV) or DEFAULT_LEVEL,
        help=f"what to log on stderr: debug, info, warning, error (default ${LEVEL_ENV}, "
        f"else {DEFAULT_LEVEL.lower()}); stdout keeps the result",
    )


class _StderrHandler(logging.StreamHandler):
    """A handler on ``sys.stderr`` as it is at each record (pytest's capture and a live
    progress bar's redirection replace ``sys.stderr`` after the handler is made)."""

    def __init__(self, level: int) -> None:
        super().__init__(sys.stderr)
        self.setLevel(level)
        self.setFormatter(logging.Formatter(_FORMAT, datefmt="%Y-%m-%d %H:%M:%S"))

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr
        super().emit(record)


def configure_logging(level: int | str | None = None) -> int:
    """ropeload's records of ``level`` and above on stderr; returns the level.

    ``None`` takes ``$ROPELOAD_LOG_LEVEL``, else WARNING. Idempotent: calling it again
    replaces the handler (one line per record, whatever the number of calls).
    """
    if level is None:
        level = os.environ.get(LEVEL_ENV) or DEFAULT_LEVEL
    if isinstance(level, str):
        level = parse_level(level)
    _state["stderr_level"] = level
    _apply()
    return level


def enable_run_logs() -> None:
    """Let INFO records through to Prefect's run logs (see the module docstring).

    Sets up stderr as :func:`configure_logging` would if nothing has yet (a served
    deployment, a Dask worker); a bad ``$ROPELOAD_LOG_LEVEL`` counts as WARNING there.
    Call it after importing Prefect: if Prefect was imported before
    ``PREFECT_LOGGING_EXTRA_LOGGERS`` named the namespaces, its API handler (that of
    its ``prefect.extra`` logger, as Prefect does) is attached here.
    """
    _state["run_logs"] = True
    api = logging.getLogger("prefect.extra").handlers
    for name in NAMESPACES:
        logger = logging.getLogger(name)
        for handler in api:
            if handler not in logger.handlers:
                logger.addHandler(handler)
    if _state["stderr_level"] is None:
        try:
            _state["stderr_level"] = parse_level(os.environ.get(LEVEL_ENV) or DEFAULT_LEVEL)
        except ValueError:
            _state["stderr_level"] = logging.WARNING
    _apply()


def _apply() -> None:
    stderr_level = int(_state["stderr_level"] or logging.WARNING)
    level = min(stderr_level, RUN_LOG_LEVEL) if _state["run_logs"] else stderr_level
    for name in NAMESPACES:
        logger = logging.getLogger(name)
        for handler in [h for h in logger.handlers if isinstance(h, _StderrHandler)]:
            logger.removeHandler(handler)
        logger.addHandler(_StderrHandler(stderr_level))
        logger.setLevel(level)
        logger.propagate = False
