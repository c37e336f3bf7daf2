"""Nightly (plain functions): new files since the watermark, late files, self-healing nights."""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import inspect
import os
import shutil
from pathlib import Path

import polars as pl
import pytest

from pipelines.cli import main
from pipelines.cli_parser import build_parser as build_cli_parser
from pipelines.deploy import build_parser, nightly_parameters, write_example_mine
from pipelines.flows import nightly_flow
from pipelines.hoist_day import check_sanity
from pipelines.hoists import find_new_files, known_files, load_hoists
from pipelines.lake import scan_lake
from pipelines.ledger import fingerprint, partition_ledger
from pipelines.night_options import add_night_options
from pipelines.nightly import nightly, watermarks
from pipelines.steps import steps_of
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.field_day import generate_field_day, write_field_day
from warehouse.store import DataRoot, open_reader


@pytest.fixture(scope="module")
def mine(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("night-mine")
    return write_example_mine(root, hoists=2, days=2)


@pytest.fixture
def site(mine, tmp_path) -> tuple[Path, Path, DataRoot]:
    """A private copy of the mine (tests add files and edit hoists)."""
    hoists, incoming = mine
    shutil.copytree(hoists, tmp_path / "hoists")
    shutil.copytree(incoming, tmp_path / "incoming")
    return tmp_path / "hoists", tmp_path / "incoming", DataRoot.resolve(tmp_path / "data")


def test_a_night_takes_new_files_only_and_moves_the_watermark(site):
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    assert [len(find_new_files(s, known_files(data))) for s in sources] == [2, 2]
    first = nightly(sources, data=data)
    assert first.ok, str(first)
    assert first.runs.count("succeeded") == 4
    # every day run is checked against the simulation; the synthetic data pass
    # every trip is checked but a day's first, which only warms up the friction state
    assert all(o.checks >= 1 for o in first.runs.outcomes)
    assert sum(o.checks_failed for o in first.runs.outcomes) == 0
    assert first.discoveries == {}
    # a row per trip, the warm-ups' skipped with their reason
    assert fingerprint(data)["sanity_checks"][0] == sum(
        o.checks + o.checks_skipped for o in first.runs.outcomes
    )
    marks = watermarks(data)
    assert marks[("paper-field-test", "shaft-1")] == first.hoists[0].watermark_after
    assert marks[("paper-field-test", "shaft-1")].date() == dt.date(2026, 3, 3)
    assert [len(find_new_files(s, known_files(data))) for s in sources] == [0, 0]
    before = fingerprint(data)
    second = nightly(sources, data=data)
    assert second.runs.outcomes == []
    assert fingerprint(data) == before  # re-running a night changes nothing
    assert "0 new file(s)" in str(second)


def test_a_late_file_reopens_only_its_day(site):
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    assert nightly(sources, data=data, sanity=False).ok
    runs_before = partition_ledger(data).select("hoist", "day", "run_id")
    # an hour file for shaft-1, 2026-03-02 14:00 local, copied in late with an old mtime
    hoist = load_hoist(hoists / "shaft-1.toml")
    late = generate_field_day(
        hoist, date="2026-03-02", seed=99, trips=2, hours=1 / 6, start_hour=14.0
    )
    target = incoming / "paper-field-test" / "shaft-1"
    written = write_field_day(late, target, formats=("csv",), split="hour")
    for path in written:
        if path.suffix != ".csv":
            path.unlink()
        else:
            os.utime(path, (0, 0))  # rsync -a keeps the source's old mtime
    night = nightly(sources, data=data, sanity=False)
    assert [n.row()["new_files"] for n in night.hoists] == [1, 0]
    assert [o.key for o in night.runs.outcomes if o.status == "succeeded"] == [
        "paper-field-test/shaft-1/2026-03-02"
    ]
    runs_after = partition_ledger(data).select("hoist", "day", "run_id")
    rerun = runs_after.join(runs_before, on=["hoist", "day"], suffix="_before").filter(
        pl.col("run_id") != pl.col("run_id_before")
    )
    assert rerun.select("hoist", "day").rows() == [("shaft-1", dt.date(2026, 3, 2))]


class _Killed(BaseException):
    """A night's process killed (as by ``kill -9``: nothing of the night's own catches it)."""


def test_a_night_killed_after_its_plan_is_finished_by_the_next(site):
    """The first night ingests both hoists' two days and is killed once it knows what to
    run: the files are in the manifest (no longer new) and no day has a run. The next
    night, with no lookback, runs the four days the killed one planned (it ran none and
    said nothing: a week of arrears was lost the same way), then nothing is pending."""
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)

    def killed(partitions):
        assert len(partitions) == 4
        raise _Killed

    with pytest.raises(_Killed):
        nightly(sources, data=data, lookback_days=0, sanity=False, on_plan=killed)
    assert [len(find_new_files(s, known_files(data))) for s in sources] == [0, 0]
    _runs_the_four_days_once(sources, data)


