"""Everything the user can cause is one line ``ropeload <command>: <reason>`` (issue 15).

Missing data for a period, a data root that is a file / cannot be created / is not
writable, a warehouse lock held by another process past the time-out, memory
exhaustion under ``ulimit -v`` (in-process errors, and the Rust allocator's abort that
only a supervising parent can see), and processes left running by a command that died.
Real commands, real processes, real signals.
"""

from __future__ import annotations

import gzip
import itertools
import os
import resource
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from pipelines.cli import main
from warehouse.lock import INVOCATION_ENV

REPO = Path(__file__).resolve().parents[2]
HOIST = REPO / "schemas" / "hoists" / "paper_field_test.toml"


def _one_line(err: str, command: str) -> str:
    assert err.count("\n") == 1, err
    assert err.endswith("\n"), err
    assert err.startswith(f"ropeload {command}: "), err
    assert "Traceback" not in err
    return err


# ------------------------------------------------------------------ missing data


def test_run_without_landed_data_names_hoist_and_says_ingest(tmp_path, capsys):
    data = tmp_path / "data"
    assert main(["run", "--data", str(data), "--hoist", str(HOIST)]) == 1
    err = _one_line(capsys.readouterr().err, "run")
    assert "hoist paper-field-test/main-shaft" in err
    assert "ropeload ingest" in err
    assert str(data) in err


def test_run_for_a_period_without_data_names_the_period_and_the_landed_days(
    tmp_path, capsys, small_csv
):
    data = tmp_path / "data"
    assert main(["ingest", "--data", str(data), str(small_csv(tmp_path / "day.csv"))]) == 0
    capsys.readouterr()
    status = main(
        ["run", "--data", str(data), "--hoist", str(HOIST), "--from", "2020-01-01",
         "--to", "2020-01-02"]
    )  # fmt: skip
    assert status == 1
    err = _one_line(capsys.readouterr().err, "run")
    assert "hoist paper-field-test/main-shaft" in err
    assert "2020-01-01 00:00:00 .. 2020-01-02 00:00:00 UTC" in err
    assert "landed days: 2026-03-02" in err
    assert "--from/--to" in err


# ------------------------------------------------------------------ the data root


@pytest.mark.parametrize(
    "args",
    [
        ["ingest", "IN.csv"],
        ["run", "--hoist", str(HOIST)],
        ["backfill", "--hoists", str(HOIST), "--from", "2026-03-02", "--to", "2026-03-02"],
        ["demo", "--hours", "0.01"],
        ["query", "select 1"],
    ],
    ids=lambda a: a[0],
)
def test_data_root_that_is_a_file(args, tmp_path, capsys, small_csv):
    afile = tmp_path / "afile"
    afile.write_text("not a folder\n")
    args = [str(small_csv(tmp_path / "in.csv")) if a == "IN.csv" else a for a in args]
    assert main([*args, "--data", str(afile)]) == 1
    err = _one_line(capsys.readouterr().err, args[0])
    assert f"data root {afile} (--data) is a file, not a folder" in err
    assert afile.read_text() == "not a folder\n"


@pytest.mark.parametrize("command", ["ingest", "query"])
def test_empty_data_root_is_a_usage_error(command, tmp_path, capsys, monkeypatch, small_csv):
    """``--data "$UNSET"`` is a usage error, not the working directory as the data root."""
    monkeypatch.chdir(tmp_path)
    args = [str(small_csv(tmp_path / "in.csv"))] if command == "ingest" else ["select 1"]
    with pytest.raises(SystemExit) as exc:
        main([command, "--data", "", *args])
    assert exc.value.code == 2
    assert "argument --data: empty" in capsys.readouterr().err
    assert {p.name for p in tmp_path.iterdir()} <= {"in.csv"}  # nothing landed here


@pytest.mark.parametrize("command", ["ingest", "demo"])
def test_data_root_under_a_file_cannot_be_created(
    command, tmp_path, capsys, monkeypatch, small_csv
):
    afile = tmp_path / "afile"
    afile.write_text("")
    monkeypatch.setenv("ROPELOAD_DATA", str(afile / "data"))
    args = [command, str(small_csv(tmp_path / "in.csv"))] if command == "ingest" else [command]
    assert main(args) == 1
    err = _one_line(capsys.readouterr().err, command)
    assert f"data root {afile / 'data'} ($ROPELOAD_DATA) cannot be created: {afile} is a" in err


