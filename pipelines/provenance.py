"""What produced a number: code version and run ids for the ``runs`` table."""

from __future__ import annotations

import datetime as dt
import subprocess
import uuid
from collections.abc import Sequence
from functools import cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from schemas.hoist import HoistDescription, hoist_sha256
from warehouse.landing import RunRecord

__all__ = ["code_version", "hoist_run", "new_run_id", "utc_now"]

_REPO = Path(__file__).resolve().parents[1]


@cache
def code_version() -> str:
    """Package version plus the git commit (``+dirty`` with uncommitted changes)."""
    try:
        base = version("ropeload")
    except PackageNotFoundError:  # pragma: no cover - running from a bare checkout
        base = "0+unknown"
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"],
            cwd=_REPO,
            capture_output=True,
            text=True,
            check=True,
            timeout=5,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=_REPO,
            capture_output=True,
            text=True,
            check=True,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return base
    return f"{base}+g{sha}{'.dirty' if dirty else ''}"


def new_run_id(command: str) -> str:
    """A unique, sortable run id: ``<command>-<UTC timestamp>-<random>``."""
    stamp = utc_now().strftime("%Y%m%dT%H%M%S")
    return f"{command}-{stamp}-{uuid.uuid4().hex[:8]}"


def utc_now() -> dt.datetime:
    return dt.datetime.now(dt.UTC)


def hoist_run(
    *,
    run_id: str,
    command: str,
    started_at_utc: dt.datetime,
    hoist: HoistDescription,
    hoist_path: str | Path,
    period: tuple[dt.datetime, dt.datetime],
    inputs: Sequence[str],
    message: str,
) -> RunRecord:
    """The ``runs`` row of a succeeded run over one hoist's period, finished now: the code
    version, the hoist file's hash, friction parameter set and time zone, the sources it
    read."""
    return RunRecord(
        run_id=run_id,
        command=command,
        code_version=code_version(),
        started_at_utc=started_at_utc,
        hoist_sha256=hoist_sha256(hoist_path),
        parameter_set=hoist.friction.parameter_set,
        site=hoist.hoist.site,
        hoist=hoist.hoist.name,
        period_start_utc=period[0],
        period_end_utc=period[1],
        inputs=tuple(inputs),
        finished_at_utc=utc_now(),
        status="succeeded",
        message=message,
        timezone=hoist.hoist.timezone,
    )
