"""``ropeload paper``: each section through the real CLI, its printed numbers against the
paper's published figures (independent truth: typed in here from the paper's text and
tables, with the tolerance each test states), its figure written.
"""

from __future__ import annotations

import contextlib
import io
import math
import re
import struct
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from pipelines.cli import main
from pipelines.cli_parser import PAPER_SECTIONS
from pipelines.paper import SECTIONS, data

G = 9.80665
PAPER_DIR = Path("/work/shared/paper")


def _run(section: str, out: Path) -> str:
    """``ropeload paper SECTION --out OUT`` through the CLI's main; its stdout."""
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        status = main(["paper", section, "--out", str(out)])
    assert status == 0
    return buffer.getvalue()


def _rows(text: str) -> dict[str, dict[str, str]]:
    """Table rows of the printed output by quantity (columns: 2+ spaces apart)."""
    rows = {}
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("quantity"))
    for line in lines[start + 2 :]:
        if not line.strip():
            break
        cells = re.split(r"\s{2,}", line.strip())
        quantity, unit, paper, ropeload, difference = cells[:5]
        rows[quantity] = {
            "unit": unit,
            "paper": paper,
            "ropeload": ropeload,
            "difference": difference,
            "note": cells[5] if len(cells) > 5 else "",
        }
    return rows


def _value(cell: str) -> float:
    return float(cell)


def _png_size(path: Path) -> tuple[int, int]:
    """Width and height from the PNG header (IHDR), refusing anything else."""
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path
    assert head[12:16] == b"IHDR", path
    return struct.unpack(">II", head[16:24])


def _assert_figure(out: Path, key: str) -> None:
    png = out / f"{key}.png"
    assert png.stat().st_size > 30_000  # four curves and labels, not an empty canvas
    width, height = _png_size(png)
    assert width >= 1200
    assert height >= 500
    assert (out / f"{key}.csv").exists()


