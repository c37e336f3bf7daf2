"""Safe names and the paths built of them: the alphabet, the messages, DataRoot's checks."""

from __future__ import annotations

import datetime as dt
import doctest
import re
from pathlib import Path

import pytest

import schemas.names
from schemas.hoist import EXAMPLE_HOIST, HoistDescriptionError, parse_hoist
from schemas.names import (
    PathEscapeError,
    UnsafeNameError,
    is_safe_name,
    join_inside,
    safe_name,
)
from warehouse.store import DataRoot

GOOD = ["a", "7", "xuzhou-north", "main-shaft-1", "rig_a.2", "A.b-c_d", "x" * 64, "v1.2.3"]
#: value -> a fragment of the reason
BAD = {
    "": "empty",
    "..": "contains '..'",
    "../../../../x": "contains '..'",
    "a..b": "contains '..'",
    "a/b": "character '/' not allowed",
    "a\\b": "character '\\\\' not allowed",
    "/tmp/x": "character '/' not allowed",
    ".hidden": "starts with '.'",
    "-flag": "starts with '-'",
    "_x": "starts with '_'",
    "a\x00b": "character '\\x00' not allowed",
    "a\nb": "character '\\n' not allowed",
    "a\rb": "character '\\r' not allowed",
    "main shaft": "character ' ' not allowed",
    "site=x": "character '=' not allowed",
    "50%": "character '%' not allowed",
    "x" * 65: "65 characters, more than 64",
    "nörd": "character 'ö' not allowed",
}


@pytest.mark.parametrize("value", GOOD)
def test_safe_names_pass_unchanged(value):
    assert safe_name(value, key="site", source="log.csv") == value
    assert is_safe_name(value)


@pytest.mark.parametrize("value", sorted(BAD))
def test_unsafe_names_are_refused_with_one_line_naming_source_key_and_value(value):
    with pytest.raises(UnsafeNameError) as info:
        safe_name(value, key="hoist", source="/logs/day.csv: line 2")
    message = str(info.value)
    assert isinstance(info.value, ValueError)
    assert not {"\n", "\r", "\x00"} & set(message)
    assert message.startswith(f"/logs/day.csv: line 2: hoist: unsafe name {value!r}: ")
    assert BAD[value] in message
    assert not is_safe_name(value)


@pytest.mark.parametrize("value", [None, 7, b"site", ["a"]])
def test_non_strings_are_not_names(value):
    with pytest.raises(UnsafeNameError, match="not a string"):
        safe_name(value, key="rig_id", source="rec.mcap")


def test_the_pattern_is_the_documented_one():
    readme = (EXAMPLE_HOIST.parent / "README.md").read_text(encoding="utf-8")
    assert schemas.names.NAME_PATTERN.pattern in readme
    assert re.fullmatch(
        r"\[A-Za-z0-9\]\[A-Za-z0-9\._-\]\{0,63\}", schemas.names.NAME_PATTERN.pattern
    )


def test_doctests():
    result = doctest.testmod(schemas.names, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 2
    assert result.failed == 0


# ------------------------------------------------------------------ hoist description
@pytest.mark.parametrize(
    ("line", "replacement", "location"),
    [
        ('site = "paper-field-test"', 'site = "../../x"', "hoist.site"),
        ('site = "paper-field-test"', 'site = "a\\u0000b"', "hoist.site"),
        ('name = "main-shaft"', 'name = "a/b"', "hoist.name"),
        ('name = "main-shaft"', 'name = "a\\nb"', "hoist.name"),
        ('name = "main-shaft"', 'name = ""', "hoist.name"),
        ('parameter_set = "paper-table1-ols"', 'parameter_set = "../p"', "friction.parameter_set"),
    ],
)
def test_hoist_description_refuses_unsafe_names(line, replacement, location):
    text = EXAMPLE_HOIST.read_text(encoding="utf-8")
    assert text.count(line) == 1
    with pytest.raises(HoistDescriptionError) as info:
        parse_hoist(text.replace(line, replacement), source="bad.toml")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"bad.toml: {location}: unsafe name ")


# ---------------------------------------------------------------------- join_inside
@pytest.mark.parametrize("part", ["..", ".", "", "a/b", "/abs", ".x", "a\x00", "a\nb", "a..b"])
def test_join_inside_refuses_parts_that_are_not_plain_names(tmp_path, part):
    with pytest.raises(UnsafeNameError) as info:
        join_inside(tmp_path, "ok", part, source="report")
    assert repr(part) in str(info.value)
    assert "\n" not in str(info.value)


def test_join_inside_allows_hive_folders_and_long_file_names(tmp_path):
    name = f"{'s' * 64}_{'h' * 64}_2026-03-02.json"
    path = join_inside(tmp_path, "site=a", name)
    assert path == tmp_path / "site=a" / name


