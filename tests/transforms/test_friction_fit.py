"""Tests for transforms.friction_fit: Table 1 lines, Stribeck fits, calibration."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

from physics.friction_law import stribeck_friction
from transforms.friction_fit import (
    EQ17,
    compare_with_eq17,
    fit_friction_law,
    fit_line,
    fit_stribeck,
    fit_table1,
)
from transforms.friction_lines import law_relative_sigma

TABLE1 = Path("/work/shared/paper/table1_leuven_parameters.csv")


@pytest.fixture(scope="module")
def table1() -> pl.DataFrame:
    if TABLE1.exists():
        return pl.read_csv(TABLE1)
    # Table 1 as printed in the paper (same numbers as the CSV)
    return pl.DataFrame(
        {
            "oil_pressure_mpa": list(range(2, 13)),
            "coulomb_friction": [
                0.0799,
                0.1095,
                0.1331,
                0.1557,
                0.1813,
                0.2116,
                0.2368,
                0.2584,
                0.2963,
                0.3356,
                0.3192,
            ],
            "max_static_friction": [
                0.1771,
                0.1993,
                0.2360,
                0.2578,
                0.2770,
                0.2983,
                0.3279,
                0.3586,
                0.3809,
                0.4093,
                0.4277,
            ],
            "stribeck_speed": [
                7.8386,
                6.1813,
                6.7047,
                6.0063,
                5.9152,
                5.5787,
                5.2612,
                4.7855,
                4.3099,
                4.1943,
                3.4387,
            ],
            "viscous_coefficient": [
                0.0013,
                0.0014,
                0.0015,
                0.0015,
                0.0017,
                0.0017,
                0.0017,
                0.0018,
                0.0019,
                0.0019,
                0.0020,
            ],
        }
    )


def test_table1_ols_against_polyfit_and_notes(table1):
    fits = fit_table1(table1)
    p = table1["oil_pressure_mpa"].to_numpy().astype(float)
    for column, fit in fits.items():
        y = table1[column].to_numpy()
        (slope, intercept), cov = np.polyfit(p, y, 1, cov=True)
        assert fit.intercept == pytest.approx(intercept, rel=1e-10)
        assert fit.slope == pytest.approx(slope, rel=1e-10)
        assert fit.se_slope == pytest.approx(np.sqrt(cov[0, 0]), rel=1e-8)
        assert fit.se_intercept == pytest.approx(np.sqrt(cov[1, 1]), rel=1e-8)
        np.testing.assert_allclose(fit.residuals, y - (intercept + slope * p), atol=1e-12)
        r2 = 1 - np.sum(fit.residuals**2) / np.sum((y - y.mean()) ** 2)
        assert fit.r_squared == pytest.approx(r2)
    # NOTES.md figures
    assert fits["coulomb_friction"].intercept == pytest.approx(0.0292, abs=5e-5)
    assert fits["coulomb_friction"].slope == pytest.approx(0.0259, abs=5e-5)
    assert fits["max_static_friction"].intercept == pytest.approx(0.1276, abs=5e-5)
    assert fits["max_static_friction"].slope == pytest.approx(0.0253, abs=5e-5)
    assert fits["stribeck_speed"].intercept == pytest.approx(8.034, abs=5e-4)
    assert fits["stribeck_speed"].slope == pytest.approx(-0.3657, abs=5e-5)
    assert fits["viscous_coefficient"].intercept == pytest.approx(0.00121, abs=5e-6)
    assert fits["viscous_coefficient"].slope == pytest.approx(0.000066, abs=5e-7)


def test_compare_with_eq17_flags_coulomb_and_stribeck(table1):
    report = compare_with_eq17(fit_table1(table1))
    assert report.height == 8
    reproduced = {
        (r["parameter"], r["coefficient"]): r["reproduced"] for r in report.iter_rows(named=True)
    }
    assert reproduced == {
        ("coulomb_friction", "intercept"): False,
        ("coulomb_friction", "slope"): False,
        ("max_static_friction", "intercept"): True,
        ("max_static_friction", "slope"): True,
        ("stribeck_speed", "intercept"): False,
        ("stribeck_speed", "slope"): False,
        ("viscous_coefficient", "intercept"): True,
        ("viscous_coefficient", "slope"): True,
    }
    row = report.filter(
        (pl.col("parameter") == "coulomb_friction") & (pl.col("coefficient") == "intercept")
    ).row(0, named=True)
    assert row["eq17"] == float(EQ17["coulomb_friction"][0])
    assert row["difference"] == pytest.approx(0.0357 - 0.02922, abs=1e-5)


def test_compare_with_eq17_statistics_against_polyfit(table1):
    """z per coefficient and the F test per line, from numpy's polyfit covariance."""
    report = compare_with_eq17(fit_table1(table1))
    p = table1["oil_pressure_mpa"].to_numpy().astype(float)
    t_975_9 = 2.262  # Student t, 97.5 % quantile, 9 degrees of freedom (printed tables)
    for name, (a_txt, b_txt) in EQ17.items():
        (slope, intercept), cov = np.polyfit(p, table1[name].to_numpy(), 1, cov=True)
        cov = cov[::-1, ::-1]  # polyfit orders (slope, intercept)
        d = np.array([float(a_txt) - intercept, float(b_txt) - slope])
        f = d @ np.linalg.solve(cov, d) / 2
        rows = {r["coefficient"]: r for r in report.iter_rows(named=True) if r["parameter"] == name}
        for k, coefficient in enumerate(("intercept", "slope")):
            row = rows[coefficient]
            assert row["z"] == pytest.approx(d[k] / np.sqrt(cov[k, k]), rel=1e-6)
            assert row["z_limit"] == pytest.approx(t_975_9, abs=5e-4)
            assert row["consistent"] == (abs(row["z"]) < t_975_9)
            assert row["line_f"] == pytest.approx(f, rel=1e-6)
    rows = list(report.iter_rows(named=True))
    # Table 1: every printed coefficient within its 95 % interval (largest |z| 1.52) ...
    assert max(abs(r["z"]) for r in rows) == pytest.approx(1.52, abs=0.01)
    assert all(r["consistent"] for r in rows)
    # ... but the Kv line as printed (slope 0.00006 for 0.0000664) is not: F(2, 9) = 6.86
    # against the 95 % point 4.26; the other lines are consistent
    line = {r["parameter"]: r for r in rows}
    assert line["viscous_coefficient"]["line_f"] == pytest.approx(6.86, abs=0.01)
    assert line["viscous_coefficient"]["line_p"] == pytest.approx(0.0155, abs=5e-4)
    assert {n for n, r in line.items() if r["line_consistent"]} == {
        "coulomb_friction",
        "max_static_friction",
        "stribeck_speed",
    }


