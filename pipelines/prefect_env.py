"""Environment defaults for Prefect on these machines, applied before Prefect is imported.

Measured in ../shared/notes/stack.md: without them Prefect tries to send telemetry (an
error on this network), keeps a fresh home per process (slower start) and can time
out starting its temporary server. Values already set in the environment win.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["PREFECT_DEFAULTS", "apply_prefect_defaults"]

PREFECT_DEFAULTS: dict[str, str] = {
    "PREFECT_SERVER_ANALYTICS_ENABLED": "false",
    "PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS": "120",
    "PREFECT_HOME": str(Path.home() / ".prefect"),
    "PREFECT_LOGGING_TO_API_BATCH_INTERVAL": "0.3",
    "DASK_LOGGING__DISTRIBUTED": "warning",
}


def apply_prefect_defaults() -> None:
    """Set each default unless the environment already has a value for it."""
    for key, value in PREFECT_DEFAULTS.items():
        os.environ.setdefault(key, value)
