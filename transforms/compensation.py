"""From logged sensor pressures to compensated rope tensions (paper sections 4-5).

For each cylinder i of a hoist, per sample:

1. sensor calibration: p_i = (reading_i - offset_i) / gain_i (hoist ``[[sensors]]``);
2. single-sample spikes removed (3-point median) and a zero-phase low-pass, per
   gap-free segment;
3. piston motion and seal friction. Where the logged x identify the head ropes
   (:mod:`transforms.rope_identification`: each rope's stiffness and length offset,
   from the first 2 h of the record), the forces decide: each rope is a spring on its
   piston, each seal elasto-plastic with the eq 17 capacity (or the hoist's Maxwell-slip
   elements with ``presliding_hysteresis``; and, for LuGre's single
   bristle, eq 15's drift along the oil's back-and-forth: a ringing hoist shakes its
   seals loose), and the closed oil volume, A sum dx_i = V dp / beta, fixes the sum of
   the motions; solved per sample (:mod:`transforms.stick_slip`), it says which piston
   slides and what friction the sticking ones keep; without a logged x, on the sigma
   points of the ropes' prior stiffness spread, their mean the estimate
   (:func:`transforms.stick_slip_band.prior_rope_springs`). Otherwise (a record
   at rest, ropes the model does not fit, ``CompensationSettings(rope_springs=False)``,
   or without x ``rope_stiffness_sigma=0``)
   the oil's motion is shared out to the pistons the smoothed, played logged x show
   moving, the part within the seals' presliding range equally
   (:mod:`transforms.piston_motion`); the friction state is then driven by the
   increments of a play (deadband) operator on that estimate, so residual noise does
   not move it. The branch flow uses the Savitzky-Golay velocity of the motion;
4. chamber pressure: the sensor sits after the globe valve and the first branch part,
   so p_chamber = p_sensor - (p_sensor - p_chamber)(v, T) (paper eq 12-14, contract 1a);
5. seal friction F_i (without identified ropes): LuGre (paper eq 15, which the paper
   calls "Leuven") driven by v_i,
   with parameters linear in chamber pressure (eq 17 form); with
   ``presliding_hysteresis`` in the hoist's model, the Maxwell-slip elements (the
   Leuven / GMS idea) replace the single bristle. The state is carried through
   standstill, so the friction left by the last motion is kept, not zeroed, but for
   LuGre's drift along a ringing at rest that the played motion hides
   (:meth:`transforms.compensation_block.BlockCompensation.ringing_drift`);
6. tension T_i = p_chamber,i A_bore + F_i (paper eq 2, F positive while the rod moves
   out), and the uncompensated T_raw,i = p_sensor,i A_bore (the paper's "before");
7. a 95 % band for each tension and the load (:mod:`transforms.uncertainty`): the
   friction range the estimate cannot resolve (with identified ropes: the spread of the
   stick-slip solution over the law's capacity, the bristle stiffness, the seals'
   unknown friction where the record starts and the ropes as identified on each
   quarter of the record, Student's t of their spread; without:
   motion only the oil saw and the law's uncertainty) and the sensor noise.

Which corrections apply follows the hoist's ``[model] effects``: ``seal_friction``,
``presliding_hysteresis``, ``pipe_laminar_loss`` / ``local_loss`` (the branch loss along
the pipe / at the valve and fittings, each only when declared:
:func:`physics.sensor_branch.sensor_branch`), ``viscosity_temperature`` (viscosity from
the logged oil temperature instead of the reference temperature).

The friction state is sequential over the whole record, so :func:`compensate` takes a
collected frame of one hoist, sorted by time, and returns a ``ROPE_TENSIONS`` frame.
:func:`compensate_window` does the same for one block of a longer record, resuming the
sequential kernels from the state the previous block left (:class:`CompensationCarry`)
with the record's statistics (:class:`CompensationContext`): :mod:`transforms.blocks`.
"""

from __future__ import annotations

import datetime as dt

import polars as pl

from schemas.hoist import HoistDescription
from transforms.compensation_block import BlockCompensation
from transforms.compensation_output import OUTPUT_SCHEMA
from transforms.compensation_record import (
    CompensationCarry,
    CompensationContext,
    CompensationSettings,
    compensation_context,
    compensation_look_ahead_s,
    compensation_margins_s,
    context_sample,
    context_stride,
    depth_turns,
    displacement_noise_sigma,
    identification_means,
    logger_rate_hz,
    rope_cols,
)
from transforms.seal_drift import seal_elements

