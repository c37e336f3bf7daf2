"""Session-wide test set-up: one Prefect test harness for every flow test."""

from __future__ import annotations

import os
import tempfile

import pytest

from pipelines.prefect_env import apply_prefect_defaults

# A stable Prefect home for this test session, away from the user's own.
os.environ.setdefault("PREFECT_HOME", tempfile.mkdtemp(prefix="ropeload-prefect-"))
apply_prefect_defaults()


@pytest.fixture(scope="session")
def prefect_harness():
    """A temporary Prefect server (SQLite) for the whole session (~11 s once)."""
    from prefect.testing.utilities import prefect_test_harness

    with prefect_test_harness(server_startup_timeout=120):
        yield
