"""The evaluation's helpers on windows with known ropes (benchmarks/eval_compensation.py)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from schemas.hoist import EXAMPLE_HOIST, load_hoist


@pytest.fixture(scope="module")
def evaluation(benchmark_script):
    with benchmark_script("eval_compensation") as module:
        yield module


def test_truth_ropes_recovers_the_constants_the_windows_obey(evaluation) -> None:
    """Windows built from T_i = a_i k (s - x_i - c_i) at three depths, rope 1 the
    gauge (a = 1, c = 0), give back every rope's a and c, with no misfit."""
    hoist = load_hoist(EXAMPLE_HOIST)
    a = np.array([1.0, 1.04, 1.01, 0.99])
    c = np.array([0.0, -0.004, 0.007, 0.001])
    rng = np.random.default_rng(3)
    t0 = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    windows = []
    for depth in (0.0, 300.0, 600.0) * 3:
        k = hoist.ropes.head_rope_axial_stiffness_n / (hoist.shaft.headframe_height_m + depth)
        x = rng.uniform(-3e-3, 3e-3, 4)
        s = 0.05 + rng.uniform(0.0, 0.01)
        tension = a * k * (s - x - c)
        windows.append(evaluation.Window("arrival", "p", t0, t0, float(tension.sum()),
                                         tuple(tension), depth, tuple(x)))  # fmt: skip
    found = evaluation.truth_ropes(windows, hoist)
    assert found is not None
    a_found, c_found, rms = found
    np.testing.assert_allclose(a_found, a, rtol=1e-9)
    np.testing.assert_allclose(c_found, c, atol=1e-9)
    assert rms < 1e-6


def test_truth_ropes_needs_piston_positions(evaluation) -> None:
    hoist = load_hoist(EXAMPLE_HOIST)
    t0 = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    windows = [evaluation.Window("arrival", "p", t0, t0, 4.0, (1.0,) * 4)] * 5
    assert evaluation.truth_ropes(windows, hoist) is None


def test_window_errors_splits_out_the_seals_friction(evaluation) -> None:
    """A landed second of constant values against a window's truth: the load's and each
    seal's error come out as the differences, and the summed friction error per position."""
    t0 = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    times = [t0 + dt.timedelta(milliseconds=20 * k) for k in range(50)]
    columns = {"time_utc": times, "load_raw_n": [990.0] * 50, "load_n": [1010.0] * 50}
    for i in range(1, 5):
        columns[f"tension{i}_n"] = [250.0 + i] * 50
        columns[f"friction{i}_n"] = [10.0 * i] * 50
    tensions = pl.DataFrame(columns)
    window = evaluation.Window(
        "arrival", "pithead", t0, t0 + dt.timedelta(seconds=1), 1000.0, (250.0,) * 4,
        true_friction_n=(5.0, 20.0, 35.0, 40.0),
    )  # fmt: skip
    errors = evaluation.window_errors(tensions, [window])
    row = errors.row(0, named=True)
    assert row["before_pct"] == pytest.approx(-1.0)
    assert row["after_pct"] == pytest.approx(1.0)
    assert [row[f"friction{i}_error_n"] for i in range(1, 5)] == pytest.approx([5, 0, -5, 0])
    no_truth = evaluation.window_errors(
        tensions,
        [
            evaluation.Window(
                "arrival", "pithead", t0, t0 + dt.timedelta(seconds=1), 1000.0, (250.0,) * 4
            )
        ],
    )
    assert "friction1_error_n" not in no_truth.columns


def test_report_friction_prints_the_rms_of_the_sum_and_per_piston(evaluation, capsys) -> None:
    """Two pithead windows with errors (30, 10, 0, 0) and (-10, -10, 0, 0) N: summed
    40 and -20 (RMS 31.6 N), per piston RMS ((900 + 100 + 100 + 100) / 8)^(1/2) = 12.2 N; a
    window without the truth's friction is left out."""
    errors = pl.DataFrame(
        {
            "position": ["pithead", "pithead", "pithead"],
            "friction1_error_n": [30.0, -10.0, None],
            "friction2_error_n": [10.0, -10.0, None],
            "friction3_error_n": [0.0, 0.0, None],
            "friction4_error_n": [0.0, 0.0, None],
        }
    )
    evaluation.report_friction(errors)
    line = capsys.readouterr().out.splitlines()[-1]
    assert "2 windows" in line
    assert f"summed {np.sqrt((40**2 + 20**2) / 2):>5.0f} N" in line
    assert f"per piston {np.sqrt(1200 / 8):>5.0f} N" in line


