"""A run reads what its hoist's description makes impossible as not logged.

``ropeload ingest`` without ``--hoist`` lands every value it can parse: without the
description it knows no stroke, no winder and no shaft depth. The run has the
description: a piston 100 m out of its cylinder, a speed of 1e300 m/s or a depth of
1e300 m is a corrupted number, which the run and its sanity check read as not logged.
Two data roots of the same simulated record, one whose corrupted cells say so and one
whose same cells are empty, land the same rope tensions and sanity checks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
from polars.testing import assert_frame_equal

from pipelines.cli import main
from pipelines.lake import scan_lake
from schemas.hoist import load_hoist
from sims.field_day import generate_field_day, write_field_day
from warehouse.store import DataRoot, open_reader

REPO = Path(__file__).resolve().parents[2]
HOIST_PATH = REPO / "schemas" / "hoists" / "paper_field_test.toml"
HOIST = load_hoist(HOIST_PATH)


def _root(day, corrupt: bool, tmp_path: Path) -> Path:
    rows = np.zeros(day.sensors.height, dtype=bool)
    rows[1000:1400] = True  # 4 s of one stop or trip
    rows[5000:5050] = True
    bad = pl.Series(rows)

    def spoiled(column: str, value: float) -> pl.Expr:
        return pl.when(bad).then(value if corrupt else None).otherwise(pl.col(column)).alias(column)

    spoiled_day = type(day)(**{**day.__dict__})
    spoiled_day.sensors = day.sensors.with_columns(
        spoiled("x1_m", 100.0), spoiled("speed_m_s", 1e300), spoiled("depth_m", 1e300)
    )
    name = "corrupt" if corrupt else "empty"
    (csv,) = write_field_day(spoiled_day, tmp_path / f"logs-{name}", formats=("csv",))[:1]
    data = tmp_path / f"data-{name}"
    assert main(["ingest", "--data", str(data), str(csv)]) == 0  # no --hoist: all landed
    assert main(["run", "--data", str(data), "--hoist", str(HOIST_PATH)]) == 0
    return data


def test_values_the_description_makes_impossible_are_read_as_not_logged(
    tmp_path: Path, capsys
) -> None:
    day = generate_field_day(HOIST, date="2026-03-02", seed=11, trips=2, hours=0.25)
    corrupt, empty = _root(day, True, tmp_path), _root(day, False, tmp_path)
    capsys.readouterr()
    site, name = HOIST.hoist.site, HOIST.hoist.name
    landed = scan_lake(DataRoot.resolve(corrupt), "field_samples", site=site, hoist=name)
    assert landed.select((pl.col("x1_m") == 100.0).sum()).collect().item() == 450
    tensions = [
        scan_lake(DataRoot.resolve(d), "rope_tensions", site=site, hoist=name).collect()
        for d in (corrupt, empty)
    ]
    assert tensions[0].height == day.sensors.height
    assert_frame_equal(tensions[0], tensions[1])
    checks = []
    for data in (corrupt, empty):
        con = open_reader(DataRoot.resolve(data))
        try:
            checks.append(
                con.sql(
                    "SELECT trip_id, status, rms_gap_pa FROM sanity_checks ORDER BY trip_id"
                ).pl()
            )
        finally:
            con.close()
    assert checks[0].height > 0
    assert_frame_equal(checks[0], checks[1])
