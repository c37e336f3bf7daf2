"""Environment defaults for Prefect on these machines, applied before Prefect is imported.

Measured in ../shared/notes/stack.md: without them Prefect tries to send telemetry (an
error on this network), keeps a fresh home per process (slower start) and can time
out starting its temporary server. Values already set in the environment win.

Logging: Prefect attaches its API handler to the loggers named in
``PREFECT_LOGGING_EXTRA_LOGGERS`` when it is imported (Prefect 3 setting
``logging.extra_loggers``), so ropeload's module loggers (:data:`pipelines.log.NAMESPACES`)
reach the run logs of the flow or task run they are called in, without library code
importing Prefect; outside a run Prefect would warn per record, hence
``PREFECT_LOGGING_TO_API_WHEN_MISSING_FLOW=ignore``. The levels: :mod:`pipelines.log`.
"""

from __future__ import annotations

import os
from pathlib import Path

from pipelines.log import NAMESPACES

__all__ = ["PREFECT_DEFAULTS", "apply_prefect_defaults"]

_EXTRA = "PREFECT_LOGGING_EXTRA_LOGGERS"

PREFECT_DEFAULTS: dict[str, str] = {
    "PREFECT_SERVER_ANALYTICS_ENABLED": "false",
    "PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS": "120",
    "PREFECT_HOME": str(Path.home() / ".prefect"),
    "PREFECT_LOGGING_TO_API_BATCH_INTERVAL": "0.3",
    "DASK_LOGGING__DISTRIBUTED": "warning",
    _EXTRA: ",".join(NAMESPACES),
    "PREFECT_LOGGING_TO_API_WHEN_MISSING_FLOW": "ignore",
}


def apply_prefect_defaults() -> None:
    """Set each default unless the environment already has a value for it; ropeload's
    namespaces are added to extra loggers the environment already names."""
    for key, value in PREFECT_DEFAULTS.items():
        os.environ.setdefault(key, value)
    named = [n.strip() for n in os.environ[_EXTRA].split(",") if n.strip()]
    os.environ[_EXTRA] = ",".join(named + [n for n in NAMESPACES if n not in named])
