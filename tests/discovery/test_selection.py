"""Discovery on sims-generated data where the hoist's model omits one effect the data contain.

Known truth: every case is a synthetic field day (sims.field_day) of the example hoist
with one effect hidden from the model; discovery must name it and shrink the gap, and
report ``none`` when the model is the data's. The pipe, valve and viscosity effects are
hidden in the scenarios with differential branch flow that excite them (drum-groove
wear in the hoist's description, a cold start; :mod:`discovery.cases`).
"""

from __future__ import annotations

import dataclasses
import inspect
import re

import numpy as np
import pytest

from discovery import EFFECT_LIBRARY, discover_effects
from discovery.cases import ORIFICE_LOSS_COEFFICIENT, hidden_case
from discovery.columns import FitEngine
from discovery.selection import fitted_baseline
from sims.noise import NoiseModel

#: Effects found in the plain two-trip scenario (full-shaft trips, loading at the stops)
#: and, for the pipe loss and the viscosity, in the differential-flow scenario.
FOUND = [
    "tail_rope_weight",
    "conveyance_inertia",
    "seal_friction",
    "presliding_hysteresis",
    "oil_compressibility",
    "sensor_offset",
    "sensor_gain",
    "groove_wear",
    "pipe_laminar_loss",
    "viscosity_temperature",
]


SLOW = {"groove_wear", "pipe_laminar_loss", "viscosity_temperature"}


def test_null_case_reports_none():
    plan, _ = hidden_case(None)
    result = discover_effects(plan, bootstrap=50)
    assert [f.effect for f in result.findings] == ["none"]
    assert result.findings[0].variance_ratio < 1.3


@pytest.mark.slow
@pytest.mark.parametrize("hidden", FOUND)
def test_hidden_effect_is_named_and_the_gap_shrinks(hidden):
    plan, _ = hidden_case(hidden)
    result = discover_effects(plan, bootstrap=50, max_iterations=1 if hidden in SLOW else 2)
    first = result.findings[0]
    assert first.effect == hidden
    assert first.confidence >= 0.6
    # the gap in excess of the sensor noise at least halves
    noise = plan.noise_sigma_pa
    excess_before = np.sqrt(max(first.gap_before_pa**2 - noise**2, 0.0))
    excess_after = np.sqrt(max(first.gap_after_pa**2 - noise**2, 0.0))
    assert excess_after < 0.5 * excess_before
    assert first.ranking[0]["effect"] == hidden
    if hidden not in SLOW:  # a second iteration runs: with the effect added, nothing else
        assert [f.effect for f in result.findings[1:]] == ["none"]
    if hidden == "sensor_offset":
        assert first.parameters["offsets_pa"][1] == pytest.approx(2e4, rel=0.1)
        assert np.abs(np.delete(first.parameters["offsets_pa"], 1)).max() < 2e3
    if hidden == "sensor_gain":
        assert first.parameters["gains"][2] == pytest.approx(1.01, abs=1e-3)
    if hidden == "tail_rope_weight":
        assert first.parameters["mass_per_length_kg_m"] == pytest.approx(6.2, rel=0.05)
    if hidden == "conveyance_inertia":
        assert first.parameters["mass_kg"] == pytest.approx(8200, rel=0.05)
    if hidden == "groove_wear":  # truth [0, 0, 0.4, 0] mm, found from a non-zero start
        dev = np.asarray(first.parameters["groove_radius_deviation_m"])
        assert dev[2] - dev[0] == pytest.approx(4e-4, rel=0.15)
        assert np.abs(np.delete(dev - dev[0], 2)).max() < 1.5e-4


@pytest.mark.slow
def test_groove_wear_is_found_and_fitted_under_heavy_sensor_noise():
    """At 15 kPa sensor noise the groove signature (a few kPa per sensor, signed by the
    direction of travel) is below the noise per sample but certain over thousands of
    samples: the scan for a start must not be skipped, and the fit with payloads
    refitted lands on the true deviation (rope 3: +0.4 mm)."""
    plan, _ = hidden_case("groove_wear", seed=200, noise=NoiseModel(pressure_sigma_pa=15e3))
    result = discover_effects(plan, bootstrap=50, max_iterations=1)
    first = result.findings[0]
    assert first.effect == "groove_wear"
    noise = plan.noise_sigma_pa
    assert first.gap_before_pa > 10 * noise
    assert first.gap_after_pa < 1.5 * noise
    dev = np.asarray(first.parameters["groove_radius_deviation_m"])
    assert dev[2] - dev[0] == pytest.approx(4e-4, rel=0.15)


