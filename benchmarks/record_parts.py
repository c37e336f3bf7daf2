"""A field-log CSV cut into consecutive records, as exports cut them (the evaluations'
``--parts N``).

A mine's logger exports hourly or daily files that start and end wherever the cut
falls: mid-trip, mid-stop. :func:`split_record` makes such records from one validation
file, so that an evaluation sees more records of the same kind than the files it has
(``eval_compensation.py``, ``eval_sanity.py`` and ``eval_discovery.py --trials``). Not a
unit test and not ropeload code: the scripts in ``benchmarks/`` import it as a sibling.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from record_variants import delimiter_of, header_keys  # the sibling script

__all__ = ["RecordPart", "split_record"]


@dataclass(frozen=True)
class RecordPart:
    """One part of a record: its CSV (the header lines of the whole file, then its rows),
    the logged timestamps of its first and last rows as the file writes them, and the
    file's ``# key: value`` header lines (``timezone``, ...; keys in lower case)."""

    path: Path
    first_stamp: str
    last_stamp: str
    header: dict[str, str]


def split_record(csv: Path, parts: int) -> list[RecordPart]:
    """``csv`` cut into ``parts`` consecutive records of equal row counts, each written
    beside it as ``<stem>-part<k>.csv`` with the whole file's header lines; the file
    itself when ``parts`` <= 1. ValueError when it has fewer rows than parts."""
    lines = csv.read_text().splitlines(keepends=True)
    header = next(i for i, line in enumerate(lines) if not line.startswith("#")) + 1
    rows = [line for line in lines[header:] if line.strip()]
    if len(rows) < max(parts, 1):
        raise ValueError(f"{csv.name}: {len(rows)} rows cannot be cut into {parts} parts")
    delimiter = delimiter_of(lines[header - 1])
    keys = header_keys(lines[: header - 1])
    if parts <= 1:
        stamps = (rows[0].split(delimiter, 1)[0], rows[-1].split(delimiter, 1)[0])
        return [RecordPart(csv, *stamps, keys)]
    out = []
    for k in range(parts):
        chunk = rows[k * len(rows) // parts : (k + 1) * len(rows) // parts]
        path = csv.with_name(f"{csv.stem}-part{k + 1}.csv")
        path.write_text("".join(lines[:header] + chunk))
        stamps = (chunk[0].split(delimiter, 1)[0], chunk[-1].split(delimiter, 1)[0])
        out.append(RecordPart(path, *stamps, keys))
    return out
