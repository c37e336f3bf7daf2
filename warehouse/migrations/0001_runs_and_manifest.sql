-- Runs (lineage root) and the ingest manifest: one row per distinct source content.
CREATE TABLE runs (
    run_id VARCHAR NOT NULL,
    command VARCHAR NOT NULL,
    code_version VARCHAR NOT NULL,
    hoist_sha256 VARCHAR,
    parameter_set VARCHAR,
    site VARCHAR,
    hoist VARCHAR,
    period_start_utc TIMESTAMPTZ,
    period_end_utc TIMESTAMPTZ,
    inputs VARCHAR[],
    started_at_utc TIMESTAMPTZ NOT NULL,
    finished_at_utc TIMESTAMPTZ,
    status VARCHAR NOT NULL,
    message VARCHAR,
    PRIMARY KEY (run_id)
);

CREATE TABLE manifest (
    source_sha256 VARCHAR NOT NULL,
    source_path VARCHAR NOT NULL,
    format VARCHAR NOT NULL,
    size_bytes BIGINT NOT NULL,
    bytes_consumed BIGINT,
    site VARCHAR,
    hoist VARCHAR,
    rows_read BIGINT NOT NULL,
    rows_landed BIGINT NOT NULL,
    rows_quarantined BIGINT NOT NULL,
    rows_duplicate BIGINT NOT NULL,
    quarantined_by_reason MAP(VARCHAR, BIGINT),
    time_start_utc TIMESTAMPTZ,
    time_end_utc TIMESTAMPTZ,
    status VARCHAR NOT NULL,
    message VARCHAR,
    ingested_at_utc TIMESTAMPTZ NOT NULL,
    PRIMARY KEY (source_sha256)
);

CREATE TABLE quarantine (
    source_sha256 VARCHAR NOT NULL,
    source_path VARCHAR NOT NULL,
    line BIGINT,
    topic VARCHAR,
    reason VARCHAR NOT NULL,
    raw VARCHAR
);
