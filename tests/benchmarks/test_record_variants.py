"""The evaluations' logger variants of a record (benchmarks/record_variants.py), on small
hand-made contract-1a CSVs."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

NAMES = ["timestamp", "p1", "p2", "p3", "p4", "x1", "x2", "x3", "x4", "depth", "speed", "oil_temp"]


@pytest.fixture(scope="module")
def variants(benchmark_script):
    with benchmark_script("record_variants") as module:
        yield module


def _record(
    path: Path, rows: int, *, delimiter: str = ",", unit: str = "MPa", rate: int = 50
) -> Path:
    """``rows`` rows at ``rate`` Hz: pressures 4.951 + k/1000 (MPa) or 49.51 + k/100 (bar,
    with ';' and decimal commas), x, depth, speed and oil temperature."""
    point = "," if delimiter == ";" else "."
    lines = [
        "# site: s",
        "# hoist: h",
        "# timezone: UTC",
        f"# sample_rate_hz: {rate}",
        f"# units: p={unit}, x=mm, depth=m, speed=m/s, oil_temp=degC",
        delimiter.join(NAMES),
    ]
    for k in range(rows):
        p = f"{4.951 + k / 1000:.3f}" if unit == "MPa" else f"{49.51 + k / 100:.2f}"
        p = p.replace(".", point)
        stamp = f"2026-02-10 06:{k // (60 * rate):02d}:{(k / rate) % 60:06.3f}"
        values = ["2.8", "-3.5", "-6.7", "7.4", f"{k / 100:.2f}", "1.000", "21.7"]
        values = [v.replace(".", point) for v in values]
        lines.append(delimiter.join([stamp, p, p, p, p, *values]))
    path.write_text("\n".join(lines) + "\n")
    return path


def _rows(csv: Path, delimiter: str = ",") -> tuple[list[str], list[list[str]]]:
    lines = csv.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    return lines[: first + 1], [line.split(delimiter) for line in lines[first + 1 :]]


def test_no_x_and_no_oil_temp_take_their_columns_out(variants, tmp_path) -> None:
    csv = _record(tmp_path / "r.csv", 10)
    head, rows = _rows(variants.make_variant(csv, "no-x"))
    assert head[-1].split(",") == [n for n in NAMES if not n.startswith("x")]
    assert all(len(row) == len(NAMES) - 4 for row in rows)
    head, rows = _rows(variants.make_variant(csv, "no-oil-temp"))
    assert head[-1].split(",") == NAMES[:-1]
    assert rows[3][-1] == "1.000"  # speed last now
    # the record's own file is as it was
    assert _rows(csv)[0][-1].split(",") == NAMES


def test_no_speed_empties_every_speed_field(variants, tmp_path) -> None:
    csv = _record(tmp_path / "r.csv", 10)
    head, rows = _rows(variants.make_variant(csv, "no-speed"))
    assert head[-1].split(",") == NAMES
    assert {row[NAMES.index("speed")] for row in rows} == {""}
    assert {row[NAMES.index("oil_temp")] for row in rows} == {"21.7"}


def test_ten_hertz_keeps_every_fifth_row_and_says_so(variants, tmp_path) -> None:
    csv = _record(tmp_path / "r.csv", 23)
    head, rows = _rows(variants.make_variant(csv, "10hz"))
    assert "# sample_rate_hz: 10" in head
    _, whole = _rows(csv)
    assert rows == whole[::5]  # rows 0, 5, 10, 15, 20


@pytest.mark.parametrize(("delimiter", "unit"), [(",", "MPa"), (";", "bar")])
def test_pressures_on_a_ten_kilopascal_step_in_the_files_unit(
    variants, tmp_path, delimiter, unit
) -> None:
    """4.951 ... MPa to 0.01 MPa steps (3 decimals kept); 49,51 ... bar to 0,1 bar steps
    (decimal commas kept)."""
    csv = _record(tmp_path / "r.csv", 12, delimiter=delimiter, unit=unit)
    _, rows = _rows(variants.make_variant(csv, "p-step-10kpa"), delimiter)
    _, whole = _rows(csv, delimiter)
    step = 0.01 if unit == "MPa" else 0.1
    for row, before in zip(rows, whole, strict=True):
        for k in range(1, 5):
            value, was = (float(f.replace(",", ".")) for f in (row[k], before[k]))
            assert round(value / step, 6) == round(was / step)
            assert len(row[k].replace(",", ".").split(".")[1]) == (3 if unit == "MPa" else 2)
            assert ("," in row[k]) == (delimiter == ";")
        assert row[5:] == before[5:]
    assert rows[0][1] == ("4.950" if unit == "MPa" else "49,50")


def test_a_stuck_sensor_holds_one_value_over_the_middle(variants, tmp_path) -> None:
    """At 1 Hz, 20 min is 1200 rows: of 3600 rows the middle 1200."""
    csv = _record(tmp_path / "r.csv", 3600, rate=1)
    _, rows = _rows(variants.make_variant(csv, "stuck-p2"))
    _, whole = _rows(csv)
    held = [n for n, (row, was) in enumerate(zip(rows, whole, strict=True)) if row != was]
    assert held == list(range(1201, 2400))  # row 1200 holds its own value
    assert {rows[n][2] for n in range(1200, 2400)} == {whole[1200][2]}
    assert all(rows[n][1] == whole[n][1] for n in range(3600))


def test_an_outage_takes_five_minutes_of_rows_out_of_the_middle(variants, tmp_path) -> None:
    csv = _record(tmp_path / "r.csv", 1200, rate=1)
    _, rows = _rows(variants.make_variant(csv, "outage-5min"))
    _, whole = _rows(csv)
    assert rows == whole[:450] + whole[750:]


def _with_standstill(csv: Path, still: range) -> Path:
    """``csv`` with its speed 0 over the data rows ``still`` (1.000 elsewhere)."""
    header, rows = _rows(csv)
    k = NAMES.index("speed")
    for n in still:
        rows[n][k] = "0.000"
    csv.write_text("\n".join(header + [",".join(r) for r in rows]) + "\n")
    return csv


def test_a_pause_shifts_the_rows_after_a_standstill_past_the_middle(variants, tmp_path) -> None:
    """``pause-10min``: the logger stops in the first standstill past the record's middle
    with 5 s of rest either side (rows 60-79 at 1 Hz: it resumes at row 65) and the rows
    after it are logged 600 s later, everything else as it was; a standstill before the
    middle does not count, and a record without one says so."""
    csv = _with_standstill(_record(tmp_path / "r.csv", 100, rate=1), range(60, 80))
    csv = _with_standstill(csv, range(10, 30))  # before the middle: not where it pauses
    _, whole = _rows(csv)
    _, rows = _rows(variants.make_variant(csv, "pause-10min"))
    assert rows[:65] == whole[:65]
    assert [r[1:] for r in rows[65:]] == [r[1:] for r in whole[65:]]
    assert (whole[64][0], rows[64][0]) == ("2026-02-10 06:01:04.000", "2026-02-10 06:01:04.000")
    assert (whole[65][0], rows[65][0]) == ("2026-02-10 06:01:05.000", "2026-02-10 06:11:05.000")
    assert rows[-1][0] == "2026-02-10 06:11:39.000"
    plain = _record(tmp_path / "moving.csv", 100, rate=1)
    with pytest.raises(ValueError, match="no standstill of 10 s after the record's middle"):
        variants.make_variant(plain, "pause-10min")


def test_repeated_rows_are_exact_duplicates_and_a_block_out_of_order(variants, tmp_path) -> None:
    """Every row is there; the extra ones are exact copies (ingest counts them as
    duplicates); the order differs only inside one block of 100."""
    csv = _record(tmp_path / "r.csv", 2000)
    _, rows = _rows(variants.make_variant(csv, "repeated-rows"))
    _, whole = _rows(csv)
    counts = Counter(map(tuple, rows))
    assert set(counts) == set(map(tuple, whole))
    assert 10 < sum(c - 1 for c in counts.values()) < 80  # ~2 % of 2000
    assert max(counts.values()) == 2
    stamps = [row[0] for row in rows]
    out_of_order = [n for n in range(1, len(stamps)) if stamps[n] < stamps[n - 1]]
    assert out_of_order
    assert max(out_of_order) - min(out_of_order) < 100
    # the same each time (a seeded logger)
    assert (
        variants.make_variant(csv, "repeated-rows").read_text()
        == (tmp_path / "r-repeated-rows.csv").read_text()
    )


def test_an_unknown_variant_or_column_is_named(variants, tmp_path) -> None:
    csv = _record(tmp_path / "r.csv", 5)
    assert variants.make_variant(csv, "") == csv
    with pytest.raises(KeyError, match=r"no variant 'fast'.*no-x"):
        variants.make_variant(csv, "fast")
    without = variants.make_variant(csv, "no-x")
    with pytest.raises(KeyError, match="no column 'x1'"):
        variants.make_variant(without, "no-x")


def test_no_x_in_a_semicolon_file_with_decimal_commas(variants, tmp_path) -> None:
    csv = _record(tmp_path / "r.csv", 6, delimiter=";", unit="bar")
    head, rows = _rows(variants.make_variant(csv, "no-x"), ";")
    assert head[-1].split(";") == [n for n in NAMES if not n.startswith("x")]
    assert rows[2][1] == "49,53"
    assert rows[2][-1] == "21,7"


def test_the_pressure_step_keeps_missing_values_and_reads_each_channels_unit(
    variants, tmp_path
) -> None:
    """-9999, NaN and empty stay as written; ``p=MPa; p2=kPa`` (';' between items, a
    channel's own unit before ``p``) steps p2 by 10 kPa in kPa."""
    csv = _record(tmp_path / "r.csv", 4)
    text = csv.read_text().replace("p=MPa, x=mm", "p=MPa; p2=kPa; x=mm")
    lines = text.splitlines()
    lines[6] = lines[6].replace("4.951,4.951", "-9999,NaN", 1)  # p1, p2 of the first row
    fields = lines[7].split(",")
    fields[2], fields[3] = "4952.4", ""  # p2 in kPa, p3 missing
    lines[7] = ",".join(fields)
    csv.write_text("\n".join(lines) + "\n")
    _, rows = _rows(variants.make_variant(csv, "p-step-10kpa"))
    assert rows[0][1:3] == ["-9999", "NaN"]
    assert rows[1][2] == "4950.0"
    assert rows[1][3] == ""
    assert rows[1][1] == "4.950"


def test_a_variant_that_cannot_be_made_whole_says_why(variants, tmp_path) -> None:
    csv = _record(tmp_path / "r.csv", 100, rate=1)  # 100 s: no 20 min in its middle
    with pytest.raises(ValueError, match="too short for 20 min"):
        variants.make_variant(csv, "stuck-p2")
    with pytest.raises(ValueError, match="no every-n-th rows at 10 Hz"):
        variants.make_variant(csv, "10hz")
    csv.write_text(csv.read_text().replace("# sample_rate_hz: 1\n", ""))
    with pytest.raises(ValueError, match="sample_rate_hz"):
        variants.make_variant(csv, "outage-5min")


def test_a_frozen_sensor_holds_its_last_value_not_a_gap(variants, tmp_path) -> None:
    """Where p2 was empty at the frozen stretch's start, it holds the last value it
    gave before."""
    csv = _record(tmp_path / "r.csv", 3600, rate=1)
    lines = csv.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    fields = lines[head + 1 + 1200].split(",")
    fields[2] = ""
    lines[head + 1 + 1200] = ",".join(fields)
    csv.write_text("\n".join(lines) + "\n")
    _, rows = _rows(variants.make_variant(csv, "stuck-p2"))
    _, whole = _rows(csv)
    assert {rows[n][2] for n in range(1200, 2400)} == {whole[1199][2]}


@pytest.mark.parametrize(("delimiter", "unit"), [(",", "MPa"), (";", "bar")])
def test_a_sensor_error_is_written_to_the_files_resolution_and_measured(
    variants, tmp_path, delimiter, unit
) -> None:
    """Sensor 2 reads p + 25 kPa, sensor 3 1.004 p (the readings 4.951 + k/1000 MPa or
    49.51 + k/100 bar, to 1 kPa / 0.01 bar); each change's RMS is over the four
    sensors: half the one sensor's. A missing reading stays missing."""
    csv = _record(tmp_path / "r.csv", 20, delimiter=delimiter, unit=unit)
    lines = csv.read_text().splitlines()
    row = lines[8].split(delimiter)
    row[2] = ""  # p2 missing on that row
    lines[8] = delimiter.join(row)
    csv.write_text("\n".join(lines) + "\n")
    to_pa = 1e6 if unit == "MPa" else 1e5
    offset, rms = variants.write_changed(csv, "off", variants.sensor_error(2, offset_pa=25e3))
    assert rms == pytest.approx(12.5e3)
    _, rows = _rows(offset, delimiter)
    _, whole = _rows(csv, delimiter)
    for now, was in zip(rows, whole, strict=True):
        assert now[:2] + now[3:] == was[:2] + was[3:]
        if was[2]:
            change = (float(now[2].replace(",", ".")) - float(was[2].replace(",", "."))) * to_pa
            assert change == pytest.approx(25e3, abs=1.0)
            assert ("," in now[2]) == (delimiter == ";")
        else:
            assert now[2] == ""
    gain, rms = variants.write_changed(csv, "gain", variants.sensor_error(3, gain=1.004))
    values = np.array([float(r[3].replace(",", ".")) * to_pa for r in _rows(csv, delimiter)[1]])
    assert rms == pytest.approx(0.004 * np.sqrt(np.mean(values**2)) / 2, rel=1e-9)
    step = 1e3  # the file's last decimal: 0.001 MPa, 0.01 bar
    for now, was in zip(_rows(gain, delimiter)[1], _rows(csv, delimiter)[1], strict=True):
        value = float(now[3].replace(",", ".")) * to_pa
        expected = 1.004 * float(was[3].replace(",", ".")) * to_pa
        assert abs(value - expected) <= step / 2 + 1e-6


def test_the_sensor_error_cases_alternate_sensors_signs_and_sizes(benchmark_script) -> None:
    """eval_sensor_errors: per record an offset and a gain on neighbouring sensors, of
    the size given (RMS over four sensors: twice it on the one), signs by turns."""
    with benchmark_script("eval_sensor_errors") as evaluation:
        first = list(evaluation.cases(0, 5e6, (2.5, 4.0)))
        second = list(evaluation.cases(1, 5e6, (2.5, 4.0)))
    assert [(c.effect, c.sensor, c.offset_pa, c.size_x_noise) for c in first] == [
        ("sensor_offset", 1, 25e3, 2.5),
        ("sensor_gain", 2, 0.0, 4.0),
    ]
    assert first[1].gain == pytest.approx(1.0 - 2 * 4.0 * 5e3 / 5e6)
    assert (second[0].sensor, second[0].offset_pa, second[0].size_x_noise) == (2, -40e3, 4.0)
    assert second[1].gain == pytest.approx(1.0 + 2 * 2.5 * 5e3 / 5e6)
