"""What produced a number: code version and run ids for the ``runs`` table."""

from __future__ import annotations

import datetime as dt
import subprocess
import uuid
from functools import cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

__all__ = ["code_version", "new_run_id", "utc_now"]

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
