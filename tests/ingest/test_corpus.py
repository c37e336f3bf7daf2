"""The corpus: every bad or awkward input has a clear outcome and balanced row accounting.

Each case builds its file(s) in ``tmp_path``, ingests them into a fresh data root (real
Parquet, real DuckDB) and checks status, counts, reasons and message, plus
``rows_read = landed + quarantined + duplicates`` and that the lake holds exactly the
landed rows.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from pipelines.ingest import ingest_paths
from schemas.hoist import EXAMPLE_HOIST, load_hoist
from warehouse.store import DataRoot, open_reader

UTC = dt.UTC


@dataclass
class Expect:
    status: str
    read: int
    landed: int
    quarantined: int = 0
    duplicate: int = 0
    reasons: dict[str, int] = field(default_factory=dict)
    message: str = ""


def _lake(root: DataRoot, table: str = "field_samples") -> pl.DataFrame:
    files = sorted(root.table_dir(table).glob("site=*/hoist=*/date=*/*.parquet"))
    if not files:
        return pl.DataFrame()
    return pl.read_parquet(files, hive_partitioning=False)


def _check(report, root: DataRoot, expect: Expect, table: str = "field_samples") -> None:
    (result,) = report.files[-1:]
    assert result.status == expect.status, result.message
    assert result.balanced
    got = (result.rows_read, result.rows_landed, result.rows_quarantined, result.rows_duplicate)
    assert got == (expect.read, expect.landed, expect.quarantined, expect.duplicate), result
    for reason, count in expect.reasons.items():
        assert result.quarantined_by_reason.get(reason) == count, result.quarantined_by_reason
    assert expect.message in result.message
    assert sum(result.quarantined_by_reason.values()) >= result.rows_quarantined
    if result.status != "refused":
        assert _lake(root, table).height == sum(f.rows_landed for f in report.files)
    with open_reader(root) as con:
        status = con.execute(
            "SELECT status FROM manifest WHERE source_sha256 = ?", [result.sha256]
        ).fetchall()
    assert status == [(expect.status,)]


# ------------------------------------------------------------------------------ CSV cases
def _bad_rows(corpus, tmp: Path, name: str, replace: dict[int, str]) -> Path:
    rows: list = corpus.data_rows(10)
    for index, text in replace.items():
        rows[index] = text
    return corpus.csv_file(tmp / name, rows)


def case_clean(corpus, tmp):
    return corpus.csv_file(tmp / "clean.csv", corpus.data_rows(50)), Expect("landed", 50, 50)


def case_wrong_field_count(corpus, tmp):
    good = corpus.data_rows(10)
    short, long = ",".join(good[2][:-1]), ",".join([*good[5], "9"])
    path = _bad_rows(corpus, tmp, "fields.csv", {2: short, 5: long})
    return path, Expect("landed", 10, 8, 2, reasons={"wrong field count": 2})


def case_unparsable_number(corpus, tmp):
    row = corpus.data_rows(10)[3]
    row[2] = "4.8x"
    path = _bad_rows(corpus, tmp, "number.csv", {3: ",".join(row)})
    return path, Expect("landed", 10, 9, 1, reasons={"unparsable value (p2)": 1})


def case_negative_pressure(corpus, tmp):
    row = corpus.data_rows(10)[4]
    row[1] = "-0.200"
    path = _bad_rows(corpus, tmp, "negative.csv", {4: ",".join(row)})
    return path, Expect("landed", 10, 9, 1, reasons={"negative absolute pressure (p1)": 1})


def case_pressure_above_60_mpa(corpus, tmp):
    row = corpus.data_rows(10)[6]
    row[4] = "61.000"
    path = _bad_rows(corpus, tmp, "high.csv", {6: ",".join(row)})
    return path, Expect("landed", 10, 9, 1, reasons={"pressure above 60 MPa (p4)": 1})


def case_unparsable_timestamp(corpus, tmp):
    row = corpus.data_rows(10)[1]
    row[0] = "2026-02-30 06:00:00.010"
    path = _bad_rows(corpus, tmp, "stamp.csv", {1: ",".join(row)})
    return path, Expect("landed", 10, 9, 1, reasons={"unparsable timestamp": 1})


def case_timestamps_no_calendar_holds(corpus, tmp):
    # years polars reads but no datetime holds (signed, five digits, 0, or out of
    # 1-9999 once the zone's offset is applied): those rows, not the file or the command
    rows = corpus.data_rows(10)
    stamps = [
        "-2026-03-02 06:00:00.020",
        "+12026-03-02 06:00:00.030",
        "0000-01-01 00:00:00.000",
        "0001-01-01 00:00:00.000",  # Asia/Shanghai: year 0 in UTC
        "0001-01-01T00:00:00+14:00",
        "9999-12-31T23:59:59-14:00",
    ]
    for i, stamp in enumerate(stamps, start=2):
        rows[i][0] = stamp
    header = {**corpus.HEADER, "timezone": "Asia/Shanghai"}
    path = corpus.csv_file(tmp / "calendar.csv", rows, header=header)
    return path, Expect("landed", 10, 4, 6, reasons={"unparsable timestamp": 6})


def case_bar_units(corpus, tmp):
    rows = [[r[0], "48.12", "47.90", "48.36", "48.01", *r[5:]] for r in corpus.data_rows(5)]
    header = {**corpus.HEADER, "units": "p=bar, x=m"}
    rows = [[*r[:5], "0.0121", "-0.0034", "0.0002", "0.0079", *r[9:]] for r in rows]
    return corpus.csv_file(tmp / "bar.csv", rows, header=header), Expect("landed", 5, 5)


def case_kpa_units(corpus, tmp):
    rows = [[r[0], "4812", "4790", "4836", "4801", *r[5:]] for r in corpus.data_rows(5)]
    header = {**corpus.HEADER, "units": "p=kPa, x=mm"}
    return corpus.csv_file(tmp / "kpa.csv", rows, header=header), Expect("landed", 5, 5)


def case_semicolon_decimal_comma(corpus, tmp):
    rows = [[v.replace(".", ",") if i else v for i, v in enumerate(r)] for r in corpus.data_rows(8)]
    path = corpus.csv_file(tmp / "semicolon.csv", rows, sep=";")
    return path, Expect("landed", 8, 8)


def case_tab_delimiter(corpus, tmp):
    return corpus.csv_file(tmp / "tab.tsv", corpus.data_rows(8), sep="\t"), Expect("landed", 8, 8)


def case_crlf_and_bom(corpus, tmp):
    path = corpus.csv_file(tmp / "crlf.csv", corpus.data_rows(8), newline="\r\n", bom=True)
    return path, Expect("landed", 8, 8)


def case_iso_with_offsets(corpus, tmp):
    rows = corpus.data_rows(4)
    rows[0][0] = "2026-03-02T14:00:00.000+08:00"
    rows[1][0] = "2026-03-02T06:00:00.010Z"
    rows[2][0] = "2026-03-02T01:00:00.020-05:00"
    rows[3][0] = "2026-03-02T06:00:00.030+00:00"
    return corpus.csv_file(tmp / "offsets.csv", rows), Expect("landed", 4, 4)


def case_sentinels(corpus, tmp):
    rows = corpus.data_rows(5)
    for i, token in enumerate(["", "NaN", "nan", "-9999", "-9999.0"]):
        rows[i][2] = token
        rows[i][10] = token
    return corpus.csv_file(tmp / "sentinels.csv", rows), Expect("landed", 5, 5)


def case_missing_optional_channels(corpus, tmp):
    rows = [r[:5] for r in corpus.data_rows(6)]
    header = {**corpus.HEADER, "units": "p=MPa"}
    path = corpus.csv_file(tmp / "ponly.csv", rows, header=header, columns=corpus.COLUMNS[:5])
    return path, Expect("landed", 6, 6)


def case_no_timezone_defaults_to_utc(corpus, tmp):
    header = {k: v for k, v in corpus.HEADER.items() if k != "timezone"}
    return corpus.csv_file(tmp / "notz.csv", corpus.data_rows(3), header=header), Expect(
        "landed", 3, 3
    )


def case_depth_above_pithead_without_hoist(corpus, tmp):
    rows = corpus.data_rows(6)
    rows[2][9] = "-25.00"  # impossible anywhere
    rows[3][9] = "900.00"  # unknown shaft: allowed
    path = corpus.csv_file(tmp / "depth.csv", rows)
    return path, Expect("landed", 6, 5, 1, reasons={"depth outside the shaft": 1})


def case_out_of_order_rows(corpus, tmp):
    rows = corpus.data_rows(10)
    rows[2], rows[7] = rows[7], rows[2]
    return corpus.csv_file(tmp / "order.csv", rows), Expect("landed", 10, 10)


def case_exact_duplicate_row_in_file(corpus, tmp):
    rows = corpus.data_rows(6)
    rows.insert(3, list(rows[2]))
    return corpus.csv_file(tmp / "duprow.csv", rows), Expect("landed", 7, 6, duplicate=1)


def case_conflicting_row_in_file(corpus, tmp):
    rows = corpus.data_rows(6)
    twin = list(rows[2])
    twin[1] = "5.000"
    rows.insert(3, twin)
    return corpus.csv_file(tmp / "conflict.csv", rows), Expect(
        "landed", 7, 6, 1, reasons={"conflicts with landed sample": 1}
    )


def case_blank_lines_are_not_rows(corpus, tmp):
    rows: list = corpus.data_rows(6)
    rows.insert(2, "")
    rows.insert(5, "")
    return corpus.csv_file(tmp / "blank.csv", rows), Expect("landed", 6, 6)


def case_non_utf8_line(corpus, tmp):
    path = corpus.csv_file(tmp / "latin1.csv", corpus.data_rows(6))
    data = path.read_bytes().replace(
        b"31.2\n2026-03-02 06:00:00.020", b"31.2\xe9\n2026-03-02 06:00:00.020"
    )
    path.write_bytes(data)
    return path, Expect("landed", 6, 5, 1, reasons={"non-UTF-8 bytes": 1})


def case_truncated_last_line(corpus, tmp):
    path = corpus.csv_file(tmp / "cut.csv", corpus.data_rows(6))
    path.write_bytes(path.read_bytes()[:-20])
    return path, Expect("partial", 5, 5, message="cut off")


def case_unknown_column(corpus, tmp):
    rows = [[*r, "7"] for r in corpus.data_rows(3)]
    path = corpus.csv_file(tmp / "extra.csv", rows, columns=[*corpus.COLUMNS, "vibration"])
    return path, Expect("landed", 3, 3, message="unknown column(s) vibration ignored")


def case_missing_header_key(corpus, tmp):
    header = {k: v for k, v in corpus.HEADER.items() if k != "hoist"}
    path = corpus.csv_file(tmp / "nohoist.csv", corpus.data_rows(3), header=header)
    return path, Expect("refused", 0, 0, message="lacks required key(s) 'hoist'")


def case_missing_pressure_column(corpus, tmp):
    rows = [[*r[:3], *r[4:]] for r in corpus.data_rows(3)]
    columns = [c for c in corpus.COLUMNS if c != "p3"]
    path = corpus.csv_file(tmp / "nop3.csv", rows, columns=columns)
    return path, Expect("refused", 0, 0, message="lacks required channel(s) p3")


def case_unknown_unit(corpus, tmp):
    header = {**corpus.HEADER, "units": "p=psi, x=mm"}
    path = corpus.csv_file(tmp / "psi.csv", corpus.data_rows(3), header=header)
    return path, Expect("refused", 0, 0, message="line 5: units: p1: unknown unit 'psi'")


def case_empty_file(corpus, tmp):
    path = tmp / "empty.csv"
    path.write_bytes(b"")
    return path, Expect("refused", 0, 0, message="empty file")


def case_header_only(corpus, tmp):
    # an export of a period without samples: lands 0 rows, says so; not a refusal
    path = corpus.csv_file(tmp / "headonly.csv", [])
    return path, Expect("landed", 0, 0, message="no data rows (header and column line only)")


def case_header_only_with_blank_lines(corpus, tmp):
    path = corpus.csv_file(tmp / "headblank.csv", ["", ""], newline="\r\n")
    return path, Expect("landed", 0, 0, message="no data rows")


def _with_header_line(path: Path, after: bytes, line: bytes) -> Path:
    """Insert ``line`` (raw bytes, any encoding) after the header line starting ``after``."""
    data = path.read_bytes()
    at = data.index(b"\n", data.index(after)) + 1
    path.write_bytes(data[:at] + line + b"\n" + data[at:])
    return path


def case_latin1_header_comment(corpus, tmp):
    # an operator's comment typed on a Windows PC: Latin-1, not UTF-8
    path = corpus.csv_file(tmp / "comment.csv", corpus.data_rows(100))
    comment = "# comment: Prüfung nach Seilwechsel, Schacht geölt (Müller)".encode("latin-1")
    _with_header_line(path, b"# timezone", comment)
    return path, Expect("landed", 100, 100, message="line 4: not UTF-8 text, read as cp1252")


def case_hoist_stated_twice_with_two_values(corpus, tmp):
    # two exports' headers pasted together: which hoist the rows belong to is not said
    path = corpus.csv_file(tmp / "twice.csv", corpus.data_rows(3))
    _with_header_line(path, b"# timezone", b"# Hoist : other-hoist")
    return path, Expect(
        "refused", 0, 0,
        message="line 4: 'hoist' stated again ('other-hoist') unlike line 2 ('main-shaft-1')",
    )  # fmt: skip


def case_a_unit_stated_twice_with_two_units(corpus, tmp):
    # the units of two exports pasted into one line: the pressures' scale is not said
    # (read as the last, bar for MPa, every pressure was 10 x off and landed)
    header = {**corpus.HEADER, "units": "p=MPa, x=mm, depth=m, speed=m/s, oil_temp=degC, p=bar"}
    path = corpus.csv_file(tmp / "units.csv", corpus.data_rows(3), header=header)
    return path, Expect(
        "refused", 0, 0, message="units: 'p' stated twice ('MPa' and 'bar'); which one holds?"
    )


def case_a_unit_for_no_channel_is_said(corpus, tmp):
    header = {**corpus.HEADER, "units": "p=MPa, x=mm, depth=m, speed=m/s, oil_temp=degC, q=hPa"}
    path = corpus.csv_file(tmp / "stray_unit.csv", corpus.data_rows(3), header=header)
    return path, Expect("landed", 3, 3, message="units for q name no channel, ignored")


def case_a_read_key_repeated_alike_and_a_free_key_twice(corpus, tmp):
    path = corpus.csv_file(tmp / "alike.csv", corpus.data_rows(4))
    lines = b"# timezone: UTC \n# sample_rate_hz: 100.0\n# note: one\n# note: two"
    _with_header_line(path, b"# timezone", lines)
    return path, Expect("landed", 4, 4)


def case_stray_bytes_in_free_comment(corpus, tmp):
    # bytes no code page defines (0x81, 0x8d, 0x90 are holes in cp1252) in a line
    # without 'key: value': read as Latin-1, ignored as a comment
    path = corpus.csv_file(tmp / "stray.csv", corpus.data_rows(20))
    _with_header_line(path, b"# site", b"# \x81\x8d\x90\xfe export tool v2 \xff")
    return path, Expect("landed", 20, 20, message="line 2: not UTF-8 text, read as Latin-1")


def case_cp1252_degree_sign_in_units(corpus, tmp):
    header = {**corpus.HEADER, "units": "p=MPa, x=mm, depth=m, speed=m/s, oil_temp=°C"}
    path = corpus.csv_file(tmp / "degree.csv", corpus.data_rows(10), header=header)
    path.write_bytes(path.read_bytes().replace("°".encode(), "°".encode("cp1252")))
    return path, Expect("landed", 10, 10, message="line 5: not UTF-8 text, read as cp1252")


def case_non_utf8_rows_among_good_ones(corpus, tmp):
    # undecodable bytes in data rows: those rows are quarantined (raw kept), not lost
    rows: list = corpus.data_rows(12)
    rows[3] = ",".join(rows[3]).replace("12.1", "12.1\udce9")
    rows[8] = ",".join(rows[8]) + "\udc81"
    path = corpus.csv_file(tmp / "rows.csv", [])
    with path.open("ab") as handle:
        for row in rows:
            text = row if isinstance(row, str) else ",".join(row)
            handle.write(text.encode("utf-8", "surrogateescape") + b"\n")
    return path, Expect("landed", 12, 10, 2, reasons={"non-UTF-8 bytes": 2})


def case_classic_mac_line_ends(corpus, tmp):
    # 3000 rows: past the header's 64 KB limit, as every real log
    path = corpus.csv_file(tmp / "mac.csv", corpus.data_rows(3000))
    path.write_bytes(path.read_bytes().replace(b"\n", b"\r"))
    return path, Expect(
        "refused", 0, 0, message="line 1: its lines end with a bare carriage return"
    )


def case_separator_at_the_end_of_every_line(corpus, tmp):
    path = corpus.csv_file(tmp / "trailing.csv", corpus.data_rows(6))
    lines = path.read_bytes().split(b"\n")
    at = next(i for i, line in enumerate(lines) if line.startswith(b"timestamp"))
    lines[at:-1] = [line + b"," for line in lines[at:-1]]
    path.write_bytes(b"\n".join(lines))
    return path, Expect(
        "landed", 6, 6, message="unknown column(s) unnamed column 13 (a separator at the end"
    )


def case_binary_garbage(corpus, tmp):
    path = tmp / "garbage.csv"
    path.write_bytes(bytes(range(256)) * 8)
    return path, Expect("refused", 0, 0, message="line 1: binary data")


def case_binary_without_nul_bytes(corpus, tmp):
    path = tmp / "image.csv"
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(1, 256)) * 4)
    return path, Expect("refused", 0, 0, message="line 1: binary data or not a column line")


def case_no_header_at_all(corpus, tmp):
    path = corpus.csv_file(tmp / "plain.csv", corpus.data_rows(3), header={})
    return path, Expect("refused", 0, 0, message="line 1: header lacks required key(s) 'site'")


def case_empty_mcap(corpus, tmp):
    path = tmp / "empty.mcap"
    path.write_bytes(b"")
    return path, Expect("refused", 0, 0, message="empty file (0 bytes)")


def case_empty_tdms(corpus, tmp):
    path = tmp / "empty.tdms"
    path.write_bytes(b"")
    return path, Expect("refused", 0, 0, message="empty file (0 bytes)")


def case_garbage_mcap(corpus, tmp):
    path = tmp / "garbage.mcap"
    path.write_bytes(np.random.default_rng(3).bytes(4000))
    return path, Expect("refused", 0, 0, message="no readable MCAP messages")


def case_mcap_protobuf_topic(corpus, tmp):
    path = corpus.mcap_file(tmp / "proto.mcap", bad_encoding_topic="/rig/pressure")
    return path, Expect("refused", 0, 0, message="topic /rig/pressure: schema encoding")


def case_missing_p4_column(corpus, tmp):
    rows = [r[:4] + r[5:] for r in corpus.data_rows(3)]
    columns = [c for c in corpus.COLUMNS if c != "p4"]
    path = corpus.csv_file(tmp / "nop4.csv", rows, columns=columns)
    return path, Expect("refused", 0, 0, message="line 6: column line lacks required channel(s) p4")


def case_tdms(corpus, tmp):
    return corpus.tdms_file(tmp / "log.tdms"), Expect(
        "landed", 100, 99, 1, reasons={"pressure above 60 MPa (p1)": 1}
    )


def case_tdms_without_wf_increment(corpus, tmp):
    path = corpus.tdms_file(tmp / "nowf.tdms", omit=["wf_increment"], omit_in="p2")
    return path, Expect(
        "refused", 0, 0, message="channel hoist/p2: waveform property 'wf_increment'"
    )


def case_site_path_traversal(corpus, tmp):  # more in test_traversal.py
    header = {**corpus.HEADER, "site": "../../../../../x"}
    path = corpus.csv_file(tmp / "traversal.csv", corpus.data_rows(5), header=header)
    return path, Expect("refused", 0, 0, message="line 1: site: unsafe name '../../../../../x'")


def case_hoist_with_a_slash(corpus, tmp):
    header = {**corpus.HEADER, "hoist": "a/b"}
    path = corpus.csv_file(tmp / "slash.csv", corpus.data_rows(5), header=header)
    return path, Expect("refused", 0, 0, message="line 2: hoist: unsafe name 'a/b'")


def case_tdms_hoist_with_a_newline(corpus, tmp):
    path = corpus.tdms_file(tmp / "newline.tdms", 20, properties={"hoist": "a\nb"})
    return path, Expect("refused", 0, 0, message="file property 'hoist': unsafe name 'a\\nb'")


def case_mcap_rig_id_with_a_nul(corpus, tmp):
    path = corpus.mcap_file(tmp / "nul.mcap", seconds=0.1, rig_id="rig\x00a")
    return path, Expect("refused", 0, 0, message="rig_id: unsafe name 'rig\\x00a'")


def case_tdms_truncated(corpus, tmp):
    # the logger stopped mid-write: the last channel (speed) has 60 of 100 values; the
    # 60 samples every channel has land (no rows with a null channel), the file is partial
    path = corpus.tdms_file(tmp / "cut.tdms")
    path.write_bytes(path.read_bytes()[: -40 * 8])
    return path, Expect(
        "partial", 60, 59, 1, message="truncated: channel hoist/speed ends at sample 60"
    )


CASES = {
    name.removeprefix("case_"): fn
    for name, fn in list(globals().items())
    if name.startswith("case_")
}


def test_corpus_has_at_least_25_cases():
    assert len(CASES) >= 25


@pytest.mark.parametrize("name", sorted(CASES))
def test_corpus_case(name, corpus, tmp_path, root):
    path, expect = CASES[name](corpus, tmp_path)
    report = ingest_paths([path], data=root)
    _check(report, root, expect)
    if expect.status == "refused":
        assert str(path) in report.files[0].message or path.name in report.files[0].message
        assert report.refusal_lines() == [f"{path}: {report.files[0].reason}"]
        assert "\n" not in report.refusal_lines()[0]
    else:
        assert report.ok
        assert report.refusal_lines() == []


# ---------------------------------------------------------------- values, not just counts
def _only(root: DataRoot) -> pl.DataFrame:
    return _lake(root).sort("time_utc")


def test_units_convert_to_si(corpus, tmp_path, root):
    ingest_paths([case_bar_units(corpus, tmp_path)[0]], data=root)
    frame = _only(root)
    assert frame["p1_pa"][0] == pytest.approx(48.12e5)
    assert frame["x1_m"][0] == pytest.approx(0.0121)
    root2 = DataRoot.resolve(tmp_path / "data2")
    ingest_paths([case_kpa_units(corpus, tmp_path)[0]], data=root2)
    assert _only(root2)["p3_pa"][0] == pytest.approx(4836e3)


def test_a_decimal_comma_in_the_timestamps_fraction_is_read(corpus, tmp_path, root):
    """ISO 8601 allows a comma before a fraction of a second ("06:00:00,021"): a
    decimal-comma export writing one was quarantined whole as unparsable timestamps."""
    rows = [[v.replace(".", ",") for v in r] for r in corpus.data_rows(8)]
    assert "," in rows[0][0]
    path = corpus.csv_file(tmp_path / "comma_times.csv", rows, sep=";")
    _check(ingest_paths([path], data=root), root, Expect("landed", 8, 8))
    ingest_paths([case_tab_delimiter(corpus, tmp_path)[0]], data=DataRoot.resolve(tmp_path / "d2"))
    assert _only(root)["time_utc"].equals(_only(DataRoot.resolve(tmp_path / "d2"))["time_utc"])


def test_decimal_comma_and_tab_give_the_same_values(corpus, tmp_path, root):
    ingest_paths([case_semicolon_decimal_comma(corpus, tmp_path)[0]], data=root)
    comma = _only(root)
    root2 = DataRoot.resolve(tmp_path / "data2")
    ingest_paths([case_tab_delimiter(corpus, tmp_path)[0]], data=root2)
    tab = _only(root2)
    cols = [c for c in comma.columns if c not in ("source_sha256", "source_line")]
    assert comma.select(cols).equals(tab.select(cols))
    assert comma["p1_pa"][0] == pytest.approx(4.812e6)


def test_a_decimal_comma_first_seen_late_in_a_file_is_read(corpus, tmp_path, root):
    """With ";" between fields a comma in a number is its decimal separator wherever it
    first appears: 60 rows of whole numbers and empty fields, then decimal commas (was:
    decided from the first 50 rows, the later ones quarantined as unparsable)."""
    rows = corpus.data_rows(80)
    for r in rows[:60]:
        r[1:] = ["5", "", "-9999", "5", "12", "-3", "0", "8", "0", "1", "31"]
    for r in rows[60:]:
        r[1:] = [v.replace(".", ",") for v in r[1:]]
    report = ingest_paths([corpus.csv_file(tmp_path / "late.csv", rows, sep=";")], data=root)
    assert (report.files[0].rows_landed, report.files[0].rows_quarantined) == (80, 0)
    frame = _only(root).sort("time_utc")
    assert frame["p1_pa"][0] == pytest.approx(5e6)
    assert frame["p1_pa"][79] == pytest.approx(4.812e6)
    assert frame["x1_m"][79] == pytest.approx(12.1e-3)


def test_an_oil_temperature_in_kelvin_lands_in_degc_from_csv_and_tdms(corpus, tmp_path, root):
    """``oil_temp=K`` in a CSV ``units`` line and ``unit_string K`` on a TDMS channel are
    one conversion (contract 1a/1b: the same units): 305.15 K lands as 32.0 degC."""
    rows = corpus.data_rows(3)
    for r in rows:
        r[11] = "305.15"
    header = {**corpus.HEADER, "units": "p=MPa, x=mm, depth=m, speed=m/s, oil_temp=K"}
    csv_path = corpus.csv_file(tmp_path / "kelvin.csv", rows, header=header)
    tdms_path = corpus.tdms_file(tmp_path / "kelvin.tdms", n=10, oil_temp=(305.15, "K"))
    report = ingest_paths([csv_path, tdms_path], data=root)
    assert [f.status for f in report.files] == ["landed", "landed"]
    with open_reader(root) as con:
        temps = con.sql("SELECT DISTINCT oil_temp_c FROM lake_field_samples").fetchall()
    assert temps == [(pytest.approx(32.0),)]


def test_offsets_give_one_utc_timeline(corpus, tmp_path, root):
    ingest_paths([case_iso_with_offsets(corpus, tmp_path)[0]], data=root)
    times = _only(root)["time_utc"].to_list()
    start = dt.datetime(2026, 3, 2, 6, 0, tzinfo=UTC)
    assert times == [start + dt.timedelta(milliseconds=10 * i) for i in range(4)]


def test_sentinels_become_null(corpus, tmp_path, root):
    ingest_paths([case_sentinels(corpus, tmp_path)[0]], data=root)
    frame = _only(root)
    assert frame["p2_pa"].null_count() == 5
    assert frame["speed_m_s"].null_count() == 5
    assert frame["p1_pa"].null_count() == 0


def test_missing_optional_channels_are_null_columns(corpus, tmp_path, root):
    ingest_paths([case_missing_optional_channels(corpus, tmp_path)[0]], data=root)
    frame = _only(root)
    for column in ("x1_m", "depth_m", "speed_m_s", "oil_temp_c"):
        assert frame[column].null_count() == frame.height


def test_out_of_order_rows_are_landed_sorted(corpus, tmp_path, root):
    ingest_paths([case_out_of_order_rows(corpus, tmp_path)[0]], data=root)
    frame = _lake(root)
    assert frame["time_utc"].is_sorted()
    assert frame.height == 10


def test_quarantine_rows_are_queryable_with_line_and_raw(corpus, tmp_path, root):
    path, _ = case_wrong_field_count(corpus, tmp_path)
    ingest_paths([path], data=root)
    with open_reader(root) as con:
        rows = con.sql(
            "SELECT line, reason, raw, source_path FROM quarantine ORDER BY line"
        ).fetchall()
    assert [r[0] for r in rows] == [9, 12]  # 5 header lines + column line; rows 3 and 6
    assert all(r[1] == "wrong field count" and r[2].startswith("2026-03-02") for r in rows)
    assert rows[0][3] == str(path)


def test_depth_outside_the_shaft_with_a_hoist_description(corpus, tmp_path, root):
    hoist = load_hoist(EXAMPLE_HOIST)  # shaft 620 m
    rows = corpus.data_rows(6)
    rows[1][9] = "700.00"
    rows[2][9] = "625.00"  # within the margin
    path = corpus.csv_file(tmp_path / "deep.csv", rows)
    report = ingest_paths([path], data=root, hoist_lookup=lambda site, name: hoist)
    _check(report, root, Expect("landed", 6, 5, 1, reasons={"depth outside the shaft": 1}))


def test_impossible_piston_speed_and_oil_temperature(corpus, tmp_path, root):
    """A malformed number that parses (``1e5``) is no piston's, winder's or oil's: with
    the description's 400 mm stroke and 10 m/s winder, x beyond a stroke from
    mid-stroke and a speed beyond twice the maximum are quarantined; the oil's range
    holds with or without a description."""
    hoist = load_hoist(EXAMPLE_HOIST)
    rows = corpus.data_rows(8)
    rows[1][5] = "1e5"  # x1 = 100 m
    rows[2][8] = "-450.0"  # x4 beyond -400 mm
    rows[3][5] = "390.0"  # within a stroke: landed
    rows[4][10] = "-25.0"  # speed
    rows[5][11] = "1e5"  # oil temperature
    path = corpus.csv_file(tmp_path / "odd.csv", rows)
    report = ingest_paths([path], data=root, hoist_lookup=lambda site, name: hoist)
    reasons = {
        "piston beyond a stroke from mid-stroke (x1)": 1,
        "piston beyond a stroke from mid-stroke (x4)": 1,
        "speed above twice the winder's maximum": 1,
        "oil temperature outside -60..200 degC": 1,
    }
    _check(report, root, Expect("landed", 8, 4, 4, reasons=reasons))


def test_impossible_oil_temperature_without_a_description(corpus, tmp_path, root):
    rows = corpus.data_rows(4)
    rows[1][5] = "1e5"  # x1 = 100 m: no stroke known, landed
    rows[2][11] = "-80.0"
    path = corpus.csv_file(tmp_path / "cold.csv", rows)
    reasons = {"oil temperature outside -60..200 degC": 1}
    _check(ingest_paths([path], data=root), root, Expect("landed", 4, 3, 1, reasons=reasons))


@pytest.mark.parametrize(
    ("zone", "offsets", "note"),
    [
        (
            None,
            False,
            "timestamps without a UTC offset taken as UTC (the file has no "
            "timezone line; contract 1a), but the hoist's description says Asia/Shanghai: "
            "check the export",
        ),
        (
            "Europe/Berlin",
            False,
            "taken as local time in Europe/Berlin (line 5), but the "
            "hoist's description says Asia/Shanghai",
        ),
        ("Asia/Shanghai", False, None),
        ("PRC", False, None),  # an alias of the same clock
        (None, True, None),  # the offsets say where they are
    ],
)
def test_a_log_whose_zone_differs_from_its_hoist_lands_with_a_note(
    corpus, tmp_path, root, zone, offsets, note
):
    """Timestamps without offset are local time in the header's zone, UTC without a
    ``timezone`` line (contract 1a): a logger that exports the mine's local time
    without that line lands 8 h off for a hoist in Shanghai. The rows land as the
    contract says; the file's report says the zones differ."""
    hoist = load_hoist(EXAMPLE_HOIST)
    assert hoist.hoist.timezone == "Asia/Shanghai"
    header = {k: v for k, v in corpus.HEADER.items() if k != "timezone"}
    if zone is not None:
        header["timezone"] = zone
    rows = corpus.data_rows(3)
    if offsets:
        for k, row in enumerate(rows):
            row[0] = f"2026-03-02T06:00:00.0{k}0Z"
    path = corpus.csv_file(tmp_path / "zone.csv", rows, header=header)
    report = ingest_paths([path], data=root, hoist_lookup=lambda site, name: hoist)
    _check(report, root, Expect("landed", 3, 3))
    message = report.files[0].message
    if note is None:
        assert "check the export" not in message
    else:
        assert note in message


