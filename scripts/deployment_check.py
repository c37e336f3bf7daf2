"""Check the nightly deployment end to end on a local Prefect server, then stop it.

1. writes a tiny synthetic mine (one hoist, one day of logs) in a temporary folder;
2. starts ``prefect server start --host 127.0.0.1 --port <free port>`` with its own
   PREFECT_HOME (scheduler loop every 5 s so the check is quick);
3. starts ``python -m pipelines.deploy serve`` (the README recipe) against it, which
   registers ``nightly/ropeload-nightly`` with a cron schedule in the hoist's time zone;
4. reads the deployment back through the API: schedule, time zone and the runs the
   scheduler created (shown in UTC and mine-local time);
5. triggers one run through the API (``run_deployment``), waits for it, and checks it
   Completed, landed rows and published the report artifact;
6. stops the serve process and the server (also on failure).

Run by hand (about a minute)::

    .venv/bin/python scripts/deployment_check.py

Exit status 0 when every check passed.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
import zoneinfo
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

CRON = "30 2 * * *"
NAME = "ropeload-nightly"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_healthy(url: str, timeout_s: float = 120.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"{url}/health", timeout=2) as response:
                if response.status == 200:
                    return
        except OSError:
            pass
        time.sleep(0.5)
    raise TimeoutError(f"prefect server at {url} not healthy after {timeout_s:.0f} s")


def _stop(process: subprocess.Popen[bytes] | None, name: str) -> None:
    if process is None or process.poll() is not None:
        return
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout=20)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    print(f"stopped {name} (pid {process.pid})")


def main() -> int:
    work = Path(tempfile.mkdtemp(prefix="ropeload-deploy-check-"))
    port = _free_port()
    api = f"http://127.0.0.1:{port}/api"
    env = {
        **os.environ,
        "PREFECT_HOME": str(work / "prefect-home"),
        "PREFECT_API_URL": api,
        "PREFECT_SERVER_ANALYTICS_ENABLED": "false",
        "PREFECT_SERVER_SERVICES_SCHEDULER_LOOP_SECONDS": "5",
        "PREFECT_RUNNER_POLL_FREQUENCY": "2",
    }
    os.environ.update(env)  # this process talks to the same server

    from pipelines.deploy import write_example_mine

    hoists, incoming = write_example_mine(work / "mine", hoists=1, days=1)
    data = work / "data"
    print(f"work folder: {work}")
    prefect = Path(sys.executable).with_name("prefect")
    server = serve = None
    try:
        t0 = time.monotonic()
        server = subprocess.Popen(
            [str(prefect), "server", "start", "--host", "127.0.0.1", "--port", str(port)],
            env=env,
            stdout=(work / "server.log").open("wb"),
            stderr=subprocess.STDOUT,
        )
        _wait_healthy(api)
        print(f"prefect server healthy at {api} after {time.monotonic() - t0:.1f} s")
        serve = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "pipelines.deploy",
                "serve",
                "--hoists",
                str(hoists),
                "--data",
                str(data),
                "--incoming",
                str(incoming),
                "--cron",
                CRON,
                "--name",
                NAME,
            ],
            cwd=REPO,
            env=env,
            stdout=(work / "serve.log").open("wb"),
            stderr=subprocess.STDOUT,
        )
        return _check(work, data)
    finally:
        _stop(serve, "serve")
        _stop(server, "prefect server")


def _check(work: Path, data: Path) -> int:
    """The deployment's schedule, then one run triggered through the API; 0 when both
    are as they should be."""
    failures = _check_schedule(work) + _check_triggered_run(data)
    for failure in failures:
        print(f"FAILED: {failure}")
    print("deployment check: " + ("OK" if not failures else "FAILED"))
    return 0 if not failures else 1


def _check_schedule(work: Path) -> list[str]:
    """The deployment is registered with the mine-local cron and its next runs are
    scheduled at 02:30 mine-local time; what is not."""
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import (
        DeploymentFilter,
        DeploymentFilterId,
        FlowRunFilter,
        FlowRunFilterState,
        FlowRunFilterStateName,
    )

    failures: list[str] = []
    with get_client(sync_client=True) as client:
        deadline = time.monotonic() + 120
        deployment = None
        while deployment is None and time.monotonic() < deadline:
            try:
                deployment = client.read_deployment_by_name(f"nightly/{NAME}")
            except Exception:
                time.sleep(1)
        if deployment is None:
            print((work / "serve.log").read_text()[-3000:])
            raise TimeoutError("deployment not registered after 120 s (serve.log above)")
        print(f"deployment registered: nightly/{deployment.name} id {deployment.id}")
        for schedule in deployment.schedules:
            print(
                f"  schedule: cron {schedule.schedule.cron!r} timezone "
                f"{schedule.schedule.timezone} active {schedule.active}"
            )
            if schedule.schedule.cron != CRON or schedule.schedule.timezone != "Asia/Shanghai":
                failures.append("schedule is not the mine-local cron")
        print(f"  parameters: {deployment.parameters}")
        scheduled = []
        deadline = time.monotonic() + 60
        while not scheduled and time.monotonic() < deadline:
            scheduled = client.read_flow_runs(
                deployment_filter=DeploymentFilter(id=DeploymentFilterId(any_=[deployment.id])),
                flow_run_filter=FlowRunFilter(
                    state=FlowRunFilterState(name=FlowRunFilterStateName(any_=["Scheduled"]))
                ),
                limit=3,
            )
            time.sleep(1)
        zone = zoneinfo.ZoneInfo("Asia/Shanghai")
        for run in sorted(scheduled, key=lambda r: r.expected_start_time)[:3]:
            when = run.expected_start_time
            print(
                f"  scheduled run {run.name}: {when:%Y-%m-%d %H:%M} UTC = "
                f"{when.astimezone(zone):%Y-%m-%d %H:%M} Asia/Shanghai"
            )
            if when.astimezone(zone).strftime("%H:%M") != "02:30":
                failures.append("a scheduled run is not at 02:30 mine-local time")
        if not scheduled:
            failures.append("the scheduler created no scheduled run")
    return failures


def _check_triggered_run(data: Path) -> list[str]:
    """A run triggered through the API completes, leaves its report artifact and lands
    a hoist-day in the warehouse; what does not."""
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import ArtifactFilter, ArtifactFilterFlowRunId
    from prefect.deployments import run_deployment

    from pipelines.ledger import fingerprint
    from warehouse.store import DataRoot

    failures: list[str] = []
    t0 = time.monotonic()
    run = run_deployment(f"nightly/{NAME}", timeout=300)
    print(
        f"triggered flow run {run.name} through the API: state {run.state.type.value} "
        f"after {time.monotonic() - t0:.1f} s"
    )
    if not run.state.is_completed():
        failures.append(f"triggered run ended {run.state.type.value}: {run.state.message}")
    with get_client(sync_client=True) as client:
        artifacts = client.read_artifacts(
            artifact_filter=ArtifactFilter(flow_run_id=ArtifactFilterFlowRunId(any_=[run.id]))
        )
    print(f"  artifacts of the run: {sorted(a.key for a in artifacts if a.key)}")
    if "nightly-report" not in {a.key for a in artifacts}:
        failures.append("no nightly-report artifact")
    if (data / "warehouse.duckdb").exists():
        landed = fingerprint(DataRoot.resolve(data))
        print(
            f"  landed: {landed['field_samples'][0]} samples, "
            f"{landed['position_summary'][0]} position rows, "
            f"{landed['sanity_checks'][0]} sanity checks, {landed['runs_per_day'][1]} hoist-days"
        )
        if landed["runs_per_day"][1] < 1:
            failures.append("the run landed no hoist-day")
    else:
        failures.append("the run created no warehouse")
    return failures


if __name__ == "__main__":
    sys.exit(main())
