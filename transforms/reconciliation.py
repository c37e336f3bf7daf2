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

from physics.tension import tail_rope_mass_kg
from schemas.hoist import G_STANDARD, HoistDescription
from schemas.tables import ROPES
from transforms.load_exprs import (
    STEADY_PHASES,
    PayloadSource,
    expected_load_expr,
    tail_rope_weight_expr,
)
from transforms.position_summary import (
    StintCarry,
    stint_partials,
    summarise_positions,
    summarise_positions_from_partials,
)
from transforms.trip_summary import summarise_trips, summarise_trips_from_partials, trip_partials

# the two summaries and the expressions are part of this module's interface
__all__ = [
    "G_STANDARD",
    "PAPER_TEXT_PITHEAD_BEFORE_N",
    "STEADY_PHASES",
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


class Reconciliation(NamedTuple):
    """Result of :func:`reconcile`: two frames with the Arrow schemas of schemas.tables."""

    position_summary: pl.DataFrame
    trip_summary: pl.DataFrame


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
      :func:`physics.tension.expected_load_n` at the position's depth (cage + tail rope from the
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
