"""The hoists a mine runs, where their raw logs arrive, and which of those files are new.

Contents
--------
:class:`HoistSource`, :func:`load_hoists`
    One hoist: its description file and its incoming folder.
:func:`file_span`, :func:`file_days`
    The UTC span and days a raw file covers by the date stamp in its name.
:func:`raw_files`, :func:`find_new_files`, :func:`known_files`, :func:`incoming_notes`
    A hoist's raw files, those not yet in the ingest manifest (the watermark), and what
    the incoming convention leaves unread.
:func:`lake_inputs`, :func:`hoist_lookup`
    The sources landed for a hoist and period; ingest's hoist lookup for one hoist.

Hoists and incoming files (``--hoists DIR``, ``--incoming DIR``)::

    <hoists>/<any name>.toml           one hoist description per file (schemas/hoists/README.md)
    <incoming>/<site>/<hoist>/**       that hoist's raw logs (CSV, TDMS) as the logger writes them

``--incoming`` defaults to ``<data>/incoming``. A raw file belongs to the UTC days its
name's date stamp covers: ``..._YYYYMMDD.csv`` is that local day (the hoist's
``timezone``), ``..._YYYYMMDD_HH00.csv`` that local hour; files without a stamp are
ingested while planning so their time range is known from the manifest.

Watermark. The ingest manifest *is* the watermark: a raw file is new when its path and
size are not in the manifest (:func:`known_files`). Unlike a modification-time watermark
this survives copies that keep old mtimes (``rsync -a``, robocopy), clock skew and late
files; a file that grew since (a logger still writing) is new again and ingest resumes
after the bytes it already consumed.
"""

from __future__ import annotations

import datetime as dt
import re
import zoneinfo
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from pipelines.ingest.field_checks import ForeignHoistError
from pipelines.ingest.sources import expand_paths
from pipelines.lake import scan_lake
from schemas.hoist import HoistDescription, load_hoist
from schemas.names import printable
from warehouse.store import DataRoot, open_reader

__all__ = [
    "HoistSource",
    "file_days",
    "file_span",
    "find_new_files",
    "hoist_lookup",
    "incoming_notes",
    "is_new",
    "known_files",
    "lake_inputs",
    "load_hoists",
    "raw_files",
    "utc_days",
]

_STAMP = re.compile(r"(?<!\d)(\d{8})(?:[_T-](\d{2})00)?(?!\d)")
_RAW_SUFFIXES = {".csv", ".tdms"}


@dataclass(frozen=True)
class HoistSource:
    """One hoist: its description file and the folder its raw logs arrive in."""

    path: Path
    site: str
    hoist: str
    timezone: str
    incoming: Path

    @property
    def key(self) -> str:
        return f"{self.site}/{self.hoist}"

    def description(self) -> HoistDescription:
        return load_hoist(self.path)


def _source(path: Path, incoming_root: Path) -> HoistSource:
    description = load_hoist(path)
    site, name = description.hoist.site, description.hoist.name
    return HoistSource(
        path=path.absolute(),
        site=site,
        hoist=name,
        timezone=description.hoist.timezone,
        incoming=(incoming_root / site / name).absolute(),
    )


def load_hoists(
    hoists: str | Path | Sequence[str | Path],
    *,
    data: DataRoot,
    incoming: str | Path | None = None,
    unreadable: list[str] | None = None,
) -> list[HoistSource]:
    """Hoists from a folder of hoist descriptions (``*.toml``) or a list of files.

    ``incoming`` (default ``<data>/incoming``) holds ``<site>/<hoist>/`` per hoist.
    Raises ValueError for an empty folder or two files describing the same hoist, and
    whatever loading a description raises -- unless ``unreadable`` is a list: then a
    description that cannot be loaded is left out and said there, one ``<file>:
    <reason>`` line each (a night runs the other hoists).
    """
    root = Path(incoming) if incoming is not None else data.path / "incoming"
    if isinstance(hoists, str | Path):
        hoists = [hoists]
    files: list[Path] = []
    for entry in map(Path, hoists):
        if entry.is_dir():
            found = sorted(entry.glob("*.toml"))
            if not found:
                raise ValueError(f"{entry}: no hoist descriptions (*.toml) in this folder")
            files.extend(found)
        elif entry.is_file():
            files.append(entry)
        else:
            raise FileNotFoundError(f"{entry}: no such hoist description or folder")
    sources = []
    for path in files:
        try:
            sources.append(_source(path, root))
        except (ValueError, OSError) as exc:  # HoistDescriptionError is a ValueError
            if unreadable is None:
                raise
            reason = " ".join(str(exc).split()).removeprefix(f"{path}: ")
            unreadable.append(f"{printable(path)}: {reason or type(exc).__name__}")
    seen: dict[str, Path] = {}
    for source in sources:
        if source.key in seen:
            raise ValueError(
                f"{source.path}: hoist {source.key} is also described in {seen[source.key]}"
            )
        seen[source.key] = source.path
    return sources


