"""Reconciliation: measured rope tensions against the load the hoist must carry.

Contents
--------
Expected load
    :func:`expected_load_expr` -- polars expression of the expected head-rope load.
Per position and per trip (paper Table 2 shape)
    :func:`reconcile` -- POSITION_SUMMARY and TRIP_SUMMARY frames from compensated samples.
    :func:`summarise_positions`, :func:`summarise_trips` -- the two halves.
Paper check
    :func:`table2_check` -- the field test of Song et al., section 5, Table 2.

The load on the four rope attachments of a Koepe conveyance is

.. math::

    F_\\mathrm{expected} = (m_c + m_p + m_t(z))\\,(g + a_\\uparrow),
    \\qquad m_t(z) = n_t\\,\\mu_t\\,(L_\\mathrm{shaft} - z + L_\\mathrm{loop})

with :math:`m_c` the conveyance mass [kg], :math:`m_p` the payload [kg], :math:`a_\\uparrow`
the upward acceleration of the conveyance [m/s2], :math:`m_t(z)` the mass of the tail
ropes hanging below the conveyance at depth :math:`z` [m] (:math:`n_t` ropes of
:math:`\\mu_t` kg/m), and :math:`g` = 9.80665 m/s2. The tail ropes hang from the
conveyance and accelerate with it, so they count with their inertia as well as their
weight (issue 13: the earlier ``(m_c + m_p)(g + a) + m_t g`` of issue 6 left the tail
rope's inertia out, 3.8-4.3 % low at departures on an independent simulator). The
tension from the loop at the shaft bottom is left out; at the named positions the
conveyance is at rest or at constant speed, where the acceleration terms vanish.

Inverting the same relation per sample gives the payload the measured (compensated) sum
of rope tensions implies:

.. math::

    m_p = \\frac{F_\\mathrm{measured}}{g + a_\\uparrow} - m_c - m_t(z)

A trip carries one payload, so the payloads inferred at its positions must agree; their
spread (max - min) is reported per trip.

References
----------
Song et al., "Hydraulic connection device ... wire rope tension and load", section 5 and
Table 2 (field test; NOTES.md lists the figures and the 145.2 / 141.8 kN erratum).
"""

from __future__ import annotations

from typing import NamedTuple

import polars as pl

from physics.tension import expected_load_n, tail_rope_length_m, tail_rope_mass_kg
from schemas.hoist import G_STANDARD, HoistDescription
from schemas.tables import POSITION_SUMMARY, ROPES, TRIP_SUMMARY, conform

__all__ = [
    "G_STANDARD",
    "PAPER_TEXT_PITHEAD_BEFORE_N",
    "Reconciliation",
    "StintCarry",
    "expected_load_expr",
    "reconcile",
    "stint_partials",
    "summarise_positions",
    "summarise_positions_from_partials",
    "summarise_trips",
    "summarise_trips_from_partials",
    "table2_check",
    "tail_rope_weight_expr",
    "trip_partials",
]

#: The pithead sum before compensation as printed in the paper's text (section 5.2).
#: Table 2's four ropes sum to 141.8 kN, and the text's own 9.7 % gain matches 141.8 kN,
#: so 145.2 kN is an erratum (NOTES.md); :func:`table2_check` uses the table.
PAPER_TEXT_PITHEAD_BEFORE_N = 145.2e3

PayloadSource = float | pl.DataFrame | None


class Reconciliation(NamedTuple):
    """Result of :func:`reconcile`: two frames with the Arrow schemas of schemas.tables."""

    position_summary: pl.DataFrame
    trip_summary: pl.DataFrame


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


def _inferred_payload_expr(hoist: HoistDescription) -> pl.Expr:
    """Per-sample payload [kg] implied by the compensated load ``load_n``."""
    accel = pl.col("acceleration_up_m_s2").fill_null(0.0)
    tail_mass_kg = tail_rope_mass_kg(hoist, pl.col("depth_m"))
    return pl.col("load_n") / (G_STANDARD + accel) - hoist.conveyance.mass_kg - tail_mass_kg


