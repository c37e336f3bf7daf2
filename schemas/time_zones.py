"""IANA time-zone names: the zones a hoist description or a log header may name.

Python's :mod:`zoneinfo` opens any zone file of the machine's zone folders, names and
not: ``localtime``, ``posixrules``, ``Factory``, ``posix/...``, ``right/...``. polars and
DuckDB know the IANA names only (``timezone('localtime', t)`` failed every query of a
view once a run had landed with it), and ``localtime`` is whatever zone the machine
that runs the pipeline is set to, not the mine's.
"""

from __future__ import annotations

import functools
import zoneinfo

__all__ = ["zone_problem"]


@functools.cache
def _iana_zone_names() -> frozenset[str]:
    """The IANA zone names (links included: ``PRC``, ``US/Pacific``), without the zone
    files that are no names (:func:`zoneinfo.available_timezones` leaves out
    ``posix/...`` and ``right/...``)."""
    return frozenset(zoneinfo.available_timezones() - {"localtime", "Factory", "posixrules"})


def zone_problem(name: str) -> str | None:
    """Why ``name`` is not an IANA time-zone name this machine knows, or None.

    >>> zone_problem("Asia/Shanghai") is None, zone_problem("UTC") is None
    (True, True)
    >>> zone_problem("Mars/Olympus")
    "unknown IANA time zone 'Mars/Olympus'"
    >>> "a zone file of this machine, not a zone name" in zone_problem("localtime")
    True
    """
    try:
        zoneinfo.ZoneInfo(name)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        return f"unknown IANA time zone {name!r}"
    if name not in _iana_zone_names():
        return (
            f"unknown IANA time zone {name!r}: a zone file of this machine, not a zone name "
            "(polars and DuckDB know names only, e.g. 'Asia/Shanghai')"
        )
    return None
