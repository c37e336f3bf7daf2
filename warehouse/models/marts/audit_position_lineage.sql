-- grain: one row per position-summary row and source file its run read
-- (run_id, position, time_start_utc, source_sha256): the Table 2 numbers -> run ->
-- parameter set -> raw files; covers_position is true for files overlapping the
-- position window.
with positions as (
    select * from position_summary
),

runs as (
    select * from stg_pipeline__runs
),

inputs as (
    select * from int_run_inputs_unnested
),

final as (
    select
        positions.run_id,
        positions.site,
        positions.hoist,
        positions.trip_id,
        positions.position,
        positions.time_start_utc,
        positions.time_end_utc,
        positions.load_after_n,
        positions.expected_load_n,
        positions.error_after_fraction,
        positions.payload_kg,
        runs.command,
        runs.code_version,
        runs.hoist_sha256,
        runs.parameter_set,
        fps.source as parameter_set_source,
        inputs.source_sha256,
        inputs.source_path,
        coalesce(
            inputs.source_time_start_utc <= positions.time_end_utc
            and inputs.source_time_end_utc >= positions.time_start_utc
            and inputs.source_site = positions.site
            and inputs.source_hoist = positions.hoist,
            false
        ) as covers_position
    from positions
    left join runs using (run_id)
    left join friction_parameter_sets fps on fps.parameter_set = runs.parameter_set
    left join inputs on inputs.run_id = positions.run_id
)

select * from final