def test_null_case_with_differential_flow_reports_none():
    plan, _ = hidden_case(None, scenario="differential")
    assert "groove_wear" in plan.hoist.model.effects
    result = discover_effects(plan, bootstrap=50, max_iterations=1)
    assert [f.effect for f in result.findings] == ["none"]


@pytest.mark.slow
def test_local_loss_is_named_on_trips_at_different_winding_speeds():
    """A damping orifice (K = 1000) on trips at 4, 10 and 4 m/s: the branch flow scales
    with the winding speed, so the orifice's loss (quadratic in the flow) differs from
    a re-tuned laminar loss (linear, scaled by the viscosity: the speeds are not
    monotonic in the trip temperatures) and is named; the gap shrinks to the noise."""
    plan, info = hidden_case("local_loss", trips=3)
    assert info["scenario"] == "orifice"
    assert "pipe_laminar_loss" in plan.hoist.model.effects  # re-tuned, not a candidate
    result = discover_effects(plan, bootstrap=50, max_iterations=1)
    first = result.findings[0]
    assert first.effect == "local_loss"
    assert first.confidence >= 0.6
    assert first.ranking[0]["effect"] == "local_loss"
    noise = plan.noise_sigma_pa
    excess_before = np.sqrt(max(first.gap_before_pa**2 - noise**2, 0.0))
    excess_after = np.sqrt(max(first.gap_after_pa**2 - noise**2, 0.0))
    assert excess_after < 0.5 * excess_before


@pytest.mark.slow
def test_an_orifice_far_beyond_the_described_one_is_walked_out_to():
    """The orifice (K = 1000 on the tee -> manifold fittings) described 64 times smaller:
    the candidate's scale (1 at the description's coefficients, the globe valve's K = 9
    beside it) is walked out by factors of 4 while the gap falls (``start_scales``) and
    its columns are taken there, about the orifice's size (a scale of ~40), so the fit
    starts in reach of it; described right, the walk stays at the description's (a
    factor 4 more loss fits worse)."""
    plan, _ = hidden_case("local_loss", trips=3)
    model = [e for e in plan.hoist.model.effects if e != "local_loss"]
    walked = {}
    for shrink in (64.0, 1.0):
        described = plan.hoist.piping.model_copy(
            update={
                "fittings_loss_coefficient_sensor_to_manifold": ORIFICE_LOSS_COEFFICIENT / shrink
            }
        )
        case = dataclasses.replace(plan, hoist=plan.hoist.model_copy(update={"piping": described}))
        base = fitted_baseline(case, model, {}, passes=2)
        eng = FitEngine(case, EFFECT_LIBRARY, base)
        eng.rebase(base, model, {})
        eng.switch_on_all(["local_loss"], model, {}, eng.layout.flat(base.simulated))
        walked[shrink] = float(eng.cache["local_loss"].theta0[0])
    assert 10.0 < walked[64.0] < 100.0
    assert walked[1.0] == 1.0


@pytest.mark.slow
def test_a_walk_stops_at_a_step_the_noise_does_not_show():
    """A soft oil hidden, the model without it: a valve 4x the described one lowers the
    residual by less than 25 noise variances (a branch flow it barely throttles), so the
    local loss's walk stops at its first step and the candidate keeps its default: one
    replay switched on, one walk step, one finite-difference step (a walk that took any
    fall of the RSS went a step further)."""
    plan, _ = hidden_case("oil_compressibility", trips=3)
    model = [e for e in plan.hoist.model.effects if e not in ("local_loss", "oil_compressibility")]
    base = fitted_baseline(plan, model, {}, passes=2)
    eng = FitEngine(plan, EFFECT_LIBRARY, base)
    eng.rebase(base, model, {})
    eng.switch_on_all(["local_loss"], model, {}, eng.layout.flat(base.simulated))
    assert eng.replays == 3
    assert eng.cache["local_loss"].theta0[0] == 1.0