def _imbalance_expr(prefix: str) -> pl.Expr:
    """Largest |T_i - mean(T)| / mean(T) over the ropes, per row."""
    cols = [pl.col(f"{prefix}{i}_n") for i in ROPES]
    mean = pl.mean_horizontal(cols)
    return pl.max_horizontal([(c - mean).abs() for c in cols]) / mean


def _rope_imbalance_expr(prefix: str, rope: int) -> pl.Expr:
    """|T_rope - mean(T)| / mean(T) of one rope, per row (null where not a number)."""
    mean = pl.mean_horizontal([pl.col(f"{prefix}{i}_n") for i in ROPES])
    return ((pl.col(f"{prefix}{rope}_n") - mean).abs() / mean).fill_nan(None)


def _rope_extremes_aggs() -> list[pl.Expr]:
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


def _worst_rope_exprs() -> list[pl.Expr]:
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


_OPTIONAL = {"direction": pl.String, "acceleration_up_m_s2": pl.Float64, "phase": pl.String}

#: Trip phases whose samples infer the payload: the winder's acceleration is not the
#: conveyance's while the ropes stretch and bounce (accelerate / decelerate), so those
#: samples would bias the payload by the bounce (several hundred kg on the paper hoist).
STEADY_PHASES = ("run", "creep", "standstill")
#: Stints with fewer samples (a pass by the edge of a position's window) do not count
#: for a trip's payload spread.
MIN_STINT_SAMPLES = 5


def _trip_payload_expr() -> pl.Expr:
    """A trip's payload [kg]: its stints' inferred payloads weighted by their samples."""
    weight = pl.when(pl.col("payload_kg").is_not_null()).then(pl.col("samples"))
    return pl.when(weight.sum() > 0).then(
        (pl.col("payload_kg") * pl.col("samples")).sum() / weight.sum()
    )


def _trip_payload_spread_expr() -> pl.Expr:
    """Largest minus smallest stint payload [kg] of a trip (stints of enough samples)."""
    payload = pl.col("payload_kg").filter(pl.col("samples") >= MIN_STINT_SAMPLES)
    return payload.max() - payload.min()


def _lazy(frame: pl.LazyFrame | pl.DataFrame) -> pl.LazyFrame:
    """Lazy, ``trip_id`` as Int64; optional columns (direction, acceleration) null if absent."""
    lazy = frame.lazy() if isinstance(frame, pl.DataFrame) else frame
    names = lazy.collect_schema().names()
    missing = [pl.lit(None, dtype=t).alias(n) for n, t in _OPTIONAL.items() if n not in names]
    return lazy.with_columns(pl.col("trip_id").cast(pl.Int64), *missing)


def _with_reference_payload(frame: pl.DataFrame, payload_kg: PayloadSource) -> pl.DataFrame:
    """Add ``reference_payload_kg``: the known payload if given, else the trip's inferred one.

    Stints outside a trip (``trip_id`` null: standstill, where loading happens) have no
    inferred reference; they get the known payload when it is a float, else null.
    """
    inferred = pl.when(pl.col("trip_id").is_not_null()).then(_trip_payload_expr().over("trip_id"))
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


_STINT_MEANS = (
    "depth_m",
    *(f"tension_raw{i}_n" for i in ROPES),
    *(f"tension{i}_n" for i in ROPES),
    "load_raw_n",
    "load_n",
    "load_lo_n",
    "load_hi_n",
    "_payload_sample_kg",
)


class StintCarry(NamedTuple):
    """Where a block's stints continue from: the previous block's last ``position`` and
    ``trip_id`` and the number of stints so far (:func:`stint_partials`)."""

    position: str | None = None
    trip_id: int | None = None
    stints: int = 0


