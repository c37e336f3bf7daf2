"""Arrow schemas of every table ropeload writes: one source of truth.

Ingest writes the lake tables (Parquet, Hive-partitioned), transforms produce the
result tables, and the warehouse creates its DuckDB tables from these same schemas
(see :func:`duckdb_columns`). Units are SI and named in the column names.

Lake tables (Parquet under ``<data>/lake/<table>/site=../hoist=../date=../``):
    FIELD_SAMPLES, RIG_SAMPLES, QUARANTINE
Warehouse tables (DuckDB):
    MANIFEST, RUNS, ROPE_TENSIONS (also Parquet), POSITION_SUMMARY, TRIP_SUMMARY, ALARMS,
    FRICTION_PARAMETER_SETS, SANITY_CHECKS, DISCOVERY_FINDINGS, RUN_STEPS
"""

from __future__ import annotations

import polars as pl
import pyarrow as pa

__all__ = [
    "ALARMS",
    "DISCOVERY_FINDINGS",
    "FIELD_SAMPLES",
    "FRICTION_PARAMETER_SETS",
    "LAKE_PARTITIONS",
    "MANIFEST",
    "MANIFEST_ALIASES",
    "POSITION_SUMMARY",
    "QUARANTINE",
    "RIG_SAMPLES",
    "ROPES",
    "ROPE_TENSIONS",
    "RUNS",
    "RUN_STEPS",
    "SANITY_CHECKS",
    "TABLES",
    "TRIP_SUMMARY",
    "conform",
    "duckdb_columns",
    "empty_frame",
    "polars_schema",
]

#: Head ropes per hoist handled by the wide per-rope columns (contract: 4).
ROPES = (1, 2, 3, 4)

#: Hive partition keys of the lake tables, in path order.
LAKE_PARTITIONS = ("site", "hoist", "date")

TIME = pa.timestamp("us", tz="UTC")


def _per_rope(template: str, dtype: pa.DataType, *, nullable: bool = True) -> list[pa.Field]:
    return [pa.field(template.format(i=i), dtype, nullable=nullable) for i in ROPES]


def _schema(fields: list[pa.Field], doc: str) -> pa.Schema:
    return pa.schema(fields, metadata={"doc": doc})


#: One row per landed sample of a field log (contract 1a/1b), SI units.
#: Sensor pressures are as logged (converted to Pa), before sensor calibration.
FIELD_SAMPLES = _schema(
    [
        pa.field("time_utc", TIME, nullable=False),
        *_per_rope("p{i}_pa", pa.float64()),
        *_per_rope("x{i}_m", pa.float64()),
        pa.field("depth_m", pa.float64()),
        pa.field("speed_m_s", pa.float64()),
        pa.field("oil_temp_c", pa.float64()),
        pa.field("source_sha256", pa.string(), nullable=False),
        pa.field("source_line", pa.int64(), nullable=False),
    ],
    "one row per field-log sample; partitioned by site/hoist/date (UTC date)",
)

#: One row per rig sample on the pressure timeline, other topics joined as-of.
RIG_SAMPLES = _schema(
    [
        pa.field("time_utc", TIME, nullable=False),
        pa.field("rig_id", pa.string(), nullable=False),
        pa.field("step", pa.int32()),
        pa.field("pressure_setpoint_pa", pa.float64()),
        pa.field("velocity_setpoint_m_s", pa.float64()),
        pa.field("p_rodless_pa", pa.float64()),
        pa.field("p_rod_pa", pa.float64()),
        pa.field("x_m", pa.float64()),
        pa.field("oil_temp_c", pa.float64()),
        pa.field("source_sha256", pa.string(), nullable=False),
    ],
    "one row per /rig/pressure message; partitioned by site=rig/hoist=<rig_id>/date",
)

