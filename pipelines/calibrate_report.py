"""The printed reports of ``ropeload calibrate``.

:func:`format_calibration` -- per-pressure table, eq-17 lines and TOML of a
calibration. :func:`table1_report` -- OLS lines through paper Table 1 with residuals,
and where they differ from the printed eq 17 (``ropeload calibrate --table1``), in the
words of :func:`eq17_coefficient_verdict`, :func:`eq17_line_verdict` and
:func:`eq17_summary` (also used by :mod:`pipelines.paper.tables`).
"""

from __future__ import annotations

import math

import numpy as np
import polars as pl

from pipelines.calibrate_outputs import LINE_NAMES, CalibrationResult, written_uncertainty
from transforms.friction_fit import compare_with_eq17, fit_table1
from transforms.friction_lines import law_relative_sigma

__all__ = [
    "eq17_coefficient_verdict",
    "eq17_line_verdict",
    "eq17_summary",
    "format_calibration",
    "table1_report",
]


#: Table-1 units of each SI line: (label, unit, scale from SI given the bore area [m2]).
def _table1_units(area_m2: float) -> dict[str, tuple[str, str, float]]:
    force = 1e6 * area_m2  # N per MPa of equivalent pressure
    return {
        "coulomb_n": ("Fc", "MPa", 1.0 / force),
        "static_n": ("Fs", "MPa", 1.0 / force),
        "stribeck_speed_m_s": ("vs", "mm/s", 1e3),
        "viscous_n_s_m": ("Kv", "MPa/(mm/s)", 1e-3 / force),
    }


def format_calibration(result: CalibrationResult) -> str:
    """The report ``ropeload calibrate`` prints: per-pressure table, lines, TOML.

    Table-1 units: friction as equivalent pressure (force / bore area) in MPa, speed in
    mm/s, pressure in MPa; SI forces in N beside them. Each value carries its 1-sigma
    uncertainty (``+-``); each line its standard errors and residual per pressure.
    """
    rig = result.rig
    units = _table1_units(rig.bore_area_m2)
    out = [
        f"ropeload calibrate: rig {result.rig_id}, parameter set {result.parameter_set}, "
        f"run {result.run_id}",
        f"rig: bore {rig.bore_m * 1e3:g} mm, rod {rig.rod_m * 1e3:g} mm, moving mass "
        f"{rig.moving_mass_kg:g} kg; {len(result.inputs)} recording(s), "
        f"{result.steps.height} steady steps",
        *(f"note: {n}" for n in result.notes),
        "",
        "Stribeck fit per pressure (paper eq 16/18; analogue of Table 1), +- 1 sigma.",
        "Friction as equivalent pressure F / A_bore [MPa] (and [N]), speed [mm/s].",
    ]
    header = (
        f"{'p [MPa]':>8} {'steps':>5} {'Fc [MPa]':>18} {'Fs [MPa]':>18} {'vs [mm/s]':>15} "
        f"{'Kv [MPa/(mm/s)]':>22} {'Fc [N]':>8} {'Fs [N]':>8} {'rms [N]':>8}"
    )
    out += [header, "-" * len(header)]
    for row in result.per_pressure.iter_rows(named=True):
        cells = []
        for name, width, fmt in (
            ("coulomb_n", 18, ".4f"),
            ("static_n", 18, ".4f"),
            ("stribeck_speed_m_s", 15, ".3f"),
            ("viscous_n_s_m", 22, ".6f"),
        ):
            scale = units[name][2]
            sigma_key = (
                name.replace("_n", "_sigma_n", 1)
                if name != "stribeck_speed_m_s"
                else ("stribeck_speed_sigma_m_s")
            )
            text = f"{row[name] * scale:{fmt}} +- {row[sigma_key] * scale:{fmt}}"
            cells.append(f"{text:>{width}}")
        out.append(
            f"{row['p_rodless_pa'] / 1e6:8.3f} {row['steps']:5d} {' '.join(cells)} "
            f"{row['coulomb_n']:8.1f} {row['static_n']:8.1f} {row['rms_n']:8.2f}"
        )
    out += ["", "Lines in pressure, value = a + b p (paper eq 17 form), weighted by 1/sigma^2:"]
    p_mpa = result.per_pressure["p_rodless_pa"].to_numpy() / 1e6
    for name in LINE_NAMES:
        label, unit, scale = units[name]
        line = result.lines[name]
        residuals = ", ".join(
            f"{p:.1f}: {r * scale:+.3g}" for p, r in zip(p_mpa, line.residuals, strict=True)
        )
        out.append(
            f"  {label} [{unit}] = {line.intercept * scale:.5g} "
            f"(+- {line.se_intercept * scale:.2g}) + {line.slope * scale * 1e6:.5g} "
            f"(+- {line.se_slope * scale * 1e6:.2g}) p[MPa]"
            f"   R2 {line.r_squared:.4f}"
        )
        out.append(f"      residuals by p [MPa]: {residuals}")
    relative = result.relative_uncertainty
    out += [
        "The law's relative standard uncertainty (Coulomb and static lines, the 95 % band's "
        "1 sigma): " + (f"{100 * relative:.1f} %" if math.isfinite(relative) else "not determined"),
        "",
        "Hoist description snippet:",
        "",
        result.toml.rstrip(),
    ]
    return "\n".join(out) + "\n"


