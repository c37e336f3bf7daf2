-- A raw file whose content is already in the manifest under another path (a re-export
-- under a new name, a moved incoming folder): ingest skips it and records the path
-- here, so the nightly no longer takes it for new every night.
CREATE TABLE manifest_aliases (
    source_path VARCHAR NOT NULL,
    size_bytes BIGINT NOT NULL,
    source_sha256 VARCHAR NOT NULL,
    seen_at_utc TIMESTAMPTZ NOT NULL,
    PRIMARY KEY (source_path, size_bytes)
);