@pytest.mark.slow
def test_seal_friction_described_four_times_stronger_is_walked_down_to_it():
    """The world's seals at the hoist's friction law, the description's law four times
    as strong (Coulomb and static): in a model without seal friction the candidate's
    scale (1 at the description's law) is walked down by factors of 2^(-1/2) while the
    gap falls (``start_scales``) and its columns are taken within a step of the world's
    1/4; described right, the walk ends at most one step below the law."""
    plan, _ = hidden_case("seal_friction", trips=3)
    model = [e for e in plan.hoist.model.effects if e != "seal_friction"]
    walked = {}
    for stronger in (4.0, 1.0):
        fr = plan.hoist.friction
        described = fr.model_copy(
            update={
                "coulomb": tuple(stronger * v for v in fr.coulomb),
                "static": tuple(stronger * v for v in fr.static),
            }
        )
        hoist = plan.hoist.model_copy(update={"friction": described})
        case = dataclasses.replace(plan, hoist=hoist)
        base = fitted_baseline(case, model, {}, passes=2)
        eng = FitEngine(case, EFFECT_LIBRARY, base)
        eng.rebase(base, model, {})
        eng.switch_on_all(["seal_friction"], model, {}, eng.layout.flat(base.simulated))
        walked[stronger] = float(eng.cache["seal_friction"].theta0[0])
    step = 2.0**0.5
    assert 0.25 / step - 1e-9 <= walked[4.0] <= 0.25 * step + 1e-9  # 0.25, measured
    assert walked[1.0] >= 1.0 / step - 1e-9  # 1.0, measured


@pytest.mark.slow
def test_oil_described_four_times_stiffer_is_walked_down_to_its_modulus():
    """The world's oil at the hoist's 1.5 GPa, described at 6 GPa (a mine writing down the
    oil's own modulus while its hoses and air soften it): the candidate's ln(bulk
    modulus) is walked down by steps of ln 2 / 2 while the gap falls (``start_shifts``)
    and its columns are taken within two steps of the world's modulus, where the linear
    fit finishes. The gap is flat about its minimum: described 4x too stiff or right,
    the walk ends one step softer than the world's (1.06 GPa, measured), never further."""
    plan, _ = hidden_case("oil_compressibility", trips=3)
    world = plan.hoist.oil.bulk_modulus_pa
    model = [e for e in plan.hoist.model.effects if e != "oil_compressibility"]
    walked = {}
    for stiffer in (4.0, 1.0):
        oil = plan.hoist.oil.model_copy(update={"bulk_modulus_pa": stiffer * world})
        case = dataclasses.replace(plan, hoist=plan.hoist.model_copy(update={"oil": oil}))
        base = fitted_baseline(case, model, {}, passes=2)
        eng = FitEngine(case, EFFECT_LIBRARY, base)
        eng.rebase(base, model, {})
        eng.switch_on_all(["oil_compressibility"], model, {}, eng.layout.flat(base.simulated))
        walked[stiffer] = float(np.exp(eng.cache["oil_compressibility"].theta0[0]))
    assert world / 2.0 < walked[4.0] < world * 2.0
    assert world / 2.0 < walked[1.0] <= world


@pytest.mark.slow
def test_local_loss_on_equal_speed_trips_is_not_misnamed():
    """The same orifice on trips of one winding speed: its loss is mimicked by
    re-tuning the laminar loss and its viscosity slope (two coordinates for two trip
    temperatures), so the honest answer is ``none`` or ``ambiguous`` with
    pipe_laminar_loss -- never another effect; the library names the separating
    excitation (trips at different winding speeds)."""
    plan, _ = hidden_case("local_loss", max_speeds_m_s=(10.0,))
    result = discover_effects(plan, bootstrap=50, max_iterations=1)
    first = result.findings[0]
    assert first.effect in ("local_loss", "none", "ambiguous")
    if first.effect == "ambiguous":
        assert set(first.ambiguous_between) == {"local_loss", "pipe_laminar_loss"}
    assert "winding speeds" in EFFECT_LIBRARY["local_loss"].excitation