def test_eq17_tests_reject_a_true_line_5_percent_of_the_time():
    """Data drawn around eq 17 itself: each test must reject at its nominal 5 %."""
    rng = np.random.default_rng(17)
    p = np.arange(2.0, 13.0)
    trials, rejected_z, rejected_line = 800, 0, 0
    for _ in range(trials):
        frame = {"oil_pressure_mpa": p}
        for name, (a_txt, b_txt) in EQ17.items():
            line = float(a_txt) + float(b_txt) * p
            frame[name] = line + rng.normal(0.0, 0.02 * np.abs(line).mean(), p.size)
        report = compare_with_eq17(fit_table1(pl.DataFrame(frame)))
        rejected_z += int((~report["consistent"]).sum())
        rejected_line += int((~report["line_consistent"]).sum()) // 2
    # binomial: 5 % of 6400 coefficient tests (sd 0.27 %), of 3200 line tests (sd 0.39 %)
    assert rejected_z / (8 * trials) == pytest.approx(0.05, abs=0.012)
    assert rejected_line / (4 * trials) == pytest.approx(0.05, abs=0.015)


def test_fit_line_weighted_known_truth():
    rng = np.random.default_rng(11)
    x = np.linspace(2, 12, 200)
    sigma = np.where(x < 7, 0.01, 0.1)
    y = 0.5 + 0.25 * x + rng.normal(0, sigma)
    fit = fit_line(x, y, sigma, absolute_sigma=True)
    assert fit.intercept == pytest.approx(0.5, abs=4 * fit.se_intercept)
    assert fit.slope == pytest.approx(0.25, abs=4 * fit.se_slope)
    # weighted standard error, independently: (X^T W X)^-1
    design = np.column_stack([np.ones_like(x), x])
    cov = np.linalg.inv(design.T @ (design / sigma[:, None] ** 2))
    assert fit.se_slope == pytest.approx(np.sqrt(cov[1, 1]), rel=1e-10)
    with pytest.raises(ValueError):
        fit_line(np.zeros(2), np.zeros(2))