#: One row per rejected raw row (or unreadable file), with where and why.
QUARANTINE = _schema(
    [
        pa.field("source_sha256", pa.string(), nullable=False),
        pa.field("source_path", pa.string(), nullable=False),
        pa.field("line", pa.int64()),
        pa.field("topic", pa.string()),
        pa.field("reason", pa.string(), nullable=False),
        pa.field("raw", pa.string()),
    ],
    "one row per quarantined raw row; line is 1-based in the file (null for binary formats)",
)

#: One row per source file content seen by ingest.
MANIFEST = _schema(
    [
        pa.field("source_sha256", pa.string(), nullable=False),
        pa.field("source_path", pa.string(), nullable=False),
        pa.field("format", pa.string(), nullable=False),
        pa.field("size_bytes", pa.int64(), nullable=False),
        pa.field("bytes_consumed", pa.int64()),
        pa.field("site", pa.string()),
        pa.field("hoist", pa.string()),
        pa.field("rows_read", pa.int64(), nullable=False),
        pa.field("rows_landed", pa.int64(), nullable=False),
        pa.field("rows_quarantined", pa.int64(), nullable=False),
        pa.field("rows_duplicate", pa.int64(), nullable=False),
        pa.field("quarantined_by_reason", pa.map_(pa.string(), pa.int64())),
        pa.field("time_start_utc", TIME),
        pa.field("time_end_utc", TIME),
        pa.field("status", pa.string(), nullable=False),
        pa.field("message", pa.string()),
        pa.field("ingested_at_utc", TIME, nullable=False),
        # where the logger clock stood at bytes_consumed (migration 0007): the latest
        # sample time read, and the clock step back the reading ended inside (its first
        # line, its size in s; null when none)
        pa.field("clock_latest_utc", TIME),
        pa.field("clock_step_line", pa.int64()),
        pa.field("clock_step_s", pa.float64()),
    ],
    "one row per distinct source content (sha256); status landed | partial | refused",
)

#: One row per pipeline run (ingest, calibrate, run, backfill, discover, demo).
RUNS = _schema(
    [
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("command", pa.string(), nullable=False),
        pa.field("code_version", pa.string(), nullable=False),
        pa.field("hoist_sha256", pa.string()),
        pa.field("parameter_set", pa.string()),
        pa.field("site", pa.string()),
        pa.field("hoist", pa.string()),
        pa.field("period_start_utc", TIME),
        pa.field("period_end_utc", TIME),
        pa.field("inputs", pa.list_(pa.string())),
        pa.field("started_at_utc", TIME, nullable=False),
        pa.field("finished_at_utc", TIME),
        pa.field("status", pa.string(), nullable=False),
        pa.field("message", pa.string()),
        pa.field("timezone", pa.string()),
    ],
    "one row per run; inputs are source_sha256 of the files it read; timezone is the "
    "hoist's IANA time zone ([hoist] timezone of its description) for runs over a hoist",
)

#: One row per compensated sample (wide over the four ropes). These are the lake's
#: Parquet names (a contract kept since issue 2); the warehouse's ``rope_tensions`` view
#: speaks the marts' words (warehouse/README.md, Glossary): ``p{i}_pa`` (calibrated and
#: filtered) -> ``p_sensor{i}_pa``, ``tension_raw{i}_n`` -> ``tension_before{i}_n``,
#: ``tension{i}_n`` -> ``tension_after{i}_n``, ``load_raw_n`` -> ``load_before_n``,
#: ``load_n`` -> ``load_after_n``.
ROPE_TENSIONS = _schema(
    [
        pa.field("time_utc", TIME, nullable=False),
        pa.field("depth_m", pa.float64()),
        pa.field("speed_m_s", pa.float64()),
        pa.field("acceleration_up_m_s2", pa.float64()),
        pa.field("trip_id", pa.int64()),
        pa.field("phase", pa.string()),
        pa.field("direction", pa.string()),
        pa.field("position", pa.string()),
        *_per_rope("p{i}_pa", pa.float64()),
        *_per_rope("p_chamber{i}_pa", pa.float64()),
        *_per_rope("friction{i}_n", pa.float64()),
        *_per_rope("tension_raw{i}_n", pa.float64()),
        *_per_rope("tension{i}_n", pa.float64()),
        pa.field("load_raw_n", pa.float64()),
        pa.field("load_n", pa.float64()),
        # the band in single precision: 7 digits are 0.01 N of a 100 kN load
        *_per_rope("tension{i}_lo_n", pa.float32()),
        *_per_rope("tension{i}_hi_n", pa.float32()),
        pa.field("load_lo_n", pa.float32()),
        pa.field("load_hi_n", pa.float32()),
    ],
    "one row per sample after filtering and compensation; raw = p x A_bore (paper eq 2 "
    "without corrections); *_lo_n / *_hi_n: the 95 % band of the compensated value "
    "(transforms.uncertainty; null in partitions landed before the band existed)",
)

