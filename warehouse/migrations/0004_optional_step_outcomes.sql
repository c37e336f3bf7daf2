-- Issue 15: an optional step that fails is a finding, not a failed day.
-- sanity_checks: a trip the check could not compare is landed as skipped with the reason
-- (passed null); rows landed before keep their verdict as status.
ALTER TABLE sanity_checks ALTER COLUMN passed DROP NOT NULL;
ALTER TABLE sanity_checks ADD COLUMN status VARCHAR;
UPDATE sanity_checks SET status = CASE WHEN passed THEN 'passed' ELSE 'failed' END;

-- The outcome of each optional step of a hoist-day run (sanity_check, discovery, report):
-- done, skipped or failed, and why. The completion ledger counts a day's sanity check as
-- done once its row is here, whatever it found.
CREATE TABLE run_steps (
    run_id VARCHAR NOT NULL,
    step VARCHAR NOT NULL,
    site VARCHAR NOT NULL,
    hoist VARCHAR NOT NULL,
    status VARCHAR NOT NULL,
    message VARCHAR,
    finished_at_utc TIMESTAMPTZ NOT NULL,
    PRIMARY KEY (run_id, step)
);
