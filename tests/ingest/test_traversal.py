"""Names from input data never become paths outside the data root (issue 15).

A site, hoist or rig id like ``../../../../../x``, ``a/b``, an absolute path, a NUL or a
newline, an empty value or ``..`` is refused at the edge where it enters (CSV header,
TDMS file property, MCAP ``/rig/info``, hoist description used by ``run``) with one line
naming the file, the key and the value; the refusal is recorded in the manifest like
other refused files; nothing of the file lands, and nothing at all is written outside
the data root. Behind the edges, the writers refuse such names again.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import polars as pl
import pytest

from pipelines.cli import main
from pipelines.ingest import ingest_paths
from pipelines.ingest.landing import LakeTable
from pipelines.lake import scan_lake
from schemas.hoist import EXAMPLE_HOIST
from schemas.names import PathEscapeError, UnsafeNameError
from warehouse.landing import land_rope_tensions
from warehouse.store import DataRoot, open_reader

#: Escapes the data root ``<tmp>/data`` from ``lake/<table>/site=<value>``.
ESCAPE = "../../../../../escaped"


def _listing(top: Path, skip: Path | None = None) -> set[str]:
    """Every file and folder below ``top`` (symlinks not followed), minus ``skip``'s tree."""
    found = set()
    for path in top.rglob("*"):
        if skip is not None and (path == skip or path.is_relative_to(skip)):
            continue
        found.add(str(path.relative_to(top)))
    return found


def _ingest_refused(path: Path, root: DataRoot, tmp_path: Path, *fragments: str):
    """Ingest ``path``; check the refusal, its manifest row, and that nothing was written."""
    before = _listing(tmp_path, skip=root.path)
    report = ingest_paths([path], data=root)
    (result,) = report.files
    assert result.status == "refused", result
    message = result.message
    assert not {"\n", "\r", "\x00"} & set(message)
    assert message.startswith(f"{path}: ")
    for fragment in fragments:
        assert fragment in message, message
    assert (result.rows_read, result.rows_landed, result.rows_quarantined) == (0, 0, 0)
    assert result.balanced
    assert _listing(tmp_path, skip=root.path) == before  # nothing outside the data root
    assert not list(root.path.rglob("*.parquet"))  # and nothing landed inside it
    assert not [p for p in root.path.rglob("*") if ".." in p.name or p.name == "escaped"]
    with open_reader(root) as con:
        rows = con.execute(
            "SELECT status, message, rows_landed FROM manifest WHERE source_path = ?", [str(path)]
        ).fetchall()
    assert rows == [("refused", message, 0)]
    return result


# --------------------------------------------------------------------------------- CSV
CSV_CASES = {
    "site-traversal-4": ("site", "../../../../x", "contains '..'"),
    "site-traversal-escape": ("site", ESCAPE, "contains '..'"),
    "hoist-slash": ("hoist", "a/b", "character '/' not allowed"),
    "site-absolute": ("site", "<tmp>/abs", "character '/' not allowed"),
    "hoist-dotdot": ("hoist", "..", "contains '..'"),
    "site-empty": ("site", "", "empty"),
    "hoist-carriage-return": ("hoist", "a\rb", "character '\\r' not allowed"),
    "site-leading-dot": ("site", ".hidden", "starts with '.'"),
}


@pytest.mark.parametrize("case", sorted(CSV_CASES))
def test_csv_header_names_cannot_escape(case, corpus, tmp_path, root):
    key, value, reason = CSV_CASES[case]
    value = value.replace("<tmp>", str(tmp_path))
    header = {**corpus.HEADER, key: value}
    path = corpus.csv_file(tmp_path / f"{case}.csv", corpus.data_rows(20), header=header)
    line = list(header).index(key) + 1
    _ingest_refused(path, root, tmp_path, f"line {line}: {key}: unsafe name {value!r}", reason)


def test_csv_header_with_a_nul_names_the_line(corpus, tmp_path, root):
    header = {**corpus.HEADER, "site": "a\x00b"}
    path = corpus.csv_file(tmp_path / "nul.csv", corpus.data_rows(5), header=header)
    _ingest_refused(path, root, tmp_path, "line 1: NUL byte in header line b'# site: a\\x00b'")


