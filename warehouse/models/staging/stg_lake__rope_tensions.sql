-- grain: one row per compensated sample (site, hoist, time_utc)
-- source: raw_rope_tensions (lake Parquet written by warehouse.landing.land_rope_tensions)
select
    -- ids
    site,
    hoist,
    cast(date as date) as date_utc,
    trip_id,
    phase,
    direction,
    position,
    -- numerics
    depth_m,
    speed_m_s,
    acceleration_up_m_s2,
    p1_pa, p2_pa, p3_pa, p4_pa,
    p_chamber1_pa, p_chamber2_pa, p_chamber3_pa, p_chamber4_pa,
    friction1_n, friction2_n, friction3_n, friction4_n,
    tension_raw1_n, tension_raw2_n, tension_raw3_n, tension_raw4_n,
    tension1_n, tension2_n, tension3_n, tension4_n,
    load_raw_n,
    load_n,
    -- timestamps
    time_utc
from raw_rope_tensions
