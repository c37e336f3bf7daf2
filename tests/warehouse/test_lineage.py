"""Lineage: from one alarm row, SQL reaches the raw files, the run and the parameter set."""

from __future__ import annotations

import datetime as dt
import hashlib
import re
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from physics.tension import expected_load_n
from schemas.hoist import EXAMPLE_HOIST, hoist_sha256, load_hoist
from schemas.tables import FIELD_SAMPLES, MANIFEST, conform
from transforms.alarms import evaluate_alarms
from transforms.reconciliation import reconcile
from warehouse.landing import (
    RunRecord,
    insert_frame,
    land_friction_parameter_sets,
    land_results,
    land_rope_tensions,
)
from warehouse.store import DataRoot, open_reader, open_writer

T0 = dt.datetime(2026, 3, 2, 6, 55, tzinfo=dt.UTC)
FS_HZ = 100.0


def _samples(hoist) -> pl.DataFrame:
    """10 min parked empty at the pithead; rope 3 goes slack 07:02:00-07:02:05."""
    n = int(600 * FS_HZ)
    t = np.arange(n) / FS_HZ
    rng = np.random.default_rng(0)
    load = expected_load_n(hoist, 0.0)
    tensions = {f"tension{i}_n": load / 4 * (1 + rng.normal(0, 0.003, n)) for i in range(1, 5)}
    slack = (t >= 420.0) & (t < 425.0)
    tensions["tension3_n"] = np.where(slack, 0.2 * tensions["tension3_n"], tensions["tension3_n"])
    time = pl.Series(
        np.datetime64(T0.replace(tzinfo=None), "us") + (t * 1e6).astype("timedelta64[us]")
    ).dt.replace_time_zone("UTC")
    frame = pl.DataFrame(
        {"time_utc": time, "depth_m": 0.0, "speed_m_s": 0.0, "acceleration_up_m_s2": 0.0,
         "position": "pithead", **tensions}
    )  # fmt: skip
    area = hoist.cylinders.bore_area_m2
    return frame.with_columns(
        *[(pl.col(f"tension{i}_n") / area).alias(f"p{i}_pa") for i in range(1, 5)],
        *[pl.col(f"tension{i}_n").alias(f"tension_raw{i}_n") for i in range(1, 5)],
        load_n=pl.sum_horizontal(f"tension{i}_n" for i in range(1, 5)),
        load_raw_n=pl.sum_horizontal(f"tension{i}_n" for i in range(1, 5)),
        trip_id=pl.lit(None, dtype=pl.Int64),
    )


def _ingest_by_hand(root: DataRoot, tmp_path, samples: pl.DataFrame, hoist):
    """What ingest does: raw files on disk, their samples in the lake, a manifest row each."""
    manifest, shas = [], []
    halves = [samples.filter(pl.col("time_utc") < T0 + dt.timedelta(minutes=5)),
              samples.filter(pl.col("time_utc") >= T0 + dt.timedelta(minutes=5))]  # fmt: skip
    for k, half in enumerate(halves):
        raw = tmp_path / "logs" / f"main-shaft-{k}.csv"
        raw.parent.mkdir(exist_ok=True)
        half.select("time_utc", "p1_pa", "p2_pa", "p3_pa", "p4_pa").write_csv(raw)
        sha = hashlib.sha256(raw.read_bytes()).hexdigest()
        shas.append(sha)
        lake = conform(
            half.with_columns(source_sha256=pl.lit(sha), source_line=pl.int_range(pl.len()) + 2),
            FIELD_SAMPLES,
        )
        partition = f"site={hoist.hoist.site}/hoist={hoist.hoist.name}/date=2026-03-02"
        part = root.table_dir("field_samples") / partition / f"part-{k}.parquet"
        part.parent.mkdir(parents=True, exist_ok=True)
        lake.write_parquet(part)
        manifest.append(
            {"source_sha256": sha, "source_path": str(raw), "format": "csv",
             "size_bytes": raw.stat().st_size, "site": hoist.hoist.site,
             "hoist": hoist.hoist.name, "rows_read": half.height, "rows_landed": half.height,
             "rows_quarantined": 0, "rows_duplicate": 0,
             "time_start_utc": half["time_utc"].min(), "time_end_utc": half["time_utc"].max(),
             "status": "landed", "ingested_at_utc": T0}
        )  # fmt: skip
    return conform(pl.DataFrame(manifest), MANIFEST), shas


