"""Prefect flows under the session test harness, on real files and a real warehouse.

Each flow call costs ~1-2 s on the harness, so there are few: backfill on threads,
nightly twice (the second must change nothing), backfill on a local Dask cluster,
ingest + run. Every flow must land exactly the rows the plain functions land.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest
from polars.testing import assert_frame_equal

from pipelines.backfill import backfill
from pipelines.deploy import write_example_mine
from pipelines.hoists import load_hoists
from pipelines.ledger import fingerprint
from pipelines.run_period import run_period
from warehouse.store import DataRoot

FIRST, LAST = dt.date(2026, 3, 1), dt.date(2026, 3, 4)

pytestmark = [pytest.mark.prefect, pytest.mark.usefixtures("prefect_harness")]


@pytest.fixture(scope="module")
def mine(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("flow-mine")
    return write_example_mine(root, hoists=2, days=2)


@pytest.fixture(scope="module")
def reference(mine, tmp_path_factory) -> dict[str, tuple[int, int]]:
    """The plain functions' rows for the whole range (no Prefect)."""
    hoists, incoming = mine
    data = DataRoot.resolve(tmp_path_factory.mktemp("plain"))
    report = backfill(
        load_hoists(hoists, data=data, incoming=incoming), data=data, start=FIRST, end=LAST
    )
    assert report.ok
    return fingerprint(data)


def _artifacts(key: str) -> list:
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import ArtifactFilter, ArtifactFilterKey

    with get_client(sync_client=True) as client:
        return client.read_artifacts(
            artifact_filter=ArtifactFilter(key=ArtifactFilterKey(any_=[key]))
        )


def test_backfill_flow_lands_the_plain_rows_and_publishes_the_report(mine, reference, tmp_path):
    from pipelines.flows import run_backfill_flow

    hoists, incoming = mine
    data = tmp_path / "data"
    report = run_backfill_flow(
        [hoists], start=FIRST, end=LAST, data=data, incoming=incoming, max_workers=2
    )
    assert report.ok
    assert report.count("succeeded") == 4
    assert fingerprint(DataRoot.resolve(data)) == reference
    markdown = _artifacts("backfill-report")
    assert markdown
    assert markdown[0].type == "markdown"
    assert "## Reconciliation per position" in markdown[0].data
    assert "data:image/png;base64," in markdown[0].data
    assert _artifacts("backfill-report-partitions")[0].type == "table"
    (html,) = (data / "reports").glob("backfill-*.html")  # the same report, interactive
    assert f"`{html}`" in markdown[0].data
    assert report.report_path == html


def test_nightly_flow_processes_new_files_and_a_second_night_changes_nothing(
    mine, reference, tmp_path
):
    from pipelines.flows import run_nightly_flow

    hoists, incoming = mine
    data = tmp_path / "data"
    first = run_nightly_flow(hoists, data=data, incoming=incoming, max_workers=2)
    assert first.ok
    assert [n.row()["new_files"] for n in first.hoists] == [2, 2]
    assert first.runs.count("succeeded") == 4
    # a night lands exactly what a backfill of the same days lands, plus sanity checks
    after_first = fingerprint(DataRoot.resolve(data))
    checks = after_first.pop("sanity_checks")
    assert checks[0] == sum(o.checks + o.checks_skipped for o in first.runs.outcomes) > 0
    assert after_first == {k: v for k, v in reference.items() if k != "sanity_checks"}
    second = run_nightly_flow(hoists, data=data, incoming=incoming, max_workers=2)
    assert [n.row()["new_files"] for n in second.hoists] == [0, 0]
    assert second.runs.outcomes == []
    assert fingerprint(DataRoot.resolve(data)) == {**after_first, "sanity_checks": checks}
    report = _artifacts("nightly-report")
    assert report
    assert any("| paper-field-test/shaft-1 | 0 |" in r.data for r in report)  # 2nd night
    assert any("Simulation sanity check:" in r.data for r in report)