# --------------------------------------------------------------------- daylight saving
def _berlin(corpus, tmp, name: str, stamps: list[str]) -> Path:
    rows = corpus.data_rows(len(stamps))
    for row, stamp in zip(rows, stamps, strict=True):
        row[0] = stamp
    header = {**corpus.HEADER, "timezone": "Europe/Berlin"}
    return corpus.csv_file(tmp / name, rows, header=header)


def test_dst_repeated_hour_resolved_by_file_order(corpus, tmp_path, root):
    # 2026-10-25: 03:00 CEST -> 02:00 CET, local 02:00-02:59 happens twice
    stamps = [
        "2026-10-25 01:59:00.000",
        "2026-10-25 02:00:00.000",
        "2026-10-25 02:30:00.000",
        "2026-10-25 02:59:00.000",
        "2026-10-25 02:00:00.000",
        "2026-10-25 02:30:00.000",
        "2026-10-25 03:00:00.000",
    ]
    report = ingest_paths([_berlin(corpus, tmp_path, "fallback.csv", stamps)], data=root)
    _check(report, root, Expect("landed", 7, 7))
    times = _only(root)["time_utc"].to_list()
    expected = [dt.datetime(2026, 10, 24, 23, 59, tzinfo=UTC)] + [
        dt.datetime(2026, 10, 25, h, m, tzinfo=UTC)
        for h, m in [(0, 0), (0, 30), (0, 59), (1, 0), (1, 30), (2, 0)]
    ]
    assert times == expected


