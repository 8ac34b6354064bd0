"""Chi-square, beta and F quantiles and survival functions, over ``scipy.special`` (exact to machine precision).

The pose's covariance inflation, outlier and ambiguity tests, the survey's suspects and gross test, the
bent-board test of a calibration and the tracker's gates use these: every quantile in fidlearn comes from here
(the functions exist in scipy 1.11 and later; ``betaincc`` and ``betainccinv`` are the newest).
"""

from __future__ import annotations

from scipy import special


def chi2_sf(x: float, dof: float) -> float:
    """P(X > x) for X chi-square with ``dof`` degrees of freedom."""
    return float(special.chdtrc(dof, max(float(x), 0.0)))


def chi2_isf(p: float, dof: float) -> float:
    """The x with P(X > x) = p, X chi-square with ``dof`` degrees of freedom."""
    return float(2.0 * special.gammainccinv(dof / 2.0, p))


def chi2_ppf(p: float, dof: float) -> float:
    """The x with P(X < x) = p, X chi-square with ``dof`` degrees of freedom."""
    return float(2.0 * special.gammaincinv(dof / 2.0, p))


def beta_sf(x: float, a: float, b: float) -> float:
    """P(B > x) for B ~ Beta(a, b)."""
    return float(special.betaincc(a, b, min(max(float(x), 0.0), 1.0)))


def beta_isf(p: float, a: float, b: float) -> float:
    """The x with P(B > x) = p, B ~ Beta(a, b)."""
    return float(special.betainccinv(a, b, p))


def f_isf(p: float, d1: float, d2: float) -> float:
    """The x with P(F > x) = p for F ~ F(d1, d2): through ``B = d1 F / (d1 F + d2)`` ~ Beta(d1 / 2, d2 / 2)."""
    b = beta_isf(p, d1 / 2.0, d2 / 2.0)
    return float((b / d1) / ((1.0 - b) / d2))
