"""fidlearn._stats against published table values, and the pose's limits built on it against the tables they replace."""

from __future__ import annotations

import math

import pytest
from scipy import stats as scipy_stats

from fidlearn import _stats
from fidlearn.pose import _outliers
from fidlearn.pose import _stats as pose_stats
from fidlearn.survey import _gross


@pytest.mark.parametrize(
    ("dof", "p", "x"),
    [(1, 0.95, 3.8415), (2, 0.95, 5.9915), (3, 0.95, 7.8147), (3, 0.99, 11.3449), (6, 0.999, 22.4577)],
)
def test_chi_square_quantiles_match_published_tables(dof, p, x):
    assert _stats.chi2_ppf(p, dof) == pytest.approx(x, abs=5e-5)
    assert _stats.chi2_isf(1 - p, dof) == pytest.approx(x, abs=5e-5)
    assert _stats.chi2_sf(x, dof) == pytest.approx(1 - p, abs=1e-5)


@pytest.mark.parametrize(
    ("d1", "d2", "x"),
    [(3, 10, 3.708), (3, 20, 3.098), (1, 10, 4.965), (2, 30, 3.316), (8, 60, 2.097), (3, 120, 2.680)],
)
def test_f_95_quantiles_match_published_tables(d1, d2, x):
    assert _stats.f_isf(0.05, d1, d2) == pytest.approx(x, abs=5e-4)


def test_f_quantiles_agree_with_scipy_stats_far_in_the_tail():
    for p, d1, d2 in ((1e-4, 8, 10), (2.7e-3, 1, 1), (1e-3 / 40, 3, 87), (0.05, 3, 2.5)):
        assert _stats.f_isf(p, d1, d2) == pytest.approx(scipy_stats.f.isf(p, d1, d2), rel=1e-10)
    assert _stats.beta_sf(_stats.beta_isf(0.01, 1.5, 4.0), 1.5, 4.0) == pytest.approx(0.01, rel=1e-10)


# the tables these limits once were, as typed (rounded to 4 significant digits)
_AMBIGUITY_F1 = ((1, 55602.3), (2, 368.9), (3, 84.99), (8, 18.29), (10, 15.66), (30, 10.70), (120, 9.386))
_F3_95 = ((1, 215.7), (2, 19.16), (5, 5.41), (10, 3.71), (24, 3.01), (60, 2.76), (120, 2.68))
_OUTLIER_F8 = ((10, 125.9), (14, 83.66), (26, 53.0), (58, 39.87), (180, 34.21))


def test_the_pose_limits_reproduce_their_former_tables():
    for nu, f in _AMBIGUITY_F1:
        assert pose_stats._ambiguity_limit(nu) == pytest.approx(f, rel=5e-4)
    assert pose_stats._ambiguity_limit(1e9) == pytest.approx(pose_stats.AMBIGUITY_CHI2, rel=1e-6)
    assert pose_stats._ambiguity_limit(None) == pose_stats.AMBIGUITY_CHI2
    for nu, f in _F3_95:
        assert pose_stats._estimated_sigma_inflation(nu) == pytest.approx(3 * f / 7.8147, rel=5e-3)
    assert pose_stats._estimated_sigma_inflation(1e9) == pytest.approx(1.0, rel=1e-6)
    for nu, t in _OUTLIER_F8:
        assert _outliers._outlier_threshold(nu, False) == pytest.approx(t, rel=5e-4)
    assert pytest.approx(31.83, abs=5e-3) == _outliers.OUTLIER_CHI2
    assert _outliers._outlier_threshold(5, True) == _outliers.OUTLIER_CHI2
    # below 10 degrees of freedom the limit grows as 1 / nu^2 from its value at 10
    assert _outliers._outlier_threshold(5, False) == pytest.approx(4 * _outliers._outlier_threshold(10, False))


def test_the_other_constants_are_the_quantiles_they_name():
    assert pytest.approx(1.5382, abs=5e-5) == _gross._MEDIAN_3D
    assert pytest.approx(math.sqrt(scipy_stats.chi2.median(3)), rel=1e-12) == _gross._MEDIAN_3D
