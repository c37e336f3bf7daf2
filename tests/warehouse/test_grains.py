"""The grains of warehouse/README.md hold: each declared key is unique and never null.

The table "Grains and keys" of the warehouse README is read here, so a relation or key
documented there is tested, and a documented key that stops holding (a landing that
duplicates, a view whose join fans out) fails. Every mart (the tables the migrations
make, the views of ``warehouse/models/marts``) must have a row there. Checked on the demo
warehouse with every mart filled; a relation the demo leaves empty must enforce the key
as its primary key. ``position_summary``, ``trip_summary``, ``sanity_checks`` and
``discovery_findings`` have no primary key: this is the test of their keys.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from warehouse.store import open_reader

REPO = Path(__file__).resolve().parents[2]
README = REPO / "warehouse" / "README.md"
#: tables that are not marts: landed by ingest, one row per refused line (an unreadable
#: file's row has no line, so no key); the migrations' own bookkeeping
NOT_MARTS = {"quarantine", "schema_migrations"}


def declared_grains() -> dict[str, list[str]]:
    """relation -> key columns, from the README's "Grains and keys" table."""
    text = README.read_text(encoding="utf-8")
    section = text[text.index("### Grains and keys") :]
    section = section[: section.index("\n\n", section.index("| relation |"))]
    grains = {}
    for line in section.splitlines():
        match = re.fullmatch(r"\| `(\w+)` \| [^|]+ \| `([\w, ]+)` \|", line.strip())
        if match:
            grains[match.group(1)] = [c.strip() for c in match.group(2).split(",")]
    return grains


GRAINS = declared_grains()


def test_the_readme_declares_every_mart():
    assert {
        "runs",
        "manifest",
        "position_summary",
        "trip_summary",
        "alarms",
        "sanity_checks",
        "friction_parameter_sets",
        "discovery_findings",
        "rope_tensions",
        "hoists",
        "rope_trip_extremes",
        "run_steps",
        "audit_runs",
        "audit_alarm_lineage",
        "audit_position_lineage",
        "audit_trip_lineage",
    } <= set(GRAINS)
    assert GRAINS["rope_trip_extremes"] == ["run_id", "trip_id", "rope"]


def test_every_mart_has_a_declared_grain(demo_warehouse):
    views = {path.stem for path in (REPO / "warehouse" / "models" / "marts").glob("*.sql")}
    con = open_reader(demo_warehouse)
    try:
        tables = {name for (name,) in con.sql("select table_name from duckdb_tables()").fetchall()}
    finally:
        con.close()
    assert "position_summary" in tables
    assert (tables - NOT_MARTS) | views <= set(GRAINS)


@pytest.mark.parametrize("relation", sorted(GRAINS))
def test_declared_key_is_unique_and_not_null(demo_warehouse, relation):
    key = GRAINS[relation]
    columns = ", ".join(key)
    nulls = " or ".join(f"{c} is null" for c in key)
    con = open_reader(demo_warehouse)
    try:
        rows, null_rows = con.sql(
            f"select count(*), count(*) filter (where {nulls}) from {relation}"
        ).fetchall()[0]
        duplicates = con.sql(
            f"select {columns}, count(*) as n from {relation} group by {columns} "
            f"having count(*) > 1 order by n desc limit 3"
        ).fetchall()
        primary = con.sql(
            "select constraint_column_names from duckdb_constraints() "
            f"where table_name = '{relation}' and constraint_type = 'PRIMARY KEY'"
        ).fetchall()
    finally:
        con.close()
    assert null_rows == 0, f"{relation}: {null_rows} rows with a null in ({columns})"
    assert not duplicates, f"{relation}: keys ({columns}) on more than one row: {duplicates}"
    if rows == 0:
        assert primary == [(key,)], f"{relation} is empty in the demo and has no primary key"