def stint_partials(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    hoist: HoistDescription,
    *,
    carry: StintCarry | None = None,
) -> tuple[pl.DataFrame, StintCarry]:
    """Sums, counts and extents per stint of one block of samples (issue 16).

    A stint is a run of consecutive samples with the same ``trip_id`` and ``position``
    (:func:`summarise_positions`); ``carry`` continues the numbering of the previous
    block, so a stint cut by a block edge gets one number in both. Concatenate the
    partials of every block and pass them to :func:`summarise_positions_from_partials`.
    """
    carry = carry or StintCarry()
    lazy = _lazy(rope_tensions).sort("time_utc")
    names = lazy.collect_schema().names()
    previous = [
        pl.lit(carry.position, dtype=pl.String),
        pl.lit(carry.trip_id, dtype=pl.Int64),
    ]
    changed = pl.col("position").ne_missing(
        pl.col("position").shift(1, fill_value=previous[0])
    ) | pl.col("trip_id").ne_missing(pl.col("trip_id").shift(1, fill_value=previous[1]))
    if carry.stints == 0:  # the record's first sample starts a stint
        changed = changed | (pl.int_range(pl.len()) == 0)
    steady = pl.col("phase").is_null() | pl.col("phase").is_in(STEADY_PHASES)
    numbered = lazy.with_columns(
        _stint=(changed.cast(pl.Int64).cum_sum() + (carry.stints - 1)),
        _payload_sample_kg=pl.when(steady).then(_inferred_payload_expr(hoist)),
    ).collect()
    if numbered.height == 0:
        return _empty_partials(), carry
    last = numbered.row(numbered.height - 1, named=True)
    following = StintCarry(last["position"], last["trip_id"], int(last["_stint"]) + 1)
    present = [c for c in _STINT_MEANS if c in names or c == "_payload_sample_kg"]
    partials = (
        numbered.lazy()
        .filter(pl.col("position").is_not_null())
        .group_by("_stint")
        .agg(
            pl.col("trip_id").first(),
            pl.col("position").first(),
            pl.col("time_utc").min().alias("time_start_utc"),
            pl.col("time_utc").max().alias("time_end_utc"),
            pl.col("acceleration_up_m_s2").fill_null(0.0).sum().alias("_sum_accel"),
            *(pl.col(c).cast(pl.Float64).sum().alias(f"_sum_{c}") for c in present),
            *(pl.col(c).count().cast(pl.Int64).alias(f"_n_{c}") for c in present),
            pl.len().cast(pl.Int64).alias("samples"),
        )
        .collect()
    )
    return partials, following


def _empty_partials() -> pl.DataFrame:
    return pl.DataFrame(
        schema={
            "_stint": pl.Int64,
            "trip_id": pl.Int64,
            "position": pl.String,
            "time_start_utc": pl.Datetime("us", "UTC"),
            "time_end_utc": pl.Datetime("us", "UTC"),
            "_sum_accel": pl.Float64,
            **{f"_sum_{c}": pl.Float64 for c in _STINT_MEANS},
            **{f"_n_{c}": pl.Int64 for c in _STINT_MEANS},
            "samples": pl.Int64,
        }
    )


def summarise_positions(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    hoist: HoistDescription,
    *,
    run_id: str,
    site: str | None = None,
    hoist_name: str | None = None,
    payload_kg: PayloadSource = None,
) -> pl.DataFrame:
    """One row per trip and named position: the paper's Table 2 for every trip.

    Samples count for a position where the ``position`` column names it (trip
    segmentation marks samples within the hoist's ``position_window`` of a named depth).
    One row per stint: a run of consecutive samples with the same ``trip_id`` and
    ``position`` (standstill samples carry no trip id and give one row per stay). A trip
    usually passes a position once, but a sample just outside the position window (the
    conveyance's bounce at a stop, a logger's jitter) splits a pass into two stints: the
    grain is ``(run_id, position, time_start_utc)``, not the trip and position
    (warehouse/README.md). Tensions are averaged over the stint; ``payload_kg`` is
    the payload inferred there from its steady samples (:data:`STEADY_PHASES`; null when
    the stint is all acceleration). ``expected_load_n`` uses the reference payload:
    ``payload_kg`` when known (a float for every trip, or a frame with ``trip_id`` and
    ``payload_kg``),
    otherwise the mean of the trip's inferred payloads, so the error then measures how
    far the positions disagree.

    The whole record is one block of :func:`stint_partials`. Returns a frame with the
    POSITION_SUMMARY schema.
    """
    partials, _ = stint_partials(rope_tensions, hoist)
    return summarise_positions_from_partials(
        partials, hoist, run_id=run_id, site=site, hoist_name=hoist_name, payload_kg=payload_kg
    )


