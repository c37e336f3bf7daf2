"""Temporary files never outlive a crash, and a live writer's are never taken (issue 15).

A real writer process is SIGKILLed in the middle of writing a rope-tensions day (its
``.data.<pid>.tmp``) inside the warehouse lock (its ``warehouse.duckdb.next``); the
next writer finds the lock file still naming the dead holder and cleans up: the dead
writer's files go, a live process's temporary file stays, and so does the published
warehouse.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import duckdb
import polars as pl

from schemas.tables import ROPE_TENSIONS
from warehouse.lock import read_holder
from warehouse.parquet_files import remove_stale_temporaries, temporary_path, writer_alive
from warehouse.store import DataRoot, open_writer

REPO = Path(__file__).resolve().parents[2]

# Lands like `ropeload run` (inside the lock, an atomic Parquet day) but stops for good
# once the temporary file is written: the test kills it there.
WRITER = textwrap.dedent(
    """
    import datetime as dt, sys, time
    from pathlib import Path
    sys.path.insert(0, sys.argv[1])
    import polars as pl
    import pyarrow.parquet as pq
    from schemas.tables import ROPE_TENSIONS
    from schemas.tables import conform
    from warehouse.parquet_files import write_parquet_atomic
    from warehouse.store import DataRoot, open_writer

    real_write = pq.write_table
    def write_then_hang(*args, **kwargs):
        real_write(*args, **kwargs)
        print("written", flush=True)
        time.sleep(300)
    pq.write_table = write_then_hang

    root = DataRoot(Path(sys.argv[2]))
    t0 = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    frame = conform(pl.DataFrame({
        "site": ["s"] * 100, "hoist": ["h"] * 100,
        "time_utc": [t0 + dt.timedelta(seconds=i) for i in range(100)],
    }), ROPE_TENSIONS)
    with open_writer(root) as con:
        con.execute("CREATE TABLE crashed_writer AS SELECT 1 AS x")
        target = root.partition_dir("rope_tensions", site="s", hoist="h", date=t0.date())
        write_parquet_atomic(frame, target / "data.parquet", ROPE_TENSIONS)
    """
)


def _published_tables(root: DataRoot) -> set[str]:
    con = duckdb.connect(str(root.warehouse), read_only=True)
    try:
        return {r[0] for r in con.execute("SELECT table_name FROM duckdb_tables()").fetchall()}
    finally:
        con.close()


def test_writer_killed_mid_write_its_temporaries_are_cleaned_next_start(tmp_path):
    root = DataRoot(tmp_path / "data")
    with open_writer(root):  # a published, migrated warehouse to start from
        pass
    published = root.warehouse.read_bytes()
    writer = subprocess.Popen(
        [sys.executable, "-c", WRITER, str(REPO), str(root.path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = writer.stdout.readline()
        assert line == "written\n", writer.stderr.read()
    finally:
        writer.kill()  # SIGKILL: no finally, no atexit
        writer.wait(timeout=30)
    day = root.partition_dir("rope_tensions", site="s", hoist="h", date="2026-03-02")
    dead_tmp = temporary_path(day / "data.parquet", writer.pid)
    staging = root.path / "warehouse.duckdb.next"
    assert dead_tmp.exists()
    assert staging.exists()
    assert (read_holder(root.lock_file) or {}).get("pid") == writer.pid  # died holding it
    assert root.warehouse.read_bytes() == published  # nothing half-published

    # a live process's temporary file elsewhere in the lake (started before it wrote)
    live = subprocess.Popen(["sleep", "60"])
    try:
        time.sleep(0.05)
        other = root.partition_dir("rope_tensions", site="s", hoist="h2", date="2026-03-02")
        other.mkdir(parents=True)
        live_tmp = temporary_path(other / "data.parquet", live.pid)
        live_tmp.write_bytes(b"being written")
        keep = [other / "data.parquet.notes", other / ".hidden.tmp"]  # not ours: untouched
        for path in keep:
            path.write_text("x")

        with open_writer(root) as con:
            assert not dead_tmp.exists()
            assert live_tmp.exists()
            assert all(path.exists() for path in keep)
            tables = {
                r[0] for r in con.execute("SELECT table_name FROM duckdb_tables()").fetchall()
            }
            assert "crashed_writer" not in tables  # a fresh staging copy, not the dead one's
        assert live_tmp.read_bytes() == b"being written"
    finally:
        live.kill()
        live.wait()
    assert "crashed_writer" not in _published_tables(root)
    assert not staging.exists()
    assert root.lock_file.read_text() == "released\n"
    assert not list(day.glob("*.parquet"))  # the killed writer published nothing


def test_planted_temporaries_dead_live_and_reused_pids(tmp_path):
    lake = tmp_path / "lake"
    folder = lake / "field_samples" / "site=s" / "hoist=h" / "date=2026-03-02"
    folder.mkdir(parents=True)
    dead = temporary_path(folder / "part-00001-abc.parquet", _dead_pid())
    dead.write_bytes(b"x")
    # pid 1 is alive but started long before this file was written ... (kept)
    alive = temporary_path(folder / "part-00002-abc.parquet", 1)
    alive.write_bytes(b"x")
    # ... while a file older than the process now holding its pid is a reused pid's
    live = subprocess.Popen(["sleep", "60"])
    try:
        reused = temporary_path(folder / "part-00003-abc.parquet", live.pid)
        reused.write_bytes(b"x")
        hour_ago = time.time() - 3600
        os.utime(reused, (hour_ago, hour_ago))
        assert writer_alive(live.pid, time.time())
        assert not writer_alive(live.pid, hour_ago)
        removed = remove_stale_temporaries(lake)
    finally:
        live.kill()
        live.wait()
    assert sorted(removed) == sorted([dead, reused])
    assert alive.exists()
    assert not dead.exists()
    assert not reused.exists()


def test_a_killed_ingest_part_is_cleaned_by_the_next_writer(tmp_path):
    """The ingest's ``.part-*.<pid>.tmp`` names follow the same rule, lake-wide."""
    root = DataRoot(tmp_path / "data")
    folder = root.partition_dir("field_samples", site="s", hoist="h", date="2026-03-02")
    folder.mkdir(parents=True)
    stale = temporary_path(folder / "part-00001-0123456789ab.parquet", _dead_pid())
    stale.write_bytes(b"half a part")
    root.lock_file.write_text('{"pid": 999999, "command": "ropeload ingest x.csv"}\n')
    with open_writer(root):
        assert not stale.exists()


def test_temporary_name_is_hidden_and_carries_the_pid(tmp_path):
    target = tmp_path / "data.parquet"
    assert temporary_path(target).name == f".data.{os.getpid()}.tmp"
    frame = pl.DataFrame(schema=dict(pl.from_arrow(ROPE_TENSIONS.empty_table()).schema))
    from warehouse.parquet_files import write_parquet_atomic

    write_parquet_atomic(frame, target, ROPE_TENSIONS)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.parquet"]


def _dead_pid() -> int:
    """The pid of a process that has ended (and, for the test's few ms, not reused)."""
    proc = subprocess.Popen(["true"])
    proc.wait()
    try:
        os.kill(proc.pid, 0)
    except ProcessLookupError:
        return proc.pid
    raise AssertionError("pid reused at once")
