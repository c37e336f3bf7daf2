"""The chamber-to-sensor branch of a rope attachment's cylinder (contract 1a, eq 12-14).

The pressure sensor sits after the globe valve and the first part of the branch pipe,
so while oil flows out of the chamber it reads low by the branch loss
(:func:`physics.branch_loss.pipe_loss_pa`), and high while oil flows in.

    :func:`sensor_branch` -- the hoist's branch as the kernels take it.
    :func:`sensor_minus_chamber_at` -- p_sensor - p_chamber of one sample (numba).
    :func:`sensor_minus_chamber_pa` / :func:`sensor_minus_chamber_expr` -- the same
    over arrays / as a polars expression.
"""

from __future__ import annotations

import numpy as np
import polars as pl
from numba import njit

from physics.branch_loss import COLEBROOK, pipe_loss_pa
from physics.oil import kinematic_viscosity
from schemas.hoist import HoistDescription

__all__ = [
    "sensor_branch",
    "sensor_minus_chamber_at",
    "sensor_minus_chamber_expr",
    "sensor_minus_chamber_pa",
]


def sensor_branch(hoist: HoistDescription) -> np.ndarray:
    """The chamber-to-sensor branch as the kernels take it [-, m, m, kg/m3, -, -].

    ``[A_bore / A_pipe, bore, length chamber -> sensor, density, K valve + K fittings
    (chamber -> sensor), relative roughness]`` (contract 1a), with the hoist's
    ``[model] effects`` deciding which losses the branch has (contract 4): the part
    along the pipe only with ``pipe_laminar_loss`` (else length 0), the valve and
    fittings only with ``local_loss`` (else K = 0). A described valve is not a loss the
    model includes unless ``local_loss`` is declared; the device simulation
    (``sims.device_model._line_loss``) reads the same switches, so the compensation, the
    ropes' identification and the replay describe one branch.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> sensor_branch(hoist).shape
    (6,)
    >>> pipe_only = sensor_branch(hoist.with_effects(["pipe_laminar_loss"]))
    >>> float(pipe_only[4]), float(pipe_only[2]) > 0
    (0.0, True)
    """
    piping = hoist.piping
    effects = set(hoist.model.effects)
    along_pipe = "pipe_laminar_loss" in effects
    local = "local_loss" in effects
    return np.array(
        [
            hoist.cylinders.bore_area_m2 / piping.area_m2,
            piping.bore_m,
            piping.length_chamber_to_sensor_m if along_pipe else 0.0,
            hoist.oil.density_kg_m3,
            piping.valve_loss_coefficient + piping.fittings_loss_coefficient_chamber_to_sensor
            if local
            else 0.0,
            piping.roughness_m / piping.bore_m,
        ],
        dtype=np.float64,
    )


@njit(cache=True, nogil=True, inline="always")
def sensor_minus_chamber_at(v_piston_m_s: float, nu_m2_s: float, branch: np.ndarray) -> float:
    """p_sensor - p_chamber of one sample [Pa]: minus :func:`pipe_loss_pa` of the
    branch flow u = (A_bore / A_pipe) v (``branch`` from :func:`sensor_branch`)."""
    u = v_piston_m_s * branch[0]
    bore, length, rho, k_local, roughness = branch[1], branch[2], branch[3], branch[4], branch[5]
    loss = pipe_loss_pa(u, bore, length, nu_m2_s, rho, k_local, roughness, COLEBROOK)
    return 0.0 - loss  # not -loss: no -0.0 at rest


@njit(cache=True, nogil=True, error_model="numpy")
def _sensor_minus_chamber(v, nu, branch, out):  # pragma: no cover - numba
    per_sample = nu.shape[0] > 1
    for i in range(v.shape[0]):
        out[i] = sensor_minus_chamber_at(v[i], nu[i] if per_sample else nu[0], branch)


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
    rest. Turbulent lambda by Colebrook (:data:`COLEBROOK`). Each part only where the
    hoist's ``[model] effects`` declare it (:func:`sensor_branch`): the pipe's with
    ``pipe_laminar_loss``, K with ``local_loss``.

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
        Kinematic viscosity [m2/s] already computed for ``t_oil_c``; overrides it.

    Returns
    -------
    numpy.ndarray
        p_sensor - p_chamber [Pa].

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> [float(x) < 0 for x in sensor_minus_chamber_pa(np.array([0.01, -0.01]), hoist)]
    [True, False]
    """
    if nu_m2_s is None:
        t = hoist.oil.reference_temperature_c if t_oil_c is None else t_oil_c
        nu_m2_s = kinematic_viscosity(t, hoist.oil)
    v, nu = np.broadcast_arrays(
        np.asarray(v_piston_m_s, dtype=np.float64), np.asarray(nu_m2_s, dtype=np.float64)
    )
    flat, nu_flat = np.ascontiguousarray(v.ravel()), np.ascontiguousarray(nu.ravel())
    out = np.empty(flat.size)
    if flat.size:
        _sensor_minus_chamber(flat, nu_flat, sensor_branch(hoist), out)
    return out.reshape(v.shape)


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
