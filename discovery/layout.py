"""The scored entries of a replay laid out flat: one row per (trip, sample, sensor).

Discovery's least squares run over every valid scored entry of every planned trip at
once; :class:`EntryLayout` keeps, per entry, its trip, sensor, time, trip phase, direction,
depth, oil temperature, pressure level and measured value, and flattens any per-trip
(m_k, n) arrays (simulated pressures) in the same order.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from sims.replay_plan import ReplayPlan, ReplayResult

__all__ = ["EntryLayout", "entry_layout"]


@dataclass(frozen=True)
class EntryLayout:
    mask: tuple[np.ndarray, ...]  # per trip (m_k, n) entries used
    trip: np.ndarray
    sensor: np.ndarray
    time_s: np.ndarray
    phase: np.ndarray
    direction: np.ndarray
    depth_m: np.ndarray
    oil_temp_c: np.ndarray
    level_pa: np.ndarray
    y: np.ndarray

    def flat(self, arrays: Iterable[np.ndarray]) -> np.ndarray:
        return np.concatenate([a[m] for a, m in zip(arrays, self.mask, strict=True)])

    def trip_columns(self, trips: int) -> np.ndarray:
        """(entries, ``trips``) indicator columns, 1 where an entry is of that trip: the
        per-trip common-mode nuisance (each trip's payload) of the least squares."""
        columns = np.zeros((self.y.size, trips))
        columns[np.arange(self.y.size), self.trip] = 1.0
        return columns


def entry_layout(plan: ReplayPlan, base: ReplayResult) -> EntryLayout:
    masks, cols = [], {k: [] for k in ("trip", "sensor", "t", "ph", "dir", "d", "oil", "lvl")}
    for k, (tr, sim) in enumerate(zip(plan.trips, base.simulated, strict=True)):
        m = tr.valid & np.isfinite(sim) & np.isfinite(tr.measured_pa)
        masks.append(m)
        rows, sens = np.nonzero(m)
        n_s = m.shape[1]
        level = np.nanmean(tr.measured_pa, axis=1)
        cols["trip"].append(np.full(rows.size, k))
        cols["sensor"].append(sens)
        cols["t"].append(tr.time_s[rows])
        cols["ph"].append(tr.phase[rows])
        direction = np.where(tr.phase == "standstill", "rest", tr.direction)
        cols["dir"].append(direction[rows])
        cols["d"].append(tr.depth_m[rows])
        cols["oil"].append(np.full(rows.size, tr.oil_temp_c))
        cols["lvl"].append(level[rows])
        del n_s
    cat = {k: np.concatenate(v) if v else np.zeros(0) for k, v in cols.items()}
    y = np.concatenate([tr.measured_pa[m] for tr, m in zip(plan.trips, masks, strict=True)])
    return EntryLayout(
        tuple(masks),
        cat["trip"].astype(int),
        cat["sensor"].astype(int),
        cat["t"],
        cat["ph"],
        cat["dir"],
        cat["d"],
        cat["oil"],
        cat["lvl"],
        y,
    )
