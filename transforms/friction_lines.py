"""Straight lines in pressure (paper eq 17 form) and the paper's Table 1 and eq 17.

    :func:`fit_line` -- (weighted) least squares value = a + b p with standard errors.
    :func:`fit_table1` -- OLS lines for every column of paper Table 1.
    :func:`law_relative_sigma` -- the law's relative standard uncertainty as a new
    seal would follow it: the capacity lines' scatter about themselves and their own
    standard error (what the compensation's 95 % band takes, ``[friction]
    relative_uncertainty``).
    :func:`compare_with_eq17` -- OLS lines against the paper's printed eq 17: whether
    eq 17 is the OLS value to its printed digits, and whether it is statistically
    consistent with the data (per coefficient and as a whole line).
    :data:`EQ17` -- eq 17 as printed (strings: the printed precision matters).

Re-exported by :mod:`transforms.friction_fit`, whose calibration fits these lines
through per-pressure Stribeck fits. No file reads here: callers pass frames and arrays in.
"""

from __future__ import annotations

from dataclasses import dataclass
from decimal import Decimal

import numpy as np
import polars as pl
from scipy import stats

__all__ = [
    "EQ17",
    "TABLE1_COLUMNS",
    "LinearFit",
    "compare_with_eq17",
    "fit_line",
    "fit_table1",
    "law_relative_sigma",
]


#: Table 1 columns (pressure first) as in ``table1_leuven_parameters.csv``.
TABLE1_COLUMNS = (
    "oil_pressure_mpa",
    "coulomb_friction",
    "max_static_friction",
    "stribeck_speed",
    "viscous_coefficient",
)

#: Paper eq 17 as printed: column -> (intercept, slope per MPa), in Table 1's units.
EQ17: dict[str, tuple[str, str]] = {
    "coulomb_friction": ("0.0357", "0.0254"),
    "max_static_friction": ("0.1276", "0.0253"),
    "stribeck_speed": ("8.3503", "-0.3966"),
    "viscous_coefficient": ("0.001208", "0.00006"),
}


@dataclass(frozen=True)
class LinearFit:
    """A straight line y = intercept + slope * x fitted by (weighted) least squares.

    ``se_*`` are 1-sigma standard errors and ``cov_intercept_slope`` their covariance
    (strongly negative when the x values are far from 0: the two coefficients are not
    independent); ``residuals`` are y - fit per point; ``r_squared`` the (weighted)
    coefficient of determination; ``n`` the points; ``x_range`` the smallest and
    largest x fitted.
    """

    intercept: float
    slope: float
    se_intercept: float
    se_slope: float
    residuals: np.ndarray
    r_squared: float
    n: int
    cov_intercept_slope: float = 0.0
    x_range: tuple[float, float] = (0.0, 0.0)

    def __call__(self, x: np.ndarray | float) -> np.ndarray:
        return self.intercept + self.slope * np.asarray(x, dtype=np.float64)

    @property
    def covariance(self) -> np.ndarray:
        """2 x 2 covariance matrix of (intercept, slope)."""
        return np.array(
            [
                [self.se_intercept**2, self.cov_intercept_slope],
                [self.cov_intercept_slope, self.se_slope**2],
            ]
        )

    def se_line(self, x: np.ndarray | float) -> np.ndarray:
        """Standard error of the fitted line's value at ``x`` (from the covariance)."""
        x = np.asarray(x, dtype=np.float64)
        var = self.se_intercept**2 + 2.0 * x * self.cov_intercept_slope + x**2 * self.se_slope**2
        return np.sqrt(np.maximum(var, 0.0))