# The public interface of the compensation: its own two functions, and the settings,
# statistics and carried state defined in transforms.compensation_record.
__all__ = [
    "CompensationCarry",
    "CompensationContext",
    "CompensationSettings",
    "compensate",
    "compensate_window",
    "compensation_context",
    "compensation_look_ahead_s",
    "compensation_margins_s",
    "context_sample",
    "context_stride",
    "displacement_noise_sigma",
    "logger_rate_hz",
]


def compensate(
    samples: pl.DataFrame | pl.LazyFrame,
    hoist: HoistDescription,
    *,
    settings: CompensationSettings | None = None,
    effects: set[str] | None = None,
) -> pl.DataFrame:
    """Compensated rope tensions for one hoist's samples (a ``FIELD_SAMPLES`` frame).

    Parameters
    ----------
    samples : polars.DataFrame or LazyFrame
        Landed samples of one hoist (columns of ``schemas.tables.FIELD_SAMPLES``).
    hoist : HoistDescription
        Geometry, oil, sensors, friction law and ``[model] effects``.
    settings : CompensationSettings, optional
        Filtering and differentiation choices.
    effects : set of str, optional
        Effects to compensate; default ``hoist.model.effects``. Given, they replace the
        hoist's for the whole compensation: the ropes' identification too (it runs the
        same seals), and its cache keys them.

    Returns
    -------
    polars.DataFrame
        One row per sample with the columns of ``schemas.tables.ROPE_TENSIONS``.

    See Also
    --------
    compensate_window : the same on a block of a longer record, with its state carried
        (what ``ropeload run`` uses, :mod:`pipelines.blocks`).
    """
    settings = settings or CompensationSettings()
    if effects is not None and set(effects) != set(hoist.model.effects):
        hoist = hoist.with_effects(sorted(effects))
    frame = _input_frame(samples)
    if frame.height == 0:
        return pl.DataFrame(schema=OUTPUT_SCHEMA)
    stride = context_stride(frame.height)
    context = compensation_context(
        context_sample(frame, stride).collect(), hoist, settings, stride,
        means=(
            identification_means(frame, frame["time_utc"][0], hoist, settings)
            if settings.rope_springs
            else None
        ),
        depth_turns=depth_turns(frame),
    )  # fmt: skip
    result, _ = compensate_window(frame, hoist, context=context, settings=settings)
    return result


def _input_frame(samples: pl.DataFrame | pl.LazyFrame) -> pl.DataFrame:
    """The columns :func:`compensate_window` reads, collected and sorted by time."""
    lazy = samples.lazy()
    available = set(lazy.collect_schema().names())
    # only the columns used below (a landed frame also carries e.g. long provenance
    # strings, which sorting would otherwise have to move)
    wanted = ["time_utc", "depth_m", "speed_m_s", "oil_temp_c", *rope_cols("p{i}_pa")]
    wanted += rope_cols("x{i}_m")
    frame = lazy.select(c for c in wanted if c in available).collect()
    if frame.height and not frame["time_utc"].is_sorted():
        frame = frame.sort("time_utc")
    return frame


def compensate_window(
    samples: pl.DataFrame | pl.LazyFrame,
    hoist: HoistDescription,
    *,
    context: CompensationContext,
    settings: CompensationSettings | None = None,
    carry: CompensationCarry | None = None,
    block_start_utc: dt.datetime | None = None,
    block_end_utc: dt.datetime | None = None,
) -> tuple[pl.DataFrame, CompensationCarry]:
    """Compensate the block ``block_start_utc <= t < block_end_utc`` of a longer record.

    ``samples`` hold the block and the margins of :func:`compensation_margins_s` either
    side, and :func:`compensation_look_ahead_s` more after it (less at the record's
    ends); ``context`` the record's statistics; ``carry`` the state the previous block
    returned (None for the record's first block, which must then start at the samples'
    start). Returns the block's ``ROPE_TENSIONS`` rows and the state for the next block,
    which starts at ``block_end_utc``. Called on the whole record at once (no carry, no
    bounds) it is :func:`compensate`; block by block it gives the same rows
    (tests/transforms/test_blocks.py states the tolerance).
    """
    frame = _input_frame(samples)
    effects = set(hoist.model.effects)
    if frame.height == 0:
        fresh = CompensationCarry.fresh(seal_elements(effects, hoist))
        return pl.DataFrame(schema=OUTPUT_SCHEMA), carry or fresh
    block = BlockCompensation(
        frame,
        hoist,
        context=context,
        settings=settings or CompensationSettings(),
        effects=effects,
        carry=carry,
        block_start_utc=block_start_utc,
        block_end_utc=block_end_utc,
    )
    return block.run()
