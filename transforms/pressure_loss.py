"""Pressure loss in the cylinder branches (paper section 4.1, eq 12-14).

Friction factor
    :func:`reynolds_number` -- Re = |v| d / nu.
    :func:`darcy_friction_factor` -- 64/Re laminar, ``fluids`` (Clamond) turbulent,
    interpolated on a Re grid (never per sample).

Losses
    :func:`pipe_pressure_loss` -- signed along-pipe plus local loss, eq 12-14.
    :func:`globe_valve_k` -- Crane TP-410 K of a fully open globe valve via ``fluids``.

The hoist's sensor branch (contract section 1a)
    :func:`sensor_minus_chamber_pa` -- p_sensor - p_chamber from piston velocity.
    :func:`sensor_minus_chamber_expr` -- the same as a polars expression.

Sign: a loss is positive in the direction of flow (pressure falls along the flow), so
the signed loss has the sign of the velocity.
"""

from __future__ import annotations

from functools import lru_cache

import fluids
import numpy as np
import polars as pl

from schemas.hoist import HoistDescription
from transforms.oil import kinematic_viscosity

__all__ = [
    "RE_LAMINAR",
    "RE_TURBULENT",
    "darcy_friction_factor",
    "globe_valve_k",
    "pipe_pressure_loss",
    "reynolds_number",
    "sensor_minus_chamber_expr",
    "sensor_minus_chamber_pa",
]

#: Upper Reynolds number of the laminar law lambda = 64/Re [-].
RE_LAMINAR = 2000.0
#: Lower Reynolds number of the fully turbulent correlation [-].
RE_TURBULENT = 4000.0
_RE_MAX = 1e8
_GRID_POINTS = 241  # 40 per decade over 4000..1e8: interpolation error < 1e-4 relative


def reynolds_number(
    v_m_s: np.ndarray | float, d_m: float, nu_m2_s: np.ndarray | float
) -> np.ndarray:
    r"""Pipe Reynolds number Re = |v| d / nu [-].

    ``v_m_s`` mean velocity [m/s], ``d_m`` inner diameter [m], ``nu_m2_s`` kinematic
    viscosity [m2/s].

    >>> float(reynolds_number(-1.0, 0.01, 46e-6)) > 217
    True
    """
    return np.abs(np.asarray(v_m_s, dtype=np.float64)) * d_m / np.asarray(nu_m2_s)


@lru_cache(maxsize=64)
def _turbulent_grid(relative_roughness: float) -> tuple[np.ndarray, np.ndarray]:
    log_re = np.linspace(np.log10(RE_TURBULENT), np.log10(_RE_MAX), _GRID_POINTS)
    log_f = np.log10(
        [fluids.friction_factor(10.0**x, eD=relative_roughness, Method="Clamond") for x in log_re]
    )
    return log_re, log_f


def darcy_friction_factor(re: np.ndarray | float, relative_roughness: float = 0.0) -> np.ndarray:
    r"""Darcy friction factor lambda of paper eq 12, laminar to turbulent.

    .. math::
        \lambda = \begin{cases}
        64/Re & Re \le 2000 \\
        \text{linear in } Re \text{ between the two} & 2000 < Re < 4000 \\
        \lambda_{Colebrook}(Re, \epsilon/D) & Re \ge 4000
        \end{cases}

    The turbulent branch is ``fluids.friction_factor(Method="Clamond")`` (Colebrook
    solved to machine precision), evaluated once per roughness on a log grid of 241
    Reynolds numbers and interpolated in log-log (relative error < 1e-4).

    Parameters
    ----------
    re : array_like
        Reynolds number [-], > 0.
    relative_roughness : float
        epsilon / D [-].

    Returns
    -------
    numpy.ndarray
        Darcy friction factor [-].

    Notes
    -----
    64/Re is exact for fully developed laminar flow (Hagen-Poiseuille); the
    transitional band is not predictable and is bridged linearly for continuity.

    >>> float(darcy_friction_factor(1000.0))
    0.064
    >>> round(float(darcy_friction_factor(1e5, 1e-4)), 5)
    0.01851

    References
    ----------
    Clamond, D. (2009), Efficient resolution of the Colebrook equation, Ind. Eng.
    Chem. Res. 48(7), 3665-3671, doi:10.1021/ie801626g.
    """
    re_arr = np.asarray(re, dtype=np.float64)
    with np.errstate(divide="ignore"):
        friction = 64.0 / re_arr
    beyond = re_arr > RE_LAMINAR
    if not np.any(beyond):  # the usual case on a hoist: laminar everywhere, 64/Re only
        return friction
    log_re, log_f = _turbulent_grid(float(relative_roughness))
    re_beyond = re_arr[beyond] if friction.ndim else re_arr
    f_turb_start = 10.0 ** log_f[0]
    weight = np.clip((re_beyond - RE_LAMINAR) / (RE_TURBULENT - RE_LAMINAR), 0.0, 1.0)
    transitional = (1.0 - weight) * (64.0 / RE_LAMINAR) + weight * f_turb_start
    turbulent = 10.0 ** np.interp(np.log10(np.maximum(re_beyond, RE_TURBULENT)), log_re, log_f)
    value = np.where(re_beyond < RE_TURBULENT, transitional, turbulent)
    if friction.ndim == 0:
        return value
    friction[beyond] = value
    return friction


