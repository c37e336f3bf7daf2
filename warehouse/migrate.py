"""Numbered, append-only schema migrations for the DuckDB warehouse.

Each ``warehouse/migrations/NNNN_<what>.sql`` makes one change and is never edited once
merged; a new change gets a new number. ``apply_migrations`` runs the ones not yet in
``schema_migrations``, in order, each in its own transaction, so applying twice is a
no-op and an old database is upgraded in place.

Migrations are plain SQL. ``tests/warehouse/test_migrate.py`` checks that the migrated
tables match the Arrow schemas of :mod:`schemas.tables`, so a schema change there needs
a new migration here.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import duckdb

__all__ = ["MIGRATIONS_DIR", "apply_migrations", "migration_files"]

MIGRATIONS_DIR = Path(__file__).parent / "migrations"
_NAME = re.compile(r"^(\d{4})_[a-z0-9_]+\.sql$")

logger = logging.getLogger(__name__)


def migration_files() -> list[tuple[int, Path]]:
    """All migration files, numbered and sorted; refuses gaps and duplicates."""
    found = []
    for path in sorted(MIGRATIONS_DIR.glob("*.sql")):
        match = _NAME.match(path.name)
        if match is None:
            raise ValueError(f"{path}: migration names are NNNN_lower_snake.sql")
        found.append((int(match.group(1)), path))
    numbers = [n for n, _ in found]
    if numbers != list(range(1, len(numbers) + 1)):
        raise ValueError(f"{MIGRATIONS_DIR}: migrations must be numbered 1..N, got {numbers}")
    return found


def apply_migrations(con: duckdb.DuckDBPyConnection) -> list[int]:
    """Apply pending migrations; return the numbers applied (empty when up to date)."""
    con.execute(
        "CREATE TABLE IF NOT EXISTS schema_migrations ("
        " version INTEGER PRIMARY KEY, name VARCHAR NOT NULL,"
        " applied_at TIMESTAMPTZ NOT NULL DEFAULT now())"
    )
    done = {row[0] for row in con.sql("SELECT version FROM schema_migrations").fetchall()}
    applied = []
    for number, path in migration_files():
        if number in done:
            continue
        con.execute("BEGIN TRANSACTION")
        try:
            con.execute(path.read_text(encoding="utf-8"))
            con.execute(
                "INSERT INTO schema_migrations (version, name) VALUES (?, ?)", [number, path.stem]
            )
            con.execute("COMMIT")
        except Exception:
            con.execute("ROLLBACK")
            raise
        logger.info("warehouse migration %s applied", path.stem)
        applied.append(number)
    return applied