@pytest.fixture(scope="module")
def landed(tmp_path_factory):
    """A warehouse with two raw files ingested and one run's alarms and positions."""
    tmp_path = tmp_path_factory.mktemp("lineage")
    hoist = load_hoist(EXAMPLE_HOIST)
    root = DataRoot(tmp_path / "data")
    samples = _samples(hoist)
    manifest, shas = _ingest_by_hand(root, tmp_path, samples, hoist)
    law = hoist.friction_law
    parameter_sets = pl.DataFrame(
        {"parameter_set": [hoist.friction.parameter_set], "created_at_utc": [T0],
         "source": [hoist.friction.source], "bore_m": [hoist.cylinders.bore_m],
         "coulomb_n": [law.coulomb_n[0]], "coulomb_n_per_pa": [law.coulomb_n[1]]}
    )  # fmt: skip
    run = RunRecord(
        run_id="run-2026-03-02", command="run", code_version="abc1234",
        started_at_utc=T0 + dt.timedelta(hours=1), hoist_sha256=hoist_sha256(EXAMPLE_HOIST),
        parameter_set=hoist.friction.parameter_set, site=hoist.hoist.site,
        hoist=hoist.hoist.name, period_start_utc=T0, period_end_utc=T0 + dt.timedelta(minutes=10),
        inputs=shas,
    )  # fmt: skip
    alarms = evaluate_alarms(samples, hoist, run_id=run.run_id, payload_kg=0.0)
    positions, _ = reconcile(samples, hoist, run_id=run.run_id, payload_kg=0.0)
    assert alarms.filter(pl.col("rule") == "slack_rope").height == 1

    with open_writer(root) as con:
        insert_frame(con, "manifest", manifest)  # ingest's part
        land_friction_parameter_sets(con, parameter_sets)
        land_rope_tensions(root, samples, site=run.site, hoist=run.hoist,
                           period_start_utc=run.period_start_utc,
                           period_end_utc=run.period_end_utc)  # fmt: skip
        land_results(con, run, alarms=alarms, position_summary=positions)
    return tmp_path, root, hoist


def test_alarm_row_leads_to_raw_files_run_and_parameter_set(landed):
    tmp_path, root, hoist = landed
    con = open_reader(root)
    try:
        (alarm_id,) = con.sql("SELECT alarm_id FROM alarms WHERE rule = 'slack_rope'").fetchall()[0]
        # plain SQL over the tables: alarm -> run -> parameter set -> manifest
        rows = con.execute(
            """
            SELECT r.run_id, r.code_version, r.hoist_sha256, f.parameter_set, f.source,
                   m.source_path, m.time_start_utc <= a.end_utc AND m.time_end_utc >= a.start_utc
            FROM alarms a
            JOIN runs r USING (run_id)
            JOIN friction_parameter_sets f ON f.parameter_set = r.parameter_set
            JOIN manifest m ON list_contains(r.inputs, m.source_sha256)
            WHERE a.alarm_id = ?
            ORDER BY m.source_path
            """,
            [alarm_id],
        ).fetchall()
        # the documented audit view answers the same question
        audit = con.execute(
            "SELECT source_path, run_id, parameter_set, code_version FROM audit_alarm_lineage "
            "WHERE alarm_id = ? AND covers_alarm",
            [alarm_id],
        ).fetchall()
        # and the raw samples behind it, by file and line, from the lake view
        raw = con.execute(
            """
            SELECT m.source_path, min(s.source_line), count(*), min(s.p3_pa)
            FROM alarms a
            JOIN stg_lake__field_samples s
              ON s.time_utc BETWEEN a.start_utc AND a.end_utc
             AND s.site = a.site AND s.hoist = a.hoist
            JOIN manifest m ON m.source_sha256 = s.source_sha256
            WHERE a.alarm_id = ?
            GROUP BY 1
            """,
            [alarm_id],
        ).fetchall()
        position_audit = con.sql(
            "SELECT DISTINCT source_path FROM audit_position_lineage WHERE covers_position "
            "ORDER BY 1"
        ).fetchall()
    finally:
        con.close()

    paths = [str(tmp_path / "logs" / f"main-shaft-{k}.csv") for k in (0, 1)]
    params = (hoist.friction.parameter_set, hoist.friction.source)
    assert rows == [
        ("run-2026-03-02", "abc1234", hoist_sha256(EXAMPLE_HOIST), *params, paths[0], False),
        ("run-2026-03-02", "abc1234", hoist_sha256(EXAMPLE_HOIST), *params, paths[1], True),
    ]
    # the slack started at 07:02:00, in the second file only
    assert audit == [(paths[1], "run-2026-03-02", hoist.friction.parameter_set, "abc1234")]
    (path, first_line, count, p3_min) = raw[0]
    assert len(raw) == 1
    assert path == paths[1]
    assert first_line == 2 + 100 * 120  # header line 1; 07:02:00 is 120 s into the file
    assert count == 500  # 5 s at 100 Hz
    assert p3_min * hoist.cylinders.bore_area_m2 < 0.3 * expected_load_n(hoist, 0.0) / 4
    # the position summary of the whole 10 min reaches both files
    assert position_audit == [(paths[0],), (paths[1],)]