def eq17_coefficient_verdict(row: dict) -> str:
    """One coefficient of eq 17 against the OLS fit, in words (a row of
    :func:`transforms.friction_fit.compare_with_eq17`).

    Two separate statements: whether eq 17 prints the OLS value (arithmetic: the OLS
    line of the printed table is unique) and whether it is within the 95 % interval of
    the OLS estimate (statistics: |z| against Student's t).
    """
    printed = "the OLS value to its printed digits" if row["reproduced"] else "not the OLS value"
    z, limit = abs(row["z"]), row["z_limit"]
    if row["consistent"]:
        stat = f"consistent with OLS at 95 % (|z| {z:.2f} < {limit:.2f})"
    else:
        stat = f"differs from OLS at 95 % (|z| {z:.2f} >= {limit:.2f})"
    return f"{printed}; {stat}"


def eq17_line_verdict(row: dict) -> str:
    """The eq-17 line of one parameter as a whole against the OLS line, in words (F
    test of intercept and slope together, their correlation included)."""
    test = f"F {row['line_f']:.2f}, p {row['line_p']:.2g}"
    if row["line_consistent"]:
        return f"line consistent with the OLS line at 95 % ({test})"
    return (
        f"line differs from the OLS line at 95 % ({test}; "
        f"{row['line_gap_se']:.1f} standard errors apart at {row['line_gap_at']:g} MPa)"
    )


def eq17_summary(compare: pl.DataFrame) -> list[str]:
    """What the comparison of eq 17 with OLS says, in a few sentences."""
    rows = list(compare.iter_rows(named=True))
    names = list(dict.fromkeys(r["parameter"] for r in rows))

    def where(test) -> str:
        chosen = [n for n in names if test([r for r in rows if r["parameter"] == n])]
        return ", ".join(chosen) or "none"

    worst = max(abs(r["z"]) for r in rows)
    out = [
        f"Printed digits: eq 17 is the OLS line of Table 1 for "
        f"{where(lambda rs: all(r['reproduced'] for r in rs))}; not for "
        f"{where(lambda rs: not all(r['reproduced'] for r in rs))}.",
    ]
    if all(r["consistent"] for r in rows):
        out.append(
            f"Statistics: every printed coefficient is within the 95 % interval of its OLS "
            f"estimate (largest |z| {worst:.2f} < {rows[0]['z_limit']:.2f})."
        )
    else:
        out.append(
            "Statistics: outside the 95 % interval of the OLS estimate: "
            + ", ".join(
                f"{r['parameter']} {r['coefficient']} (|z| {abs(r['z']):.2f})"
                for r in rows
                if not r["consistent"]
            )
            + "."
        )
    out.append(
        f"Whole lines at 95 %: consistent for "
        f"{where(lambda rs: rs[0]['line_consistent'])}; different for "
        f"{where(lambda rs: not rs[0]['line_consistent'])}."
    )
    return out


