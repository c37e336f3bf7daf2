"""HTML reports (issue 18): what a report of a real run holds, checked against the
warehouse, the lake and the hoist description, and what a real browser makes of it.

One short demo day (``ropeload demo`` with 15 minutes of logs) is landed once per module;
the report it wrote is parsed: its figures (the JSON handed to ``Plotly.newPlot``) and
its tables (HTML). A second data root, copied from it, is run again with a hoist model
missing the tail-rope weight, so that the sanity check fails for real.
"""

from __future__ import annotations

import base64
import datetime as dt
import importlib.util
import json
import re
import shutil
import sys
import zoneinfo
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from pipelines.cli import main
from pipelines.demo import run_demo
from pipelines.reports import downsample_minmax
from schemas.hoist import EXAMPLE_HOIST, G_STANDARD, load_hoist
from warehouse.store import DataRoot, open_reader

ZONE = "Asia/Shanghai"
AXIS = "local time (Asia/Shanghai, UTC+08:00)"


# ---------------------------------------------------------------------- downsampling


def _brute_force(t: np.ndarray, y: np.ndarray, buckets: int) -> dict[int, tuple]:
    """Per bucket (same rule, one bucket at a time): min and max value and time."""
    t0, t1 = float(t[0]), float(t[-1])
    width = (t1 - t0) / buckets
    out = {}
    for k in range(buckets):
        low, high = t0 + k * width, t0 + (k + 1) * width
        inside = (t >= low) & ((t < high) if k < buckets - 1 else (t <= t1)) & np.isfinite(y)
        if inside.any():
            idx = np.flatnonzero(inside)
            i_min, i_max = idx[np.argmin(y[idx])], idx[np.argmax(y[idx])]
            out[k] = (y[i_min], t[i_min], y[i_max], t[i_max])
    return out


def test_downsample_keeps_the_global_and_every_bucket_extreme():
    rng = np.random.default_rng(7)
    n = 200_000
    t = np.cumsum(rng.uniform(9_000, 11_000, n)).astype(np.int64)  # jittered 100 Hz in us
    t[120_000:] += 600_000_000  # a 10-minute logger gap
    y = rng.normal(150e3, 500.0, n)
    spikes = rng.choice(n, 40, replace=False)
    y[spikes] += rng.choice([-1, 1], 40) * rng.uniform(5e3, 40e3, 40)  # one-sample peaks
    y[50_000:50_300] = np.nan  # missing values
    buckets = 700
    t_out, y_out = downsample_minmax(t, y, buckets)
    assert len(t_out) <= 3 * buckets
    assert np.all(np.diff(t_out) >= 0)
    assert np.nanmax(y_out) == np.nanmax(y)
    assert np.nanmin(y_out) == np.nanmin(y)
    finite = np.isfinite(y_out)
    kept = set(zip(t_out[finite].tolist(), y_out[finite].tolist(), strict=True))
    truth = _brute_force(t, y, buckets)
    for y_min, t_min, y_max, t_max in truth.values():
        assert (int(t_min), float(y_min)) in kept
        assert (int(t_max), float(y_max)) in kept
    assert len(kept) <= 2 * len(truth)
    # the gap breaks the line: a NaN point strictly inside it, and nothing else there
    breaks = t_out[~np.isfinite(y_out)]
    assert np.any((breaks > t[119_999]) & (breaks < t[120_000]))
    assert not np.any((t_out > t[119_999]) & (t_out < t[120_000]) & np.isfinite(y_out))


@pytest.mark.parametrize("seed", range(60))
def test_downsample_matches_the_brute_force_on_any_series(seed):
    """Random series (seeded: a property test that cannot flake on threads that touch the
    global random state): NaN runs, repeated instants, ties, one sample, all NaN."""
    rng = np.random.default_rng(seed)
    size = 1 if seed % 6 == 2 else int(rng.integers(1, 301))
    y = rng.uniform(-1e6, 1e6, size)
    if seed % 6 == 3:
        y = np.round(y / 2e5)  # ties
    y[rng.random(size) < rng.uniform(0.0, 0.5)] = np.nan
    if seed % 6 == 1:
        y[:] = np.nan
    steps = np.zeros(size, np.int64) if seed % 6 == 0 else rng.integers(0, 51, size)
    buckets = int(rng.integers(1, 41))
    t = np.cumsum(steps)
    t_out, y_out = downsample_minmax(t, y, buckets)
    finite = np.isfinite(y_out)
    kept = set(zip(t_out[finite].tolist(), y_out[finite].tolist(), strict=True))
    truth = _brute_force(t, y, buckets) if t[-1] > t[0] else {}
    if t[-1] == t[0] and np.isfinite(y).any():  # one instant: one bucket
        i_min, i_max = np.nanargmin(y), np.nanargmax(y)
        truth = {0: (y[i_min], t[i_min], y[i_max], t[i_max])}
    assert {(int(a), float(b)) for a, b in kept} == {
        p for v in truth.values() for p in ((int(v[1]), float(v[0])), (int(v[3]), float(v[2])))
    }


