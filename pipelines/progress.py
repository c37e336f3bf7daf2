"""Progress of a backfill's or a night's partitions on stderr (:class:`StderrProgress`)."""

from __future__ import annotations

import atexit
import sys
import threading
import time
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from rich.progress import Progress

    from pipelines.partitions import PartitionOutcome

__all__ = ["StderrProgress"]


class StderrProgress:
    """Progress of the partitions on stderr: a live bar (rich) on a terminal only.

    Call it with each :class:`PartitionOutcome`; :meth:`resize` once the number of
    partitions is known. On a terminal rich redraws one line
    (``partitions ━━━━━━━━━━━━━━━━━━━━━━━━━━ 12/60 1 failed 0:00:41 eta 0:03:05 <key>``)
    and lines written to ``sys.stderr`` meanwhile (the log) go above it. Elsewhere (CI,
    cron, a log file) it says nothing until the last partition, then one summary line
    ``60/60 partitions, 1 failed, 245 s``. The bar ends at the last partition, on
    :meth:`close`, or at exit. ``stream``: default ``sys.stderr``.
    """

    def __init__(
        self, total: int, *, label: str = "partitions", stream: TextIO | None = None
    ) -> None:
        self.total, self.label = total, label
        self.done = 0
        self.failed = 0
        self._stream = sys.stderr if stream is None else stream
        self._started = time.perf_counter()
        self._lock = threading.Lock()
        self._closed = False
        self._bar: Progress | None = None
        if self._stream.isatty():
            from rich.console import Console  # 0.2 s to import: only for a terminal
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[failed]} failed"),
                TimeElapsedColumn(),
                TextColumn("eta"),
                TimeRemainingColumn(),
                TextColumn("{task.fields[key]}"),
                console=Console(file=self._stream, force_terminal=True),
                refresh_per_second=2,
                redirect_stdout=False,  # stdout is the command's result, never the bar's
                redirect_stderr=self._stream is sys.stderr,  # log lines go above the bar
            )
            self._task = self._bar.add_task(label, total=total, failed=0, key="")
            self._start_bar()

    def _start_bar(self) -> None:
        """Draw the bar once there is something to count (not for an empty plan)."""
        if self._bar is not None and self.total and not self._bar.live.is_started:
            self._bar.start()
            atexit.register(self.close)

    def resize(self, total: int) -> None:
        """Set the number of partitions once known (after planning)."""
        with self._lock:
            self.total = total
            if self._bar is not None:
                self._bar.update(self._task, total=total)
                self._start_bar()
        if total and self.done >= total:
            self.close()

    def __call__(self, outcome: PartitionOutcome) -> None:
        with self._lock:
            self.done += 1
            self.failed += outcome.status == "failed"
            if self._bar is not None:
                self._bar.update(self._task, advance=1, failed=self.failed, key=outcome.key)
        if self.total and self.done >= self.total:
            self.close()

    def close(self) -> None:
        """End the bar (a terminal) or write the summary line (elsewhere); once."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        if self._bar is not None:
            if self._bar.live.is_started:
                self._bar.stop()
                atexit.unregister(self.close)
            return
        elapsed = time.perf_counter() - self._started
        self._stream.write(
            f"{self.done}/{self.total} {self.label}, {self.failed} failed, {elapsed:.0f} s\n"
        )
        self._stream.flush()
