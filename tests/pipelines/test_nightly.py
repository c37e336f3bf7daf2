"""Nightly (plain functions): new files since the watermark, late files, self-healing nights."""

from __future__ import annotations

import datetime as dt
import os
import shutil
from pathlib import Path

import polars as pl
import pytest

from pipelines.backfill import fingerprint, known_files, load_hoists, partition_ledger
from pipelines.deploy import write_example_mine
from pipelines.nightly import find_new_files, nightly, watermarks
from schemas.hoist import load_hoist
from sims.field_day import generate_field_day, write_field_day
from warehouse.store import DataRoot


@pytest.fixture(scope="module")
def mine(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("night-mine")
    return write_example_mine(root, hoists=2, days=2)


@pytest.fixture
def site(mine, tmp_path) -> tuple[Path, Path, DataRoot]:
    """A private copy of the mine (tests add files and edit hoists)."""
    hoists, incoming = mine
    shutil.copytree(hoists, tmp_path / "hoists")
    shutil.copytree(incoming, tmp_path / "incoming")
    return tmp_path / "hoists", tmp_path / "incoming", DataRoot.resolve(tmp_path / "data")


def test_a_night_takes_new_files_only_and_moves_the_watermark(site):
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    assert [len(find_new_files(s, known_files(data))) for s in sources] == [2, 2]
    first = nightly(sources, data=data)
    assert first.ok, str(first)
    assert first.runs.count("succeeded") == 4
    # every day run is checked against the simulation; the synthetic data pass
    # every trip is checked but a day's first, which only warms up the friction state
    assert all(o.checks >= 1 for o in first.runs.outcomes)
    assert sum(o.checks_failed for o in first.runs.outcomes) == 0
    assert first.discoveries == {}
    assert fingerprint(data)["sanity_checks"][0] == sum(o.checks for o in first.runs.outcomes)
    marks = watermarks(data)
    assert marks[("paper-field-test", "shaft-1")] == first.hoists[0].watermark_after
    assert marks[("paper-field-test", "shaft-1")].date() == dt.date(2026, 3, 3)
    assert [len(find_new_files(s, known_files(data))) for s in sources] == [0, 0]
    before = fingerprint(data)
    second = nightly(sources, data=data)
    assert second.runs.outcomes == []
    assert fingerprint(data) == before  # re-running a night changes nothing
    assert "0 new file(s)" in str(second)


def test_a_late_file_reopens_only_its_day(site):
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    assert nightly(sources, data=data, sanity=False).ok
    runs_before = partition_ledger(data).select("hoist", "day", "run_id")
    # an hour file for shaft-1, 2026-03-02 14:00 local, copied in late with an old mtime
    hoist = load_hoist(hoists / "shaft-1.toml")
    late = generate_field_day(
        hoist, date="2026-03-02", seed=99, trips=2, hours=1 / 6, start_hour=14.0
    )
    target = incoming / "paper-field-test" / "shaft-1"
    written = write_field_day(late, target, formats=("csv",), split="hour")
    for path in written:
        if path.suffix != ".csv":
            path.unlink()
        else:
            os.utime(path, (0, 0))  # rsync -a keeps the source's old mtime
    night = nightly(sources, data=data, sanity=False)
    assert [n.row()["new_files"] for n in night.hoists] == [1, 0]
    assert [o.key for o in night.runs.outcomes if o.status == "succeeded"] == [
        "paper-field-test/shaft-1/2026-03-02"
    ]
    runs_after = partition_ledger(data).select("hoist", "day", "run_id")
    rerun = runs_after.join(runs_before, on=["hoist", "day"], suffix="_before").filter(
        pl.col("run_id") != pl.col("run_id_before")
    )
    assert rerun.select("hoist", "day").rows() == [("shaft-1", dt.date(2026, 3, 2))]


def test_a_recalibrated_hoist_is_rerun_within_the_lookback(site):
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    assert nightly(sources, data=data, sanity=False).ok
    path = hoists / "shaft-2.toml"
    path.write_text(path.read_text() + "\n# friction parameters recalibrated\n")
    night = nightly(sources, data=data, lookback_days=1, sanity=False)  # no new file
    assert [o.key for o in night.runs.outcomes] == ["paper-field-test/shaft-2/2026-03-03"]


def test_a_hoist_failing_its_ingest_does_not_hold_up_the_others_and_heals(site):
    hoists, incoming, data = site
    sources = load_hoists(hoists, data=data, incoming=incoming)
    path = hoists / "shaft-2.toml"
    good = path.read_text()
    path.write_text(good.replace('mass = "8.2 t"', 'mass = "8.2 m"'))
    broken = nightly(sources, data=data, retries=0, sanity=False)
    assert not broken.ok
    assert "HoistDescriptionError" in broken.hoists[1].error
    assert "conveyance.mass" in str(broken)
    assert broken.runs.count("succeeded") == 2  # shaft-1 is not held up
    path.write_text(good)
    healed = nightly(
        sources, data=data, sanity=False
    )  # shaft-2's files were never ingested: still new
    assert healed.ok
    assert sorted(o.key for o in healed.runs.outcomes if o.status == "succeeded") == [
        "paper-field-test/shaft-2/2026-03-02",
        "paper-field-test/shaft-2/2026-03-03",
    ]