def test_join_inside_refuses_a_symlink_out_of_the_base(tmp_path):
    base, outside = tmp_path / "base", tmp_path / "outside"
    base.mkdir()
    outside.mkdir()
    (base / "link").symlink_to(outside)
    with pytest.raises(PathEscapeError, match="outside"):
        join_inside(base, "link", "file.json")


# ------------------------------------------------------------------------- DataRoot
@pytest.fixture
def root(tmp_path: Path) -> DataRoot:
    return DataRoot.resolve(tmp_path / "data")


def test_partition_dir_is_the_hive_layout(root):
    day = dt.date(2026, 3, 2)
    expected = root.path / "lake" / "field_samples" / "site=s-1" / "hoist=h.2" / "date=2026-03-02"
    assert root.partition_dir("field_samples", site="s-1", hoist="h.2", date=day) == expected
    assert root.partition_dir("field_samples", site="s-1", hoist="h.2", date="2026-03-02") == (
        expected
    )
    assert root.partition_dir("field_samples", site="s-1", hoist="h.2") == expected.parent


@pytest.mark.parametrize(
    "kwargs",
    [
        {"site": "../../../../../x", "hoist": "h"},
        {"site": "s", "hoist": "a/b"},
        {"site": "/tmp/x", "hoist": "h"},
        {"site": "s", "hoist": ".."},
        {"site": "", "hoist": "h"},
        {"site": "a\x00b", "hoist": "h"},
        {"site": "s", "hoist": "a\nb"},
    ],
)
def test_partition_dir_refuses_unsafe_names(root, kwargs):
    with pytest.raises(UnsafeNameError) as info:
        root.partition_dir("field_samples", date="2026-03-02", **kwargs)
    bad = next(v for v in kwargs.values() if not is_safe_name(v))
    assert repr(bad) in str(info.value)


@pytest.mark.parametrize("table", ["../x", "a/b", ""])
def test_partition_dir_refuses_unsafe_tables(root, table):
    with pytest.raises(UnsafeNameError):
        root.partition_dir(table, site="s", hoist="h")


@pytest.mark.parametrize("date", ["../2026-03-02", "2026-03-02/..", "x", dt.datetime(2026, 3, 2)])
def test_partition_dir_refuses_dates_that_are_not_days(root, date):
    with pytest.raises(ValueError, match="not YYYY-MM-DD"):
        root.partition_dir("field_samples", site="s", hoist="h", date=date)


def test_partition_dir_refuses_a_symlink_inside_the_data_root_pointing_out(root, tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    table = root.table_dir("field_samples")
    table.mkdir(parents=True)
    (table / "site=s").symlink_to(outside)
    with pytest.raises(PathEscapeError, match="outside"):
        root.partition_dir("field_samples", site="s", hoist="h", date="2026-03-02")
    with pytest.raises(PathEscapeError):
        root.inside(table / "site=s" / "hoist=h")


def test_a_lake_on_another_disk_through_a_symlinked_folder_is_allowed(root, tmp_path):
    disk = tmp_path / "disk" / "lake"
    disk.mkdir(parents=True)
    root.path.mkdir()
    root.lake.symlink_to(disk, target_is_directory=True)
    path = root.partition_dir("field_samples", site="s", hoist="h", date="2026-03-02")
    assert path.resolve() == disk / "field_samples" / "site=s" / "hoist=h" / "date=2026-03-02"


def test_inside_accepts_the_root_and_below_and_refuses_escapes(root, tmp_path):
    root.path.mkdir()
    assert root.inside(root.path) == root.path
    assert root.inside(root.path / "lake" / "x.parquet") == root.path / "lake" / "x.parquet"
    for escape in (root.path / ".." / "x", tmp_path / "x", Path("/etc/passwd"), root.path.parent):
        with pytest.raises(PathEscapeError) as info:
            root.inside(escape)
        assert "outside the data root" in str(info.value)
    (root.path / "out").symlink_to(tmp_path)
    with pytest.raises(PathEscapeError):
        root.inside(root.path / "out" / "x")


def test_inside_follows_a_relative_data_root(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    root = DataRoot.resolve("data")
    assert root.inside("data/lake") == Path("data", "lake")
    with pytest.raises(PathEscapeError):
        root.inside("x")


def test_under_names_folders_of_the_root(root):
    assert root.under("reports", "discovery", "s_h_2026-03-02.json") == (
        root.path / "reports" / "discovery" / "s_h_2026-03-02.json"
    )
    for folder, part in (("..", "x"), ("reports", "../../x"), ("reports", "a/b"), ("/tmp", "x")):
        with pytest.raises(UnsafeNameError):
            root.under(folder, part)
