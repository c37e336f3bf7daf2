"""What discovery answers: one :class:`Finding` per iteration, the :class:`DiscoveryResult`.

Also the parameter overrides' shape (``Params``: ``{effect: {parameter: value}}``) and
:func:`merge_parameters` (one effect's values set in a copy of them), shared by the package.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from schemas.effects import NO_EFFECT
from sims.replay_plan import ReplayPlan, ReplayResult

__all__ = [
    "AMBIGUOUS",
    "DiscoveryResult",
    "Finding",
    "Params",
    "RereadCandidate",
    "merge_parameters",
]

#: What a finding says when two candidates cannot be told apart.
AMBIGUOUS = "ambiguous"

Params = dict[str, dict[str, Any]]


@dataclass(frozen=True)
class RereadCandidate:
    """A candidate judged on ropes read without it, though the ropes' identification
    reads it (:data:`schemas.effects.READ_WITH_THE_ROPES`): the refused winner or a
    contender beside it (:func:`discovery.iteration._to_reread`). Its name, the model's
    parameters with it at its linear fit, its fitted change in noise sigmas, its share of
    the trip resamples and its place in the ranking (0 the winner, 1 the runner-up).
    :func:`discovery.record_rereading.discover_in_record` tries it with the record read
    again (not reported)."""

    effect: str
    parameters: Params
    size_x_noise: float
    share: float
    place: int = 0


@dataclass(frozen=True)
class Finding:
    """One iteration's answer (one row of ``discovery_findings``).

    ``gap_before_pa`` is the model's own fit before the finding's effect was added
    (payloads fitted without it: what the model achieved, and what the decision ran
    on), ``gap_after_pa`` with it; ``gap_without_effect_pa`` the model after, the effect
    taken out, at the inputs (payloads, loading ramps, parameters) fitted with it
    (:func:`discovery.refit.gap_without`): ``gap_without_effect^2 - gap_after^2`` is the
    variance the effect itself accounts for, which the baseline's payloads partly took
    (their mean of the effect over each trip). Where nothing is added the three are the
    same. A winner added with the record read again (:mod:`discovery.record_rereading`)
    has the first plan's gap there: the effect taken out with the ropes read without
    it. ``reread``: the refused winner, and a contender beside it, to try that way in
    turn (not reported).
    """

    iteration: int
    effect: str
    parameters: dict[str, Any]
    retuned: dict[str, dict[str, Any]]
    confidence: float
    gap_before_pa: float
    gap_after_pa: float
    noise_pa: float
    variance_ratio: float
    autocorrelation_time: float
    ranking: list[dict[str, Any]]
    where: list[dict[str, Any]]
    ambiguous_between: tuple[str, ...] = ()
    excitation: str = ""
    message: str = ""
    gap_without_effect_pa: float | None = None
    reread: tuple[RereadCandidate, ...] = ()

    def __post_init__(self) -> None:
        if self.gap_without_effect_pa is None:
            object.__setattr__(self, "gap_without_effect_pa", self.gap_before_pa)


@dataclass
class DiscoveryResult:
    """All iterations of :func:`discover_effects` and the model they lead to."""

    plan: ReplayPlan
    findings: list[Finding]
    effects_before: tuple[str, ...]
    effects_after: tuple[str, ...]
    parameters_after: Params
    before: ReplayResult
    after: ReplayResult
    replays: int = 0
    notes: list[str] = field(default_factory=list)

    @property
    def effects_found(self) -> list[str]:
        return [f.effect for f in self.findings if f.effect not in (NO_EFFECT, AMBIGUOUS)]


def merge_parameters(params: Params, name: str, values: Mapping[str, Any]) -> Params:
    out = {k: dict(v) for k, v in params.items()}
    out[name] = {**out.get(name, {}), **values}
    return out
