-- Issue 18: one name per quantity in the marts (warehouse/README.md, Glossary), the rope
-- of a trip's worst imbalance and per-rope extremes per trip, the hoist's time zone per run.
-- Rows landed before this migration keep null in the new columns (re-run a day to fill).
ALTER TABLE trip_summary RENAME COLUMN max_load_n TO max_load_after_n;
ALTER TABLE trip_summary RENAME COLUMN max_imbalance_fraction TO max_imbalance_after_fraction;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after_rope INTEGER;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after_time_utc TIMESTAMPTZ;
ALTER TABLE trip_summary ADD COLUMN max_tension_after1_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_tension_after2_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_tension_after3_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_tension_after4_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN min_tension_after1_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN min_tension_after2_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN min_tension_after3_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN min_tension_after4_n DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after1_fraction DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after2_fraction DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after3_fraction DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after4_fraction DOUBLE;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after1_time_utc TIMESTAMPTZ;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after2_time_utc TIMESTAMPTZ;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after3_time_utc TIMESTAMPTZ;
ALTER TABLE trip_summary ADD COLUMN max_imbalance_after4_time_utc TIMESTAMPTZ;

ALTER TABLE runs ADD COLUMN timezone VARCHAR;