def test_downsample_edge_cases():
    times = np.array(["2026-03-02T06:00", "2026-03-02T06:01"], dtype="datetime64[us]")
    t_out, y_out = downsample_minmax(times, np.array([1.0, 2.0]), 10)
    assert t_out.dtype == times.dtype
    assert y_out[0] == 1.0
    assert np.isnan(y_out[1])  # buckets 2-9 are empty: the line breaks after the first
    assert y_out[2] == 2.0
    assert t_out[1] == np.datetime64("2026-03-02T06:00:06", "us")
    t_out, y_out = downsample_minmax(np.arange(3), np.full(3, np.nan), 5)
    assert t_out.size == y_out.size == 0
    with pytest.raises(ValueError, match="ascending"):
        downsample_minmax(np.array([2, 1, 3]), np.ones(3), 2)
    with pytest.raises(ValueError, match="buckets"):
        downsample_minmax(np.arange(3), np.ones(3), 0)


# ------------------------------------------------------------------- parsing a report


def figures_of(html: str) -> list[tuple[list[dict], dict]]:
    """(traces, layout) of every ``Plotly.newPlot`` call after the page head."""
    decoder = json.JSONDecoder()
    body = html[html.index("</head>") :]
    out = []
    for match in re.finditer(r'Plotly\.newPlot\(\s*"[^"]+",\s*', body):
        traces, end = decoder.raw_decode(body, match.end())
        gap = re.match(r"\s*,\s*", body[end:])
        assert gap is not None
        layout, _ = decoder.raw_decode(body, end + gap.end())
        out.append((traces, layout))
    return out


def values(data: object) -> list:
    """A trace's ``x`` or ``y``: a list, or plotly's typed array (``{"dtype", "bdata"}``)."""
    if isinstance(data, dict) and "bdata" in data:
        raw = np.frombuffer(base64.b64decode(data["bdata"]), dtype=np.dtype(data["dtype"]))
        return raw.tolist()
    return list(data or [])


def figure(html: str, title_start: str) -> tuple[list[dict], dict]:
    found = [f for f in figures_of(html) if f[1]["title"]["text"].startswith(title_start)]
    assert len(found) == 1, [f[1]["title"]["text"] for f in figures_of(html)]
    return found[0]


class _Tables(HTMLParser):
    """Tables of a report under the heading (h2-h4) before them: heading -> rows."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self.heading = ""
        self._in_heading = False
        self._row: list[str] | None = None
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag in ("h2", "h3", "h4"):
            self._in_heading, self.heading = True, ""
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("h2", "h3", "h4"):
            self._in_heading = False
        elif tag in ("td", "th") and self._row is not None and self._cell is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.tables.setdefault(self.heading, []).append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._in_heading:
            self.heading += data
        elif self._cell is not None:
            self._cell.append(data)


def tables_of(html: str) -> dict[str, list[list[str]]]:
    parser = _Tables()
    parser.feed(html)
    return parser.tables


def table(html: str, heading_start: str) -> list[dict[str, str]]:
    found = [rows for h, rows in tables_of(html).items() if h.startswith(heading_start)]
    assert len(found) == 1, list(tables_of(html))
    header, *rows = found[0]
    return [dict(zip(header, row, strict=True)) for row in rows]


def _sql(data: DataRoot, query: str) -> pl.DataFrame:
    con = open_reader(data)
    try:
        return con.sql(query).pl()
    finally:
        con.close()


def _local(moment: dt.datetime) -> str:
    return moment.astimezone(zoneinfo.ZoneInfo(ZONE)).strftime("%Y-%m-%d %H:%M:%S")


# ------------------------------------------------------------------------ the demo day


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> tuple[DataRoot, Path, str, str]:
    """A landed 15-minute demo day: data root, report path, its HTML, the run id."""
    data = DataRoot.resolve(tmp_path_factory.mktemp("report-demo"))
    summary = run_demo(data=data, seed=3, hours=0.25)
    match = re.search(r"report: (\S+\.html)", summary)
    assert match, summary
    path = Path(match.group(1))
    run_id = re.search(r"run (demo-\S+)", summary).group(1)
    return data, path, path.read_text(encoding="utf-8"), run_id


def test_demo_writes_one_self_contained_report_under_the_data_root(demo):
    data, path, html, run_id = demo
    assert path.parent == data.path / "reports"
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]
    assert path.name.startswith(run_id)
    assert '<script src="http' not in html.lower()
    assert not re.search(r"""<(script|link|img)[^>]+(src|href)=["']?(https?:)?//""", html)
    from plotly.offline import get_plotlyjs

    assert get_plotlyjs()[:2000] in html  # the library itself is inlined
    assert len(figures_of(html)) >= 6


