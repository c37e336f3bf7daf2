"""Two exports in one CSV: a header repeated mid-file (``cat a.csv b.csv``, a logger that
writes its header again after a restart).

The rows after a repeated header are read with the file's header (the first). Where the
repeated one says the same, they land as ever; where it differs (other units, another
hoist, another column order), reading them with the first header would land wrong
numbers (49.6 bar as 49.6 MPa), another hoist's samples or swapped ropes: they are
quarantined, naming the repeated header's line and what differs, until a header like
the file's own comes again.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import polars as pl

from pipelines.ingest import ingest_paths
from warehouse.store import DataRoot, open_reader

START = dt.datetime(2026, 3, 2, 6, 0, 0)


def _export(corpus, n: int, start: dt.datetime, **header: str) -> list[str]:
    """The lines of one export (header, column line, rows), pressures in MPa unless
    ``units`` says otherwise (then written in bar)."""
    head = {**corpus.HEADER, **header}
    rows = corpus.data_rows(n, start=start)
    if "bar" in head["units"]:
        for row in rows:
            row[1:5] = [f"{float(v) * 10:.2f}" for v in row[1:5]]
    columns = list(corpus.COLUMNS)
    if header.get("_swap"):  # the second export writes p4 first, p1 last
        head.pop("_swap")
        columns[1], columns[4] = columns[4], columns[1]
        for row in rows:
            row[1], row[4] = row[4], row[1]
    return (
        [f"# {k}: {v}" for k, v in head.items()] + [",".join(columns)] + [",".join(r) for r in rows]
    )


def _concatenated(tmp: Path, *exports: list[str]) -> Path:
    path = tmp / "two-exports.csv"
    path.write_text("\n".join(line for export in exports for line in export) + "\n")
    return path


def _landed(root: DataRoot) -> pl.DataFrame:
    files = sorted(root.lake.glob("field_samples/site=*/hoist=*/date=*/*.parquet"))
    return pl.concat([pl.read_parquet(f, hive_partitioning=False) for f in files])


def _quarantine(root: DataRoot) -> list[tuple[int, str]]:
    with open_reader(root) as con:
        return con.sql("SELECT line, reason FROM quarantine ORDER BY line").fetchall()


def test_a_repeated_header_alike_lands_every_row(corpus, tmp_path, root):
    later = START + dt.timedelta(seconds=1)
    path = _concatenated(tmp_path, _export(corpus, 100, START), _export(corpus, 50, later))
    [result] = ingest_paths([path], data=root).files
    assert (result.status, result.rows_landed) == ("landed", 150)
    assert result.balanced


def test_a_second_export_in_bar_is_quarantined_not_landed_as_mpa(corpus, tmp_path, root):
    later = START + dt.timedelta(seconds=1)
    second = _export(corpus, 50, later, units="p=bar, x=mm, depth=m, speed=m/s, oil_temp=degC")
    path = _concatenated(tmp_path, _export(corpus, 100, START), second)
    [result] = ingest_paths([path], data=root).files
    assert result.balanced
    assert result.rows_landed == 100
    landed = _landed(root)
    assert landed["p1_pa"].max() < 5e6  # the logged 4.8 MPa, never 48 MPa
    # header line 107 (6 header lines + 100 rows before it): its rows from line 113 on
    reasons = {line: reason for line, reason in _quarantine(root) if line > 112}
    assert sorted(reasons) == list(range(113, 163))
    assert all("header repeated at line 107" in r for r in reasons.values())
    assert all("units" in r for r in reasons.values())


def test_a_second_export_of_another_hoist_or_column_order_is_quarantined(corpus, tmp_path, root):
    later = START + dt.timedelta(seconds=1)
    other = _export(corpus, 50, later, hoist="aux-shaft-2")
    swapped = _export(corpus, 50, later + dt.timedelta(seconds=1), _swap="1")
    path = _concatenated(tmp_path, _export(corpus, 100, START), other, swapped)
    [result] = ingest_paths([path], data=root).files
    assert result.balanced
    assert result.rows_landed == 100
    reasons = dict(_quarantine(root))
    assert "hoist" in reasons[113]
    assert "columns" in reasons[175]


def test_a_header_like_the_files_own_ends_the_quarantine(corpus, tmp_path, root):
    bar = "p=bar, x=mm, depth=m, speed=m/s, oil_temp=degC"
    exports = (
        _export(corpus, 100, START),
        _export(corpus, 50, START + dt.timedelta(seconds=1), units=bar),
        _export(corpus, 40, START + dt.timedelta(seconds=2)),
    )
    path = _concatenated(tmp_path, *exports)
    [result] = ingest_paths([path], data=root).files
    assert result.balanced
    assert result.rows_landed == 140
    assert _landed(root)["p1_pa"].max() < 5e6


def test_the_quarantine_holds_across_batches_and_a_resumed_growing_file(corpus, tmp_path, root):
    later = START + dt.timedelta(seconds=1)
    second = _export(corpus, 200, later, units="p=bar, x=mm, depth=m, speed=m/s, oil_temp=degC")
    path = _concatenated(tmp_path, _export(corpus, 100, START), second)
    whole = path.read_bytes()
    cut = whole.index(b"\n", len(whole) - 4000) + 1  # the earlier version ended with a line
    path.write_bytes(whole[:cut])
    first = ingest_paths([path], data=root, batch_bytes=2000).files[0]
    path.write_bytes(whole)
    grown = ingest_paths([path], data=root, batch_bytes=2000).files[0]
    assert "resumed" in grown.message
    assert first.balanced
    assert grown.balanced
    assert first.rows_landed + grown.rows_landed == 100
    assert _landed(root)["p1_pa"].max() < 5e6


def test_a_comment_and_the_column_line_again_keep_the_files_header(corpus, tmp_path, root):
    """A logger that writes a comment and the column line again after a restart (no
    site, hoist or units lines): the keys it does not state are the file's, its rows
    land; a column line alone in another order is quarantined."""
    later = START + dt.timedelta(seconds=1)
    restart = ["# restarted by the operator", *_export(corpus, 50, later)[5:]]
    swapped = _export(corpus, 40, later + dt.timedelta(seconds=1), _swap="1")[5:]
    path = _concatenated(tmp_path, _export(corpus, 100, START), restart, swapped)
    [result] = ingest_paths([path], data=root).files
    assert result.balanced
    assert result.rows_landed == 150
    reasons = dict(_quarantine(root))
    # 6 header lines, 100 rows, the comment, the column line, 50 rows: then the column
    # line alone (line 159) and its 40 rows
    assert sorted(line for line in reasons if line > 159) == list(range(160, 200))
    assert "header repeated at line 159" in reasons[160]
    assert "columns" in reasons[160]