def summarise_positions_from_partials(
    partials: pl.DataFrame,
    hoist: HoistDescription,
    *,
    run_id: str,
    site: str | None = None,
    hoist_name: str | None = None,
    payload_kg: PayloadSource = None,
) -> pl.DataFrame:
    """:func:`summarise_positions` from the :func:`stint_partials` of every block."""
    sums = [c for c in partials.columns if c.startswith("_sum_") and c != "_sum_accel"]
    counts = [f"_n_{c.removeprefix('_sum_')}" for c in sums]
    grouped = partials.group_by("_stint").agg(
        pl.col("trip_id").first(),
        pl.col("position").first(),
        pl.col("time_start_utc").min(),
        pl.col("time_end_utc").max(),
        pl.col("_sum_accel").sum(),
        *(pl.col(c).sum() for c in (*sums, *counts)),
        pl.col("samples").sum(),
    )
    alias = {
        "depth_m": "depth_m",
        "load_raw_n": "load_before_n",
        "load_n": "load_after_n",
        "load_lo_n": "load_after_lo_n",
        "load_hi_n": "load_after_hi_n",
        "_payload_sample_kg": "payload_kg",
        **{f"tension_raw{i}_n": f"tension_before{i}_n" for i in ROPES},
        **{f"tension{i}_n": f"tension_after{i}_n" for i in ROPES},
    }
    means = [
        pl.when(pl.col(f"_n_{c}") > 0).then(pl.col(f"_sum_{c}") / pl.col(f"_n_{c}")).alias(alias[c])
        for c in (s.removeprefix("_sum_") for s in sums)
    ]
    grouped = grouped.with_columns(*means, _accel_m_s2=pl.col("_sum_accel") / pl.col("samples"))
    expected = expected_load_expr(
        hoist,
        payload_kg=pl.col("reference_payload_kg"),
        acceleration_up_m_s2=pl.col("_accel_m_s2"),
    )
    result = (
        _with_reference_payload(grouped, payload_kg)
        .with_columns(
            run_id=pl.lit(run_id),
            site=pl.lit(site or hoist.hoist.site),
            hoist=pl.lit(hoist_name or hoist.hoist.name),
            tail_rope_length_m=tail_rope_length_m(hoist, pl.col("depth_m")),
            expected_load_n=expected,
            imbalance_after_fraction=_imbalance_expr("tension_after"),
        )
        .with_columns(
            error_before_fraction=pl.col("load_before_n") / pl.col("expected_load_n") - 1.0,
            error_after_fraction=pl.col("load_after_n") / pl.col("expected_load_n") - 1.0,
        )
        .sort("time_start_utc")
    )
    return conform(result, POSITION_SUMMARY)


def trip_partials(rope_tensions: pl.LazyFrame | pl.DataFrame) -> pl.DataFrame:
    """Extents and peaks per trip of one block of samples (:func:`summarise_trips`);
    concatenate the partials of every block for :func:`summarise_trips_from_partials`."""
    lazy = _lazy(rope_tensions)
    band = "load_hi_n" in lazy.collect_schema().names()
    return (
        lazy.filter(pl.col("trip_id").is_not_null())
        .sort("time_utc")
        .with_columns(_rope_imbalance_expr("tension", i).alias(f"_imbalance{i}") for i in ROPES)
        .group_by("trip_id")
        .agg(
            pl.col("direction").drop_nulls().first(),
            pl.col("time_utc").first().alias("time_start_utc"),
            pl.col("time_utc").last().alias("time_end_utc"),
            pl.col("depth_m").drop_nulls().first().alias("depth_start_m"),
            pl.col("depth_m").drop_nulls().last().alias("depth_end_m"),
            pl.col("load_n").max().alias("max_load_after_n"),
            *([pl.col("load_hi_n").max().alias("max_load_after_hi_n")] if band else []),
            *_rope_extremes_aggs(),
        )
        .collect()
    )