def test_report_ropes_prints_the_offsets_part_at_the_pithead(evaluation, capsys) -> None:
    """Rope 2 identified 0.1 mm shorter than the truth's: its tension at the pithead is
    a k (0.1 mm) higher, printed with a plus sign."""
    hoist = load_hoist(EXAMPLE_HOIST)
    ropes = evaluation.RopeSprings((1.0, 1.05, 1.0, 1.0), (0.0, 0.0019, 0.0, 0.0), 0.0, 0)
    implied = ((1.0, 1.05, 1.0, 1.0), (0.0, 0.002, 0.0, 0.0), 20.0)
    evaluation.report_ropes(ropes, implied, hoist)
    rope2 = capsys.readouterr().out.splitlines()[1]
    k = hoist.ropes.head_rope_axial_stiffness_n / hoist.shaft.headframe_height_m
    assert f"({-0.1:+.3f} mm: {1.05 * k * 1e-4:+.0f} N at the pithead from dc)" in rope2


def test_a_variant_of_a_day_keeps_its_truth_and_its_own_file(evaluation, tmp_path) -> None:
    """``as_variant(case, "no-x")`` is the day without x1..x4 beside the day's own CSV,
    named for its variant, with the day's windows; no variant is the day itself."""
    rows = [
        ["timestamp", "p1", "p2", "p3", "p4", "x1", "x2", "x3", "x4", "depth", "speed"],
        ["2026-02-10 06:00:00.000", "4.9", "4.8", "4.7", "4.6", "1.2", "-3", "0", "7", "0", "0"],
    ]
    csv = tmp_path / "day.csv"
    csv.write_text("# site: s\n" + "\n".join(",".join(r) for r in rows) + "\n")
    t0 = dt.datetime(2026, 2, 10, tzinfo=dt.UTC)
    windows = [evaluation.Window("arrival", "p", t0, t0, 1.0, (0.25,) * 4)]
    case = evaluation.DayCase("day", csv, tmp_path / "h.toml", windows)
    out = evaluation.as_variant(case, "no-x")
    assert out.name == "day [no-x]"
    assert out.windows == windows
    assert out.csv != csv
    assert out.csv.read_text().splitlines()[1].split(",") == [
        "timestamp", "p1", "p2", "p3", "p4", "depth", "speed",
    ]  # fmt: skip
    assert csv.read_text().count("x1") == 1  # the day's own file as it was
    assert evaluation.as_variant(case, "") is case


def test_a_paused_variant_moves_the_truth_after_the_pause(evaluation, tmp_path) -> None:
    """``as_variant(case, "pause-10min")``: the truth's windows from the row the logger
    resumes with on (its local time in the file's zone) are 600 s later, the earlier
    ones as they were, and one the pause falls in ends 600 s later (a review: the
    windows holding the pause had kept their rows before it only)."""
    names = ["timestamp", "p1", "p2", "p3", "p4", "depth", "speed"]
    lines = ["# timezone: Asia/Shanghai", "# sample_rate_hz: 1", ",".join(names)]
    for k in range(100):
        speed = "0.000" if 60 <= k < 80 else "1.000"
        lines.append(f"2026-02-10 14:{k // 60:02d}:{k % 60:02d}.000,4.9,4.9,4.9,4.9,0,{speed}")
    csv = tmp_path / "day.csv"
    csv.write_text("\n".join(lines) + "\n")
    # 14:01:05 local (UTC+8) is 06:01:05 UTC: the row the logger resumes with
    at = dt.datetime(2026, 2, 10, 6, 1, 5, tzinfo=dt.UTC)
    second = dt.timedelta(seconds=1)
    spans = [(at - second, at), (at, at + second), (at - second, at + second)]
    windows = [evaluation.Window("arrival", "p", a, b, 1.0, (0.25,) * 4) for a, b in spans]
    out = evaluation.as_variant(evaluation.DayCase("day", csv, tmp_path / "h.toml", windows),
                                "pause-10min")  # fmt: skip
    later = dt.timedelta(seconds=600)
    assert out.windows[0] == windows[0]  # ends where the logger resumes: before the pause
    assert (out.windows[1].t0, out.windows[1].t1) == (at + later, at + second + later)
    # one the pause falls in spans it: its rows before the pause and after it
    assert (out.windows[2].t0, out.windows[2].t1) == (at - second, at + second + later)


