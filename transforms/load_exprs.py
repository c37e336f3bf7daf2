"""Polars expressions of the reconciliation: expected load, inferred payload, imbalance.

The load the head ropes must carry (:func:`physics.tension.expected_load_n`, paper eq
3-4 with Table 2's masses) as an expression of a frame's columns, the payload that the
compensated load implies, and the rope imbalance; shared by the position and trip
summaries (:mod:`transforms.position_summary`, :mod:`transforms.trip_summary`) and the
alarms.
"""

from __future__ import annotations

import polars as pl

from physics.tension import expected_load_n, tail_rope_mass_kg
from schemas.hoist import G_STANDARD, HoistDescription
from schemas.tables import ROPES

__all__ = [
    "MIN_STINT_SAMPLES",
    "OPTIONAL_COLUMNS",
    "STEADY_PHASES",
    "PayloadSource",
    "expected_load_expr",
    "imbalance_expr",
    "inferred_payload_expr",
    "rope_extremes_aggs",
    "rope_imbalance_expr",
    "tail_rope_weight_expr",
    "trip_payload_expr",
    "trip_payload_spread_expr",
    "with_optional_columns",
    "with_reference_payload",
    "worst_rope_exprs",
]

#: A payload: one value for every trip [kg], a frame of ``trip_id, payload_kg``, or None
#: (inferred from the trip's steady samples).
PayloadSource = float | pl.DataFrame | None


def tail_rope_weight_expr(hoist: HoistDescription, depth_m: pl.Expr | None = None) -> pl.Expr:
    """Weight of the tail ropes hanging below the conveyance [N], m_t(z) g."""
    depth = pl.col("depth_m") if depth_m is None else depth_m
    return tail_rope_mass_kg(hoist, depth) * G_STANDARD


def expected_load_expr(
    hoist: HoistDescription,
    *,
    payload_kg: pl.Expr | float = 0.0,
    depth_m: pl.Expr | None = None,
    acceleration_up_m_s2: pl.Expr | None = None,
) -> pl.Expr:
    """Expected head-rope load [N] of the columns (:func:`physics.tension.expected_load_n`).

    ``depth_m`` and ``acceleration_up_m_s2`` default to the columns of that name; a null
    acceleration counts as zero.
    """
    depth = pl.col("depth_m") if depth_m is None else depth_m
    accel = pl.col("acceleration_up_m_s2") if acceleration_up_m_s2 is None else acceleration_up_m_s2
    payload = payload_kg if isinstance(payload_kg, pl.Expr) else pl.lit(float(payload_kg))
    return expected_load_n(hoist, depth, payload, accel.fill_null(0.0))


def inferred_payload_expr(hoist: HoistDescription) -> pl.Expr:
    """Per-sample payload [kg] implied by the compensated load ``load_n``."""
    accel = pl.col("acceleration_up_m_s2").fill_null(0.0)
    tail_mass_kg = tail_rope_mass_kg(hoist, pl.col("depth_m"))
    return pl.col("load_n") / (G_STANDARD + accel) - hoist.conveyance.mass_kg - tail_mass_kg


def imbalance_expr(prefix: str) -> pl.Expr:
    """Largest |T_i - mean(T)| / mean(T) over the ropes, per row."""
    cols = [pl.col(f"{prefix}{i}_n") for i in ROPES]
    mean = pl.mean_horizontal(cols)
    return pl.max_horizontal([(c - mean).abs() for c in cols]) / mean


def rope_imbalance_expr(prefix: str, rope: int) -> pl.Expr:
    """|T_rope - mean(T)| / mean(T) of one rope, per row (null where not a number)."""
    mean = pl.mean_horizontal([pl.col(f"{prefix}{i}_n") for i in ROPES])
    return ((pl.col(f"{prefix}{rope}_n") - mean).abs() / mean).fill_nan(None)


def rope_extremes_aggs() -> list[pl.Expr]:
    """Per rope over a group of samples, after compensation: largest and smallest
    tension, largest imbalance and the time of its sample (``_imbalance{i}`` columns)."""
    aggs = []
    for i in ROPES:
        tension, imbalance = pl.col(f"tension{i}_n").fill_nan(None), pl.col(f"_imbalance{i}")
        peak_time = pl.col("time_utc").sort_by(imbalance, descending=True, nulls_last=True)
        aggs += [
            tension.max().alias(f"max_tension_after{i}_n"),
            tension.min().alias(f"min_tension_after{i}_n"),
            imbalance.max().alias(f"max_imbalance_after{i}_fraction"),
            pl.when(imbalance.max().is_not_null())
            .then(peak_time.first())
            .alias(f"max_imbalance_after{i}_time_utc"),
        ]
    return aggs