def test_every_time_axis_is_in_the_hoists_local_time_and_says_so(demo):
    data, _, html, run_id = demo
    (start,) = _sql(data, f"SELECT period_start_utc FROM runs WHERE run_id = '{run_id}'")[
        "period_start_utc"
    ]
    local_start = _local(start)[:16].replace(" ", "T")  # 22:00 UTC is 06:00 in Shanghai
    assert local_start.endswith("T06:00")
    time_axes = 0
    for traces, layout in figures_of(html):
        for trace in traces:
            xs = [x for x in values(trace.get("x")) if isinstance(x, str)]
            if not xs or not re.match(r"\d{4}-\d\d-\d\dT", xs[0]):
                continue
            time_axes += 1
            assert min(xs) >= local_start, layout["title"]["text"]
            key = "xaxis" + trace.get("xaxis", "x")[1:]
            titled = [
                v["title"]["text"]
                for k, v in layout.items()
                if k.startswith("xaxis") and "title" in v and "text" in v["title"]
            ]
            assert AXIS in titled, (layout["title"]["text"], key, titled)
    assert time_axes >= 10
    assert "[UTC]" not in html


def test_ropes_figure_draws_the_imbalance_slack_and_tight_limits(demo):
    hoist = load_hoist(EXAMPLE_HOIST)
    per_rope = G_STANDARD / 4
    slack_kn = 0.60 * hoist.conveyance.mass_kg * per_rope / 1e3
    tail_kg = 2 * 6.2 * (620.0 + 0.0)  # two 6.2 kg/m tail ropes below the cage at the pithead
    static_kn = hoist.conveyance.mass_kg + hoist.conveyance.rated_payload_kg + tail_kg
    tight_kn = static_kn * per_rope / 1e3 + 0.10 * 900.0
    traces, _ = figure(demo[2], "Rope tensions against the limits")

    def limit(name: str) -> list[float]:
        return sorted(
            values(t["y"])[0] for t in traces if t.get("legendgroup", "").startswith(name)
        )

    assert limit("imbalance limit") == [-10.0, 10.0]
    assert limit("slack rope") == [pytest.approx(slack_kn, rel=1e-9)]
    assert limit("tight rope") == [pytest.approx(tight_kn, rel=1e-9)]
    # the four ropes are drawn as deviations from their mean, in per cent
    ropes = [t for t in traces if t.get("name", "").startswith("rope ")]
    assert sorted(t["name"] for t in ropes) == ["rope 1", "rope 2", "rope 3", "rope 4"]
    # and the load figure's error panel has the +-3 % reconciliation tolerance
    load_traces, _ = figure(demo[2], "Load on the four ropes")
    tolerance = [
        values(t["y"])[0] for t in load_traces if t.get("legendgroup", "").startswith("tolerance")
    ]
    assert sorted(tolerance) == [-3.0, 3.0]


