"""The head ropes' constants a replay takes from the compensation (issue 14).

The replay (:func:`discovery.planning.plan_replay`) needs to know how the head ropes'
stiffnesses differ, and which rope is which: while the pistons stick, rope i takes
``k_i / sum(k)`` of a load change, and the piston pushed hardest slides first. It also
needs the ropes' length offsets, to start a block with its pistons where the record
logged them and the seals holding what the ropes leave them
(:func:`sims.replay.block_pistons`). The compensation identifies both from the logged
piston positions (:mod:`transforms.rope_identification`); discovery imports no
transforms, so the pipelines that replay a record (the sanity check, ``ropeload
discover``) bring the identified ropes with them (``identified_ropes=``).

The identification reads the record's first two hours (its 0.2 s means) and is
remembered in ``<data>/cache/rope_springs`` by a digest of those means and the hoist:
a sanity check that reads its samples from where its run's record starts
(:func:`pipelines.run_period.record_start`) takes the run's ropes from there instead of
identifying them again. Where no run identified them (``ropeload discover`` on a record
not yet run), only the whole record's ropes are searched, not the alternatives the
compensation's band takes from its quarters (a third of the time).
"""

from __future__ import annotations

import polars as pl

from schemas.hoist import HoistDescription
from transforms.compensation import CompensationSettings
from transforms.compensation_record import identification_means
from transforms.rope_identification import identify_from_means
from transforms.stick_slip_band import RopeSprings
from warehouse.store import DataRoot

__all__ = ["identified_ropes"]


def identified_ropes(
    samples: pl.DataFrame,
    hoist: HoistDescription,
    *,
    data: DataRoot | None = None,
    settings: CompensationSettings | None = None,
) -> RopeSprings | None:
    """The head ropes' constants (each one's stiffness relative to the description's EA
    and its length offset) as the compensation identifies them from ``samples`` (landed
    field samples of one hoist, the record from its first sample); None when nothing
    identifies them (no logged piston positions, no piston motion, no constants within
    the bounds fit the logged x) or the description states its ropes' factors (the
    replay keeps those); as the run, only when every rope's displacement is logged
    somewhere in ``samples`` and ``settings.rope_springs``.

    ``data``: the data root whose ``cache/rope_springs`` remembers identified ropes;
    ``settings``: the compensation's (the seals' drift travel, where they drift).
    """
    settings = settings or CompensationSettings()
    x_columns = [f"x{i}_m" for i in range(1, hoist.ropes_n + 1)]
    if (
        hoist.ropes.head_rope_stiffness_factors is not None
        or not settings.rope_springs
        or samples.height == 0
        or not all(_logged(samples, c) for c in x_columns)
    ):
        return None
    record = samples.sort("time_utc")
    means = identification_means(record, record["time_utc"][0], hoist, settings)
    cache = None if data is None else data.under("cache", "rope_springs")
    springs = identify_from_means(means, hoist, cache_dir=cache, alternatives=False)
    return springs


def _logged(samples: pl.DataFrame, column: str) -> bool:
    """The column has a value somewhere (the run identifies the ropes only then:
    ``CompensationContext.has_x``, every rope's displacement logged somewhere)."""
    if column not in samples.columns:
        return False
    values = samples[column].cast(pl.Float64)
    return bool(values.is_finite().fill_null(False).any())
