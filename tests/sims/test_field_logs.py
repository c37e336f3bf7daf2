"""Tests of sims.field_logs: contract 1a CSV and 1b TDMS, read back independently."""

from __future__ import annotations

import datetime as dt

import numpy as np
import polars as pl
import pytest
from nptdms import TdmsFile

from schemas.hoist import EXAMPLE_HOIST, load_hoist
from sims.field_logs import write_csv, write_tdms

HOIST = load_hoist(EXAMPLE_HOIST)
N = 2000


@pytest.fixture(scope="module")
def frame() -> pl.DataFrame:
    rng = np.random.default_rng(7)
    start = dt.datetime(2026, 3, 1, 22, 0, tzinfo=dt.UTC)  # 06:00 in Asia/Shanghai
    t_us = np.arange(N) * 10_000 + rng.integers(0, 300, N)
    cols = {f"p{i}_pa": rng.uniform(2e6, 8e6, N) for i in range(1, 5)}
    cols |= {f"x{i}_m": rng.uniform(-0.2, 0.2, N) for i in range(1, 5)}
    cols |= {
        "depth_m": rng.uniform(0, 620, N),
        "speed_m_s": rng.uniform(-10, 10, N),
        "oil_temp_c": rng.uniform(25, 40, N),
    }
    cols["p2_pa"][5] = np.nan
    cols["depth_m"][7] = np.nan
    f = pl.DataFrame(cols).with_columns(
        (pl.lit(start) + pl.duration(microseconds=pl.Series(t_us))).alias("time_utc")
    )
    return f.select("time_utc", *cols)


def _header(path, n=5):
    with path.open(encoding="utf-8") as handle:
        return [next(handle).rstrip("\n") for _ in range(n)]


def _read(path, **kwargs) -> pl.DataFrame:
    return pl.read_csv(path, comment_prefix="#", infer_schema_length=0, **kwargs)


def _floats(col: pl.Series, decimal=".", missing=("", "NaN", "-9999")) -> np.ndarray:
    s = col.fill_null("")
    if decimal == ",":
        s = s.str.replace(",", ".", literal=True)
    return np.array([np.nan if v in missing else float(v) for v in s.to_list()])


def test_csv_header_and_columns_per_contract(frame, tmp_path):
    path = write_csv(frame, tmp_path / "a.csv", hoist=HOIST)
    assert _header(path) == [
        "# site: paper-field-test",
        "# hoist: main-shaft",
        "# timezone: Asia/Shanghai",
        "# sample_rate_hz: 100",
        "# units: p=MPa, x=mm, depth=m, speed=m/s, oil_temp=degC",
    ]
    data = _read(path)
    assert data.columns == [
        "timestamp",
        "p1",
        "p2",
        "p3",
        "p4",
        "x1",
        "x2",
        "x3",
        "x4",
        "depth",
        "speed",
        "oil_temp",
    ]
    assert data["timestamp"][0] == "2026-03-02 06:00:00.000"


def test_csv_values_round_trip_within_quantisation(frame, tmp_path):
    path = write_csv(frame, tmp_path / "a.csv", hoist=HOIST)
    data = _read(path)
    local = data["timestamp"].str.to_datetime("%Y-%m-%d %H:%M:%S%.3f", time_unit="us")
    utc = local.dt.replace_time_zone("Asia/Shanghai").dt.convert_time_zone("UTC")
    assert (utc - frame["time_utc"]).dt.total_microseconds().abs().max() <= 500
    p1 = _floats(data["p1"]) * 1e6
    assert np.abs(p1 - frame["p1_pa"].to_numpy()).max() <= 500.0 + 1e-6  # 0.001 MPa
    x3 = _floats(data["x3"]) * 1e-3
    assert np.abs(x3 - frame["x3_m"].to_numpy()).max() <= 0.05e-3 + 1e-12  # 0.1 mm
    p2 = _floats(data["p2"])
    assert np.isnan(p2[5])
    assert data["p2"][5] is None
    assert np.isnan(_floats(data["depth"])[7])


