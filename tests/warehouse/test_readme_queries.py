"""Every example query of README.md and warehouse/README.md, run on a demo warehouse.

Each fenced ``sql`` block runs through ``ropeload query``'s own path (the read-only check
and the sandbox, :func:`pipelines.query.run_query`), as an analyst pasting it would, and
its answer is checked against truth computed here without the warehouse: the lake's
Parquet read with polars, the raw CSV file read as text, the hoist description. A query
added to a README without a check here fails :func:`test_every_readme_query_has_a_check`.
"""

from __future__ import annotations

import datetime as dt
import re
import zoneinfo
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import polars as pl
import pytest

from pipelines.query import run_query
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from warehouse.store import DataRoot

REPO = Path(__file__).resolve().parents[2]
READMES = (REPO / "README.md", REPO / "warehouse" / "README.md")
DEMO_DAY = dt.date(2026, 3, 2)  # the demo's local day (pipelines.demo.DEMO_DATE)
ROPES = (1, 2, 3, 4)


def readme_queries() -> list[tuple[str, str]]:
    """(``README.md`` / ``warehouse/README.md``, SQL) of every fenced ``sql`` block."""
    found = []
    for path in READMES:
        for sql in re.findall(r"```sql\n(.*?)```", path.read_text(encoding="utf-8"), re.DOTALL):
            found.append((str(path.relative_to(REPO)), sql.strip()))
    return found


@dataclass(frozen=True)
class Truth:
    """What the demo warehouse must answer, from the lake Parquet and the raw file."""

    root: DataRoot
    zone: zoneinfo.ZoneInfo
    samples: pl.DataFrame  # lake rope_tensions, lake column names
    trips: pl.DataFrame  # per trip: worst rope, its imbalance and time, max load
    ropes: pl.DataFrame  # per trip and rope: extremes
    stints: pl.DataFrame  # per stint at a position: trip, start, mean loads
    csv: Path
    field_rows: int
    alarm: dict

    def local(self, t: dt.datetime) -> dt.datetime:
        return t.astimezone(self.zone).replace(tzinfo=None)


def _truth(root: DataRoot) -> Truth:
    lake = root.table_dir("rope_tensions")
    samples = pl.read_parquet(
        lake / "site=*" / "hoist=*" / "date=*" / "*.parquet", hive_partitioning=False
    ).sort("time_utc")
    mean = pl.mean_horizontal(f"tension{i}_n" for i in ROPES)
    imbalance = samples.with_columns(
        (pl.col(f"tension{i}_n") - mean).abs().truediv(mean).alias(f"imb{i}") for i in ROPES
    ).filter(pl.col("trip_id").is_not_null())
    ropes = pl.concat(
        imbalance.group_by("trip_id").agg(
            pl.lit(i).alias("rope"),
            pl.col(f"imb{i}").max().alias("imbalance"),
            pl.col("time_utc").get(pl.col(f"imb{i}").arg_max()).alias("time_utc"),
            pl.col(f"tension{i}_n").max().alias("max_n"),
            pl.col(f"tension{i}_n").min().alias("min_n"),
        )
        for i in ROPES
    )
    worst = ropes.sort("imbalance", descending=True).group_by("trip_id").first()
    loads = imbalance.group_by("trip_id").agg(pl.col("load_n").max().alias("max_load_n"))
    trips = worst.join(loads, on="trip_id").sort("trip_id")
    changed = (pl.col("position") != pl.col("position").shift(1)) | pl.col("trip_id").ne_missing(
        pl.col("trip_id").shift(1)
    )
    stints = (
        samples.with_columns(_stint=changed.fill_null(True).cum_sum())
        .filter(pl.col("position").is_not_null())
        .group_by("_stint")
        .agg(
            pl.col("trip_id").first(),
            pl.col("position").first(),
            pl.col("time_utc").min().alias("time_start_utc"),
            pl.col("load_raw_n").mean().alias("load_before_n"),
            pl.col("load_n").mean().alias("load_after_n"),
        )
    )
    (csv,) = (root.path / "incoming" / "demo").glob("*.csv")
    field_rows = (
        pl.scan_parquet(
            root.table_dir("field_samples") / "site=*" / "hoist=*" / "date=*" / "*.parquet",
            hive_partitioning=False,
        )
        .select(pl.len())
        .collect()
        .item()
    )
    alarms = run_query("select * from alarms", data=root)
    assert alarms.height == 1, "the demo (seed 3, 15 min) has one alarm: a logger gap"
    return Truth(
        root=root,
        zone=zoneinfo.ZoneInfo(load_hoist(EXAMPLE_HOIST).hoist.timezone),
        samples=samples,
        trips=trips,
        ropes=ropes,
        stints=stints,
        csv=csv,
        field_rows=field_rows,
        alarm={
            k: v.astimezone(dt.UTC) if isinstance(v, dt.datetime) else v
            for k, v in alarms.to_dicts()[0].items()
        },
    )


