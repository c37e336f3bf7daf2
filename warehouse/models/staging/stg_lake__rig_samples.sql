-- grain: one row per friction-rig pressure message (rig_id, time_utc)
-- source: lake_rig_samples (lake Parquet, partitions site=rig/hoist=<rig_id>/date=)
select
    -- ids
    rig_id,
    step,
    cast(date as date) as date_utc,
    source_sha256,
    -- numerics
    pressure_setpoint_pa,
    velocity_setpoint_m_s,
    p_rodless_pa,
    p_rod_pa,
    x_m,
    oil_temp_c,
    -- timestamps
    time_utc
from lake_rig_samples