def worst_rope_exprs() -> list[pl.Expr]:
    """The trip's worst rope (lowest number on a tie), its imbalance and when."""
    per_rope = [pl.col(f"max_imbalance_after{i}_fraction") for i in ROPES]
    worst = pl.max_horizontal(per_rope)
    rope = pl.when(per_rope[0] == worst).then(pl.lit(ROPES[0], dtype=pl.Int32))
    time = pl.when(per_rope[0] == worst).then(pl.col(f"max_imbalance_after{ROPES[0]}_time_utc"))
    for i, column in zip(ROPES[1:], per_rope[1:], strict=True):
        rope = rope.when(column == worst).then(pl.lit(i, dtype=pl.Int32))
        time = time.when(column == worst).then(pl.col(f"max_imbalance_after{i}_time_utc"))
    return [
        worst.alias("max_imbalance_after_fraction"),
        rope.alias("max_imbalance_after_rope"),
        time.alias("max_imbalance_after_time_utc"),
    ]


OPTIONAL_COLUMNS = {"direction": pl.String, "acceleration_up_m_s2": pl.Float64, "phase": pl.String}

#: Trip phases whose samples infer the payload: the winder's acceleration is not the
#: conveyance's while the ropes stretch and bounce (accelerate / decelerate), so those
#: samples would bias the payload by the bounce (several hundred kg on the paper hoist).
STEADY_PHASES = ("run", "creep", "standstill")
#: Stints with fewer samples (a pass by the edge of a position's window) do not count
#: for a trip's payload spread.
MIN_STINT_SAMPLES = 5


def trip_payload_expr() -> pl.Expr:
    """A trip's payload [kg]: its stints' inferred payloads weighted by their samples."""
    weight = pl.when(pl.col("payload_kg").is_not_null()).then(pl.col("samples"))
    return pl.when(weight.sum() > 0).then(
        (pl.col("payload_kg") * pl.col("samples")).sum() / weight.sum()
    )


def trip_payload_spread_expr() -> pl.Expr:
    """Largest minus smallest stint payload [kg] of a trip (stints of enough samples)."""
    payload = pl.col("payload_kg").filter(pl.col("samples") >= MIN_STINT_SAMPLES)
    return payload.max() - payload.min()


def with_optional_columns(frame: pl.LazyFrame | pl.DataFrame) -> pl.LazyFrame:
    """Lazy, ``trip_id`` as Int64; optional columns (direction, acceleration) null if absent."""
    lazy = frame.lazy() if isinstance(frame, pl.DataFrame) else frame
    names = lazy.collect_schema().names()
    missing = [
        pl.lit(None, dtype=t).alias(n) for n, t in OPTIONAL_COLUMNS.items() if n not in names
    ]
    return lazy.with_columns(pl.col("trip_id").cast(pl.Int64), *missing)


def with_reference_payload(frame: pl.DataFrame, payload_kg: PayloadSource) -> pl.DataFrame:
    """Add ``reference_payload_kg``: the known payload if given, else the trip's inferred one.

    Stints outside a trip (``trip_id`` null: standstill, where loading happens) have no
    inferred reference; they get the known payload when it is a float, else null.
    """
    inferred = pl.when(pl.col("trip_id").is_not_null()).then(trip_payload_expr().over("trip_id"))
    if payload_kg is None:
        return frame.with_columns(reference_payload_kg=inferred)
    if isinstance(payload_kg, pl.DataFrame):
        known = payload_kg.select(
            pl.col("trip_id").cast(pl.Int64), pl.col("payload_kg").alias("_known_payload_kg")
        )
        return (
            frame.join(known, on="trip_id", how="left")
            .with_columns(reference_payload_kg=pl.coalesce("_known_payload_kg", inferred))
            .drop("_known_payload_kg")
        )
    return frame.with_columns(reference_payload_kg=pl.lit(float(payload_kg)))