def summarise_trips(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    position_summary: pl.DataFrame,
    *,
    run_id: str,
    site: str,
    hoist_name: str,
) -> pl.DataFrame:
    """One row per trip: extent, payload (over positions, by samples) and its spread, peaks.

    Peaks are over the trip's samples after compensation: ``max_load_after_n``; per rope
    i the largest and smallest tension and the largest imbalance |T_i - mean T| / mean T
    with the time of its sample (``max_imbalance_after{i}_fraction``, ``..._time_utc``);
    and the worst rope's: ``max_imbalance_after_fraction`` (the largest per-sample
    rope-to-mean imbalance of the trip), ``max_imbalance_after_rope`` (1-4, the lowest on
    a tie) and ``max_imbalance_after_time_utc``. Returns the TRIP_SUMMARY schema.
    """
    return summarise_trips_from_partials(
        trip_partials(rope_tensions),
        position_summary,
        run_id=run_id,
        site=site,
        hoist_name=hoist_name,
    )


def summarise_trips_from_partials(
    partials: pl.DataFrame,
    position_summary: pl.DataFrame,
    *,
    run_id: str,
    site: str,
    hoist_name: str,
) -> pl.DataFrame:
    """:func:`summarise_trips` from the :func:`trip_partials` of every block."""
    band = "max_load_after_hi_n" in partials.columns
    extremes = []
    for i in ROPES:
        imbalance = pl.col(f"max_imbalance_after{i}_fraction")
        extremes += [
            pl.col(f"max_tension_after{i}_n").max(),
            pl.col(f"min_tension_after{i}_n").min(),
            imbalance.max(),
            pl.col(f"max_imbalance_after{i}_time_utc")
            .sort_by(imbalance, descending=True, nulls_last=True, maintain_order=True)
            .first(),
        ]
    trips = (
        partials.sort("time_start_utc")
        .group_by("trip_id", maintain_order=True)
        .agg(
            pl.col("direction").drop_nulls().first(),
            pl.col("time_start_utc").first(),
            pl.col("time_end_utc").last(),
            pl.col("depth_start_m").drop_nulls().first(),
            pl.col("depth_end_m").drop_nulls().last(),
            pl.col("max_load_after_n").max(),
            *([pl.col("max_load_after_hi_n").max()] if band else []),
            *extremes,
        )
        .with_columns(_worst_rope_exprs())
    )
    payloads = (
        position_summary.filter(pl.col("trip_id").is_not_null())
        .with_columns(pl.col("trip_id").cast(pl.Int64))
        .group_by("trip_id")
        .agg(
            _trip_payload_expr().alias("payload_kg"),
            _trip_payload_spread_expr().alias("payload_spread_kg"),
        )
    )
    result = (
        trips.join(payloads, on="trip_id", how="left")
        .with_columns(run_id=pl.lit(run_id), site=pl.lit(site), hoist=pl.lit(hoist_name))
        .sort("trip_id")
    )
    return conform(result, TRIP_SUMMARY)


def reconcile(
    rope_tensions: pl.LazyFrame | pl.DataFrame,
    hoist: HoistDescription,
    *,
    run_id: str,
    site: str | None = None,
    hoist_name: str | None = None,
    payload_kg: PayloadSource = None,
) -> Reconciliation:
    """Per-position and per-trip reconciliation of compensated rope tensions.

    ``rope_tensions`` has the ROPE_TENSIONS columns (``time_utc``, ``depth_m``,
    ``acceleration_up_m_s2``, ``trip_id``, ``direction``, ``position``,
    ``tension_raw{i}_n``, ``tension{i}_n``, ``load_raw_n``, ``load_n``). ``payload_kg``:
    see :func:`summarise_positions`. ``site``/``hoist_name`` default to the description's.
    """
    site = site or hoist.hoist.site
    hoist_name = hoist_name or hoist.hoist.name
    positions = summarise_positions(
        rope_tensions, hoist, run_id=run_id, site=site, hoist_name=hoist_name, payload_kg=payload_kg
    )
    trips = summarise_trips(
        rope_tensions, positions, run_id=run_id, site=site, hoist_name=hoist_name
    )
    return Reconciliation(positions, trips)


