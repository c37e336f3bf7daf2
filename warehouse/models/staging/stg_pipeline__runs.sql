-- grain: one row per pipeline run (run_id)
-- source: runs table (landed by warehouse.landing.land_run)
select
    -- ids
    run_id,
    command,
    code_version,
    hoist_sha256,
    parameter_set,
    site,
    hoist,
    timezone,
    status as run_status,
    message as run_message,
    inputs as input_sha256s,
    -- numerics
    coalesce(len(inputs), 0) as input_count,
    date_diff('millisecond', started_at_utc, finished_at_utc) / 1000.0 as duration_s,
    -- timestamps
    period_start_utc,
    period_end_utc,
    started_at_utc,
    finished_at_utc
from runs