@pytest.mark.parametrize(
    ("name", "character"),
    [("data[X]", "["), ("data*", "*"), ("data?", "?"), ("d\\x", "\\")],
    ids=["bracket", "star", "question-mark", "backslash"],
)
@pytest.mark.parametrize("command", ["ingest", "query"])
def test_a_data_root_whose_path_duckdb_reads_otherwise_is_refused(
    name, character, command, tmp_path, capsys, small_csv
):
    """DuckDB reads the lake through a file pattern built on the data root's path, and
    takes a backslash for a folder separator: ``data[X]`` read the lake of ``dataX``
    (another data root) and never its own, ``d\\x`` wrote ``d/x/warehouse.duckdb.next``.
    Such a data root is refused, one line naming it and the character, before anything
    is written."""
    other = tmp_path / "dataX"  # what data[X], data* and data? match
    assert main(["ingest", "--data", str(other), str(small_csv(tmp_path / "o.csv"))]) == 0
    capsys.readouterr()
    data = tmp_path / name
    args = [str(small_csv(tmp_path / "in.csv"))] if command == "ingest" else ["select 1"]
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    assert main([command, "--data", str(data), *args]) == 1
    err = _one_line(capsys.readouterr().err, command)
    assert f"data root {data} (--data)" in err
    assert f"{character!r}" in err
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before  # nothing written
    from warehouse.store import DataRoot, open_reader, open_writer

    with pytest.raises(ValueError, match="data root"):
        with open_writer(DataRoot.resolve(data)):
            pass
    with pytest.raises(ValueError, match="data root"):
        open_reader(DataRoot.resolve(data), sandbox=True)
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before


@pytest.mark.parametrize("command", ["ingest", "query"])
def test_a_data_root_whose_path_is_not_utf8_is_one_line(command, tmp_path, capsys, small_csv):
    """``--data $'data\\xff'``: DuckDB cannot open a path that is not UTF-8 text; it
    ended in a traceback (``RuntimeError: std::bad_cast``) after the lock file was made."""
    data = tmp_path / os.fsdecode(b"data\xff")
    args = [str(small_csv(tmp_path / "in.csv"))] if command == "ingest" else ["select 1"]
    before = sorted(tmp_path.rglob("*"))
    assert main([command, "--data", str(data), *args]) == 1
    err = _one_line(capsys.readouterr().err, command)
    assert f"data root {tmp_path}/data\\xff (--data): its path is not UTF-8 text" in err
    assert sorted(tmp_path.rglob("*")) == before


@pytest.mark.skipif(
    os.geteuid() == 0, reason="as root, permission bits do not stop writes (nothing to refuse)"
)
@pytest.mark.parametrize("command", ["ingest", "run", "demo"])
def test_read_only_data_root(command, tmp_path, capsys, small_csv):
    data = tmp_path / "data"
    data.mkdir()
    data.chmod(0o555)
    try:
        args = {
            "ingest": ["ingest", str(small_csv(tmp_path / "in.csv"))],
            "run": ["run", "--hoist", str(HOIST)],
            "demo": ["demo"],
        }[command]
        assert main([*args, "--data", str(data)]) == 1
        err = _one_line(capsys.readouterr().err, command)
        assert f"data root {data} (--data) is not writable (permission denied)" in err
        assert list(data.iterdir()) == []
    finally:
        data.chmod(0o755)


def test_unwritable_file_inside_the_data_root_is_one_line(tmp_path, capsys, small_csv):
    """A user-caused OSError deep inside a command names the file (root or not)."""
    data = tmp_path / "data"
    (data / "lake").mkdir(parents=True)
    (data / "lake" / "field_samples").write_text("a file where the table folder belongs")
    status = main(["ingest", "--data", str(data), str(small_csv(tmp_path / "in.csv"))])
    assert status == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert str(data / "lake" / "field_samples") in err


def test_bad_lock_timeout_is_a_usage_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("ROPELOAD_LOCK_TIMEOUT", "soon")
    assert main(["query", "--data", str(tmp_path), "select 1"]) == 2
    err = _one_line(capsys.readouterr().err, "query")
    assert "ROPELOAD_LOCK_TIMEOUT='soon'" in err


# ------------------------------------------------------------------ the lock

