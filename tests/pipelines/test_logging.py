"""Logging and progress (issue 18, mine IT): module loggers reach the Prefect run logs
of a real flow run; the CLI's stdout stays its result and its stderr its one-line
errors unless ``--log-level`` asks for more; the progress bar (rich) only on a
terminal, a single summary line elsewhere."""

from __future__ import annotations

import datetime as dt
import logging
import os
import select
import time
from pathlib import Path

import pytest

from pipelines.cli import main
from pipelines.log import LEVEL_ENV, configure_logging
from pipelines.partitions import PartitionOutcome
from pipelines.progress import StderrProgress

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def _quiet_afterwards(monkeypatch):
    """Whatever a test set, later tests of the session see the default stderr level."""
    monkeypatch.delenv(LEVEL_ENV, raising=False)
    yield
    configure_logging("WARNING")


# ------------------------------------------------------------------ the CLI


def test_log_level_adds_lines_on_stderr_only(tmp_path, capsys, monkeypatch, small_csv):
    csv = small_csv(tmp_path / "day.csv")
    assert main(["ingest", "--data", str(tmp_path / "quiet"), str(csv)]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == ""  # default WARNING: nothing but refusals

    assert main(["ingest", "--log-level", "info", "--data", str(tmp_path / "a"), str(csv)]) == 0
    loud = capsys.readouterr()
    assert loud.out == quiet.out  # the report, unchanged
    landed = [line for line in loud.err.splitlines() if "pipelines.ingest.pipeline" in line]
    assert len(landed) == 1
    assert f"INFO    pipelines.ingest.pipeline: landed {csv}: 20 rows read, 20 landed" in landed[0]
    assert "INFO" not in loud.out

    monkeypatch.setenv(LEVEL_ENV, "debug")  # the environment, when no option is given
    assert main(["ingest", "--data", str(tmp_path / "a"), str(csv)]) == 0
    again = capsys.readouterr()
    assert f"DEBUG   pipelines.ingest.pipeline: skipped {csv}" in again.err
    assert "DEBUG" not in again.out


def test_a_refusal_stays_one_line_at_the_default_level(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("# site: paper-field-test\nnot,a,log\n")
    assert main(["ingest", "--data", str(tmp_path / "d"), str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith(f"ropeload ingest: {bad}: ")


def test_bad_log_level_is_a_usage_error(tmp_path, capsys, monkeypatch):
    with pytest.raises(SystemExit) as exited:
        main(["query", "--log-level", "loud", "select 1"])
    assert exited.value.code == 2
    assert "log level 'loud' is not one of debug, info, warning, error" in capsys.readouterr().err
    monkeypatch.setenv(LEVEL_ENV, "chatty")
    with pytest.raises(SystemExit) as exited:
        main(["query", "select 1"])
    assert exited.value.code == 2
    assert f"'chatty' is not one of debug, info, warning, error (--log-level or ${LEVEL_ENV})" in (
        capsys.readouterr().err
    )


def test_backfill_off_a_terminal_prints_one_summary_line_and_logs_on_request(tmp_path, capsys):
    from pipelines.deploy import write_example_mine

    hoists, incoming = write_example_mine(tmp_path / "mine", hoists=1, days=1)
    status = main(
        ["backfill", "--data", str(tmp_path / "data"), "--hoists", str(hoists),
         "--incoming", str(incoming), "--from", "2026-03-02", "--to", "2026-03-03",
         "--log-level", "info"]
    )  # fmt: skip
    assert status == 0
    out, err = capsys.readouterr()
    assert out.startswith("2 partitions: 1 run, 0 already done, 1 without data, 0 failed;")
    assert "INFO" not in out
    lines = err.splitlines()
    assert lines[-1].startswith("2/2 partitions, 0 failed, ")  # the progress, once, at the end
    assert not any("partitions, 0 failed" in line for line in lines[:-1])
    assert any(
        "INFO    pipelines.backfill: plan 2026-03-02 .. 2026-03-03: 2 hoist-days, 1 to run" in line
        for line in lines
    )
    runs = [line for line in lines if "pipelines.run_period: run backfill-" in line]
    assert len(runs) == 2  # started and landed (the second day has no data)
    assert "pipelines.backfill: paper-field-test/shaft-1/2026-03-02: succeeded" in err


# ------------------------------------------------------------------ progress


def _outcome(day: int, status: str = "succeeded") -> PartitionOutcome:
    return PartitionOutcome(
        key=f"s/h/2026-03-0{day}", site="s", hoist="h", day=dt.date(2026, 3, day), status=status
    )


def test_progress_off_a_terminal_is_one_summary_line_at_the_end():
    import io

    stream = io.StringIO()
    bar = StderrProgress(0, stream=stream)
    bar.resize(3)
    bar(_outcome(1))
    bar(_outcome(2, "failed"))
    assert stream.getvalue() == ""  # nothing while it runs (CI, cron, a log file)
    bar(_outcome(3))
    assert stream.getvalue().startswith("3/3 partitions, 1 failed, ")
    assert stream.getvalue().count("\n") == 1
    bar.close()  # once
    assert stream.getvalue().count("\n") == 1


def _read_pty(fd: int) -> str:
    chunks = []
    while select.select([fd], [], [], 0.2)[0]:
        data = os.read(fd, 65536)
        if not data:
            break
        chunks.append(data)
    return b"".join(chunks).decode("utf-8", "replace")


def test_progress_on_a_terminal_is_a_live_bar_that_ends_cleanly():
    master, slave = os.openpty()
    try:
        with os.fdopen(slave, "w") as terminal:
            bar = StderrProgress(2, stream=terminal)
            bar(_outcome(1, "failed"))
            during = ""  # a refresh at 2 per second: one within seconds on a busy machine
            deadline = time.monotonic() + 20.0
            while "1 failed" not in during and time.monotonic() < deadline:
                time.sleep(0.1)
                during += _read_pty(master)
            bar(_outcome(2))  # the last one ends the bar
            after = _read_pty(master)
    finally:
        os.close(master)
    assert "1/2" in during
    assert "1 failed" in during
    assert "\x1b[?25l" in during  # rich hides the cursor while it draws
    assert "2/2" in after
    assert "s/h/2026-03-02" in after
    assert after.endswith("\x1b[?25h") or "\x1b[?25h" in after  # and shows it again
    assert "partitions, 1 failed, " not in during + after  # the summary line is for non-ttys


# ------------------------------------------------------------------ Prefect


def _flow_logs(flow_run_id, *, want: str, timeout_s: float = 20.0) -> list:
    """The flow run's logs once one contains ``want`` (logs are sent in batches)."""
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import LogFilter, LogFilterFlowRunId

    deadline = time.monotonic() + timeout_s
    with get_client(sync_client=True) as client:
        while True:
            logs = client.read_logs(
                log_filter=LogFilter(flow_run_id=LogFilterFlowRunId(any_=[flow_run_id]))
            )
            if any(want in log.message for log in logs) or time.monotonic() > deadline:
                return logs
            time.sleep(0.3)


@pytest.mark.prefect
@pytest.mark.usefixtures("prefect_harness")
def test_library_log_lines_reach_the_flow_run_logs(tmp_path, small_csv):
    """A line logged by library code (pipelines.ingest, no Prefect import) inside a real
    ingest flow run is in that run's logs, under the task run that logged it."""
    from pipelines.flows import ingest_flow

    csv = small_csv(tmp_path / "day.csv")
    state = ingest_flow(paths=[str(csv)], data=str(tmp_path / "data"), return_state=True)
    assert state.is_completed()
    logs = _flow_logs(state.state_details.flow_run_id, want=f"landed {csv}")
    ours = [log for log in logs if log.name == "pipelines.ingest.pipeline"]
    assert [log.message for log in ours] == [
        f"landed {csv}: 20 rows read, 20 landed, 0 quarantined, 0 duplicates"
    ]
    assert ours[0].level == logging.INFO
    assert ours[0].task_run_id is not None  # logged in the ingest-files task
    assert logging.getLogger("pipelines").propagate is False  # never twice on stderr