def _rig_points(fc, fs, vs, kv, noise, rng):
    speeds = np.geomspace(0.05 * vs, 20 * vs, 25)
    v = np.concatenate([speeds, -speeds])
    return v, stribeck_friction(v, fc, fs, vs, kv) + rng.normal(0, noise, v.size)


@pytest.mark.parametrize("p_mpa", [2.0, 7.0, 12.0])
def test_fit_stribeck_recovers_truth(p_mpa):
    rng = np.random.default_rng(int(p_mpa))
    area = np.pi * 0.1**2 / 4
    fc = (0.0292 + 0.0259 * p_mpa) * 1e6 * area  # N (Table 1 read as MPa)
    fs = (0.1276 + 0.0253 * p_mpa) * 1e6 * area
    vs = (8.034 - 0.3657 * p_mpa) * 1e-3  # m/s
    kv = (0.00121 + 0.000066 * p_mpa) * 1e6 * area / 1e-3  # N s/m
    v, f = _rig_points(fc, fs, vs, kv, 0.005 * fs, rng)
    fit = fit_stribeck(v, f)
    assert fit.success
    for got, true, sig in zip(
        (fit.fc, fit.fs, fit.vs, fit.kv), (fc, fs, vs, kv), fit.sigma, strict=True
    ):
        assert got == pytest.approx(true, rel=0.05)
        assert abs(got - true) < 5 * sig  # the uncertainty is honest
    assert fit.rms == pytest.approx(0.005 * fs, rel=0.4)


def test_fit_friction_law_recovers_slopes():
    rng = np.random.default_rng(5)
    truth = {"fc": (50.0, 2e-5), "fs": (100.0, 2e-5), "vs": (8e-3, -4e-10), "kv": (1e4, 5e-4)}
    pressures = np.arange(2, 13) * 1e6
    fits = []
    for p in pressures:
        par = [a + b * p for a, b in truth.values()]
        v, f = _rig_points(*par, 0.003 * par[1], rng)
        fits.append(fit_stribeck(v, f))
    law, lines = fit_friction_law(
        pressures,
        fits,
        bristle_stiffness_n_m=2.5e7,
        bristle_damping_n_s_m=2e4,
        presliding_elements=4,
    )
    for (a, b), (ga, gb) in zip(
        truth.values(),
        (law.coulomb_n, law.static_n, law.stribeck_speed_m_s, law.viscous_n_s_m),
        strict=True,
    ):
        assert gb == pytest.approx(b, rel=0.10)
        assert ga + gb * 7e6 == pytest.approx(a + b * 7e6, rel=0.03)
    assert law.presliding_elements == 4
    assert lines["coulomb_n"].residuals.shape == (11,)


def test_law_relative_sigma_is_the_relative_error_of_a_new_seal():
    """Lines through 11 pressures (Table 1's) whose points scatter 5 % of the line: the
    relative sigma is the RMS relative error of a fresh point at each pressure against
    the fitted line over 400 draws (the truth by simulation), never under it and at most
    15 % over it (the line's own standard error is the fit's, taken as even in absolute
    terms, which overstates it at the low end of a steep line); the larger of the two
    lines counts, whichever it is; a line through zero has none."""
    rng = np.random.default_rng(5)
    p = np.arange(2.0, 13.0)
    coulomb, static = 0.03 + 0.026 * p, 0.13 + 0.025 * p
    for noisy, quiet, line in ((0.05, 0.01, coulomb), (0.01, 0.05, static)):
        found, errors = [], []
        for _ in range(400):
            fc = fit_line(p, coulomb * (1.0 + rng.normal(0.0, noisy, p.size)))
            fs = fit_line(p, static * (1.0 + rng.normal(0.0, quiet, p.size)))
            found.append(law_relative_sigma(fc, fs, p))
            fit = fc if line is coulomb else fs
            fresh = line * (1.0 + rng.normal(0.0, 0.05, p.size))
            errors.append((fresh - fit(p)) / fit(p))
        truth = np.sqrt(np.mean(np.square(errors)))
        assert truth <= np.sqrt(np.mean(np.square(found))) <= 1.15 * truth
    through_zero = fit_line(p, 0.026 * (p - 2.0) + rng.normal(0.0, 1e-3, p.size))
    assert np.isnan(law_relative_sigma(through_zero, fit_line(p, static), p))
    with pytest.raises(ValueError, match="one abscissa per fitted point"):
        law_relative_sigma(fit_line(p, coulomb), fit_line(p, static), p[:-1])