def test_alarms_are_a_table_with_rope_start_end_peak_and_a_timeline(demo):
    data, _, html, run_id = demo
    alarms = _sql(data, f"SELECT * FROM alarms WHERE run_id = '{run_id}' ORDER BY start_utc")
    assert alarms.height >= 1
    rows = table(html, "Alarms (")
    tz = "Asia/Shanghai, UTC+08:00"
    assert list(rows[0])[:6] == [
        "rule", "rope", f"start ({tz})", f"end ({tz})", "duration [s]", "peak",
    ]  # fmt: skip
    assert len(rows) == alarms.height
    for row, alarm in zip(rows, alarms.iter_rows(named=True), strict=True):
        assert row["rule"] == alarm["rule"]
        assert row["rope"] == ("hoist" if alarm["rope"] is None else str(alarm["rope"]))
        assert row[f"start ({tz})"] == _local(alarm["start_utc"])
        assert row[f"end ({tz})"] == _local(alarm["end_utc"])
        assert row["peak at"] == _local(alarm["peak_time_utc"])[11:]
        assert row["peak"].split()[0] in (
            f"{alarm['peak_value']:.2f}",
            f"{alarm['peak_value']:.3f}",
        )
    traces, layout = figure(html, "Alarms by rope")
    peaks = [x for t in traces if t.get("mode") == "markers" for x in values(t["x"])]
    assert sorted(p[:19] for p in peaks) == sorted(
        _local(a).replace(" ", "T") for a in alarms["peak_time_utc"]
    )
    assert layout["yaxis"]["categoryarray"] == ["hoist", "rope 4", "rope 3", "rope 2", "rope 1"]


def test_reconciliation_has_a_tolerance_line_per_position_and_drops_short_stints(demo):
    data, _, html, run_id = demo
    visits = _sql(data, f"SELECT * FROM position_summary WHERE run_id = '{run_id}'")
    plotted = visits.filter((pl.col("samples") >= 5) & pl.col("expected_load_n").is_not_null())
    short = visits.filter((pl.col("samples") < 5) & pl.col("expected_load_n").is_not_null())
    assert short.height >= 1  # the demo day passes a window's edge: there is one to drop
    traces, layout = figure(html, "Load minus expected load per position visit")
    names = ("pithead", "middle", "bottom")
    positions = [a["text"] for a in layout["annotations"] if a["text"] in names]
    assert positions == ["pithead", "middle", "bottom"]  # by depth
    axes = {t.get("xaxis", "x") for t in traces}
    assert len(axes) == 3
    for axis in axes:
        limits = sorted(
            values(t["y"])[0]
            for t in traces
            if t.get("xaxis", "x") == axis and t.get("legendgroup") == "tolerance"
        )
        assert limits == [-3.0, 3.0], axis
    after = [t for t in traces if t.get("name") == "after compensation"]
    assert sum(len(values(t["y"])) for t in after) == plotted.height
    rows = {r["position"]: r for r in table(html, "Reconciliation per position")}
    for position, part in plotted.group_by("position"):
        worst_after = part["error_after_fraction"].abs().max() * 100
        assert rows[position[0]]["worst after"] == f"{worst_after:.2f} %"
        assert rows[position[0]]["visits"] == str(part.height)


def test_trips_table_names_the_worst_rope_from_the_samples(demo):
    data, _, html, run_id = demo
    trips = _sql(data, f"SELECT * FROM trip_summary WHERE run_id = '{run_id}' ORDER BY trip_id")
    samples = pl.scan_parquet(str(data.table_dir("rope_tensions") / "**" / "*.parquet")).collect()
    mean = pl.mean_horizontal([pl.col(f"tension{i}_n") for i in range(1, 5)])
    worst = (
        samples.filter(pl.col("trip_id").is_not_null())
        .group_by("trip_id")
        .agg(
            ((pl.col(f"tension{i}_n") - mean).abs() / mean).max().alias(str(i))
            for i in range(1, 5)
        )
        .sort("trip_id")
    )  # fmt: skip
    rows = table(html, "Trips (")
    assert [r["trip"] for r in rows] == [str(t) for t in trips["trip_id"]]
    truths = zip(worst.iter_rows(named=True), trips.iter_rows(named=True), strict=True)
    for row, (truth, trip) in zip(rows, truths, strict=True):
        by_rope = {int(k): v for k, v in truth.items() if k != "trip_id"}
        rope = max(by_rope, key=by_rope.get)
        assert row["rope"] == str(rope)
        assert row["worst imbalance"] == f"{by_rope[rope] * 100:.2f} %"
        assert row["direction"] == trip["direction"]
        assert row["payload [kg]"] == f"{trip['payload_kg']:.0f}"


