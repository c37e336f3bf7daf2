-- grain: one row per landed field-log sample (site, hoist, time_utc)
-- source: lake_field_samples (lake Parquet, Hive partitions site=/hoist=/date=)
-- staging only: rename, cast, units (all SI already; pressures Pa, lengths m)
select
    -- ids
    site,
    hoist,
    cast(date as date) as date_utc,
    source_sha256,
    source_line,
    -- numerics
    p1_pa,
    p2_pa,
    p3_pa,
    p4_pa,
    x1_m,
    x2_m,
    x3_m,
    x4_m,
    depth_m,
    speed_m_s,
    oil_temp_c,
    -- timestamps
    time_utc
from lake_field_samples
