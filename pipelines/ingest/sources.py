"""Which files to ingest and in which format (contract 1a, 1b, 3).

``ingest PATH...`` takes files and folders in any mix; folders are walked recursively
in name order, skipping hidden files and npTDMS ``.tdms_index`` files. The format
comes from the extension, else from the first bytes (MCAP and TDMS magic); anything
else is treated as a CSV log and refused by the CSV reader if it is not one.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["detect_format", "expand_paths"]

_EXTENSIONS = {".csv": "csv", ".txt": "csv", ".tsv": "csv", ".tdms": "tdms", ".mcap": "mcap"}
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_TDMS_MAGIC = b"TDSm"


def expand_paths(paths: Sequence[str | Path]) -> list[Path]:
    """Files named or found under the folders named, in order, without repeats."""
    seen: set[Path] = set()
    found: list[Path] = []
    for raw in paths:
        path = Path(raw).expanduser().absolute()
        for file in _walk(path):
            if file not in seen:
                seen.add(file)
                found.append(file)
    return found


def _walk(path: Path) -> Iterable[Path]:
    if path.is_dir():
        for child in sorted(path.rglob("*")):
            rel = child.relative_to(path)
            if child.is_file() and not any(p.startswith(".") for p in rel.parts):
                if child.suffix != ".tdms_index":
                    yield child
    else:
        yield path  # a missing file is reported by ingest, not dropped here


def detect_format(path: Path) -> str:
    """``csv``, ``tdms`` or ``mcap``."""
    by_name = _EXTENSIONS.get(path.suffix.lower())
    if by_name is not None:
        return by_name
    with path.open("rb") as handle:
        head = handle.read(8)
    if head.startswith(_MCAP_MAGIC):
        return "mcap"
    if head.startswith(_TDMS_MAGIC):
        return "tdms"
    return "csv"
