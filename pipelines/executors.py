"""How the steps of a backfill or a night run: the one thing that differs between the
plain commands and their Prefect flows (issue 17).

:func:`pipelines.backfill.backfill` and :func:`pipelines.nightly.nightly` are written
once, in terms of an :class:`Executor`: ``map`` a plain function over items (hoists,
hoist-days), ``call`` one, ``publish`` a report. :class:`PlainExecutor` runs them in this
process (a thread pool for the hoist-days, transient errors retried);
:class:`pipelines.tasks.PrefectExecutor` submits the Prefect task of each function to the
flow's task runner (threads or a Dask cluster, :func:`pipelines.tasks.task_runner`).

Contents
--------
:class:`Done`, :class:`Executor`, :class:`PlainExecutor`
    The executor interface and the plain one.
:func:`is_transient`
    The errors worth retrying, for every executor.
:func:`workers_within_budget`
    The most workers whose memory fits a budget.
"""

from __future__ import annotations

import datetime as dt
import logging
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

import duckdb

__all__ = [
    "PROCESS_BASE_BYTES",
    "WORKER_BYTES_PER_BLOCK_SAMPLE",
    "Done",
    "Executor",
    "PlainExecutor",
    "is_transient",
    "workers_within_budget",
]

# The retry lines keep the name they had when retries lived in pipelines.backfill.
logger = logging.getLogger("pipelines.backfill")

T = TypeVar("T")
R = TypeVar("R")


@dataclass(frozen=True)
class Done(Generic[T, R]):
    """One item of :meth:`Executor.map`: its value, or the error of its last attempt."""

    item: T
    value: R | None = None
    error: BaseException | None = None
    attempts: int = 1


class Executor(Protocol):
    """How the steps of a backfill or a night run (module docstring)."""

    def map(
        self, fn: Callable[..., R], items: Sequence[T], *, pooled: bool = False, **common: Any
    ) -> Iterator[Done[T, R]]:
        """``fn(item, **common)`` per item, as each completes; an error is ``Done.error``.

        ``pooled``: the items are the units of work (hoist-days), spread over the
        workers and retried on a transient error; otherwise (a hoist's ingest, a day's
        discovery) the plain executor runs them one after another, once each.
        """
        ...

    def call(self, fn: Callable[..., R], *args: Any, **kwargs: Any) -> R:
        """``fn(*args, **kwargs)`` once (as its task, in Prefect); raises its error."""
        ...

    def publish(self, report: Any, key: str) -> None:
        """Publish a written report (:class:`pipelines.reports.Report`) under ``key``."""
        ...


@dataclass(frozen=True)
class PlainExecutor:
    """The steps in this process, as ``ropeload backfill`` and ``nightly`` run them.

    Pooled items on ``max_workers`` threads, a transient error (:func:`is_transient`)
    retried ``retries`` times after ``retry_delay_s`` x the attempt number; other items
    one after another in the calling thread. Nothing to publish (no artifacts).
    """

    max_workers: int = 2
    retries: int = 2
    retry_delay_s: float = 1.0

    def __post_init__(self) -> None:
        if self.max_workers < 1:
            raise ValueError(f"max_workers must be >= 1, got {self.max_workers}")

    def map(
        self, fn: Callable[..., R], items: Sequence[T], *, pooled: bool = False, **common: Any
    ) -> Iterator[Done[T, R]]:
        """See :meth:`Executor.map`."""
        if not pooled:
            for item in items:
                yield self._attempts(fn, item, common, retries=0)
            return
        with ThreadPoolExecutor(
            max_workers=self.max_workers, thread_name_prefix="partition"
        ) as pool:
            futures = [
                pool.submit(self._attempts, fn, item, common, retries=self.retries)
                for item in items
            ]
            for future in as_completed(futures):
                yield future.result()

    def _attempts(
        self, fn: Callable[..., R], item: T, common: dict[str, Any], *, retries: int
    ) -> Done[T, R]:
        attempt = 0
        while True:
            attempt += 1
            try:
                return Done(item, fn(item, **common), attempts=attempt)
            except Exception as exc:
                if not (is_transient(exc) and attempt <= retries):
                    return Done(item, error=exc, attempts=attempt)
                delay = self.retry_delay_s * attempt
                logger.warning(
                    "%s: %s: %s; retry %d of %d in %.0f s",
                    getattr(item, "key", item),
                    type(exc).__name__,
                    exc,
                    attempt,
                    retries,
                    delay,
                )
                time.sleep(delay)

    def call(self, fn: Callable[..., R], *args: Any, **kwargs: Any) -> R:
        """``fn(*args, **kwargs)``."""
        return fn(*args, **kwargs)

    def publish(self, report: Any, key: str) -> None:
        """Nothing: the report is the HTML file already written."""


def is_transient(exc: BaseException) -> bool:
    """Worth retrying: I/O trouble and lock time-outs; never bad data or code errors.

    Missing files and permission errors are not transient (retrying cannot fix them);
    other ``OSError`` (NFS hiccups, ``EAGAIN``, a full disk being cleaned) and DuckDB
    I/O errors ("Could not set lock on file") are.
    """
    if isinstance(
        exc, FileNotFoundError | PermissionError | IsADirectoryError | NotADirectoryError
    ):
        return False
    return isinstance(exc, OSError | TimeoutError | duckdb.IOException)


#: Memory of a backfill or night (``benchmarks/bench_day.py --backfill 4``, 100 Hz
#: hoist-days, hour blocks): four workers 2.78 GB (session 42, each block reading the stop
#: continuity's look-ahead; 2.46-2.73 GB before), so 0.9 GB and 0.47 GB a worker. A
#: worker's share grows with its block's samples.
PROCESS_BASE_BYTES = 0.9e9
WORKER_BYTES_PER_BLOCK_SAMPLE = 0.47e9 / 360_000


def workers_within_budget(
    workers: int,
    budget_bytes: float,
    *,
    block: dt.timedelta = dt.timedelta(hours=1),
    sample_rate_hz: float = 100.0,
) -> int:
    """The most workers (at most ``workers``, at least 1) whose memory fits ``budget_bytes``.

    Estimate: :data:`PROCESS_BASE_BYTES` + workers x :data:`WORKER_BYTES_PER_BLOCK_SAMPLE`
    x the samples of a block (``sample_rate_hz`` x ``block``).

    >>> [workers_within_budget(8, gb * 1e9) for gb in (8.0, 2.78, 2.7, 1.0)]
    [8, 4, 3, 1]
    """
    per_worker = WORKER_BYTES_PER_BLOCK_SAMPLE * sample_rate_hz * block.total_seconds()
    fit = int((budget_bytes - PROCESS_BASE_BYTES) / per_worker + 1e-9)  # 1.88 / 0.47 is 4
    return max(1, min(workers, fit))