@pytest.mark.slow
def test_null_case_with_an_orifice_and_different_speeds_reports_none():
    plan, _ = hidden_case(None, scenario="orifice", trips=3)
    result = discover_effects(plan, bootstrap=50, max_iterations=1)
    assert [f.effect for f in result.findings] == ["none"]


def test_library_terms_cover_the_contract():
    from schemas.effects import EFFECT_NAMES

    assert EFFECT_LIBRARY.get_feature_names() == list(EFFECT_NAMES)
    assert "presliding_hysteresis" not in EFFECT_LIBRARY.candidates(["tail_rope_weight"])
    assert "presliding_hysteresis" in EFFECT_LIBRARY.candidates(["seal_friction"])


def test_bad_hyperparameters_raise():
    plan, _ = hidden_case(None)
    with pytest.raises(ValueError, match="variance_threshold"):
        discover_effects(plan, variance_threshold=0.9)
    with pytest.raises(ValueError, match="detectable_x_noise"):
        discover_effects(plan, detectable_x_noise=0.0)


def test_local_loss_candidate_is_not_null_when_the_description_declares_no_loss(tmp_path):
    """A description with every loss coefficient 0 (issue 14): the candidate's scale
    still moves the valve's K (from a nominal open globe valve), so its simulated
    column is not identically zero and discovery can estimate it from a zero start."""
    import re

    from discovery.effect_terms import NOMINAL_VALVE_LOSS_COEFFICIENT
    from schemas.hoist import EXAMPLE_HOIST, load_hoist
    from sims.device import simulate
    from sims.trips import hold

    text = EXAMPLE_HOIST.read_text()
    for key in ("valve_loss_coefficient", "fittings_loss_coefficient_chamber_to_sensor",
                "fittings_loss_coefficient_sensor_to_manifold"):  # fmt: skip
        text = re.sub(rf"^{key} = .*$", f"{key} = 0", text, flags=re.M)
    path = tmp_path / "no_loss.toml"
    path.write_text(text)
    hoist = load_hoist(path)
    assert hoist.piping.valve_loss_coefficient == 0.0
    term = EFFECT_LIBRARY["local_loss"]
    declared = {
        "valve_loss_coefficient": 0.0,
        "fittings_chamber_to_sensor": 0.0,
        "fittings_sensor_to_manifold": 0.0,
    }
    assert term.get(hoist, declared).tolist() == [0.0]  # the zero start
    scaled = term.set(hoist, np.array([100.0]))
    assert scaled["valve_loss_coefficient"] == pytest.approx(100 * NOMINAL_VALVE_LOSS_COEFFICIENT)
    assert term.get(hoist, scaled).tolist() == pytest.approx([100.0])

    def drop(parameters: dict) -> np.ndarray:
        profile = hold(depth_m=320.0, duration_s=8.0, payload_time_s=[1.0, 4.0],
                       payload_kg=[0.0, 6000.0])  # fmt: skip
        fx = {"tail_rope_weight", "oil_compressibility", "pipe_laminar_loss", "local_loss"}
        frame = simulate(hoist, profile, effects=fx, parameters={"local_loss": parameters}).frame
        return (frame["p_sensor1_pa"] - frame["p_chamber1_pa"]).to_numpy()

    # the candidate's column: what the scaled valve adds to the sensor's reading
    assert np.max(np.abs(drop(scaled) - drop(declared))) > 0.1


def _with_unnamed_wave_and_offset(plan, wave_pa: float, offset_pa: float):
    """The plan's measured pressures plus what no library term names -- a common-mode
    wave (periods of 17 s and 61 s beating) -- and a sensor 2 that reads ``offset_pa``
    high (a hidden sensor offset of known size)."""
    trips = []
    for tr in plan.trips:
        t = tr.time_s
        wave = wave_pa * np.sin(2 * np.pi * t / 17.0) * np.sin(2 * np.pi * t / 61.0)
        measured = tr.measured_pa + wave[:, None]
        measured[:, 1] += offset_pa
        trips.append(dataclasses.replace(tr, measured_pa=measured))
    return dataclasses.replace(plan, trips=tuple(trips))


