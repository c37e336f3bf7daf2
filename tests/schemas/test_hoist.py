"""Hoist description loader: the example file, and refusals that name the bad key."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from schemas.effects import EFFECT_NAMES
from schemas.hoist import (
    EXAMPLE_HOIST,
    HoistDescriptionError,
    hoist_sha256,
    load_hoist,
    parse_hoist,
)

EXAMPLE_TEXT = EXAMPLE_HOIST.read_text(encoding="utf-8")


def _edit(pattern: str, replacement: str, text: str = EXAMPLE_TEXT) -> str:
    edited, count = re.subn(pattern, replacement, text, count=1, flags=re.MULTILINE)
    assert count == 1, f"pattern {pattern!r} not found in the example"
    return edited


def _error(text: str) -> str:
    with pytest.raises(HoistDescriptionError) as info:
        parse_hoist(text, source="bad.toml")
    return str(info.value)


def test_example_is_the_papers_field_hoist():
    hoist = load_hoist(EXAMPLE_HOIST)
    assert hoist.conveyance.mass_kg == 8200.0
    assert hoist.conveyance.head_ropes == 4
    assert hoist.conveyance.tail_ropes == 2
    assert hoist.ropes.tail_rope_mass_per_length_kg_m == 6.2
    assert hoist.shaft.depth_m == 620.0
    assert set(hoist.shaft.positions_m) == {"pithead", "middle", "bottom"}


def test_quantities_are_converted_to_si():
    hoist = load_hoist(EXAMPLE_HOIST)
    assert hoist.cylinders.bore_m == pytest.approx(0.100)
    assert hoist.cylinders.bore_area_m2 == pytest.approx(math.pi * 0.05**2)
    assert hoist.oil.kinematic_viscosity_40c_m2_s == pytest.approx(46e-6)
    assert hoist.oil.bulk_modulus_pa == pytest.approx(1.5e9)
    assert hoist.piping.roughness_m == pytest.approx(1.5e-6)
    assert hoist.cylinders.dead_volume_m3 == pytest.approx(0.3e-3)


def test_friction_stated_as_equivalent_pressure_converts_to_newtons():
    """force_unit = MPa: F[N] = value[MPa] * 1e6 * A_bore; slope per MPa -> per Pa."""
    hoist = load_hoist(EXAMPLE_HOIST)
    law = hoist.friction_law
    area = hoist.cylinders.bore_area_m2
    fc_at_5mpa = law.coulomb_n[0] + law.coulomb_n[1] * 5e6
    assert fc_at_5mpa == pytest.approx((0.0292 + 0.0259 * 5) * 1e6 * area)
    vs_at_5mpa = law.stribeck_speed_m_s[0] + law.stribeck_speed_m_s[1] * 5e6
    assert vs_at_5mpa == pytest.approx((8.034 - 0.3657 * 5) * 1e-3)
    # viscous coefficient: MPa per (mm/s) -> N per (m/s)
    kv_at_5mpa = law.viscous_n_s_m[0] + law.viscous_n_s_m[1] * 5e6
    assert kv_at_5mpa == pytest.approx((0.00121 + 0.000066 * 5) * 1e6 * area / 1e-3)


def test_a_copy_with_other_friction_or_bore_has_its_own_friction_law():
    """The law is cached per description; a copy made after it was read derives its own
    (the copy's friction set, its bore area), and the original keeps its."""
    hoist = load_hoist(EXAMPLE_HOIST)
    before = hoist.friction_law.coulomb_n[0]
    doubled = hoist.friction.model_copy(update={"coulomb": (0.0584, 0.0518)})
    assert hoist.model_copy(update={"friction": doubled}).friction_law.coulomb_n[
        0
    ] == pytest.approx(2 * before)
    wider = hoist.cylinders.model_copy(update={"bore_m": 0.2})
    copied = hoist.model_copy(update={"cylinders": wider})
    assert copied.cylinders.bore_area_m2 == pytest.approx(4 * hoist.cylinders.bore_area_m2)
    assert copied.friction_law.coulomb_n[0] == pytest.approx(4 * before)
    assert hoist.friction_law.coulomb_n[0] == before


def test_friction_stated_as_force_in_kn():
    text = _edit(r'^force_unit = "MPa"', 'force_unit = "kN"')
    law = parse_hoist(text).friction_law
    assert law.static_n[0] == pytest.approx(0.1276e3)
    assert law.static_n[1] == pytest.approx(0.0253e3 / 1e6)


def test_example_effects_are_known_names():
    hoist = load_hoist(EXAMPLE_HOIST)
    assert set(hoist.model.effects) <= set(EFFECT_NAMES)


def test_hash_changes_with_content(tmp_path: Path):
    copy = tmp_path / "h.toml"
    copy.write_text(EXAMPLE_TEXT, encoding="utf-8")
    first = hoist_sha256(copy)
    copy.write_text(EXAMPLE_TEXT + "\n# edited\n", encoding="utf-8")
    assert hoist_sha256(copy) != first
    assert len(first) == 64


# -- refusals --------------------------------------------------------------------------


def test_missing_key_is_named():
    message = _error(_edit(r'^mass = "8.2 t".*$', ""))
    assert "bad.toml: conveyance.mass: required key is missing" in message


def test_wrong_unit_is_named():
    message = _error(_edit(r'^mass = "8.2 t"', 'mass = "8.2 m"'))
    assert "bad.toml: conveyance.mass:" in message
    assert "'m' is a length, expected a mass" in message


def test_number_without_unit_is_refused():
    message = _error(_edit(r'^bore = "100 mm"', "bore = 100"))
    assert "cylinders.bore:" in message
    assert "has no unit" in message


def test_negative_mass_is_refused():
    message = _error(_edit(r'^mass = "8.2 t"', 'mass = "-8.2 t"'))
    assert "bad.toml: conveyance.mass: must be positive, got -8200" in message


def test_a_friction_uncertainty_out_of_range_is_named():
    message = _error(_edit(r"^relative_uncertainty = .*$", "relative_uncertainty = 4.72"))
    assert "bad.toml: friction.relative_uncertainty:" in message
    assert "less than 0.5" in message
    message = _error(_edit(r"^relative_uncertainty = .*$", "relative_uncertainty = -0.05"))
    assert "bad.toml: friction.relative_uncertainty:" in message
    assert "greater than or equal to 0" in message
    stated = load_hoist(EXAMPLE_HOIST).friction.relative_uncertainty
    assert stated == 0.0472  # paper Table 1's Coulomb line (ropeload calibrate --table1)


def test_with_effects_replaces_them_and_checks_the_names():
    hoist = load_hoist(EXAMPLE_HOIST)
    plain = hoist.with_effects(["seal_friction", "oil_compressibility"])
    assert plain.model.effects == ["seal_friction", "oil_compressibility"]
    assert plain.cylinders == hoist.cylinders
    assert hoist.model.effects != plain.model.effects  # the original is unchanged
    with pytest.raises(ValueError, match="seal_fricton"):
        hoist.with_effects(["seal_fricton"])
    with pytest.raises(ValueError, match="listed twice"):
        hoist.with_effects(["seal_friction", "seal_friction"])


def test_unknown_effect_name_is_named():
    message = _error(_edit(r'^    "seal_friction",', '    "seal_fricton",'))
    assert "model.effects.2: unknown effect name 'seal_fricton'" in message
    assert "'seal_friction'" in message  # the valid names are listed


def test_unknown_key_is_refused():
    message = _error(_edit(r'^mass = "8.2 t"', 'mass = "8.2 t"\nmasss = "1 t"'))
    assert "conveyance.masss: unknown key" in message


def test_unknown_unit_lists_known_units():
    message = _error(_edit(r'^depth = "620 m"', 'depth = "620 furlongs"'))
    assert "shaft.depth: unknown unit 'furlongs' for a length" in message


def test_position_below_shaft_is_refused():
    message = _error(_edit(r'^bottom = "600 m"', 'bottom = "700 m"'))
    assert "positions.bottom: depth 700 m is below the shaft depth 620 m" in message


def test_sensor_per_rope_required():
    text = EXAMPLE_TEXT.replace(
        '[[sensors]]\ncylinder = 4\noffset = "0 MPa"\ngain = 1.0\nfull_scale = "25 MPa"\n', ""
    )
    assert text != EXAMPLE_TEXT
    message = _error(text)
    assert "sensors: need exactly one [[sensors]] entry per head rope" in message


def test_unknown_time_zone_is_refused():
    message = _error(_edit(r'^timezone = "Asia/Shanghai"', 'timezone = "Mars/Olympus"'))
    assert "hoist.timezone: unknown IANA time zone 'Mars/Olympus'" in message


@pytest.mark.parametrize(
    "zone", ["localtime", "posixrules", "Factory", "posix/Asia/Shanghai", "right/Asia/Shanghai"]
)
def test_a_zone_file_that_is_no_iana_zone_name_is_refused(zone):
    """Python's zoneinfo opens any TZif file under the zone folders, but polars (the
    reports' local times) and DuckDB (``timezone(h.timezone, ...)`` in the views) know
    IANA names only: a run landed with ``localtime`` made every query of
    ``rope_trip_extremes`` fail, every hoist's ("Unknown TimeZone 'localtime'")."""
    message = _error(_edit(r'^timezone = "Asia/Shanghai"', f'timezone = "{zone}"'))
    assert f"hoist.timezone: unknown IANA time zone {zone!r}" in message


def test_iana_links_are_time_zones():
    for zone in ("UTC", "PRC", "US/Pacific", "Etc/GMT-8", "EST5EDT", "Asia/Calcutta"):
        edited = _edit(r'^timezone = "Asia/Shanghai"', f'timezone = "{zone}"')
        assert parse_hoist(edited).hoist.timezone == zone


def test_rod_larger_than_bore_is_refused():
    message = _error(_edit(r'^rod = "60 mm"', 'rod = "120 mm"'))
    assert "cylinders:" in message
    assert "must be smaller than bore" in message


def test_invalid_toml_names_the_file():
    message = _error("[hoist\nsite = 1")
    assert message.startswith("bad.toml: not valid TOML")


def test_missing_file_names_the_path(tmp_path: Path):
    with pytest.raises(HoistDescriptionError, match=r"nowhere\.toml: hoist description not found"):
        load_hoist(tmp_path / "nowhere.toml")


def test_several_errors_reported_together():
    text = _edit(r'^mass = "8.2 t"', 'mass = "-1 t"')
    text = _edit(r'^bore = "100 mm"', 'bore = "100 kg"', text)
    lines = _error(text).splitlines()
    assert len(lines) == 2
    assert all(line.startswith("bad.toml: ") for line in lines)


def test_rope_stiffness_factors_one_per_rope():
    ok = parse_hoist(
        _edit(
            r"^head_rope_damping_ratio = 0.02 .*$",
            "head_rope_damping_ratio = 0.02\nhead_rope_stiffness_factors = [0.97, 1.0, 1.01, 1.02]",
        ),
        source="ok.toml",
    )
    assert ok.ropes.head_rope_stiffness_factors == [0.97, 1.0, 1.01, 1.02]
    assert parse_hoist(EXAMPLE_TEXT, source="x.toml").ropes.head_rope_stiffness_factors is None
    message = _error(
        _edit(
            r"^head_rope_damping_ratio = 0.02 .*$",
            "head_rope_damping_ratio = 0.02\nhead_rope_stiffness_factors = [0.97, 1.03]",
        )
    )
    assert "ropes.head_rope_stiffness_factors: need 4 values (one per head rope), got 2" in message
    message = _error(
        _edit(
            r"^head_rope_damping_ratio = 0.02 .*$",
            "head_rope_damping_ratio = 0.02\nhead_rope_stiffness_factors = [0.2, 1, 1, 1]",
        )
    )
    assert "head_rope_stiffness_factors" in message