HOLDER = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path
    sys.path.insert(0, sys.argv[1])
    from warehouse.store import DataRoot, open_writer

    with open_writer(DataRoot(Path(sys.argv[2]))):
        print("held", flush=True)
        sys.stdin.readline()  # until the test closes our stdin
    """
)


def test_lock_timeout_names_the_holder(tmp_path, capsys, monkeypatch, small_csv):
    data = tmp_path / "data"
    env = {k: v for k, v in os.environ.items() if k != INVOCATION_ENV}  # another command
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(REPO), str(data)],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline() == "held\n"
        monkeypatch.setenv("ROPELOAD_LOCK_TIMEOUT", "0.5")
        t0 = time.monotonic()
        status = main(["ingest", "--data", str(data), str(small_csv(tmp_path / "in.csv"))])
        waited = time.monotonic() - t0
    finally:
        holder.stdin.close()
        holder.wait(timeout=30)
    assert status == 1
    assert waited >= 0.5
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 2, err  # said once who holds it, then the time-out
    notice, failure = lines
    assert notice.startswith("ropeload: warehouse lock ")
    assert f"held by pid {holder.pid} (-c {REPO} {data}, since " in notice
    assert "waiting up to 0.5 s" in notice
    assert failure.startswith("ropeload ingest: timed out after 0.5 s waiting for the warehouse")
    assert f"held by pid {holder.pid} (-c {REPO} {data}, since " in failure
    assert "ROPELOAD_LOCK_TIMEOUT" in failure
    # the holder finished normally: the lock is free and says so
    assert (data / ".warehouse.lock").read_text() == "released\n"
    assert main(["ingest", "--data", str(data), str(tmp_path / "in.csv")]) == 0


# ------------------------------------------------------------------ memory

LIMITED = textwrap.dedent(
    """
    import resource, sys
    limit = int(sys.argv.pop(1))
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.RLIM_INFINITY))
    sys.path.insert(0, {repo!r})
    from pipelines.cli import main
    sys.argv[0] = "ropeload"
    sys.exit(main())
    """
)


def _limited_ropeload(limit: int, *args: str) -> subprocess.CompletedProcess:
    script = LIMITED.format(repo=str(REPO))
    return subprocess.run(
        [sys.executable, "-c", script, str(limit), *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )


@pytest.mark.parametrize(
    ("kib", "args", "advice"),
    [
        (500_000, ["run", "--hoist", str(HOIST)], "--from/--to"),
        (1_800_000, ["demo", "--hours", "0.1"], "fewer --hours"),
    ],
    ids=["import-fails", "allocator-aborts"],
)
def test_out_of_memory_under_an_address_space_limit_is_one_line(kib, args, advice, tmp_path):
    """``ulimit -v``, measured: at 0.5 GB a library cannot be mapped (ImportError in
    the child); at 1.8 GB the demo dies in polars' Rust allocator ("memory allocation of
    N bytes failed", a backtrace, SIGABRT), at other sizes by SIGSEGV or a SystemError.
    Whichever way, one line, exit 1, and nothing of the allocator's last words."""
    if resource.getrlimit(resource.RLIMIT_AS)[1] != resource.RLIM_INFINITY:
        pytest.skip("a hard address-space limit is already set")
    done = _limited_ropeload(kib * 1024, *args, "--data", str(tmp_path / "data"))
    assert done.returncode == 1, done.stderr
    err = _one_line(done.stderr, args[0])
    assert f"out of memory (address-space limit {kib * 1024 / 2**30:.1f} GiB, ulimit -v): " in err
    assert advice in err
    assert "memory allocation of" not in err


def test_duckdbs_own_out_of_memory_error_is_memory_exhaustion():
    """DuckDB reports exhaustion as an OperationalError of its own (seen by the demo under
    ``ulimit -v`` 1.8 GiB, where polars' allocator usually aborts first): the same one
    line as any out-of-memory, not DuckDB's text; its other errors are not."""
    import duckdb

    from pipelines import exits

    con = duckdb.connect()
    con.execute("SET memory_limit = '2MB'")
    con.execute("SET threads = 1")
    with pytest.raises(duckdb.Error) as exhausted:
        con.execute("SELECT string_agg(range::VARCHAR, ',') FROM range(3000000)").fetchall()
    with pytest.raises(duckdb.Error) as other:
        con.execute("SELECT * FROM no_such_table")
    assert exits.memory_exhausted(exhausted.value, None)
    assert not exits.memory_exhausted(other.value, None)


ABORTING = textwrap.dedent(
    """
    import os, resource, sys
    sys.path.insert(0, sys.argv[1])
    resource.setrlimit(resource.RLIMIT_AS, (64 * 2**30, resource.RLIM_INFINITY))
    from pipelines import exits, supervise
    status = supervise.run_supervised("backfill", exits.memory_limit())
    if status is None:  # the child: say something, then die like Rust's allocator
        sys.stderr.write("progress 1/2\\n")
        sys.stderr.flush()
        os.write(2, b"memory allocation of 12082160 bytes failed\\nstack backtrace:\\n  0: x\\n")
        os.abort()
    sys.exit(status)
    """
)