@pytest.fixture(scope="module")
def truth(demo_warehouse) -> Truth:
    return _truth(demo_warehouse)


def _close(value: float, exact: float, digits: int) -> bool:
    """``value`` is ``exact`` rounded to ``digits`` decimals (any rounding rule)."""
    return abs(value - exact) <= 0.51 * 10.0**-digits


# ---------------------------------------------------------------- checks, one per query


def _trips(rows: list[dict], t: Truth) -> None:
    assert len(rows) == t.trips.height == 2
    for row, trip in zip(rows, t.trips.iter_rows(named=True), strict=True):
        assert row["trip_id"] == trip["trip_id"]
        assert row["worst_rope"] == trip["rope"]
        assert _close(row["max_imbalance_pct"], 100 * trip["imbalance"], 2)
        assert _close(row["max_load_kn"], trip["max_load_n"] / 1e3, 1)
        assert -500 <= row["payload_kg"] <= 6500  # rated payload 6 t
        assert 0 <= row["spread_kg"] < 200


def _worst_rope(rows: list[dict], t: Truth) -> None:
    (row,) = rows
    worst = t.ropes.sort("imbalance", descending=True).row(0, named=True)
    assert (row["rope"], row["trip_id"]) == (worst["rope"], worst["trip_id"])
    assert _close(row["imbalance_pct"], 100 * worst["imbalance"], 2)
    assert row["max_imbalance_after_time_local"] == t.local(worst["time_utc"])
    assert row["source_path"] == str(t.csv)


def _ropes_of_a_day(rows: list[dict], t: Truth) -> None:
    assert [row["rope"] for row in rows] == list(ROPES)
    for row in rows:
        rope = t.ropes.filter(pl.col("rope") == row["rope"])
        assert row["trips"] == rope.height == t.trips.height
        assert _close(row["max_kn"], rope["max_n"].max() / 1e3, 2)
        assert _close(row["min_kn"], rope["min_n"].min() / 1e3, 2)
        assert _close(row["max_imbalance_pct"], 100 * rope["imbalance"].max(), 2)


def _table2(rows: list[dict], t: Truth) -> None:
    passes = t.stints.filter(pl.col("trip_id").is_not_null())
    assert len(rows) == passes.height >= 6  # 2 trips x 3 positions (and short extra stints)
    by_start = {t.local(s["time_start_utc"]): s for s in passes.iter_rows(named=True)}
    for row in rows:
        stint = by_start[row["time_start_local"]]
        assert row["time_start_local"].date() == DEMO_DAY
        assert (row["trip_id"], row["position"]) == (stint["trip_id"], stint["position"])
        assert _close(row["before_kn"], stint["load_before_n"] / 1e3, 1)
        assert _close(row["after_kn"], stint["load_after_n"] / 1e3, 1)
        assert 80 < row["expected_kn"] < 250


def _alarms_of_a_month(rows: list[dict], t: Truth) -> None:
    (row,) = rows
    assert row["start_local"] == t.local(t.alarm["start_utc"])
    assert row["end_local"] == t.local(t.alarm["end_utc"])
    assert row["start_local"].date() == DEMO_DAY
    assert (row["rule"], row["message"]) == (t.alarm["rule"], t.alarm["message"])


def _alarm_lineage(rows: list[dict], t: Truth) -> None:
    assert [(r["alarm_id"], r["source_path"]) for r in rows] == [(t.alarm["alarm_id"], str(t.csv))]


def _raw_lines(rows: list[dict], t: Truth) -> None:
    assert 0 < len(rows) <= 100
    lines = t.csv.read_text(encoding="utf-8").splitlines()
    for row in rows:
        assert row["source_path"] == str(t.csv)
        assert t.alarm["start_utc"] - dt.timedelta(seconds=1) <= row["time_utc"]
        assert row["time_utc"] <= t.alarm["end_utc"] + dt.timedelta(seconds=1)
        stamp, p1_mpa = lines[row["source_line"] - 1].split(",")[:2]  # 1-based line
        local = dt.datetime.fromisoformat(stamp).replace(tzinfo=t.zone)
        assert local == row["time_utc"]
        assert row["p1_pa"] == pytest.approx(float(p1_mpa) * 1e6)


