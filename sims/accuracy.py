"""Compensated tensions against the simulation's truth, per hoist position visit.

A *visit* is a maximal run of samples labelled with one named position (pithead,
middle, bottom; ``transforms.kinematics.position_expr``). For each visit the mean
measured (uncompensated, p_sensor x A), compensated and true load and rope tensions
are compared: the synthetic counterpart of the paper's Table 2, with the true load
known instead of inferred from masses.
"""

from __future__ import annotations

import polars as pl

from schemas.tables import ROPES

__all__ = ["align_truth", "position_accuracy"]


def align_truth(tensions: pl.DataFrame, truth: pl.DataFrame) -> pl.DataFrame:
    """Join the truth's loads and tensions onto the compensated samples (nearest time).

    Logged timestamps are jittered and some samples dropped, so the join is as-of on
    the nearest truth sample (the truth is on the nominal grid).
    """
    truth_cols = truth.select(
        "time_utc",
        pl.col("load_n").alias("true_load_n"),
        *[pl.col(f"tension{i}_n").alias(f"true_tension{i}_n") for i in ROPES],
    ).sort("time_utc")
    return tensions.sort("time_utc").join_asof(truth_cols, on="time_utc", strategy="nearest")


def position_accuracy(
    tensions: pl.DataFrame, truth: pl.DataFrame, *, min_samples: int = 100
) -> pl.DataFrame:
    """Per position visit: errors of the load and of each rope, before and after compensation.

    Columns: ``visit``, ``position``, ``phase`` (the visit's most common phase),
    ``samples``, ``true_load_n``, ``load_before_n``, ``load_after_n``,
    ``error_before_fraction``, ``error_after_fraction`` (load), and
    ``rope_error_before_fraction`` / ``rope_error_after_fraction`` (the largest rope
    error of the visit, each rope's mean tension against its mean true tension).
    Visits shorter than ``min_samples`` are dropped.
    """
    aligned = align_truth(tensions, truth).with_columns(
        pl.col("position").ne_missing(pl.col("position").shift()).cum_sum().alias("visit")
    )
    aligned = aligned.filter(pl.col("position").is_not_null())
    per_visit = aligned.group_by("visit", maintain_order=True).agg(
        pl.col("position").first(),
        pl.col("phase").mode().first(),
        pl.len().alias("samples"),
        pl.col("true_load_n").mean(),
        pl.col("load_raw_n").mean().alias("load_before_n"),
        pl.col("load_n").mean().alias("load_after_n"),
        *[pl.col(f"true_tension{i}_n").mean() for i in ROPES],
        *[pl.col(f"tension_raw{i}_n").mean() for i in ROPES],
        *[pl.col(f"tension{i}_n").mean() for i in ROPES],
    )
    rope_before = [
        (pl.col(f"tension_raw{i}_n") / pl.col(f"true_tension{i}_n") - 1).abs() for i in ROPES
    ]
    rope_after = [(pl.col(f"tension{i}_n") / pl.col(f"true_tension{i}_n") - 1).abs() for i in ROPES]
    return per_visit.filter(pl.col("samples") >= min_samples).select(
        "visit",
        "position",
        "phase",
        "samples",
        "true_load_n",
        "load_before_n",
        "load_after_n",
        (pl.col("load_before_n") / pl.col("true_load_n") - 1).alias("error_before_fraction"),
        (pl.col("load_after_n") / pl.col("true_load_n") - 1).alias("error_after_fraction"),
        pl.max_horizontal(rope_before).alias("rope_error_before_fraction"),
        pl.max_horizontal(rope_after).alias("rope_error_after_fraction"),
    )