def test_report_day_prints_the_margin_to_the_worse_than_raw_limit(evaluation, capsys) -> None:
    """Three windows: |after| - |before| = -1.5, +0.15 and +0.05 pp. None is worse than
    raw by more than 0.2 pp, but the largest excess, +0.15 pp, is printed with the one
    window above half the limit (0.1 pp): a day one window away from failing says so."""
    t0 = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    errors = pl.DataFrame(
        {
            "kind": ["arrival"] * 3,
            "position": ["pithead", "middle", "bottom"],
            "t0": [t0] * 3,
            "before_pct": [2.0, -0.05, 0.30],
            "after_pct": [0.5, 0.20, -0.35],
            "rope_max_pct": [0.6, 0.3, 0.4],
        }
    )
    figures = evaluation.report_day("hand-made", errors, 3, 0.0)
    out = capsys.readouterr().out
    assert figures["worse"] == 0
    assert figures["excess"] == pytest.approx(0.15)
    assert "the largest |after| - |before| +0.150 pp (limit 0.2); windows above half" in out
    assert "half the limit: 1" in out


def test_a_day_in_parts_keeps_every_row_once_and_the_windows_inside_each(
    evaluation, tmp_path
) -> None:
    """Ten rows a second apart, logged in Asia/Shanghai (UTC+8) with `;` between fields,
    cut in two: five rows each, the header on both, and each part keeps the windows
    whole inside its UTC span (the window across the cut is in neither)."""
    header = ["# site: s\n", "# timezone: Asia/Shanghai\n", "timestamp;p1\n"]
    rows = [f"2026-02-12 06:00:0{i}.000;49,5\n" for i in range(10)]
    csv = tmp_path / "day.csv"
    csv.write_text("".join(header + rows))
    utc = dt.datetime(2026, 2, 11, 22, 0, 0, tzinfo=dt.UTC)  # 06:00 local

    def window(a: float, b: float):
        return evaluation.Window(
            "arrival", "p", utc + dt.timedelta(seconds=a), utc + dt.timedelta(seconds=b),
            1.0, (0.25,) * 4,
        )  # fmt: skip

    inside_first, across, inside_second = window(0.5, 3.5), window(3.5, 6.5), window(6, 9)
    case = evaluation.DayCase("d", csv, tmp_path / "h.toml", [inside_first, across, inside_second])
    first, second = evaluation.in_parts(case, 2)
    assert first.windows == [inside_first]
    assert second.windows == [inside_second]
    texts = [part.csv.read_text().splitlines(keepends=True) for part in (first, second)]
    assert [t[:3] for t in texts] == [header, header]
    assert texts[0][3:] + texts[1][3:] == rows
    assert evaluation.in_parts(case, 1) == [case]


def test_a_day_in_parts_is_consecutive_exports_with_the_windows_inside_each(
    evaluation, tmp_path: Path
) -> None:
    """Seven rows of a ';' file in local time (UTC+8) cut in three: 2, 2 and 3 rows in
    order, each part with the file's header lines, and each truth window in the part
    that holds it whole (one across a cut is in none)."""
    header = "# site: s\n# timezone: Asia/Shanghai\ntimestamp;p1;depth\n"
    rows = [f"2026-03-02 08:00:0{k}.000;49,5{k};0,00\n" for k in range(7)]
    csv = tmp_path / "day.csv"
    csv.write_text(header + "".join(rows))

    def window(a: int, b: int):
        t = dt.datetime(2026, 3, 2, 0, 0, tzinfo=dt.UTC)
        s = dt.timedelta(seconds=1)
        return evaluation.Window("arrival", "pithead", t + a * s, t + b * s, 1.0, (1.0,))

    inside_first, across, inside_last = window(0, 1), window(1, 3), window(4, 6)
    case = evaluation.DayCase("d", csv, tmp_path / "h.toml", [inside_first, across, inside_last])
    parts = evaluation.in_parts(case, 3)
    assert [p.name for p in parts] == ["d part 1/3", "d part 2/3", "d part 3/3"]
    texts = [p.csv.read_text() for p in parts]
    assert all(t.startswith(header) for t in texts)
    assert "".join(t[len(header) :] for t in texts) == "".join(rows)
    assert [t.count("\n") - 3 for t in texts] == [2, 2, 3]
    assert [p.windows for p in parts] == [[inside_first], [], [inside_last]]
    assert evaluation.in_parts(case, 1) == [case]
    with pytest.raises(ValueError, match="7 rows cannot be cut into 8 parts"):
        evaluation.in_parts(case, 8)
