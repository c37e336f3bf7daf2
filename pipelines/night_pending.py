"""What a night set out to do and has not done yet, kept in the data root.

A night plans its hoist-days from the files that are new to it (:mod:`pipelines.nightly`)
and its discoveries from the days whose sanity check failed this night
(:mod:`pipelines.night_discovery`). Killed between planning and finishing, the next
night would see neither again: the files are in the manifest (no longer new) and the
days' checks have their outcomes, so a week of arrears beyond the lookback, or a
discovery cut short, was never done, and nothing said so. The plan is written to
``<data>/state/nightly-pending.json`` before the work starts; each night adds the pending
items of its hoists to its own plan and keeps those not done yet (a failed hoist-day
stays pending until a night runs it; a discovery is done once its outcome, a report or
a failure, is landed).

The file holds partition keys (``site/hoist/YYYY-MM-DD``) of hoist-days to run and, per
key, the run id of a day to discover. It is written atomically; a missing or unreadable
file is an empty plan (the work it named is then found only as before).
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

from warehouse.store import DataRoot, write_text_atomic

__all__ = ["PendingWork", "key_parts", "load_pending", "save_pending"]

logger = logging.getLogger(__name__)

#: The file under the data root's ``state`` folder.
PENDING_FILE = "nightly-pending.json"


@dataclass
class PendingWork:
    """Hoist-days a night planned to run, and days (with the run to land the outcome
    with) it planned to discover, not done yet."""

    runs: set[str] = field(default_factory=set)
    discoveries: dict[str, str] = field(default_factory=dict)

    def days_of(self, site: str, hoist: str) -> set[dt.date]:
        """The pending hoist-days of one hoist."""
        return {day for s, h, day in map(key_parts, self.runs) if (s, h) == (site, hoist)}


def key_parts(key: str) -> tuple[str, str, dt.date]:
    """(site, hoist, day) of a partition key ``site/hoist/YYYY-MM-DD``
    (:attr:`pipelines.partitions.Partition.key`)."""
    site, hoist, day = key.split("/")
    return site, hoist, dt.date.fromisoformat(day)


def _path(data: DataRoot) -> Path:
    return data.path / "state" / PENDING_FILE


#: A partition key: site/hoist/YYYY-MM-DD (safe names hold no "/").
_KEY = re.compile(r"[^/]+/[^/]+/\d{4}-\d{2}-\d{2}")


def _valid_key(key: object) -> bool:
    if not isinstance(key, str) or not _KEY.fullmatch(key):
        return False
    try:
        key_parts(key)
    except ValueError:
        return False
    return True


def load_pending(data: DataRoot) -> PendingWork:
    """The pending work of the data root (empty without a readable file; an entry that
    is not a partition key is left out, said in a warning naming the file)."""
    path = _path(data)
    try:
        raw = json.loads(path.read_text())
    except FileNotFoundError:
        return PendingWork()
    except (OSError, ValueError) as exc:
        logger.warning("%s unreadable, taken as no pending work: %s", path, exc)
        return PendingWork()
    runs = raw.get("runs", []) if isinstance(raw, dict) else []
    found = raw.get("discoveries", {}) if isinstance(raw, dict) else {}
    runs = runs if isinstance(runs, list) else []
    found = found if isinstance(found, dict) else {}
    work = PendingWork(
        runs={k for k in runs if _valid_key(k)},
        discoveries={k: v for k, v in found.items() if _valid_key(k) and isinstance(v, str)},
    )
    left = len(runs) - len(work.runs) + len(found) - len(work.discoveries)
    if left or not isinstance(raw, dict):
        logger.warning("%s: %d entr(ies) not hoist-days left out", path, max(left, 1))
    return work


def save_pending(data: DataRoot, work: PendingWork) -> None:
    """Write the pending work, whole or not at all."""
    text = json.dumps(
        {"runs": sorted(work.runs), "discoveries": dict(sorted(work.discoveries.items()))},
        indent=1,
    )
    write_text_atomic(_path(data), text)
