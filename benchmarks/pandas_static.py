"""The baseline of ``bench_day.py``: the paper's static compensation as a plain pandas script.

What a hoist engineer would script without ropeload, per sample and rope i (paper eq 2
with the friction of eq 17's Coulomb line and no dynamics, no pipe loss, no filtering):

    v_i = dx_i / dt,   F_i = sign(v_i) F_c(p_i),   T_i = p_i A + F_i,   load = sum_i T_i

Read the contract-1a CSV (``#`` header lines, MPa and mm), convert to SI, compute the four
tensions and the load, write Parquet. Not used by ropeload; a yardstick for speed only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from schemas.hoist import load_hoist

__all__ = ["static_compensation"]


def static_compensation(csv: Path, hoist_path: Path, out: Path) -> int:
    """Compensate ``csv`` statically with the hoist's bore and friction law; rows written."""
    hoist = load_hoist(hoist_path)
    area = hoist.cylinders.bore_area_m2
    a, b = hoist.friction_law.coulomb_n
    frame = pd.read_csv(csv, comment="#")
    frame["time_utc"] = (
        pd.to_datetime(frame["timestamp"]).dt.tz_localize(hoist.hoist.timezone).dt.tz_convert("UTC")
    )
    dt_s = frame["time_utc"].diff().dt.total_seconds()
    load = np.zeros(len(frame))
    for i in range(1, 5):
        p = frame[f"p{i}"] * 1e6
        x = frame[f"x{i}"] * 1e-3
        v = x.diff() / dt_s
        friction = np.sign(v.fillna(0.0)) * np.maximum(a + b * p, 0.0)
        frame[f"tension{i}_n"] = p * area + friction
        load += frame[f"tension{i}_n"].to_numpy()
    frame["load_n"] = load
    columns = ["time_utc", *(f"tension{i}_n" for i in range(1, 5)), "load_n"]
    frame[columns].to_parquet(out)
    return len(frame)
