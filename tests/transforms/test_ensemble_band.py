"""The stick-slip band's members combined by source (transforms.uncertainty.ensemble_band).

The answers: independent sources, each given by its 95 % extremes, combine in
quadrature either side (JCGM 100:2008 eq 10 with the sources' one-at-a-time extremes for
c_i U_i); one source alone is its own range; the seals' own departure from the law is
what the law's members do not span, whatever the other sources span; a member without
a value leaves its source out at that sample. Arithmetic written out here, not the
kernel's.
"""

from __future__ import annotations

import numpy as np
import pytest

from transforms.uncertainty import Z95, ensemble_band

VALUE = np.full(3, 100_000.0)
FRICTION = np.array([1000.0, -500.0, 0.0])


def test_independent_sources_combine_in_quadrature_either_side():
    rng = np.random.default_rng(5)
    deviations = rng.normal(0.0, 300.0, (6, 3))  # three sources of two members each
    members = [FRICTION + d for d in deviations]
    lo, hi = ensemble_band(VALUE, FRICTION, members, 25.0, groups=(0, 0, 1, 1, 2, 2))
    pairs = deviations.reshape(3, 2, 3)
    below = np.sqrt((np.maximum(-pairs, 0.0).max(axis=1) ** 2).sum(axis=0))
    above = np.sqrt((np.maximum(pairs, 0.0).max(axis=1) ** 2).sum(axis=0))
    assert lo == pytest.approx(VALUE - below - Z95 * 25.0, rel=1e-12)
    assert hi == pytest.approx(VALUE + above + Z95 * 25.0, rel=1e-12)
    # narrower than the sources' reaches added, wider than the largest alone
    assert (VALUE - lo > np.maximum(-pairs, 0.0).max(axis=(0, 1))).all()
    assert (VALUE - lo < np.maximum(-pairs, 0.0).max(axis=1).sum(axis=0) + Z95 * 25.0).all()


def test_one_source_is_the_members_range():
    members = [FRICTION - 200.0, FRICTION + 50.0, FRICTION + 350.0]
    lo, hi = ensemble_band(VALUE, FRICTION, members, 0.0)
    assert lo == pytest.approx(VALUE - 200.0)
    assert hi == pytest.approx(VALUE + 350.0)
    # members all on one side: the estimate is the band's edge on the other
    lo, hi = ensemble_band(VALUE, FRICTION, [FRICTION + 100.0, FRICTION + 300.0], 0.0)
    assert lo == pytest.approx(VALUE)
    assert hi == pytest.approx(VALUE + 300.0)


def test_the_seals_own_sigma_is_what_the_law_members_leave():
    seal = np.full(3, 150.0)
    law = [FRICTION - 100.0, FRICTION + 100.0]  # spans 200 / 2 / 1.96 = 51 N of it
    other = [FRICTION - 400.0, FRICTION + 400.0]  # spans nothing of the law's
    lo, hi = ensemble_band(
        VALUE, FRICTION, law + other, 10.0, seal_sigma_n=seal, groups=(0, 0, 1, 1)
    )
    own = np.sqrt(150.0**2 - (200.0 / 2 / Z95) ** 2)
    reach = np.hypot(100.0, 400.0) + Z95 * np.hypot(10.0, own)
    assert hi == pytest.approx(VALUE + reach, rel=1e-12)
    assert lo == pytest.approx(VALUE - reach, rel=1e-12)
    # the law's source numbered otherwise: the other pair now spans the seal's sigma
    lo, hi = ensemble_band(
        VALUE, FRICTION, law + other, 10.0, seal_sigma_n=seal, groups=(0, 0, 1, 1), law_group=1
    )
    assert hi == pytest.approx(VALUE + np.hypot(100.0, 400.0) + Z95 * 10.0, rel=1e-12)


def test_a_member_without_a_value_leaves_its_source_out_there():
    members = [FRICTION + np.array([np.nan, 300.0, 300.0]), FRICTION + 200.0]
    lo, hi = ensemble_band(VALUE, FRICTION, members, 0.0, groups=(0, 1))
    assert hi == pytest.approx(VALUE + np.array([200.0, np.hypot(300.0, 200.0), 360.555]), 1e-6)
    assert lo == pytest.approx(VALUE)
    # an estimate without a value has no band
    lo, _ = ensemble_band(VALUE, np.array([np.nan, 0.0, 0.0]), members, 0.0, groups=(0, 1))
    assert np.isnan(lo[0])
    assert np.isfinite(lo[1:]).all()


def test_groups_must_name_a_source_per_member():
    with pytest.raises(ValueError, match="one source"):
        ensemble_band(VALUE, FRICTION, [FRICTION] * 3, 0.0, groups=(0, 1))
    with pytest.raises(ValueError, match="law_group 2"):  # its range read past the sources
        ensemble_band(VALUE, FRICTION, [FRICTION] * 2, 0.0, groups=(0, 1), law_group=2)