def test_dst_repeated_hour_across_batches(corpus, tmp_path, root):
    stamps = [f"2026-10-25 02:{m:02d}:00.000" for m in range(0, 60, 5)] * 2
    path = _berlin(corpus, tmp_path, "fallback2.csv", stamps)
    report = ingest_paths([path], data=root, batch_bytes=300)  # a few lines per batch
    _check(report, root, Expect("landed", 24, 24))
    assert _only(root)["time_utc"].n_unique() == 24


def test_dst_a_file_that_starts_in_the_second_pass_of_the_repeated_hour(corpus, tmp_path, root):
    """An hourly export cut at the change: it starts in the repeated hour and goes on
    into standard time without going back, so it held the second pass (CET): one
    continuous UTC timeline, no false hour's gap."""
    stamps = [f"2026-10-25 02:{m:02d}:00.000" for m in range(30, 60, 5)]
    stamps += ["2026-10-25 03:00:00.000", "2026-10-25 03:05:00.000"]
    path = _berlin(corpus, tmp_path, "second.csv", stamps)
    report = ingest_paths([path], data=root)
    _check(report, root, Expect("landed", 8, 8))
    start = dt.datetime(2026, 10, 25, 1, 30, tzinfo=UTC)  # 02:30 CET
    assert _only(root)["time_utc"].to_list() == [
        start + dt.timedelta(minutes=5 * k) for k in range(8)
    ]
    # one unparsable time among them changes nothing else (it is quarantined)
    stamps[2] = "not a time"
    root2 = DataRoot.resolve(tmp_path / "data2")
    ingest_paths([_berlin(corpus, tmp_path, "second2.csv", stamps)], data=root2)
    assert _only(root2)["time_utc"].to_list() == [
        start + dt.timedelta(minutes=5 * k) for k in range(8) if k != 2
    ]


