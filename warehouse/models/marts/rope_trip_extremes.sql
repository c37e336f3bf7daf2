-- grain: one row per trip and rope (run_id, trip_id, rope)
-- a trip's per-rope extremes after compensation (trip_summary's wide per-rope columns,
-- one row per rope), in UTC and in the hoist's local time, with the raw file that holds
-- the sample of the rope's largest imbalance: the run's input whose time range covers
-- that sample (source_path, source_sha256; source_paths lists every such file, e.g. a
-- CSV and a TDMS copy of the same log, or a day's file and an hour's overlapping it).
-- Where several inputs cover it, the one that landed the sample (the lake sample's
-- source_sha256) is named, not the first path in sort order: the others' lines there
-- were skipped as duplicates. is_worst_rope marks the trip's worst rope.
-- "Which rope was most unbalanced in March, and from which raw file":
--   select * from rope_trip_extremes where date_trunc('month', date_local) = '2026-03-01'
--   order by max_imbalance_after_fraction desc limit 1
with trips as (
    select * from trip_summary
),

runs as (
    select run_id, timezone as run_timezone from stg_pipeline__runs
),

hoist_zones as (
    select site, hoist, timezone as hoist_timezone from hoists
),

ropes as (
    select * from (values (1), (2), (3), (4)) as ropes (rope)
),

per_rope as (
    select
        trips.run_id,
        trips.site,
        trips.hoist,
        coalesce(runs.run_timezone, hoist_zones.hoist_timezone) as timezone,
        trips.trip_id,
        trips.direction,
        ropes.rope,
        ropes.rope = trips.max_imbalance_after_rope as is_worst_rope,
        trips.time_start_utc,
        trips.time_end_utc,
        [trips.max_tension_after1_n, trips.max_tension_after2_n,
         trips.max_tension_after3_n, trips.max_tension_after4_n][ropes.rope]
            as max_tension_after_n,
        [trips.min_tension_after1_n, trips.min_tension_after2_n,
         trips.min_tension_after3_n, trips.min_tension_after4_n][ropes.rope]
            as min_tension_after_n,
        [trips.max_imbalance_after1_fraction, trips.max_imbalance_after2_fraction,
         trips.max_imbalance_after3_fraction, trips.max_imbalance_after4_fraction][ropes.rope]
            as max_imbalance_after_fraction,
        [trips.max_imbalance_after1_time_utc, trips.max_imbalance_after2_time_utc,
         trips.max_imbalance_after3_time_utc, trips.max_imbalance_after4_time_utc][ropes.rope]
            as max_imbalance_after_time_utc
    from trips
    cross join ropes
    left join runs using (run_id)
    left join hoist_zones using (site, hoist)
),

inputs as (
    select * from int_run_inputs_unnested
),

covering as (
    select
        per_rope.run_id,
        per_rope.trip_id,
        per_rope.rope,
        per_rope.site,
        per_rope.hoist,
        per_rope.max_imbalance_after_time_utc,
        inputs.source_path,
        inputs.source_sha256
    from per_rope
    join inputs
        on inputs.run_id = per_rope.run_id
        and inputs.source_site = per_rope.site
        and inputs.source_hoist = per_rope.hoist
        and per_rope.max_imbalance_after_time_utc
            between inputs.source_time_start_utc and inputs.source_time_end_utc
),

covered as (
    select
        run_id,
        trip_id,
        rope,
        min(source_path) as first_path,
        arg_min(source_sha256, source_path) as first_sha256,
        list(source_path order by source_path)
            filter (where source_path is not null) as source_paths,
        count(*) as covering_files
    from covering
    group by run_id, trip_id, rope
),

-- only where files overlap (rare: the lake is read for those samples alone)
ambiguous as (
    select distinct covering.site, covering.hoist, covering.max_imbalance_after_time_utc
    from covering
    join covered using (run_id, trip_id, rope)
    where covered.covering_files > 1
),

landed as (
    select distinct samples.site, samples.hoist, samples.time_utc, samples.source_sha256
    from ambiguous
    join stg_lake__field_samples as samples
        on samples.site = ambiguous.site
        and samples.hoist = ambiguous.hoist
        and samples.time_utc = ambiguous.max_imbalance_after_time_utc
),

landed_by as (
    select
        covering.run_id,
        covering.trip_id,
        covering.rope,
        min(covering.source_path) as source_path,
        arg_min(covering.source_sha256, covering.source_path) as source_sha256
    from covering
    join landed
        on landed.site = covering.site
        and landed.hoist = covering.hoist
        and landed.time_utc = covering.max_imbalance_after_time_utc
        and landed.source_sha256 = covering.source_sha256
    group by covering.run_id, covering.trip_id, covering.rope
),

files as (
    select
        covered.run_id,
        covered.trip_id,
        covered.rope,
        coalesce(landed_by.source_path, covered.first_path) as source_path,
        coalesce(landed_by.source_sha256, covered.first_sha256) as source_sha256,
        covered.source_paths
    from covered
    left join landed_by using (run_id, trip_id, rope)
),

final as (
    select
        per_rope.site,
        per_rope.hoist,
        per_rope.timezone,
        per_rope.run_id,
        per_rope.trip_id,
        per_rope.direction,
        per_rope.rope,
        per_rope.is_worst_rope,
        per_rope.time_start_utc,
        per_rope.time_end_utc,
        timezone(per_rope.timezone, per_rope.time_start_utc) as time_start_local,
        cast(timezone(per_rope.timezone, per_rope.time_start_utc) as date) as date_local,
        per_rope.max_tension_after_n,
        per_rope.min_tension_after_n,
        per_rope.max_imbalance_after_fraction,
        per_rope.max_imbalance_after_time_utc,
        timezone(per_rope.timezone, per_rope.max_imbalance_after_time_utc)
            as max_imbalance_after_time_local,
        files.source_path,
        files.source_sha256,
        coalesce(files.source_paths, []) as source_paths
    from per_rope
    left join files using (run_id, trip_id, rope)
)

select * from final