@pytest.fixture(scope="module")
def out(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("paper")


# ---------------------------------------------------------------------------------------
# table1
# ---------------------------------------------------------------------------------------
#: Paper eq 17 as printed.
EQ17_PRINTED = {
    "coulomb_friction": (0.0357, 0.0254),
    "max_static_friction": (0.1276, 0.0253),
    "stribeck_speed": (8.3503, -0.3966),
    "viscous_coefficient": (0.001208, 0.00006),
}
SYMBOL = {
    "coulomb_friction": "Fc",
    "max_static_friction": "Fs",
    "stribeck_speed": "vs",
    "viscous_coefficient": "Kv",
}


@pytest.fixture(scope="module")
def table1_text(out) -> str:
    return _run("table1", out)


def test_table1_numbers_against_eq17_and_polyfit(table1_text, out):
    rows = _rows(table1_text)
    table = data.table1()
    p = table["oil_pressure_mpa"].to_numpy().astype(float)
    for name, (a17, b17) in EQ17_PRINTED.items():
        (b, a), cov = np.polyfit(p, table[name].to_numpy(), 1, cov=True)
        for label, paper, ols, se in (("a", a17, a, math.sqrt(cov[1, 1])),
                                      ("b", b17, b, math.sqrt(cov[0, 0]))):  # fmt: skip
            row = rows[f"{SYMBOL[name]} {label} ({name})"]
            assert _value(row["paper"]) == pytest.approx(paper, rel=1e-9)
            assert _value(row["ropeload"]) == pytest.approx(ols, rel=1e-4)  # 5 digits printed
            z = (paper - ols) / se
            assert f"z {z:+.2f}" in row["note"]
            # every |z| of Table 1 is under 1.6: the verdict must say consistent (issue 18)
            assert abs(z) < 1.6
            assert "consistent with OLS at 95 %" in row["note"]
    assert "DIFFERS" not in table1_text
    assert "differs from OLS at 95 % (|z|" not in table1_text
    # NOTES.md: OLS reproduces Fs and Kv but not Fc nor vs (to eq 17's printed digits)
    assert rows["Fc a (coulomb_friction)"]["note"].count("not the OLS value") == 1
    assert rows["Fs a (max_static_friction)"]["note"].count("the OLS value to its printed") == 1
    # the one line that fails as a whole: Kv, slope printed with one digit
    assert "Kv: line differs from the OLS line at 95 %" in table1_text
    for symbol in ("Fc", "Fs", "vs"):
        assert f"{symbol}: line consistent with the OLS line at 95 %" in table1_text
    _assert_figure(out, "table1")


def test_calibrate_table1_says_the_same(tmp_path, capsys):
    csv = tmp_path / "t1.csv"
    data.table1().write_csv(csv)
    assert main(["calibrate", "--table1", str(csv)]) == 0
    text = capsys.readouterr().out
    assert "DIFFERS" not in text
    assert "every printed coefficient is within the 95 % interval" in text


# ---------------------------------------------------------------------------------------
# table2
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def table2_text(out) -> str:
    return _run("table2", out)


def test_table2_reproduces_the_field_test(table2_text, out):
    rows = _rows(table2_text)
    # the paper's Table 2: total mass [t], printed sums before / after [kN]
    printed = {
        "pithead": (15.888, 141.8, 155.6),
        "middle": (11.92, 111.2, 118.7),
        "bottom": (8.448, 68.1, 83.1),
    }
    # NOTES.md, checked there by hand: errors before / after [%]
    errors = {"pithead": (-9.0, -0.1), "middle": (-4.9, 1.5), "bottom": (-17.8, 0.3)}
    for pos, (mass_t, before, after) in printed.items():
        expected = rows[f"{pos}: expected load"]
        assert _value(expected["paper"]) == pytest.approx(mass_t * G, abs=0.006)
        # ropeload's hoist model (8.2 t cage + 2 x 6.2 kg/m tail rope) gives the same
        assert _value(expected["ropeload"]) == pytest.approx(mass_t * G, abs=0.006)
        assert _value(rows[f"{pos}: sum of 4 ropes, before"]["paper"]) == before
        assert _value(rows[f"{pos}: sum of 4 ropes, before"]["ropeload"]) == before
        assert _value(rows[f"{pos}: sum of 4 ropes, after"]["ropeload"]) == after
        assert _value(rows[f"{pos}: error before compensation"]["ropeload"]) == errors[pos][0]
        assert _value(rows[f"{pos}: error after compensation"]["ropeload"]) == errors[pos][1]
        assert rows[f"{pos}: error before compensation"]["paper"] == "-"  # not printed
    gain = rows["pithead: gain (compensation rate)"]
    assert _value(gain["paper"]) == 9.7
    assert _value(gain["ropeload"]) == 9.7
    # the erratum: the text's 145.2 kN against Table 2's 141.8 kN
    text_row = rows["pithead: sum before, as in the text"]
    assert _value(text_row["paper"]) == 145.2
    assert _value(text_row["ropeload"]) == 141.8
    assert "Erratum" in table2_text
    assert "Table 2 is used" in table2_text
    _assert_figure(out, "table2")


# ---------------------------------------------------------------------------------------
# eq9-10
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def eq9_10_text(out) -> str:
    return _run("eq9-10", out)


def test_eq9_10_formulas_and_simulation(eq9_10_text, out):
    rows = _rows(eq9_10_text)
    # by hand from the paper's 2.2 constants and beta = 1.5 GPa (the value stated)
    v2 = math.pi * 0.08**2 / 4 * 0.8
    wn = 0.003 * math.sqrt(math.pi * 1.5e9 / (900 * 1.0 * v2))
    xi = 32 * 0.0414 / 0.006**3 * math.sqrt(1.0 * v2 / (math.pi * 1.5e9 * 900))
    assert "beta = 1.5 GPa: NOT given by the paper" in eq9_10_text
    omega = rows["natural frequency omega_n"]
    assert _value(omega["paper"]) == pytest.approx(wn, abs=0.006)
    assert _value(omega["ropeload"]) == pytest.approx(wn, rel=0.01)  # simulated, 1 %
    damping = rows["damping ratio xi, eq 10 corrected"]
    assert _value(damping["paper"]) == pytest.approx(xi, abs=6e-5)
    assert _value(damping["ropeload"]) == pytest.approx(xi, rel=0.02)  # simulated, 2 %
    # second-order step: overshoot exp(-pi xi / sqrt(1 - xi^2)), peak at pi / omega_d
    overshoot = 100 * math.exp(-math.pi * xi / math.sqrt(1 - xi * xi))
    assert _value(rows["first overshoot"]["ropeload"]) == pytest.approx(overshoot, abs=0.5)
    peak_ms = 1e3 * math.pi / (wn * math.sqrt(1 - xi * xi))
    assert _value(rows["time of the first peak"]["ropeload"]) == pytest.approx(peak_ms, abs=0.3)
    # eq 11 corrected resonance 1 / (2 xi), measured on the simulation
    assert _value(rows["resonance |P2/P1| at omega_n"]["ropeload"]) == pytest.approx(
        1 / (2 * xi), rel=0.01
    )
    # the errata show: eq 10 as printed is far from what the simulation does
    printed = rows["damping ratio xi, eq 10 as printed"]
    assert abs(_value(printed["paper"]) - _value(printed["ropeload"])) > 1.0
    _assert_figure(out, "eq9-10")


# ---------------------------------------------------------------------------------------
# section3.1
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def section_3_1_text(out) -> str:
    return _run("section3.1", out)


def test_section_3_1_against_the_paper(section_3_1_text, out):
    rows = _rows(section_3_1_text)
    # paper 3.1: 0.36 MPa at every load 11..1 MPa (tolerance 5 %)
    for load in (11, 9, 7, 5, 3, 1):
        row = rows[f"loss at {load} MPa load"]
        assert _value(row["paper"]) == 0.36
        assert _value(row["ropeload"]) == pytest.approx(0.36, rel=0.05)
    assert _value(rows["loss spread over the loads (max - min)"]["ropeload"]) < 0.018
    # at 11 MPa: peak 11.86 MPa (0.1 MPa), steady 11.36 MPa (0.02 MPa)
    assert _value(rows["11 MPa: peak pressure"]["ropeload"]) == pytest.approx(11.86, abs=0.1)
    assert _value(rows["11 MPa: steady pressure"]["ropeload"]) == pytest.approx(11.36, abs=0.02)
    # timing: peak "during 0.2 s" (0.1 s); "stable after 0.3 s" is not matched (the
    # simulation settles later, and the output says so): within 0.3 s of it
    assert _value(rows["11 MPa: time of the peak"]["ropeload"]) == pytest.approx(0.2, abs=0.1)
    assert _value(rows["11 MPa: settled from"]["ropeload"]) == pytest.approx(0.3, abs=0.3)
    assert "the timing is not matched" in section_3_1_text
    assert "Calibrated, not predicted" in section_3_1_text
    # Fig. 7: lower pump flow, smaller loss and overshoot, later peak
    flows = (20, 15, 10, 5)
    loss = [_value(rows[f"10 MPa, {q} L/min: loss"]["ropeload"]) for q in flows]
    peak = [_value(rows[f"10 MPa, {q} L/min: time of the peak"]["ropeload"]) for q in flows]
    assert loss == sorted(loss, reverse=True)
    assert peak == sorted(peak)
    _assert_figure(out, "section3.1")


# ---------------------------------------------------------------------------------------
# the command itself
# ---------------------------------------------------------------------------------------
def test_default_out_is_under_the_data_root(tmp_path, capsys):
    assert main(["paper", "table2", "--data", str(tmp_path / "data")]) == 0
    text = capsys.readouterr().out
    folder = tmp_path / "data" / "reports" / "paper"
    assert (folder / "table2.png").exists()
    assert f"figure: {folder / 'table2.png'}" in text


def test_usage_and_refusals(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["paper", "table3"])
    assert exc.value.code == 2
    capsys.readouterr()
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("x")
    assert main(["paper", "table2", "--out", str(not_a_folder)]) == 1
    err = capsys.readouterr().err
    assert err == f"ropeload paper: output folder {not_a_folder} is a file, not a folder\n"


def test_sections_named_in_the_cli_are_the_package_sections():
    assert PAPER_SECTIONS == (*SECTIONS, "all")


def test_embedded_tables_are_the_papers():
    """The tables kept in pipelines.paper.data equal the CSVs beside the repository."""
    if not PAPER_DIR.exists():
        pytest.skip("no ../shared/paper in this checkout")
    assert pl.read_csv(PAPER_DIR / "table1_leuven_parameters.csv").equals(data.table1())
    assert pl.read_csv(PAPER_DIR / "table2_field_test.csv").equals(data.table2())