def table1_report(table1: pl.DataFrame) -> str:
    """Ordinary least squares through paper Table 1, residuals, and the eq-17 comparison.

    Fits every column of Table 1 as a + b p (p in MPa) by OLS
    (:func:`transforms.friction_fit.fit_table1`), prints each line with standard errors
    and R^2, the residual at each pressure, and then each coefficient of eq 17 as
    printed against the OLS value (:func:`transforms.friction_fit.compare_with_eq17`):
    whether eq 17 prints the OLS value, and whether it is statistically consistent with
    it (per coefficient, |z| against Student's t at 95 %; per line, an F test of both
    coefficients together). Table 1 has no units (NOTES.md): the numbers are Table 1's
    own (friction read as equivalent pressure in MPa, speed in mm/s).

    ``table1`` has the columns of :data:`transforms.friction_fit.TABLE1_COLUMNS`; the
    caller reads the file.
    """
    fits = fit_table1(table1)
    compare = compare_with_eq17(fits)
    p = table1["oil_pressure_mpa"].cast(pl.Float64).to_numpy()
    out = [
        f"Paper Table 1: ordinary least squares, value = a + b p (p in MPa), {p.size} points.",
        "Units as printed (none given; NOTES.md reads friction as equivalent pressure [MPa]",
        "and speed as [mm/s]). +- is one standard error.",
        "",
    ]
    for name, fit in fits.items():
        out.append(
            f"{name:20s} a = {fit.intercept:.6g} +- {fit.se_intercept:.2g}, "
            f"b = {fit.slope:.6g} +- {fit.se_slope:.2g}, R2 = {fit.r_squared:.4f}, "
            f"residual rms = {float(np.sqrt(np.mean(fit.residuals**2))):.3g}"
        )
    out += ["", "Residuals (Table 1 minus OLS line):"]
    names = list(fits)
    out.append(f"{'p [MPa]':>8} " + " ".join(f"{n:>20s}" for n in names))
    for k, pk in enumerate(p):
        out.append(f"{pk:8.1f} " + " ".join(f"{fits[n].residuals[k]:+20.5f}" for n in names))
    rows = list(compare.iter_rows(named=True))
    out += [
        "",
        "Eq 17 as printed against OLS (z = (eq17 - OLS) / se; 95 % two-sided limit "
        f"|z| < {rows[0]['z_limit']:.2f}, Student t, {p.size - 2} degrees of freedom):",
    ]
    for row in rows:
        out.append(
            f"  {row['parameter']:20s} {row['coefficient']:9s} OLS {row['ols']:+.6g} "
            f"eq17 {row['eq17']:+.6g} (diff {row['difference']:+.3g}, z {row['z']:+.2f}): "
            f"{eq17_coefficient_verdict(row)}"
        )
        if row["coefficient"] == "slope":
            out.append(f"  {'':20s} {'':9s} {eq17_line_verdict(row)}")
    relative = law_relative_sigma(fits["coulomb_friction"], fits["max_static_friction"], p)
    out += [
        "",
        "The law's relative standard uncertainty (the OLS Coulomb and static lines' scatter "
        "and standard error,",
        f"the compensation's 95 % band's 1 sigma): {100 * relative:.1f} %, "
        f"[friction] relative_uncertainty = {written_uncertainty(relative)}",
    ]
    out += ["", "Summary:", *(f"  {line}" for line in eq17_summary(compare))]
    out.append("Use the OLS lines (with their residuals), not eq 17, as the fit of Table 1.")
    return "\n".join(out) + "\n"
