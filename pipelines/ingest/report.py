"""What ingest did with each file: one :class:`FileResult` per path, an :class:`IngestReport`.

Statuses (also the manifest ``status``, except ``skipped``):

``landed``
    every row accounted for (landed, quarantined with a reason, or an exact duplicate).
``partial``
    the complete part landed, the rest could not be read yet: a CSV whose last line is
    cut off (still growing: ``bytes_consumed < size_bytes``, picked up on the next
    ingest) or a truncated MCAP recording. The message says why.
``refused``
    nothing landed; the message names the file and the line, channel or topic. A
    refusal is never final: the same content ingested again is read again (the code or
    the options may have changed) and refused again, or landed, and the manifest row
    replaced by the new outcome.
``skipped``
    this content (sha256) is already in the manifest as a landed or partial file of the
    same format, under this or another name; nothing was done (not written to the
    manifest again). Refused content and content of another format are never skipped.

``ropeload ingest`` prints the report on stdout and one line per refused file on
stderr (:meth:`IngestReport.refusal_lines`), and exits 1 when any file was refused.

For every file ``rows_read == rows_landed + rows_quarantined + rows_duplicate``.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from pipelines.ingest.clock import ClockState
from schemas.names import printable

__all__ = ["STATUSES", "FileResult", "FilesRefused", "IngestReport"]

STATUSES = ("landed", "partial", "refused", "skipped")


@dataclass
class FileResult:
    """Outcome and row accounting of one source file."""

    path: Path
    sha256: str
    format: str
    status: str
    size_bytes: int = 0
    bytes_consumed: int | None = None
    site: str | None = None
    hoist: str | None = None
    rows_read: int = 0
    rows_landed: int = 0
    rows_quarantined: int = 0
    rows_duplicate: int = 0
    quarantined_by_reason: dict[str, int] = field(default_factory=dict)
    time_start_utc: dt.datetime | None = None
    time_end_utc: dt.datetime | None = None
    message: str = ""
    #: where the logger clock stood at ``bytes_consumed`` (field logs; :mod:`.clock`)
    clock: ClockState | None = None

    @property
    def shown_path(self) -> str:
        """The path for a message: a line break or a control character in the file's
        name escaped (:func:`schemas.names.printable`)."""
        return printable(self.path)

    @property
    def reason(self) -> str:
        """The message on one line, without the leading ``<path>: `` it usually has."""
        text = self.message.removeprefix(f"{self.path}: ").removeprefix(f"{self.shown_path}: ")
        return printable(" ".join(text.split())) or self.status

    @property
    def balanced(self) -> bool:
        """True when read = landed + quarantined + duplicates (always, by design)."""
        return self.rows_read == self.rows_landed + self.rows_quarantined + self.rows_duplicate


@dataclass
class IngestReport:
    """All files of one :func:`pipelines.ingest.ingest_paths` call, in input order."""

    files: list[FileResult] = field(default_factory=list)

    def __iter__(self) -> Iterator[FileResult]:
        return iter(self.files)

    def __len__(self) -> int:
        return len(self.files)

    @property
    def refused(self) -> list[FileResult]:
        return [f for f in self.files if f.status == "refused"]

    @property
    def ok(self) -> bool:
        """No file refused (quarantined rows do not make a run fail)."""
        return not self.refused

    def refusal_lines(self) -> list[str]:
        """One ``<file>: <reason>`` line per refused file, in input order (for stderr)."""
        return [f"{f.shown_path}: {f.reason}" for f in self.refused]

    def totals(self) -> dict[str, int]:
        keys = ("rows_read", "rows_landed", "rows_quarantined", "rows_duplicate")
        return {k: sum(getattr(f, k) for f in self.files) for k in keys}

    def __str__(self) -> str:
        head = ("file", "format", "status", "read", "landed", "quar", "dup", "message")
        rows = [
            (
                printable(f.path.name),
                f.format,
                f.status,
                str(f.rows_read),
                str(f.rows_landed),
                str(f.rows_quarantined),
                str(f.rows_duplicate),
                _short(f.reason if f.message else "", 70),
            )
            for f in self.files
        ]
        t = self.totals()
        rows.append(
            (
                f"total ({len(self.files)} files)",
                "",
                f"{len(self.refused)} refused",
                str(t["rows_read"]),
                str(t["rows_landed"]),
                str(t["rows_quarantined"]),
                str(t["rows_duplicate"]),
                "",
            )
        )
        widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
        numeric = {3, 4, 5, 6}

        def line(r: tuple[str, ...]) -> str:
            cells = [
                c.rjust(w) if i in numeric else c.ljust(w)
                for i, (c, w) in enumerate(zip(r, widths, strict=True))
            ]
            return "  ".join(cells).rstrip()

        rule = "  ".join("-" * w for w in widths)
        return "\n".join([line(head), rule, *(line(r) for r in rows[:-1]), rule, line(rows[-1])])


class FilesRefused(RuntimeError):
    """Raised by the ``ingest`` flow when some files were refused: the flow run fails.

    ``report`` is the whole :class:`IngestReport` (the other files did land); the
    message is the refusal lines, one per file.
    """

    def __init__(self, report: IngestReport) -> None:
        lines = report.refusal_lines()
        super().__init__(f"{len(lines)} file(s) refused:\n" + "\n".join(lines))
        self.report = report


def _short(text: str, width: int) -> str:
    text = " ".join(text.split())
    return text if len(text) <= width else text[: width - 1] + "…"