SAYS_THEN_CRASHES = textwrap.dedent(
    """
    import os, resource, signal, sys
    sys.path.insert(0, sys.argv[1])
    resource.setrlimit(resource.RLIMIT_AS, (64 * 2**30, resource.RLIM_INFINITY))
    from pipelines import exits, supervise
    status = supervise.run_supervised("run", exits.memory_limit())
    if status is None:  # the child: its own line, then a crash at exit (measured under
        # ulimit -v 500000: an ImportError said, then SIGSEGV in the teardown)
        sys.stderr.write(sys.argv[2] + "\\n")
        sys.stderr.flush()
        os.kill(os.getpid(), signal.SIGSEGV)
    sys.exit(status)
    """
)


@pytest.mark.parametrize(
    ("said", "added"),
    [
        ("ropeload run: out of memory (address-space limit 0.5 GiB)", False),
        ("ropeload run: --workers 4 -> 2, to stay within --memory-budget-gb 8", True),
    ],
    ids=["out-of-memory", "a-note"],
)
def test_a_child_that_said_it_is_out_of_memory_and_crashed_is_that_one_line(said, added):
    """The child's own ``ropeload run: out of memory ...`` line is the one line: its
    crash after it (SIGSEGV under an address-space limit) adds no second, and the exit
    status is 1. After any other line of the child's, the supervisor says why."""
    hard = resource.getrlimit(resource.RLIMIT_AS)[1]
    if hard != resource.RLIM_INFINITY and hard < 64 * 2**30:
        pytest.skip("a hard address-space limit below 64 GiB is set")
    done = subprocess.run(
        [sys.executable, "-c", SAYS_THEN_CRASHES, str(REPO), said],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1
    lines = done.stderr.splitlines()
    assert lines[0] == said
    assert len(lines) == 1 + added
    if added:
        assert lines[1].startswith("ropeload run: crashed (SIGSEGV), probably out of memory")


def test_allocator_abort_in_the_child_becomes_one_line():
    """Deterministic form of the 1.5 GiB case: what came before the allocator's last
    words passes through, they and the backtrace do not, SIGABRT becomes exit 1."""
    hard = resource.getrlimit(resource.RLIMIT_AS)[1]
    if hard != resource.RLIM_INFINITY and hard < 64 * 2**30:
        pytest.skip("a hard address-space limit below 64 GiB is set")
    done = subprocess.run(
        [sys.executable, "-c", ABORTING, str(REPO)], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 1
    first, second = done.stderr.splitlines()
    assert first == "progress 1/2"
    assert second.startswith("ropeload backfill: out of memory (address-space limit 64.0 GiB, ")
    assert "try fewer --workers" in second


#: What polars wrote under ``ulimit -v 1800000`` (a CI run, 2026-11-27) before the
#: allocator's own last words: a thread it could not spawn.
STARVED_PANIC = (
    b"\nthread '<unnamed>' (24483) panicked at crates/polars-async/src/executor/mod.rs:435:26:"
    b"\ncalled `Result::unwrap()` on an `Err` value: Os { code: 11, kind: WouldBlock, "
    b'message: "Resource temporarily unavailable" }\nstack backtrace:\n'
)
OTHER_PANIC = (
    b"thread 'main' panicked at src/lib.rs:7:5:\ncalled `Option::unwrap()` on a `None` "
    b"value\nnote: run with `RUST_BACKTRACE=1`\n"
)


def _relayed(stream: bytes, *cuts: int) -> tuple[bytes, bool]:
    """What the relay copies of ``stream`` arriving in pieces split at ``cuts``, to its
    end (``_Relay._close``), and whether it heard dying words."""
    from pipelines.supervise import _Relay

    relay, copied = _Relay(None), []
    relay._write = copied.append  # instead of our stderr
    edges = [0, *cuts, len(stream)]
    for a, b in itertools.pairwise(edges):
        copied.append(relay._filter(stream[a:b]))
    relay._close()
    return b"".join(copied), relay.dying


def _splits(stream: bytes):
    """Every split of ``stream`` in three pieces, at every 5th byte."""
    for i in range(0, len(stream) + 1, 5):
        for j in range(i, len(stream) + 1, 5):
            yield i, j


@pytest.mark.parametrize(
    ("before", "after"),
    [(b"progress 1/2\n", b"progress 1/2\n"), (b"pct 5%", b"pct 5%\n"), (b"", b"")],
    ids=["after-a-line", "after-a-progress-bar", "first"],
)
def test_a_thread_that_cannot_be_spawned_is_the_processes_last_words(before, after):
    """A Rust panic starting a line whose next line says the process is starved
    (WouldBlock: no memory for the thread's stack) is dying words from its blank line on,
    wherever the pieces of stderr split it; what came before passes through, and the
    newline that ends a progress bar's line is that line's."""
    stream = before + STARVED_PANIC + b"memory allocation of 8"
    for i, j in _splits(stream):
        assert _relayed(stream, i, j) == (after, True), (i, j)


@pytest.mark.parametrize(
    "stream",
    [
        b"progress 1/2\n" + OTHER_PANIC,
        b"pct 5%\n\n" + OTHER_PANIC + b"done\n",
        b"pct 5%thread 'x' (1) panicked at y:\nkind: WouldBlock\n",  # within a line
        b"a\n\nb\n\n",
    ],
    ids=["panic", "panic-after-a-blank-line", "within-a-line", "blank-lines"],
)
def test_any_other_panic_and_blank_lines_pass_through_whole(stream):
    """A panic that is not starvation is the program's own error, and blank lines are
    its own text: copied whole, however the pieces split them."""
    for i, j in _splits(stream):
        assert _relayed(stream, i, j) == (stream, False), (i, j)


def test_glibcs_last_words_on_a_thread_it_cannot_end_are_dying_words():
    """Measured under ``ulimit -v`` (the demo at 1.8 GB): glibc cannot register a
    thread's TLS destructor and aborts; what came before passes through."""
    stream = b"progress 1/2\nFatal glibc error: failed to register TLS destructor: out of memory\n"
    for i, j in _splits(stream):
        assert _relayed(stream, i, j) == (b"progress 1/2\n", True), (i, j)


def test_a_starving_allocators_complaints_go_but_the_blank_lines_before_stay():
    assert _relayed(b"a\n\n<jemalloc>: x", 3) == (b"a\n\n", False)


# ------------------------------------------------------------------ children

SUPERVISED = textwrap.dedent(
    """
    import subprocess, sys, time
    sys.path.insert(0, sys.argv[1])
    from pipelines import exits, supervise
    status = supervise.run_supervised("backfill", None)
    if status is None:
        # the child: a 'server' in its own session (like a daemon that ignores its
        # parent's fate), stopped by our cleanup when we end cleanly
        server = subprocess.Popen(["sleep", "300"], start_new_session=True)
        try:
            with exits.terminate_on_signals():
                # told only once the cleanup is armed: a signal before it (the test
                # signals as soon as it reads this) would end us without one
                print(server.pid, flush=True)
                time.sleep(300)
        except KeyboardInterrupt:
            server.terminate()
            server.wait()
            sys.exit(143)
    print("supervisor", status, flush=True)
    sys.exit(status)
    """
)


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _wait_gone(pid: int, seconds: float = 30.0) -> bool:
    # 30 s: a child's cleanup on a loaded 2-core machine once took over 10 s
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not _alive(pid):
            return True
        time.sleep(0.05)
    return False


def _start_supervised() -> tuple[subprocess.Popen, int, int]:
    proc = subprocess.Popen(
        [sys.executable, "-c", SUPERVISED, str(REPO)], stdout=subprocess.PIPE, text=True
    )
    server = int(proc.stdout.readline())
    child = int(Path(f"/proc/{server}/stat").read_text().rsplit(")", 1)[1].split()[1])
    assert child != proc.pid  # the server's parent is the supervisor's child
    return proc, child, server


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl is Linux-only")
def test_child_killed_hard_its_server_is_ended_by_the_supervisor():
    proc, child, server = _start_supervised()
    try:
        os.kill(child, signal.SIGKILL)  # no cleanup can run in the child
        out = proc.stdout.read()
        assert proc.wait(timeout=30) == 128 + signal.SIGKILL
        assert out == f"supervisor {128 + signal.SIGKILL}\n"
        assert _wait_gone(server)  # re-parented to the supervisor (subreaper), ended
    finally:
        for pid in (server, child, proc.pid):
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl is Linux-only")
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGKILL], ids=["TERM", "KILL"])
def test_supervisor_signalled_the_child_cleans_up(signum):
    """SIGTERM is passed on; SIGKILL of the supervisor reaches the child as SIGTERM
    (parent-death signal): either way the child's cleanup ends its server."""
    proc, child, server = _start_supervised()
    try:
        proc.send_signal(signum)
        status = proc.wait(timeout=30)
        assert status == (143 if signum == signal.SIGTERM else -signal.SIGKILL)
        assert _wait_gone(child)
        assert _wait_gone(server)
    finally:
        for pid in (server, child, proc.pid):
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_a_report_that_cannot_be_written_is_the_runs_finding_not_its_failure(
    tmp_path, capsys, small_csv
):
    """``<data>/reports`` a file: the run lands, says the report was not written, exits
    0, and its ``report`` step is landed failed with the reason (as backfill does)."""
    import duckdb

    data = tmp_path / "data"
    assert main(["ingest", "--data", str(data), str(small_csv(tmp_path / "in.csv", rows=200))]) == 0
    (data / "reports").write_text("a file where the reports folder belongs")
    status = main(["run", "--data", str(data), "--hoist", str(HOIST), "--no-sanity"])
    out, err = capsys.readouterr()
    assert status == 0, err
    assert "report: not written" in out
    con = duckdb.connect(str(data / "warehouse.duckdb"), read_only=True)
    try:
        steps = con.sql(
            "SELECT step, status, message FROM run_steps WHERE step = 'report'"
        ).fetchall()
        runs = con.sql("SELECT status FROM runs").fetchall()
    finally:
        con.close()
    assert runs == [("succeeded",)]
    assert len(steps) == 1
    assert steps[0][1] == "failed"
    assert "not written" in steps[0][2]


