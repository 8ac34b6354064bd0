"""Statistics of a pose: the corner noise (sigma), the covariance, chi-square quantiles, Mahalanobis distances and
the batches of 6 x 6 solves the outlier screen makes."""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .. import _stats
from ..errors import PoseError

if TYPE_CHECKING:
    from ._observations import _Candidate

#: Prior corner noise (px) and its weight in degrees of freedom, blended with the
#: residuals when ``corner_sigma_px`` is not given (see :func:`estimate_pose`).
PRIOR_SIGMA_PX = 0.25
PRIOR_DOF = 2.0
#: Smallest corner noise (px) ever assumed: below this a covariance would claim
#: more than any detector can deliver.
MIN_SIGMA_PX = 0.02
#: The alternative planar solution counts as "as good" when its extra sum of
#: squared residuals is below this many sigma^2 (a likelihood ratio above
#: exp(-9/2) ~ 1/90: the data cannot rule it out).
AMBIGUITY_CHI2 = 9.0
#: With sigma estimated from nu degrees of freedom the same likelihood-ratio level is
#: F(1, nu; q) sigma^2 instead, q = P(chi-square(1) < AMBIGUITY_CHI2) = 0.9973 (the extra sum of
#: squares over the estimated sigma^2 follows F(1, nu), not chi-square(1)): see :func:`_ambiguity_limit`.
#: The ambiguity test never assumes a corner noise above this (px) when it estimates the noise
#: from the residuals: no detector is that far off on a marker it decoded, so larger residuals
#: are a wrong map or camera, and they must not make a poorer second pose look "as good".
AMBIGUITY_MAX_SIGMA_PX = 3.0


def _chi2_3_quantile(p: float) -> float:
    """Quantile of the chi-square distribution with 3 degrees of freedom (7.815 for 0.95).

    ``fidlearn._stats.chi2_ppf`` (scipy), with the probability checked.
    """
    if not 0 < p < 1:
        raise PoseError(f"probability must be between 0 and 1 (exclusive), got {p}")
    return _stats.chi2_ppf(p, 3)


def _relative_rotvec(R_b: np.ndarray, R_a: np.ndarray) -> np.ndarray:
    """The rotation vector (3,), rad, of ``R_b @ R_a.T``: :func:`~fidlearn.frames._rotations._rotvec`'s numbers
    (exact for tiny angles too) without its argument handling, which costs as much as the Rodrigues formula here
    (two rotations of this package: float64 arrays, their product C-contiguous)."""
    R = R_b @ R_a.T
    r = cv2.Rodrigues(R)[0][:, 0]
    if not any(r.tolist()):  # below about 1e-5 rad cv2.Rodrigues gives zero: there the skew part is the vector
        r = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return r


def _mahalanobis2(a: _Candidate, b: _Candidate, JtJ: np.ndarray, sigma: float) -> float:
    """Squared distance between two poses in units of the pose's uncertainty at ``a``."""
    d = np.concatenate([_relative_rotvec(b.R_wc, a.R_wc), b.C - a.C])
    return float(d @ JtJ @ d) / sigma**2


def _ambiguity_limit(nu: float | None) -> float:
    """The "as good" limit of the flip's extra sum of squares, in sigma^2: AMBIGUITY_CHI2 with sigma given
    (``nu`` None), else F(1, nu; q), q = P(chi-square(1) < AMBIGUITY_CHI2), for sigma estimated with ``nu``
    degrees of freedom (55602 at nu = 1, 15.66 at 10, 9.386 at 120, AMBIGUITY_CHI2 in the limit)."""
    if nu is None:
        return AMBIGUITY_CHI2
    return _f1_ambiguity(max(float(nu), 1.0))


@functools.lru_cache(maxsize=256)
def _f1_ambiguity(nu: float) -> float:
    return _stats.f_isf(_stats.chi2_sf(AMBIGUITY_CHI2, 1), 1, nu)


