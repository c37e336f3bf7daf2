"""The rows a compensated block returns: rope tensions, loads and their bands.

:func:`block_frame` sums the ropes into the load (paper eq 3-4, before and after the
compensation), adds the load's 95 % band (:func:`transforms.uncertainty.load_band`) and
lays the columns out as ``ROPE_TENSIONS``.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from schemas.tables import ROPE_TENSIONS, polars_schema
from transforms.compensation_kernels import load_kernel
from transforms.compensation_record import rope_cols
from transforms.stick_slip_band import BAND_SOURCES
from transforms.uncertainty import (
    disagreeing_sensor_shifts,
    ensemble_band,
    load_band,
    widen_for_shifts,
)

__all__ = ["OUTPUT_SCHEMA", "block_frame"]

#: The polars schema of a ``ROPE_TENSIONS`` frame.
OUTPUT_SCHEMA = polars_schema(ROPE_TENSIONS)


def _nullable(name: str, values: np.ndarray, dtype: type = pl.Float64) -> pl.Series:
    """``values`` as a column, NaN (no value: a pressure not logged) as null: in SQL a
    NaN is greater than every number, so an analyst's max() of a tension would be NaN."""
    series = pl.Series(name, values, dtype=dtype)
    return series.fill_nan(None) if np.isnan(values).any() else series


def _shifted_band(
    lo: np.ndarray, hi: np.ndarray, shift: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``[lo, hi]`` reaching ``[lo + shift, hi + shift]`` too (NaN shift: as it is).

    >>> [v.tolist() for v in _shifted_band(np.zeros(2), np.ones(2), np.array([3.0, -0.5]))]
    [[0.0, -0.5], [4.0, 1.0]]
    """
    shift = np.nan_to_num(shift)
    low, high = widen_for_shifts(lo, lo, hi, shift)
    return widen_for_shifts(hi, low, high, shift)


def block_frame(
    rows: pl.DataFrame,
    accel_up: np.ndarray,
    labels: dict[str, pl.Series],
    pressures: list[np.ndarray],
    columns: dict[str, np.ndarray],
    load_raw: np.ndarray,
    gaussian_sigma_n: tuple[float, float],
    *,
    load_members: list[np.ndarray] | None = None,
    member_sources: tuple[int, ...] | None = None,
    off_sensors: list[np.ndarray] | None = None,
    area_m2: float = 0.0,
    reading_shifts: list[np.ndarray] | None = None,
) -> pl.DataFrame:
    """The block's ``ROPE_TENSIONS`` rows.

    ``rows`` the block's input rows (time, depth, speed), ``accel_up`` the conveyance's
    acceleration [m/s2] up, ``labels`` the trip columns, ``pressures`` the filtered
    pressures, ``columns`` each rope's output arrays by column name; ``load_raw`` is
    overwritten with the raw load; ``gaussian_sigma_n`` = (relative friction sigma,
    pressure noise [N]) of the band; ``load_members`` the summed frictions of the
    stick-slip band's members (:func:`transforms.uncertainty.ensemble_band`), if any,
    ``member_sources`` the source of each (its ``groups``); ``off_sensors`` where each
    sensor departs from the others at rest (:func:`transforms.compensation_record.
    disagreeing_as_unknown`), whose rope's band and the load's then reach the others'
    reading too (:func:`transforms.uncertainty.disagreeing_sensor_shifts`, ``area_m2``
    the piston's); ``reading_shifts`` each rope's tension shift were its sensor reading
    as the others do at the record's rests (a sensor apart there by less than the
    disagreement limit, :func:`transforms.compensation_record.sensor_departures`), which
    its band and the load's reach too.
    """
    load = np.empty(rows.height)
    load_kernel(
        tuple(columns[c] for c in rope_cols("tension_raw{i}_n")),
        tuple(columns[c] for c in rope_cols("tension{i}_n")),
        load_raw,
        load,
    )
    frictions = [columns[c] for c in rope_cols("friction{i}_n")]
    if load_members is not None:
        noise = gaussian_sigma_n[1] * np.sqrt(len(frictions))  # independent sensors
        seals = gaussian_sigma_n[0] * np.sqrt(sum(f * f for f in frictions))  # and seals
        load_lo, load_hi = ensemble_band(
            load,
            sum(frictions),
            load_members,
            noise,
            seal_sigma_n=seals,
            groups=member_sources,
            law_group=BAND_SOURCES.index("law"),
        )
    else:
        load_lo, load_hi = load_band(
            load,
            [columns[c] for c in rope_cols("tension{i}_lo_n")],
            [columns[c] for c in rope_cols("tension{i}_hi_n")],
            [columns[c] for c in rope_cols("tension{i}_n")],
            frictions,
            gaussian_sigma_n=gaussian_sigma_n,
        )
    if off_sensors is not None:
        shifts = disagreeing_sensor_shifts(pressures, off_sensors, area_m2)
        for i, shift in zip(rope_cols("{i}"), shifts, strict=True):
            lo, hi = f"tension{i}_lo_n", f"tension{i}_hi_n"
            columns[lo], columns[hi] = widen_for_shifts(
                columns[f"tension{i}_n"], columns[lo], columns[hi], shift
            )
        load_lo, load_hi = widen_for_shifts(load, load_lo, load_hi, sum(shifts))
    if reading_shifts is not None:  # the band reaches the other reading's band whole
        for i, shift in zip(rope_cols("{i}"), reading_shifts, strict=True):
            lo, hi = f"tension{i}_lo_n", f"tension{i}_hi_n"
            columns[lo], columns[hi] = _shifted_band(columns[lo], columns[hi], shift)
        load_lo, load_hi = _shifted_band(load_lo, load_hi, sum(reading_shifts))
    p_cols = rope_cols("p{i}_pa")
    out: dict[str, pl.Series] = {
        "time_utc": rows["time_utc"],
        "depth_m": rows["depth_m"],
        "speed_m_s": rows["speed_m_s"],
        "acceleration_up_m_s2": _nullable("acceleration_up_m_s2", accel_up),
        **labels,
        **{c: _nullable(c, v) for c, v in zip(p_cols, pressures, strict=True)},
        **{
            name: _nullable(name, values, pl.Float32)  # the band (schemas.tables)
            if name.endswith(("_lo_n", "_hi_n"))
            else _nullable(name, values)
            for name, values in columns.items()
        },
        "load_raw_n": _nullable("load_raw_n", load_raw),
        "load_n": _nullable("load_n", load),
        "load_lo_n": _nullable("load_lo_n", load_lo, pl.Float32),
        "load_hi_n": _nullable("load_hi_n", load_hi, pl.Float32),
    }
    result = pl.DataFrame([out[name] for name in OUTPUT_SCHEMA])
    if result.schema != OUTPUT_SCHEMA:
        result = result.cast(dict(OUTPUT_SCHEMA))
    return result