@pytest.mark.parametrize("value", ["nan", "-500", "inf", "heavy"])
def test_a_payload_that_is_no_payload_is_a_usage_error(value, tmp_path, capsys):
    """``--payload-kg`` NaN, negative or not a number: refused before anything runs
    (was: NaN errors in every position visit, or alarms from a negative payload)."""
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--data", str(tmp_path / "d"), "--hoist", str(HOIST), "--payload-kg", value])
    assert exit_info.value.code == 2
    assert "argument --payload-kg" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("value", ["nan", "0", "-1", "inf", "1e400"])
def test_a_memory_budget_that_is_no_budget_is_a_usage_error(value, tmp_path, capsys):
    """``--memory-budget-gb`` not a positive finite number: refused with the usage
    status before anything runs (infinity was a traceback: int(inf))."""
    with pytest.raises(SystemExit) as exit_info:
        main(["backfill", "--hoists", str(tmp_path / "h"), "--data", str(tmp_path / "d"),
              "--from", "2026-03-02", "--to", "2026-03-02",
              "--memory-budget-gb", value])  # fmt: skip
    assert exit_info.value.code == 2
    assert "argument --memory-budget-gb: must be a positive, finite number of GB" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("command", ["run", "discover"])
def test_a_reversed_period_says_so(command, tmp_path, capsys, small_csv):
    """--to before --from: one line saying the period is empty (was: 'no samples landed
    in 23:00 .. 22:00', as if the data were missing), and the status of a bad option's
    value, 2 (was 1, a run's failure)."""
    data = tmp_path / "data"
    assert main(["ingest", "--data", str(data), str(small_csv(tmp_path / "in.csv"))]) == 0
    capsys.readouterr()
    argv = [command, "--data", str(data), "--hoist", str(HOIST),
            "--from", "2026-03-02T07:00", "--to", "2026-03-02T06:00"]  # fmt: skip
    if command == "discover":
        argv += ["--json", str(tmp_path / "r.json")]
    assert main(argv) == 2
    err = _one_line(capsys.readouterr().err, command)
    assert "the period is empty" in err


