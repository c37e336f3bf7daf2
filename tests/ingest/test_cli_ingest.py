"""``ropeload ingest`` as an operator (or a script) sees it: exit status and stderr.

Contract 6: exit 0 on success (also with quarantined rows), 1 with a one-line reason on
stderr when an input is refused. For a folder: every file is tried, the good ones land,
each refused file is named once on stderr (``ropeload ingest: <file>: <reason>``), the
report stays on stdout. A refusal is said again on every re-ingest, never turned into a
silent "already ingested".
"""

from __future__ import annotations

import datetime as dt
import os
import shutil
import subprocess
import sys
from pathlib import Path

import polars as pl
import pytest

from pipelines.cli import main
from schemas.hoist import EXAMPLE_HOIST
from warehouse.store import DataRoot, open_reader

PREFIX = "ropeload ingest: "


def _ingest(capfd, data: Path, *args: str | Path) -> tuple[int, str, list[str]]:
    code = main(["ingest", "--data", str(data), *map(str, args)])
    out, err = capfd.readouterr()
    return code, out, err.splitlines()


def _lake_rows(data: Path, table: str = "field_samples") -> int:
    files = sorted(DataRoot.resolve(data).table_dir(table).rglob("*.parquet"))
    return pl.read_parquet(files, hive_partitioning=False).height if files else 0


