"""pipelines.discover and ``ropeload discover``: lake in, contract-5 JSON + plot + warehouse out."""

from __future__ import annotations

import json

import polars as pl
import pytest

from discovery.cases import hidden_case
from pipelines.cli import main
from pipelines.discover import discover_period
from schemas.hoist import EXAMPLE_HOIST
from warehouse.store import DataRoot, open_reader


@pytest.fixture(scope="module")
def lake_with_offset(tmp_path_factory):
    """Two trips whose sensor 2 reads 20 kPa high, landed in a lake; hoist file without it."""
    plan, info = hidden_case("sensor_offset")
    root = tmp_path_factory.mktemp("data")
    hoist = plan.hoist
    sensors = info["day"].sensors.with_columns(
        pl.lit("0" * 64).alias("source_sha256"), pl.int_range(pl.len()).alias("source_line")
    )
    for (day,), part in (
        sensors.with_columns(_d=pl.col("time_utc").dt.date())
        .partition_by("_d", as_dict=True)
        .items()
    ):
        target = (
            root
            / "lake"
            / "field_samples"
            / f"site={hoist.hoist.site}"
            / f"hoist={hoist.hoist.name}"
            / f"date={day}"
            / "part-0.parquet"
        )
        target.parent.mkdir(parents=True, exist_ok=True)
        part.drop("_d").write_parquet(target)
    toml = root / "hoist.toml"  # the example hoist: its model has no sensor_offset
    toml.write_text(EXAMPLE_HOIST.read_text())
    return root, toml


def test_discover_period_writes_report_plot_and_lands(lake_with_offset, tmp_path):
    root, toml = lake_with_offset
    out = discover_period(
        hoist_path=toml, data=DataRoot.resolve(root), json_path=tmp_path / "r.json"
    )
    report = json.loads((tmp_path / "r.json").read_text())
    for key in (
        "hoist",
        "period",
        "effect",
        "parameters",
        "confidence",
        "where",
        "gap_before_pa",
        "gap_after_pa",
        "ranking",
    ):
        assert key in report
    assert report["effect"] == "sensor_offset"
    assert report["gap_after_pa"] < report["gap_before_pa"]
    # the offset explains the gap down to the noise: nothing left unexplained (contract 5)
    assert report["gap_after_pa"] <= 3.0 * report["noise_pa"]
    assert "unexplained_gap_pa" not in report
    assert (tmp_path / "r.png").stat().st_size > 1000
    assert out.landed_rows == len(report["findings"])
    con = open_reader(DataRoot.resolve(root))
    try:
        rows = con.sql(
            "select effect, iteration from discovery_findings order by iteration"
        ).fetchall()
    finally:
        con.close()
    assert rows[0] == ("sensor_offset", 1)


def test_cli_discover(lake_with_offset, tmp_path, capsys):
    root, toml = lake_with_offset
    code = main(
        ["discover", "--data", str(root), "--hoist", str(toml), "--json", str(tmp_path / "c.json")]
    )
    assert code == 0
    assert json.loads(capsys.readouterr().out)["effect"] == "sensor_offset"


@pytest.mark.parametrize(
    "target",
    ["warehouse.duckdb", "lake/field_samples/evil.parquet", ".warehouse.lock", "lake", "."],
)
def test_cli_discover_refuses_a_json_among_the_data_roots_files(
    lake_with_offset, tmp_path, capsys, target
):
    """``--json`` over the warehouse, into the lake or onto the lock (or a folder) is
    refused before anything runs, one line, and the data root is as it was: a report
    written there would destroy what every command reads."""
    root, toml = lake_with_offset
    before = sorted((p.relative_to(root), p.stat().st_size) for p in root.rglob("*"))
    code = main(
        ["discover", "--data", str(root), "--hoist", str(toml), "--json", str(root / target)]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert len(err) == 1, err
    assert err[0].startswith("ropeload discover: --json "), err
    assert sorted((p.relative_to(root), p.stat().st_size) for p in root.rglob("*")) == before


def test_cli_discover_writes_under_the_data_roots_reports(lake_with_offset, capsys):
    root, toml = lake_with_offset
    target = root / "reports" / "discovery" / "r.json"
    code = main(["discover", "--data", str(root), "--hoist", str(toml), "--json", str(target)])
    assert code == 0
    assert json.loads(target.read_text())["effect"] == "sensor_offset"
    capsys.readouterr()


def test_an_ambiguous_answer_names_its_pair_at_the_top_level():
    """Contract 5: ``effect: ambiguous`` comes with ``ambiguous_between`` and
    ``excitation`` in the report object itself (they were only in ``findings[0]``)."""
    from types import SimpleNamespace

    from discovery.results import Finding
    from pipelines.discover import report_objects
    from schemas.hoist import EXAMPLE_HOIST, load_hoist

    finding = Finding(
        iteration=1, effect="ambiguous", parameters={}, retuned={}, confidence=0.5,
        gap_before_pa=9000.0, gap_after_pa=9000.0, noise_pa=5000.0, variance_ratio=3.2,
        autocorrelation_time=1.0, where=[],
        ranking=[{"effect": "local_loss", "score": 10.0},
                 {"effect": "pipe_laminar_loss", "score": 9.5}],
        ambiguous_between=("local_loss", "pipe_laminar_loss"),
        excitation="trips at different speeds",
    )  # fmt: skip
    plan = SimpleNamespace(hoist=load_hoist(EXAMPLE_HOIST), trips=[], trips_found=0)
    result = SimpleNamespace(plan=plan, findings=[finding], effects_found=[],
                             effects_before=(), effects_after=())  # fmt: skip
    report, _ = report_objects(result, ("2026-03-02T00:00:00+00:00", "2026-03-03T00:00:00+00:00"))
    assert report["effect"] == "ambiguous"
    assert report["ambiguous_between"] == ["local_loss", "pipe_laminar_loss"]
    assert report["excitation"] == "trips at different speeds"


def test_the_plotted_sensor_of_a_trip_with_a_blanked_sensor_warns_nothing():
    """The plot's worst trip and sensor where one sensor was blanked as stuck (all NaN in
    that trip): the worst of the others, and no "Mean of empty slice" on stderr (a
    discover run with a stuck sensor printed one)."""
    import warnings

    import numpy as np

    from pipelines.discover import _worst_trip

    quiet = np.full((50, 4), 1e3)
    loud = np.full((50, 4), 1e3)
    loud[:, 1] = np.nan  # blanked
    loud[:, 2] = 5e3
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _worst_trip((quiet, loud)) == (1, 2)