def test_a_good_file_next_to_a_bad_one_still_lands(corpus, tmp_path, root):
    bad = corpus.csv_file(
        tmp_path / "bad.csv", corpus.data_rows(5), header={**corpus.HEADER, "site": ESCAPE}
    )
    good = corpus.csv_file(tmp_path / "good.csv", corpus.data_rows(5))
    before = _listing(tmp_path, skip=root.path)
    report = ingest_paths([bad, good], data=root)
    assert [f.status for f in report.files] == ["refused", "landed"]
    assert _listing(tmp_path, skip=root.path) == before
    landed = sorted(root.path.rglob("*.parquet"))
    assert landed
    assert all(
        p.is_relative_to(
            root.partition_dir("field_samples", site="xuzhou-north", hoist="main-shaft-1")
        )
        for p in landed
    )


# -------------------------------------------------------------------------------- TDMS
TDMS_CASES = {
    "site-traversal": ("site", ESCAPE, "contains '..'"),
    "hoist-slash": ("hoist", "a/b", "character '/' not allowed"),
    "hoist-newline": ("hoist", "a\nb", "character '\\n' not allowed"),
    "site-nul": ("site", "a\x00b", "character '\\x00' not allowed"),
    "hoist-dotdot": ("hoist", "..", "contains '..'"),
}


@pytest.mark.parametrize("case", sorted(TDMS_CASES))
def test_tdms_file_property_names_cannot_escape(case, corpus, tmp_path, root):
    key, value, reason = TDMS_CASES[case]
    path = corpus.tdms_file(tmp_path / f"{case}.tdms", 50, properties={key: value})
    _ingest_refused(path, root, tmp_path, f"file property {key!r}: unsafe name {value!r}", reason)


# -------------------------------------------------------------------------------- MCAP
MCAP_CASES = {
    "traversal": (ESCAPE, "contains '..'"),
    "absolute": ("/tmp/x", "character '/' not allowed"),
    "nul": ("rig\x00a", "character '\\x00' not allowed"),
    "newline": ("rig\na", "character '\\n' not allowed"),
    "empty": ("", "empty"),
}


@pytest.mark.parametrize("case", sorted(MCAP_CASES))
def test_mcap_rig_id_cannot_escape(case, corpus, tmp_path, root):
    value, reason = MCAP_CASES[case]
    path = corpus.mcap_file(tmp_path / f"{case}.mcap", seconds=0.2, rig_id=value)
    _ingest_refused(path, root, tmp_path, f"topic /rig/info: rig_id: unsafe name {value!r}", reason)


# ----------------------------------------------------------------- hoist description
@pytest.mark.parametrize(
    ("line", "replacement", "location"),
    [
        ('site = "paper-field-test"', 'site = "../../x"', "hoist.site"),
        ('site = "paper-field-test"', f'site = "{ESCAPE}"', "hoist.site"),
        ('name = "main-shaft"', 'name = "a/b"', "hoist.name"),
        ('name = "main-shaft"', 'name = "a\\u0000b"', "hoist.name"),
        ('name = "main-shaft"', 'name = "a\\nb"', "hoist.name"),
    ],
)
def test_run_refuses_a_hoist_description_with_unsafe_names(
    line, replacement, location, tmp_path, root, capsys
):
    hoist = tmp_path / "bad.toml"
    hoist.write_text(EXAMPLE_HOIST.read_text(encoding="utf-8").replace(line, replacement))
    before = _listing(tmp_path, skip=root.path)
    status = main(["run", "--hoist", str(hoist), "--data", str(root.path)])
    assert status == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert f"{hoist}: {location}: unsafe name " in err
    assert _listing(tmp_path, skip=root.path) == before
    assert not root.path.exists() or not list(root.path.rglob("*.parquet"))


# ------------------------------------------------------- behind the edges: the writers
def _samples(n: int = 3) -> pl.DataFrame:
    times = [dt.datetime(2026, 3, 2, 6, 0, s, tzinfo=dt.UTC) for s in range(n)]
    return pl.DataFrame(
        {"time_utc": times, **{f"p{i}_pa": [1e6] * n for i in range(1, 5)}, "_row": range(n)}
    )


