r"""Each piston's motion and seal friction from its rope spring and the oil (issue 13).

The compensation needs each seal's friction, and that depends on how each piston moved.
What is observed: the four sensor pressures (equal at rest, apart only while oil flows
through the branches), each piston's logged x (0.1 mm steps, ~0.02 mm noise: a sliding
piston's millimetres, not a sticking one's micrometres) and the conveyance's depth.

The method: a **quasi-static, constrained stick-slip solution per sample** with the
device's own physics, and two constants per rope identified from the record.

- Rope i pulls its piston with T_i = a_i k(z) (s - x_i - c_i) (:mod:`physics.rope_spring`:
  k = EA / (headframe + depth), a_i the rope's stiffness relative to the nominal EA,
  c_i its length offset, plus where the hoist declares ``groove_wear`` its groove's
  payout z dr_i / R, :func:`physics.rope_spring.groove_payout_m`), s the conveyance's
  common stretch.
- Each piston obeys eq 2, T_i = p_i A + F_i, with p_i the chamber pressure (the sensor's
  minus the branch loss of the piston's flow, contract 1a, eq 12-14) and F_i an
  elasto-plastic seal, F' = clip(F + sigma_0 dx, -g(v), g(v)) with the eq 17 capacity
  g(v) = Stribeck + K_v |v| at the piston's last speed
  (:func:`physics.rope_spring.seal_on_rope_step`: LuGre's elastic bristles), or with
  ``presliding_hysteresis`` the hoist's Maxwell-slip elements, each clipped at its
  share of g(v) (:func:`physics.rope_spring.elements_on_rope_step`). The
  branch loss resists a step like a damper whose rate is the loss's secant at the
  piston's last speed (implicit in the step, lagged in the rate: an explicit loss
  diverged at a throttled valve).
- Seals of LuGre's single bristle also drift (:mod:`transforms.seal_drift`): eq 15's
  -sigma_0 |dx| F / g relaxes them along the oil's real back-and-forth, shared out by
  each piston's compliance at its last step (a sliding piston takes the oil's motion,
  the sticking ones barely travel) and applied before each sample's elastic step. A
  monotone motion then follows LuGre's presliding curve and a ringing shakes the seals
  loose. Maxwell-slip seals do not drift.
- The chambers are one closed oil volume (eq 5): A sum_i dx_i = V dp / beta_e(p).

Each dx_i is a monotone, piecewise-linear function of s (with elements too), so the oil
equation has one root per sample: a Newton solve, exact in a few steps (halving its
bracket where Newton would cycle between break points). What a piston does follows from
its rope and its seal: at a payload change at rest the piston nearest its capacity
slides and the others stick with the friction their ropes leave them; on a trip the
ropes' rates grow as they shorten and the pistons whose ropes pull hardest slide.

The constants theta = (a_2..a_n, c_2..c_n) (gauge a_1 = 1, c_1 = 0) are identified per
record by making the model's x_i match the logged x_i
(:mod:`transforms.rope_identification`). The logged x enter only there and as the
start: the solution runs on pressures. The mismatch starts a record at the
least-squares stretch of the logged x (every piston not logged at x = 0, clipped seals
as they fall), as the identification was measured; the solution starts balanced (the
seals' friction summing to 0, a clipped rope's piston at its seal's capacity, a piston
not logged where its rope holds it; session 47). The mismatch with the solution's start
identified validation trial_006's ropes so that discovery's replay gap went 12.9 ->
18.0 kPa, and the stiffer rope of ``tests/transforms/test_stick_slip.py`` 1.017 for
1.04 (1.038 with the least-squares start).

Why this and not a smoother or filter of a random-walk piston state (the first wave's
estimate, a Kalman/RTS smoother, a particle filter): stick-slip motion is sparse and
non-smooth, and which piston slides is decided by forces, not by where the x noise
points. A filter with a minimum-energy prior spreads a slide over all pistons and
makes sticking ones reverse (their friction changes sign; issue 13 measured the load
error of stops after a payload change growing from 6 to 8 %). Here the sliding
piston is the one the forces select, the sticking ones keep what their ropes leave.

Measured (``benchmarks/eval_compensation.py``, stop windows of the independent
validation days 101 / 102 / 103 / 104, load error |after| worst / median, worst rope):
0.80 / 0.18, 1.12 %; 0.67 / 0.13, 1.04 %; 0.79 / 0.16, 1.86 %; 0.96 / 0.22, 1.18 %
(session 15: the ropes identified with the drift, and the ringing below the drift's
play counted, :mod:`transforms.seal_drift`; session 40, the loggers' 1 kPa steps in
the drift's play: rope 1.13 % on day 101, 0.15 / 1.84 % on day 103, 0.97 % worst on
day 104, the rest as they were). Before: 1.16 / 0.18, 1.89 %; 1.29 / 0.17,
2.01 %; 0.86 / 0.22, 2.13 %; 1.77 / 0.26, 3.44 % (session 14), and without any drift
1.29 / 0.37, 2.15 %; 1.04 / 0.32, 1.95 %; 2.25 / 0.52, 2.93 %; 2.60 / 1.21, 4.44 %.
Windows worse than raw by > 0.2 points: 0 / 1 / 0 / 4, all at the pithead where the
raw reading is within 0.4 %. The band
(:func:`~transforms.stick_slip_band.band_solutions`, each rope's own seal added,
:mod:`transforms.uncertainty`) held the true load and every true rope tension
in 97 / 98 / 95 / 90 % of those windows at a median half-width of 0.92 / 0.89 / 0.84 /
0.55 % of the load (session 32: its sources in quadrature, and the ringing's members;
session 16, the ropes' members from quarters of the record with Student's t and two
members for the seals' unknown friction where the record starts: 97 / 96 / 91 / 74 %
at 0.84 / 0.82 / 0.76 / 0.43 %; the windows' half-widths fall in two clusters, and the
medians between them move with a window or two). The windows
it misses are the pithead's (shortest ropes): on days 101-103 a rope's tension 0.7-1.0 %
off, on day 104 (ringing) the load 0.4-0.9 % off after the seals' friction moved
together by ~300 N each, more at a payload change than the validation's ringing let
them. On ropeload's
own simulation with Maxwell-slip seals (no drift) worst 0.55 / 0.54 %, median 0.30 /
0.33 % (session 17: the seals' own elements in the solution; before 1.10 / 1.20 and
0.60 / 0.65 % with one bristle), band 100 % at 1.61 / 1.73 % (session 32; 1.53 /
1.59 % before its sources were combined in quadrature): an assumed bristle
stiffness halved moves the friction at the pithead after a payload change by 2.5-3 %
of the load, and elements that do not drift never forget it. What remains is the
simulation's: it holds the pipes' oil rigid (11 % of the example hoist's oil), which
the description's oil volume counts; run on its chamber pressures with the true ropes,
this solution's friction is within 10 N of its truth with its volume, 110-120 N
(0.5 % of the load) off with the description's. With the pipes' oil lumped compressible
in the simulation (half of each branch with its chamber, half with the manifold; session
34, not kept): worst 0.24 / 0.28 %, median 0.11 / 0.10 %, the band unchanged (1.61 /
1.74 %); it moved the simulation under ten tests pinned to it (the share-out's 0.5 %
at a bottom visit to 0.61 %, the demo record's sensor offset no longer credited), which
a change of the simulation needs re-examined one by one. With LuGre seals worst 0.52 /
0.61 %, median 0.01 % (band 100 % at a median of 0.63 %, session 32; at session 16
0.58 %: half the windows' band 0.29 %, half 0.87-0.91 %), against 0.85-0.91 % and
30-35 windows worse than raw without the drift. The session-4 research prototype of
this method (since
removed; elasto-plastic seals on sensor pressures, no band) gave 1.6-1.8 % worst with
the ropes' constants fitted to the truth windows.
What it assumes: quasi-static pistons (no rope bounce in the spring law; a ringing
hoist's dynamic tension is common to the ropes and enters through the pressure);
the hoist description's oil volume, bulk modulus, bristle stiffness and friction law.
Without a logged x nothing identifies the ropes: the solution runs on the sigma points
of their prior stiffness spread (5 % per rope) and the estimate is the points' mean
(:func:`transforms.stick_slip_band.prior_rope_springs`, the unscented transform): ropes
taken alike move every piston alike and put every seal at the same friction, the most
the seals can hold together. Validation days 101-104 with the x columns taken out
(session 37): worst 3.50 / 2.37 / 1.50 / 0.82 %, median 0.36 / 0.27 / 0.25 / 0.09 %,
1 / 2 / 0 / 2 windows worse than raw, the band 98 / 99 / 98 / 100 % at 1.77 / 1.76 /
1.49 / 0.62 % (the equal share of :mod:`transforms.piston_motion` before: median 1.40 /
1.45 / 1.40 / 0.48 %, 23-24 windows worse than raw, band 5.5-6 %). The pistons start
where their ropes hold their chambers, every seal at 0 (session 47; before, every piston
at x = 0, so that a sigma point's stiffer ropes started their seals up to 1.7 kN apart
and the first payload change slid two of them): worst 2.10 / 2.37 / 1.31 / 0.71 %,
median 0.32 / 0.29 / 0.20 / 0.09 %, worst rope 4.42 / 4.42 / 4.49 / 3.47 % (4.94 /
4.87 / 5.55 / 3.47 before), the same windows worse than raw, the band 100 % on every day.

Tried and not kept: LuGre's presliding inside the step (bristle stiffness
sigma_0 (1 - sgn(dx) F / g)), driven by each sensor's pressure through a 4-sigma play
that settles over 2 s (session 13): days 101 / 102 went to 1.40 / 0.38 % and 1.37 /
0.52 %; applied to every hoist, it also drained the Maxwell-slip seals of ropeload's
own simulation (3.7 %, the raw error). The drift on the mean pressure instead, only
for LuGre seals, and with the turns counted, is what is kept (session 14). The drift's
path doubled: day 104 to 1.11 / 0.25 % but days 101-103 to 0.55-0.76 % median (the
trips' monotone changes lose little to the play, the ringing a lot: hence the turns).
A band member with 3x the drift: coverage +0-13 points for +0.25 % half-width.
Each seal also drained along its own played path (session 31, beside the oil's shared
travel, the larger of the two): day 104 to 0.66 / 0.17 %, none worse than raw, but days
101-103 to 1.6-1.9 / 0.5-0.6 %; only along its elastic (unclipped) steps, the same;
the drift shared equally instead of by compliance: 1.2-1.8 % worst on all four days.
The own path only while a ringing is counted (:func:`transforms.seal_drift.
ringing_travel` > 0): days 101-103 unchanged (none rings), day 104 0.96 -> 0.84 %
worst, 0.22 -> 0.14 % median, 4 -> 2 windows worse than raw, coverage 74 -> 84 %; but
ropeload's own LuGre simulation, which rings and integrates eq 15 exactly, went from
0.52 to 0.91 % worst and 100 to 90 % coverage: more drain than LuGre's, so a guess at
the validation world's own shaking, not the paper's physics.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.friction_law import friction_law_at, law_array, stribeck_g
from physics.lugre import lugre_drift, lugre_drift_exponent
from physics.maxwell_slip import maxwell_slip_elements, maxwell_slip_step, maxwell_slip_virgin
from physics.oil import ATMOSPHERIC_PRESSURE_PA, effective_bulk_modulus_at
from physics.rope_spring import (
    elements_on_rope_step,
    groove_payout_m,
    head_rope_stiffness_n_m,
    seal_on_rope_step,
)
from physics.sensor_branch import sensor_minus_chamber_at
from schemas.hoist import HoistDescription
from transforms.seal_drift import played_travel
from transforms.stick_slip_band import RopeSprings

__all__ = [
    "groove_deviations",
    "stick_slip",
    "stick_slip_mismatch",
    "stick_slip_state",
]

#: Samples between the bound's checks of :func:`stick_slip_mismatch`.
COMPARE_EVERY = 256

#: :func:`_kernel`'s sums of a mismatch when it computes none (:func:`stick_slip`): empty
#: arrays, so that the solution and the mismatch's loop call one compiled kernel (with
#: ``None`` there numba compiled the kernel twice, ~12 s more on a cold cache).
_NOT_COMPARED = np.zeros(0)
_NOT_RELAXED = np.zeros((0, 0))  # the kernel's relaxation not written


def stick_slip_state(pistons: int, elements: int = 1) -> np.ndarray:
    """Fresh state of :func:`stick_slip` (``[ran, continues, s, p, the ropes' hanging
    length, per piston the seal's force (its elements' total), x, v, the drift's play
    output and heading, per piston the compliance, the given drift travel not yet
    applied]``, then with ``elements`` > 1 Maxwell-slip elements per seal each
    element's deflection, then each sensor's reading at the last sample solved, then the
    time since that sample; :func:`transforms.filtering.fresh_state`). The hanging
    length is kept also where no sample was solved (0: no depth known yet)."""
    return np.zeros(8 + 4 * pistons + (pistons * elements if elements > 1 else 0) + pistons + 1)


def groove_deviations(hoist: HoistDescription, ropes: int) -> np.ndarray:
    """Each rope's groove radius deviation over the drum's radius, dr_i / R, where the
    hoist's model declares ``groove_wear`` (:func:`physics.rope_spring.groove_payout_m`),
    else zeros.

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> groove_deviations(load_hoist(EXAMPLE_HOIST), 4).tolist()
    [0.0, 0.0, 0.0, 0.0]
    """
    if "groove_wear" not in hoist.model.effects:
        return np.zeros(ropes)
    deviations = np.asarray(hoist.drum.groove_radius_deviation_m, dtype=np.float64)
    if deviations.shape != (ropes,):
        raise ValueError(f"drum.groove_radius_deviation: {deviations.size} values for "
                         f"{ropes} ropes")  # fmt: skip
    return deviations / hoist.drum.radius_m


def _constants(hoist: HoistDescription) -> np.ndarray:
    """[V, A, beta_liquid, air fraction, p_ref, EA, headframe, sigma_0] of the kernel."""
    return np.array(
        [
            hoist.oil_volume_m3,
            hoist.cylinders.bore_area_m2,
            hoist.oil.bulk_modulus_pa,
            hoist.oil.air_fraction,
            ATMOSPHERIC_PRESSURE_PA,
            hoist.ropes.head_rope_axial_stiffness_n,
            hoist.shaft.headframe_height_m,
            float(hoist.friction_law.bristle_stiffness_n_m),
        ]
    )


def stick_slip(
    p_sensor: tuple[np.ndarray, ...],
    x_logged: tuple[np.ndarray, ...],
    depth_m: np.ndarray,
    segment_id: np.ndarray,
    hoist: HoistDescription,
    springs: RopeSprings,
    *,
    dt_s: float | np.ndarray,
    nu_m2_s: np.ndarray | float = 0.0,
    branch: np.ndarray | None = None,
    state: np.ndarray | None = None,
    capacity_scale: float = 1.0,
    sigma0_scale: float = 1.0,
    start_at_capacity: float = 0.0,
    drift_pressure_pa: np.ndarray | None = None,
    drift_half_width_pa: float = 0.0,
    drift_travel_pa: np.ndarray | None = None,
    drift_ringing_pa: np.ndarray | None = None,
    presliding_elements: int = 1,
    out: tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]] | None = None,
    relaxation_out: np.ndarray | None = None,
) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    """Each piston's displacement [m] and seal friction [N] (module docstring).

    Parameters
    ----------
    p_sensor : tuple of ndarray
        Each rope's sensor pressure [Pa], calibrated and low-passed (NaN: unknown; the
        state is held).
    x_logged : tuple of ndarray
        Each piston's logged displacement [m]: read only at the record's first sample
        with a known mean pressure (NaN there: where its rope holds its chamber, its
        seal at 0; with none logged, their mean at 0).
    depth_m : ndarray
        Conveyance depth [m] (the ropes' hanging length; NaN: the last known, before any
        the record's first known).
    segment_id : ndarray of int
        Gap-free segment of each sample: a piston's speed restarts at 0 after a gap, and
        the drift's play at the new segment's first known pressure.
    hoist : HoistDescription
        Oil volume, bulk modulus, piston area, nominal EA, headframe, friction law.
    springs : RopeSprings
        The ropes' constants.
    dt_s : float or ndarray
        Sample step [s] (the pistons' speed for the capacity and the branch flow); or
        per sample, the step from the sample before (the band's members on means,
        :mod:`transforms.band_members`).
    nu_m2_s : ndarray or float
        Oil kinematic viscosity (per sample or one value) for the branch loss.
    branch : ndarray, optional
        :func:`physics.sensor_branch.sensor_branch`; None: no branch loss.
    state : ndarray, optional
        :func:`stick_slip_state`, carried from the previous block (updated in place).
    capacity_scale, sigma0_scale : float
        Factors on the friction law's capacity and on the bristle stiffness (the
        uncertainty band's members, :func:`~transforms.stick_slip_band.band_solutions`).
    start_at_capacity : float
        The seals' friction where the record starts (nothing tells it): 0 what the
        ropes leave each seal with their sum taken 0 (clipped at the seals' static
        capacity, :func:`_centred_stretch`); -1 or +1 the conveyance's common
        stretch that takes every seal as far that way as the ropes let them, one at its
        static capacity (the band's extremes of the unknown start, remembered until
        the pistons slide); where the ropes already leave a seal beyond its capacity
        that way, the estimate's start.
    drift_pressure_pa : ndarray, optional
        The pressure whose played travel drives the seals' drift
        (:func:`transforms.seal_drift.drift_pressure`, one per sample); None: the seals
        do not drift (Maxwell-slip).
    drift_half_width_pa : float
        Half-width of the play on it [Pa] (:func:`transforms.seal_drift.drift_pressure`),
        >= 0 (0: every wiggle of the drift's pressure counts).
    drift_travel_pa : ndarray, optional
        Instead of ``drift_pressure_pa``: the drift's travel of each sample given [Pa],
        finite and >= 0 (the full-rate samples' :func:`transforms.seal_drift.
        drift_travel`, ringing included, summed over each mean by
        :func:`transforms.compensation_record.identification_means`). The travel of
        samples with unknown pressures, and of the record's first (which only sets
        the state), is carried to the next sample with known pressures.
    drift_ringing_pa : ndarray, optional
        With ``drift_pressure_pa``: travel added to the play's at each sample [Pa],
        finite and >= 0 (the ringing the play hides, :func:`transforms.seal_drift.
        ringing_travel`).
    presliding_elements : int
        1: each seal is one elasto-plastic bristle (:func:`physics.rope_spring.
        seal_on_rope_step`); more: that many Maxwell-slip elements of the bristle
        stiffness in all (``presliding_hysteresis``, :func:`physics.maxwell_slip.
        maxwell_slip_elements`, :func:`physics.rope_spring.elements_on_rope_step`),
        which do not drift, and which start the record on their virgin curve
        (:func:`physics.maxwell_slip.maxwell_slip_virgin`).
    out : (tuple of ndarray, tuple of ndarray), optional
        Contiguous float64 arrays the displacements and frictions are written into.
    relaxation_out : ndarray, optional
        A C-contiguous float64 array of shape (samples, pistons) written with each
        seal's drift at
        each sample as the exponent it relaxes by there, sigma_0 s / g (its drift path
        s over its capacity's presliding range, :func:`physics.lugre.lugre_drift`: the
        friction, and any error of it, is multiplied by exp(-that)); 0 where it does not
        drift (:func:`transforms.stop_continuity.apply_stop_continuity` lets its shifts
        relax by it).

    Returns
    -------
    (x, friction) : tuple of tuple of ndarray

    Examples
    --------
    Four equal ropes at rest, then the load rises: the common pressure rises and the
    seals take the difference the oil's compression lets through (every piston sticks:
    the friction is the same on each).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> p = np.linspace(4.0e6, 4.05e6, 50)
    >>> springs = RopeSprings((1.0,) * 4, (0.0,) * 4, 0.0, 0)
    >>> x, f = stick_slip((p,) * 4, (np.zeros(50),) * 4, np.full(50, 300.0),
    ...                   np.zeros(50, int), hoist, springs, dt_s=0.01)
    >>> [round(float(fi[-1]), 1) for fi in f]
    [239.3, 239.3, 239.3, 239.3]
    """
    n = depth_m.shape[0]
    m = len(p_sensor)
    if out is None:
        out = (tuple(np.empty(n) for _ in range(m)), tuple(np.empty(n) for _ in range(m)))
    x_out, f_out = out
    if relaxation_out is None:
        relaxation_out = _NOT_RELAXED
    elif relaxation_out.shape != (n, m) or not relaxation_out.flags.c_contiguous:
        raise ValueError(
            f"relaxation_out: a C-contiguous array of {(n, m)}, not of {relaxation_out.shape}"
        )
    head, tail = _kernel_inputs(
        p_sensor, x_logged, depth_m, segment_id, hoist,
        dt_s=dt_s, nu_m2_s=nu_m2_s, branch=branch, capacity_scale=capacity_scale,
        sigma0_scale=sigma0_scale, start_at_capacity=start_at_capacity,
        drift_pressure_pa=drift_pressure_pa, drift_half_width_pa=drift_half_width_pa,
        drift_travel_pa=drift_travel_pa, drift_ringing_pa=drift_ringing_pa,
        presliding_elements=presliding_elements,
    )  # fmt: skip
    if state is not None and state.shape != stick_slip_state(m, presliding_elements).shape:
        raise ValueError(f"state has {state.shape[0]} values, not stick_slip_state's "
                         f"{stick_slip_state(m, presliding_elements).shape[0]}")  # fmt: skip
    if n:
        _kernel(
            *head,
            np.asarray(springs.stiffness_factors, dtype=np.float64),
            np.asarray(springs.length_offsets_m, dtype=np.float64),
            *tail,
            x_out,
            f_out,
            relaxation_out,
            stick_slip_state(m, presliding_elements) if state is None else state,
            np.inf,
            _NOT_COMPARED,
            _NOT_COMPARED,
            _NOT_COMPARED,
        )
    return x_out, f_out


def stick_slip_mismatch(
    p_sensor: tuple[np.ndarray, ...],
    x_logged: tuple[np.ndarray, ...],
    depth_m: np.ndarray,
    segment_id: np.ndarray,
    hoist: HoistDescription,
    stiffness_factors: np.ndarray,
    length_offsets_m: np.ndarray,
    *,
    dt_s: float,
    nu_m2_s: np.ndarray | float = 0.0,
    branch: np.ndarray | None = None,
    drift_travel_pa: np.ndarray | None = None,
    presliding_elements: int = 1,
    bounds: np.ndarray | None = None,
) -> np.ndarray:
    """For each row of candidate ropes, :func:`stick_slip`'s x against the logged x: the
    mean over the pistons with a logged x of each one's mean square of the model's x
    less the logged x (NaN samples left out) [m^2]; NaN where no piston has one.

    ``bounds`` (one per candidate [m^2], default none): a candidate's solution stops
    where what it has summed so far already exceeds its bound (each piston's squares
    over its count of logged x, averaged over the pistons that have one: it only grows
    to the mismatch), and that partial value, above the bound and at most the whole
    mismatch, is its answer; one within its bound is the whole mismatch, the same to
    the last bit. What a search
    needs that only asks whether a candidate beats a known one
    (:func:`transforms.rope_identification.identify_rope_springs`).

    The rope identification's objective (:mod:`transforms.rope_identification`), for
    a whole population in one call to compiled code: on a short record the Python
    around one solution costs more than the solution. Releases the GIL.

    ``stiffness_factors``, ``length_offsets_m``: (candidates, pistons) arrays of
    :class:`RopeSprings`' constants; the other arguments as :func:`stick_slip`'s (the
    seals start as its default, ``capacity_scale`` 1, ``start_at_capacity`` 0).

    >>> from schemas.hoist import EXAMPLE_HOIST, load_hoist
    >>> hoist = load_hoist(EXAMPLE_HOIST)
    >>> p = np.linspace(4.0e6, 4.05e6, 1000)
    >>> x = np.zeros(1000)
    >>> ropes = np.array([[1.0] * 4, [1.0, 1.05, 1.0, 1.0]])
    >>> mismatch = stick_slip_mismatch((p,) * 4, (x,) * 4, np.full(1000, 300.0),
    ...     np.zeros(1000, int), hoist, ropes, np.zeros((2, 4)), dt_s=0.01)
    >>> bool(mismatch[0] < mismatch[1])
    True

    Unbounded, the first is whole; bounded by a hundredth of its mismatch, the second
    stops early (its squares grow as t^3: a lower bound above that hundredth):

    >>> bounded = stick_slip_mismatch((p,) * 4, (x,) * 4, np.full(1000, 300.0),
    ...     np.zeros(1000, int), hoist, ropes, np.zeros((2, 4)), dt_s=0.01,
    ...     bounds=np.array([np.inf, mismatch[1] / 100]))
    >>> bool(bounded[0] == mismatch[0]), bool(mismatch[1] / 100 < bounded[1] < mismatch[1])
    (True, True)
    """
    stiffness = np.atleast_2d(np.asarray(stiffness_factors, dtype=np.float64))
    offsets = np.atleast_2d(np.asarray(length_offsets_m, dtype=np.float64))
    m = len(p_sensor)
    if stiffness.shape != offsets.shape or stiffness.shape[1] != m:
        raise ValueError(f"candidate ropes {stiffness.shape} and offsets {offsets.shape} "
                         f"are not (candidates, {m})")  # fmt: skip
    head, tail = _kernel_inputs(
        p_sensor, x_logged, depth_m, segment_id, hoist, dt_s=dt_s, nu_m2_s=nu_m2_s,
        branch=branch, drift_travel_pa=drift_travel_pa,
        presliding_elements=presliding_elements,
    )  # fmt: skip
    n = depth_m.shape[0]
    if not n:
        return np.full(stiffness.shape[0], np.nan)
    limits = np.full(stiffness.shape[0], np.inf)
    if bounds is not None:
        limits = np.array(bounds, dtype=np.float64)
        if limits.shape != (stiffness.shape[0],) or np.isnan(limits).any():
            raise ValueError(f"bounds {limits.shape}: one number per candidate")
    scratch = tuple(np.empty(n) for _ in range(m)), tuple(np.empty(n) for _ in range(m))
    return _mismatch_kernel(
        head, np.ascontiguousarray(stiffness), np.ascontiguousarray(offsets), tail, *scratch,
        stick_slip_state(m, presliding_elements).shape[0], limits,
    )  # fmt: skip


def _kernel_inputs(
    p_sensor: tuple[np.ndarray, ...],
    x_logged: tuple[np.ndarray, ...],
    depth_m: np.ndarray,
    segment_id: np.ndarray,
    hoist: HoistDescription,
    *,
    dt_s: float | np.ndarray,
    nu_m2_s: np.ndarray | float = 0.0,
    branch: np.ndarray | None = None,
    capacity_scale: float = 1.0,
    sigma0_scale: float = 1.0,
    start_at_capacity: float = 0.0,
    drift_pressure_pa: np.ndarray | None = None,
    drift_half_width_pa: float = 0.0,
    drift_travel_pa: np.ndarray | None = None,
    drift_ringing_pa: np.ndarray | None = None,
    presliding_elements: int = 1,
) -> tuple[tuple, tuple]:
    """:func:`_kernel`'s arguments before the ropes' constants and after them up to the
    outputs, checked (:func:`stick_slip`'s parameters)."""
    n = depth_m.shape[0]
    if len(x_logged) != len(p_sensor):
        raise ValueError(f"{len(x_logged)} logged x for {len(p_sensor)} pressures")
    for name, given in (("p_sensor", p_sensor), ("x_logged", x_logged)):
        for i, values in enumerate(given):
            if np.shape(values) != (n,):
                raise ValueError(f"{name}[{i}] has {np.shape(values)} samples, depth_m {n}")
    if np.shape(segment_id) != (n,):
        raise ValueError(f"segment_id has {np.shape(segment_id)} samples, depth_m {n}")
    nu = np.atleast_1d(np.asarray(nu_m2_s, dtype=np.float64))
    steps = np.ascontiguousarray(np.atleast_1d(np.asarray(dt_s, dtype=np.float64)))
    if steps.shape not in ((1,), (n,)) or not (np.isfinite(steps).all() and (steps > 0).all()):
        raise ValueError(f"dt_s must be one step or one per sample (> 0 s), got {steps.shape}")
    drift, drift_mode = np.zeros(1), 0
    if drift_pressure_pa is not None and drift_travel_pa is not None:
        raise ValueError("give drift_pressure_pa or drift_travel_pa, not both")
    for name, given in (
        ("drift_pressure_pa", drift_pressure_pa),
        ("drift_travel_pa", drift_travel_pa),
    ):
        if given is not None:
            drift = np.ascontiguousarray(given, dtype=np.float64)
            drift_mode = 1 if name == "drift_pressure_pa" else 2
            if drift.shape != (n,):
                raise ValueError(f"{name} has {drift.shape} samples, depth_m {n}")
            if drift_mode == 2 and not (np.isfinite(drift).all() and (drift >= 0.0).all()):
                raise ValueError(f"{name} must be finite and >= 0")
    if presliding_elements < 1:
        raise ValueError(f"presliding_elements {presliding_elements} must be >= 1")
    if presliding_elements > 1 and drift_mode:
        raise ValueError("Maxwell-slip seals (presliding_elements > 1) do not drift")
    sigma0 = float(hoist.friction_law.bristle_stiffness_n_m) * sigma0_scale
    if presliding_elements > 1:
        element_k, element_w = maxwell_slip_elements(presliding_elements, sigma0)
    else:
        element_k, element_w = np.full(1, sigma0), np.ones(1)
    if start_at_capacity not in (-1.0, 0.0, 1.0):
        raise ValueError(f"start_at_capacity {start_at_capacity} must be -1, 0 or 1")
    if drift_mode == 1 and not drift_half_width_pa >= 0.0:
        raise ValueError(f"drift_half_width_pa {drift_half_width_pa} must be >= 0")
    ringing = np.zeros(1)
    if drift_ringing_pa is not None:
        if drift_mode != 1:
            raise ValueError("drift_ringing_pa goes with drift_pressure_pa")
        ringing = np.ascontiguousarray(drift_ringing_pa, dtype=np.float64)
        if ringing.shape != (n,):
            raise ValueError(f"drift_ringing_pa has {ringing.shape} samples, depth_m {n}")
        if not (np.isfinite(ringing).all() and (ringing >= 0.0).all()):
            raise ValueError("drift_ringing_pa must be finite and >= 0")
    head = (
        tuple(np.ascontiguousarray(p, dtype=np.float64) for p in p_sensor),
        tuple(np.ascontiguousarray(x, dtype=np.float64) for x in x_logged),
        np.ascontiguousarray(depth_m, dtype=np.float64),
        np.ascontiguousarray(segment_id, dtype=np.int64),
        steps,
        np.ascontiguousarray(nu),
        branch is not None,
        np.zeros(6) if branch is None else branch,
        _constants(hoist) * np.r_[np.ones(7), sigma0_scale],
        law_array(hoist.friction_law),
        groove_deviations(hoist, len(p_sensor)),
    )
    tail = (
        float(capacity_scale),
        float(start_at_capacity),
        drift_mode,
        drift,
        float(drift_half_width_pa),
        drift_ringing_pa is not None,
        ringing,
        element_k,
        element_w,
    )
    return head, tail


@njit(cache=True, nogil=True, error_model="numpy")
def _mismatch_kernel(
    head, stiffness, offsets, tail, x_out, f_out, state_size, bounds
):  # pragma: no cover - numba
    """:func:`stick_slip_mismatch`'s loop over the candidates."""
    p_sensor, x_logged, depth, segment, dt, nu, with_loss, branch, const, law, groove = head
    scale, start, drift_mode, drift, half_width, rings, ringing, element_k, element_w = tail
    m = len(p_sensor)
    n = depth.shape[0]
    out = np.full(stiffness.shape[0], np.nan)
    logged = np.zeros(m)  # each piston's logged samples: at least those compared
    for i in range(m):
        for t in range(n):
            if not np.isnan(x_logged[i][t]):
                logged[i] += 1.0
    squares = np.zeros(m)
    counts = np.zeros(m)
    unwritten = np.zeros((0, 0))  # the seals' relaxation, not written
    for k in range(stiffness.shape[0]):
        squares[:] = 0.0
        counts[:] = 0.0
        whole = _kernel(
            p_sensor, x_logged, depth, segment, dt, nu, with_loss, branch, const, law, groove,
            stiffness[k], offsets[k], scale, start, drift_mode, drift, half_width, rings,
            ringing, element_k, element_w, x_out, f_out, unwritten, np.zeros(state_size),
            bounds[k], logged, squares, counts,
        )  # fmt: skip
        if not whole:  # stopped beyond its bound: a lower bound of the mismatch
            out[k] = _so_far(squares, logged)
            continue
        total = 0.0
        pistons = 0
        for i in range(m):
            if counts[i]:  # np.nanmean's: a NaN either side is left out
                total += squares[i] / counts[i]
                pistons += 1
        if pistons:
            out[k] = total / pistons
    return out


@njit(cache=True, nogil=True, inline="always")
def _compare(x_out, x_logged, t, squares, counts):  # pragma: no cover - numba
    """Sample t's squared differences of the model's x and the logged, summed by piston."""
    for i in range(len(x_out)):
        d = x_out[i][t] - x_logged[i][t]
        if not np.isnan(d):
            squares[i] += d * d
            counts[i] += 1.0


@njit(cache=True, nogil=True, inline="always")
def _so_far(squares, logged):  # pragma: no cover - numba
    """A lower bound of the mismatch from the squares summed so far: each piston's
    squares over all its logged samples (the whole's divides more squares by at most
    as many), averaged over the pistons with any (one whose samples all compare NaN
    adds nothing here and leaves the whole's average); NaN without a logged x."""
    total = 0.0
    pistons = 0
    for i in range(squares.shape[0]):
        if logged[i]:
            total += squares[i] / logged[i]
            pistons += 1
    return total / pistons if pistons else np.nan


@njit(cache=True, nogil=True, inline="always")
def _beyond(bound, squares, logged):  # pragma: no cover - numba
    """What the squares summed so far make of the mismatch already exceeds ``bound``."""
    return _so_far(squares, logged) > bound * (1.0 + 1e-9)


@njit(cache=True, nogil=True)
def _centred_stretch(s, ka, x, off, p_now, area, capacity, skip):  # pragma: no cover - numba
    """The common stretch at a record's start where the seals' friction sums to 0 (the
    pistons not ``skip``-ped: those with a logged x).

    Nothing tells the seals' friction where a record starts, so the estimate takes it
    centred: sum_i F_i = 0, F_i = clip(ka_i (s - x_i - off_i) - p_i A, +-capacity), the
    load the sensors show (eq 2 with the frictions' sum 0). ``s`` is the least-squares
    stretch, where the unclipped forces sum to 0; where none clips it is kept as it is.
    Else the clipped sum, continuous and non-decreasing in s from -m capacity to
    +m capacity, is brought to 0 by bisection (once per record); the kernel then puts a
    clipped rope's piston where its rope holds it at its seal's capacity. Before
    (session 47), a rope asking more than its seal holds left the frictions' sum at the
    clip's excess, and its piston slid at standing pressure. On the validation days
    that moved nothing (``benchmarks/eval_compensation.py``).
    """
    m = ka.shape[0]
    clipped = False
    lo = np.inf
    hi = -np.inf
    for i in range(m):
        if skip[i]:
            continue
        if abs(ka[i] * (s - x[i] - off[i]) - p_now[i] * area) > capacity:
            clipped = True
        lo = min(lo, (p_now[i] * area - capacity) / ka[i] + x[i] + off[i])
        hi = max(hi, (p_now[i] * area + capacity) / ka[i] + x[i] + off[i])
    if not clipped or not capacity > 0.0:
        return s
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        total = 0.0
        for i in range(m):
            if not skip[i]:
                force = ka[i] * (mid - x[i] - off[i]) - p_now[i] * area
                total += min(max(force, -capacity), capacity)
        if total < 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(cache=True, nogil=True, error_model="numpy")
def _kernel(
    p_sensor, x_logged, depth, segment, steps, nu, with_loss, branch, const, law, groove, a, c,
    scale, start, drift_mode, drift_p, drift_w, rings, ringing, element_k, element_w, x_out,
    f_out, relax_out, state, bound, logged, squares, counts,
):  # pragma: no cover - numba  # fmt: skip
    """Per sample: the seals' drift, the oil's Newton solve for s, each piston's seal step
    (module docstring).

    One function over 80 lines on purpose: the per-sample loop keeps the pistons' state
    in registers; the physics is in :func:`physics.rope_spring.seal_on_rope_step` (or
    with Maxwell-slip elements :func:`physics.rope_spring.elements_on_rope_step` and
    :func:`physics.maxwell_slip.maxwell_slip_step`) and :func:`physics.lugre.lugre_drift`,
    the play in :func:`transforms.seal_drift.played_travel`.

    With ``squares`` not empty (:func:`_mismatch_kernel`; :func:`stick_slip` passes
    empty ones, :data:`_NOT_COMPARED`) it sums each piston's squared x less the logged
    x and returns False where, every :data:`COMPARE_EVERY` samples, they already exceed
    ``bound`` (:func:`_beyond`): stopped, the state not kept. Else True. With
    ``relax_out`` not empty (its shape (n, m)) it writes each seal's drift exponent of
    each sample there (:func:`stick_slip`'s ``relaxation_out``; C-contiguous, as the
    empty one, so that one compiled kernel serves both).
    """
    m = len(p_sensor)
    n = depth.shape[0]
    volume, area, beta_l, air, p_ref = const[0], const[1], const[2], const[3], const[4]
    ea, headframe, sigma0 = const[5], const[6], const[7]
    z = np.zeros(m)
    x = np.zeros(m)
    v = np.zeros(m)
    damping = np.zeros(m)
    cap = np.zeros(m)
    ka = np.zeros(m)
    off = np.zeros(m)  # each rope's length offset at the sample (c_i, a worn groove's payout)
    p_now = np.zeros(m)  # each sensor's pressure at the sample, the others' mean if unknown
    # each sensor's reading at the last sample solved (NaN: not logged), carried in the
    # state after the elements: where a sensor leaves or rejoins the mean, the oil's
    # change is taken from those logged at both samples, also across a block's edge
    prev_at = 8 + 4 * m + (m * element_k.shape[0] if element_k.shape[0] > 1 else 0)
    p_prev = np.full(m, np.nan)
    ran = state[0] != 0.0
    resume = ran and state[1] != 0.0
    s, p_last = state[2], state[3]
    p_play = state[5 + 3 * m] if resume else np.nan
    heading = state[6 + 3 * m] if resume else 0.0  # the play's last direction of travel
    compliance = np.ones(m)  # each piston's d dx / d demand at its last step
    unlogged = np.zeros(m, dtype=np.bool_)  # at the record's start: no logged x
    step = np.zeros(m)  # the Newton solve's last evaluation: each piston's dx,
    bristle = np.zeros(m)  # its seal's force (one bristle),
    given = np.zeros(m)  # and its d dx / d demand,
    demand = np.zeros(m)  # at that demand,
    lo = np.zeros(m)  # linear between these demands
    hi = np.zeros(m)
    pending = state[7 + 4 * m]  # given drift travel not yet applied (unknown pressures)
    elements = element_k.shape[0] > 1  # Maxwell-slip seals: each element's deflection
    deltas = np.zeros((m, element_k.shape[0]))
    limits = np.zeros((m, element_k.shape[0]))  # each element's deflection limit [m]
    # the limits per newton of capacity: x cap, maxwell_slip_step's own w g / k to
    # within an ulp (a division a sample saved; its step clips at its own limit)
    per_capacity = element_w / element_k
    if elements and ran:
        for i in range(m):
            for j in range(element_k.shape[0]):
                deltas[i, j] = state[8 + 4 * m + i * element_k.shape[0] + j]
    if resume:
        for i in range(m):
            compliance[i] = state[7 + 3 * m + i]
    if ran:
        for i in range(m):
            p_prev[i] = state[prev_at + i]
        for i in range(m):
            z[i] = state[5 + i]
            x[i] = state[5 + m + i]
            v[i] = state[5 + 2 * m + i]
    # the last known depth's, carried (also from a block where no pressure was known);
    # NaN: none known yet, the record's first known depth is taken at its start
    hanging = state[4] if state[4] > 0.0 else np.nan
    held = state[prev_at + m]  # time since the last solved sample, unknown pressures held
    per_sample = nu.shape[0] > 1
    per_step = steps.shape[0] > 1
    compare = squares.shape[0] > 0  # the mismatch's sums (_mismatch_kernel), and its bound
    relaxes = relax_out.shape[0] > 0
    for t in range(n):
        if relaxes:
            for i in range(m):
                relax_out[t, i] = 0.0
        if compare and t > 0:
            _compare(x_out, x_logged, t - 1, squares, counts)
            if t % COMPARE_EVERY == 0 and _beyond(bound, squares, logged):
                return False  # stopped; the state is not kept: the mismatch's start afresh
        dt = steps[t] if per_step else steps[0]
        # a new gap-free segment restarts the speeds and the drift's play, also where its
        # first pressures are unknown (the reset is then carried in the state)
        if (t == 0 and not resume) or (t > 0 and segment[t] != segment[t - 1]):
            p_play = np.nan
            heading = 0.0
            for i in range(m):
                v[i] = 0.0
        if drift_mode == 2:
            pending += drift_p[t]
        # a sensor not logged here takes the others' mean: the chambers share the oil
        # (equal at rest, apart by branch losses while it flows); none logged: held
        p_mean = 0.0
        known = 0
        for i in range(m):
            if np.isfinite(p_sensor[i][t]):
                p_mean += p_sensor[i][t]
                known += 1
        p_mean = p_mean / known if known else np.nan
        for i in range(m):
            p_now[i] = p_sensor[i][t] if np.isfinite(p_sensor[i][t]) else p_mean
        if np.isfinite(depth[t]):
            hanging = headframe + max(depth[t], 0.0)
        if not np.isfinite(p_mean):
            for i in range(m):
                x_out[i][t] = x[i]
                f_out[i][t] = z[i]
                p_prev[i] = np.nan
            held += dt
            continue
        if not ran:
            held = 0.0
            if not np.isfinite(hanging):  # no depth known yet: the record's first known
                hanging = headframe
                for later in range(t, n):
                    if np.isfinite(depth[later]):
                        hanging = headframe + max(depth[later], 0.0)
                        break
        # the step's time: since the last sample solved (a stretch of unknown pressures
        # held the pistons; its motion is solved here, over that whole time)
        elapsed = dt
        if held > 0.0:
            elapsed += held
            held = 0.0
        k = head_rope_stiffness_n_m(ea, hanging)
        p_law = max(p_mean, 1e5)
        fc, fs, vs, kv = friction_law_at(p_law, law)
        for i in range(m):
            ka[i] = a[i] * k
            off[i] = c[i] + groove_payout_m(hanging - headframe, groove[i])
            damping[i] = 0.0
            if with_loss:  # the branch loss as a damper, implicit (explicit it diverges)
                speed = v[i] if abs(v[i]) > 1e-6 else 1e-6
                nu_t = nu[t] if per_sample else nu[0]
                damping[i] = -area * sensor_minus_chamber_at(speed, nu_t, branch) / speed / elapsed
            cap[i] = scale * (stribeck_g(v[i], fc, fs, vs) + kv * abs(v[i]))
            if elements:
                for j in range(element_k.shape[0]):
                    limits[i, j] = per_capacity[j] * cap[i]
        if not ran:  # the record's start: positions logged, friction unknown (sum 0, or
            # for the band's start members as far as the ropes let every seal go)
            num = 0.0
            den = 0.0
            for i in range(m):
                unlogged[i] = not np.isfinite(x_logged[i][t])
                if not unlogged[i]:
                    x[i] = x_logged[i][t]
                    num += p_now[i] * area + ka[i] * (x[i] + off[i])
                    den += ka[i]
            if compare:  # the mismatch keeps the least-squares start (module docstring)
                for i in range(m):
                    if unlogged[i]:
                        den += ka[i]  # at x = 0
                        num += p_now[i] * area + ka[i] * off[i]
                        x[i] = 0.0
                s = num / den
            elif den == 0.0:  # no piston logged: their mean x at 0
                for i in range(m):
                    num += p_now[i] * area / ka[i] + off[i]
                s = num / m
            else:  # the logged seals' friction summing to 0, also where a rope's clips
                s = _centred_stretch(num / den, ka, x, off, p_now, area, scale * fs, unlogged)
            for i in range(m):  # a piston not logged where its rope holds its chamber
                if unlogged[i] and not compare:
                    x[i] = s - off[i] - p_now[i] * area / ka[i]
            if start != 0.0:  # the common stretch that takes the seals farthest that way
                reach = s
                for i in range(m):
                    at_cap = (start * scale * fs + p_now[i] * area) / ka[i] + x[i] + off[i]
                    reach = (
                        at_cap
                        if i == 0
                        else (min(reach, at_cap) if start > 0.0 else max(reach, at_cap))
                    )
                s = max(s, reach) if start > 0.0 else min(s, reach)
            for i in range(m):
                force = ka[i] * (s - x[i] - off[i]) - p_now[i] * area
                z[i] = min(max(force, -scale * fs), scale * fs)
                balanced = z[i] == force
                if elements:
                    z[i] = maxwell_slip_virgin(z[i], deltas[i], element_k, element_w, cap[i])
                if not balanced and not compare:
                    # a rope asking more than its seal holds: the piston where its rope
                    # holds its chamber and seal (eq 2), not out of balance at the logged
                    # x, to slide at standing pressure and push the others' seals up to
                    # their capacity (the mismatch keeps the logged x: module docstring)
                    x[i] = s - off[i] - (p_now[i] * area + z[i]) / ka[i]
                x_out[i][t] = x[i]
                f_out[i][t] = z[i]
                p_prev[i] = p_sensor[i][t]
            ran = True
            p_last = p_mean
            continue
        beta = effective_bulk_modulus_at(p_law, beta_l, air, p_ref, 1.0)
        if drift_mode:  # LuGre's drift: the bristles relax along the oil's real motion
            if drift_mode == 1:
                travel, p_play, heading = played_travel(drift_p[t], p_play, heading, drift_w)
                if rings:
                    travel += ringing[t]
            else:  # the travel given, with what samples of unknown pressure carried
                travel = pending
                pending = 0.0
            shares = compliance.sum()  # each piston's share of the oil's motion (eq 5)
            if travel > 0.0 and 0.0 < shares < np.inf:
                path = travel * volume / (beta * area * shares)
                for i in range(m):
                    if cap[i] > 0.0:
                        z[i] = lugre_drift(z[i], path * compliance[i], sigma0, cap[i])
                        if relaxes:
                            relax_out[t, i] = lugre_drift_exponent(
                                path * compliance[i], sigma0, cap[i]
                            )
        dp = p_mean - p_last
        steady = known == m
        for i in range(m):
            steady = steady and not np.isnan(p_prev[i])
        if not steady:
            # a sensor leaves or rejoins the mean: the oil's change from those logged at
            # both samples, not a step of their mean's make-up
            common = 0.0
            both = 0
            for i in range(m):
                if np.isfinite(p_sensor[i][t]) and np.isfinite(p_prev[i]):
                    common += p_sensor[i][t] - p_prev[i]
                    both += 1
            if both:
                dp = common / both
        for i in range(m):
            p_prev[i] = p_sensor[i][t]
        target = volume / (beta * area) * dp
        ds = 0.0
        below, above = -np.inf, np.inf  # the root's bracket (the sum rises with ds)
        solved = False  # step, friction and compliance of the last evaluation are at s + ds
        for _ in range(60):
            total = 0.0
            slope = 0.0
            for i in range(m):
                demand[i] = ka[i] * (s + ds - x[i] - off[i]) - p_now[i] * area
                if elements:
                    step[i], given[i], lo[i], hi[i] = elements_on_rope_step(
                        demand[i], deltas[i], element_k, limits[i], ka[i] + damping[i]
                    )
                else:
                    step[i], bristle[i], given[i], lo[i], hi[i] = seal_on_rope_step(
                        demand[i], z[i], sigma0, ka[i] + damping[i], cap[i]
                    )
                total += step[i]
                slope += given[i] * ka[i]
            err = total - target
            if abs(err) < 1e-13 or slope == 0.0:
                solved = True
                break
            if err < 0.0:
                below = ds
            else:
                above = ds
            move = -err / slope
            # every piston's demand stays on its piece: the sum is linear up to the new
            # s, which is its root; the steps follow their slopes, no evaluation there
            linear = True
            for i in range(m):
                if not lo[i] <= demand[i] + ka[i] * move <= hi[i]:
                    linear = False
                    break
            ds += move
            if linear:
                for i in range(m):
                    shift = given[i] * ka[i] * move
                    step[i] += shift
                    if not elements and np.isfinite(lo[i]) and np.isfinite(hi[i]):
                        bristle[i] += sigma0 * shift  # sticking: the bristles follow
                solved = True
                break
            # a piecewise-linear sum is not convex: where Newton leaves the bracket (it
            # can cycle between break points) the bracket is halved instead
            if not below < ds < above and np.isfinite(below) and np.isfinite(above):
                ds = 0.5 * (below + above)
        s += ds
        for i in range(m):
            if not solved:  # the iterations ran out: evaluate at the last s
                demand[i] = ka[i] * (s - x[i] - off[i]) - p_now[i] * area
                if elements:
                    step[i], given[i], lo[i], hi[i] = elements_on_rope_step(
                        demand[i], deltas[i], element_k, limits[i], ka[i] + damping[i]
                    )
                else:
                    step[i], bristle[i], given[i], lo[i], hi[i] = seal_on_rope_step(
                        demand[i], z[i], sigma0, ka[i] + damping[i], cap[i]
                    )
            dx = step[i]
            compliance[i] = given[i]
            if elements:
                z[i] = maxwell_slip_step(deltas[i], dx, element_k, element_w, cap[i])
            else:
                z[i] = bristle[i]
            x[i] += dx
            v[i] = dx / elapsed
            x_out[i][t] = x[i]
            f_out[i][t] = z[i]
        p_last = p_mean
    if compare and n:
        _compare(x_out, x_logged, n - 1, squares, counts)
    if np.isfinite(hanging):
        state[4] = hanging
    state[prev_at + m] = held
    if n and ran:
        state[0] = 1.0
        state[2], state[3] = s, p_last
        state[5 + 3 * m] = p_play
        state[6 + 3 * m] = heading
        for i in range(m):
            state[7 + 3 * m + i] = compliance[i]
        for i in range(m):
            state[5 + i] = z[i]
            state[5 + m + i] = x[i]
            state[5 + 2 * m + i] = v[i]
        if elements:
            for i in range(m):
                for j in range(element_k.shape[0]):
                    state[8 + 4 * m + i * element_k.shape[0] + j] = deltas[i, j]
        for i in range(m):
            state[prev_at + i] = p_prev[i]
    state[7 + 4 * m] = pending
    return True
