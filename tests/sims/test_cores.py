"""sims.cores: the cores the replays' threads may use, on control-group files written here."""

from __future__ import annotations

import os

import pytest

from sims.cores import cgroup_cpu_quota, usable_cores

AFFINITY = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1


def _v2(tmp_path, text):
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "cpu.max").write_text(text)
    return tmp_path


def _v1(tmp_path, quota, period):
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "cpu").mkdir()
    (tmp_path / "cpu" / "cpu.cfs_quota_us").write_text(f"{quota}\n")
    (tmp_path / "cpu" / "cpu.cfs_period_us").write_text(f"{period}\n")
    return tmp_path


def test_a_v2_quota_caps_the_affinity(tmp_path):
    root = _v2(tmp_path, "150000 100000\n")
    assert cgroup_cpu_quota(root) == pytest.approx(1.5)
    assert usable_cores(root) == min(AFFINITY, 2)  # 1.5 CPUs rounded up


def test_a_quarter_cpu_still_gets_one_core(tmp_path):
    assert usable_cores(_v2(tmp_path, "25000 100000")) == 1


def test_no_v2_quota_leaves_the_affinity(tmp_path):
    root = _v2(tmp_path, "max 100000\n")
    assert cgroup_cpu_quota(root) is None
    assert usable_cores(root) == AFFINITY


def test_a_v1_quota_and_none(tmp_path):
    assert cgroup_cpu_quota(_v1(tmp_path / "a", 100000, 100000)) == pytest.approx(1.0)
    assert usable_cores(tmp_path / "a") == 1
    assert cgroup_cpu_quota(_v1(tmp_path / "b", -1, 100000)) is None
    assert usable_cores(tmp_path / "b") == AFFINITY


def test_unreadable_or_missing_files_leave_the_affinity(tmp_path):
    assert cgroup_cpu_quota(tmp_path) is None
    assert usable_cores(tmp_path) == AFFINITY
    assert cgroup_cpu_quota(_v2(tmp_path / "x", "garbage")) is None
