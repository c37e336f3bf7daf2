-- grain: one row per alarm and source file its run read (alarm_id, source_sha256)
-- alarm -> run (code version, hoist description hash) -> friction parameter set ->
-- source files (manifest.source_path). covers_alarm is true for the files whose time
-- range overlaps the alarm, i.e. the raw files that hold the samples that fired it.
with alarm_events as (
    select * from alarms
),

runs as (
    select * from stg_pipeline__runs
),

inputs as (
    select * from int_run_inputs_unnested
),

parameter_sets as (
    select parameter_set, source as parameter_set_source, created_at_utc
    from friction_parameter_sets
),

final as (
    select
        alarm_events.alarm_id,
        alarm_events.rule,
        alarm_events.rope,
        alarm_events.site,
        alarm_events.hoist,
        alarm_events.start_utc,
        alarm_events.end_utc,
        alarm_events.peak_value,
        alarm_events.threshold,
        alarm_events.unit,
        alarm_events.run_id,
        runs.command,
        runs.code_version,
        runs.hoist_sha256,
        runs.run_status,
        runs.started_at_utc as run_started_at_utc,
        runs.parameter_set,
        parameter_sets.parameter_set_source,
        inputs.source_sha256,
        inputs.source_path,
        inputs.source_time_start_utc,
        inputs.source_time_end_utc,
        coalesce(
            inputs.source_time_start_utc <= alarm_events.end_utc
            and inputs.source_time_end_utc >= alarm_events.start_utc
            and inputs.source_site = alarm_events.site
            and inputs.source_hoist = alarm_events.hoist,
            false
        ) as covers_alarm
    from alarm_events
    left join runs using (run_id)
    left join parameter_sets on parameter_sets.parameter_set = runs.parameter_set
    left join inputs on inputs.run_id = alarm_events.run_id
)

select * from final
