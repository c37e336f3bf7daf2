"""Backfill: partition plan, ledger, resume after SIGKILL, failures with reasons (no Prefect)."""

from __future__ import annotations

import datetime as dt
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import duckdb
import pytest

from pipelines.backfill import backfill, plan_backfill
from pipelines.deploy import write_example_mine
from pipelines.executors import is_transient
from pipelines.hoists import file_days, load_hoists
from pipelines.ledger import completed_partitions, fingerprint, partition_ledger
from pipelines.partitions import Partition
from warehouse.store import DataRoot, open_reader

REPO = Path(__file__).resolve().parents[2]
FIRST, LAST = dt.date(2026, 3, 1), dt.date(2026, 3, 4)


@pytest.fixture(scope="module")
def mine(tmp_path_factory) -> tuple[Path, Path]:
    """2 hoists x 3 local days of 10 minutes at 100 Hz (one CSV per hoist-day)."""
    root = tmp_path_factory.mktemp("mine")
    return write_example_mine(root, hoists=2, days=3)


@pytest.fixture(scope="module")
def reference(mine, tmp_path_factory) -> dict[str, tuple[int, int]]:
    """Fingerprint of one uninterrupted backfill of the whole range."""
    hoists, incoming = mine
    data = DataRoot.resolve(tmp_path_factory.mktemp("reference"))
    report = backfill(
        load_hoists(hoists, data=data, incoming=incoming), data=data, start=FIRST, end=LAST
    )
    assert report.ok, str(report)
    assert report.count("succeeded") == 6
    return fingerprint(data)


def test_file_days_follow_the_name_stamp_in_local_time():
    assert file_days("x_20260302.csv", "Asia/Shanghai") == [
        dt.date(2026, 3, 1),
        dt.date(2026, 3, 2),
    ]
    assert file_days("x_20260302_0700.csv", "Asia/Shanghai") == [dt.date(2026, 3, 1)]
    assert file_days("x_20260302_0800.csv", "Asia/Shanghai") == [dt.date(2026, 3, 2)]
    assert file_days("x_20260302.csv", "UTC") == [dt.date(2026, 3, 2)]
    assert file_days("site7_export.tdms", "UTC") is None


def test_transient_errors_are_io_and_locks_only():
    assert is_transient(OSError(5, "Input/output error"))
    assert is_transient(TimeoutError("lock"))
    assert is_transient(duckdb.IOException("Could not set lock on file"))
    assert not is_transient(FileNotFoundError("gone"))
    assert not is_transient(PermissionError("denied"))
    assert not is_transient(ValueError("bad data"))
    assert not is_transient(KeyError("column"))


def test_second_backfill_skips_everything_and_force_changes_no_mart_row(mine, reference, tmp_path):
    hoists, incoming = mine
    data = DataRoot.resolve(tmp_path / "data")
    sources = load_hoists(hoists, data=data, incoming=incoming)
    first = backfill(sources, data=data, start=FIRST, end=LAST, max_workers=1)
    assert first.count("succeeded") == 6
    assert first.count("empty") == 2  # 03-01 UTC: no logs (12:00 local = 04:00 UTC)
    assert fingerprint(data) == reference  # thread count does not change the rows

    plan = plan_backfill(sources, data=data, start=FIRST, end=LAST)
    assert (len(plan.todo), len(plan.done), len(plan.empty)) == (0, 6, 2)
    again = backfill(sources, data=data, start=FIRST, end=LAST)
    assert again.count("skipped") == 6
    assert again.count("succeeded") == 0
    assert fingerprint(data) == reference

    forced = backfill(sources, data=data, start=FIRST, end=LAST, force=True)
    assert forced.count("succeeded") == 6
    after = fingerprint(data)
    runs_rows, runs_days = after.pop("runs_per_day")
    expected = dict(reference)
    ref_rows, ref_days = expected.pop("runs_per_day")
    assert after == expected  # marts and lake replaced, not added to
    assert (runs_rows, runs_days) == (2 * ref_rows, ref_days)  # history of runs kept


def test_changed_hoist_description_or_late_file_makes_a_day_not_done(mine, tmp_path):
    hoists, incoming = mine
    local = tmp_path / "hoists"
    shutil.copytree(hoists, local)
    data = DataRoot.resolve(tmp_path / "data")
    sources = load_hoists(local / "shaft-1.toml", data=data, incoming=incoming)
    day = dt.date(2026, 3, 2)
    assert backfill(sources, data=data, start=day, end=day).count("succeeded") == 1
    partition = Partition(sources[0], day)
    assert completed_partitions(data, [partition]) == {partition.key}
    # recalibration: a new hoist description content means the day must be recomputed
    path = local / "shaft-1.toml"
    path.write_text(path.read_text() + "\n# recalibrated\n")
    assert completed_partitions(data, [partition]) == set()
    assert backfill(sources, data=data, start=day, end=day).count("succeeded") == 1
    ledger = partition_ledger(data)
    assert ledger.filter(ledger["day"] == day)["status"].to_list() == ["succeeded"]