#: Paper Table 2 shape: one row per trip and hoist position.
POSITION_SUMMARY = _schema(
    [
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("site", pa.string(), nullable=False),
        pa.field("hoist", pa.string(), nullable=False),
        pa.field("trip_id", pa.int64()),
        pa.field("position", pa.string(), nullable=False),
        pa.field("time_start_utc", TIME),
        pa.field("time_end_utc", TIME),
        pa.field("depth_m", pa.float64()),
        pa.field("tail_rope_length_m", pa.float64()),
        *_per_rope("tension_before{i}_n", pa.float64()),
        *_per_rope("tension_after{i}_n", pa.float64()),
        pa.field("load_before_n", pa.float64()),
        pa.field("load_after_n", pa.float64()),
        pa.field("expected_load_n", pa.float64()),
        pa.field("payload_kg", pa.float64()),
        pa.field("error_before_fraction", pa.float64()),
        pa.field("error_after_fraction", pa.float64()),
        pa.field("imbalance_after_fraction", pa.float64()),
        pa.field("samples", pa.int64()),
        # migration 0005 (issue 13): the stint means of the 95 % band of load_after_n
        pa.field("load_after_lo_n", pa.float64()),
        pa.field("load_after_hi_n", pa.float64()),
    ],
    "one row per trip and named position (Table 2 of the paper); loads in N; "
    "load_after_lo_n / _hi_n: the stint means of the load's 95 % band",
)

#: One row per hoist trip.
TRIP_SUMMARY = _schema(
    [
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("site", pa.string(), nullable=False),
        pa.field("hoist", pa.string(), nullable=False),
        pa.field("trip_id", pa.int64(), nullable=False),
        pa.field("direction", pa.string()),
        pa.field("time_start_utc", TIME),
        pa.field("time_end_utc", TIME),
        pa.field("depth_start_m", pa.float64()),
        pa.field("depth_end_m", pa.float64()),
        pa.field("payload_kg", pa.float64()),
        pa.field("payload_spread_kg", pa.float64()),
        pa.field("max_load_after_n", pa.float64()),
        pa.field("max_imbalance_after_fraction", pa.float64()),
        pa.field("max_imbalance_after_rope", pa.int32()),
        pa.field("max_imbalance_after_time_utc", TIME),
        *_per_rope("max_tension_after{i}_n", pa.float64()),
        *_per_rope("min_tension_after{i}_n", pa.float64()),
        *_per_rope("max_imbalance_after{i}_fraction", pa.float64()),
        *_per_rope("max_imbalance_after{i}_time_utc", TIME),
        # migration 0005 (issue 13): the highest upper bound of the load's 95 % band
        pa.field("max_load_after_hi_n", pa.float64()),
    ],
    "one row per trip; max_load_after_hi_n: the highest the load may have been (95 % "
    "band); payload inferred from the compensated load at each position; "
    "extremes over the trip's samples after compensation, per rope and for the worst rope "
    "(imbalance of rope i = |T_i - mean T| / mean T)",
)