def test_demo_report_says_how_the_sanity_check_and_discovery_went(demo):
    data, _, html, run_id = demo
    checks = _sql(data, f"SELECT * FROM sanity_checks WHERE run_id = '{run_id}'")
    compared = checks.filter(pl.col("status") != "skipped")
    assert compared.height >= 1
    passed = int(compared["passed"].sum())
    assert f"Sanity check: {passed} of {compared.height} trips passed" in html
    # the record's first trip only warms the replay up: skipped, with its row and reason
    skipped = checks.filter(pl.col("status") == "skipped")
    assert skipped.height == checks.height - compared.height >= 1
    assert f"{skipped.height} skipped (reasons in sanity_checks)" in html
    assert "Discovery: skipped: not needed: no trip failed the sanity check." in html


def test_load_figure_draws_the_landed_95_percent_band(demo):
    """The band (issue 13) lands beside the values, holds them and is drawn."""
    data, _, html, _ = demo
    outside = _sql(
        data,
        "SELECT count(*) AS n, count(load_after_lo_n) AS with_band FROM rope_tensions "
        "WHERE NOT (load_after_lo_n <= load_after_n AND load_after_n <= load_after_hi_n "
        "AND tension_after1_lo_n <= tension_after1_n "
        "AND tension_after1_n <= tension_after1_hi_n)",
    )
    assert outside["n"][0] == 0
    assert _sql(data, "SELECT count(load_after_lo_n) AS n FROM rope_tensions")["n"][0] > 0
    assert "95 % band (after)" in html
    assert "no uncertainty band yet" not in html.lower()


# ----------------------------------------------------------- a failing sanity check


@pytest.fixture(scope="module")
def no_tail_rope(demo, tmp_path_factory) -> tuple[DataRoot, Path]:
    """A copy of the demo's data root and a hoist model without the tail-rope weight."""
    root = tmp_path_factory.mktemp("report-no-tail")
    shutil.copytree(demo[0].path / "lake", root / "lake")
    shutil.copy2(demo[0].warehouse, root / "warehouse.duckdb")
    text = EXAMPLE_HOIST.read_text(encoding="utf-8")
    hoist = root / "no_tail_rope.toml"
    hoist.write_text(text.replace('    "tail_rope_weight",\n', ""), encoding="utf-8")
    assert "tail_rope_weight" not in load_hoist(hoist).model.effects
    return DataRoot.resolve(root), hoist


def test_a_run_whose_sanity_check_fails_still_writes_its_report(no_tail_rope, capsys):
    data, hoist = no_tail_rope
    assert main(["run", "--data", str(data.path), "--hoist", str(hoist)]) == 0
    out = capsys.readouterr().out
    path = Path(re.search(r"report: (\S+\.html)", out).group(1))
    html = path.read_text(encoding="utf-8")
    run_id = re.search(r"run (run-\S+):", out).group(1)
    checks = _sql(data, f"SELECT * FROM sanity_checks WHERE run_id = '{run_id}' ORDER BY trip_id")
    compared = checks.filter(pl.col("status") != "skipped")
    failed = int((~compared["passed"]).sum())
    assert failed >= 1
    words = f"{compared.height - failed} of {compared.height} trips passed, {failed} failed"
    assert words in out
    assert words in html
    assert [r["check"] for r in table(html, "Sanity check")] == [
        "FAILED" if s == "failed" else s for s in checks["status"]
    ]
    traces, _ = figure(html, "Measured minus simulated sensor pressure, RMS per trip")
    assert any(t.get("name") == "trip failed" for t in traces)