@pytest.mark.parametrize(("site", "hoist"), [(ESCAPE, "h"), ("s", "a/b"), ("s", "..")])
def test_lake_writers_refuse_unsafe_names_themselves(site, hoist, tmp_path, root):
    before = _listing(tmp_path, skip=root.path)
    with pytest.raises(UnsafeNameError):
        LakeTable(root, "field_samples").land(_samples(), site=site, hoist=hoist, source_sha256="x")
    start = dt.datetime(2026, 3, 2, tzinfo=dt.UTC)
    with pytest.raises(UnsafeNameError):
        land_rope_tensions(
            root,
            _samples().drop("_row"),
            site=site,
            hoist=hoist,
            period_start_utc=start,
            period_end_utc=start + dt.timedelta(days=1),
        )
    assert _listing(tmp_path, skip=root.path) == before
    assert not root.path.exists() or not list(root.path.rglob("*"))


def test_lake_writer_refuses_a_planted_symlink_out_of_the_lake(tmp_path, root):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    table = root.table_dir("field_samples")
    table.mkdir(parents=True)
    (table / "site=s").symlink_to(outside)
    with pytest.raises(ValueError, match="outside"):
        LakeTable(root, "field_samples").land(_samples(), site="s", hoist="h", source_sha256="x")
    assert not list(outside.iterdir())


@pytest.mark.parametrize("planted", ["date-folder", "file"])
def test_lake_readers_refuse_a_planted_symlink_out_of_the_lake(planted, corpus, tmp_path, root):
    """The writers refuse a partition that leaves the lake; the readers followed it: a
    run read the samples of ``date=...`` linked to a folder elsewhere, and so did every
    view of the warehouse (``ropeload query`` refused the whole view)."""
    path = corpus.csv_file(tmp_path / "in.csv", corpus.data_rows(10))
    assert ingest_paths([path], data=root).ok
    hoist = root.partition_dir("field_samples", site="xuzhou-north", hoist="main-shaft-1")
    (landed,) = hoist.glob("date=*/*.parquet")
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    copy = outside / "part-00001-000000000000.parquet"
    copy.write_bytes(landed.read_bytes())
    if planted == "date-folder":
        (hoist / "date=2026-03-03").symlink_to(outside)
    else:
        landed.with_name(copy.name).symlink_to(copy)
    with pytest.raises(PathEscapeError, match="outside"):
        scan_lake(root, "field_samples", site="xuzhou-north", hoist="main-shaft-1").collect()
    later = corpus.csv_file(
        tmp_path / "later.csv", corpus.data_rows(5, start=dt.datetime(2026, 3, 2, 7))
    )
    with pytest.raises(PathEscapeError, match="outside"):  # a writer refreshes the views
        ingest_paths([later], data=root)


@pytest.mark.parametrize(("option", "value"), [("rig_id", ESCAPE), ("parameter_set", "a/b")])
def test_calibrate_refuses_unsafe_rig_and_parameter_set_names(option, value, root):
    from pipelines.calibrate import calibrate_rig
    from pipelines.calibrate_inputs import CalibrationError

    key = "rig" if option == "rig_id" else "parameter set"
    with pytest.raises(CalibrationError) as info:
        calibrate_rig(data=root, **{option: value})
    assert str(info.value).startswith(f"{key}: unsafe name {value!r}")
    assert not root.path.exists()


@pytest.mark.parametrize(("flag", "value"), [("--rig", "../x"), ("--parameter-set", "a/b")])
def test_calibrate_cli_says_an_unsafe_name_once_as_a_usage_error(flag, value, root, capsys):
    """The command line refuses the name before anything runs: exit 2 (a usage error),
    one line naming the option, the command's name said once."""
    from pipelines.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["calibrate", "--data", str(root.path), flag, value])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"argument {flag}: unsafe name {value!r}" in err
    assert err.count("calibrate") == 1
    assert not root.path.exists()