@pytest.mark.parametrize(("unit", "scale", "step"), [("bar", 1e5, 1e3), ("kPa", 1e3, 1e3)])
def test_csv_pressure_units(frame, tmp_path, unit, scale, step):
    path = write_csv(frame, tmp_path / f"{unit}.csv", hoist=HOIST, units={"p": unit, "x": "m"})
    assert _header(path)[4] == f"# units: p={unit}, x=m, depth=m, speed=m/s, oil_temp=degC"
    data = _read(path)
    p4 = _floats(data["p4"]) * scale
    assert np.abs(p4 - frame["p4_pa"].to_numpy()).max() <= step / 2 + 1e-6
    x1 = _floats(data["x1"])
    assert np.abs(x1 - frame["x1_m"].to_numpy()).max() <= 0.5e-4 + 1e-12


def test_csv_semicolon_decimal_comma_offset_sentinel(frame, tmp_path):
    path = write_csv(
        frame,
        tmp_path / "eu.csv",
        hoist=HOIST,
        delimiter=";",
        decimal=",",
        with_offset=True,
        missing="-9999",
    )
    data = _read(path, separator=";")
    assert data["timestamp"][0] == "2026-03-02T06:00:00.000+08:00"
    assert data["p2"][5] == "-9999"
    assert "," in data["p1"][0]
    assert "." not in data["p1"][0]
    p1 = _floats(data["p1"], decimal=",") * 1e6
    assert np.abs(p1 - frame["p1_pa"].to_numpy()).max() <= 500.0 + 1e-6
    ts = data["timestamp"].str.to_datetime("%Y-%m-%dT%H:%M:%S%.3f%:z", time_unit="us")
    assert (
        ts.dt.convert_time_zone("UTC") - frame["time_utc"]
    ).dt.total_microseconds().abs().max() <= 500

    with pytest.raises(ValueError, match="decimal"):
        write_csv(frame, tmp_path / "bad.csv", hoist=HOIST, decimal=",")


def test_csv_cut_last_line(frame, tmp_path):
    path = write_csv(frame, tmp_path / "cut.csv", hoist=HOIST, cut_last_line=True)
    lines = path.read_text().split("\n")
    assert lines[-1] != ""
    assert len(lines[-1].split(",")) < 12
    assert len(lines) == 5 + 1 + N


def test_tdms_per_contract(frame, tmp_path):
    path = write_tdms(frame, tmp_path / "a.tdms", hoist=HOIST)
    tdms = TdmsFile.read(path)
    assert {k: tdms.properties[k] for k in ("site", "hoist", "timezone")} == {
        "site": "paper-field-test",
        "hoist": "main-shaft",
        "timezone": "Asia/Shanghai",
    }
    group = tdms["hoist"]
    names = [c.name for c in group.channels()]
    assert names == [
        "timestamp",
        "p1",
        "p2",
        "p3",
        "p4",
        "x1",
        "x2",
        "x3",
        "x4",
        "depth",
        "speed",
        "oil_temp",
    ]
    p1 = group["p1"]
    assert p1.properties["unit_string"] == "MPa"
    assert group["x1"].properties["unit_string"] == "mm"
    assert p1.properties["wf_increment"] == pytest.approx(0.01)
    first = frame["time_utc"].dt.epoch("us")[0]
    assert p1.properties["wf_start_time"] == np.datetime64(first, "us")
    assert len(p1.time_track()) == N
    assert np.abs(p1[:] * 1e6 - frame["p1_pa"].to_numpy()).max() <= 500.0 + 1e-6
    assert np.isnan(group["p2"][5])
    stamps = group["timestamp"][:].astype("datetime64[us]").astype(np.int64)
    # TDMS stores 2^-64 s fractions: read back to within 1 us
    assert np.abs(stamps - frame["time_utc"].dt.epoch("us").to_numpy()).max() <= 1


def test_tdms_without_wf_increment(frame, tmp_path):
    path = write_tdms(frame, tmp_path / "b.tdms", hoist=HOIST, omit_properties=["wf_increment"])
    assert "wf_increment" not in TdmsFile.read(path)["hoist"]["p1"].properties
