-- grain: one row per compensated sample (site, hoist, time_utc)
-- the compensated layer: rope tensions after pipe-loss and seal-friction compensation,
-- with the raw (p x A_bore) tensions beside them. Lake Parquet, not a DuckDB table.
select * from stg_lake__rope_tensions