def pipe_pressure_loss(
    v_m_s: np.ndarray | float,
    d_m: float,
    length_m: float,
    nu_m2_s: np.ndarray | float,
    rho_kg_m3: float,
    *,
    roughness_m: float = 0.0,
    k_local: float = 0.0,
) -> np.ndarray:
    r"""Signed pressure loss along a pipe with local losses, paper eq 12-14.

    .. math::
        \Delta p = \left(\lambda \frac{l}{d} + \xi\right)\frac{\rho v |v|}{2}

    (eq 12 along the pipe, eq 13 local, eq 14 their sum), with lambda from
    :func:`darcy_friction_factor`. In laminar flow the along-pipe part is the
    Hagen-Poiseuille loss 32 mu l v / d^2 (paper eq 6 per unit area), linear in v.

    Parameters
    ----------
    v_m_s : array_like
        Mean oil velocity in the pipe [m/s], signed.
    d_m : float
        Pipe inner diameter [m].
    length_m : float
        Pipe length [m].
    nu_m2_s : array_like
        Kinematic viscosity [m2/s].
    rho_kg_m3 : float
        Oil density [kg/m3].
    roughness_m : float
        Absolute wall roughness [m].
    k_local : float
        Sum of local loss coefficients xi (valves, fittings) referred to v [-].

    Returns
    -------
    numpy.ndarray
        Pressure drop in the direction of ``v`` [Pa]; same sign as v, 0 at v = 0.

    Notes
    -----
    Loss coefficients of valves (e.g. Crane's K) are stated for turbulent flow; in
    laminar flow the real local loss is larger (see the 2-K/3-K methods in
    ``fluids``), so xi rho v^2/2 underestimates it there.

    >>> dp = pipe_pressure_loss(1.0, 0.01, 1.0, 46e-6, 900.0)   # Re 217: laminar
    >>> round(float(dp), 3)   # 32 mu l v / d^2 = 32 * 0.0414 / 1e-4
    13248.0
    """
    v = np.asarray(v_m_s, dtype=np.float64)
    re = reynolds_number(v, d_m, nu_m2_s)
    lam = darcy_friction_factor(np.where(re > 0.0, re, 1.0), roughness_m / d_m)
    dynamic = 0.5 * rho_kg_m3 * v * np.abs(v)
    return (lam * length_m / d_m + k_local) * dynamic


def globe_valve_k(d_m: float) -> float:
    """Loss coefficient K of a fully open globe valve of bore ``d_m`` [m] (Crane TP-410).

    K = 340 f_T with f_T Crane's fully turbulent friction factor for clean commercial
    steel of that size, via ``fluids.K_globe_valve_Crane`` [-].

    >>> round(globe_valve_k(0.01), 2)
    9.88

    References
    ----------
    Crane Co. (2009), Flow of Fluids Through Valves, Fittings, and Pipe, TP-410, A-27.
    """
    return float(fluids.K_globe_valve_Crane(d_m, d_m))