def _runs_the_four_days_once(sources, data) -> None:
    """The next night runs both hoists' two days, and the one after runs nothing."""
    night = nightly(sources, data=data, lookback_days=0, sanity=False)
    assert sorted(o.key for o in night.runs.outcomes if o.status == "succeeded") == [
        f"paper-field-test/shaft-{k}/2026-03-0{d}" for k in (1, 2) for d in (2, 3)
    ]
    assert nightly(sources, data=data, lookback_days=0, sanity=False).runs.outcomes == []


def test_files_a_killed_night_ingested_before_its_plan_are_run_by_the_next(site):
    """A night killed during its ingest (here: the files ingested as that night's
    ingest lands them, and no plan saved): the next night, with no lookback and nothing
    new, runs the days of those files, never run (they were no longer new, and no plan
    named them)."""
    from pipelines.hoists import hoist_lookup, raw_files
    from pipelines.ingest import ingest_paths

    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    for source in sources:
        report = ingest_paths(raw_files(source), data=data, hoist_lookup=hoist_lookup(source))
        assert report.ok
    assert [len(find_new_files(s, known_files(data))) for s in sources] == [0, 0]
    _runs_the_four_days_once(sources, data)


def test_a_recalibrated_hoist_is_rerun_within_the_lookback(site):
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    assert nightly(sources, data=data, sanity=False).ok
    path = hoists / "shaft-2.toml"
    path.write_text(path.read_text() + "\n# friction parameters recalibrated\n")
    night = nightly(sources, data=data, lookback_days=1, sanity=False)  # no new file
    assert [o.key for o in night.runs.outcomes] == ["paper-field-test/shaft-2/2026-03-03"]


def test_a_hoist_failing_its_ingest_does_not_hold_up_the_others_and_heals(site):
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    path = hoists / "shaft-2.toml"
    good = path.read_text()
    path.write_text(good.replace('mass = "8.2 t"', 'mass = "8.2 m"'))
    broken = nightly(sources, data=data, retries=0, sanity=False)
    assert not broken.ok
    assert "HoistDescriptionError" in broken.hoists[1].error
    assert "conveyance.mass" in str(broken)
    assert broken.runs.count("succeeded") == 2  # shaft-1 is not held up
    path.write_text(good)
    healed = nightly(
        sources, data=data, sanity=False
    )  # shaft-2's files were never ingested: still new
    assert healed.ok
    assert sorted(o.key for o in healed.runs.outcomes if o.status == "succeeded") == [
        "paper-field-test/shaft-2/2026-03-02",
        "paper-field-test/shaft-2/2026-03-03",
    ]


# ------------------------------------------- ordinary data never fail a night (issue 15)

MIDNIGHT = dt.datetime(2026, 3, 3, tzinfo=dt.UTC)


