"""``ropeload paper table1`` and ``table2``: the paper's two tables reproduced.

Table 1 / eq 17
    OLS lines through Table 1 (:func:`transforms.friction_fit.fit_table1`) against
    eq 17 as printed, with standard errors, z-scores and the verdicts of
    :func:`transforms.friction_fit.compare_with_eq17` in the words of
    :mod:`pipelines.calibrate_report` (the same as ``ropeload calibrate --table1``).
Table 2
    The field test (section 5.2) through :func:`transforms.reconciliation.table2_check`
    with the example hoist (``schemas/hoists/paper_field_test.toml``: 8.2 t cage,
    2 tail ropes of 6.2 kg/m): sums, expected loads from ropeload's hoist model,
    errors before / after compensation, the paper's "compensation rate" and the rope
    imbalance, with the 145.2 / 141.8 kN erratum.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
from scipy import stats

from pipelines.calibrate_report import eq17_coefficient_verdict, eq17_line_verdict, eq17_summary
from pipelines.paper import data
from pipelines.paper.report import PaperSection, Row, new_figure, save_figure
from schemas.hoist import EXAMPLE_HOIST, G_STANDARD, load_hoist
from transforms.friction_fit import EQ17, compare_with_eq17, fit_table1
from transforms.reconciliation import table2_check

__all__ = ["table1_section", "table2_section"]

#: Table 1's columns: symbol, unit of the value, unit of the slope (NOTES.md reading:
#: friction as an equivalent pressure in MPa, speed in mm/s).
_PARAMETERS = {
    "coulomb_friction": ("Fc", "MPa", "MPa/MPa"),
    "max_static_friction": ("Fs", "MPa", "MPa/MPa"),
    "stribeck_speed": ("vs", "mm/s", "mm/s/MPa"),
    "viscous_coefficient": ("Kv", "MPa s/mm", "s/mm"),
}


def table1_section(out_dir: Path) -> PaperSection:
    """Table 1: OLS vs eq 17 per coefficient (z-scores, verdicts), residual RMS of
    Table 1 about each line, and the figure (points, OLS with its 95 % band, eq 17)."""
    table = data.table1()
    fits = fit_table1(table)
    compare = compare_with_eq17(fits)
    rows_by = {(r["parameter"], r["coefficient"]): r for r in compare.iter_rows(named=True)}
    p = table["oil_pressure_mpa"].cast(pl.Float64).to_numpy()
    section = PaperSection(
        key="table1",
        title="Paper Table 1 and eq 17: friction parameters as lines in oil pressure",
        intro=[
            f"Table 1 ({p.size} pressures, {p.min():g}..{p.max():g} MPa) fitted by ordinary "
            "least squares, value = a + b p; paper = eq 17 as printed, ropeload = the OLS "
            "line (transforms.friction_fit, as `ropeload calibrate --table1`).",
            "Table 1 gives no units; read as friction in MPa (equivalent pressure) and speed "
            "in mm/s (NOTES.md). se = standard error of the OLS coefficient; z = (eq17 - OLS) "
            f"/ se; the 95 % two-sided limit is |z| < {compare['z_limit'][0]:.2f} (Student t, "
            f"{p.size - 2} degrees of freedom).",
        ],
    )
    for name, (symbol, unit, slope_unit) in _PARAMETERS.items():
        for coefficient, label, u in (("intercept", "a", unit), ("slope", "b", slope_unit)):
            row = rows_by[(name, coefficient)]
            section.rows.append(
                Row(
                    f"{symbol} {label} ({name})",
                    u,
                    row["eq17"],
                    row["ols"],
                    ".5g",
                    f"se {row['se']:.2g}, z {row['z']:+.2f}: {eq17_coefficient_verdict(row)}",
                )
            )
    for name, (symbol, unit, _) in _PARAMETERS.items():
        a, b = (float(v) for v in EQ17[name])
        y = table[name].to_numpy()
        section.rows.append(
            Row(
                f"{symbol} residual rms of Table 1",
                unit,
                float(np.sqrt(np.mean((y - a - b * p) ** 2))),
                float(np.sqrt(np.mean(fits[name].residuals ** 2))),
                ".3g",
                "paper: about the eq 17 line; ropeload: about the OLS line",
            )
        )
    section.notes.append("Whole lines (intercept and slope together, F test, 2 and 9 dof):")
    for name, (symbol, *_) in _PARAMETERS.items():
        section.notes.append(f"  {symbol}: {eq17_line_verdict(rows_by[(name, 'slope')])}")
    section.notes.append("Summary:")
    section.notes += [f"  {line}" for line in eq17_summary(compare)]
    kv = fits["viscous_coefficient"]
    if not rows_by[("viscous_coefficient", "slope")]["line_consistent"]:
        correlation = kv.cov_intercept_slope / (kv.se_intercept * kv.se_slope)
        section.notes.append(
            f"  The Kv line fails as a whole although each coefficient passes: eq 17 prints "
            f"its slope {EQ17['viscous_coefficient'][1]} for the OLS {kv.slope:.3g}, and "
            f"intercept and slope are correlated ({correlation:+.2f})."
        )
    section.notes.append("  ropeload uses its own OLS lines, not eq 17 (README, Units).")
    _table1_figure(section, table, fits, compare, out_dir)
    section.write_rows(out_dir)
    return section


def _table1_figure(section, table, fits, compare, out_dir: Path) -> None:
    p = table["oil_pressure_mpa"].cast(pl.Float64).to_numpy()
    grid = np.linspace(p.min(), p.max(), 101)
    figure = new_figure(10.0, 7.0)
    axes = figure.subplots(2, 2)
    for ax, (name, (symbol, unit, _)) in zip(axes.flat, _PARAMETERS.items(), strict=True):
        fit = fits[name]
        t = stats.t.ppf(0.975, fit.n - 2)
        band = t * fit.se_line(grid)
        ax.fill_between(grid, fit(grid) - band, fit(grid) + band, color="C0", alpha=0.18,
                        label="OLS 95 % confidence band")  # fmt: skip
        ax.plot(grid, fit(grid), color="C0", label=f"OLS {fit.intercept:.4g} + {fit.slope:.4g} p")
        a, b = (float(v) for v in EQ17[name])
        ax.plot(grid, a + b * grid, "--", color="C3", label=f"eq 17 {a:g} + {b:g} p")
        ax.plot(p, table[name].to_numpy(), "o", color="k", ms=4, label="Table 1")
        row = compare.filter(pl.col("parameter") == name).row(1, named=True)
        verdict = "consistent" if row["line_consistent"] else "differs"
        ax.set_title(f"{symbol} ({name}): eq 17 line {verdict} at 95 % (p {row['line_p']:.2g})",
                     fontsize=9)  # fmt: skip
        ax.set_xlabel("oil pressure p [MPa]")
        ax.set_ylabel(f"{symbol} [{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    figure.suptitle("Paper Table 1 against eq 17 and ordinary least squares")
    save_figure(figure, section, out_dir)


def table2_section(out_dir: Path) -> PaperSection:
    """Table 2: the field test with ropeload's expected loads (hoist model), errors,
    gains and imbalance; the paper's printed numbers beside them."""
    hoist = load_hoist(EXAMPLE_HOIST)
    table = data.table2()
    check = table2_check(table, hoist)
    section = PaperSection(
        key="table2",
        title="Paper Table 2: field test, sum of the four rope tensions against the load",
        intro=[
            "Cage at rest and empty at three positions; expected load = total mass x g "
            "(g = 9.80665 m/s2). paper = as printed in Table 2 or the text ('-': not "
            "printed); ropeload = transforms.reconciliation.table2_check with the example "
            f"hoist ({EXAMPLE_HOIST.name}: {hoist.conveyance.mass_kg / 1e3:g} t cage, "
            f"{hoist.conveyance.tail_ropes} tail ropes of "
            f"{hoist.ropes.tail_rope_mass_per_length_kg_m:g} kg/m) on Table 2's rope "
            "tensions.",
            "error = sum of the four ropes / expected load - 1; gain (the paper's "
            "'compensation rate') = sum after / sum before - 1; imbalance = largest "
            "|T_i - mean| / mean of the four ropes.",
        ],
    )
    printed = {r["position"]: r for r in table.iter_rows(named=True)}
    for row in check.iter_rows(named=True):
        pos = row["position"]
        t2 = printed[pos]
        kn = 1e-3
        expected_hoist_kn = row["expected_from_hoist_n"] * kn
        section.rows += [
            Row(f"{pos}: tail rope mass", "t", t2["tail_rope_mass_t"],
                row["tail_rope_mass_kg"] / 1e3, ".3f", "ropeload: 2 x 6.2 kg/m x length"),
            Row(f"{pos}: expected load", "kN", t2["total_mass_t"] * 1e3 * G_STANDARD * kn,
                expected_hoist_kn, ".2f", "paper: printed total mass x g; ropeload: hoist model"),
            Row(f"{pos}: sum of 4 ropes, before", "kN", t2["sum_before_kn"],
                row["sum_before_n"] * kn, ".1f", "paper: printed sum; ropeload: 4 ropes added"),
            Row(f"{pos}: sum of 4 ropes, after", "kN", t2["sum_after_kn"],
                row["sum_after_n"] * kn, ".1f", "paper: printed sum; ropeload: 4 ropes added"),
            Row(f"{pos}: error before compensation", "%", None,
                100 * (row["sum_before_n"] * kn / expected_hoist_kn - 1), ".1f",
                "not printed"),
            Row(f"{pos}: error after compensation", "%", None,
                100 * (row["sum_after_n"] * kn / expected_hoist_kn - 1), ".1f",
                "not printed"),
            Row(f"{pos}: gain (compensation rate)", "%",
                data.TEXT_PITHEAD_GAIN_PERCENT if pos == "pithead" else None,
                100 * row["gain_fraction"], ".1f",
                "paper: text, pithead only" if pos == "pithead" else "not printed"),
            Row(f"{pos}: rope imbalance, before", "%", None,
                100 * row["imbalance_before_fraction"], ".1f", "not printed"),
            Row(f"{pos}: rope imbalance, after", "%", None,
                100 * row["imbalance_after_fraction"], ".1f", "not printed"),
        ]  # fmt: skip
        if pos == "pithead":
            section.rows.append(
                Row("pithead: sum before, as in the text", "kN", data.TEXT_PITHEAD_BEFORE_KN,
                    row["sum_before_n"] * kn, ".1f", "erratum: Table 2 sums to 141.8 kN")
            )  # fmt: skip
    pithead = check.filter(pl.col("position") == "pithead").row(0, named=True)
    text_gain = 100 * (pithead["sum_after_n"] / (data.TEXT_PITHEAD_BEFORE_KN * 1e3) - 1)
    section.notes += [
        f"Erratum: the text's pithead 145.2 kN before compensation would give a gain of "
        f"{text_gain:.1f} %, not the text's 9.7 %; Table 2's own sum, 141.8 kN, gives "
        f"{100 * pithead['gain_fraction']:.1f} %. Table 2 is used.",
        "The expected loads from ropeload's hoist model equal the printed total masses x g "
        f"(largest difference {_largest_gap(check):.2g} kN): the description is the paper's.",
        f"Errors before compensation {_span(check['error_before_fraction'])}, after "
        f"{_span(check['error_after_fraction'])}; largest rope imbalance after "
        f"{100 * check['imbalance_after_fraction'].max():.1f} % (before "
        f"{100 * check['imbalance_before_fraction'].max():.1f} %).",
    ]
    _table2_figure(section, check, out_dir)
    section.write_rows(out_dir)
    return section