def test_dst_a_file_that_enters_the_repeated_hour_keeps_the_first_pass(corpus, tmp_path, root):
    """Coming into the repeated hour from before it: the first pass (CEST), as before."""
    stamps = ["2026-10-25 01:55:00.000", "2026-10-25 02:00:00.000", "2026-10-25 02:05:00.000"]
    report = ingest_paths([_berlin(corpus, tmp_path, "first.csv", stamps)], data=root)
    _check(report, root, Expect("landed", 3, 3))
    start = dt.datetime(2026, 10, 24, 23, 55, tzinfo=UTC)  # 01:55 CEST
    assert _only(root)["time_utc"].to_list() == [
        start + dt.timedelta(minutes=5 * k) for k in range(3)
    ]


def test_dst_a_file_of_one_pass_of_the_repeated_hour_says_it_took_the_first(corpus, tmp_path, root):
    """Nothing in the file tells which pass it holds: the first is taken, and the
    file's report says so."""
    stamps = [f"2026-10-25 02:{m:02d}:00.000" for m in range(0, 30, 10)]
    report = ingest_paths([_berlin(corpus, tmp_path, "onepass.csv", stamps)], data=root)
    _check(report, root, Expect("landed", 3, 3))
    assert "3 sample(s) in the repeated hour" in report.files[0].message
    assert "taken as the first (daylight-saving) pass" in report.files[0].message
    assert _only(root)["time_utc"][0] == dt.datetime(2026, 10, 25, 0, 0, tzinfo=UTC)


def test_dst_skipped_hour_is_quarantined(corpus, tmp_path, root):
    # 2026-03-29: 02:00 CET -> 03:00 CEST, local 02:xx never happens
    stamps = [
        "2026-03-29 01:59:00.000",
        "2026-03-29 02:15:00.000",
        "2026-03-29 02:45:00.000",
        "2026-03-29 03:00:00.000",
    ]
    report = ingest_paths([_berlin(corpus, tmp_path, "spring.csv", stamps)], data=root)
    _check(
        report, root, Expect("landed", 4, 2, 2, reasons={"local time in daylight-saving gap": 2})
    )
