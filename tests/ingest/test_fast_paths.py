"""The fast paths of the CSV reader give exactly what the string path gives.

The reference is the same parser with the compiled scan's hints switched off
(``ts_ok`` and ``clean`` all false): every timestamp then goes through the polars
formats and every number through strings + cast, as before the fast paths existed.
"""

from __future__ import annotations

import datetime as dt
import random
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from polars.testing import assert_frame_equal

from pipelines.ingest import field_csv, ingest_paths
from pipelines.ingest.batch import Batch
from pipelines.ingest.csv_header import read_header
from pipelines.ingest.csv_scan import NUMBER_BYTES, scan_chunk
from pipelines.ingest.field_checks import field_limits
from pipelines.ingest.field_csv import _BatchParser
from pipelines.ingest.local_time import AmbiguityState, _constant_offset, _localise

GOOD = ["4.812", "4.792", "4.832", "4.802", "12.1", "-3.4", "0.2", "7.9", "1.50", "1.000", "31.2"]

AWKWARD_TIMES = [
    "2026-03-02 06:00:00.000",
    "2026-03-02 06:00:00.010",
    "2026-03-02T06:00:00.020",
    "2026-03-02 06:00:00",
    "2026-03-02 06:00:00.5",
    "2026-03-02 06:00:00.123456",
    "2026-03-02 06:00:00.1234567",  # 7 digits: polars decides
    "2026-03-02 06:00:00.",  # no fraction digits
    "2026-03-02 06:00:60.000",  # leap second
    "2026-03-02 24:00:00.000",
    "2026-02-29 06:00:00.000",  # not a leap year
    "2024-02-29 06:00:00.000",
    "2000-02-29 06:00:00.000",
    "1900-02-29 06:00:00.000",
    "2100-02-28 23:59:59.999",
    "2026-04-31 06:00:00.000",
    "2026-12-31 23:59:59.999999",
    "1899-12-31 23:59:59.000",
    "2200-01-01 00:00:00.000",
    "0001-01-01 00:00:00.000",
    " 2026-03-02 06:00:00.000",
    "2026-3-02 06:00:00.000",
    "2026-03-02  06:00:00.000",
    "2026-03-02 06:00:00.000Z",
    "2026-03-02T06:00:00.000+08:00",
    "2026-03-02 06:00:00.000+01:00",
    "2026/03/02 06:00:00.000",
    "yesterday",
    "",
    "2026-10-25 02:30:00.000",  # Europe/Berlin: repeated hour
    "2026-10-25 02:30:00.000",
    "2026-03-29 02:30:00.000",  # Europe/Berlin: skipped hour
    "2026-03-29 03:30:00.000",
]


def _reference(monkeypatch: pytest.MonkeyPatch) -> None:
    """Switch the compiled scan's hints off: the string path for everything."""

    def no_hints(*args):
        starts, ends, fields, high, clean, naive_us, ts_ok = scan_chunk(*args)
        return starts, ends, fields, high, clean & False, naive_us * 0, ts_ok & False

    monkeypatch.setattr(field_csv, "scan_chunk", no_hints)


def _parse(path: Path) -> Batch:
    header = read_header(path)
    parser = _BatchParser(header, field_limits(None), AmbiguityState())
    data = path.read_bytes()[header.data_offset :]
    data = data[: data.rfind(b"\n") + 1]
    return parser.parse(data, header.data_line, data.count(b"\n"))


def _both(path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Batch, Batch]:
    fast = _parse(path)
    with monkeypatch.context() as patch:
        _reference(patch)
        reference = _parse(path)
    assert_frame_equal(fast.samples, reference.samples)
    assert_frame_equal(fast.rejected, reference.rejected)
    return fast, reference


