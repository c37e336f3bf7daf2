"""Readers keep querying while a writer lands: no failure, never half a landing.

The reader is a separate process (DuckDB's file lock is per process). Each landing puts
rows into two tables, with pauses between the two inserts and before publishing, so a
reader that could see a half-landed day would see position rows without their trips.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import polars as pl
import pytest

from schemas.tables import POSITION_SUMMARY, TRIP_SUMMARY, conform
from warehouse.landing import RunRecord, insert_frame, land_run
from warehouse.lock import INVOCATION_ENV, LockTimeoutError, lock_timeout_s, read_holder
from warehouse.store import DataRoot, open_writer

REPO = Path(__file__).resolve().parents[2]
DAYS = 4
TRIPS_PER_DAY = 50

READER = textwrap.dedent(
    """
    import json, sys, time
    from pathlib import Path
    sys.path.insert(0, sys.argv[1])
    from warehouse.store import DataRoot, open_reader

    root, stop = DataRoot(Path(sys.argv[2])), Path(sys.argv[3])
    checks, errors, states, inconsistent, told = 0, [], set(), [], False
    while not stop.exists():
        try:
            con = open_reader(root)
            try:
                positions = dict(con.sql(
                    "SELECT run_id, count(*) FROM position_summary GROUP BY 1").fetchall())
                trips = dict(con.sql(
                    "SELECT run_id, count(*) FROM trip_summary GROUP BY 1").fetchall())
                audit = dict(con.sql(
                    "SELECT run_id, position_rows FROM audit_runs").fetchall())
            finally:
                con.close()
        except Exception as exc:  # the test asserts there are none
            errors.append(f"{type(exc).__name__}: {exc}")
            continue
        finally:
            if not told:  # one look at the empty warehouse taken
                print("ready", flush=True)
                told = True
        checks += 1
        states.add(len(positions))
        ok = (set(positions) == set(trips) == set(audit)
              and all(positions[r] == 3 * trips[r] == audit[r] for r in positions))
        if not ok:
            inconsistent.append([positions, trips, audit])
    print(json.dumps({"checks": checks, "errors": errors[:5], "n_errors": len(errors),
                      "states": sorted(states), "inconsistent": inconsistent[:3]}))
    """
)


def _frame(schema, rows):
    return conform(pl.DataFrame(rows), schema)


def _land_day(root: DataRoot, day: int) -> None:
    start = dt.datetime(2026, 3, 1, tzinfo=dt.UTC) + dt.timedelta(days=day)
    run = RunRecord(run_id=f"day-{day}", command="run", code_version="t", started_at_utc=start,
                    site="s", hoist="h", period_start_utc=start,
                    period_end_utc=start + dt.timedelta(days=1))  # fmt: skip
    base = {"run_id": run.run_id, "site": "s", "hoist": "h"}
    with open_writer(root) as con:
        land_run(con, run)
        insert_frame(
            con,
            "position_summary",
            _frame(POSITION_SUMMARY, [
                {**base, "trip_id": t, "position": p, "time_start_utc": start}
                for t in range(TRIPS_PER_DAY) for p in ("bottom", "middle", "pithead")
            ]),
        )  # fmt: skip
        time.sleep(0.3)  # half a day landed, in the writer's copy only
        insert_frame(
            con,
            "trip_summary",
            _frame(TRIP_SUMMARY, [{**base, "trip_id": t, "time_start_utc": start}
                                  for t in range(TRIPS_PER_DAY)]),
        )  # fmt: skip
        time.sleep(0.2)


def test_reader_process_never_fails_nor_sees_half_a_landing(tmp_path):
    root = DataRoot(tmp_path / "data")
    with open_writer(root):  # an empty, migrated warehouse to start from
        pass
    stop = tmp_path / "stop"
    reader = subprocess.Popen(
        [sys.executable, "-c", READER, str(REPO), str(root.path), str(stop)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        # the reader has looked at the empty warehouse (a busy machine can take seconds
        # to start it)
        assert reader.stdout.readline() == "ready\n"
        for day in range(DAYS):
            _land_day(root, day)
            time.sleep(0.2)
        time.sleep(0.5)
    finally:
        stop.touch()
        out, err = reader.communicate(timeout=60)
    assert reader.returncode == 0, err
    result = json.loads(out)
    assert result["n_errors"] == 0, result["errors"]
    assert result["inconsistent"] == []
    assert result["checks"] > 20
    # it saw the empty warehouse, intermediate days and the last one
    assert result["states"][0] == 0
    assert result["states"][-1] == DAYS
    assert len(result["states"]) >= 3


# ----------------------------------------------------------- the lock: time-out, holder

HOLDER = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    sys.path.insert(0, sys.argv[1])
    from warehouse.store import DataRoot, open_writer

    with open_writer(DataRoot(Path(sys.argv[2]))):
        print("held", flush=True)
        sys.stdin.readline()  # until the test says so
    """
)


