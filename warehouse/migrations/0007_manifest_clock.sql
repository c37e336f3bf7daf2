-- Where a field log's clock stood at the end of what ingest read of it: the latest
-- sample time read, and the clock step back (a logger clock set back mid-file) the
-- reading ended inside, by its first line and its size. A resume of the growing file
-- carries them on, so the rows it appends are checked against all the file held.
ALTER TABLE manifest ADD COLUMN clock_latest_utc TIMESTAMPTZ;
ALTER TABLE manifest ADD COLUMN clock_step_line BIGINT;
ALTER TABLE manifest ADD COLUMN clock_step_s DOUBLE;
