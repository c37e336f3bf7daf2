"""Where the replay gap is: the residual's RMS per operating region, largest first."""

from __future__ import annotations

from typing import Any

import numpy as np

from discovery.layout import EntryLayout
from sims.replay_plan import ReplayPlan

__all__ = ["locate_gap", "rms"]


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def locate_gap(
    plan: ReplayPlan,
    layout_or_none: Any,
    before: np.ndarray,
    after: np.ndarray | None = None,
    *,
    top: int = 6,
    min_entries: int = 40,
) -> list[dict[str, Any]]:
    """Regions where the residual is large: RMS per trip phase, direction, shaft position,
    oil temperature band, pressure level band and cylinder, largest first.

    Each region: ``start``/``end`` (UTC ISO of its first and last sample), ``regime``
    (e.g. ``"phase=accelerate"``), ``gap_pa`` (RMS before), ``gap_after_pa`` and
    ``entries``.
    """
    lay: EntryLayout = layout_or_none
    hoist = plan.hoist
    labels: dict[str, np.ndarray] = {
        "phase": lay.phase.astype(str),
        "direction": lay.direction.astype(str),
        "cylinder": np.array([f"{i + 1}" for i in range(hoist.ropes_n)])[lay.sensor],
    }
    pos = np.full(lay.depth_m.size, "shaft", dtype=object)
    for name, d in hoist.shaft.positions_m.items():
        pos[np.abs(lay.depth_m - d) <= hoist.shaft.position_window_m] = name
    labels["position"] = pos.astype(str)
    oil = lay.oil_temp_c
    if oil.size and np.ptp(oil) > 2.0:
        edges = np.linspace(oil.min(), oil.max(), 4)
        band = np.clip(np.digitize(oil, edges[1:-1]), 0, 2)
        names = [f"{edges[b]:.0f}-{edges[b + 1]:.0f} degC" for b in range(3)]
        labels["oil_temp"] = np.array(names)[band]
    lvl = lay.level_pa
    if lvl.size:
        q = np.quantile(lvl, [1 / 3, 2 / 3])
        band = np.digitize(lvl, q)
        names = [
            f"low (< {q[0] / 1e6:.2f} MPa)",
            f"mid ({q[0] / 1e6:.2f}-{q[1] / 1e6:.2f} MPa)",
            f"high (> {q[1] / 1e6:.2f} MPa)",
        ]
        labels["pressure"] = np.array(names)[band]
    regions = []
    for dim, lab in labels.items():
        for value in np.unique(lab):
            sel = lab == value
            if sel.sum() < min_entries:
                continue
            times = plan.time_utc(lay.time_s[sel])
            regions.append(
                {
                    "start": times.min().isoformat(),
                    "end": times.max().isoformat(),
                    "regime": f"{dim}={value}",
                    "gap_pa": round(rms(before[sel]), 1),
                    "gap_after_pa": None if after is None else round(rms(after[sel]), 1),
                    "entries": int(sel.sum()),
                }
            )
    regions.sort(key=lambda r: -r["gap_pa"])
    return regions[:top]