@pytest.mark.slow
def test_backfill_flow_on_a_local_dask_cluster(mine, reference, tmp_path):
    pytest.importorskip("prefect_dask")
    from pipelines.flows import run_backfill_flow

    hoists, incoming = mine
    data = tmp_path / "data"
    report = run_backfill_flow(
        [hoists], start=FIRST, end=LAST, data=data, incoming=incoming, max_workers=2, dask="local"
    )
    assert report.count("succeeded") == 4
    assert fingerprint(DataRoot.resolve(data)) == reference


def test_ingest_and_run_flows_share_the_plain_implementation(mine, tmp_path):
    from pipelines.flows import ingest_flow, run_flow

    hoists, incoming = mine
    data = tmp_path / "data"
    files = sorted((incoming / "paper-field-test" / "shaft-1").glob("*.csv"))
    ingested = ingest_flow(paths=[str(f) for f in files], data=str(data))
    assert [f.status for f in ingested] == ["landed"] * 2
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    result = run_flow(
        hoist=str(hoists / "shaft-1.toml"),
        data=str(data),
        start=start,
        end=start + dt.timedelta(days=1),
    )
    assert result.samples > 50_000
    assert result.trip_summary.height >= 2
    # the plain implementation (no flow, no task) on the same lake and period computes
    # the same summaries and alarms, run ids aside: the flow passes its arguments through
    # (to polars' summation order: two plain runs differ by 1e-15 relative)
    plain = run_period(hoist_path=hoists / "shaft-1.toml", data=DataRoot.resolve(data),
                       start=start, end=start + dt.timedelta(days=1))  # fmt: skip
    assert plain.run_id != result.run_id
    assert (plain.samples, plain.period_start_utc, plain.period_end_utc) == (
        result.samples, result.period_start_utc, result.period_end_utc,
    )  # fmt: skip
    for table in ("position_summary", "trip_summary", "alarms"):
        flowed, direct = getattr(result, table), getattr(plain, table)
        assert_frame_equal(flowed.drop("run_id"), direct.drop("run_id"), rel_tol=1e-9, abs_tol=1e-6)


def test_only_transient_failures_are_retried():
    from prefect.states import Failed

    from pipelines.tasks import _retry_transient

    assert _retry_transient(None, None, Failed(data=OSError(5, "I/O error")))
    assert not _retry_transient(None, None, Failed(data=ValueError("bad data")))
    assert not _retry_transient(None, None, Failed(data=FileNotFoundError("gone")))


def test_every_command_of_contract_6_is_a_flow():
    """Contract 6: demo, ingest, calibrate, run, backfill, discover and query are each
    also a Prefect flow (demo and query were CLI-only)."""
    from prefect import Flow

    import pipelines.flows as flows

    names = {f.name for f in vars(flows).values() if isinstance(f, Flow)}
    assert {"demo", "ingest", "calibrate", "run", "backfill", "discover", "query"} <= names


def test_query_flow_returns_what_the_plain_query_returns(tmp_path):
    from pipelines.flows import query_flow
    from pipelines.query import QueryRefused, run_query
    from warehouse.store import open_writer

    root = DataRoot.resolve(tmp_path / "data")
    with open_writer(root) as con:
        con.execute(
            "INSERT INTO runs (run_id, command, code_version, started_at_utc, status) VALUES "
            "('r1', 'demo', 'test', TIMESTAMPTZ '2026-03-02 06:00:00+00', 'succeeded')"
        )
    sql = "select run_id, command, status from runs"
    flowed = query_flow(sql=sql, data=str(root.path))
    assert_frame_equal(flowed, run_query(sql, data=root))
    assert flowed.rows() == [("r1", "demo", "succeeded")]
    with pytest.raises(QueryRefused):  # read-only in a flow too
        query_flow(sql="delete from runs", data=str(root.path))
