-- Issue 13: the compensation's 95 % band, summarised where analysts read loads.
-- position_summary: the stint means of the band of load_after_n; trip_summary: the
-- highest upper bound of the load over the trip (how high the load may have been).
-- Rows landed before stay null.
ALTER TABLE position_summary ADD COLUMN load_after_lo_n DOUBLE;
ALTER TABLE position_summary ADD COLUMN load_after_hi_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_load_after_hi_n DOUBLE;
