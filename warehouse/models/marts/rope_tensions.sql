-- grain: one row per compensated sample (site, hoist, time_utc)
-- the compensated layer: rope tensions after pipe-loss and seal-friction compensation,
-- with the uncompensated (p_sensor x A_bore) "before" tensions beside them, in the
-- warehouse's words (Glossary of warehouse/README.md). Lake Parquet, not a DuckDB table.
select * from stg_lake__rope_tensions
