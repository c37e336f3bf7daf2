"""The conveyance's logged motion as a replay input, and the rope bounce seen in a record.

A replay (:mod:`sims.replay`) simulates measured trips through the device model. The
winder profile of the hoist description (:func:`sims.trips.trip`: constant acceleration
and deceleration, infinite jerk at the phase changes, the described top speed) is what
the winder is set to do, not what it did: real winders are jerk-limited, reach a top
speed a few percent off the nameplate and accelerate differently trip to trip
(0.75-0.85 m/s2 seen on one hoist). On a 600 m trip a 3 % slower top speed moves the
conveyance 10 m behind the described one by mid-trip, and the hanging tail rope
(6.2 kg/m x 2) with it: ~0.1 MPa of common-mode pressure. So the replay drives the
simulation with what the encoder logged:

:func:`motion_knots`
    The logged speed of one trip averaged into ``knot_s`` bins and integrated
    (trapezoid) from the standstill depth before the trip; the speeds are scaled by the
    ratio of the logged travel (stop depth - start depth) to the integrated one, so the
    profile ends at the logged stop depth (an encoder's speed and depth channels
    disagree by the speed's calibration).
:func:`profile_from_knots`
    A :class:`sims.trips.TripProfile` whose constant-acceleration segments join the
    knots: speed piecewise linear, depth piecewise quadratic, both continuous -- the
    form the device simulation takes (its kernel looks segments up by time).

Rope bounce (the conveyance oscillating on its head ropes, 0.8-2.7 Hz from pithead to
bottom) is rung by every change of acceleration. How much a hoist rings depends on its
ropes' damping, which a mine does not know (the hoist description's
``head_rope_damping_ratio`` is a default). :func:`rope_damping_from_record` reads it off
the record: the common-mode pressure after each stop, band-passed around the bounce
frequencies, against the same band at quiet standstill. Where the ringing is not above
the noise 3-7 s after the stops, the ropes are damped at ~0.2 or more (a model that rings
where the data does not leaves a gap of ~0.1 MPa, see issue 14) and the replay chooses
among 0.1 / 0.3 / 1.0 by its gap (:func:`discovery.planning.plan_replay`); where it is, the
damping ratio comes from the decay of its envelope (logarithmic decrement,
``zeta = lambda / (2 pi f)``, small-damping form).
"""

from __future__ import annotations

import numpy as np
from scipy import fft as sp_fft
from scipy import signal

from physics.trip_rule import TRIP_BRIDGE_S
from physics.white_noise import MAD_TO_SIGMA
from sims.trips import TripProfile

__all__ = [
    "KNOT_ACCELERATION_SIGMA",
    "KNOT_MAX_S",
    "KNOT_S",
    "knot_spacing_s",
    "motion_knots",
    "profile_from_knots",
    "rope_bounce_unseen",
    "rope_damping_from_record",
]

#: Knot spacing of the logged motion [s]: the bins average the encoder's speed
#: quantisation (1 mm/s) and jitter, and are short against a winder's jerk phase (~1 s).
#: A coarser quantisation widens them (:func:`knot_spacing_s`).
KNOT_S = 0.1
#: The RMS error of the knots' acceleration a logged speed's quantisation may leave
#: [m/s2]: 0.005 m/s2 of a ~20 t conveyance is ~100 N, under the pressure sensors' noise
#: (5 kPa on four 100 mm pistons, ~160 N).
KNOT_ACCELERATION_SIGMA = 0.005
#: The widest knot spacing [s]: half a winder's jerk phase (~1 s), which the knots'
#: straight segments must still follow.
KNOT_MAX_S = 0.5


