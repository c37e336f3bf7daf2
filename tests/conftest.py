"""Session-wide test set-up: one Prefect test harness for every flow test, and a
writer of small field logs."""

from __future__ import annotations

import atexit
import datetime as dt
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest

from pipelines.prefect_env import apply_prefect_defaults

# A stable Prefect home for this test session, away from the user's own (one the user
# sets is kept with `-n 0`); with pytest-xdist one per worker (a worker inherits the
# controller's environment, and two Prefect servers must not share a home). The process
# that made a home removes it when it exits: a run leaves nothing in the temp directory.
if "PREFECT_HOME" not in os.environ or os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ["PREFECT_HOME"] = tempfile.mkdtemp(prefix="ropeload-prefect-")
    atexit.register(shutil.rmtree, os.environ["PREFECT_HOME"], ignore_errors=True)
apply_prefect_defaults()


@pytest.fixture(scope="session")
def prefect_harness():
    """A temporary Prefect server (SQLite) for the whole session (~11 s once)."""
    from prefect.testing.utilities import prefect_test_harness

    with prefect_test_harness(server_startup_timeout=120):
        yield


def _small_field_csv(path: Path, rows: int = 20, start: str = "2026-03-02 06:00:00") -> Path:
    """A small contract-1a CSV of the paper's field-test hoist (UTC, 100 Hz)."""
    t0 = dt.datetime.fromisoformat(start)
    lines = [
        "# site: paper-field-test",
        "# hoist: main-shaft",
        "# timezone: UTC",
        "# sample_rate_hz: 100",
        "# units: p=MPa, x=mm, depth=m, speed=m/s, oil_temp=degC",
        "timestamp,p1,p2,p3,p4,x1,x2,x3,x4,depth,speed,oil_temp",
    ]
    for i in range(rows):
        t = (t0 + dt.timedelta(milliseconds=10 * i)).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]
        lines.append(f"{t},4.812,4.792,4.832,4.802,12.1,-3.4,0.2,7.9,{i * 0.5:.2f},1.000,31.2")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def small_csv() -> Callable[..., Path]:
    """``small_csv(path, rows=20, start=...)`` writes a small field log and returns it."""
    return _small_field_csv