def _bad_files(corpus, folder: Path) -> dict[str, str]:
    """Refused inputs of every kind the tester found, file name -> expected reason part."""
    folder.mkdir(parents=True, exist_ok=True)
    header = {k: v for k, v in corpus.HEADER.items() if k != "site"}
    corpus.csv_file(folder / "no-site.csv", corpus.data_rows(3), header=header)
    corpus.csv_file(
        folder / "psi.csv", corpus.data_rows(3), header={**corpus.HEADER, "units": "p=psi"}
    )
    (folder / "empty.csv").write_bytes(b"")
    (folder / "garbage.csv").write_bytes(bytes(range(256)) * 4)
    columns = [c for c in corpus.COLUMNS if c != "p4"]
    rows = [r[:4] + r[5:] for r in corpus.data_rows(3)]
    corpus.csv_file(folder / "no-p4.csv", rows, columns=columns)
    corpus.mcap_file(folder / "proto.mcap", bad_encoding_topic="/rig/displacement")
    (folder / "junk.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 8)
    corpus.tdms_file(folder / "when.tdms", channel_properties={"wf_start_time": "yesterday"})
    corpus.tdms_file(folder / "step.tdms", channel_properties={"wf_increment": "fast"})
    corpus.tdms_file(folder / "text.tdms", text_in="p1")
    corpus.tdms_file(folder / "stamps.tdms", text_in="timestamp")
    return {
        "no-site.csv": "lines 1-4: header lacks required key(s) 'site'",
        "psi.csv": "line 5: units: p1: unknown unit 'psi'",
        "empty.csv": "empty file (0 bytes)",
        "garbage.csv": "line 1: binary data",
        "no-p4.csv": "line 6: column line lacks required channel(s) p4",
        "proto.mcap": "topic /rig/displacement: schema encoding 'protobuf'",
        "junk.mcap": "no readable MCAP messages",
        "when.tdms": "channel hoist/p2: wf_start_time 'yesterday' is not a time",
        "step.tdms": "channel hoist/p2: wf_increment 'fast' is not a finite number",
        "text.tdms": "channel hoist/p1: values of type",
        "stamps.tdms": "channel hoist/timestamp: values of type",
    }


def _good_files(corpus, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    rows = corpus.data_rows(30)
    rows[4][1] = "-1.0"  # quarantined, not refused: exit status stays 0 for this file
    corpus.csv_file(folder / "day.csv", rows)
    corpus.tdms_file(folder / "log.tdms")
    corpus.mcap_file(folder / "rig.mcap", seconds=0.5)


def _check_refusals(err: list[str], folder: Path, expected: dict[str, str]) -> None:
    assert len(err) == len(expected), err
    for line in err:
        assert line.startswith(PREFIX), line
    by_file = {line.removeprefix(PREFIX).split(": ", 1)[0]: line for line in err}
    assert sorted(by_file) == sorted(str(folder / name) for name in expected)
    for name, reason in expected.items():
        assert f"{PREFIX}{folder / name}: " in by_file[str(folder / name)]
        assert reason in by_file[str(folder / name)], by_file[str(folder / name)]


def test_each_kind_of_refusal_exits_1_with_one_line(corpus, tmp_path, capfd):
    expected = _bad_files(corpus, tmp_path / "bad")
    for name, reason in expected.items():
        path = tmp_path / "bad" / name
        code, out, err = _ingest(capfd, tmp_path / f"data-{name}", path)
        assert code == 1, name
        assert len(err) == 1, err
        assert err[0].startswith(f"{PREFIX}{path}: "), err
        assert reason in err[0], err
        assert "landed" not in err[0], err  # a refusal lands nothing and must not say so
        assert "refused" in out  # the report is on stdout


def test_a_file_name_with_a_line_break_or_a_control_character_is_one_line(corpus, tmp_path, capfd):
    """A file name may hold any byte but ``/`` and NUL: a line break in a refused file's
    name split its stderr line in two (and the path was said twice), an escape sequence
    reached the terminal. Such characters are shown escaped, ``\\n``, ``\\x1b``."""
    folder = tmp_path / "incoming"
    folder.mkdir()
    bad = {**corpus.HEADER, "site": "../x"}
    corpus.csv_file(folder / "bad\nname.csv", corpus.data_rows(3), header=bad)
    corpus.csv_file(folder / "esc\x1b[2J.csv", corpus.data_rows(3), header=bad)
    (folder / "cr\r.csv").write_text("garbage\n")
    corpus.csv_file(folder / "good\n.csv", corpus.data_rows(3))
    code, out, err = _ingest(capfd, tmp_path / "data", folder)
    assert code == 1
    assert sorted(err) == [
        f"{PREFIX}{folder}/bad\\nname.csv: line 1: site: unsafe name '../x': contains '..'; "
        "a name is 1-64 characters of A-Z a-z 0-9 . _ -, starts with a letter or digit and "
        "has no '..'",
        f"{PREFIX}{folder}/cr\\r.csv: line 1: header lacks required key(s) 'site', 'hoist', "
        "'units' (found: none)",
        f"{PREFIX}{folder}/esc\\x1b[2J.csv: line 1: site: unsafe name '../x': contains '..'; "
        "a name is 1-64 characters of A-Z a-z 0-9 . _ -, starts with a letter or digit and "
        "has no '..'",
    ]
    assert not {"\r", "\x1b"} & set(out)
    assert len(out.splitlines()) == 2 + 4 + 2  # head, rule, a line per file, rule, total
    assert "good\\n.csv" in out
    assert _lake_rows(tmp_path / "data") == 3


def test_a_file_name_that_is_not_utf8_is_refused_and_the_others_land(corpus, tmp_path, capfd):
    """Linux file names are bytes: a logger's Latin-1 ``k\\xff.csv`` could not be stored
    in the manifest, and the DuckDB error ended the whole ingest (no file named, the files
    of its batch not recorded). It is refused, named on one line; the others land."""
    folder = tmp_path / "incoming"
    folder.mkdir()
    corpus.csv_file(folder / "a.csv", corpus.data_rows(3))
    odd = folder / os.fsdecode(b"k\xff.csv")
    corpus.csv_file(odd, corpus.data_rows(4, start=dt.datetime(2026, 3, 2, 7)))
    corpus.csv_file(folder / "z.csv", corpus.data_rows(5, start=dt.datetime(2026, 3, 2, 8)))
    data = tmp_path / "data"
    for _ in range(2):  # and again: refused again, nothing landed twice
        code, out, err = _ingest(capfd, data, folder)
        assert code == 1
        assert err == [
            f"{PREFIX}{folder}/k\\xff.csv: the file name is not UTF-8 text (byte 0xff); "
            "rename the file to ingest it"
        ]
        assert "k\\xff.csv" in out
        assert _lake_rows(data) == 3 + 5
    with open_reader(DataRoot.resolve(data)) as con:
        rows = con.sql("SELECT source_path, status FROM manifest ORDER BY 1").fetchall()
    assert rows == [(str(folder / "a.csv"), "landed"), (str(folder / "z.csv"), "landed")]


def test_clean_and_quarantined_files_exit_0_with_nothing_on_stderr(corpus, tmp_path, capfd):
    _good_files(corpus, tmp_path / "good")
    code, out, err = _ingest(capfd, tmp_path / "data", tmp_path / "good")
    assert (code, err) == (0, [])
    assert "0 refused" in out
    assert _lake_rows(tmp_path / "data") == 29 + 99


def test_mixed_folder_lands_the_good_names_each_refused_once_and_again(corpus, tmp_path, capfd):
    folder = tmp_path / "incoming"
    _good_files(corpus, folder)
    expected = _bad_files(corpus, folder)
    data = tmp_path / "data"
    code, out, err = _ingest(capfd, data, folder)
    assert code == 1
    _check_refusals(err, folder, expected)
    assert _lake_rows(data) == 29 + 99
    assert _lake_rows(data, "rig_samples") == 500
    assert f"{len(expected)} refused" in out
    with open_reader(DataRoot.resolve(data)) as con:
        quarantined = con.sql("SELECT count(*) FROM quarantine WHERE topic IS NULL").fetchall()
    assert quarantined == [(2,)]  # the negative pressure (CSV) and the 75 MPa (TDMS)

    # the same folder again: nothing new lands, and every refusal is said again
    code, out, err = _ingest(capfd, data, folder)
    assert code == 1
    _check_refusals(err, folder, expected)
    assert out.count("skipped") == 3
    assert _lake_rows(data) == 29 + 99
    with open_reader(DataRoot.resolve(data)) as con:
        statuses = con.sql("SELECT status, count(*) FROM manifest GROUP BY ALL").fetchall()
    # one row per distinct content: empty.csv and the rest refused, the good ones landed
    assert dict(statuses) == {"landed": 3, "refused": len(expected)}


def test_a_renamed_copy_of_a_refused_file_is_refused_again(corpus, tmp_path, capfd):
    header = {k: v for k, v in corpus.HEADER.items() if k != "units"}
    first = corpus.csv_file(tmp_path / "a.csv", corpus.data_rows(3), header=header)
    code, _, err = _ingest(capfd, tmp_path / "data", first)
    assert code == 1
    assert err == [
        f"{PREFIX}{first}: lines 1-4: header lacks required key(s) 'units' (found: "
        "hoist, sample_rate_hz, site, timezone)"
    ]
    copy = tmp_path / "export-again.csv"
    shutil.copy(first, copy)
    code, out, err = _ingest(capfd, tmp_path / "data", copy)
    assert code == 1
    assert err == [
        f"{PREFIX}{copy}: lines 1-4: header lacks required key(s) 'units' (found: "
        "hoist, sample_rate_hz, site, timezone)"
    ]
    assert "already ingested" not in out
    with open_reader(DataRoot.resolve(tmp_path / "data")) as con:
        rows = con.sql("SELECT source_path, status FROM manifest").fetchall()
    assert rows == [(str(copy), "refused")]  # the latest verdict on this content


def test_an_empty_mcap_after_an_empty_csv_is_refused_not_skipped(tmp_path, capfd):
    empty_csv, empty_mcap = tmp_path / "empty.csv", tmp_path / "empty.mcap"
    empty_csv.write_bytes(b"")
    empty_mcap.write_bytes(b"")
    code, _, err = _ingest(capfd, tmp_path / "data", empty_csv)
    assert (code, err) == (1, [f"{PREFIX}{empty_csv}: empty file (0 bytes): no header, no data"])
    code, out, err = _ingest(capfd, tmp_path / "data", empty_mcap)
    assert (code, err) == (1, [f"{PREFIX}{empty_mcap}: empty file (0 bytes): no header, no data"])
    assert "skipped" not in out
    assert "mcap" in out


def test_landed_csv_bytes_under_an_mcap_name_are_not_skipped_as_the_same_file(
    corpus, tmp_path, capfd
):
    good = corpus.csv_file(tmp_path / "day.csv", corpus.data_rows(5))
    assert _ingest(capfd, tmp_path / "data", good)[0] == 0
    fake = tmp_path / "day.mcap"
    shutil.copy(good, fake)
    code, _out, err = _ingest(capfd, tmp_path / "data", fake)
    assert code == 1
    assert len(err) == 1
    assert err[0].startswith(f"{PREFIX}{fake}: no readable MCAP messages")
    assert f"recorded as the csv file {good}" in err[0]
    with open_reader(DataRoot.resolve(tmp_path / "data")) as con:
        rows = con.sql("SELECT source_path, status FROM manifest").fetchall()
    assert rows == [(str(good), "landed")]


def test_latin1_header_comment_lands_every_row(corpus, tmp_path, capfd):
    path = corpus.csv_file(tmp_path / "day.csv", corpus.data_rows(100))
    text = path.read_bytes()
    comment = "# operator: J. Müller – rope change, all OK\n".encode("cp1252")
    path.write_bytes(text.replace(b"# units", comment + b"# units", 1))
    code, out, err = _ingest(capfd, tmp_path / "data", path)
    assert (code, err) == (0, [])
    assert _lake_rows(tmp_path / "data") == 100
    assert "not UTF-8 text, read as cp1252" in out


@pytest.mark.parametrize("zone", ["localtime", "posixrules", "Mars/Olympus"])
def test_a_header_zone_that_is_no_iana_name_is_refused_naming_its_line(
    corpus, tmp_path, capfd, zone
):
    """``# timezone: localtime`` names a zone file of the machine that runs ingest (its
    own clock, not the mine's), which polars and DuckDB do not know either: refused with
    the file and the header's line, as an unknown name is."""
    path = corpus.csv_file(tmp_path / "day.csv", corpus.data_rows(10),
                           header={**corpus.HEADER, "timezone": zone})  # fmt: skip
    code, _, err = _ingest(capfd, tmp_path / "data", path)
    assert code == 1
    assert err == [f"{PREFIX}{path}: line 3: unknown IANA time zone {zone!r}" + (
        "" if "/" in zone else ": a zone file of this machine, not a zone name (polars and "
        "DuckDB know names only, e.g. 'Asia/Shanghai')"
    )]  # fmt: skip


def test_header_only_file_lands_zero_rows_with_exit_0(corpus, tmp_path, capfd):
    path = corpus.csv_file(tmp_path / "quiet-hour.csv", [])
    code, out, err = _ingest(capfd, tmp_path / "data", path)
    assert (code, err) == (0, [])
    assert "no data rows" in out
    with open_reader(DataRoot.resolve(tmp_path / "data")) as con:
        rows = con.sql("SELECT status, rows_read, rows_landed FROM manifest").fetchall()
    assert rows == [("landed", 0, 0)]


def _deep_log(corpus, path: Path) -> Path:
    """A log of the example hoist (shaft 620 m) with 2 depths beyond the shaft."""
    rows = corpus.data_rows(20)
    rows[5][9] = "700.00"
    rows[6][9] = "1250.00"
    rows[7][9] = "628.00"  # overtravel margin: lands
    header = {**corpus.HEADER, "site": "paper-field-test", "hoist": "main-shaft"}
    return corpus.csv_file(path, rows, header=header)


def test_ingest_hoist_quarantines_depth_beyond_the_shaft(corpus, tmp_path, capfd):
    path = _deep_log(corpus, tmp_path / "deep.csv")
    code, _out, err = _ingest(capfd, tmp_path / "data", "--hoist", EXAMPLE_HOIST, path)
    assert (code, err) == (0, [])
    assert _lake_rows(tmp_path / "data") == 18
    with open_reader(DataRoot.resolve(tmp_path / "data")) as con:
        rows = con.sql("SELECT line, reason FROM quarantine ORDER BY line").fetchall()
    assert rows == [(12, "depth outside the shaft"), (13, "depth outside the shaft")]
    # without the description the shaft depth is unknown: the same rows land
    code, _, err = _ingest(capfd, tmp_path / "data2", path)
    assert (code, err) == (0, [])
    assert _lake_rows(tmp_path / "data2") == 20


def test_ingest_hoist_says_which_files_it_could_not_check(corpus, tmp_path, capfd):
    other = corpus.csv_file(tmp_path / "other.csv", corpus.data_rows(3))
    code, out, err = _ingest(capfd, tmp_path / "data", "--hoist", EXAMPLE_HOIST, other)
    assert (code, err) == (0, [])
    assert "no hoist description for xuzhou-north/main-shaft-1" in " ".join(out.split())


def test_ingest_hoist_invalid_description_is_one_line_exit_1(tmp_path, capfd):
    bad = tmp_path / "bad.toml"
    bad.write_text("[hoist]\nsite = 'x'\n")
    code, _out, err = _ingest(capfd, tmp_path / "data", "--hoist", bad, tmp_path)
    assert code == 1
    assert len(err) == 1
    assert err[0].startswith("ropeload ingest: ")
    assert str(bad) in err[0]
    assert not (tmp_path / "data" / "warehouse.duckdb").exists()


def _console_ingest(data: Path, *paths: Path) -> subprocess.CompletedProcess[str]:
    """``ropeload ingest`` as its own process (stdout and stderr as an operator sees them)."""
    return subprocess.run(
        [sys.executable, "-m", "pipelines.cli", "ingest", "--data", str(data), *map(str, paths)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_console_script_exit_status_and_streams(corpus, tmp_path):
    """The real process: stdout has the report, stderr only the refusal lines."""
    folder = tmp_path / "in"
    folder.mkdir()
    corpus.csv_file(folder / "ok.csv", corpus.data_rows(5))
    (folder / "empty.mcap").write_bytes(b"")
    done = _console_ingest(tmp_path / "d", folder)
    assert done.returncode == 1
    assert done.stderr.splitlines() == [
        f"{PREFIX}{folder / 'empty.mcap'}: empty file (0 bytes): no header, no data"
    ]
    assert "ok.csv" in done.stdout
    assert "1 refused" in done.stdout


def test_a_reader_that_leaves_stdout_early_ends_the_report_quietly(corpus, tmp_path):
    """``ropeload ingest ... | head -0``: the reader has gone before the report is
    written. The files land all the same, stderr stays empty (it held a traceback),
    and the status is the shell's for a writer a closed pipe stopped, 128 + SIGPIPE."""
    folder = tmp_path / "in"
    folder.mkdir()
    corpus.csv_file(folder / "ok.csv", corpus.data_rows(5))
    read, write = os.pipe()
    os.close(read)
    try:
        done = subprocess.run(
            [sys.executable, "-m", "pipelines.cli", "ingest", "--data", str(tmp_path / "d"),
             str(folder)],
            stdout=write, stderr=subprocess.PIPE, text=True, timeout=120, check=False,
        )  # fmt: skip
    finally:
        os.close(write)
    assert done.returncode == 141
    assert done.stderr == ""
    assert _lake_rows(tmp_path / "d") == 5


def test_console_script_truncated_tdms_is_partial_with_nothing_on_stderr(corpus, tmp_path):
    """The real process: a TDMS the logger stopped writing mid-segment lands the samples
    every channel has (partial, said in the report); npTDMS's own warnings about the
    short last segment are not further stderr lines of a command that succeeded."""
    path = corpus.tdms_file(tmp_path / "cut.tdms")
    path.write_bytes(path.read_bytes()[: -40 * 8])
    done = _console_ingest(tmp_path / "d", path)
    assert (done.returncode, done.stderr) == (0, "")
    assert "partial" in done.stdout
    assert _lake_rows(tmp_path / "d") == 59


@pytest.mark.usefixtures("prefect_harness")
def test_prefect_flow_fails_and_cli_says_the_same_lines(corpus, tmp_path, capfd):
    from pipelines.flows import ingest_flow

    folder = tmp_path / "incoming"
    folder.mkdir()
    corpus.csv_file(folder / "ok.csv", corpus.data_rows(5))
    (folder / "empty.csv").write_bytes(b"")
    deep = _deep_log(corpus, folder / "deep.csv")
    state = ingest_flow(
        paths=[str(folder)],
        data=str(tmp_path / "flow-data"),
        hoists=[str(EXAMPLE_HOIST)],
        return_state=True,
    )
    assert state.is_failed()
    assert f"{folder / 'empty.csv'}: empty file (0 bytes)" in state.message
    code, out, err = _ingest(
        capfd, tmp_path / "cli-data", "--prefect", "--hoist", EXAMPLE_HOIST, folder
    )
    assert code == 1
    assert [line for line in err if line.startswith(PREFIX)] == [
        f"{PREFIX}{folder / 'empty.csv'}: empty file (0 bytes): no header, no data"
    ]
    assert "deep.csv" in out
    assert _lake_rows(tmp_path / "cli-data") == 5 + 18
    assert deep.exists()
