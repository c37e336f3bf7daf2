-- grain: one row per run (run_id)
-- what each run was: command, code, hoist description, friction parameter set, inputs,
-- timing, and how many mart rows it owns; unknown_inputs > 0 flags broken lineage.
with runs as (
    select * from stg_pipeline__runs
),

inputs as (
    select
        run_id,
        count(*) filter (where source_path is null) as unknown_inputs,
        list(source_path order by source_path) filter (where source_path is not null)
            as source_paths
    from int_run_inputs_unnested
    group by run_id
),

owned as (
    select
        runs.run_id,
        (select count(*) from position_summary p where p.run_id = runs.run_id)
            as position_rows,
        (select count(*) from trip_summary t where t.run_id = runs.run_id) as trip_rows,
        (select count(*) from alarms a where a.run_id = runs.run_id) as alarm_rows,
        (select count(*) from sanity_checks s where s.run_id = runs.run_id) as sanity_rows
    from runs
),

final as (
    select
        runs.*,
        coalesce(inputs.unknown_inputs, 0) as unknown_inputs,
        inputs.source_paths,
        fps.source as parameter_set_source,
        fps.created_at_utc as parameter_set_created_at_utc,
        owned.position_rows,
        owned.trip_rows,
        owned.alarm_rows,
        owned.sanity_rows
    from runs
    left join inputs using (run_id)
    left join owned using (run_id)
    left join friction_parameter_sets fps on fps.parameter_set = runs.parameter_set
)

select * from final
