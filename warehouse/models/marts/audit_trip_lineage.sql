-- grain: one row per trip-summary row and source file its run read
-- (run_id, trip_id, source_sha256); covers_trip flags files overlapping the trip.
with trips as (
    select * from trip_summary
),

runs as (
    select * from stg_pipeline__runs
),

inputs as (
    select * from int_run_inputs_unnested
),

final as (
    select
        trips.run_id,
        trips.site,
        trips.hoist,
        trips.trip_id,
        trips.direction,
        trips.time_start_utc,
        trips.time_end_utc,
        trips.payload_kg,
        trips.payload_spread_kg,
        runs.code_version,
        runs.hoist_sha256,
        runs.parameter_set,
        inputs.source_sha256,
        inputs.source_path,
        coalesce(
            inputs.source_time_start_utc <= trips.time_end_utc
            and inputs.source_time_end_utc >= trips.time_start_utc
            and inputs.source_site = trips.site
            and inputs.source_hoist = trips.hoist,
            false
        ) as covers_trip
    from trips
    left join runs using (run_id)
    left join inputs on inputs.run_id = trips.run_id
)

select * from final