def test_a_sanity_check_that_errors_is_said_in_the_report(demo, tmp_path):
    from pipelines.lake import scan_lake
    from pipelines.reports import run_report, sanity_step
    from pipelines.run_period import RunResult

    data, _, _, run_id = demo
    run = _sql(data, f"SELECT * FROM runs WHERE run_id = '{run_id}'").row(0, named=True)
    frame = scan_lake(data, "rope_tensions", site=run["site"], hoist=run["hoist"]).collect()
    result = RunResult(
        run_id=run_id, site=run["site"], hoist=run["hoist"],
        period_start_utc=run["period_start_utc"], period_end_utc=run["period_end_utc"],
        samples=frame.height, rope_tensions=frame, position_summary=pl.DataFrame(),
        trip_summary=pl.DataFrame(), alarms=pl.DataFrame(), inputs=(),
    )  # fmt: skip
    error = RuntimeError("the replay diverged at trip 1")
    report = run_report(
        data, result, hoist=load_hoist(EXAMPLE_HOIST), steps=[sanity_step(None, error=error)]
    )
    path = report.write(tmp_path)
    html = path.read_text(encoding="utf-8")
    assert html.count("Sanity check: FAILED: RuntimeError: the replay diverged at trip 1.") == 2
    assert "class='fail'" in html
    assert len(figures_of(html)) >= 5  # everything else is still drawn


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning:scipy")
def test_discovery_findings_are_drawn_before_and_after_with_titles_in_words(no_tail_rope, capsys):
    """Discovery (about 15 s) names the missing tail-rope weight; the next report draws
    the per-regime gap and the worst trip's residual, before and after adding it."""
    from pipelines.discover import discover_period

    data, hoist = no_tail_rope
    run = _sql(data, "SELECT * FROM runs WHERE command = 'demo'").row(0, named=True)
    day = run["period_start_utc"].astimezone(dt.UTC).date()
    target = data.under("reports", "discovery", f"{run['site']}_{run['hoist']}_{day}.json")
    found = discover_period(hoist_path=hoist, data=data, json_path=target, max_iterations=1)
    assert found.report["effect"] == "tail_rope_weight"
    assert main(["run", "--data", str(data.path), "--hoist", str(hoist)]) == 0
    html = Path(re.search(r"report: (\S+\.html)", capsys.readouterr().out).group(1)).read_text()
    titles = [layout["title"]["text"] for _, layout in figures_of(html)]
    trace = found.report["residual_trace"]
    assert (
        f"Measured minus simulated pressure, sensor {trace['sensor']}, trip {trace['trip_id']} "
        f"({trace['direction']}), before and after adding tail_rope_weight"
    ) in titles
    assert any(
        t.startswith("Measured minus simulated pressure per regime")
        and t.endswith("before and after adding tail_rope_weight")
        for t in titles
    )
    rows = table(html, "Discovery")
    assert rows[0]["effect"] == "tail_rope_weight"
    assert rows[0]["gap before [kPa]"] == f"{found.report['gap_before_pa'] / 1e3:.2f}"


# ---------------------------------------------------------------- a real browser


def _screenshot_module():
    path = Path(__file__).resolve().parents[2] / "scripts" / "screenshot_report.py"
    spec = importlib.util.spec_from_file_location("screenshot_report", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_the_report_draws_every_figure_in_headless_chromium_without_network(demo):
    shot = _screenshot_module()
    if shot.find_chromium() is None:
        pytest.skip(
            "no chromium on PATH (Debian: apt-get install chromium; make test installs it as root)"
        )
    _, path, html, _ = demo
    rendering = shot.render(path, width=1400, settle_s=0.5)
    assert rendering.plotly_loaded
    assert rendering.figures == len(figures_of(html))
    assert rendering.drawn == rendering.with_data == rendering.figures
    assert rendering.external_requests == []
    assert rendering.png[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = (int.from_bytes(rendering.png[k : k + 4], "big") for k in (16, 20))
    assert (width, height) == (1400, rendering.height)
    assert height > 2500
    assert len(rendering.png) > 100_000  # drawn lines and tables, not a blank page


def test_two_fleet_reports_started_in_the_same_second_do_not_share_a_file(tmp_path):
    """Two nightlies (or backfills) started in the same second: two report files (was:
    the second overwrote the first, both named by the second)."""
    from pipelines.reports.fleet import fleet_report

    data = DataRoot.resolve(tmp_path / "data")
    stamp = dt.datetime(2026, 3, 3, 2, 0, tzinfo=dt.UTC)
    names = {
        fleet_report(
            data, kind="nightly", outcomes=[], sources=[], sanity=False, stamp=stamp
        ).file_name
        for _ in range(2)
    }
    assert len(names) == 2
    assert all(n.startswith("nightly-20260303T020000Z-") for n in names)