def test_discover_without_a_logged_speed_says_so(tmp_path, capsys, small_csv):
    """A log without the conveyance's speed: discover refuses in one line (a probe's
    record hiding nothing, replayed on the depth's derivative, named an effect)."""
    data = tmp_path / "data"
    csv = small_csv(tmp_path / "in.csv")
    lines = csv.read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("timestamp"))
    cut = [",".join(f for k, f in enumerate(line.split(",")) if k != 10) for line in lines[header:]]
    assert lines[header].split(",")[10] == "speed"
    csv.write_text("\n".join(lines[:header] + cut) + "\n")
    assert main(["ingest", "--data", str(data), str(csv)]) == 0
    capsys.readouterr()
    argv = [
        "discover",
        "--data",
        str(data),
        "--hoist",
        str(HOIST),
        "--json",
        str(tmp_path / "r.json"),
    ]
    assert main(argv) == 1
    assert "no speed logged" in _one_line(capsys.readouterr().err, "discover")


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["backfill", "--workers", "0"], "argument --workers: must be at least 1, got 0"),
        (["run", "--from", "yesterday"], "argument --from: not an ISO 8601 time: 'yesterday'"),
    ],
)
def test_bad_option_values_are_usage_errors_in_words(argv, said, tmp_path, capsys):
    """Exit 2 with the option and what is wrong, not a function's name."""
    base = {"backfill": ["--hoists", str(tmp_path), "--from", "2026-03-01", "--to", "2026-03-02"],
            "run": ["--hoist", str(HOIST)]}[argv[0]]  # fmt: skip
    with pytest.raises(SystemExit) as exit_info:
        main([argv[0], "--data", str(tmp_path / "d"), *base, *argv[1:]])
    assert exit_info.value.code == 2
    assert said in capsys.readouterr().err