def _position_lineage(rows: list[dict], t: Truth) -> None:
    assert len(rows) == t.stints.height  # every stint of the day, one raw file each
    assert {row["source_path"] for row in rows} == {str(t.csv)}


def _broken_lineage(rows: list[dict], t: Truth) -> None:
    assert rows == []  # and that is the truth: every run succeeded, every input is known
    runs = run_query("select status, inputs from runs", data=t.root)
    assert set(runs["status"]) == {"succeeded"}
    known = set(run_query("select source_sha256 from manifest", data=t.root)["source_sha256"])
    assert {sha for inputs in runs["inputs"] for sha in inputs} <= known


def _samples_around_an_alarm(rows: list[dict], t: Truth) -> None:
    margin = dt.timedelta(seconds=5)
    window = t.samples.filter(
        pl.col("time_utc").is_between(t.alarm["start_utc"] - margin, t.alarm["end_utc"] + margin)
    )
    assert len(rows) == window.height > 500  # 100 Hz, +-5 s around a 1.5 s gap
    for row, sample in zip(rows, window.iter_rows(named=True), strict=True):
        assert row["time_utc"] == sample["time_utc"]
        assert row["load_after_n"] == sample["load_n"]
        assert row["load_before_n"] == sample["load_raw_n"]
        assert row["tension_after3_n"] == sample["tension3_n"]


def _ingest_health(rows: list[dict], t: Truth) -> None:
    (row,) = rows
    text = t.csv.read_text(encoding="utf-8").splitlines()
    lines = [line for line in text if line.strip() and not line.startswith("#")]
    assert row["source_path"] == str(t.csv)
    assert row["ingest_status"] == "landed"
    assert row["rows_read"] == len(lines) - 1  # the column-name line is not a row
    assert row["rows_landed"] == t.field_rows == row["rows_read"]
    assert (row["rows_quarantined"], row["rows_duplicate"]) == (0, 0)


def _hoists(rows: list[dict], t: Truth) -> None:
    hoist = load_hoist(EXAMPLE_HOIST)
    (row,) = rows
    assert (row["site"], row["hoist"]) == (hoist.hoist.site, hoist.hoist.name)
    assert row["timezone"] == hoist.hoist.timezone == "Asia/Shanghai"
    assert row["parameter_set"] == hoist.friction.parameter_set
    assert row["run_count"] == 3  # demo, run, discover


#: A phrase only its queries contain -> the check of their answer.
CHECKS: dict[str, Callable[[list[dict], Truth], None]] = {
    "from trip_summary": _trips,
    "order by max_imbalance_after_fraction desc": _worst_rope,
    "group by rope": _ropes_of_a_day,
    "from position_summary p": _table2,
    "date_trunc('month', timezone(h.timezone, a.start_utc))": _alarms_of_a_month,
    "from audit_alarm_lineage": _alarm_lineage,
    "join stg_lake__field_samples": _raw_lines,
    "from audit_position_lineage": _position_lineage,
    "from audit_runs": _broken_lineage,
    "join rope_tensions s": _samples_around_an_alarm,
    "from stg_ingest__manifest": _ingest_health,
    "last_run_id, run_count from hoists": _hoists,
}


def _check_for(sql: str) -> list[str]:
    return [phrase for phrase in CHECKS if phrase in sql]


def test_every_readme_query_has_a_check():
    queries = readme_queries()
    assert len(queries) >= 14
    for readme, sql in queries:
        assert len(_check_for(sql)) == 1, f"{readme}: no single check for\n{sql}"
    used = {phrase for _, sql in queries for phrase in _check_for(sql)}
    assert used == set(CHECKS), f"checks for queries no README has: {set(CHECKS) - used}"
    assert {readme for readme, _ in queries} == {"README.md", "warehouse/README.md"}


QUERIES = readme_queries()


@pytest.mark.parametrize(
    ("readme", "sql"), QUERIES, ids=[f"{readme}:{k}" for k, (readme, _) in enumerate(QUERIES)]
)
def test_readme_query_answers_on_demo_data(readme, sql, truth):
    (phrase,) = _check_for(sql)
    frame = run_query(sql.replace("<alarm_id>", truth.alarm["alarm_id"]), data=truth.root)
    CHECKS[phrase](frame.to_dicts(), truth)