def _holder(root: DataRoot, *, same_invocation: bool = False) -> subprocess.Popen:
    env = dict(os.environ)
    if same_invocation:
        env[INVOCATION_ENV] = "test-invocation"
    else:
        env.pop(INVOCATION_ENV, None)
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(REPO), str(root.path)],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline() == "held\n"
    return proc


def _release(proc: subprocess.Popen) -> None:
    proc.stdin.close()
    assert proc.wait(timeout=30) == 0


def test_lock_times_out_naming_the_holder(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv(INVOCATION_ENV, raising=False)
    root = DataRoot(tmp_path / "data")
    holder = _holder(root)
    try:
        t0 = time.monotonic()
        with pytest.raises(LockTimeoutError) as caught, open_writer(root, lock_timeout_s=0.3):
            pass
        waited = time.monotonic() - t0
    finally:
        _release(holder)
    assert 0.3 <= waited < 5
    message = str(caught.value)
    assert f"held by pid {holder.pid} (-c {REPO} {root.path}, since 20" in message
    assert "ROPELOAD_LOCK_TIMEOUT" in message
    notice = capsys.readouterr().err.splitlines()
    assert len(notice) == 1  # said once, however many times it looked
    assert f"{root.lock_file} is held by pid {holder.pid} " in notice[0]
    with open_writer(root, lock_timeout_s=0):  # free again, at once
        pass


def test_waiting_writer_gets_the_lock_when_the_holder_lets_go(tmp_path, monkeypatch):
    monkeypatch.setenv("ROPELOAD_LOCK_TIMEOUT", "30")  # the default path reads it
    root = DataRoot(tmp_path / "data")
    holder = _holder(root)
    threading.Timer(0.5, holder.stdin.close).start()
    t0 = time.monotonic()
    with open_writer(root):
        waited = time.monotonic() - t0
        assert read_holder(root.lock_file)["pid"] == os.getpid()
    assert holder.wait(timeout=30) == 0
    assert 0.4 <= waited < 10


def test_lock_timeout_from_the_environment(tmp_path, monkeypatch):
    root = DataRoot(tmp_path / "data")
    holder = _holder(root)
    try:
        monkeypatch.setenv("ROPELOAD_LOCK_TIMEOUT", "0.2")
        t0 = time.monotonic()
        with pytest.raises(LockTimeoutError, match=r"timed out after 0\.2 s"), open_writer(root):
            pass
        assert time.monotonic() - t0 < 5
    finally:
        _release(holder)
    for bad in ("-1", "soon", "inf", "nan"):
        with pytest.raises(ValueError, match="ROPELOAD_LOCK_TIMEOUT"):
            lock_timeout_s(bad)
    assert lock_timeout_s("") == 600.0


def test_a_sibling_of_the_same_command_waits_silently(tmp_path, capsys, monkeypatch):
    """Dask workers and threads of one backfill queue for the lock all the time."""
    monkeypatch.setenv(INVOCATION_ENV, "test-invocation")
    root = DataRoot(tmp_path / "data")
    holder = _holder(root, same_invocation=True)
    try:
        with pytest.raises(LockTimeoutError), open_writer(root, lock_timeout_s=1.2):
            pass
    finally:
        _release(holder)
    assert capsys.readouterr().err == ""
