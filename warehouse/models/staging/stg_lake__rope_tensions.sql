-- grain: one row per compensated sample (site, hoist, time_utc)
-- source: lake_rope_tensions (lake Parquet written by warehouse.landing.land_rope_tensions)
-- renames the lake's words to the warehouse's (warehouse/README.md, Glossary):
-- p{i}_pa -> p_sensor{i}_pa, tension_raw{i}_n -> tension_before{i}_n,
-- tension{i}_n -> tension_after{i}_n, load_raw_n -> load_before_n, load_n -> load_after_n,
-- tension{i}_lo_n / _hi_n -> tension_after{i}_lo_n / _hi_n, load_lo_n / _hi_n -> load_after_lo_n / _hi_n
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
    p1_pa as p_sensor1_pa,
    p2_pa as p_sensor2_pa,
    p3_pa as p_sensor3_pa,
    p4_pa as p_sensor4_pa,
    p_chamber1_pa, p_chamber2_pa, p_chamber3_pa, p_chamber4_pa,
    friction1_n, friction2_n, friction3_n, friction4_n,
    tension_raw1_n as tension_before1_n,
    tension_raw2_n as tension_before2_n,
    tension_raw3_n as tension_before3_n,
    tension_raw4_n as tension_before4_n,
    tension1_n as tension_after1_n,
    tension2_n as tension_after2_n,
    tension3_n as tension_after3_n,
    tension4_n as tension_after4_n,
    load_raw_n as load_before_n,
    load_n as load_after_n,
    -- the 95 % band of the compensated values (transforms.uncertainty; null before it)
    tension1_lo_n as tension_after1_lo_n,
    tension2_lo_n as tension_after2_lo_n,
    tension3_lo_n as tension_after3_lo_n,
    tension4_lo_n as tension_after4_lo_n,
    tension1_hi_n as tension_after1_hi_n,
    tension2_hi_n as tension_after2_hi_n,
    tension3_hi_n as tension_after3_hi_n,
    tension4_hi_n as tension_after4_hi_n,
    load_lo_n as load_after_lo_n,
    load_hi_n as load_after_hi_n,
    -- timestamps
    time_utc
from lake_rope_tensions