@pytest.mark.parametrize("zone", ["UTC", "Europe/Berlin", "Asia/Shanghai"])
@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_fast_timestamps_match_polars_formats(
    tmp_path: Path, corpus, monkeypatch: pytest.MonkeyPatch, zone: str, newline: str
) -> None:
    rows = [[stamp, *GOOD] for stamp in AWKWARD_TIMES]
    header = {**corpus.HEADER, "timezone": zone}
    path = corpus.csv_file(tmp_path / "times.csv", rows, header=header, newline=newline)
    fast, _ = _both(path, monkeypatch)
    assert fast.samples.height > 10
    assert fast.rows_read == len(rows)


def test_fast_timestamps_random_valid(tmp_path: Path, corpus, monkeypatch) -> None:
    rng = random.Random(7)
    start = dt.datetime(1900, 1, 1)
    rows = []
    for _ in range(3000):
        t = start + dt.timedelta(microseconds=rng.randrange(300 * 365 * 86400 * 10**6))
        digits = rng.randrange(0, 7)
        text = t.strftime("%Y-%m-%d" + rng.choice(" T") + "%H:%M:%S")
        if digits:
            text += "." + f"{t.microsecond:06d}"[:digits]
        rows.append([text, *GOOD])
    path = corpus.csv_file(tmp_path / "random.csv", rows)
    fast, _ = _both(path, monkeypatch)
    assert fast.samples.height == 3000


def test_scan_takes_the_plain_shapes() -> None:
    lines = [
        "2026-03-02 06:00:00.000,1",
        "2026-03-02T06:00:00,1",
        "2024-02-29 23:59:59.999999,1",
        "2026-02-29 06:00:00.000,1",
        "2026-03-02 06:00:60.000,1",
        "2026-03-02 06:00:00.0000001,1",
        "2026-03-02 06:00:00.000Z,1",
    ]
    data = ("\n".join(lines) + "\n").encode()
    numeric = np.array([False, True])
    *_, naive_us, ts_ok = scan_chunk(
        np.frombuffer(data, np.uint8), len(lines), ord(","), numeric, NUMBER_BYTES
    )
    assert ts_ok.tolist() == [True, True, True, False, False, False, False]
    epoch = dt.datetime(1970, 1, 1)
    expected = dt.datetime(2024, 2, 29, 23, 59, 59, 999999) - epoch
    assert naive_us[2] == expected // dt.timedelta(microseconds=1)


AWKWARD_NUMBERS = [
    "4.8",
    "+4.8",
    ".5",
    "5.",
    "4.8e0",
    "4.8E+0",
    "-0",
    "00012",
    "",
    "NaN",
    "nan",
    "-9999",
    "-9999.0",
    "1e400",
    "4.8e-400",
]


def test_typed_numbers_match_string_cast(tmp_path: Path, corpus, monkeypatch) -> None:
    rows = []
    for i, value in enumerate(AWKWARD_NUMBERS * 3):
        stamp = f"2026-03-02 06:00:{i % 60:02d}.{i:03d}"
        rows.append([stamp, *[value if k == i % 11 else GOOD[k] for k in range(11)]])
    path = corpus.csv_file(tmp_path / "numbers.csv", rows)
    typed = []
    read = _BatchParser._read

    def spy(self, data, fast):
        frame, is_typed = read(self, data, fast)
        typed.append(is_typed)
        return frame, is_typed

    monkeypatch.setattr(_BatchParser, "_read", spy)
    fast, _ = _both(path, monkeypatch)
    assert typed[0] is True  # the first parse took the typed path
    reasons = fast.rejected["reason"].to_list()
    assert any(r.startswith("unparsable value") for r in reasons)  # 1e400 is infinite


