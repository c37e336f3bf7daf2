"""A logger clock that steps back mid-file: the repeated stretch is quarantined with a
reason naming the step (or counted as exact duplicates), never landed interleaved with
the first pass; rows swapped by jitter still land, sorted. Batches and resumes of a
growing file carry the state (:mod:`pipelines.ingest.clock`)."""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest

from pipelines.ingest import ingest_paths
from pipelines.ingest.clock import clock_step_reason
from warehouse.store import open_reader, open_writer

START = dt.datetime(2026, 3, 2, 6, 0, 0)
HZ = 50
FIRST_LINE = 7  # 5 header lines and the column line


def _times(seconds: float, step_back_at: float, step_s: float, seed: int = 1) -> list[dt.datetime]:
    """A 50 Hz logger's times (+-1 ms jitter) for ``seconds``; from ``step_back_at`` on
    its clock reads ``step_s`` less (0: no step)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(int(seconds * HZ)):
        t = i / HZ + rng.integers(-1, 2) / 1000
        if i / HZ >= step_back_at:
            t -= step_s
        out.append(START + dt.timedelta(seconds=t))
    return out


def _rows(corpus, times: list[dt.datetime]) -> list[list[str]]:
    rows = corpus.data_rows(len(times))  # depth i * 0.5 m: each row's values its own
    for row, t in zip(rows, times, strict=True):
        row[0] = t.strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]
    return rows


def _header(corpus) -> dict[str, str]:
    return {**corpus.HEADER, "sample_rate_hz": str(HZ)}


def _expected_step(times: list[dt.datetime]) -> tuple[int, float, list[int]]:
    """The step's first line, its size and the lines of its stretch, by the rule: from
    the first time more than 0.2 s before the latest read, until one passes that."""
    latest = before = None
    onset = None
    stretch: list[int] = []
    for k, t in enumerate(times):
        if onset is None and latest is not None and t < latest - dt.timedelta(seconds=0.2):
            onset, before = (FIRST_LINE + k, (latest - t).total_seconds()), latest
        if onset is not None and before is not None:
            if t > before:
                break
            stretch.append(FIRST_LINE + k)
        latest = t if latest is None else max(latest, t)
    assert onset is not None
    return onset[0], onset[1], stretch


def _lake(root) -> pl.DataFrame:
    files = sorted(root.table_dir("field_samples").rglob("*.parquet"))
    return pl.read_parquet(files, hive_partitioning=False).sort("time_utc")


def _quarantine(root) -> list[tuple[int, str]]:
    with open_reader(root) as con:
        return con.sql("SELECT line, reason FROM quarantine ORDER BY line").fetchall()


def _check_not_merged(root, stretch: list[int]) -> None:
    """The lake holds one stream: its lines rise with its times, none of the stretch."""
    lake = _lake(root)
    assert lake["source_line"].is_sorted()
    assert not set(stretch) & set(lake["source_line"].to_list())


@pytest.mark.parametrize("step_s", [30.0, 2.0])
def test_a_clock_step_back_is_quarantined_not_merged(corpus, tmp_path, root, step_s):
    times = _times(90, 45, step_s)
    path = corpus.csv_file(tmp_path / "step.csv", _rows(corpus, times), header=_header(corpus))
    report = ingest_paths([path], data=root)
    result = report.files[0]
    line, size, stretch = _expected_step(times)
    assert abs(size - (step_s - 1 / HZ)) <= 0.003  # before the last time read
    assert len(stretch) == pytest.approx(step_s * HZ, abs=2)
    reason = clock_step_reason("line", line, size)
    assert f"stepped back {step_s:.1f} s at line {line}" in reason
    assert result.status == "landed"
    assert result.balanced
    assert result.rows_read == len(times)
    assert (result.rows_quarantined, result.rows_duplicate) == (len(stretch), 0)
    assert result.rows_landed == len(times) - len(stretch)
    assert result.quarantined_by_reason == {reason: len(stretch)}
    assert "the logger clock stepped back 1 time(s)" in result.message
    assert _quarantine(root) == [(k, reason) for k in stretch]
    _check_not_merged(root, stretch)
    assert _lake(root).height == result.rows_landed


def test_rows_swapped_by_jitter_still_land_sorted(corpus, tmp_path, root):
    times = _times(10, 99, 0)
    for k in (10, 100, 250):  # neighbours swapped
        times[k], times[k + 1] = times[k + 1], times[k]
    times[300], times[304] = times[304], times[300]  # 80 ms out of order
    path = corpus.csv_file(tmp_path / "swap.csv", _rows(corpus, times), header=_header(corpus))
    result = ingest_paths([path], data=root).files[0]
    assert (result.status, result.rows_landed, result.rows_quarantined) == ("landed", 500, 0)
    lake = _lake(root)
    assert lake["time_utc"].is_sorted()
    assert lake["time_utc"].to_list() == sorted(t.replace(tzinfo=dt.UTC) for t in times)


def test_a_step_across_batch_boundaries_is_the_same(corpus, tmp_path, root):
    """Batches of ~2 KB (a few dozen lines): the step begins in one batch and its
    stretch runs over many; the outcome is that of one batch."""
    times = _times(20, 10, 3.0)
    path = corpus.csv_file(tmp_path / "step.csv", _rows(corpus, times), header=_header(corpus))
    one = ingest_paths([path], data=root).files[0]
    small_root = type(root).resolve(tmp_path / "small")
    many = ingest_paths([path], data=small_root, batch_bytes=2048).files[0]
    counts = ("rows_read", "rows_landed", "rows_quarantined", "rows_duplicate")
    assert [getattr(many, k) for k in counts] == [getattr(one, k) for k in counts]
    assert many.quarantined_by_reason == one.quarantined_by_reason
    assert one.rows_quarantined == pytest.approx(3.0 * HZ, abs=2)
    assert _quarantine(small_root) == _quarantine(root)
    assert _lake(small_root)["source_line"].to_list() == _lake(root)["source_line"].to_list()


@pytest.mark.parametrize(
    ("step_s", "step_at_s", "cut_at_s"),
    [
        (4.0, 10.0, 9.0),  # the earlier version ends before the step: its latest time carries over
        (4.0, 10.0, 12.0),  # ... inside the step's stretch: the step goes on, by its first line
        (4.0, 10.0, 13.9),  # ... inside it, within 0.2 s of the latest time read before the step
        (30.0, 20.0, 45.0),  # ... 25 s into it: more than the 64 KB tail (the manifest's state)
    ],
)
def test_a_growing_file_resumed_inside_a_step(corpus, tmp_path, root, step_s, step_at_s, cut_at_s):
    times = _times(step_at_s + 2 * step_s, step_at_s, step_s)
    rows = _rows(corpus, times)
    full = corpus.csv_file(tmp_path / "full.csv", rows, header=_header(corpus)).read_bytes()
    line, size, stretch = _expected_step(times)
    reason = clock_step_reason("line", line, size)
    cut_row = int(cut_at_s * HZ)
    cut = full.index(rows[cut_row][0].encode())
    live = tmp_path / "live.csv"
    live.write_bytes(full[: cut + 10])  # the last line cut off: partial
    first = ingest_paths([live], data=root).files[0]
    assert first.status == "partial"
    with open_reader(root) as con:
        step_line, latest = con.sql(
            "SELECT clock_step_line, clock_latest_utc FROM manifest"
        ).fetchall()[0]
    assert step_line == (line if FIRST_LINE + cut_row > line else None)
    assert latest is not None
    live.write_bytes(full)
    second = ingest_paths([live], data=root).files[0]
    assert second.status == "landed"
    assert "resumed at byte" in second.message
    assert second.balanced
    assert first.balanced
    assert first.rows_read + second.rows_read == len(times)
    assert first.rows_quarantined + second.rows_quarantined == len(stretch)
    assert first.rows_duplicate + second.rows_duplicate == 0
    assert _quarantine(root) == [(k, reason) for k in stretch]
    _check_not_merged(root, stretch)
    assert _lake(root).height == len(times) - len(stretch)


def test_a_resume_without_the_clock_in_the_manifest_reads_the_tail(corpus, tmp_path, root):
    """A version ingested before the manifest kept the clock (its columns null): the
    resume takes the state from the last 64 KB of what that version held."""
    times = _times(20, 10, 4.0)
    rows = _rows(corpus, times)
    full = corpus.csv_file(tmp_path / "full.csv", rows, header=_header(corpus)).read_bytes()
    _, _, stretch = _expected_step(times)
    cut = full.index(rows[12 * HZ][0].encode())
    live = tmp_path / "live.csv"
    live.write_bytes(full[:cut])
    assert ingest_paths([live], data=root).files[0].status == "landed"
    with open_writer(root) as con:
        con.execute(
            "UPDATE manifest SET clock_latest_utc = NULL, clock_step_line = NULL, "
            "clock_step_s = NULL"
        )
    live.write_bytes(full)
    second = ingest_paths([live], data=root).files[0]
    assert "resumed at byte" in second.message
    assert len(_quarantine(root)) == len(stretch)
    _check_not_merged(root, stretch)


def test_a_stretch_written_again_unchanged_is_counted_as_duplicates(corpus, tmp_path, root):
    """A logger that writes its last 2 s again, the same rows: exact duplicates (the
    rows equal to landed samples), not quarantined; the lake holds each once."""
    rows = _rows(corpus, _times(10, 99, 0))
    again = [list(r) for r in rows[300:400]]
    rows = rows[:400] + again + rows[400:]
    path = corpus.csv_file(tmp_path / "again.csv", rows, header=_header(corpus))
    result = ingest_paths([path], data=root).files[0]
    got = (result.rows_read, result.rows_landed, result.rows_quarantined, result.rows_duplicate)
    assert got == (600, 500, 0, 100)
    assert _lake(root)["time_utc"].is_unique().all()


def test_a_tdms_timestamp_channel_stepping_back(corpus, tmp_path, root):
    n = 1000  # 100 Hz: 10 s, the clock 2 s back from sample 600 on
    t0 = np.datetime64("2026-03-02T06:00:00", "us")
    offsets = np.arange(n) * 10_000
    offsets[600:] -= 2_000_000
    stamps = t0 + offsets.astype("timedelta64[us]")
    path = corpus.tdms_file(tmp_path / "step.tdms", n, stamps=stamps)
    result = ingest_paths([path], data=root).files[0]
    # samples 600..799 repeat 4.00-5.99 s (the latest read: 5.99 s); 7 is above 60 MPa
    reason = clock_step_reason("sample", 600, 1.99)
    assert result.status == "landed", result.message
    assert result.balanced
    assert result.quarantined_by_reason[reason] == 200
    assert (result.rows_read, result.rows_landed, result.rows_quarantined) == (1000, 799, 201)
    assert "stepped back 2.0 s at sample 600" in reason
    assert _lake(root)["source_line"].is_sorted()


@pytest.mark.parametrize("ahead", [dt.timedelta(days=365), dt.timedelta(seconds=30)])
def test_one_corrupted_time_ahead_is_quarantined_alone(corpus, tmp_path, root, ahead):
    """One row's time a year (or 30 s) ahead of its neighbours, which go on one
    timeline: that row alone is quarantined, the rest of the file lands (taken as the
    latest time read, it had quarantined every later row as a clock step back)."""
    times = _times(10, 99, 0)
    times[200] = times[200] + ahead
    path = corpus.csv_file(tmp_path / "ahead.csv", _rows(corpus, times), header=_header(corpus))
    result = ingest_paths([path], data=root).files[0]
    assert result.balanced
    assert (result.rows_landed, result.rows_quarantined) == (499, 1)
    ((line, reason),) = _quarantine(root)
    assert line == FIRST_LINE + 200
    assert reason.startswith(f"time {ahead.total_seconds():.1f} s ahead of the rows around it")
    assert FIRST_LINE + 200 not in _lake(root)["source_line"].to_list()


@pytest.mark.parametrize(
    ("ahead", "rows"),
    [(dt.timedelta(days=365), 2), (dt.timedelta(days=365), 5), (dt.timedelta(hours=1), 100)],
)
def test_a_short_stretch_of_times_ahead_is_quarantined_alone(corpus, tmp_path, root, ahead, rows):
    """A few rows (two, five, or two seconds of a time server's wrong hour) ahead of the
    rows before and after them, which go on one timeline: those rows alone are
    quarantined, the rest of the file lands. Taken as the latest times read, they had
    quarantined every later row as a clock step back (a whole day's file from there)."""
    times = _times(10, 99, 0)
    for k in range(200, 200 + rows):
        times[k] = times[k] + ahead
    path = corpus.csv_file(tmp_path / "ahead.csv", _rows(corpus, times), header=_header(corpus))
    result = ingest_paths([path], data=root).files[0]
    assert result.balanced
    assert (result.rows_landed, result.rows_quarantined) == (500 - rows, rows)
    quarantined = _quarantine(root)
    assert [line for line, _ in quarantined] == list(
        range(FIRST_LINE + 200, FIRST_LINE + 200 + rows)
    )
    assert all(r.startswith(f"time {ahead.total_seconds():.1f} s ahead") for _, r in quarantined)
    assert "stepped back" not in result.message


def test_a_clock_ahead_longer_than_its_lead_then_set_back_is_still_a_step(corpus, tmp_path, root):
    """A clock 0.5 s ahead for 4 s, then set back: the rows after the set-back repeat
    times already read (a step back, as before); the stretch ahead lasted longer than
    its lead, so it is no corrupted stretch."""
    times = _times(10, 99, 0)
    for k in range(200, 400):
        times[k] = times[k] + dt.timedelta(seconds=0.5)
    path = corpus.csv_file(tmp_path / "ahead.csv", _rows(corpus, times), header=_header(corpus))
    result = ingest_paths([path], data=root).files[0]
    assert result.balanced
    assert "stepped back 1 time(s)" in result.message
    assert all(r.startswith("the logger clock stepped back") for _, r in _quarantine(root))