#: One row per alarm event (debounced).
ALARMS = _schema(
    [
        pa.field("alarm_id", pa.string(), nullable=False),
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("site", pa.string(), nullable=False),
        pa.field("hoist", pa.string(), nullable=False),
        pa.field("rule", pa.string(), nullable=False),
        pa.field("rope", pa.int32()),
        pa.field("start_utc", TIME, nullable=False),
        pa.field("end_utc", TIME, nullable=False),
        pa.field("peak_time_utc", TIME),
        pa.field("peak_value", pa.float64()),
        pa.field("threshold", pa.float64()),
        pa.field("unit", pa.string()),
        pa.field("message", pa.string()),
    ],
    "one row per alarm event; rule names the regulation or check that fired",
)

#: One row per friction parameter set (eq 17 form, SI) from calibration or a description.
FRICTION_PARAMETER_SETS = _schema(
    [
        pa.field("parameter_set", pa.string(), nullable=False),
        pa.field("created_at_utc", TIME, nullable=False),
        pa.field("source", pa.string()),
        pa.field("bore_m", pa.float64()),
        pa.field("coulomb_n", pa.float64()),
        pa.field("coulomb_n_per_pa", pa.float64()),
        pa.field("static_n", pa.float64()),
        pa.field("static_n_per_pa", pa.float64()),
        pa.field("stribeck_speed_m_s", pa.float64()),
        pa.field("stribeck_speed_m_s_per_pa", pa.float64()),
        pa.field("viscous_n_s_m", pa.float64()),
        pa.field("viscous_n_s_m_per_pa", pa.float64()),
        pa.field("residual_rms", pa.map_(pa.string(), pa.float64())),
        pa.field("inputs", pa.list_(pa.string())),
        # migration 0008: each line's standard errors (1 sigma) and the covariance of its
        # intercept and slope, keyed by column (``static_n``, ``static_n_per_pa``,
        # ``static_n_covariance``, ...) and the law's relative standard uncertainty
        # (``law_relative``, transforms.friction_lines.law_relative_sigma; when finite)
        pa.field("standard_error", pa.map_(pa.string(), pa.float64())),
    ],
    "one row per friction parameter set; value(p) = intercept + slope * p[Pa]; "
    "standard_error: each line's 1-sigma standard errors and intercept-slope covariance, "
    "and law_relative, the law's relative standard uncertainty",
)

#: One row per trip checked against the simulation.
SANITY_CHECKS = _schema(
    [
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("site", pa.string(), nullable=False),
        pa.field("hoist", pa.string(), nullable=False),
        pa.field("trip_id", pa.int64(), nullable=False),
        pa.field("rms_gap_pa", pa.float64()),
        pa.field("noise_pa", pa.float64()),
        pa.field("passed", pa.bool_()),
        pa.field("message", pa.string()),
        pa.field("status", pa.string()),
    ],
    "one row per trip the check replays: RMS of measured minus simulated sensor pressure; "
    "status passed, failed or skipped (passed and rms_gap_pa null, the reason in message: "
    "a warm-up that starts a replay history, a trip cut at the record's start, one that "
    "could not be simulated; every trip of the run when the check itself could not run)",
)

#: One row per discrepancy report (contract section 5), the JSON kept whole.
DISCOVERY_FINDINGS = _schema(
    [
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("site", pa.string(), nullable=False),
        pa.field("hoist", pa.string(), nullable=False),
        pa.field("iteration", pa.int32(), nullable=False),
        pa.field("period_start_utc", TIME),
        pa.field("period_end_utc", TIME),
        pa.field("effect", pa.string(), nullable=False),
        pa.field("confidence", pa.float64()),
        pa.field("gap_before_pa", pa.float64()),
        pa.field("gap_after_pa", pa.float64()),
        pa.field("report_json", pa.string(), nullable=False),
    ],
    "one row per effect found (or 'none') by the discovery workflow",
)

