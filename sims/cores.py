"""How many cores this process may use, for the replays' threads.

The CPU affinity alone overstates them in a container with a CPU quota (a pod limited
to 2 CPUs on a 64-core host sees 64 cores in its affinity, and threads beyond its quota
are throttled, not run): the quota of the process's control group caps the count.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

__all__ = ["cgroup_cpu_quota", "usable_cores"]


def usable_cores(cgroup: Path = Path("/sys/fs/cgroup")) -> int:
    """The cores this process may use: its CPU affinity, capped by the CPU quota of its
    control group rounded up (:func:`cgroup_cpu_quota`). At least 1.

    >>> usable_cores() >= 1
    True
    """
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1
    quota = cgroup_cpu_quota(cgroup)
    if quota is not None:
        cores = min(cores, math.ceil(quota))
    return max(cores, 1)


def cgroup_cpu_quota(cgroup: Path = Path("/sys/fs/cgroup")) -> float | None:
    """CPUs' worth of time per period the control group under ``cgroup`` may use: cgroup
    v2 ``cpu.max`` (``"<quota> <period>"``, ``"max ..."`` for none), else v1
    ``cpu/cpu.cfs_quota_us`` over ``cpu/cpu.cfs_period_us`` (-1 for none); None when
    there is no quota or no file says."""
    try:
        words = (cgroup / "cpu.max").read_text().split()
    except OSError:
        words = None
    if words is not None:
        if len(words) != 2 or words[0] == "max":
            return None
        return _ratio(words[0], words[1])
    try:
        quota = (cgroup / "cpu" / "cpu.cfs_quota_us").read_text()
        period = (cgroup / "cpu" / "cpu.cfs_period_us").read_text()
    except OSError:
        return None
    return _ratio(quota, period)


def _ratio(quota: str, period: str) -> float | None:
    try:
        value = float(quota) / float(period)
    except (ValueError, ZeroDivisionError):
        return None
    return value if value > 0 else None