def test_a_damaged_file_in_the_lake_is_one_line(tmp_path, capsys, small_csv):
    """Junk named ``*.parquet`` in a lake partition: ``run`` says polars' words on one
    line and exits 1 (was a 29-line traceback)."""
    data = tmp_path / "data"
    assert main(["ingest", "--data", str(data), str(small_csv(tmp_path / "in.csv"))]) == 0
    (partition,) = {p.parent for p in (data / "lake" / "field_samples").rglob("*.parquet")}
    (partition / "junk.parquet").write_text("not parquet")
    capsys.readouterr()
    assert main(["run", "--data", str(data), "--hoist", str(HOIST), "--no-sanity"]) == 1
    _one_line(capsys.readouterr().err, "run")


def test_a_flow_run_failing_on_a_user_error_is_logged_without_its_traceback():
    """``--prefect``: Prefect logs a failed flow run with its traceback; for an error the
    user caused (here a refused value) the record keeps its message and loses the
    traceback, the command's one line says why. An internal error keeps it."""
    import logging
    import sys

    from pipelines.cli import _quiet_user_errors_in_flow_logs

    _quiet_user_errors_in_flow_logs()
    logger = logging.getLogger("prefect.flow_runs")
    records = []
    for error in (ValueError("the period is empty"), KeyError("bug")):
        try:
            raise error
        except (ValueError, KeyError):
            record = logger.makeRecord(
                logger.name, logging.ERROR, __file__, 1, "failed: %s", (error,), sys.exc_info()
            )
        logger.filter(record)
        records.append(record)
    user, internal = records
    assert user.exc_info is None
    assert user.getMessage() == "failed: the period is empty"
    assert internal.exc_info is not None


def test_a_model_that_cannot_replay_the_record_is_a_user_error():
    """Discovery's baseline that does not simulate the record's trips (a validation
    record's logger gap inside a trip once left a trip ending 100 m short of its stop,
    and ``ropeload discover`` died with a traceback) is a finding about the record and
    its description: one of the errors ``main`` ends in one line with exit 1, as the
    other tests here show for its kin. It stays a RuntimeError for discovery's own
    re-planning, which catches those."""
    from discovery.selection import ModelDoesNotSimulate
    from pipelines import cli

    assert issubclass(ModelDoesNotSimulate, RuntimeError)
    assert ModelDoesNotSimulate in cli._known_errors()


def test_the_deployments_empty_data_root_is_a_usage_error(tmp_path, capsys):
    """``python -m pipelines.deploy serve --data ""``, as ``ropeload``'s ``--data``."""
    from pipelines.deploy import build_parser

    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["serve", "--hoists", str(tmp_path), "--data", ""])
    assert exc.value.code == 2
    assert "argument --data: empty" in capsys.readouterr().err
    args = build_parser().parse_args(["serve", "--hoists", str(tmp_path), "--data", "d"])
    assert args.data.name == "d"


def test_a_reversed_backfill_range_is_a_usage_error(tmp_path, capsys):
    """backfill --to before --from: status 2, a bad option's value, as run's and
    discover's reversed period (was 1, a run's failure)."""
    hoists = tmp_path / "hoists"
    hoists.mkdir()
    (hoists / "main-shaft.toml").write_text(HOIST.read_text(encoding="utf-8"))
    argv = ["backfill", "--hoists", str(hoists), "--data", str(tmp_path / "data"),
            "--from", "2026-03-05", "--to", "2026-03-01", "--no-progress"]  # fmt: skip
    assert main(argv) == 2
    err = _one_line(capsys.readouterr().err, "backfill")
    assert "--to 2026-03-01 is before --from 2026-03-05" in err