#: One row per optional step of a hoist-day run (sanity check, discovery, report): its
#: outcome. A failed optional step is a finding landed here, never a failed day.
RUN_STEPS = _schema(
    [
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("step", pa.string(), nullable=False),
        pa.field("site", pa.string(), nullable=False),
        pa.field("hoist", pa.string(), nullable=False),
        pa.field("status", pa.string(), nullable=False),
        pa.field("message", pa.string()),
        pa.field("finished_at_utc", TIME, nullable=False),
    ],
    "one row per optional step of a run (sanity_check, discovery, report): status done, "
    "skipped or failed, and why",
)

#: A path whose content the manifest holds under another path (migration 0006).
MANIFEST_ALIASES = _schema(
    [
        pa.field("source_path", pa.string(), nullable=False),
        pa.field("size_bytes", pa.int64(), nullable=False),
        pa.field("source_sha256", pa.string(), nullable=False),
        pa.field("seen_at_utc", TIME, nullable=False),
    ],
    "one row per (path, size) of a raw file skipped as content the manifest already "
    "holds under another path (a re-export under a new name)",
)

TABLES: dict[str, pa.Schema] = {
    "field_samples": FIELD_SAMPLES,
    "rig_samples": RIG_SAMPLES,
    "quarantine": QUARANTINE,
    "manifest": MANIFEST,
    "manifest_aliases": MANIFEST_ALIASES,
    "runs": RUNS,
    "rope_tensions": ROPE_TENSIONS,
    "position_summary": POSITION_SUMMARY,
    "trip_summary": TRIP_SUMMARY,
    "alarms": ALARMS,
    "friction_parameter_sets": FRICTION_PARAMETER_SETS,
    "sanity_checks": SANITY_CHECKS,
    "discovery_findings": DISCOVERY_FINDINGS,
    "run_steps": RUN_STEPS,
}

_DUCKDB_TYPES = {
    pa.float64(): "DOUBLE",
    pa.float32(): "FLOAT",
    pa.int64(): "BIGINT",
    pa.int32(): "INTEGER",
    pa.string(): "VARCHAR",
    pa.bool_(): "BOOLEAN",
    TIME: "TIMESTAMPTZ",
    pa.list_(pa.string()): "VARCHAR[]",
    pa.map_(pa.string(), pa.int64()): "MAP(VARCHAR, BIGINT)",
    pa.map_(pa.string(), pa.float64()): "MAP(VARCHAR, DOUBLE)",
}


def duckdb_columns(schema: pa.Schema) -> str:
    """Column list for ``CREATE TABLE`` from an Arrow schema (``NOT NULL`` kept)."""
    parts = []
    for field in schema:
        sql_type = _DUCKDB_TYPES[field.type]
        parts.append(f"{field.name} {sql_type}{'' if field.nullable else ' NOT NULL'}")
    return ",\n    ".join(parts)


def empty_frame(schema: pa.Schema) -> pl.DataFrame:
    """A frame of no rows with ``schema``'s columns as polars types.

    Built from no record batches: ``pa.Schema.empty_table`` imports pandas (~0.2 s of
    every command's start-up, issue 16) for metadata these schemas do not carry.

    >>> empty_frame(ALARMS).columns == ALARMS.names
    True
    """
    return pl.from_arrow(pa.Table.from_batches([], schema=schema))


def polars_schema(schema: pa.Schema) -> pl.Schema:
    """``schema``'s columns as a polars schema (:func:`empty_frame`'s)."""
    return empty_frame(schema).schema


def conform(frame: pl.DataFrame, schema: pa.Schema) -> pl.DataFrame:
    """Select and cast ``frame``'s columns to ``schema`` (missing columns become null).

    >>> conform(pl.DataFrame({"rule": ["x"], "extra": [1]}), ALARMS).columns == ALARMS.names
    True
    """
    empty = empty_frame(schema)
    if frame.width == 0:
        return empty
    target = empty.schema
    return frame.select(
        (pl.col(name) if name in frame.columns else pl.lit(None)).cast(dtype).alias(name)
        for name, dtype in target.items()
    )