# ------------------------------------------------------------------- files and days


def utc_days(first: dt.datetime, last: dt.datetime) -> list[dt.date]:
    """UTC days touched by ``first <= t < last``."""
    a = first.astimezone(dt.UTC).date()
    b = (last.astimezone(dt.UTC) - dt.timedelta(microseconds=1)).date()
    return [a + dt.timedelta(days=k) for k in range((b - a).days + 1)]


def file_span(path: str | Path, timezone: str) -> tuple[dt.datetime, dt.datetime] | None:
    """UTC span ``[start, end)`` a raw file covers by the date stamp in its name, or None.

    ``..._YYYYMMDD.<ext>`` is that local day of ``timezone``, ``..._YYYYMMDD_HH00.<ext>``
    that local hour. The last stamp in the name wins (a site code may hold digits).
    """
    stamps = list(_STAMP.finditer(Path(path).stem))
    if not stamps:
        return None
    match = stamps[-1]
    try:
        day = dt.datetime.strptime(match.group(1), "%Y%m%d")
    except ValueError:
        return None
    zone = zoneinfo.ZoneInfo(timezone)
    if match.group(2) is not None:
        start = day.replace(hour=int(match.group(2)), tzinfo=zone)
        end = start + dt.timedelta(hours=1)
    else:
        start = day.replace(tzinfo=zone)
        end = (day + dt.timedelta(days=1)).replace(tzinfo=zone)
    return start.astimezone(dt.UTC), end.astimezone(dt.UTC)


def file_days(path: str | Path, timezone: str) -> list[dt.date] | None:
    """UTC days a raw file covers according to the date stamp in its name, or None.

    >>> file_days("mine_hoist_20260302.csv", "Asia/Shanghai")
    [datetime.date(2026, 3, 1), datetime.date(2026, 3, 2)]
    >>> file_days("mine_hoist_20260302_0900.csv", "Asia/Shanghai")
    [datetime.date(2026, 3, 2)]
    >>> file_days("export.csv", "UTC") is None
    True
    """
    span = file_span(path, timezone)
    return None if span is None else utc_days(*span)


def raw_files(source: HoistSource) -> list[Path]:
    """The raw files (CSV, TDMS) under ``source.incoming``; none without that folder."""
    if not source.incoming.is_dir():
        return []
    return [p for p in expand_paths([source.incoming]) if p.suffix.lower() in _RAW_SUFFIXES]


