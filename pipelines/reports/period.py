"""One hoist-period to report, the steps that made it, and the words for its numbers.

:class:`HoistPeriod` is what :func:`pipelines.reports.sections.hoist_sections` draws;
:class:`Step` a step of the command and how it went; :func:`count_text`,
:func:`pct_text` and :func:`num_text` the numbers of the sections' sentences and tables.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import polars as pl

from pipelines.reports.data import Zone
from schemas.hoist import HoistDescription

__all__ = ["HoistPeriod", "Step", "StepStatus", "count_text", "num_text", "pct_text"]


StepStatus = Literal["done", "skipped", "failed"]


@dataclass(frozen=True)
class Step:
    """A step of the command for this hoist-period and how it went, in words."""

    name: str
    status: StepStatus
    detail: str = ""

    @classmethod
    def from_outcome(cls, outcome: object) -> Step:
        """From a landed step outcome (:class:`pipelines.steps.StepOutcome`, or a
        ``run_steps`` row as a dict)."""
        get = outcome.get if isinstance(outcome, dict) else lambda k: getattr(outcome, k, None)
        name = str(get("step") or "step").replace("_", " ")
        status = str(get("status") or "done")
        return cls(name, status if status in ("done", "skipped", "failed") else "done",  # type: ignore[arg-type]
                   str(get("message") or ""))  # fmt: skip

    def sentence(self) -> str:
        """``sanity check: 5 of 6 trips passed.``, ``discovery: skipped: <why>.``,
        ``sanity check: FAILED: <reason>.``"""
        verb = {"done": "", "skipped": "skipped", "failed": "FAILED"}[self.status]
        words = ": ".join(w for w in (verb, self.detail) if w) or "done"
        return f"{self.name[:1].upper()}{self.name[1:]}: {words.rstrip('.')}."


@dataclass
class HoistPeriod:
    """One run's period of one hoist, to be reported in detail.

    ``frame``: the run's rope tensions when still in memory (``ropeload run``, demo);
    otherwise they are read from the lake. ``discovery_json``: a discovery report written
    for this period (its residual trace is drawn when present).
    """

    run_id: str
    description: HoistDescription
    start_utc: dt.datetime
    end_utc: dt.datetime
    label: str
    steps: Sequence[Step] = ()
    frame: pl.DataFrame | None = None
    discovery_json: Path | None = None
    anchor: str = ""
    extra: dict[str, object] = field(default_factory=dict)

    @property
    def site(self) -> str:
        return self.description.hoist.site

    @property
    def hoist(self) -> str:
        return self.description.hoist.name

    @property
    def zone(self) -> Zone:
        """The hoist's zone, or UTC where its clocks go back in the period
        (:meth:`Zone.for_period`)."""
        return Zone(self.description.hoist.timezone).for_period(self.start_utc, self.end_utc)


def count_text(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def pct_text(value: float | None, digits: int = 2) -> str:
    return "" if value is None else f"{value * 100:.{digits}f} %"


def num_text(value: float | None, scale: float = 1.0, digits: int = 2) -> str:
    if value is None or value != value:  # None or NaN
        return ""
    return f"{value / scale:.{digits}f}"