def _branch_constants(hoist: HoistDescription) -> tuple[float, float, float, float, float]:
    piping = hoist.piping
    area_ratio = hoist.cylinders.bore_area_m2 / piping.area_m2
    k_local = piping.valve_loss_coefficient + piping.fittings_loss_coefficient_chamber_to_sensor
    return area_ratio, piping.bore_m, piping.length_chamber_to_sensor_m, piping.roughness_m, k_local


def sensor_minus_chamber_pa(
    v_piston_m_s: np.ndarray | float,
    hoist: HoistDescription,
    t_oil_c: np.ndarray | float | None = None,
    *,
    nu_m2_s: np.ndarray | float | None = None,
) -> np.ndarray:
    r"""Sensor minus chamber pressure of a cylinder branch (contract 1a; eq 12-14) [Pa].

    Oil leaves the rodless chamber at Q = A_bore v (v > 0: rod pulled out) and passes
    the globe valve and the first branch part before the sensor tee:

    .. math::
        p_{sensor} - p_{chamber} = -\left(\lambda \frac{l_{cs}}{d} + K_{valve}
        + K_{fittings,cs}\right) \frac{\rho u |u|}{2}, \qquad u = \frac{A_{bore}}{A_{pipe}} v

    so the sensor reads low while oil flows out, high while it flows in, and equal at
    rest.

    Parameters
    ----------
    v_piston_m_s : array_like
        Piston velocity [m/s], positive rod out.
    hoist : HoistDescription
        Supplies bore, ``piping`` (bore, ``length_chamber_to_sensor``, roughness,
        ``valve_loss_coefficient``, ``fittings_loss_coefficient_chamber_to_sensor``)
        and ``oil``.
    t_oil_c : array_like, optional
        Oil temperature [degC] for the viscosity (ASTM D341); default the oil's
        ``reference_temperature``.
    nu_m2_s : array_like, optional
        Kinematic viscosity [m2/s] already computed for ``t_oil_c`` (saves recomputing
        it for each of the four cylinders); overrides ``t_oil_c``.

    Returns
    -------
    numpy.ndarray
        p_sensor - p_chamber [Pa].

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> [float(x) < 0 for x in sensor_minus_chamber_pa(np.array([0.01, -0.01]), hoist)]
    [True, False]
    """
    area_ratio, d, length, roughness, k_local = _branch_constants(hoist)
    if nu_m2_s is None:
        t = hoist.oil.reference_temperature_c if t_oil_c is None else t_oil_c
        nu = kinematic_viscosity(t, hoist.oil)
    else:
        nu = nu_m2_s
    u = np.asarray(v_piston_m_s, dtype=np.float64) * area_ratio
    loss = pipe_pressure_loss(
        u, d, length, nu, hoist.oil.density_kg_m3, roughness_m=roughness, k_local=k_local
    )
    return 0.0 - loss  # not -loss: no -0.0 at rest


def sensor_minus_chamber_expr(
    v_piston_m_s: pl.Expr, hoist: HoistDescription, t_oil_c: pl.Expr | None = None
) -> pl.Expr:
    """Polars expression for :func:`sensor_minus_chamber_pa` (Float64, Pa).

    ``v_piston_m_s`` and the optional ``t_oil_c`` are expressions (columns); the
    numpy function runs once per batch via ``map_batches``. Null velocity gives null.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> df = pl.DataFrame({"v_m_s": [0.0, None]})
    >>> df.select(sensor_minus_chamber_expr(pl.col("v_m_s"), hoist).alias("dp"))["dp"].to_list()
    [0.0, None]
    """
    t_expr = pl.lit(hoist.oil.reference_temperature_c) if t_oil_c is None else t_oil_c

    def _batch(s: pl.Series) -> pl.Series:
        frame = s.struct.unnest()
        v = frame["v"].cast(pl.Float64).to_numpy()
        t = frame["t"].cast(pl.Float64).to_numpy()
        out = sensor_minus_chamber_pa(v, hoist, t)
        return pl.Series(out, dtype=pl.Float64).fill_nan(None)

    return pl.struct(v=v_piston_m_s, t=t_expr).map_batches(_batch, return_dtype=pl.Float64)
