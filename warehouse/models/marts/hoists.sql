-- grain: one row per hoist (site, hoist) that a run over a hoist description named
-- the hoist as its latest run knew it: IANA time zone ([hoist] timezone of the hoist
-- description), the description's hash and friction parameter set, and that run.
-- A hoist's local time: timezone(hoists.timezone, <any>_utc column) (a TIMESTAMP).
with runs as (
    select * from stg_pipeline__runs
    where site is not null and hoist is not null and hoist_sha256 is not null
),

latest as (
    select
        site,
        hoist,
        arg_max(timezone, started_at_utc) filter (where timezone is not null) as timezone,
        arg_max(hoist_sha256, started_at_utc) as hoist_sha256,
        arg_max(parameter_set, started_at_utc) as parameter_set,
        arg_max(run_id, started_at_utc) as last_run_id,
        max(started_at_utc) as last_run_started_at_utc,
        count(*) as run_count
    from runs
    group by site, hoist
)

select * from latest
