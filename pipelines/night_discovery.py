"""Discovery after a failed simulation sanity check: a night's optional last step.

For each hoist with a failed check, discovery (:func:`pipelines.discover.discover_period`)
runs over its latest failed day and writes
``<data>/reports/discovery/<site>_<hoist>_<day>.json`` (and a plot), landing its findings
in ``discovery_findings`` and its outcome as a step of the day's run (``run_steps``). A
discovery that fails is a finding, it never fails the night (:mod:`pipelines.steps`).
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from pipelines.hoists import HoistSource
from pipelines.night_pending import PendingWork, key_parts, save_pending
from pipelines.partitions import Partition, PartitionOutcome
from pipelines.steps import StepOutcome, one_line, record_steps
from warehouse.store import DataRoot

if TYPE_CHECKING:
    from pipelines.executors import Executor

__all__ = [
    "days_to_discover",
    "discover_day",
    "discover_days",
    "discovery_outcome",
    "discovery_words",
    "land_discoveries",
]

# The lines of a night's discoveries keep the name they had in pipelines.nightly.
logger = logging.getLogger("pipelines.nightly")


def days_to_discover(outcomes: Sequence[PartitionOutcome]) -> list[tuple[str, str, dt.date]]:
    """(site, hoist, day): each hoist's latest day with a failed sanity check."""
    latest: dict[tuple[str, str], dt.date] = {}
    for outcome in outcomes:
        if outcome.checks_failed:
            key = (outcome.site, outcome.hoist)
            latest[key] = max(outcome.day, latest.get(key, outcome.day))
    return [(site, hoist, day) for (site, hoist), day in sorted(latest.items())]


def discover_day(day: Partition, *, data: DataRoot) -> tuple[Path, float]:
    """Discovery over one hoist-day after a failed sanity check: the JSON report's path,
    and the seconds it took (work, not orchestration)."""
    from pipelines.discover import discover_period

    t0 = time.perf_counter()
    source = day.source
    target = data.under("reports", "discovery", f"{source.site}_{source.hoist}_{day.day}.json")
    discover_period(
        hoist_path=source.path, data=data, start=day.start, end=day.end, json_path=target
    )
    logger.info("discovery of %s %s (a sanity check failed): %s", source.key, day.day, target)
    return target, time.perf_counter() - t0


def discovery_outcome(path: Path | None, exc: BaseException | None = None) -> StepOutcome:
    """The discovery step of a day: its report (and the effect named), or why it failed."""
    if exc is not None:
        return StepOutcome("discovery", "failed", one_line(exc))
    assert path is not None
    try:
        effect = json.loads(path.read_text(encoding="utf-8")).get("effect", "?")
    except (OSError, ValueError):
        effect = "?"
    return StepOutcome("discovery", "done", f"effect {effect}; report {path}")


def land_discoveries(
    run_ids: dict[str, str], found: dict[str, StepOutcome], data: DataRoot
) -> None:
    """Land each discovery's outcome as a step of the day's run it analysed (``run_ids``
    by ``site/hoist/day``; never raises: the outcome is said on stdout anyway)."""
    for key, step in found.items():
        run_id = run_ids.get(key)
        if run_id is None:
            continue
        site, hoist, _ = key_parts(key)
        try:
            record_steps(data, run_id=run_id, site=site, hoist=hoist, outcomes=[step])
        except Exception as exc:
            logger.warning("%s: discovery outcome not landed: %s", key, one_line(exc))


def discovery_words(step: StepOutcome) -> str:
    """What a night prints per discovery: the report's path, or why it failed."""
    if step.failed:
        return f"discovery failed: {step.message}"
    return step.message.rsplit("report ", 1)[-1]


def discover_days(
    executor: Executor,
    sources: Sequence[HoistSource],
    outcomes: Sequence[PartitionOutcome],
    data: DataRoot,
    pending: PendingWork | None = None,
) -> tuple[dict[str, StepOutcome], float]:
    """Discovery over each hoist's latest day with a failed check (:func:`discover_day`
    on ``executor``); its outcome per ``site/hoist/day``, also landed with the day's run,
    and the seconds the discoveries took. An optional step: a discovery that fails is a
    finding, it never fails the night. With ``pending`` (:mod:`pipelines.night_pending`)
    a hoist without such a day tonight takes the day an earlier night planned to
    discover and did not finish; the plan is kept until each discovery has run (its
    outcome, a report or a failure, said and landed where it can be)."""
    by_key = {(s.site, s.hoist): s for s in sources}
    run_ids = {o.key: o.run_id for o in outcomes if o.run_id}
    days = [
        Partition(by_key[(site, hoist)], day) for site, hoist, day in days_to_discover(outcomes)
    ]
    if pending is not None:
        tonight = {(d.source.site, d.source.hoist) for d in days}
        for key, run_id in sorted(pending.discoveries.items()):
            site, hoist, day = key_parts(key)
            if (site, hoist) in by_key and (site, hoist) not in tonight:
                days.append(Partition(by_key[(site, hoist)], day))
                run_ids[key] = run_id
                tonight.add((site, hoist))
        ours = set(by_key)
        pending.discoveries = {
            k: v for k, v in pending.discoveries.items() if key_parts(k)[:2] not in ours
        } | {d.key: run_ids[d.key] for d in days if d.key in run_ids}
        save_pending(data, pending)
    done = {d.item.key: d for d in executor.map(discover_day, days, data=data)}
    found: dict[str, StepOutcome] = {}
    seconds = 0.0
    for day in days:  # in the order of days_to_discover, whatever order they completed in
        result = done[day.key]
        if result.error is not None:
            logger.warning(
                "discovery of %s failed (a finding): %s", day.key, one_line(result.error)
            )
            found[day.key] = discovery_outcome(None, result.error)
        else:
            assert result.value is not None
            found[day.key] = discovery_outcome(result.value[0])
            seconds += result.value[1]
    land_discoveries(run_ids, found, data)
    if pending is not None:
        for key in found:
            pending.discoveries.pop(key, None)
        save_pending(data, pending)
    return found, seconds