def knot_spacing_s(t_s: np.ndarray, speed_m_s: np.ndarray) -> float:
    r"""Knot spacing for a logged speed [s]: :data:`KNOT_S`, or wider where the speed's
    quantisation q would make the knots' acceleration jagged.

    While the conveyance accelerates the logged speed sweeps through the quantisation's
    steps, so each sample's error is about uniform, of standard deviation
    :math:`q/\sqrt{12}`; a knot's mean over :math:`r \Delta` samples (r the rate, Delta
    the spacing) and the difference of two neighbours give an acceleration error of
    :math:`\sigma_a = q / (\sqrt{6 r}\, \Delta^{3/2})`. The spacing keeps
    :math:`\sigma_a` at :data:`KNOT_ACCELERATION_SIGMA`: an encoder's 1 mm/s at 50 Hz
    needs 0.05 s (the default 0.1 s stands); a speed logged to 0.01 m/s 0.24 s (0.1 s
    left the acceleration 0.018 m/s2 off in RMS, which a flow-squared valve loss took
    for its own: issue 14's probe named a local loss on a record hiding nothing), at
    most :data:`KNOT_MAX_S`. q is the smallest step between the distinct logged speeds
    (to 1 um/s) that three pairs of them share (one value off the grid does not set it).

    >>> t = np.arange(0, 60, 0.02)
    >>> v = np.minimum(0.8 * t, 10.0) + np.random.default_rng(0).normal(0, 0.003, t.size)
    >>> knot_spacing_s(t, np.round(v, 3)), round(knot_spacing_s(t, np.round(v, 2)), 3)
    (0.1, 0.237)
    """
    v = np.asarray(speed_m_s, dtype=float)
    steps = np.round(np.diff(np.unique(v[np.isfinite(v)])), 6)
    steps = steps[steps > 0.0]
    dt = np.diff(np.asarray(t_s, dtype=float))
    dt = dt[dt > 0.0]
    if steps.size == 0 or dt.size == 0:
        return KNOT_S
    values, counts = np.unique(steps, return_counts=True)
    shared = values[counts >= 3]  # a value off the grid makes steps of its own, once
    q = float(shared[0] if shared.size else values[0])
    rate = 1.0 / float(np.median(dt))
    wanted = (q / (np.sqrt(6.0 * rate) * KNOT_ACCELERATION_SIGMA)) ** (2.0 / 3.0)
    return float(min(max(KNOT_S, wanted), KNOT_MAX_S))