@pytest.mark.slow
def test_an_effect_twice_the_noise_is_named_beside_a_gap_no_term_names():
    """A baseline that is not perfect (issue 14): beside a common-mode wave of 20 kPa RMS
    that no candidate models, a sensor 40 kPa high explains 42 % of the excess, under
    the 50 % share, but 3.4 x the noise in RMS: named, its offset fitted to 40 kPa, and
    the gap shrinks: under the default 50 % share, it is credited by the size of its
    change (20 kPa on one sensor of four, at least the default 2 x the noise) and what
    it explains (at least 1 x). The same wave with nothing hidden stays ``none``."""
    plan, _ = hidden_case(None, trips=4)
    data = _with_unnamed_wave_and_offset(plan, 40e3, 40e3)
    first = discover_effects(data, bootstrap=50, max_iterations=1).findings[0]
    assert first.effect == "sensor_offset"
    assert first.parameters["offsets_pa"][1] == pytest.approx(40e3, rel=0.05)
    assert first.gap_after_pa < 0.8 * first.gap_before_pa
    assert "explains 42% of the excess variance, 3.4 x the noise in RMS" in first.message
    size = float(re.search(r"its fitted change ([\d.]+) x", first.message).group(1))
    assert size * data.noise_sigma_pa == pytest.approx(20e3, rel=0.1)
    defaults = inspect.signature(discover_effects).parameters
    assert defaults["explain_fraction"].default > 0.42
    assert defaults["detectable_x_noise"].default <= size
    null = _with_unnamed_wave_and_offset(hidden_case(None)[0], 40e3, 0.0)
    assert [f.effect for f in discover_effects(null, bootstrap=50).findings] == ["none"]


def test_a_winner_is_credited_by_the_size_of_its_fitted_change():
    """Known truth: sensor 2 reads 20 kPa high. Added as the library adds an offset
    (relative to the sensors' median), its change is 20 kPa on one sensor of four: an RMS
    of 10 kPa, the size the finding reports. With the share route closed
    (``explain_fraction`` 1), the winner is credited by that size and not by what it
    explains (the per-trip payloads take a quarter of the offset, so less): named at a
    ``detectable_x_noise`` between the two, ``none`` just above its size."""
    plan, _ = hidden_case("sensor_offset")
    noise = plan.noise_sigma_pa

    def first(**thresholds):
        result = discover_effects(plan, bootstrap=50, max_iterations=1, **thresholds)
        return result.findings[0]

    named = first()
    size, explained = (
        float(re.search(pattern, named.message).group(1))
        for pattern in (r"its fitted change ([\d.]+) x", r"([\d.]+) x the noise in RMS")
    )
    assert size * noise == pytest.approx(10e3, rel=0.1)
    assert explained < size - 0.1
    between = first(explain_fraction=1.0, detectable_x_noise=(size + explained) / 2)
    assert between.effect == "sensor_offset"
    above = first(explain_fraction=1.0, detectable_x_noise=1.1 * size)
    assert above.effect == "none"
    assert f"its fitted change {size:.1f} x" in above.message


def test_one_compared_trip_names_nothing_and_says_why():
    """A sensor offset 4x the noise on one trip: it scores best, but one trip cannot be
    resampled to test a finding's stability (every resample is that trip), so nothing is
    named and the finding says why (a probe named two effects that were not there on a
    one-trip period of an independent record)."""
    from discovery.iteration import MIN_TRIPS

    plan, _ = hidden_case("sensor_offset", trips=1)
    assert sum(tr.valid.any() for tr in plan.trips) == 1 < MIN_TRIPS
    result = discover_effects(plan, bootstrap=20, max_iterations=1)
    (finding,) = result.findings
    assert finding.effect == "none"
    assert finding.ranking[0]["effect"] == "sensor_offset"
    assert "cannot be resampled" in finding.message