def test_readme_example_queries_run(landed):
    _, root, _ = landed
    readme = (Path(__file__).resolve().parents[2] / "warehouse" / "README.md").read_text()
    queries = re.findall(r"```sql\n(.*?)```", readme, flags=re.DOTALL)
    assert len(queries) >= 8
    con = open_reader(root)
    try:
        (alarm_id,) = con.sql("SELECT alarm_id FROM alarms LIMIT 1").fetchall()[0]
        results = [con.sql(q.replace("<alarm_id>", alarm_id)).fetchall() for q in queries]
    finally:
        con.close()
    assert all(isinstance(r, list) for r in results)
    # the lineage queries of the README find the alarm's file and the positions' files
    lineage = next(r for q, r in zip(queries, results, strict=True) if "audit_alarm_lineage" in q)
    assert [row[-1] for row in lineage] == [str(root.path.parent / "logs" / "main-shaft-1.csv")]
    raw_lines = next(r for q, r in zip(queries, results, strict=True) if "source_line" in q)
    assert len(raw_lines) == 100


def test_rope_trip_extremes_name_the_file_of_each_ropes_worst_sample(tmp_path):
    """One trip over two raw files: each rope's worst sample is traced to its own file.

    Rope 1 pulls 1.5x for a second in the first file (06:56:40), rope 3 goes slack in the
    second (07:02:00); the other ropes' largest imbalance is then, too, in the second.
    """
    hoist = load_hoist(EXAMPLE_HOIST)
    root = DataRoot(tmp_path / "data")
    samples = _samples(hoist)
    seconds = (pl.col("time_utc") - T0).dt.total_microseconds() / 1e6
    tight = seconds.is_between(100.0, 101.0, closed="left")
    samples = samples.with_columns(
        pl.when(tight).then(1.5 * pl.col("tension1_n")).otherwise("tension1_n").alias(name)
        for name in ("tension1_n", "tension_raw1_n")
    ).with_columns(
        trip_id=pl.lit(0, dtype=pl.Int64),
        load_n=pl.sum_horizontal(f"tension{i}_n" for i in range(1, 5)),
    )
    manifest, shas = _ingest_by_hand(root, tmp_path, samples, hoist)
    _land_a_trip(root, "trip-run", samples, manifest, shas, hoist)
    con = open_reader(root)
    try:
        rows = con.sql(
            "select rope, is_worst_rope, max_imbalance_after_fraction, "
            "max_imbalance_after_time_utc, max_imbalance_after_time_local, "
            "max_tension_after_n, source_path, source_paths from rope_trip_extremes order by rope"
        ).fetchall()
        trip = con.sql(
            "select max_imbalance_after_rope, max_imbalance_after_fraction from trip_summary"
        ).fetchall()
    finally:
        con.close()
    files = [str(tmp_path / "logs" / f"main-shaft-{k}.csv") for k in (0, 1)]
    assert [(r[0], r[1], r[6], r[7]) for r in rows] == [
        (1, False, files[0], [files[0]]),
        (2, False, files[1], [files[1]]),
        (3, True, files[1], [files[1]]),
        (4, False, files[1], [files[1]]),
    ]
    peak1, peak3 = rows[0], rows[2]
    assert T0 + dt.timedelta(seconds=100) <= peak1[3] < T0 + dt.timedelta(seconds=101)
    assert T0 + dt.timedelta(seconds=420) <= peak3[3] < T0 + dt.timedelta(seconds=425)
    # Asia/Shanghai is UTC+8 all year
    assert peak3[4] == (peak3[3] + dt.timedelta(hours=8)).replace(tzinfo=None)
    # by hand: rope 3 at 0.2 x, the others at 1 x: mean 0.8, |0.2 - 0.8| / 0.8 = 0.75
    assert peak3[2] == pytest.approx(0.75, abs=0.02)
    # rope 1 at 1.5 x: mean 1.125, 0.375 / 1.125 = 1/3
    assert peak1[2] == pytest.approx(1 / 3, abs=0.02)
    assert peak1[5] == pytest.approx(1.5 * expected_load_n(hoist, 0.0) / 4, rel=0.02)
    assert trip == [(3, peak3[2])]


