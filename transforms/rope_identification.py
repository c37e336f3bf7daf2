"""The head ropes' constants from a record: what makes the pistons move as logged (issue 13).

:mod:`transforms.stick_slip` solves each piston's motion and friction from its rope
spring, T_i = a_i k(z) (s - x_i - c_i), with two constants per rope the mine does not
know: a_i, the rope's stiffness relative to the description's nominal EA, and c_i, its
length offset. They are constants of the hoist, so one record shows them: on every
trip the ropes' rates change thirteen-fold (50 m of rope at the pithead, 650 m at the
bottom of the validation shaft), and which piston slides, when and how far depends on
them. The logged x show it to the logger's 0.1 mm step.

:func:`identify_rope_springs` minimises the mean squared difference between the
model's x and the logged x over theta = (a_2..a_n, c_2..c_n) (gauge a_1 = 1, c_1 = 0):
a global search on every 10th of the 0.2 s means of :func:`record_means` (2 s apart),
then a Nelder-Mead polish on every 2nd (0.4 s apart), restarted while it improves. The
global search is a differential evolution; the objective has a local minimum for each
set of ropes taken for the odd ones out (a stiffer rope 2 of a simulated record was
found as softer ropes 3 and 4 by one seed in three), so its first population holds each
hypothesis "rope j is 5 % stiffer or softer than the others" beside the description's
nominal ropes, then a Latin hypercube. Tried and dropped: sweeping the ropes in turn
over grids of each one's constants (they are entangled through the gauge rope: from the
nominal start it stalled at 0.7 mm on validation day 101), and more seeds instead of the
hypotheses. The branch loss and the viscosity are those the hoist's ``[model] effects``
declare (``compensate(effects=)`` replaces them here too).
Each trial of the global search is solved only until what it has summed already
exceeds the energy of the member it would replace (:class:`_Parents` mirrors scipy's
deferred selection; :func:`transforms.stick_slip.stick_slip_mismatch`'s ``bounds``):
it loses either way, so the search and its answer are those of every trial solved
whole, to the last bit (session 32: 89 % of the trials lose; the global search of a 2 h
record at 50 Hz 1.86 -> 0.97 s; the polish, whose steps need the values, unchanged).
The objective is piecewise smooth (a slide starts or not), so no gradient method. Only
the first :data:`IDENTIFY_SAMPLES` means are used (2 h at 5 Hz): ~10 000 runs of the
model over them, 5-8 s on two cores for a 2 h record of 50 Hz (the quarters below search
again, beside it).

How well the record pins the constants down is measured, not assumed: the same search
runs again on each quarter of the means (:data:`SPLITS`; in a record under 40 min,
fewer parts of :data:`PART_MEANS` each, at least two), and the parts' constants are
the ropes' alternatives, from which the uncertainty band's rope members are made
(:func:`transforms.stick_slip_band.band_solutions`: Student's t on their spread,
:func:`transforms.stick_slip_band.parts_reach`; two halves gave a spread of one degree of
freedom, and the band missed 5-16 % of the validation days' windows on one rope). A
Hessian of the objective would understate it: the misfit (0.044-0.059 mm RMS on the
validation days) is the model's, correlated over whole trips, not the logger's white
noise, and the objective has several basins. On the four validation days the quarters'
stiffness factors differ from the whole record's by up to 0.01 and their length offsets
by up to 0.9 mm, about as much as the days' whole records differ from each other (0.01,
0.45 mm). Which basin the whole record's search ends in can turn on a second of data
(session 64, validation day 101): the whole record's search ends with rope 4 at a =
1.0435, c = -2.96 mm (mismatch 46.2 um), the record less its first 1 s at 1.0362,
-3.56 mm (48.6 um), though polished from the first basin that record fits it better
(46.6 um); the truth's windows imply 1.0328, -3.64 mm, nearer the basin the objective
ranks second: the model's misfit, not the search, sets which basin is right, and a
better search would not bring the ropes nearer (the band's quarters span both). The
five searches took ~21 s for a 2 h record of 50 Hz (whole and halves:
15 s); with Maxwell-slip seals (``presliding_hysteresis``, four elements) ~17 s for
45 min, where the coarse global search takes each seal as one bristle (it picks the
basin) and the polish the seals' elements (one bristle throughout: 14 s). The whole
record is searched beside its parts, one search per core (:func:`_identify`): on
validation trial_004 (2 h at 50 Hz) 6.0 s, against 8.7 s one after the other with each
global search's members on both cores and the polish on one (session 27).

Discovery reads the ropes again once an effect joins its model
(:mod:`discovery.record_rereading`): the same record, a description that differs by the
effect's parameters. Those ropes are the first read's moved within its basin, so the
search is polished from them (``start``) and the global search left out: on validation
trial_004 a re-read 10.7 -> 4.7 s, the discovery 54 -> 39 s. The polish ends where it
stalls in the basin's valley, in which a rope's stiffness trades against its length
offset (ropeload's simulated rope 2 4 % stiffer: 1.0295 from 1.02, the global search
1.0378, the mismatch 1.5 % higher; ``tests/transforms/test_stick_slip.py``), so the
re-read ropes differ from a global search's by about what the record's quarters do.
Tried: a differential evolution of 20 generations with the start in its first
population (1.0243 there, no faster: the polish is most of a search of a 1 h record).

Where the seals drift (LuGre's single bristle, :mod:`transforms.seal_drift`), the model
identified on drifts too, driven by each mean's played travel of the record's
full-rate samples (``drift_travel_pa``, :func:`transforms.compensation_record.
identification_means`): a 0.2 s mean hides the 0.8-2.7 Hz bounce that drives most of
the drift. On the four validation days the misfit fell from 0.090-0.146 mm to
0.044-0.059 mm and the days' ropes agree with each other (rope 2 1.070-1.081; day
104's ringing had taken it for 1.12). The means' travel includes the ringing below the
drift's play (:func:`transforms.seal_drift.ringing_travel`). A play on the
means themselves (tried in session 14) made the misfit worse (0.090 -> 0.134 mm on
day 101): it sees neither the ringing nor the full-rate noise it must ignore.

Against the constants the validation days' truth implies (the true tensions and piston
positions of the stop windows fitted to the spring law, ``benchmarks/
eval_compensation.py``'s ``truth_ropes``, per day: the same to within 0.04 mm on all
four, a = 1.078 / 1.049 / 1.033, c = 8.48 / 10.85 / -3.64 mm, 19-24 N RMS), the
identification gets each a within 0.008 and each c within 0.04-0.48 mm, the c's part
alone worth 57-618 N of a rope's tension at the pithead (session 31; the a's adds up to
~400 N there). The model's misfit, not the logger's, sets that: with the
truth's constants the model's x is 0.103 mm from the logged (0.047 mm with the
identified, day 102), offset by ~0.1 mm at the pithead's slides and kept while the
pistons stick, and the search moves c to take the offsets up. Tried there and not kept:
the viscosity per mean where it follows the oil's temperature (day 103: the ropes
barely nearer, rope error 1.86 -> 1.78 %, but the quarters' new spread left the band
at 76 % of the windows, was 91 %); a common capacity factor of the seals beside the
ropes (the misfit's minimum at 1.00-1.07 of the law, no gain on all days); the
bristle stiffness beside them (day 101, x 2 / x 3: the mismatch 46.2 -> 82.3 / 114.8 um,
the ropes farther from the truth's; session 65); the model's x read through the
logger's 0.1 mm step with its ~0.02 mm noise (its expected reading against the logged
means: 85.3 -> 85.8 um with the identified constants, 167 um with the truth's either
way: the misfit is not the quantiser's; the truth's constants leave piston 1 +0.25 mm
and pistons 2-3 -0.11 mm off on average, the oil shared among the pistons unlike the
world's; session 65, ``benchmarks/HISTORY.md``); the
objective on x differenced over 10-600 s (the truth's constants still fit worse); the
polish on the sensors' samples (day 102 worst 0.67 -> 1.25 %: the model at 0.02 s
steps fits x 0.13-0.26 mm and its step matters, through the drift's shares and the
branch loss together, yet its friction is nearer the truth's there than on means).
With the truth's constants in place of the identified, worst load / worst rope on
days 101-104 went 0.80 / 1.12 -> 0.74 / 0.88 %, 0.67 / 1.04 -> 0.69 / 0.95 %,
0.79 / 1.86 -> 0.62 / 1.00 %, 0.96 / 1.18 -> 1.08 / 1.29 %. Again with the stop
continuity (:mod:`transforms.stop_continuity`, session 43; the identified ropes'
alternatives kept for the band): worst load 0.42 / 0.33 / 0.25 / 0.31 -> 0.34 / 0.37 /
0.36 / 0.35 %, median 0.14 / 0.08 / 0.06 / 0.06 -> 0.09 / 0.09 / 0.08 / 0.06 %, worst
rope 0.87 / 0.80 / 0.99 / 0.68 -> 0.56 / 0.64 / 0.81 / 0.54 %, coverage 100 / 100 / 97 /
100 -> 100 / 99 / 94 / 100 %, and day 104 one window worse than raw by 0.23 points
(none with the identified): the runs' friction, which the continuity carries into the
stops, stays off with the true constants (days 101-102, run phases against the truth's
per-piston friction: piston 1 -141 to -143 N on the runs up, pistons 2-4 +60 to +73 N
on the runs down; with the identified -127 to -184 N and +41 to +132 N): the model's
error, not the constants'.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import importlib
import json
import logging
import os
import tempfile
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, replace
from functools import lru_cache
from itertools import pairwise
from pathlib import Path

import numpy as np
import polars as pl
import scipy

from physics.oil import kinematic_viscosity
from physics.sensor_branch import sensor_branch
from schemas.hoist import HoistDescription
from schemas.tables import ROPES
from transforms.seal_drift import seal_elements
from transforms.stick_slip import groove_deviations, stick_slip_mismatch
from transforms.stick_slip_band import MAX_ALTERNATIVES, RopeSprings

__all__ = [
    "IDENTIFICATION_VERSION",
    "IDENTIFY_SAMPLES",
    "IDENTIFY_SPAN",
    "MEAN_STEP",
    "MISMATCH_LIMIT_M",
    "PART_MEANS",
    "SPLITS",
    "identify_from_means",
    "identify_rope_springs",
    "pistons_moved",
    "record_means",
]

#: Bounds of the identification: stiffness relative to the nominal EA, length offset [m].
STIFFNESS_BOUNDS = (0.9, 1.1)
OFFSET_BOUNDS_M = (-0.015, 0.015)
#: The global search's population (per parameter) and generations, and how many times
#: the polish may restart.
POPSIZE, GENERATIONS, RESTARTS = 15, 60, 3
#: Seeds of the global search (the same record gives the same constants).
SEEDS = (1,)
#: Spacing of the means the global search and the polish take [s] (every k-th mean).
COARSE_S, POLISH_S = 2.0, 0.4
#: The same where the hoist declares a worn groove (:func:`_strides`): the wear pushes a
#: piston one way through every trip, and each swing of the ropes' ringing lets it slip
#: a little further (its seal's hysteresis ratchets), which strides that do not see the
#: ringing miss. Measured on ropeload's device simulation of a hoist with one groove
#: 0.1 mm wider (30 min, four trips, ropes ringing at a damping ratio of 0.02): the true
#: ropes 1.36 / 0.63 / 0.31 mm off the logged x on 2 / 0.4 / 0.2 s strides (0.05 mm at
#: every stride without the wear; with the ringing damped out, 0.15 / 0.21 / 0.32 mm),
#: and the search on 2 / 0.4 s gave no ropes, on 0.4 / 0.2 s the truth's (0.075 mm) in
#: 2.2 s instead of 1.4 s.
WORN_GROOVE_COARSE_S, WORN_GROOVE_POLISH_S = 0.4, 0.2
#: The means' step (a polars duration) and how many of them the identification uses.
MEAN_STEP = "200ms"
IDENTIFY_SAMPLES = 36_000
#: The span of the record the identification reads, from its first sample.
IDENTIFY_SPAN = dt.timedelta(seconds=0.2 * IDENTIFY_SAMPLES)
#: Part of the name of a cached identification (:func:`identify_from_means`), with the
#: search's constants, the source of the modules the model runs and the numpy / scipy
#: versions (:func:`_method_digest`): a file of another method is not read.
IDENTIFICATION_VERSION = "5"
#: The identification is repeated on this many consecutive parts of the means: their
#: constants are the ropes' alternatives in the band (``RopeSprings.alternatives``) ...
SPLITS = MAX_ALTERNATIVES
#: ... or on fewer, at least two, so that each part holds this many means (10 min: two
#: or three trips of a shaft's cycle; a 4 min quarter of a 15 min record holds one trip
#: or none, and gave no ropes).
PART_MEANS = 3000
#: The global search evaluates a generation's members on two threads from this many
#: coarse means (half an hour of the record), on one below it (where the threads' start
#: costs more than the split saves).
THREADED_MEANS = 900
#: The most RMS difference between the model's and the logged x the ropes are kept at
#: [m]: five logger steps. Beyond it the model does not describe the hoist (the 2 h
#: validation and own records fit to 0.07-0.2 mm) and the compensation keeps the share-out.
MISMATCH_LIMIT_M = 0.5e-3


def record_means(samples: pl.DataFrame | pl.LazyFrame, start: dt.datetime) -> pl.DataFrame:
    """0.2 s means of what the identification reads (time-sorted ``FIELD_SAMPLES`` rows)
    of the record that starts at ``start``, up to :data:`IDENTIFY_SPAN` after it.

    Windows start at multiples of 0.2 s since the epoch, so the means of a record read
    block by block (blocks at whole hours) are those of the record read whole. Columns
    ``time_utc`` (the window's start), the ``p`` and ``x`` columns, ``depth_m``,
    ``oil_temp_c`` (null where the record has none), and the sum of ``drift_travel_pa``
    when the samples have it (:func:`transforms.compensation_record.identification_means`).
    """
    lazy = samples.lazy()
    names = set(lazy.collect_schema().names())
    wanted = [f"p{i}_pa" for i in ROPES] + [f"x{i}_m" for i in ROPES] + ["depth_m", "oil_temp_c"]
    aggregations = [
        pl.col(c).cast(pl.Float64).mean() if c in names else pl.lit(None, pl.Float64).alias(c)
        for c in wanted
    ]
    if "drift_travel_pa" in names:
        aggregations.append(pl.col("drift_travel_pa").cast(pl.Float64).sum())
    lazy = lazy.filter(pl.col("time_utc") < start + IDENTIFY_SPAN)
    return lazy.group_by_dynamic("time_utc", every=MEAN_STEP).agg(aggregations).collect()


def identify_from_means(
    means: pl.DataFrame,
    hoist: HoistDescription,
    *,
    cache_dir: Path | None = None,
    alternatives: bool = True,
    start: RopeSprings | None = None,
) -> RopeSprings | None:
    """:func:`identify_rope_springs` on the first :data:`IDENTIFY_SAMPLES` of
    :func:`record_means` (:func:`transforms.compensation_record.identification_means`
    with the drift's travel where the seals drift; pressures calibrated here; the branch
    loss when the hoist declares a pipe or local loss, at the record's median oil
    temperature if the viscosity follows it, else at the reference temperature), and on
    each of :data:`SPLITS` parts of them (fewer, of :data:`PART_MEANS` each, in a
    record under 40 min; two in one under 20 min) (the alternatives).

    Remembered for the process, and in ``cache_dir`` (``<data>/cache/rope_springs`` for
    ``ropeload run``) across processes: the same means of the same hoist (a re-run, the
    run and the sanity check of one record, a backfill's retry, a flow's task) are not
    identified again. The file is named by a SHA-256 of the means, the hoist and the
    method (:func:`_method_digest`); one that does not read as this hoist's ropes is
    identified again and replaced.

    ``alternatives=False`` (a replay, which needs only the whole record's ropes): the
    ropes remembered with their alternatives if there are any, else the whole record's
    alone, a third of the searches (remembered apart).

    ``start``: ropes the same record gave under a nearby description, from which each
    search is polished instead of searched globally (:func:`identify_rope_springs`;
    remembered apart, under them too).
    """
    means = means.head(IDENTIFY_SAMPLES)
    if means.height < 2:
        return None
    # the band's law uncertainty does not identify ropes: editing it keeps what is known
    described = hoist.model_dump_json(exclude={"friction": {"relative_uncertainty"}})
    digest = hashlib.sha256(f"{_method_digest()}\n{described}".encode())
    for column in means.columns:
        digest.update(means[column].to_numpy().tobytes())
    if start is not None:
        polished_from = (start.stiffness_factors, start.length_offsets_m)
        digest.update(f"\npolished from {polished_from}".encode())
    key = digest.hexdigest()
    if alternatives:
        return _remembered(key, cache_dir, lambda: _identify(means, hoist, start=start))
    known, springs, _ = _recalled(key, cache_dir)
    if known:
        return springs
    whole = hashlib.sha256(f"{key}\nwhole record only".encode()).hexdigest()
    return _remembered(whole, cache_dir, lambda: _identify(means, hoist, parts=False, start=start))


def _remembered(
    key: str, cache_dir: Path | None, identify: Callable[[], RopeSprings | None]
) -> RopeSprings | None:
    """The ropes remembered under ``key`` (for the process, and in ``cache_dir``), or
    ``identify()``'s, remembered."""
    known, springs, on_disk = _recalled(key, cache_dir)
    path = None if cache_dir is None else cache_dir / f"{key}.json"
    if not known:
        springs = identify()
    if path is not None and not on_disk:
        _write_cached(path, springs)
    with _LOCK:
        _IDENTIFIED[key] = springs
        while len(_IDENTIFIED) > 64:
            _IDENTIFIED.pop(next(iter(_IDENTIFIED)))
    return springs


def _recalled(key: str, cache_dir: Path | None) -> tuple[bool, RopeSprings | None, bool]:
    """(known, ropes, on disk) of ``key``: remembered for the process, else read from
    ``cache_dir`` (on disk: there is nothing to write, or the file is there)."""
    with _LOCK:
        known, springs = key in _IDENTIFIED, _IDENTIFIED.get(key)
    path = None if cache_dir is None else cache_dir / f"{key}.json"
    if path is not None and not known:
        known, springs = _read_cached(path)
        return known, springs, known
    return known, springs, path is None or path.exists()


@lru_cache(maxsize=1)
def _method_digest() -> str:
    """SHA-256 of what makes the identification's answer: :data:`IDENTIFICATION_VERSION`,
    the search's constants, the source of the modules its model runs, numpy and scipy."""
    digest = hashlib.sha256(IDENTIFICATION_VERSION.encode())
    constants = (STIFFNESS_BOUNDS, OFFSET_BOUNDS_M, POPSIZE, GENERATIONS, RESTARTS, SEEDS,
                 COARSE_S, POLISH_S, WORN_GROOVE_COARSE_S, WORN_GROOVE_POLISH_S, MEAN_STEP,
                 IDENTIFY_SAMPLES, MISMATCH_LIMIT_M, SPLITS, PART_MEANS,
                 np.__version__, scipy.__version__)  # fmt: skip
    digest.update(repr(constants).encode())
    for name in _MODEL_MODULES:
        digest.update(Path(importlib.import_module(name).__file__ or "").read_bytes())
    return digest.hexdigest()


def _read_cached(path: Path) -> tuple[bool, RopeSprings | None]:
    """(found, ropes) of a file :func:`_write_cached` wrote; (False, None) when it is
    missing or does not read as ropes of this hoist (it is then identified again)."""
    try:
        payload = json.loads(path.read_text(encoding="utf-8"))
        if payload is None:
            return True, None
        springs = RopeSprings(
            stiffness_factors=tuple(float(v) for v in payload["stiffness_factors"]),
            length_offsets_m=tuple(float(v) for v in payload["length_offsets_m"]),
            mismatch_m=float(payload["mismatch_m"]),
            samples=int(payload["samples"]),
            alternatives=tuple(
                (tuple(float(v) for v in a), tuple(float(v) for v in c))
                for a, c in payload["alternatives"]
            ),
            parts=int(payload["parts"]),
        )
    except (OSError, ValueError, KeyError, TypeError):
        return False, None
    ropes = [springs.stiffness_factors, springs.length_offsets_m]
    ropes += [part for alternative in springs.alternatives for part in alternative]
    if springs.splits > SPLITS or any(
        len(values) != len(ROPES) or not np.isfinite(values).all() for values in ropes
    ):
        return False, None
    return True, springs


def _write_cached(path: Path, springs: RopeSprings | None) -> None:
    """Write ``springs`` (or null: nothing identifies the ropes) to ``path``, whole or not
    at all (a temporary file of its own, renamed into place). A data root that cannot
    take it only loses the shortcut."""
    temporary = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".tmp")
        temporary = Path(name)
        with os.fdopen(handle, "w", encoding="utf-8") as out:
            json.dump(None if springs is None else asdict(springs), out)
        temporary.replace(path)
        temporary = None
    except OSError as error:
        _LOG.warning("rope constants not cached in %s: %s", path.parent, error)
    finally:
        if temporary is not None:
            temporary.unlink(missing_ok=True)


#: Identified ropes by a digest of the means and the hoist (:func:`identify_from_means`).
_IDENTIFIED: dict[str, RopeSprings | None] = {}
#: The modules whose code decides the identified ropes (:func:`_method_digest`).
_MODEL_MODULES = (
    __name__,
    "transforms.stick_slip",
    "transforms.stick_slip_band",
    "transforms.seal_drift",
    "physics.lugre",
    "physics.maxwell_slip",
    "physics.rope_spring",
    "physics.friction_law",
    "physics.oil",
    "physics.sensor_branch",
)
_LOG = logging.getLogger(__name__)
_LOCK = threading.Lock()


def _strides(hoist: HoistDescription) -> tuple[float, float]:
    """(coarse, polish) spacing of the search's means [s]: :data:`COARSE_S`,
    :data:`POLISH_S`, or where the hoist declares a worn groove (a non-zero
    deviation, :func:`transforms.stick_slip.groove_deviations`) the finer
    :data:`WORN_GROOVE_COARSE_S`, :data:`WORN_GROOVE_POLISH_S`."""
    if groove_deviations(hoist, hoist.ropes_n).any():
        return WORN_GROOVE_COARSE_S, WORN_GROOVE_POLISH_S
    return COARSE_S, POLISH_S


def _identify(
    means: pl.DataFrame,
    hoist: HoistDescription,
    *,
    parts: bool = True,
    start: RopeSprings | None = None,
) -> RopeSprings | None:
    """:func:`identify_from_means` without the memory (``parts``: with the alternatives;
    ``start``: each search polished from those ropes)."""
    pressures = []
    for i in ROPES:
        p = means[f"p{i}_pa"].to_numpy().astype(np.float64)
        for sensor in hoist.sensors:
            if sensor.cylinder == i:
                p = sensor.calibrated(p)
        pressures.append(p)
    effects = set(hoist.model.effects)
    branch = sensor_branch(hoist) if {"pipe_laminar_loss", "local_loss"} & effects else None
    oil = means["oil_temp_c"].to_numpy().astype(np.float64)
    t_oil = hoist.oil.reference_temperature_c
    if "viscosity_temperature" in effects and np.isfinite(oil).any():
        t_oil = float(np.nanmedian(oil))
    time_s = means["time_utc"].dt.epoch("us").to_numpy() * 1e-6
    logged = tuple(means[f"x{i}_m"].to_numpy().astype(np.float64) for i in ROPES)
    depth = means["depth_m"].to_numpy().astype(np.float64)
    nu = float(kinematic_viscosity(t_oil, hoist.oil))
    travel = (
        means["drift_travel_pa"].to_numpy().astype(np.float64)
        if "drift_travel_pa" in means.columns
        else None
    )

    coarse_s, polish_s = _strides(hoist)

    def identify(part: slice, threads: int | None = None) -> RopeSprings | None:
        return identify_rope_springs(
            time_s[part],
            tuple(p[part] for p in pressures),
            tuple(x[part] for x in logged),
            depth[part],
            hoist,
            nu_m2_s=nu,
            branch=branch,
            drift_travel_pa=None if travel is None else travel[part],
            presliding_elements=seal_elements(effects, hoist),
            threads=threads,
            coarse_s=coarse_s,
            polish_s=polish_s,
            start=start,
        )

    if not parts:
        return identify(slice(None))
    splits = min(SPLITS, max(2, time_s.size // PART_MEANS))
    bounds = np.linspace(0, time_s.size, splits + 1).astype(int)
    # the whole record and its parts are independent searches: one per core, the whole
    # beside the parts (it costs about what they do together), each search on one
    # thread; the same constants as one after the other, each on the cores. The parts
    # are searched also where the whole then gives no ropes (their time is lost there).
    spans = [slice(None), *(slice(lo, hi) for lo, hi in pairwise(bounds))]
    with ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
        springs, *found = pool.map(lambda span: identify(span, threads=1), spans)
    if springs is None:
        return None
    alternatives = []
    for (lo, hi), part in zip(pairwise(bounds), found, strict=True):
        if part is not None:
            alternatives.append((part.stiffness_factors, part.length_offsets_m))
        else:  # the band leaves that part's ropes out (the others' t takes fewer dof)
            _LOG.warning(
                "the ropes were not identified on part %d-%d of %d means; the band "
                "leaves that part's ropes out", lo, hi, time_s.size,
            )  # fmt: skip
    return replace(springs, alternatives=tuple(alternatives), parts=splits)


def identify_rope_springs(
    time_s: np.ndarray,
    p_sensor: tuple[np.ndarray, ...],
    x_logged: tuple[np.ndarray, ...],
    depth_m: np.ndarray,
    hoist: HoistDescription,
    *,
    nu_m2_s: float = 0.0,
    branch: np.ndarray | None = None,
    coarse_s: float = COARSE_S,
    polish_s: float = POLISH_S,
    drift_travel_pa: np.ndarray | None = None,
    presliding_elements: int = 1,
    threads: int | None = None,
    start: RopeSprings | None = None,
) -> RopeSprings | None:
    """The ropes' constants that make the model's piston motion match the logged x.

    Parameters
    ----------
    time_s : ndarray
        Times of evenly spaced means of the record (e.g. 0.2 s means) [s].
    p_sensor, x_logged, depth_m :
        Those means: calibrated sensor pressures [Pa], logged displacements [m] (NaN
        where not logged), depth [m].
    hoist : HoistDescription
    nu_m2_s, branch :
        Oil viscosity and :func:`physics.sensor_branch.sensor_branch` for the branch
        loss (branch None: none).
    coarse_s, polish_s : float
        Spacing of the means the global search and the polish take [s] (every k-th of
        the given samples, k = spacing / their step).
    drift_travel_pa : ndarray, optional
        Each mean's played travel of the seals' drift [Pa] (summed over the means a
        strided sample stands for); None: the seals do not drift.
    presliding_elements : int
        Maxwell-slip elements per seal (:func:`transforms.stick_slip.stick_slip`).
    threads : int, optional
        Threads the global search's members are split over (the result does not
        depend on it); default up to 2 cores from :data:`THREADED_MEANS` means, else 1.
    start : RopeSprings, optional
        The ropes as the same record read them under a nearby description (discovery's
        model before an effect joined, :mod:`discovery.record_rereading`): the global
        search is left out and the polish starts from them (module docstring).

    Returns
    -------
    RopeSprings or None
        None when nothing identifies the ropes: no piston motion in the logged x (a
        record at rest), fewer than 60 samples with x and pressures, or no constants
        within the bounds make the model's x come within :data:`MISMATCH_LIMIT_M` of the
        logged x.
    """
    m = len(p_sensor)
    if presliding_elements > 1 and drift_travel_pa is not None:
        raise ValueError("Maxwell-slip seals (presliding_elements > 1) do not drift")
    usable = np.isfinite(depth_m)
    for x in x_logged:
        usable &= np.isfinite(x)
    # a sensor logged nowhere (or taken for none: compensation_record.offset_sensors)
    # is the others' mean in the model, as in the compensation
    logged_p = [p for p in p_sensor if np.isfinite(p).any()]
    for p in logged_p:
        usable &= np.isfinite(p)
    if not logged_p or usable.sum() < 60 or not pistons_moved(x_logged):
        return None
    with np.errstate(invalid="ignore"):
        p_mean = np.mean(logged_p, axis=0)
    step = float(np.median(np.diff(time_s))) if time_s.size > 1 else 1.0
    segment = np.cumsum(np.r_[0, np.diff(time_s) > 3.0 * step])
    every = max(1, round(coarse_s / step))
    fine = max(1, round(polish_s / step))

    # a stiffer rope carries more at the pithead unless it is longer: searched as (a_i,
    # c_i - (a_i - 1) e), e the ropes' stretch at the pithead, the two are less entangled
    area = hoist.cylinders.bore_area_m2
    top = hoist.shaft.headframe_height_m + max(float(np.nanmin(depth_m)), 0.0)
    p_typical = float(np.nanmedian(p_mean))
    stretch = p_typical * area * top / hoist.ropes.head_rope_axial_stiffness_n

    def constants(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(a, c) of each row of q, (rows, m) each."""
        q = np.atleast_2d(q)
        gauge = np.zeros((q.shape[0], 1))  # rope 1: a = 1, c = 0
        a = np.hstack([gauge + 1.0, q[:, : m - 1]])
        return a, np.hstack([gauge, q[:, m - 1 :]]) + (a - 1.0) * stretch

    travels = {}
    if drift_travel_pa is not None:
        total = np.cumsum(np.nan_to_num(drift_travel_pa))
        for stride in (every, fine):  # a strided sample's travel: since the one before
            travels[stride] = np.diff(total[::stride], prepend=0.0)
    strided = {  # each stride's inputs, taken once
        stride: (
            tuple(np.ascontiguousarray(p[::stride]) for p in p_sensor),
            tuple(np.ascontiguousarray(xl[::stride]) for xl in x_logged),
            np.ascontiguousarray(depth_m[::stride]),
            np.ascontiguousarray(segment[::stride]),
        )
        for stride in {every, fine}
    }

    def mismatches(q: np.ndarray, stride: int, bounds: np.ndarray | None = None) -> np.ndarray:
        """Mean square of the model's x less the logged x [m^2] on every stride-th mean,
        for each row of q (candidate constants); on the coarse means (the global
        search, where they differ from the polish's) each seal is one bristle (it picks
        the basin, a step a quarter of the cost of four elements'), on the polish's the
        seals' own elements."""
        a, c = constants(q)
        return stick_slip_mismatch(
            *strided[stride],
            hoist,
            a,
            c,
            dt_s=step * stride,
            nu_m2_s=nu_m2_s,
            branch=branch,
            drift_travel_pa=travels.get(stride),
            presliding_elements=presliding_elements if stride == fine else 1,
            bounds=bounds,
        )

    # imported here, not with the module: scipy.optimize adds ~0.5 s to every start of
    # a run, which a record whose ropes are remembered (or a record at rest) never uses
    from scipy.optimize import OptimizeResult, differential_evolution, minimize

    def mismatch(q: np.ndarray, stride: int) -> float:
        return float(mismatches(q[np.newaxis], stride)[0])

    bounds = [STIFFNESS_BOUNDS] * (m - 1) + [OFFSET_BOUNDS_M] * (m - 1)
    scale = np.array([b[1] - b[0] for b in bounds])
    # The objective has a local minimum for each set of ropes taken for the odd ones out:
    # the first population holds each hypothesis "rope j differs by +-5 %" beside the
    # description's nominal ropes and a Latin hypercube.
    lows = np.array([b[0] for b in bounds]) / scale
    # a generation's members in one compiled call, or (from THREADED_MEANS) in a call
    # per core: the model releases the GIL
    steps = int(np.isfinite(p_mean)[::every].sum())  # the model's work
    if threads is None:
        threads = min(2, os.cpu_count() or 1) if steps >= THREADED_MEANS else 1

    def search(seed: int) -> OptimizeResult:
        """One differential evolution; each trial of a generation is solved only as far
        as it takes to lose to its parent (the member it replaces if it is no worse:
        scipy's deferred updating), whose energy :class:`_Parents` keeps."""
        parents = _Parents()

        def generation(u: np.ndarray) -> np.ndarray:  # u: (parameters, members)
            members = np.array_split(u.T * scale, threads)
            limits = np.array_split(parents.limits(u.shape[1]) * 1e-6, threads)
            solved = pool.map(lambda q, b: mismatches(q, every, b), members, limits)
            energies = np.concatenate(list(solved))
            energies = np.nan_to_num(energies * 1e6, nan=np.inf)  # the search would keep NaN
            parents.select(energies)
            return energies

        return differential_evolution(
            generation,
            [(b[0] / w, b[1] / w) for b, w in zip(bounds, scale, strict=True)],
            maxiter=GENERATIONS,
            tol=1e-8,
            seed=seed,
            polish=False,
            init=_first_population(m, POPSIZE * len(bounds), lows, seed) / scale,
            updating="deferred",
            vectorized=True,
        )

    if start is None or len(start.stiffness_factors) != m:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            searches = [search(seed) for seed in SEEDS]
        q = min(searches, key=lambda result: result.fun).x * scale
    else:  # the basin the record's ropes were found in (rope 1 the gauge): polished
        a0 = np.asarray(start.stiffness_factors[1:], dtype=float)
        c0 = np.asarray(start.length_offsets_m[1:], dtype=float)
        q = np.concatenate([a0, c0 - (a0 - 1.0) * stretch])
    found = OptimizeResult(x=q / scale, fun=mismatch(q, fine) * 1e6)
    polished = found
    for _ in range(RESTARTS):  # Nelder-Mead stalls on a piecewise objective: restart it
        again = minimize(
            lambda u: mismatch(u * scale, fine) * 1e6,
            polished.x,
            method="Nelder-Mead",
            options={"maxfev": 100 * len(bounds), "xatol": 1e-4, "fatol": 1e-6},
        )
        if polished is not found and again.fun >= polished.fun * (1 - 1e-3):
            polished = again if again.fun < polished.fun else polished
            break
        polished = again
    if not np.sqrt(polished.fun * 1e-6) <= MISMATCH_LIMIT_M:
        return None
    (a,), (c,) = constants(polished.x * scale)
    return RopeSprings(
        stiffness_factors=tuple(float(v) for v in a),
        length_offsets_m=tuple(float(v) for v in c),
        mismatch_m=float(np.sqrt(polished.fun * 1e-6)),
        samples=int(usable.sum()),
    )


class _Parents:
    """The energies of a differential evolution's population as scipy's deferred
    updating keeps them (``DifferentialEvolutionSolver.__next__``: a trial replaces the
    member of its index where its energy is no higher, ``_accept_trial``; then the
    lowest is swapped to the front, ``_promote_lowest_energy``; the first call is the
    first population's), so that each trial of the next call can stop where it has
    lost (:func:`transforms.stick_slip.stick_slip_mismatch`'s ``bounds``): a trial that
    stops returns more than its member's energy and is rejected, as it would have been.
    """

    def __init__(self) -> None:
        self.energies: np.ndarray | None = None

    def limits(self, members: int) -> np.ndarray:
        """Each trial's bound: its member's energy (none for the first population)."""
        return np.full(members, np.inf) if self.energies is None else self.energies.copy()

    def select(self, energies: np.ndarray) -> None:
        """The population's energies after a call that returned ``energies``."""
        kept = energies.copy() if self.energies is None else self.energies
        kept = np.where(energies <= kept, energies, kept)
        best = int(np.argmin(kept))
        kept[[0, best]] = kept[[best, 0]]
        self.energies = kept


def _first_population(ropes: int, size: int, lows: np.ndarray, seed: int) -> np.ndarray:
    """The global search's first population in (a_2..a_n, c'_2..c'_n): the nominal ropes,
    each rope 5 % stiffer or softer than the others (rope 1 by the others' inverse), then
    a Latin hypercube over the bounds (``lows`` scaled to unit width)."""
    k = ropes - 1
    hypotheses = [np.r_[np.ones(k), np.zeros(k)]]
    for factor in (1.05, 1 / 1.05):
        hypotheses.append(np.r_[np.full(k, 1.0 / factor), np.zeros(k)])  # rope 1 differs
        for j in range(k):
            a = np.ones(k)
            a[j] = factor
            hypotheses.append(np.r_[a, np.zeros(k)])
    rng = np.random.default_rng(seed)
    cube = (np.argsort(rng.random((size, 2 * k)), axis=0) + rng.random((size, 2 * k))) / size
    spans = np.r_[
        np.full(k, STIFFNESS_BOUNDS[1] - STIFFNESS_BOUNDS[0]),
        np.full(k, OFFSET_BOUNDS_M[1] - OFFSET_BOUNDS_M[0]),
    ]
    population = lows * spans + cube * spans  # lows are in units of the spans
    population[: len(hypotheses)] = hypotheses
    return population


def pistons_moved(x_logged: tuple[np.ndarray, ...], *, least_m: float = 0.5e-3) -> bool:
    """Some piston's logged x spans more than ``least_m`` (5 logger steps), read on the
    median of each three consecutive known values: a lone spike is no motion (a 6 mm
    spike of one 50 Hz sample at rest moved its 0.2 s mean by 0.6 mm, and a search on
    it found ropes 6-7 % soft in a record that shows none).

    >>> still = np.full(50, 0.1)
    >>> spike = still.copy()
    >>> spike[20] += 6e-3
    >>> pistons_moved((spike,)), pistons_moved((np.linspace(0.1, 0.102, 50),))
    (False, True)
    """
    for x in x_logged:
        known = np.asarray(x, dtype=np.float64)
        known = known[np.isfinite(known)]
        if known.size >= 3:
            known = np.median(np.stack([known[:-2], known[1:-1], known[2:]]), axis=0)
        if known.size and float(known.max() - known.min()) > least_m:
            return True
    return False