@pytest.fixture(scope="module")
def midnight_mine(tmp_path_factory) -> tuple[Path, Path]:
    """One hoist, a 10 Hz logger, three trips 150 s apart from 23:56:40Z: trip 0 on
    2026-03-02, trip 1 across UTC midnight (moving 23:59:20Z .. 00:00:53Z), and the
    record ends at 00:02:40Z, 50 s into trip 2's motion."""
    root = tmp_path_factory.mktemp("midnight-mine")
    hoist_dir, incoming = root / "hoists", root / "incoming"
    hoist_dir.mkdir()
    path = hoist_dir / "main-shaft.toml"
    path.write_text(EXAMPLE_HOIST.read_text(encoding="utf-8"))
    hoist = load_hoist(path)
    start = MIDNIGHT - dt.timedelta(minutes=3, seconds=20)  # 07:56:40 in Asia/Shanghai
    local_hours = 8.0 - (3 * 60 + 20) / 3600
    day = generate_field_day(
        hoist, date="2026-03-03", seed=11, trips=3, hours=3 * 150 / 3600,
        start_hour=local_hours, sample_rate_hz=10.0, loading_s=5.0, rest_after_s=20.0,
        oil_temp_c=(30.0, 31.0),
    )  # fmt: skip
    assert abs(day.sensors["time_utc"].min() - start) < dt.timedelta(seconds=0.01)  # jitter
    cut = dataclasses.replace(
        day, sensors=day.sensors.filter(pl.col("time_utc") < start + dt.timedelta(seconds=360))
    )
    target = incoming / hoist.hoist.site / hoist.hoist.name
    for written in write_field_day(cut, target, formats=("csv",)):
        if written.suffix != ".csv":
            written.unlink()
    return hoist_dir, incoming


@pytest.fixture
def midnight(midnight_mine, tmp_path) -> tuple[Path, Path, DataRoot]:
    hoists, incoming = midnight_mine
    shutil.copytree(hoists, tmp_path / "hoists")
    shutil.copytree(incoming, tmp_path / "incoming")
    return tmp_path / "hoists", tmp_path / "incoming", DataRoot.resolve(tmp_path / "data")


def _runs(data: DataRoot) -> list[tuple]:
    con = open_reader(data)
    try:
        return con.sql("SELECT * FROM runs ORDER BY run_id").fetchall()
    finally:
        con.close()


def _lake_files(data: DataRoot) -> dict[str, tuple[int, int]]:
    return {
        str(p.relative_to(data.path)): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in sorted((data.path / "lake").rglob("*.parquet"))
    }


