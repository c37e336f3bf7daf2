-- grain: one row per run and input file it read (run_id, source_sha256)
-- a run's inputs are the sha256 of the source files; joined to the manifest for names.
-- source_path is null when the manifest does not know the file (then lineage is broken:
-- see audit_runs.unknown_inputs).
with runs as (
    select run_id, input_sha256s from stg_pipeline__runs
),

unnested as (
    select run_id, unnest(input_sha256s) as source_sha256 from runs
),

manifest as (
    select * from stg_ingest__manifest
),

joined as (
    select
        unnested.run_id,
        unnested.source_sha256,
        manifest.source_path,
        manifest.source_format,
        manifest.site as source_site,
        manifest.hoist as source_hoist,
        manifest.time_start_utc as source_time_start_utc,
        manifest.time_end_utc as source_time_end_utc,
        manifest.ingest_status,
        manifest.ingested_at_utc
    from unnested
    left join manifest using (source_sha256)
)

select * from joined
