"""``ropeload run`` in blocks (issue 16): the block size changes memory, not results.

A simulated 70-minute record across UTC midnight, ingested and run with 10-minute and
60-minute blocks into two data roots: the landed rope tensions (one file per UTC hour),
position and trip summaries and alarms agree. A re-run of 20 minutes rewrites only the
hour files it touches. A block of 0 minutes is refused with a one-line error.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import re
import shutil
from itertools import pairwise
from pathlib import Path

import polars as pl
import pytest
from polars.testing import assert_frame_equal

from pipelines.cli import main
from pipelines.lake import scan_lake
from schemas.hoist import load_hoist
from sims.field_day import generate_field_day, write_field_day
from warehouse.store import DataRoot, open_reader

REPO = Path(__file__).resolve().parents[2]
HOIST_PATH = REPO / "schemas" / "hoists" / "paper_field_test.toml"
HOIST = load_hoist(HOIST_PATH)
SITE, NAME = HOIST.hoist.site, HOIST.hoist.name


@pytest.fixture(scope="module")
def record(tmp_path_factory) -> Path:
    # 07:30-08:40 local (UTC+8) = 23:30-00:40 UTC: across midnight and three UTC hours
    day = generate_field_day(
        HOIST, date="2026-03-02", seed=9, trips=6, hours=70 / 60, start_hour=7.5
    )
    folder = tmp_path_factory.mktemp("logs")
    return write_field_day(day, folder, formats=("csv",))[0]


@pytest.fixture(scope="module")
def whole(record: Path, tmp_path_factory) -> Path:
    """The record ingested and run whole (60-minute blocks, no sanity check): read it, or
    copy it (:func:`_copy`) to run again on it."""
    data = tmp_path_factory.mktemp("whole") / "data"
    _run(record, data)
    return data


def _copy(whole: Path, tmp_path: Path) -> Path:
    """A data root of the whole run's own, its files' times kept."""
    return Path(shutil.copytree(whole, tmp_path / "data"))


def _run(record: Path, data: Path, *extra: str) -> None:
    if not (data / "lake").exists():
        assert main(["ingest", "--data", str(data), "--hoist", str(HOIST_PATH), str(record)]) == 0
    command = ["run", "--data", str(data), "--hoist", str(HOIST_PATH), "--no-sanity", *extra]
    assert main(command) == 0


def _marts(data: Path) -> dict[str, pl.DataFrame]:
    con = open_reader(DataRoot.resolve(data))
    try:
        return {
            table: con.sql(f"SELECT * EXCLUDE (run_id) FROM {table} ORDER BY ALL").pl()
            for table in ("position_summary", "trip_summary", "alarms")
        }
    finally:
        con.close()


def test_block_size_changes_nothing_landed(
    record: Path, whole: Path, tmp_path: Path, capsys
) -> None:
    small, large = tmp_path / "small", whole
    _run(record, small, "--block-minutes", "10")
    capsys.readouterr()
    a = scan_lake(DataRoot.resolve(small), "rope_tensions", site=SITE, hoist=NAME).collect()
    b = scan_lake(DataRoot.resolve(large), "rope_tensions", site=SITE, hoist=NAME).collect()
    assert a.height == b.height > 400_000
    assert_frame_equal(a, b, rel_tol=1e-9, abs_tol=1e-6)
    files = sorted(
        p.relative_to(small / "lake" / "rope_tensions").as_posix()
        for p in (small / "lake" / "rope_tensions").rglob("*.parquet")
    )
    assert [f.split("/", 2)[2] for f in files] == [
        "date=2026-03-01/hour-23.parquet",
        "date=2026-03-02/hour-00.parquet",
    ]
    # the identification's means do not depend on the blocks (the cache file is named by
    # their digest), and each data root remembers its ropes
    (cached_a,) = (small / "cache" / "rope_springs").glob("*.json")
    (cached_b,) = (large / "cache" / "rope_springs").glob("*.json")
    assert cached_a.name == cached_b.name
    marts_a, marts_b = _marts(small), _marts(large)
    assert marts_a["trip_summary"].height == 6
    for table in marts_a:
        assert_frame_equal(marts_a[table].drop("alarm_id", strict=False),
                           marts_b[table].drop("alarm_id", strict=False),
                           rel_tol=1e-9, abs_tol=1e-6)  # fmt: skip


def test_rerun_of_twenty_minutes_rewrites_only_its_hour(
    record: Path, whole: Path, tmp_path: Path, capsys
):
    data = _copy(whole, tmp_path)
    table = data / "lake" / "rope_tensions"
    before = {p.name: p.stat().st_mtime_ns for p in table.rglob("*.parquet")}
    _run(record, data, "--from", "2026-03-02T00:10:00+00:00", "--to", "2026-03-02T00:30:00+00:00")
    capsys.readouterr()
    after = {p.name: p.stat().st_mtime_ns for p in table.rglob("*.parquet")}
    assert sorted(n for n in after if after[n] != before[n]) == ["hour-00.parquet"]
    landed = scan_lake(DataRoot.resolve(data), "rope_tensions", site=SITE, hoist=NAME).collect()
    assert landed["time_utc"].is_unique().all()  # replaced, not duplicated


def test_a_rerun_of_part_of_a_period_leaves_no_check_of_a_replaced_trip(
    record: Path, tmp_path: Path, capsys
):
    """The whole record run with its sanity check, then 20 minutes of it again: the
    trips the second run takes over leave the first run's ``trip_summary``, and their
    sanity checks go with them (they stayed, a verdict on a trip no run had any more).
    Every check names a trip of its run."""
    data = tmp_path / "checked"
    assert main(["ingest", "--data", str(data), "--hoist", str(HOIST_PATH), str(record)]) == 0
    base = ["run", "--data", str(data), "--hoist", str(HOIST_PATH)]
    assert main(base) == 0
    capsys.readouterr()
    assert (
        main([*base, "--from", "2026-03-02T00:00:00+00:00", "--to", "2026-03-02T00:30:00+00:00"])
        == 0
    )
    said = capsys.readouterr().out
    rerun = re.search(r"run (run-\S+):", said).group(1)
    printed = re.search(r"(\d+) of (\d+) trips passed", said)
    con = open_reader(DataRoot.resolve(data))
    try:
        kept = con.execute(
            "SELECT count(*) FILTER (status = 'passed'), count(*) FILTER (status <> 'skipped') "
            "FROM sanity_checks WHERE run_id = ?",
            [rerun],
        ).fetchall()[0]
        runs = con.sql("SELECT count(DISTINCT run_id) FROM sanity_checks").fetchall()[0][0]
        orphans = con.sql(
            "SELECT c.run_id, c.trip_id FROM sanity_checks c ANTI JOIN trip_summary t "
            "USING (run_id, trip_id)"
        ).fetchall()
        moved = con.sql(
            "SELECT count(*) FROM trip_summary WHERE time_start_utc >= '2026-03-02 00:00:00+00'"
            " AND time_end_utc < '2026-03-02 00:30:00+00' GROUP BY run_id"
        ).fetchall()  # a trip across the period's end stays the first run's whole row
    finally:
        con.close()
    assert runs == 2
    assert len(moved) == 1  # the period's trips are the second run's only
    assert orphans == []
    # the printed line counts the verdicts kept: not one on the trip across the period's
    # end, which stays the first run's (it had said 3 of 3 and kept 2)
    assert (int(printed.group(1)), int(printed.group(2))) == kept
    assert kept[1] >= 1


def test_a_rerun_from_inside_a_trip_lands_each_trip_and_visit_once(
    record: Path, whole: Path, tmp_path: Path, capsys
) -> None:
    """The whole record run, then again from the middle of its third trip: the trip and
    the stops the second run sees from its start on are the first run's rows still (it
    held them whole), the later ones the second run's; no two rows of a mart overlap
    (a review measured 8 trip rows for 7 trips)."""
    data = _copy(whole, tmp_path)
    con = open_reader(DataRoot.resolve(data))
    try:
        first = con.sql(
            "SELECT time_start_utc, time_end_utc FROM trip_summary ORDER BY 1"
        ).fetchall()
    finally:
        con.close()
    start, end = first[2]
    middle = start + (end - start) / 2
    _run(record, data, "--from", middle.isoformat())
    said = capsys.readouterr().out
    con = open_reader(DataRoot.resolve(data))
    try:
        trips = con.sql(
            "SELECT run_id, time_start_utc, time_end_utc FROM trip_summary ORDER BY 2"
        ).fetchall()
        visits = con.sql(
            "SELECT run_id, time_start_utc, time_end_utc FROM position_summary ORDER BY 2"
        ).fetchall()
        strays = con.sql(  # a trip's visits are its row's run's: none names a trip not landed
            "SELECT run_id, trip_id, time_start_utc FROM position_summary p WHERE trip_id IS "
            "NOT NULL AND NOT EXISTS (SELECT 1 FROM trip_summary t WHERE (t.run_id, t.trip_id) "
            "= (p.run_id, p.trip_id))"
        ).fetchall()
    finally:
        con.close()
    assert strays == []
    assert len(trips) == len(first) == 6
    assert " 3 trips" in said  # what the re-run landed
    assert [(a, b) for _, a, b in trips[:3]] == first[:3]
    assert len({r for r, _, _ in trips[3:]}) == 1 != trips[0][0]  # the later: the re-run's
    for rows in (trips, visits):
        for (_, _, end_a), (_, start_b, _) in pairwise(rows):
            assert end_a <= start_b


def test_a_block_of_no_minutes_is_refused(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--data", str(tmp_path), "--hoist", str(HOIST_PATH), "--block-minutes", "0"])
    assert exit_info.value.code == 2
    assert "--block-minutes: must be a positive number of minutes, got 0" in capsys.readouterr().err


@pytest.mark.parametrize("trips", ["0", "two", "1.5"])
def test_a_sanity_sample_of_no_whole_trips_is_refused(tmp_path: Path, capsys, trips) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--data", str(tmp_path), "--hoist", str(HOIST_PATH), "--sanity-trips", trips])
    assert exit_info.value.code == 2
    assert f"--sanity-trips: must be a whole number of trips >= 1, got {trips}" in (
        capsys.readouterr().err
    )


def test_band_members_on_means_are_asked_for_and_recorded(record: Path, tmp_path: Path, capsys):
    """``--band-member-step``: the run says in ``runs.message`` that its band's members ran
    on means (transforms.band_members), and the band still holds the estimate."""
    data = tmp_path / "means"
    _run(record, data, "--band-member-step", "0.1")
    capsys.readouterr()
    con = open_reader(DataRoot.resolve(data))
    try:
        (message,) = con.sql("SELECT message FROM runs WHERE command = 'run'").fetchall()[0]
    finally:
        con.close()
    assert message.endswith("; band members on 0.1 s means")
    landed = scan_lake(DataRoot.resolve(data), "rope_tensions", site=SITE, hoist=NAME).collect()
    inside = landed.select(
        ((pl.col("load_lo_n") <= pl.col("load_n")) & (pl.col("load_n") <= pl.col("load_hi_n")))
        .mean()
        .alias("share")
    )["share"][0]
    assert inside > 0.99
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--data", str(data), "--hoist", str(HOIST_PATH), "--band-member-step", "-1"])
    assert exit_info.value.code == 2
    assert (
        "--band-member-step: must be 0 or a whole fraction of a second" in capsys.readouterr().err
    )


def test_a_sensor_that_repeats_its_logged_value_raises_a_flatline(tmp_path: Path, capsys):
    """Sensor 3 logs one value for 40 s while the conveyance travels (a frozen
    transmitter): ``ropeload run`` raises ``sensor_flatline`` on rope 3 over that
    stretch. The rule reads the logged pressures: the staged ones are low-passed, and
    a low-passed value never repeats (the alarm never fired in a run)."""
    day = generate_field_day(HOIST, date="2026-03-02", seed=3, trips=2, hours=0.25,
                             sample_rate_hz=20.0)  # fmt: skip
    moving = day.truth.filter(pl.col("trip_id") == 0, pl.col("phase") == "run")
    frozen_from = moving["time_utc"].min()
    frozen_to = frozen_from + dt.timedelta(seconds=40)
    window = pl.col("time_utc").is_between(frozen_from, frozen_to, closed="left")
    held = day.sensors.filter(window)["p3_pa"].drop_nulls()[0]
    sensors = day.sensors.with_columns(
        pl.when(window & pl.col("p3_pa").is_not_null()).then(held)
        .otherwise(pl.col("p3_pa")).alias("p3_pa")
    )  # fmt: skip
    written = write_field_day(
        dataclasses.replace(day, sensors=sensors), tmp_path / "logs", formats=("csv",)
    )
    path = written[0]
    data = tmp_path / "data"
    _run(path, data)
    capsys.readouterr()
    with open_reader(DataRoot.resolve(data)) as con:
        flat = con.sql(
            "SELECT rope, start_utc, end_utc FROM alarms WHERE rule = 'sensor_flatline'"
        ).fetchall()
    assert [rope for rope, _, _ in flat] == [3]
    ((_, start, end),) = flat
    assert abs((start - frozen_from).total_seconds()) < 1.0
    assert abs((end - frozen_to).total_seconds()) < 1.0