def _span(fraction: pl.Series) -> str:
    return f"{100 * fraction.min():+.1f} .. {100 * fraction.max():+.1f} %"


def _largest_gap(check: pl.DataFrame) -> float:
    return float((check["expected_from_hoist_n"] - check["expected_load_n"]).abs().max()) / 1e3


def _table2_figure(section: PaperSection, check: pl.DataFrame, out_dir: Path) -> None:
    table = data.table2()
    figure = new_figure(11.0, 4.2)
    left, right = figure.subplots(1, 2)
    x = np.arange(check.height)
    kn = 1e-3
    left.bar(x - 0.2, check["sum_before_n"].to_numpy() * kn, 0.4, label="before compensation")
    left.bar(x + 0.2, check["sum_after_n"].to_numpy() * kn, 0.4, label="after compensation")
    expected = check["expected_from_hoist_n"].to_numpy() * kn
    left.hlines(expected, x - 0.45, x + 0.45, colors="k", linestyles="--",
                label="expected load (mass x g)")  # fmt: skip
    for k, row in enumerate(check.iter_rows(named=True)):
        for dx, key in ((-0.2, "error_before_fraction"), (0.2, "error_after_fraction")):
            total = row["sum_before_n" if dx < 0 else "sum_after_n"] * kn
            left.annotate(f"{100 * row[key]:+.1f} %", (x[k] + dx, total - 3.0), ha="center",
                          va="top", fontsize=8, color="white")  # fmt: skip
    lengths = check["tail_rope_length_m"]
    labels = [f"{p}\n(tail rope {n:g} m)" for p, n in zip(check["position"], lengths, strict=True)]
    left.set_xticks(x, labels)
    left.set_ylabel("sum of the four rope tensions [kN]")
    left.set_title("Sum of rope tensions against the expected load (error in the bars)",
                   fontsize=10)  # fmt: skip
    left.legend(fontsize=8, loc="upper right")
    left.grid(axis="y", alpha=0.3)
    width = 0.18
    for i in range(1, 5):
        before = table[f"before_kn_{i}"].to_numpy()
        after = table[f"after_kn_{i}"].to_numpy()
        mean_b = table.select(pl.mean_horizontal(pl.col("^before_kn_.$"))).to_series().to_numpy()
        mean_a = table.select(pl.mean_horizontal(pl.col("^after_kn_.$"))).to_series().to_numpy()
        offset = (i - 2.5) * width
        right.bar(x + offset, 100 * (after / mean_a - 1), width, color=f"C{i - 1}",
                  label=f"rope {i}, after")  # fmt: skip
        right.plot(x + offset, 100 * (before / mean_b - 1), "x", color=f"C{i - 1}",
                   label="x: before, same colours" if i == 1 else None)  # fmt: skip
    right.axhline(0.0, color="k", lw=0.8)
    right.set_xticks(x, list(check["position"]))
    right.set_ylabel("rope tension - mean of the four [% of mean]")
    right.set_title("Rope imbalance (bars: after, x: before compensation)", fontsize=10)
    right.legend(fontsize=7, ncol=2)
    right.grid(axis="y", alpha=0.3)
    figure.suptitle("Paper Table 2 (section 5.2 field test) with ropeload's expected loads")
    save_figure(figure, section, out_dir)