def table2_check(table2: pl.DataFrame, hoist: HoistDescription) -> pl.DataFrame:
    """Reproduce the paper's Table 2 check: tension sums against the hoist's weight.

    ``table2`` holds the columns of ``table2_field_test.csv`` (kN and t as printed).
    The expected load is the printed total mass times g (the cage is at rest and empty:
    total = 8.2 t cage + tail rope). Returned per position, in SI:

    - ``sum_before_n``/``sum_after_n``: the four ropes summed here (the printed sums are
      kept as ``table_sum_*_n`` to show they agree);
    - ``expected_load_n`` = total_mass_t x 1000 x g; ``expected_from_hoist_n`` =
      ``hoist.static_load_n`` at the position's depth (cage + tail rope from the
      description), an independent route to the same number;
    - ``error_before_fraction``/``error_after_fraction`` = sum / expected - 1;
    - ``gain_fraction`` = after / before - 1 (the paper's "compensation rate");
    - ``imbalance_before_fraction``/``imbalance_after_fraction``: largest
      |T_i - mean| / mean;
    - ``tail_rope_mass_kg`` = n_t x mu_t x length from the description, beside the
      printed ``table_tail_rope_mass_kg``.

    Erratum: the text's pithead "145.2 kN" before compensation
    (:data:`PAPER_TEXT_PITHEAD_BEFORE_N`) is not what Table 2 sums to (141.8 kN); only
    141.8 kN gives the stated 9.7 % gain. The table is used here.
    """
    kn = 1e3
    before = [pl.col(f"before_kn_{i}") * kn for i in ROPES]
    after = [pl.col(f"after_kn_{i}") * kn for i in ROPES]

    def imbalance(cols: list[pl.Expr]) -> pl.Expr:
        mean = pl.mean_horizontal(cols)
        return pl.max_horizontal([(c - mean).abs() for c in cols]) / mean

    depth = hoist.shaft.depth_m + hoist.shaft.tail_rope_loop_m - pl.col("tail_rope_length_m")
    return table2.select(
        pl.col("position"),
        pl.col("tail_rope_length_m").cast(pl.Float64),
        depth.alias("depth_m"),
        pl.sum_horizontal(before).alias("sum_before_n"),
        pl.sum_horizontal(after).alias("sum_after_n"),
        (pl.col("sum_before_kn") * kn).alias("table_sum_before_n"),
        (pl.col("sum_after_kn") * kn).alias("table_sum_after_n"),
        (pl.col("total_mass_t") * 1e3 * G_STANDARD).alias("expected_load_n"),
        expected_load_expr(
            hoist, depth_m=depth, acceleration_up_m_s2=pl.lit(0.0), payload_kg=0.0
        ).alias("expected_from_hoist_n"),
        imbalance(before).alias("imbalance_before_fraction"),
        imbalance(after).alias("imbalance_after_fraction"),
        tail_rope_mass_kg(hoist, depth).alias("tail_rope_mass_kg"),
        (pl.col("tail_rope_mass_t") * 1e3).alias("table_tail_rope_mass_kg"),
    ).with_columns(
        error_before_fraction=pl.col("sum_before_n") / pl.col("expected_load_n") - 1.0,
        error_after_fraction=pl.col("sum_after_n") / pl.col("expected_load_n") - 1.0,
        gain_fraction=pl.col("sum_after_n") / pl.col("sum_before_n") - 1.0,
    )