def test_failed_partitions_are_reported_with_their_reason_and_recorded(mine, tmp_path):
    hoists, incoming = mine
    local = tmp_path / "hoists"
    shutil.copytree(hoists, local)
    data = DataRoot.resolve(tmp_path / "data")
    sources = load_hoists(local, data=data, incoming=incoming)
    # a typo saved into one hoist description while the backfill is queued: a data
    # error (HoistDescriptionError is a ValueError), so its days fail without retries
    broken = local / "shaft-2.toml"
    broken.write_text(broken.read_text().replace('mass = "8.2 t"', 'mass = "8.2 m"'))
    report = backfill(sources, data=data, start=FIRST, end=LAST, retry_delay_s=0)
    # 03-01 UTC has a raw file to ingest too (local day 03-02 starts 03-01 16:00 UTC)
    assert [o.key for o in report.failed] == [
        f"paper-field-test/shaft-2/2026-03-0{d}" for d in (1, 2, 3, 4)
    ]
    assert report.count("succeeded") == 3  # the other hoist is not held up
    failure = report.failed[0]
    assert failure.attempts == 1
    assert "HoistDescriptionError" in failure.message
    assert "conveyance.mass" in failure.message
    assert "not retried" in failure.message
    assert "failed partitions:" in str(report)
    con = open_reader(data)
    try:
        rows = con.sql(
            "SELECT command, hoist, message FROM runs WHERE status = 'failed' ORDER BY 1"
        ).fetchall()
    finally:
        con.close()
    assert [r[:2] for r in rows] == [("backfill", "shaft-2")] * 4
    # fixed: a restart runs exactly the failed days
    broken.write_text(broken.read_text().replace('mass = "8.2 m"', 'mass = "8.2 t"'))
    healed = backfill(sources, data=data, start=FIRST, end=LAST)
    assert healed.ok
    assert sorted(o.key for o in healed.outcomes if o.status == "succeeded") == [
        o.key for o in report.failed[1:]
    ]
    assert report.failed[0].key in [o.key for o in healed.outcomes if o.status == "empty"]