@pytest.mark.parametrize("bad", ["abc", "4.8.1", "1;5", " 4.8", "4.8 ", "inf ", "0x10", "1_0"])
def test_one_bad_value_falls_back(tmp_path: Path, corpus, monkeypatch, bad: str) -> None:
    rows = corpus.data_rows(50)
    rows[17][2] = bad  # p2
    path = corpus.csv_file(tmp_path / "bad.csv", rows)
    typed = []
    read = _BatchParser._read

    def spy(self, data, fast):
        frame, is_typed = read(self, data, fast)
        typed.append(is_typed)
        return frame, is_typed

    monkeypatch.setattr(_BatchParser, "_read", spy)
    fast, _ = _both(path, monkeypatch)
    assert typed[0] is False
    assert fast.samples.height == 49
    assert fast.rejected.to_dicts() == [
        {
            "row": 7 + 17,  # five header lines, the column line, then data
            "topic": None,
            "reason": "unparsable value (p2)",
            "raw": ",".join(rows[17]),
        }
    ]


def test_typed_read_agrees_with_cast_on_random_tokens() -> None:
    rng = random.Random(11)
    alphabet = "0123456789.+-eEnNaAiIfFtTyY"
    tokens = {"".join(rng.choice(alphabet) for _ in range(rng.randrange(1, 6))) for _ in range(400)}
    tokens |= {"inf", "-inf", "Infinity", "INF", "nan", "NAN", "1e5", "-1.5e-3", "+.5e+2"}
    for token in sorted(tokens):
        cast = pl.Series([token]).cast(pl.Float64, strict=False)[0]
        try:
            read = pl.read_csv(f"a\n{token}\n".encode(), schema={"a": pl.Float64}, quote_char=None)[
                "a"
            ][0]
        except pl.exceptions.ComputeError:
            continue  # the batch falls back to the string path
        assert str(read) == str(cast), token


def test_constant_offset_only_away_from_changes() -> None:
    def naive(*stamps: str) -> pl.Series:
        return pl.Series([dt.datetime.fromisoformat(s) for s in stamps], dtype=pl.Datetime("us"))

    berlin = "Europe/Berlin"
    assert _constant_offset(naive("2026-03-02 00:00", "2026-03-09 00:00"), berlin) == (
        dt.timedelta(hours=1)
    )
    assert _constant_offset(naive("2026-03-28 12:00", "2026-03-30 12:00"), berlin) is None
    assert _constant_offset(naive("2026-10-20 12:00", "2026-10-27 12:00"), berlin) is None
    assert _constant_offset(naive("2026-10-25 02:30"), berlin) is None  # ambiguous
    assert _constant_offset(naive("2026-03-01", "2026-03-25"), berlin) is None  # > 20 days
    for zone in (berlin, "America/Santiago", "Australia/Lord_Howe", "Asia/Shanghai"):
        times = pl.datetime_range(
            dt.datetime(2026, 1, 1), dt.datetime(2026, 12, 31), "37m", eager=True
        ).cast(pl.Datetime("us"))
        for start in range(0, len(times), 500):  # 500 x 37 min: under 20 days
            part = times[start : start + 500]
            expected = part.dt.replace_time_zone(
                zone, ambiguous="earliest", non_existent="null"
            ).dt.convert_time_zone("UTC")
            assert_frame_equal(
                pl.DataFrame({"t": _localise(part, zone, AmbiguityState())}),
                pl.DataFrame({"t": expected}),
            )


def test_pipelined_landing_small_batches(tmp_path: Path, corpus, root) -> None:
    """Many batches in flight one after another land every row once, in order."""
    rows = corpus.data_rows(3000)
    rows[100][3] = "junk"
    rows.insert(2000, rows[1500])  # an exact duplicate in a later batch
    path = corpus.csv_file(tmp_path / "many.csv", rows)
    report = ingest_paths([path], data=root, batch_bytes=4096)
    result = report.files[0]
    assert result.status == "landed", result.message
    assert (result.rows_read, result.rows_landed) == (3001, 2999)
    assert (result.rows_quarantined, result.rows_duplicate) == (1, 1)
    files = sorted(root.table_dir("field_samples").glob("site=*/hoist=*/date=*/*.parquet"))
    lake = pl.read_parquet(files, hive_partitioning=False)
    assert lake.height == 2999
    assert lake["time_utc"].is_unique().all()