@functools.lru_cache(maxsize=64)
def _estimated_sigma_inflation(nu: float) -> float:
    """``3 F(3, nu; 0.95) / chi2(3; 0.95)``: how much wider the 95 % region is when sigma is estimated.

    Hotelling: with sigma estimated from ``nu`` degrees of freedom, ``d^T (s^2 A)^-1 d / 3``
    follows F(3, nu), not chi-square(3) / 3 (F(3, 10; 0.95) = 3.708, chi2(3; 0.95) = 7.815).
    """
    nu = max(float(nu), 1.0)
    return 3.0 * _stats.f_isf(0.05, 3, nu) / _stats.chi2_ppf(0.95, 3)


def _alternative_weight(extra_sse: float, sigma: float, nu: float | None) -> float:
    """The weight of the other planar pose in the two-pose mixture, from its extra sum of squares ``extra_sse``.

    With the noise given (``nu`` None) the Gaussian likelihood ratio, ``1 / (1 + exp(extra_sse / 2 sigma^2))``.
    With it estimated from ``nu`` degrees of freedom (the prior's included), ``sigma^2`` the posterior scale,
    the noise is integrated out: the likelihood of a pose is then proportional to ``(nu sigma^2 + its extra sum
    of squares)^(-nu / 2)`` (scaled-inverse-chi-square prior, the pose's 6 parameters integrated about each
    mode), so the ratio is ``(1 + extra_sse / (nu sigma^2))^(-nu / 2)``: Student's heavier tail, the Gaussian
    one as ``nu`` grows. With one marker (``nu`` 4) an extra sum of squares of 8 sigma^2 leaves the other
    pose 10 % of the weight, not 1.8 %.

    >>> round(_alternative_weight(8.0, 1.0, None), 4), round(_alternative_weight(8.0, 1.0, 4.0), 4)
    (0.018, 0.1)
    >>> round(_alternative_weight(8.0, 1.0, 1e6), 4)
    0.018
    """
    if extra_sse < 0:  # the other pose fits better: the same ratio, the other way
        return 1.0 - _alternative_weight(-extra_sse, sigma, nu)
    if nu is None or not math.isfinite(nu):
        log_ratio = -extra_sse / (2 * sigma**2)
    else:
        log_ratio = -0.5 * nu * math.log1p(extra_sse / (max(nu, 1.0) * sigma**2))
    return 1.0 / (1.0 + math.exp(min(-log_ratio, 700.0)))


def _sigma(sse: float, dof: int, corner_sigma_px: float | None) -> float:
    if corner_sigma_px is not None:
        return float(corner_sigma_px)
    s2 = (PRIOR_DOF * PRIOR_SIGMA_PX**2 + sse) / (PRIOR_DOF + max(dof, 0))
    return max(math.sqrt(s2), MIN_SIGMA_PX)


def _covariance_from(JtJ: np.ndarray, sigma: float) -> np.ndarray | None:
    """``sigma^2 (J^T J)^-1``, symmetric; None when the pose is not determined (singular J^T J)."""
    ok, inv = cv2.invert(JtJ)  # LU, as numpy's inv (whose overhead is five times the work on 6 x 6)
    if not ok:
        return None
    cov = sigma**2 * inv
    if not np.all(np.isfinite(cov)):
        return None
    return (cov + cov.T) / 2


#: Up to this many markers :func:`_solve_each` solves their 6 x 6 systems one by one with OpenCV's LU (measured
#: between OpenCV's own PnP calls, as the benchmark runs: 11 us for 3 markers, 19 us for 8, against
#: np.linalg.solve's 19-29 us for any few, whose Python wrapper costs more than the work; even at 10 markers).
_SOLVE_ONE_BY_ONE = 8


def _solve_each(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """The solutions (n, 6, 1) of ``A[k] x_k = b[k]`` for ``A`` (n, 6, 6) and ``b`` (n, 6, 1); None when one is
    singular."""
    if len(A) > _SOLVE_ONE_BY_ONE:
        try:
            return np.linalg.solve(A, b)
        except np.linalg.LinAlgError:
            return None
    x = []
    for A_k, b_k in zip(A, b):
        ok, x_k = cv2.solve(A_k, b_k)
        if not ok:
            return None
        x.append(x_k)
    return np.array(x)