@pytest.mark.slow
def test_backfill_killed_repeatedly_then_restarted_lands_exactly_the_reference_rows(
    mine, reference, tmp_path
):
    """SIGKILL inside the work (seeded), at least three times, then a full run: same rows."""
    hoists, incoming = mine
    data = tmp_path / "data"
    command = [
        sys.executable,
        "-m",
        "pipelines.cli",
        "backfill",
        "--data",
        str(data),
        "--hoists",
        str(hoists),
        "--incoming",
        str(incoming),
        "--from",
        FIRST.isoformat(),
        "--to",
        LAST.isoformat(),
        "--workers",
        "1",  # one day at a time: a kill point after every day
        "--no-progress",
    ]
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    rng = random.Random(20261122)
    root = DataRoot.resolve(data)
    total = reference["runs_per_day"][0]  # hoist-days with data

    def days_done() -> int:
        return partition_ledger(root).height if root.warehouse.exists() else 0

    kills = []
    while len(kills) < 8 and sum(k[1] == "killed" for k in kills) < 3:
        before = days_done()
        if before >= total:
            break
        process = subprocess.Popen(
            command, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        # wait until this run has landed one more day, then kill it at a random moment of
        # the next one: every kill falls in the middle of real work, whatever the speed
        deadline = time.monotonic() + 90
        while process.poll() is None and days_done() <= before and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(rng.uniform(0.0, 0.4))
        finished = process.poll() is not None
        if not finished:
            process.send_signal(signal.SIGKILL)
        process.communicate(timeout=30)
        kills.append((before, "finished" if finished else "killed", days_done()))
    print("kills (days done before, outcome, days done after):", kills)
    final = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    print(final.stdout)
    assert final.returncode == 0, final.stderr
    assert sum(outcome == "killed" for _, outcome, _ in kills) >= 3
    result = fingerprint(DataRoot.resolve(data))
    print("after restarts:", result)
    print("uninterrupted: ", reference)
    assert result == reference


def test_memory_budget_lowers_the_workers_and_says_so(mine, reference, tmp_path, capsys):
    """--memory-budget-gb 1.9 fits 2 of 4 workers (0.9 GB + 0.47 GB each); same rows."""
    from pipelines.cli import main

    hoists, incoming = mine
    data = tmp_path / "data"
    status = main(
        ["backfill", "--data", str(data), "--hoists", str(hoists), "--incoming", str(incoming),
         "--from", FIRST.isoformat(), "--to", LAST.isoformat(), "--workers", "4",
         "--memory-budget-gb", "1.9", "--no-progress"]
    )  # fmt: skip
    assert status == 0
    err = capsys.readouterr().err
    assert "ropeload backfill: --workers 4 -> 2, to stay within --memory-budget-gb 1.9" in err
    assert fingerprint(DataRoot.resolve(data)) == reference


def test_backfill_with_band_members_on_means_records_it(mine, tmp_path, capsys):
    """``--band-member-step``: each day's run says in ``runs.message`` how its band's
    members ran (transforms.band_members); a day already done is not redone for it."""
    from pipelines.cli import main

    hoists, incoming = mine
    data = tmp_path / "data"
    command = ["backfill", "--data", str(data), "--hoists", str(hoists), "--incoming",
               str(incoming), "--from", "2026-03-02", "--to", "2026-03-02",
               "--no-progress"]  # fmt: skip
    assert main([*command, "--band-member-step", "0.5"]) == 0
    capsys.readouterr()
    con = open_reader(DataRoot.resolve(data))
    try:
        messages = [m for (m,) in con.sql("SELECT message FROM runs WHERE command = 'backfill'")
                    .fetchall()]  # fmt: skip
    finally:
        con.close()
    assert len(messages) == 2  # the two hoists' day
    assert all(m.endswith("; band members on 0.5 s means") for m in messages)
    assert main(command) == 0  # done: same inputs and hoist description, not redone
    assert "0 run, 2 already done" in capsys.readouterr().out


def test_a_refused_file_fails_the_backfill_and_is_named(mine, tmp_path, capsys):
    """A log the backfill ingests and refuses (here not a log at all): the backfill
    names it and exits 1 (was: status 0, "0 failed", the file nowhere on stdout or
    stderr; its day counted as "without data")."""
    from pipelines.cli import main

    hoists, incoming = mine
    local = tmp_path / "incoming"
    shutil.copytree(incoming, local)
    bad = local / "paper-field-test" / "shaft-1" / "paper-field-test_shaft-1_20260306.csv"
    bad.write_text("garbage\nnot,a,log\n")
    data = tmp_path / "data"
    argv = ["backfill", "--hoists", str(hoists), "--incoming", str(local), "--data", str(data),
            "--from", "2026-03-05", "--to", "2026-03-06", "--no-progress"]  # fmt: skip
    assert main(argv) == 1
    out, err = capsys.readouterr()
    assert str(bad) in out
    assert err.count("\n") == 1, err
    assert err.startswith("ropeload backfill: "), err
    assert str(bad) in err
    con = open_reader(DataRoot.resolve(data))
    try:
        failed = con.execute("SELECT count(*) FROM runs WHERE status = 'failed'").fetchone()
    finally:
        con.close()
    assert failed == (0,)  # a refused file is no failed day: its days had no other data


def test_a_check_of_a_run_replaced_while_it_ran_lands_no_verdict(mine, tmp_path):
    """A backfill with --sanity and a night on the same day, interleaved: the backfill's
    run lands, the night's run of the day replaces its trips, then the backfill's check
    lands. Its verdicts name trips no run holds: they go (they stayed, counted in the
    audit beside the night's own)."""
    from pipelines.hoist_day import check_sanity, land_sanity_checks
    from pipelines.ingest import ingest_paths
    from pipelines.run_period import run_period

    hoists, incoming = mine
    data = DataRoot.resolve(tmp_path / "data")
    hoist = hoists / "shaft-1.toml"
    assert ingest_paths(
        sorted((incoming / "paper-field-test" / "shaft-1").glob("*.csv")), data=data
    ).ok
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    period = {
        "hoist_path": hoist,
        "data": data,
        "start": start,
        "end": start + dt.timedelta(days=1),
    }
    first = run_period(**period, command="backfill")
    checked = check_sanity(**period, run_id=first.run_id)  # the backfill's verdicts ...
    assert checked.compared >= 1
    run_period(**period, command="nightly")  # ... its trips the night's now ...
    land_sanity_checks(  # ... and the verdicts landed after that
        data, checked.checks, site="paper-field-test", hoist="shaft-1",
        run_id=first.run_id, step=checked.step,
    )  # fmt: skip
    # a check of the replaced run, run afresh, has no trip of it to count
    again = check_sanity(**period, run_id=first.run_id)
    assert again.compared == 0
    assert again.words() == "sanity check: no trip of the period to compare"
    con = open_reader(data)
    try:
        orphans = con.sql(
            "SELECT c.run_id, c.trip_id FROM sanity_checks c ANTI JOIN trip_summary t "
            "USING (run_id, trip_id)"
        ).fetchall()
    finally:
        con.close()
    assert orphans == []