def motion_knots(
    t_s: np.ndarray,
    speed_m_s: np.ndarray,
    t_lo: float,
    t_hi: float,
    start_depth_m: float,
    end_depth_m: float,
    *,
    at_rest_before: bool = True,
    at_rest_after: bool = True,
    knot_s: float = KNOT_S,
    depth_m: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Knots (time [s], speed [m/s, + down], depth [m]) of the logged motion in
    ``[t_lo, t_hi]``; None when fewer than 5 bins hold a logged speed.

    Bins of ``knot_s`` hold the mean logged speed at their samples' mean time; empty
    bins (dropped samples) are left out (the neighbours' segment spans them). With
    ``at_rest_before`` / ``at_rest_after`` the first / last knot is at rest (the window
    starts and ends at a standstill); with both, the speeds are scaled so the
    integrated travel equals ``end_depth_m - start_depth_m`` (when that scale is
    within 10 % of one; else the encoder's channels disagree and the speed is kept as
    logged).

    A logger gap longer than :data:`~physics.trip_rule.TRIP_BRIDGE_S` inside the window
    (the trip rule bridges one the conveyance kept moving through) leaves no knot in
    it: a straight line between the speeds either side would miss the travel in the
    gap (a 30 s gap in a 600 m trip: ~100 m short, and every later trip of the replay's
    history started where its conveyance was not). With ``depth_m`` (the logged depth
    at ``t_s``) a plateau of two knots in the gap takes the speed that makes the travel
    between its neighbours the logged depth's change across the gap (:func:`_bridge_gaps`).
    """
    inside = (t_s >= t_lo) & (t_s < t_hi) & np.isfinite(speed_m_s)
    if inside.sum() < 5 or t_hi - t_lo < 5 * knot_s:
        return None
    n_bins = int(np.ceil((t_hi - t_lo) / knot_s))
    b = np.minimum(((t_s[inside] - t_lo) / knot_s).astype(np.int64), n_bins - 1)
    count = np.bincount(b, minlength=n_bins)
    total = np.bincount(b, weights=speed_m_s[inside], minlength=n_bins)
    have = count > 0
    if have.sum() < 5:
        return None
    # a bin's mean speed belongs to its samples' mean time (jitter moves a sample across
    # a bin edge: 4 or 6 samples shift the mean time by a tenth of the bin)
    when = np.bincount(b, weights=t_s[inside], minlength=n_bins)
    centres = when[have] / count[have]
    v = total[have] / count[have]
    if at_rest_before:
        v[0] = 0.0
    if at_rest_after:
        v[-1] = 0.0
    if depth_m is not None:
        centres, v = _bridge_gaps(t_s[inside], np.asarray(depth_m)[inside], centres, v)
    step = np.diff(centres)
    travel = float(np.sum(0.5 * (v[1:] + v[:-1]) * step))
    wanted = end_depth_m - start_depth_m
    if at_rest_before and at_rest_after and abs(travel) > 1.0 and np.isfinite(wanted):
        scale = wanted / travel
        if abs(scale - 1.0) < 0.1:
            v = v * scale
    depth = start_depth_m + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * step)])
    return centres, v, depth


def _bridge_gaps(
    t: np.ndarray, depth: np.ndarray, centres: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``centres`` and ``v`` with knots in each logger gap of ``t`` (the window's
    samples) longer than :data:`TRIP_BRIDGE_S`: a plateau of two knots at a third and two
    thirds of the way between the knots either side of the gap, at the speed that makes
    the trapezoid travel between those knots the logged depth's change across the gap
    (from the last finite depth before it to the first after it, plus the travel at
    those knots' speeds to them). Thirds keep the speed's changes as gentle as the gap
    allows (a plateau a knot inside the gap's edges stepped a run's speed within 0.1 s:
    the replay's conveyance went slack and the chamber cavitated) and the speed's sign
    where a run slows into the creep across the gap (one knot in the gap's middle went
    to -1.4 m/s there); a plateau that would still turn back (the ramps' own travel
    beyond the gap's) is held at rest, the trip's scale then taking the rest. A gap at
    the window's edge is not bridged (its first or last knot is the standstill's)."""
    gaps = np.flatnonzero(np.diff(t) > TRIP_BRIDGE_S)
    finite = np.flatnonzero(np.isfinite(depth))
    add_t: list[float] = []
    add_v: list[float] = []
    for j in gaps:
        before = finite[finite <= j]
        after = finite[finite > j]
        a = int(np.searchsorted(centres, t[j], side="right")) - 1  # the knot before
        b = a + 1
        if not (before.size and after.size) or a < 0 or b >= centres.size:
            continue
        ia, ib = int(before[-1]), int(after[0])
        travel = (
            (depth[ib] - depth[ia])
            + v[a] * (float(t[ia]) - centres[a])
            + v[b] * (centres[b] - float(t[ib]))
        )
        third = float(centres[b] - centres[a]) / 3.0
        # (v_a + u) / 2 + u + (u + v_b) / 2, each over a third: the travel
        u = (travel / third - 0.5 * (v[a] + v[b])) / 2.0
        u = max(u, 0.0) if travel >= 0.0 else min(u, 0.0)
        add_t += [float(centres[a]) + third, float(centres[a]) + 2.0 * third]
        add_v += [u, u]
    if not add_t:
        return centres, v
    order = np.argsort(np.concatenate([centres, add_t]), kind="stable")
    return np.concatenate([centres, add_t])[order], np.concatenate([v, add_v])[order]


def profile_from_knots(
    knots_s: np.ndarray,
    speed_m_s: np.ndarray,
    depth_m: np.ndarray,
    *,
    start_s: float,
    duration_s: float,
    payload_time_s: np.ndarray,
    payload_kg: np.ndarray,
    oil_temp_c: float | None,
    direction: str,
) -> TripProfile:
    """A :class:`~sims.trips.TripProfile` from ``start_s`` (its time 0, at rest at the
    first knot's depth) through the knots (constant acceleration between neighbours)
    to ``duration_s``, holding the last knot's speed after it (0 for a trip that ends
    in the record). Knots before ``start_s`` are dropped (the profile starts at the
    first later one). Payload knots are relative to ``start_s``.
    """
    keep = knots_s > start_s
    tk, vk, dk = knots_s[keep] - start_s, speed_m_s[keep], depth_m[keep]
    if tk.size < 2:
        raise ValueError("logged motion: fewer than two knots after the simulation start")
    acc = np.diff(vk) / np.diff(tk)
    # before the first knot: its speed held (at rest for a window that starts at a
    # standstill; a ramp refined into the motion starts the simulation moving)
    starts = np.concatenate([[0.0], tk])
    depths = np.concatenate([[dk[0] - vk[0] * tk[0]], dk])
    speeds = np.concatenate([[vk[0]], vk])
    accs = np.concatenate([[0.0], acc, [0.0]])
    return TripProfile(
        segment_start_s=starts,
        segment_depth_m=depths,
        segment_speed_m_s=speeds,
        segment_acceleration_m_s2=accs,
        duration_s=float(duration_s),
        payload_time_s=np.asarray(payload_time_s, dtype=float),
        payload_kg=np.asarray(payload_kg, dtype=float),
        oil_temp_c=oil_temp_c,
        direction=direction,
    )


def rope_bounce_unseen(t_s: np.ndarray, band_hz: tuple[float, float] = (0.5, 4.0)) -> bool:
    """Whether samples at times ``t_s`` [s] are logged too slowly to see the rope bounce
    (``band_hz``): the median rate at most 2.5 x the band's top (10 Hz for 0.5-4 Hz, to
    1 %: a logger's 10 Hz reads 9.99999 or 10.00001 Hz by the clock's rounding), where
    :func:`rope_damping_from_record` reads nothing.

    >>> slow, fast = np.arange(0.0, 60.0, 0.2), np.arange(0.0, 60.0, 0.05)
    >>> rope_bounce_unseen(slow), rope_bounce_unseen(fast)
    (True, False)
    >>> rope_bounce_unseen(1.7e9 + np.arange(0.0, 60.0, 0.1))  # 10 Hz, epoch seconds
    True
    """
    steps = np.diff(np.asarray(t_s, dtype=float))
    return bool(steps.size) and 1.0 / float(np.median(steps)) < 1.01 * 2.5 * band_hz[1]


def rope_damping_from_record(
    t_s: np.ndarray,
    common_pa: np.ndarray,
    stops_s: list[float],
    quiet: np.ndarray,
    *,
    band_hz: tuple[float, float] = (0.5, 4.0),
    window_s: float = 12.0,
    detect_ratio: float = 3.0,
) -> tuple[float | None, str]:
    """Head-rope damping ratio seen in the record, and how it was read.

    Parameters
    ----------
    t_s, common_pa : sample times [s], sorted, and the common-mode (mean of the sensors)
        pressure [Pa], NaN-free, roughly uniform in time.
    stops_s : times the conveyance came to rest [s].
    quiet : samples at quiet standstill (no motion, no load change, bounce decayed).
    band_hz : the rope-bounce band.
    window_s : the part after each stop that is read [s].
    detect_ratio : ringing is seen when the band RMS 3-7 s after a stop exceeds this
        many times the band RMS at quiet standstill (the noise).

    Returns
    -------
    (zeta, how) : ``zeta`` is 1.0 when no ringing is above the noise 3-7 s after the
        stops (a lower bound in fact: damping ratios from ~0.2 up leave nothing there;
        :func:`discovery.planning.plan_replay` decides among them by replay), the ratio
        read from the envelope decay (ringing seen), or None (not enough record to tell: keep the
        hoist description's). ``how`` says it in words.
    """
    if t_s.size < 100 or not stops_s:
        return None, "too short a record to read the rope bounce"
    rate = 1.0 / float(np.median(np.diff(t_s)))
    if rope_bounce_unseen(t_s, band_hz):
        return None, f"logged at {rate:.0f} Hz: too slow to see the rope bounce"
    sos = signal.butter(2, band_hz, btype="bandpass", fs=rate, output="sos")
    # each stretch between logger gaps on its own: filtered across a gap, the pressure's
    # jump rang the band filter, and a stop just before a gap read as ringing (the
    # described damping then kept, the replay rang where the record does not)
    gaps = np.flatnonzero(np.diff(t_s) > TRIP_BRIDGE_S)
    band = np.full(t_s.size, np.nan)
    envelope = np.full(t_s.size, np.nan)
    for part in np.split(np.arange(t_s.size), gaps + 1):
        if part.size > 3 * rate:  # too short to filter: unread
            band[part] = signal.sosfiltfilt(sos, common_pa[part])
            # zero-padded to a length the FFT factors fast (a day of 8.6 M samples has
            # a prime factor of 32707: 6.8 s unpadded, 1.2 s padded). A length that
            # factors fast is left as it is, its envelope unchanged; another's changes by
            # ~1e-5 inside and, as the circular transform's did, within seconds of the
            # stretch's ends: a stop's window reaching the end can read another decay
            # (a review's test record: 0.0352 -> 0.0344; session 48)
            fast = sp_fft.next_fast_len(part.size)
            envelope[part] = np.abs(signal.hilbert(band[part], fast)[: part.size])
    usable = quiet & np.isfinite(band)
    # robust RMS (the normal's MAD_TO_SIGMA x the median of |band|, whose median is 0): a
    # load change at standstill rings the band filter too
    noise = (
        MAD_TO_SIGMA * float(np.median(np.abs(band[usable])))
        if usable.sum() > 10 * rate
        else np.nan
    )
    if not np.isfinite(noise) or noise <= 0.0:
        return None, "no quiet standstill to compare the rope bounce with"
    rings, decays = [], []
    for t_stop in stops_s:
        ratio, decay = _ringing_after_stop(
            t_s, band, envelope, t_stop, noise, rate, window_s=window_s, detect_ratio=detect_ratio
        )
        if ratio is not None:
            rings.append(ratio)
        if decay is not None:
            decays.append(decay)
    if not rings:
        return None, "no stop with enough standstill after it to read the rope bounce"
    seen = sum(r >= detect_ratio for r in rings)
    if seen < max(1, len(rings) // 4):
        return 1.0, (
            f"no rope bounce above the noise after {len(rings) - seen} of {len(rings)} "
            f"stops (median {np.median(rings):.1f} x the noise in {band_hz[0]:g}-"
            f"{band_hz[1]:g} Hz): ropes replayed critically damped"
        )
    if not decays:
        return None, f"rope bounce seen after {seen} of {len(rings)} stops, decay not read"
    zeta = float(np.clip(np.median(decays), 0.002, 1.0))
    return zeta, (
        f"rope bounce seen after {seen} of {len(rings)} stops; damping ratio "
        f"{zeta:.3f} from its decay (median of {len(decays)})"
    )


def _ringing_after_stop(
    t_s: np.ndarray,
    band: np.ndarray,
    envelope: np.ndarray,
    t_stop: float,
    noise: float,
    rate: float,
    *,
    window_s: float,
    detect_ratio: float,
) -> tuple[float | None, float | None]:
    """The band RMS 3-7 s after one stop over the noise (None: too little standstill
    after it) and the damping ratio read from the envelope's decay (None: not read).
    ``t_s`` is sorted: each window is found by binary search, not a mask of the record."""
    w = _within(t_s, t_stop + 0.5, t_stop + window_s)
    if w.stop - w.start < 4 * rate:
        return None, None
    # 3-7 s after the stop: the band filter's answer to the stop's pressure step
    # (and a seal's settling) has died out, a rope's ringing (decay time
    # 1 / (zeta omega), 2-7 s at zeta 0.03) has not
    first = _within(t_s, t_stop + 3.0, t_stop + 7.0)
    if first.stop - first.start < 2 * rate or not np.isfinite(band[w]).all():
        return None, None  # a logger gap over them, or a stretch too short: nothing read
    ratio = float(np.sqrt(np.mean(band[first] ** 2))) / noise
    if ratio < detect_ratio:
        return ratio, None
    tw, env = t_s[w], envelope[w]
    strong = env > 2.0 * noise * np.sqrt(2.0)
    if strong.sum() < 2 * rate:
        return ratio, None
    slope = np.polyfit(tw[strong] - t_stop, np.log(env[strong]), 1)[0]
    f, pxx = signal.periodogram(band[w], fs=rate)
    f_ring = float(f[np.argmax(pxx)])
    if slope < 0 and f_ring > 0:
        return ratio, -slope / (2.0 * np.pi * f_ring)
    return ratio, None


def _within(t_s: np.ndarray, lo: float, hi: float) -> slice:
    """The samples of sorted ``t_s`` in [lo, hi)."""
    return slice(int(np.searchsorted(t_s, lo, "left")), int(np.searchsorted(t_s, hi, "left")))
