"""The grains of warehouse/README.md hold: each declared key is unique and never null.

The table "Grains and keys" of the warehouse README is read here, so a relation or key
documented there is tested, and a documented key that stops holding (a landing that
duplicates, a view whose join fans out) fails. Checked on the demo warehouse with every
mart filled; a relation the demo leaves empty must enforce the key as its primary key.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from warehouse.store import open_reader

README = Path(__file__).resolve().parents[2] / "warehouse" / "README.md"


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
    } <= set(GRAINS)
    assert GRAINS["rope_trip_extremes"] == ["run_id", "trip_id", "rope"]


@pytest.mark.parametrize("relation", sorted(GRAINS))
def test_declared_key_is_unique_and_not_null(demo_warehouse, relation):
    key = GRAINS[relation]
    columns = ", ".join(key)
    nulls = " or ".join(f"{c} is null" for c in key)
    con = open_reader(demo_warehouse)
    try:
        rows, distinct, null_rows = con.sql(
            f"select count(*), count(distinct ({columns})), count(*) filter (where {nulls}) "
            f"from {relation}"
        ).fetchall()[0]
        primary = con.sql(
            "select constraint_column_names from duckdb_constraints() "
            f"where table_name = '{relation}' and constraint_type = 'PRIMARY KEY'"
        ).fetchall()
    finally:
        con.close()
    assert null_rows == 0, f"{relation}: {null_rows} rows with a null in ({columns})"
    assert distinct == rows, f"{relation}: {rows - distinct} duplicate keys ({columns})"
    if rows == 0:
        assert primary == [(key,)], f"{relation} is empty in the demo and has no primary key"
