-- grain: one row per distinct source file content (source_sha256)
-- source: manifest table (landed by ingest)
select
    -- ids
    source_sha256,
    source_path,
    format as source_format,
    site,
    hoist,
    status as ingest_status,
    message as ingest_message,
    -- numerics
    size_bytes,
    bytes_consumed,
    rows_read,
    rows_landed,
    rows_quarantined,
    rows_duplicate,
    quarantined_by_reason,
    -- timestamps
    time_start_utc,
    time_end_utc,
    ingested_at_utc
from manifest