def fit_line(
    x: np.ndarray,
    y: np.ndarray,
    sigma: np.ndarray | None = None,
    *,
    absolute_sigma: bool = False,
) -> LinearFit:
    r"""Least-squares straight line with standard errors.

    Minimises :math:`\sum_i w_i (y_i - a - b x_i)^2`, w_i = 1/sigma_i^2 (1 without
    ``sigma``). The covariance is :math:`(X^T W X)^{-1}`, scaled by the reduced
    chi-square s^2 = sum w r^2 / (n - 2) unless ``absolute_sigma`` (then the sigmas
    are taken as the true 1-sigma errors), as in ``scipy.optimize.curve_fit``.

    Parameters
    ----------
    x, y : numpy.ndarray
        Abscissa and values, at least 3 points.
    sigma : numpy.ndarray, optional
        1-sigma uncertainty of each y.
    absolute_sigma : bool
        Use ``sigma`` as absolute (do not rescale by the residual scatter).

    Returns
    -------
    LinearFit

    >>> f = fit_line(np.array([0.0, 1.0, 2.0, 3.0]), np.array([1.0, 3.1, 4.9, 7.0]))
    >>> round(f.intercept, 3), round(f.slope, 3)
    (1.03, 1.98)
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 1 or x.size < 3:
        raise ValueError("fit_line: need 1-d x and y of equal length >= 3")
    w = np.ones_like(y) if sigma is None else 1.0 / np.asarray(sigma, dtype=np.float64) ** 2
    design = np.column_stack([np.ones_like(x), x])
    normal = design.T @ (design * w[:, None])
    coef = np.linalg.solve(normal, design.T @ (w * y))
    residuals = y - design @ coef
    cov = np.linalg.inv(normal)
    chi2 = float(np.sum(w * residuals**2))
    if not (absolute_sigma and sigma is not None):
        cov = cov * chi2 / (x.size - 2)
    y_mean = np.sum(w * y) / np.sum(w)
    total = float(np.sum(w * (y - y_mean) ** 2))
    return LinearFit(
        intercept=float(coef[0]),
        slope=float(coef[1]),
        se_intercept=float(np.sqrt(cov[0, 0])),
        se_slope=float(np.sqrt(cov[1, 1])),
        residuals=residuals,
        r_squared=1.0 - chi2 / total if total > 0 else 1.0,
        n=int(x.size),
        cov_intercept_slope=float(cov[0, 1]),
        x_range=(float(x.min()), float(x.max())),
    )


def law_relative_sigma(coulomb: LinearFit, static: LinearFit, x: np.ndarray) -> float:
    r"""Relative standard uncertainty (1 sigma) of a friction law's capacity as a new
    seal of the rig's kind follows it: the larger of the Coulomb and static lines'
    (eq 17), each the RMS over the fitted pressures ``x`` of

    .. math:: u_{rel}(x_k) = \sqrt{s_{rel}^2 + (\mathrm{se}_{line}(x_k) / \ell_k)^2},
       \qquad s_{rel}^2 = \frac{1}{n - 2} \sum_k \left(\frac{r_k}{\ell_k}\right)^2,
       \qquad \ell_k = a + b x_k,

    the prediction sigma of a new value (Montgomery and Runger, *Applied Statistics and
    Probability for Engineers*, 11-5.2: the points' scatter about the line and the
    line's own standard error, from the fit's covariance, :meth:`LinearFit.se_line`,
    weighted or not), with the scatter taken relative to the line: friction scatters in
    proportion to its level (Table 1's Coulomb residuals grow from 0.001 at 2 MPa to
    0.02 at 11-12 MPa), and the band applies the uncertainty as a share of each seal's
    friction. NaN where a line is not clearly positive over the fitted pressures (its
    least value under a tenth of its largest): no relative uncertainty then.

    It is the calibration's statistical uncertainty, which ``ropeload calibrate``
    writes into the ``[friction]`` section (``relative_uncertainty``) and the
    compensation's 95 % band takes (:mod:`transforms.uncertainty`, part 2). Seals that
    age, or run hotter than the rig's, depart further: a mine that knows by how much
    states the larger value.

    ``x`` are the fit's abscissae (``r_k`` its residuals). Paper Table 1 (OLS): Coulomb
    4.7 % (its points' own relative scatter 3.5 %), static 1.8 %.

    Five points 1 % off their line, alternately up and down: the scatter over 3
    degrees of freedom and the line's own error, about 1.6 %:

    >>> p = np.array([2.0, 4.0, 6.0, 8.0, 10.0])
    >>> line = fit_line(p, (0.1 + 0.02 * p) * np.array([1.01, 0.99, 1.01, 0.99, 1.01]))
    >>> round(law_relative_sigma(line, line, p), 3)
    0.016
    """
    x = np.asarray(x, dtype=np.float64)
    sigmas = []
    for fit in (coulomb, static):
        if x.shape != fit.residuals.shape:
            raise ValueError("law_relative_sigma: one abscissa per fitted point")
        level = fit(x)
        if not level.min() > 0.1 * level.max():
            return float("nan")
        scatter2 = float(np.sum((fit.residuals / level) ** 2)) / (fit.n - 2)
        relative2 = scatter2 + (fit.se_line(x) / level) ** 2
        sigmas.append(float(np.sqrt(np.mean(relative2))))
    return max(sigmas)


def fit_table1(table1: pl.DataFrame) -> dict[str, LinearFit]:
    """OLS line in pressure for each parameter column of paper Table 1.

    ``table1`` has the columns of :data:`TABLE1_COLUMNS`; the lines are in Table 1's
    own units (pressure in MPa; forces and speed as printed, unitless in the paper:
    see NOTES.md and ``[friction] force_unit``).
    """
    missing = set(TABLE1_COLUMNS) - set(table1.columns)
    if missing:
        raise ValueError(f"fit_table1: missing columns {sorted(missing)}")
    p = table1["oil_pressure_mpa"].cast(pl.Float64).to_numpy()
    return {c: fit_line(p, table1[c].cast(pl.Float64).to_numpy()) for c in TABLE1_COLUMNS[1:]}


def _last_place(text: str) -> float:
    exponent = Decimal(text).as_tuple().exponent
    return 10.0 ** int(exponent)  # type: ignore[arg-type]


def compare_with_eq17(fits: dict[str, LinearFit], *, confidence: float = 0.95) -> pl.DataFrame:
    """Compare OLS lines with the paper's eq 17, one row per parameter and coefficient.

    Two different questions, answered in separate columns:

    *Is eq 17 the OLS line of Table 1?* ``reproduced``: True when eq 17 equals the OLS
    value to within one unit of the last decimal eq 17 prints (so a rounded or
    truncated OLS value counts as reproduced). The OLS line of 11 given points is
    unique: this is arithmetic, not statistics.

    *Is eq 17 consistent with the data?* ``z`` = (eq17 - ols) / se, against the
    two-sided ``confidence`` quantile of Student's t with n - 2 degrees of freedom
    (``z_limit``, 2.26 for 11 points at 95 %): ``consistent`` when |z| < z_limit. The
    two coefficients of a line are strongly correlated (Table 1's pressures are far
    from 0), so the line as a whole is also tested: ``line_f`` = d^T C^-1 d / 2 with
    d = eq17 - ols of (intercept, slope) and C their covariance, against F(2, n - 2)
    (``line_p`` its p-value; ``line_consistent`` when line_p > 1 - confidence). The
    same ``line_*`` values are on both rows of a parameter. ``line_gap_se`` is the
    largest |eq17(p) - ols(p)| / se_line(p) over the fitted pressure range and
    ``line_gap_at`` where it is.

    A coefficient can be "not reproduced" (eq 17 is not the OLS value of the printed
    table) and still be consistent with the data; and two coefficients each within
    their interval can make a line that is not, when the differences go against
    their correlation.
    """
    rows = []
    for name, (a_txt, b_txt) in EQ17.items():
        fit = fits[name]
        dof = max(fit.n - 2, 1)
        z_limit = float(stats.t.ppf(0.5 + confidence / 2.0, dof))
        paper = np.array([float(a_txt), float(b_txt)])
        d = paper - np.array([fit.intercept, fit.slope])
        line_f = float(d @ np.linalg.solve(fit.covariance, d)) / 2.0
        line_p = float(stats.f.sf(line_f, 2, dof))
        x = np.linspace(*fit.x_range, 201)
        gap = np.abs(d[0] + d[1] * x) / fit.se_line(x)
        k = int(np.argmax(gap))
        for coefficient, printed, ols, se in (
            ("intercept", a_txt, fit.intercept, fit.se_intercept),
            ("slope", b_txt, fit.slope, fit.se_slope),
        ):
            value = float(printed)
            z = (value - ols) / se
            rows.append(
                {
                    "parameter": name,
                    "coefficient": coefficient,
                    "ols": ols,
                    "se": se,
                    "eq17": value,
                    "difference": value - ols,
                    "z": z,
                    "reproduced": abs(value - ols) < _last_place(printed),
                    "z_limit": z_limit,
                    "consistent": abs(z) < z_limit,
                    "line_f": line_f,
                    "line_p": line_p,
                    "line_consistent": line_p > 1.0 - confidence,
                    "line_gap_se": float(gap[k]),
                    "line_gap_at": float(x[k]),
                }
            )
    return pl.DataFrame(rows)