def incoming_notes(sources: Sequence[HoistSource]) -> list[str]:
    """One line per thing in the incoming convention that will not be processed: a hoist
    without its ``<incoming>/<site>/<hoist>/`` folder or without raw files in it, an
    incoming folder no hoist description claims (its logs are never read), raw files
    outside any ``<site>/<hoist>/`` folder. Hidden entries (``.name``) are ignored."""
    notes: list[str] = []
    claimed = {(s.site, s.hoist) for s in sources}
    sites = {s.site for s in sources}
    for source in sources:
        if not source.incoming.is_dir():
            notes.append(
                f"hoist {source.key} ({source.path.name}): no incoming folder {source.incoming}"
            )
        elif not raw_files(source):
            notes.append(
                f"hoist {source.key} ({source.path.name}): no raw files (CSV, TDMS) in "
                f"{source.incoming}"
            )
    roots = sorted({s.incoming.parent.parent for s in sources})
    for root in roots:
        if not root.is_dir():
            continue
        stray = [p for p in root.iterdir() if p.is_file() and p.suffix.lower() in _RAW_SUFFIXES]
        for site_dir in sorted(p for p in root.iterdir() if p.is_dir()):
            if site_dir.name.startswith("."):
                continue
            if site_dir.name not in sites:
                notes.append(
                    f"incoming folder {printable(site_dir)}: no hoist description has "
                    f"[hoist] site = {site_dir.name!r}; its logs are not read"
                )
                continue
            stray += [
                p for p in site_dir.iterdir() if p.is_file() and p.suffix.lower() in _RAW_SUFFIXES
            ]
            for hoist_dir in sorted(p for p in site_dir.iterdir() if p.is_dir()):
                if not hoist_dir.name.startswith(".") and (
                    (site_dir.name, hoist_dir.name) not in claimed
                ):
                    notes.append(
                        f"incoming folder {printable(hoist_dir)}: no hoist description "
                        f"claims it ([hoist] site = {site_dir.name!r}, "
                        f"name = {hoist_dir.name!r}); "
                        "its logs are not read"
                    )
        for folder in sorted({p.parent for p in stray}):
            count = sum(p.parent == folder for p in stray)
            notes.append(
                f"incoming folder {printable(folder)}: {count} raw file(s) outside any "
                "<site>/<hoist> folder; not read"
            )
    return notes


def known_files(data: DataRoot) -> set[tuple[str, int]]:
    """(absolute path, size) of every file in the ingest manifest, and of every file
    ingest skipped as content the manifest holds under another path (``manifest_aliases``).

    A raw file whose path and size are here has been ingested (or refused) already: the
    manifest is the watermark. A file that grew since (a logger still writing) is new.
    """
    if not data.warehouse.exists():
        return set()
    con = open_reader(data)
    try:
        sql = "SELECT source_path, size_bytes FROM manifest"
        tables = con.sql("SELECT table_name FROM information_schema.tables").fetchall()
        if ("manifest_aliases",) in tables:  # a warehouse before migration 0006 lacks it
            sql += " UNION ALL SELECT source_path, size_bytes FROM manifest_aliases"
        rows = con.sql(sql).fetchall()
    finally:
        con.close()
    return {(str(path), int(size)) for path, size in rows}


def is_new(path: Path, known: set[tuple[str, int]]) -> bool:
    """Whether a raw file's (path, size) is not in ``known`` (:func:`known_files`)."""
    return (str(path), path.stat().st_size) not in known


def find_new_files(source: HoistSource, known: set[tuple[str, int]]) -> list[Path]:
    """Raw files (CSV, TDMS) under ``source.incoming`` whose (path, size) is not in ``known``."""
    return [path for path in raw_files(source) if is_new(path, known)]


def lake_inputs(
    data: DataRoot, site: str, hoist: str, start: dt.datetime, end: dt.datetime
) -> tuple[str, ...]:
    """Sorted ``source_sha256`` of the field samples landed for a hoist in ``[start, end)``."""
    shas = (
        scan_lake(data, "field_samples", site=site, hoist=hoist, start=start, end=end)
        .select(pl.col("source_sha256").unique())
        .collect()["source_sha256"]
    )
    return tuple(sorted(s for s in shas.to_list() if s is not None))


def hoist_lookup(source: HoistSource) -> Callable[[str, str], HoistDescription | None]:
    """Ingest's ``hoist_lookup`` for one hoist's files (the depth-in-shaft check); a
    file whose header names another hoist is refused: it is in this hoist's incoming
    folder, and would land in the other's lake unseen by this hoist's run."""
    description = source.description()

    def lookup(site: str, hoist: str) -> HoistDescription | None:
        if (site, hoist) != (source.site, source.hoist):
            raise ForeignHoistError(
                f"header names hoist {site}/{hoist}, but the file is in the incoming "
                f"folder of {source.site}/{source.hoist}"
            )
        return description

    return lookup