@pytest.mark.parametrize("delay_s", [0.02, 0.1, 0.3])
def test_a_signal_duckdb_wraps_in_its_own_error_still_ends_the_command_as_interrupted(
    delay_s, tmp_path, capsys, monkeypatch, small_csv
):
    """SIGTERM while DuckDB inserts a Python frame: DuckDB turns the signal's exception
    into ``RuntimeError('Query interrupted')`` or an ``InvalidInputException`` ("reading
    the Python object ... failed") depending on where it lands (a probe of an ingest
    killed while writing its manifest printed that RuntimeError's traceback). Either
    way the command ends as interrupted: one line, status 143."""
    import threading

    import duckdb
    import numpy as np
    import polars as pl

    from pipelines import cli_parser

    frame = pl.DataFrame({"a": np.arange(3_000_000), "b": np.linspace(0.0, 1.0, 3_000_000)})

    timer = threading.Timer(delay_s, os.kill, (os.getpid(), signal.SIGTERM))

    def inserting(args):  # the command's work: real inserts into a real DuckDB file
        con = duckdb.connect(str(tmp_path / "w.duckdb"))
        con.execute("CREATE TABLE t (a BIGINT, b DOUBLE)")
        con.register("frame", frame)
        timer.start()
        for _ in range(10_000):
            con.execute("INSERT INTO t SELECT * FROM frame")
        return 0

    monkeypatch.setattr(cli_parser, "cmd_ingest", inserting)
    try:
        status = main(["ingest", "--data", str(tmp_path / "data"), str(small_csv)])
    finally:
        timer.cancel()  # a handler that ended early must not leave the signal to pytest
        timer.join()
    err = capsys.readouterr().err
    assert (status, err) == (143, "ropeload ingest: interrupted (SIGTERM)\n")


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["run", "--hoist"], "ropeload run: argument --hoist: expected one argument (see --help)"),
        (["frobnicate"], "ropeload: argument COMMAND: invalid choice: 'frobnicate'"),
        (["query", "--bogus", "select 1"], "ropeload query: unrecognized arguments: --bogus"),
    ],
)
def test_a_usage_error_is_one_line(argv, said, capsys):
    try:
        status = main(argv)
    except SystemExit as exit_info:
        status = exit_info.code
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1, err
    assert err.startswith(said), err


def test_inputs_that_are_no_log_say_what_they_are(tmp_path, capsys):
    """A device is not a missing file; a compressed export says to decompress it; a data
    root the system will not make (under /proc) says it is the data root."""
    gz = tmp_path / "day.csv.gz"
    with gzip.open(gz, "wb") as handle:
        handle.write(b"# site: s\n# hoist: h\n# units: p=MPa\ntimestamp,p1,p2,p3,p4\n")
    assert main(["ingest", "--data", str(tmp_path / "data"), "/dev/null", str(gz)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "ropeload ingest: /dev/null: not a regular file",
        f"ropeload ingest: {gz}: compressed (gzip), not a text log: decompress it first and "
        "ingest the CSV",
    ]
    if Path("/proc/self").is_dir():
        assert main(["ingest", "--data", "/proc/ropeload-x", str(gz)]) == 1
        (line,) = capsys.readouterr().err.splitlines()
        assert line.startswith("ropeload ingest: data root /proc/ropeload-x (--data) cannot be")


def test_a_command_that_fails_leaves_no_empty_data_root_behind(tmp_path, capsys):
    """The data root's check tries to make it (so that one the system refuses says so)
    and undoes that: a run refused for its hoist file leaves no folder."""
    data = tmp_path / "new" / "root"
    assert main(["run", "--data", str(data), "--hoist", str(tmp_path / "none.toml")]) == 1
    assert "none.toml" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()


def test_a_description_whose_shaft_the_record_leaves_is_refused_naming_the_key(
    tmp_path, capsys, small_csv
):
    """A description of a shaft shorter than the record's depth: the run would read the
    deeper samples as not logged, end the trips where they leave it and reconcile the
    stops' payloads wrong with nothing said (a probe: 4.9 t for the truth's 2.2 t). It is
    refused, one line naming the description and its key; the right one runs."""
    data = tmp_path / "data"
    log = small_csv(tmp_path / "day.csv", rows=400)  # the depth 0-199.5 m; 179 beyond 110 m
    assert main(["ingest", "--data", str(data), str(log)]) == 0
    text = HOIST.read_text()
    shorter = (
        ('depth = "620 m"', 'depth = "100 m"'),
        ('middle = "320 m"', 'middle = "50 m"'),
        ('bottom = "600 m"', 'bottom = "90 m"'),
    )
    for old, new in shorter:
        assert old in text
        text = text.replace(old, new)
    short = tmp_path / "short.toml"
    short.write_text(text)
    capsys.readouterr()
    assert main(["run", "--data", str(data), "--hoist", str(short), "--no-sanity"]) == 1
    err = _one_line(capsys.readouterr().err, "run")
    assert f"{short}: shaft.depth 100 m: 179 of 400 landed samples have a depth outside" in err
    json = tmp_path / "found.json"
    assert main(["discover", "--data", str(data), "--hoist", str(short), "--json", str(json)]) == 1
    assert "shaft.depth 100 m: 179 of 400" in _one_line(capsys.readouterr().err, "discover")
    assert main(["run", "--data", str(data), "--hoist", str(HOIST), "--no-sanity"]) == 0
