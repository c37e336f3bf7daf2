"""Idempotent landing: same run or same period replaces, never duplicates; lake views."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import duckdb
import polars as pl
import pytest

from schemas.tables import ALARMS, POSITION_SUMMARY, ROPE_TENSIONS, TRIP_SUMMARY, conform
from warehouse.landing import RunRecord, land_results, land_rope_tensions
from warehouse.store import DataRoot, open_reader, open_writer
from warehouse.views import refresh_views

DAY = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)


def _run(run_id: str, *, day: dt.datetime = DAY) -> RunRecord:
    return RunRecord(
        run_id=run_id,
        command="run",
        code_version="test",
        started_at_utc=day,
        site="s",
        hoist="h",
        period_start_utc=day,
        period_end_utc=day + dt.timedelta(days=1),
        parameter_set="p",
    )


def _positions(run_id: str, n_trips: int, *, day: dt.datetime = DAY) -> pl.DataFrame:
    rows = [
        {
            "run_id": run_id,
            "site": "s",
            "hoist": "h",
            "trip_id": trip,
            "position": position,
            "time_start_utc": day + dt.timedelta(minutes=10 * trip + k),
            "load_after_n": 1.0e5,
        }
        for trip in range(n_trips)
        for k, position in enumerate(("bottom", "middle", "pithead"))
    ]
    return pl.DataFrame(rows).pipe(_conform, POSITION_SUMMARY)


def _trips(run_id: str, n_trips: int, *, day: dt.datetime = DAY) -> pl.DataFrame:
    rows = [
        {"run_id": run_id, "site": "s", "hoist": "h", "trip_id": trip,
         "time_start_utc": day + dt.timedelta(minutes=10 * trip), "payload_kg": 1000.0 * trip}
        for trip in range(n_trips)
    ]  # fmt: skip
    return pl.DataFrame(rows).pipe(_conform, TRIP_SUMMARY)


def _alarms(run_id: str, starts_min: list[int]) -> pl.DataFrame:
    rows = [
        {"alarm_id": f"a{m}", "run_id": run_id, "site": "s", "hoist": "h", "rule": "slack_rope",
         "rope": 1, "start_utc": DAY + dt.timedelta(minutes=m),
         "end_utc": DAY + dt.timedelta(minutes=m, seconds=5)}
        for m in starts_min
    ]  # fmt: skip
    return pl.DataFrame(rows).pipe(_conform, ALARMS)


def _conform(frame: pl.DataFrame, schema) -> pl.DataFrame:
    from schemas.tables import conform

    return conform(frame, schema)


def _counts(root: DataRoot) -> dict[str, list[tuple]]:
    con = open_reader(root)
    try:
        return {
            table: con.sql(f"SELECT run_id, count(*) FROM {table} GROUP BY 1 ORDER BY 1").fetchall()
            for table in ("runs", "position_summary", "trip_summary", "alarms")
        }
    finally:
        con.close()


def test_relanding_the_same_run_replaces(tmp_path):
    root = DataRoot(tmp_path)
    for _ in range(2):
        with open_writer(root) as con:
            land_results(
                con, _run("r1"), position_summary=_positions("r1", 4),
                trip_summary=_trips("r1", 4), alarms=_alarms("r1", [5, 50]),
            )  # fmt: skip
    assert _counts(root) == {
        "runs": [("r1", 1)],
        "position_summary": [("r1", 12)],
        "trip_summary": [("r1", 4)],
        "alarms": [("r1", 2)],
    }


def test_a_new_run_over_the_same_period_replaces_the_old_rows(tmp_path):
    root = DataRoot(tmp_path)
    next_day = DAY + dt.timedelta(days=1)
    with open_writer(root) as con:
        land_results(con, _run("old"), position_summary=_positions("old", 4),
                     trip_summary=_trips("old", 4), alarms=_alarms("old", [5]))  # fmt: skip
        land_results(
            con, _run("other-day", day=next_day),
            position_summary=_positions("other-day", 2, day=next_day),
        )  # fmt: skip
    with open_writer(root) as con:
        # the re-run finds 3 trips and no alarm: the old day's rows all go
        land_results(con, _run("new"), position_summary=_positions("new", 3),
                     trip_summary=_trips("new", 3), alarms=_alarms("new", []))  # fmt: skip
    counts = _counts(root)
    assert counts["position_summary"] == [("new", 9), ("other-day", 6)]
    assert counts["trip_summary"] == [("new", 3)]
    assert counts["alarms"] == []
    # runs are kept: the old run is still documented, it just owns no rows any more
    assert [r for r, _ in counts["runs"]] == ["new", "old", "other-day"]


def test_frames_must_belong_to_the_run(tmp_path):
    root = DataRoot(tmp_path)
    with pytest.raises(ValueError, match="run_id"), open_writer(root) as con:
        land_results(con, _run("r1"), position_summary=_positions("someone-else", 1))
    assert not root.warehouse.exists()  # nothing published


def test_rope_tensions_lake_view_and_partial_relanding(tmp_path):
    root = DataRoot(tmp_path / "data")
    times = [DAY + dt.timedelta(hours=h) for h in range(24)]
    frame = pl.DataFrame(
        {"time_utc": times, "load_n": [1.0] * 24},
        schema={"time_utc": pl.Datetime("us", "UTC"), "load_n": pl.Float64},
    )
    with open_writer(root) as con:
        assert con.sql("SELECT count(*) FROM rope_tensions").fetchall() == [(0,)]  # no files yet
        land_rope_tensions(root, frame, site="s", hoist="h", period_start_utc=DAY,
                           period_end_utc=DAY + dt.timedelta(days=1))  # fmt: skip
    table = root.table_dir("rope_tensions")
    before = {p.name: p.stat().st_mtime_ns for p in table.rglob("*.parquet")}
    # re-land the hours 06:00-12:00 with new values: 6 rows replaced, 18 kept
    with open_writer(root) as con:
        land_rope_tensions(
            root, frame.with_columns(load_n=pl.lit(2.0)), site="s", hoist="h",
            period_start_utc=DAY + dt.timedelta(hours=6),
            period_end_utc=DAY + dt.timedelta(hours=12),
        )  # fmt: skip
    con = open_reader(root)
    try:
        rows = con.sql(
            "SELECT load_after_n, count(*), min(site), min(hoist), min(date_utc) "
            "FROM rope_tensions GROUP BY 1 ORDER BY 1"
        ).fetchall()
    finally:
        con.close()
    assert rows == [(1.0, 18, "s", "h", DAY.date()), (2.0, 6, "s", "h", DAY.date())]
    files = sorted(p.name for p in table.rglob("*") if p.is_file())
    assert files == [f"hour-{h:02d}.parquet" for h in range(24)]  # and no staging left
    after = {p.name: p.stat().st_mtime_ns for p in table.rglob("*.parquet")}
    rewritten = sorted(name for name in after if after[name] != before[name])
    assert rewritten == [f"hour-{h:02d}.parquet" for h in range(6, 12)]  # only what changed


def test_a_day_file_of_the_earlier_layout_is_split_into_hours(tmp_path):
    root = DataRoot(tmp_path / "data")
    times = [DAY + dt.timedelta(hours=h, minutes=30) for h in range(24)]
    frame = pl.DataFrame(
        {"time_utc": times, "load_n": [float(h) for h in range(24)]},
        schema={"time_utc": pl.Datetime("us", "UTC"), "load_n": pl.Float64},
    )
    day_dir = root.partition_dir("rope_tensions", site="s", hoist="h", date=DAY.date())
    day_dir.mkdir(parents=True)
    conform(frame, ROPE_TENSIONS).write_parquet(day_dir / "data.parquet")
    with open_writer(root):
        land_rope_tensions(
            root, frame.filter(pl.col("load_n") == 3.0).with_columns(load_n=pl.lit(-3.0)),
            site="s", hoist="h", period_start_utc=DAY + dt.timedelta(hours=3),
            period_end_utc=DAY + dt.timedelta(hours=4),
        )  # fmt: skip
    assert sorted(p.name for p in day_dir.iterdir()) == [f"hour-{h:02d}.parquet" for h in range(24)]
    landed = pl.read_parquet(sorted(day_dir.glob("*.parquet")), hive_partitioning=False)
    assert landed["load_n"].to_list() == [-3.0 if h == 3 else float(h) for h in range(24)]


def test_views_follow_a_moved_data_root(tmp_path):
    root = DataRoot(tmp_path / "a")
    frame = pl.DataFrame(
        {"time_utc": [DAY], "load_n": [3.0]},
        schema={"time_utc": pl.Datetime("us", "UTC"), "load_n": pl.Float64},
    )
    with open_writer(root) as con:
        land_rope_tensions(root, frame, site="s", hoist="h", period_start_utc=DAY,
                           period_end_utc=DAY + dt.timedelta(days=1))  # fmt: skip
    moved = DataRoot(tmp_path / "b")
    root.path.rename(moved.path)
    con = open_reader(moved)
    try:
        with pytest.raises(duckdb.Error, match=r"No files found|does not exist"):
            con.sql("SELECT count(*) FROM rope_tensions").fetchall()
        # a reader can rebuild the views for the new place on its read-only connection
        refresh_views(con, moved, temporary=True)
        assert con.sql("SELECT load_after_n FROM rope_tensions").fetchall() == [(3.0,)]
    finally:
        con.close()
    with open_writer(moved):  # the next writer stores views for the new place
        pass
    con = open_reader(moved)
    try:
        assert con.sql("SELECT load_after_n FROM rope_tensions").fetchall() == [(3.0,)]
    finally:
        con.close()


def test_sanity_checks_and_findings_are_replaced_not_duplicated(tmp_path):
    from schemas.tables import DISCOVERY_FINDINGS, SANITY_CHECKS
    from warehouse.landing import land_discovery_findings

    root = DataRoot(tmp_path)

    def checks(run_id: str, trips: int) -> pl.DataFrame:
        rows = [{"run_id": run_id, "site": "s", "hoist": "h", "trip_id": t, "passed": True}
                for t in range(trips)]  # fmt: skip
        return _conform(pl.DataFrame(rows), SANITY_CHECKS)

    def finding(run_id: str) -> pl.DataFrame:
        row = {"run_id": run_id, "site": "s", "hoist": "h", "iteration": 0,
               "period_start_utc": DAY, "period_end_utc": DAY + dt.timedelta(days=1),
               "effect": "none", "report_json": "{}"}  # fmt: skip
        return _conform(pl.DataFrame([row]), DISCOVERY_FINDINGS)

    with open_writer(root) as con:
        land_results(con, _run("a"), trip_summary=_trips("a", 4), sanity_checks=checks("a", 4))
        land_discovery_findings(con, _run("a"), finding("a"))
    with open_writer(root) as con:  # same period, new run: its 2 trips replace the 4
        land_results(con, _run("b"), trip_summary=_trips("b", 2), sanity_checks=checks("b", 2))
        land_discovery_findings(con, _run("b"), finding("b"))
        land_discovery_findings(con, _run("b"), finding("b"))
    con = open_reader(root)
    try:
        sanity = con.sql("SELECT run_id, count(*) FROM sanity_checks GROUP BY 1").fetchall()
        findings = con.sql("SELECT run_id, count(*) FROM discovery_findings GROUP BY 1").fetchall()
    finally:
        con.close()
    assert sanity == [("b", 2)]
    assert findings == [("b", 1)]
    with open_writer(root) as con:  # a run without a check (a backfill's default)
        land_results(con, _run("c"), trip_summary=_trips("c", 3))
    with open_reader(root) as con:  # b's verdicts were on trips no run holds now
        assert con.sql("SELECT count(*) FROM sanity_checks").fetchall() == [(0,)]


def _legacy_day(root: DataRoot, minutes: list[int]) -> tuple[object, pl.DataFrame]:
    """A day file of the layout before hour files, rows at the given minutes of the day."""
    frame = pl.DataFrame(
        {"time_utc": [DAY + dt.timedelta(minutes=m) for m in minutes],
         "load_n": [float(m) for m in minutes]},
        schema={"time_utc": pl.Datetime("us", "UTC"), "load_n": pl.Float64},
    )  # fmt: skip
    day_dir = root.partition_dir("rope_tensions", site="s", hoist="h", date=DAY.date())
    day_dir.mkdir(parents=True, exist_ok=True)
    conform(frame, ROPE_TENSIONS).write_parquet(day_dir / "data.parquet")
    return day_dir, frame


def _landed(day_dir) -> list[float]:
    files = sorted(day_dir.glob("*.parquet"))
    return pl.read_parquet(files, hive_partitioning=False)["load_n"].to_list()


def test_a_rerun_without_rows_in_an_hour_of_a_day_file_removes_its_old_rows(tmp_path):
    root = DataRoot(tmp_path / "data")
    day_dir, _ = _legacy_day(root, [540, 600, 640, 660, 700, 760])  # 09:00 .. 12:40
    new = pl.DataFrame(
        {"time_utc": [DAY + dt.timedelta(minutes=635)], "load_n": [-1.0]},
        schema={"time_utc": pl.Datetime("us", "UTC"), "load_n": pl.Float64},
    )
    with open_writer(root):  # re-run 10:30-12:00: nothing new in hour 11
        land_rope_tensions(root, new, site="s", hoist="h",
                           period_start_utc=DAY + dt.timedelta(minutes=630),
                           period_end_utc=DAY + dt.timedelta(hours=12))  # fmt: skip
    assert _landed(day_dir) == [540.0, 600.0, -1.0, 760.0]


def test_a_publish_interrupted_while_splitting_a_day_file_is_healed_without_duplicates(tmp_path):
    root = DataRoot(tmp_path / "data")
    day_dir, frame = _legacy_day(root, [600, 640])  # 10:00, 10:40
    # the crash: hour 10 was split out of the day file, which was not yet removed
    ten = frame.filter(pl.col("time_utc") < DAY + dt.timedelta(hours=11))
    conform(ten, ROPE_TENSIONS).write_parquet(day_dir / "hour-10.parquet")
    new = pl.DataFrame(
        {"time_utc": [DAY + dt.timedelta(minutes=645)], "load_n": [-1.0]},
        schema={"time_utc": pl.Datetime("us", "UTC"), "load_n": pl.Float64},
    )
    with open_writer(root):  # re-run 10:30-11:00
        land_rope_tensions(root, new, site="s", hoist="h",
                           period_start_utc=DAY + dt.timedelta(minutes=630),
                           period_end_utc=DAY + dt.timedelta(hours=11))  # fmt: skip
    assert sorted(p.name for p in day_dir.iterdir()) == ["hour-10.parquet"]
    assert _landed(day_dir) == [600.0, -1.0]


def test_staging_folders_of_dead_runs_are_removed(tmp_path):
    from warehouse.landing import RopeTensionStage

    root = DataRoot(tmp_path / "data")
    table = root.table_dir("rope_tensions")
    dead = table / ".staging-999999999-0123abcd"  # no such pid
    (dead / "x").mkdir(parents=True)
    live = RopeTensionStage(root, site="s", hoist="h")
    live.folder.mkdir(parents=True)
    assert not dead.exists()
    RopeTensionStage(root, site="s", hoist="h")  # a second run does not remove a live one
    assert live.folder.exists()
    live.discard()


def test_an_alarm_across_a_rerun_start_is_not_landed_twice(tmp_path):
    """A whole day's run holds a 60 s imbalance from 00:45:00; a re-run of 00:45:30 ..
    01:00 sees it from its start to 00:46:00: the earlier alarm holds that piece whole,
    so it is not landed beside it. A new event of the re-run is."""
    root = DataRoot(tmp_path)

    def alarm(run_id: str, start_s: int, end_s: int) -> dict:
        start = DAY + dt.timedelta(seconds=start_s)
        return {"alarm_id": f"{run_id}{start_s}", "run_id": run_id, "site": "s", "hoist": "h",
                "rule": "rope_imbalance", "rope": 2, "start_utc": start,
                "end_utc": DAY + dt.timedelta(seconds=end_s)}  # fmt: skip

    with open_writer(root) as con:
        land_results(con, _run("day"), alarms=_conform(pl.DataFrame([alarm("day", 2700, 2760)]),
                                                       ALARMS))  # fmt: skip
    part = RunRecord(
        run_id="part", command="run", code_version="test", started_at_utc=DAY, site="s",
        hoist="h", period_start_utc=DAY + dt.timedelta(seconds=2730),
        period_end_utc=DAY + dt.timedelta(hours=1), parameter_set="p",
    )  # fmt: skip
    new = [alarm("part", 2730, 2760), alarm("part", 3000, 3010)]
    with open_writer(root) as con:
        inserted = land_results(con, part, alarms=_conform(pl.DataFrame(new), ALARMS))
    assert inserted["alarms"] == 1
    with open_reader(root) as con:
        rows = con.sql("SELECT run_id, start_utc FROM alarms ORDER BY start_utc").fetchall()
    assert [(r, (t - DAY).total_seconds()) for r, t in rows] == [("day", 2700), ("part", 3000)]


def test_a_damaged_lake_file_is_left_out_of_the_views_not_every_writer(tmp_path, caplog):
    """One hoist's field-sample file truncated to nothing from outside (the pipeline's
    own writes are atomic): a writer still opens (every writer refreshed the views and
    failed on it, the other hoists' too), the view holds the other files' rows and the
    log names the file; a day's scan of the lake does not open the next day's files."""
    import logging

    from pipelines.lake import scan_lake

    root = DataRoot(tmp_path)
    for hoist, day in (("a", 2), ("a", 3), ("b", 2)):
        _field_file(root, hoist, day)
    damaged = root.partition_dir("field_samples", site="s", hoist="a", date=dt.date(2026, 3, 3))
    (damaged / "part-1.parquet").write_bytes(b"")
    with caplog.at_level(logging.WARNING, logger="warehouse.views"), open_writer(root) as con:
        rows = con.sql("SELECT hoist, count(*) FROM lake_field_samples GROUP BY 1 ORDER BY 1")
        assert rows.fetchall() == [("a", 5), ("b", 5)]
    assert "1 unreadable Parquet file(s) left out" in caplog.text
    assert str(damaged / "part-1.parquet") in caplog.text
    day = scan_lake(root, "field_samples", site="s", hoist="a",
                    start=dt.datetime(2026, 3, 2, tzinfo=dt.UTC),
                    end=dt.datetime(2026, 3, 3, tzinfo=dt.UTC)).collect()  # fmt: skip
    assert day.height == 5


def _field_file(root: DataRoot, hoist: str, day: int) -> Path:
    """A five-row field-sample file of hoist ``hoist`` on March ``day``."""
    from schemas.tables import FIELD_SAMPLES
    from warehouse.parquet_files import write_parquet_atomic

    start = dt.datetime(2026, 3, day, tzinfo=dt.UTC)
    frame = conform(
        pl.DataFrame({"time_utc": [start + dt.timedelta(seconds=k) for k in range(5)],
                      "p1_pa": [4e6] * 5, "source_sha256": ["0" * 64] * 5,
                      "source_line": list(range(5))}),
        FIELD_SAMPLES,
    )  # fmt: skip
    folder = root.partition_dir("field_samples", site="s", hoist=hoist, date=start.date())
    folder.mkdir(parents=True, exist_ok=True)
    write_parquet_atomic(frame, folder / "part-1.parquet", FIELD_SAMPLES)
    return folder / "part-1.parquet"


def _view_comments(root: DataRoot) -> dict[str, str | None]:
    """Each stored view's fingerprint (its comment, less the files' check time)."""
    con = duckdb.connect(str(root.warehouse), read_only=True)
    try:
        rows = con.sql("SELECT view_name, comment FROM duckdb_views() WHERE NOT internal")
        rows = rows.fetchall()
        return {name: (comment or "").split(" checked-from:")[0] for name, comment in rows}
    finally:
        con.close()


def test_views_are_made_again_only_when_what_is_under_them_changed(tmp_path, caplog):
    """Each stored view carries the fingerprint of the set in its comment; a writer that
    finds them as it would make them leaves them (re-made, a glob view reads every
    file's footer: 2.7 s a writer at 1,500 files a table). What changes them: a lake
    table's first file (its view had no glob to read), a table's columns (a migration),
    a file damaged from outside after the views were stored (left out, said)."""
    import logging

    root = DataRoot(tmp_path)
    with open_writer(root):
        pass
    empty = _view_comments(root)
    fingerprints = set(empty.values())
    assert len(fingerprints) == 1
    assert next(iter(fingerprints)).startswith("ropeload-views:")
    assert {"lake_field_samples", "rope_tensions", "hoists"} <= set(empty)
    oids = "SELECT view_name, view_oid FROM duckdb_views() WHERE NOT internal ORDER BY 1"
    with open_writer(root) as con:
        before = con.sql(oids).fetchall()
        refresh_views(con, root)  # nothing under them changed: not made again
        assert con.sql(oids).fetchall() == before
    assert _view_comments(root) == empty
    _field_file(root, "a", 2)  # the table's first file: the view reads the glob now
    with open_writer(root) as con:
        assert con.sql("SELECT count(*) FROM lake_field_samples").fetchall() == [(5,)]
    first = _view_comments(root)
    assert set(first.values()) != fingerprints
    assert len(set(first.values())) == 1
    _field_file(root, "a", 3)  # another file: read by the glob view as it stands
    with open_writer(root) as con:
        assert con.sql("SELECT count(*) FROM lake_field_samples").fetchall() == [(10,)]
    assert _view_comments(root) == first
    with open_writer(root) as con:  # a table's columns changed (as a migration would)
        con.execute("ALTER TABLE runs ADD COLUMN note VARCHAR")
    with open_writer(root):
        pass
    altered = _view_comments(root)
    assert set(altered.values()) != set(first.values())
    damaged = _field_file(root, "b", 2)
    damaged.write_bytes(b"not parquet at all")
    with caplog.at_level(logging.WARNING, logger="warehouse.views"), open_writer(root) as con:
        rows = con.sql("SELECT hoist, count(*) FROM lake_field_samples GROUP BY 1 ORDER BY 1")
        assert rows.fetchall() == [("a", 10)]
    assert f"1 unreadable Parquet file(s) left out of the view: {damaged}" in caplog.text
    assert _view_comments(root) != altered
    damaged.unlink()  # removed: the view over the glob again
    _field_file(root, "b", 2)
    with open_writer(root):
        pass
    assert _view_comments(root) == altered
    # damaged inside after the views were stored, its ends whole: the footer of a file
    # changed since the last check is read
    data = bytearray(damaged.read_bytes())
    footer = int.from_bytes(data[-8:-4], "little")
    data[-8 - footer : -8] = b"\xff" * footer
    damaged.write_bytes(bytes(data))
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="warehouse.views"), open_writer(root) as con:
        rows = con.sql("SELECT hoist, count(*) FROM lake_field_samples GROUP BY 1 ORDER BY 1")
        assert rows.fetchall() == [("a", 10)]
    assert caplog.text.count(f"left out of the view: {damaged}") == 2
    damaged.unlink()
    _field_file(root, "b", 2)
    with open_writer(root) as con:
        rows = con.sql("SELECT hoist, count(*) FROM lake_field_samples GROUP BY 1 ORDER BY 1")
        assert rows.fetchall() == [("a", 10), ("b", 5)]
    assert _view_comments(root) == altered


def test_a_file_without_the_parquet_magic_bytes_is_unsound(tmp_path):
    """The writers' cheap test of every lake file: the format's four bytes at both ends
    (an empty file, junk, a copy cut short); a whole file passes."""
    from warehouse.views import unsound_files

    root = DataRoot(tmp_path)
    whole = _field_file(root, "a", 2)
    empty, junk, cut = (_field_file(root, h, 2) for h in ("b", "c", "d"))
    empty.write_bytes(b"")
    junk.write_text("not parquet")
    cut.write_bytes(whole.read_bytes()[:-10])
    assert unsound_files(root.table_dir("field_samples"))[0] == sorted([empty, junk, cut])
    # a footer damaged, the ends whole: found where the footers are read
    data = bytearray(whole.read_bytes())
    footer = int.from_bytes(data[-8:-4], "little")
    data[-8 - footer : -8] = b"\xff" * footer
    whole.write_bytes(bytes(data))
    newest = whole.stat().st_mtime_ns
    assert unsound_files(root.table_dir("field_samples"))[0] == sorted([whole, empty, junk, cut])
    later = unsound_files(root.table_dir("field_samples"), footers_from_ns=newest + 1)
    assert later == (sorted([empty, junk, cut]), newest)


def _at(seconds: float) -> dt.datetime:
    return DAY + dt.timedelta(seconds=seconds)


def _part_run(run_id: str, start_s: float, end_s: float) -> RunRecord:
    """A run of hoist s/h over [start_s, end_s) seconds of DAY."""
    return RunRecord(
        run_id=run_id, command="run", code_version="test", started_at_utc=DAY, site="s",
        hoist="h", period_start_utc=_at(start_s), period_end_utc=_at(end_s), parameter_set="p",
    )  # fmt: skip


def _trip_rows(run_id: str, spans: dict[int, tuple[float, float]]) -> pl.DataFrame:
    """Trip rows: trip_id -> (start, end) seconds of DAY."""
    rows = [{"run_id": run_id, "site": "s", "hoist": "h", "trip_id": k,
             "time_start_utc": _at(t0), "time_end_utc": _at(t1)}
            for k, (t0, t1) in spans.items()]  # fmt: skip
    return _conform(pl.DataFrame(rows, schema_overrides={"trip_id": pl.Int64}), TRIP_SUMMARY)


def _visit_rows(run_id: str, spans: list[tuple[int | None, str, float, float]]) -> pl.DataFrame:
    """Position visits: (trip_id, position, start, end seconds of DAY)."""
    rows = [{"run_id": run_id, "site": "s", "hoist": "h", "trip_id": k, "position": p,
             "time_start_utc": _at(t0), "time_end_utc": _at(t1)}
            for k, p, t0, t1 in spans]  # fmt: skip
    return _conform(pl.DataFrame(rows, schema_overrides={"trip_id": pl.Int64}), POSITION_SUMMARY)


def test_a_trip_and_a_visit_across_a_rerun_start_are_not_landed_twice(tmp_path):
    """An hour's run holds trip 3 (00:30:00 .. 00:31:40), the stop at the bottom after it
    (.. 00:40:00) and a stop at the pithead from 00:55 to its period's end. A re-run of
    00:31:00 .. 01:06:40 sees trip 3 from its own start to the trip's end: the earlier
    row holds that piece whole, so it is not landed beside it (one trip counted twice
    in the audit); its later trip is landed. A re-run of 00:33:20 .. sees the bottom stop
    from its start: the same. The next hour's run sees the pithead stop from 01:00 on:
    the earlier row ends at its own period's end, it does not hold that piece, which
    stays (the two periods' parts of one stop)."""
    root = DataRoot(tmp_path)

    run, trips, visits = _part_run, _trip_rows, _visit_rows

    def landed(table: str) -> list[tuple[str, float, float]]:
        with open_reader(root) as con:
            rows = con.sql(
                f"SELECT run_id, time_start_utc, time_end_utc FROM {table} ORDER BY 2, 1"
            ).fetchall()
        return [(r, (a - DAY).total_seconds(), (b - DAY).total_seconds()) for r, a, b in rows]

    with open_writer(root) as con:
        land_results(
            con, run("hour", 0, 3600),
            trip_summary=trips("hour", {0: (600, 700), 1: (1800, 1900)}),
            position_summary=visits(
                "hour", [(0, "bottom", 1900, 2400), (0, "pithead", 3300, 3600)]
            ),
        )  # fmt: skip
    with open_writer(root) as con:
        inserted = land_results(
            con,
            run("trip", 1860, 4000),
            trip_summary=trips("trip", {0: (1860, 1900), 1: (3000, 3100)}),
        )
    assert inserted["trip_summary"] == 1
    assert landed("trip_summary") == [("hour", 600, 700), ("hour", 1800, 1900),
                                      ("trip", 3000, 3100)]  # fmt: skip
    with open_writer(root) as con:
        inserted = land_results(
            con,
            run("stop", 2000, 3000),
            position_summary=visits("stop", [(0, "bottom", 2000, 2400)]),
        )
    assert inserted["position_summary"] == 0
    with open_writer(root) as con:
        land_results(
            con,
            run("next", 3600, 7200),
            position_summary=visits("next", [(0, "pithead", 3600, 3900)]),
        )
    assert landed("position_summary") == [("hour", 1900, 2400), ("hour", 3300, 3600),
                                          ("next", 3600, 3900)]  # fmt: skip


def test_the_visits_of_a_trip_an_earlier_row_holds_stay_that_runs(tmp_path):
    """An hour's run holds trip 3 (00:30:00 .. 00:31:40) with its visits at the bottom,
    the middle and the pithead (00:31:30 ..). A re-run from 00:31:00 sees the trip from
    its start: the earlier trip row stays, and so do its visits, the pithead one too
    (it begins in the re-run's period); the re-run's visit of that trip is not landed (it
    named a trip the re-run did not land: the trip's visits were two runs', one of them
    without its trip row). The re-run's later trip lands with its visits."""
    root = DataRoot(tmp_path)

    run, trips, visits = _part_run, _trip_rows, _visit_rows

    with open_writer(root) as con:
        land_results(
            con, run("hour", 0, 3600), trip_summary=trips("hour", {3: (1800, 1900)}),
            position_summary=visits("hour", [(3, "bottom", 1800, 1810), (3, "middle", 1850, 1851),
                                             (3, "pithead", 1890, 1900),
                                             (None, "pithead", 1900, 3599.98)]),
        )  # fmt: skip
    with open_writer(root) as con:
        inserted = land_results(
            con, run("part", 1860, 3600),
            trip_summary=trips("part", {0: (1860, 1900), 1: (3000, 3100)}),
            position_summary=visits("part", [(0, "pithead", 1890, 1900),
                                             (None, "pithead", 1900, 3000),
                                             (1, "pithead", 3000, 3010)]),
        )  # fmt: skip
    assert inserted == {"trip_summary": 1, "position_summary": 2}
    with open_reader(root) as con:
        rows = con.sql(
            "SELECT run_id, trip_id, position, time_start_utc FROM position_summary ORDER BY 4"
        ).fetchall()
        strays = con.sql(
            "SELECT run_id, trip_id FROM position_summary p WHERE trip_id IS NOT NULL AND NOT "
            "EXISTS (SELECT 1 FROM trip_summary t WHERE (t.run_id, t.trip_id) = "
            "(p.run_id, p.trip_id))"
        ).fetchall()
    assert [(r, k, p, (t - DAY).total_seconds()) for r, k, p, t in rows] == [
        ("hour", 3, "bottom", 1800), ("hour", 3, "middle", 1850), ("hour", 3, "pithead", 1890),
        ("part", None, "pithead", 1900), ("part", 1, "pithead", 3000),
    ]  # fmt: skip
    assert strays == []


def test_a_trip_a_stop_and_an_alarm_across_a_rerun_end_are_not_cut_short(tmp_path):
    """A day's run holds trip 3 (00:30:00 .. 00:31:40) with its visits, the stop at the
    pithead after it (.. 00:50:00) and two sensor dropouts (00:41:40 .. 00:41:50,
    00:41:43 .. 00:42:00 on another rope). A re-run of 00:16:40 .. 00:31:00 sees trip 3
    up to its end only: the day's whole row stays, and its visits (the re-run's
    fragment had replaced it, the rest of the trip lost). A re-run of 00:31:35 ..
    00:41:45 sees the stop and the first dropout only up to its end, and not the second
    (3 s: too short for its rule): the day's rows stay, nothing of the re-run's beside."""
    root = DataRoot(tmp_path)

    at, run, trips, visits = _at, _part_run, _trip_rows, _visit_rows

    def alarms(run_id: str, spans: list[tuple[int, float, float]]) -> pl.DataFrame:
        rows = [{"alarm_id": f"{rope}@{t0}", "run_id": run_id, "site": "s", "hoist": "h",
                 "rule": "sensor_dropout", "rope": rope, "start_utc": at(t0), "end_utc": at(t1)}
                for rope, t0, t1 in spans]  # fmt: skip
        return _conform(pl.DataFrame(rows), ALARMS)

    def landed() -> dict[str, list[tuple]]:
        with open_reader(root) as con:
            return {
                table: [
                    (r, k, (a - DAY).total_seconds(), (b - DAY).total_seconds())
                    for r, k, a, b in con.sql(
                        f"SELECT run_id, {key}, {start}, {end} FROM {table} ORDER BY 3, 2"
                    ).fetchall()
                ]
                for table, key, start, end in (
                    ("trip_summary", "trip_id", "time_start_utc", "time_end_utc"),
                    ("position_summary", "position", "time_start_utc", "time_end_utc"),
                    ("alarms", "rope", "start_utc", "end_utc"),
                )
            }

    with open_writer(root) as con:
        land_results(
            con, run("day", 0, 7200), trip_summary=trips("day", {3: (1800, 1900)}),
            position_summary=visits("day", [(3, "bottom", 1800, 1810), (3, "middle", 1850, 1851),
                                            (3, "pithead", 1890, 1900),
                                            (None, "pithead", 1900, 3000)]),
            alarms=alarms("day", [(1, 2500, 2510), (2, 2503, 2520)]),
        )  # fmt: skip
    day = landed()
    with open_writer(root) as con:
        inserted = land_results(
            con, run("part", 1000, 1860), trip_summary=trips("part", {0: (1800, 1859.98)}),
            position_summary=visits("part", [(0, "bottom", 1800, 1810), (0, "middle", 1850, 1851)]),
            alarms=alarms("part", []),
        )  # fmt: skip
    assert inserted == {"trip_summary": 0, "position_summary": 0, "alarms": 0}
    assert landed() == day
    with open_writer(root) as con:
        inserted = land_results(
            con, run("late", 1895, 2505), trip_summary=trips("late", {0: (1895, 1900)}),
            position_summary=visits("late", [(0, "pithead", 1895, 1900),
                                             (None, "pithead", 1900, 2504.98)]),
            alarms=alarms("late", [(1, 2500, 2504.98)]),
        )  # fmt: skip
    assert inserted == {"trip_summary": 0, "position_summary": 0, "alarms": 0}
    assert landed() == day
    with open_writer(root) as con:  # a re-run that finds no alarm: the dropouts stay
        land_results(con, run("none", 2400, 2505), alarms=alarms("none", []))
    assert landed()["alarms"] == day["alarms"]