def test_a_trip_across_midnight_and_a_record_ending_mid_trip_are_a_done_night(midnight, capsys):
    hoists, incoming, data = midnight
    argv = ["nightly", "--hoists", str(hoists), "--incoming", str(incoming),
            "--data", str(data.path), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "2 partitions: 2 run, 0 already done, 0 without data, 0 failed" in out
    assert "sanity checks: 2/2 trips passed" in out
    assert "findings" not in out
    ledger = partition_ledger(data)
    assert ledger.select("day", "status").rows() == [
        (dt.date(2026, 3, 2), "succeeded"),
        (dt.date(2026, 3, 3), "succeeded"),
    ]
    # the tensions of both days are landed
    lake = scan_lake(data, "rope_tensions", site="paper-field-test", hoist="main-shaft")
    tensions = lake.select("time_utc").collect()["time_utc"]
    assert tensions.min() < MIDNIGHT < tensions.max()
    # per trip, under each day's run: the trip that crossed midnight is checked whole on
    # the day it started; the trip the record cuts is checked for what is logged
    con = open_reader(data)
    try:
        checks = con.sql(
            "SELECT r.period_start_utc, c.trip_id, c.status, c.message FROM sanity_checks c "
            "JOIN runs r USING (run_id) ORDER BY 1, 2"
        ).fetchall()
        # each check names its run's trip: the direction it states is that trip's
        named = con.sql(
            "SELECT c.message, t.direction FROM sanity_checks c JOIN trip_summary t "
            "USING (run_id, trip_id) WHERE c.status <> 'skipped' ORDER BY t.time_start_utc"
        ).fetchall()
        steps = con.sql(
            "SELECT s.step, s.status, s.message FROM run_steps s JOIN runs r USING (run_id) "
            "WHERE s.step = 'sanity_check' ORDER BY r.period_start_utc"
        ).fetchall()
    finally:
        con.close()
    # each run numbers trips from its lead-in (30 min before its day): the cut trip is
    # the 3 March run's trip 2 (trip 0 of its record ended before midnight)
    # (the record's first trip only warms the replay up: skipped, with its row)
    assert [(start.date(), trip, status) for start, trip, status, _ in checks] == [
        (dt.date(2026, 3, 2), 0, "skipped"),
        (dt.date(2026, 3, 2), 1, "passed"),
        (dt.date(2026, 3, 3), 2, "passed"),
    ]
    assert [message.split()[0] for message, _ in named] == [d for _, d in named]
    assert len(named) == 2
    assert "cut by the end of the record" in checks[2][3]
    assert steps == [
        ("sanity_check", "done", "1 of 1 trips passed, 1 skipped (reasons in sanity_checks)"),
        ("sanity_check", "done", "1 of 1 trips passed"),
    ]
    # the next night: nothing is new, nothing is recomputed
    runs, files, prints = _runs(data), _lake_files(data), fingerprint(data)
    assert main(argv) == 0
    assert "0 partitions" in capsys.readouterr().out
    assert _runs(data) == runs
    assert _lake_files(data) == files
    assert fingerprint(data) == prints


def test_a_failed_sanity_check_is_a_finding_and_its_day_is_not_recomputed(midnight):
    """A check that fails (here: an impossible limit) is landed as the day's finding;
    the ledger counts the day done. A day whose check is missing gets only the check."""
    hoists, incoming, data = midnight
    sources = load_hoists(hoists, data=data, incoming=incoming)
    assert nightly(sources, data=data, sanity=False).ok
    runs = _runs(data)
    # the checks replay with the ropes the runs identified: none is identified again
    identified = sorted((data.path / "cache" / "rope_springs").glob("*.json"))
    assert len(identified) == 2
    day2, day3 = [r for r in partition_ledger(data).iter_rows(named=True)]
    outcome = check_sanity(
        hoist_path=sources[0].path, data=data, run_id=day3["run_id"],
        start=MIDNIGHT, end=MIDNIGHT + dt.timedelta(days=1), threshold=1.0,
    )  # fmt: skip
    assert outcome.step.status == "failed"
    assert outcome.step.message == "ValueError: threshold must exceed 1 (the noise alone gives 1)"
    landed = steps_of(data, [day3["run_id"]]).filter(pl.col("step") == "sanity_check")
    assert landed.select("status", "message").rows() == [("failed", outcome.step.message)]
    # each of the run's trips has its row, skipped with the reason: an audit of the
    # trips finds one for each (was: none)
    con = open_reader(data)
    try:
        trips = con.sql(
            "SELECT trip_id FROM trip_summary WHERE run_id = ? ORDER BY trip_id",
            params=[day3["run_id"]],
        ).fetchall()
        checks = con.sql(
            "SELECT trip_id, status, passed, rms_gap_pa, message FROM sanity_checks "
            "WHERE run_id = ? ORDER BY trip_id",
            params=[day3["run_id"]],
        ).fetchall()
    finally:
        con.close()
    assert trips
    reason = f"the sanity check could not run: {outcome.step.message}"
    assert checks == [(t, "skipped", None, None, reason) for (t,) in trips]
    assert outcome.checks.height == len(trips)
    night = nightly(sources, data=data)
    assert night.ok, str(night)
    # 2026-03-03 stays done; 2026-03-02 gets its check, not a new run
    assert [(o.key, o.status, o.run_id) for o in night.runs.outcomes] == [
        ("paper-field-test/main-shaft/2026-03-02", "succeeded", day2["run_id"])
    ]
    assert night.runs.outcomes[0].message.startswith("compensation already landed")
    assert night.runs.outcomes[0].checks == 1
    assert _runs(data) == runs
    assert nightly(sources, data=data).runs.outcomes == []
    assert sorted((data.path / "cache" / "rope_springs").glob("*.json")) == identified


def test_unclaimed_incoming_folders_and_hoists_without_data_are_named(tmp_path, capsys):
    hoists, incoming = tmp_path / "hoists", tmp_path / "incoming"
    hoists.mkdir()
    text = EXAMPLE_HOIST.read_text(encoding="utf-8")
    (hoists / "a.toml").write_text(text.replace('name = "main-shaft"', 'name = "shaft-a"'))
    (hoists / "b.toml").write_text(text.replace('name = "main-shaft"', 'name = "shaft-b"'))
    (incoming / "paper-field-test" / "shaft-b").mkdir(parents=True)  # empty
    (incoming / "paper-field-test" / "Shaft-A").mkdir()  # not the name of a.toml
    (incoming / "other-site" / "x").mkdir(parents=True)
    (incoming / "loose_20260302.csv").write_text("# site: s\n")
    argv = ["nightly", "--hoists", str(hoists), "--incoming", str(incoming),
            "--data", str(tmp_path / "data"), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out.splitlines()
    expected = [
        f"hoist paper-field-test/shaft-a (a.toml): no incoming folder "
        f"{incoming / 'paper-field-test' / 'shaft-a'}",
        f"hoist paper-field-test/shaft-b (b.toml): no raw files (CSV, TDMS) in "
        f"{incoming / 'paper-field-test' / 'shaft-b'}",
        f"incoming folder {incoming / 'other-site'}: no hoist description has "
        "[hoist] site = 'other-site'; its logs are not read",
        f"incoming folder {incoming / 'paper-field-test' / 'Shaft-A'}: no hoist description "
        "claims it ([hoist] site = 'paper-field-test', name = 'Shaft-A'); its logs are not read",
        f"incoming folder {incoming}: 1 raw file(s) outside any <site>/<hoist> folder; not read",
    ]
    for line in expected:
        assert out.count(line) == 1, (line, out)


def test_deploy_serve_and_pool_take_the_switches_of_nightly(tmp_path):
    night = argparse.ArgumentParser()
    add_night_options(night)
    switches = {s for a in night._actions for s in a.option_strings} - {"-h", "--help"}
    assert switches == {"--lookback-days", "--no-sanity"}
    cli_nightly = build_cli_parser()._subparsers._group_actions[0].choices["nightly"]
    for command in ("serve", "pool"):
        sub = build_parser()._subparsers._group_actions[0].choices[command]
        options = {s for a in sub._actions for s in a.option_strings}
        assert switches <= options
        assert switches <= {s for a in cli_nightly._actions for s in a.option_strings}
    args = build_parser().parse_args(
        ["serve", "--hoists", "h", "--data", "d", "--no-sanity", "--lookback-days", "7",
         "--dask", "local", "--workers", "3"]
    )  # fmt: skip
    assert (args.no_sanity, args.lookback_days, args.dask, args.workers) == (True, 7, "local", 3)
    params = nightly_parameters(
        hoists="h", data="d", lookback_days=args.lookback_days, sanity=not args.no_sanity
    )
    assert (params["lookback_days"], params["sanity"]) == (7, False)
    # the deployment's parameters are the flow's
    assert set(params) <= set(inspect.signature(nightly_flow.fn).parameters)
    with pytest.raises(SystemExit):
        build_parser().parse_args(
            ["serve", "--hoists", "h", "--data", "d", "--lookback-days", "-1"]
        )


def _one_hoist_mine(tmp_path, small_csv):
    """A mine of one hoist (the example's, main-shaft) with 50 rows in its incoming
    folder: (hoists folder, incoming folder, the hoist's incoming folder)."""
    hoists, incoming = tmp_path / "hoists", tmp_path / "incoming"
    hoists.mkdir()
    (hoists / "main-shaft.toml").write_text(EXAMPLE_HOIST.read_text(encoding="utf-8"))
    folder = incoming / "paper-field-test" / "main-shaft"
    folder.mkdir(parents=True)
    small_csv(folder / "good.csv", rows=50)
    return hoists, incoming, folder


def test_a_file_naming_another_hoist_in_a_hoists_folder_is_refused(tmp_path, capsys, small_csv):
    """A log whose header names another hoist, dropped in main-shaft's incoming folder:
    refused, named, nothing of it landed (was: landed silently in the other hoist's lake,
    counted as main-shaft's rows)."""
    hoists, incoming, folder = _one_hoist_mine(tmp_path, small_csv)
    foreign = small_csv(folder / "foreign.csv", rows=30, start="2026-03-02 07:00:00")
    foreign.write_text(foreign.read_text().replace("# hoist: main-shaft", "# hoist: other-shaft"))
    data = tmp_path / "data"
    argv = ["nightly", "--hoists", str(hoists), "--incoming", str(incoming),
            "--data", str(data), "--no-progress", "--no-sanity"]  # fmt: skip
    status = main(argv)
    out, err = capsys.readouterr()
    assert status == 1
    assert "1 refused" in out
    assert "some files were refused" in err
    con = open_reader(DataRoot.resolve(data))
    try:
        refused = con.sql(
            "SELECT source_path, message FROM manifest WHERE status = 'refused'"
        ).fetchall()
    finally:
        con.close()
    assert len(refused) == 1
    assert refused[0][0] == str(foreign)
    assert "header names hoist paper-field-test/other-shaft" in refused[0][1]
    lake = data / "lake" / "field_samples" / "site=paper-field-test"
    assert not (lake / "hoist=other-shaft").exists()


def test_a_discovery_a_killed_night_planned_is_run_by_the_next(midnight, monkeypatch):
    """The day a night planned to discover (its check failed) and was killed before the
    discovery's outcome landed: the next night, with nothing new, discovers it and lands
    the outcome with that day's run (it was never done again: the day's check had its
    outcome, and a night only looked at its own runs)."""
    from pipelines import night_discovery
    from pipelines.executors import PlainExecutor
    from pipelines.night_pending import PendingWork, load_pending, save_pending

    hoists, incoming, data = midnight
    sources = load_hoists(hoists, data=data, incoming=incoming)
    assert nightly(sources, data=data, sanity=False).ok
    day = partition_ledger(data).row(1, named=True)  # 2026-03-03
    key = f"{day['site']}/{day['hoist']}/{day['day']}"
    save_pending(data, PendingWork(discoveries={key: day["run_id"]}))  # as a killed night left it
    found, _ = night_discovery.discover_days(
        PlainExecutor(1, 0), sources, [], data, pending=load_pending(data)
    )
    assert list(found) == [key]
    assert steps_of(data, [day["run_id"]]).filter(pl.col("step") == "discovery").height == 1
    assert load_pending(data).discoveries == {}


def test_a_night_while_another_holds_the_data_root_does_nothing_and_says_who(site, capsys):
    """A second night started while one runs (held here as a night holds it): it stops
    at once naming the holder, before ingesting anything (two nights both planned the
    same days and computed each twice). Once the first is gone, a night runs."""
    import os as _os

    from pipelines.nightly import NightRunningError
    from warehouse.lock import WarehouseLock

    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    data.path.mkdir(parents=True, exist_ok=True)
    first = WarehouseLock(data.night_lock_file, timeout_s=0.0)
    first.acquire()
    try:
        with pytest.raises(
            NightRunningError, match=f"another nightly runs on .*pid {_os.getpid()}"
        ):
            nightly(sources, data=data, sanity=False)
        assert not data.warehouse.exists()  # nothing ingested
        command = ["nightly", "--hoists", str(hoists), "--incoming", str(incoming),
                   "--data", str(data.path), "--no-sanity", "--no-progress"]  # fmt: skip
        capsys.readouterr()
        assert main(command) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1
        assert err[0].startswith("ropeload nightly: another nightly runs on")
    finally:
        first.release()
    assert nightly(sources, data=data, sanity=False).runs.count("succeeded") == 4


def test_a_pending_file_with_entries_that_are_no_hoist_days_is_read_without_them(tmp_path):
    """Entries of the pending work that are not partition keys (a hand edit, an older
    layout) are left out with a warning; the others stand (a bad date made every night
    fail after its ingest, losing that night's days)."""
    import json

    from pipelines.night_pending import load_pending

    data = DataRoot.resolve(tmp_path / "data")
    (data.path / "state").mkdir(parents=True)
    (data.path / "state" / "nightly-pending.json").write_text(json.dumps({
        "runs": ["s/h/2026-03-02", "s/h/2026-3-2x", 7, "a/b"],
        "discoveries": {"s/h/2026-03-03": "run-1", "s/h": "run-2"},
    }))  # fmt: skip
    work = load_pending(data)
    assert work.runs == {"s/h/2026-03-02"}
    assert work.discoveries == {"s/h/2026-03-03": "run-1"}
    (data.path / "state" / "nightly-pending.json").write_text('{"runs": "abc"}')
    assert load_pending(data).runs == set()


def test_a_file_a_night_refuses_is_named_with_its_reason(tmp_path, capsys, small_csv):
    """A file the night's ingest refuses is named, with the reason, in the night's
    summary and in the one line on stderr (was: "1 refused" and "some files were refused
    (see above)": which file and why were nowhere but the manifest)."""
    hoists, incoming, folder = _one_hoist_mine(tmp_path, small_csv)
    bad = folder / "paper-field-test_main-shaft_20260302.csv"
    bad.write_text("garbage\nnot,a,log\n")
    data = tmp_path / "data"
    argv = ["nightly", "--hoists", str(hoists), "--incoming", str(incoming),
            "--data", str(data), "--no-progress", "--no-sanity"]  # fmt: skip
    assert main(argv) == 1
    out, err = capsys.readouterr()
    assert f"refused {bad}: " in out
    last = err.splitlines()[-1]  # (warnings of the good file's run before it)
    assert last.startswith(f"ropeload nightly: some files were refused: {bad}: "), err
    assert "header lacks" in last


def test_a_hoist_description_broken_before_the_night_holds_up_no_other_hoist(site, capsys):
    """shaft-2's description saved with a typo between two nights: the night runs
    shaft-1, names shaft-2's file and reason, and exits 1 (was: the one line about
    shaft-2 and nothing run for any hoist, night after night until it was mended)."""
    hoists, incoming, data = site
    path = hoists / "shaft-2.toml"
    path.write_text(path.read_text().replace('mass = "8.2 t"', 'mass = "8.2 m"'))
    for later in (incoming / "paper-field-test" / "shaft-1").glob("*_20260303.csv"):
        later.unlink()  # one day of shaft-1 is enough
    argv = ["nightly", "--hoists", str(hoists), "--incoming", str(incoming),
            "--data", str(data.path), "--no-progress", "--no-sanity"]  # fmt: skip
    assert main(argv) == 1
    out, err = capsys.readouterr()
    last = err.splitlines()[-1]
    assert last.startswith(f"ropeload nightly: 1 hoist(s) not run: {path}: "), err
    assert "conveyance.mass" in last
    assert f"hoist description {path}: " in out
    ledger = partition_ledger(data).select("hoist", "day", "status").rows()
    assert ledger == [("shaft-1", dt.date(2026, 3, 2), "succeeded")]