def test_rope_trip_extremes_name_the_file_that_landed_the_sample_where_files_overlap(tmp_path):
    """Two raw files cover the worst sample's time; the one that landed it is named.

    ``main-shaft-0.csv`` was exported over the whole 10 minutes, but ``main-shaft-1.csv``
    (the second half) had been ingested first, so the second half's samples in the lake
    came from file 1 (file 0's lines there were skipped as duplicates). Rope 3's worst
    sample (07:02:00) is file 1's: the first path of the covering files in sort order,
    file 0, is not the file it came from.
    """
    hoist = load_hoist(EXAMPLE_HOIST)
    root = DataRoot(tmp_path / "data")
    samples = _samples(hoist).with_columns(trip_id=pl.lit(0, dtype=pl.Int64))
    manifest, shas = _ingest_by_hand(root, tmp_path, samples, hoist)
    manifest = manifest.with_columns(  # file 0 covers the whole record
        pl.when(pl.col("source_sha256") == shas[0])
        .then(pl.lit(samples["time_utc"].max()))
        .otherwise(pl.col("time_end_utc"))
        .alias("time_end_utc")
    )
    _land_a_trip(root, "overlap-run", samples, manifest, shas, hoist)
    con = open_reader(root)
    try:
        rope3 = con.sql(
            "select max_imbalance_after_time_utc, source_path, source_sha256, source_paths "
            "from rope_trip_extremes where rope = 3"
        ).fetchall()
        (landed_sha,) = con.sql(
            "select s.source_sha256 from rope_trip_extremes r join stg_lake__field_samples s "
            "on s.time_utc = r.max_imbalance_after_time_utc where r.rope = 3"
        ).fetchall()[0]
    finally:
        con.close()
    files = [str(tmp_path / "logs" / f"main-shaft-{k}.csv") for k in (0, 1)]
    ((peak, path, sha, paths),) = rope3
    assert T0 + dt.timedelta(seconds=420) <= peak < T0 + dt.timedelta(seconds=425)
    assert landed_sha == shas[1]
    assert (path, sha) == (files[1], shas[1])
    assert paths == files  # both files cover the sample's time


def _land_a_trip(root, run_id, samples, manifest, shas, hoist) -> None:
    """The samples' trip landed by a run of the 10 minutes from T0 over the files
    ``shas`` (their manifest rows landed with it)."""
    run = RunRecord(
        run_id=run_id, command="run", code_version="t", started_at_utc=T0,
        hoist_sha256=hoist_sha256(EXAMPLE_HOIST), site=hoist.hoist.site, hoist=hoist.hoist.name,
        period_start_utc=T0, period_end_utc=T0 + dt.timedelta(minutes=10), inputs=shas,
        timezone=hoist.hoist.timezone,
    )  # fmt: skip
    _, trips = reconcile(samples, hoist, run_id=run.run_id, payload_kg=0.0)
    with open_writer(root) as con:
        insert_frame(con, "manifest", manifest)
        land_results(con, run, trip_summary=trips)
