-- grain: one row per quarantined raw row (or unreadable file)
-- source: quarantine table (landed by ingest)
select
    -- ids
    source_sha256,
    source_path,
    line as source_line,
    topic,
    reason,
    -- raw text as read
    raw as raw_text
from quarantine
