-- grain: one row per quarantined raw row (or unreadable file)
-- source: quarantine table (landed by ingest)
select
    -- ids
    source_sha256,
    source_path,
    line as source_line,
    topic,
    reason,
    -- the line (or message) as read from the file
    raw as source_text
from quarantine
