"""What a pose's residuals say about its noise: corner noise, a shift and a size error of each marker, and the
apparent size error common to all markers; and the covariance of the pose they give.

Real photos carry more than independent corner noise: the four corners of one marker move together (a marker
printed or stuck a little off its place, a board not quite flat, blur and shading pulling its outline one way),
and a marker's apparent size differs from the map's (a dark border eaten by blur and gamma). To the pose each is
an error that does not average down over the marker's corners. The model of one marker's 8 corner coordinates is

    Sigma_m = a I + b S + c g_m g_m^T

``a`` the corner noise (px^2 per coordinate), ``S`` a common shift of the four corners (px^2 per axis), ``g_m``
the marker's corners about its centre (its growth per unit of relative size) and ``c`` the variance of its own
relative size error. All three are measured from the pose's own residuals, with the degrees of freedom the fit
used accounted for, as :func:`fidlearn.planning.noise.noise_from_residuals` does: the residuals are regressed on
the pose's Jacobian and on every marker's growth (a seventh column, the size error common to all markers), and
the expected spread of the markers' means, of their sizes and of the rest under the model, through the hat
matrix of those seven columns, is matched to what the residuals show (non-negative least squares). What the
seventh column finds, the common size error, is what the model cannot explain as noise: the pose takes it for
distance, so the covariance adds its effect, its estimate squared (whose expectation is the true error squared
plus the estimate's variance).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .. import _stats
from ._stats import PRIOR_DOF, PRIOR_SIGMA_PX

#: With at least this many markers the corner noise, the marker shift and the marker size error are told apart
#: from the residuals; with fewer the residuals give one scale of the prior's mix of the three.
SPLIT_MIN_MARKERS = 4
#: The prior's marker shift (px per axis) and each marker's own size error (relative): with fewer than
#: ``SPLIT_MIN_MARKERS`` markers and the noise estimated, the residuals scale this mix (with the corner noise
#: ``PRIOR_SIGMA_PX``), the prior worth ``PRIOR_DOF`` degrees of freedom. Chosen on the robot's photos 0, 2, 4,
#: ..., 14 and OpenCV's ChArUco photos img_00 and img_01 with all their markers (held out: the robot's odd
#: photos, img_02, img_03 and chocclusion_original): the median shift there is 1.85 times the median corner
#: noise, and each marker's size varies by 0.55 % (medians).
PRIOR_SHIFT_PX = 0.46
PRIOR_SIZE_REL = 0.0055

_MEAN8 = np.kron(np.full((4, 4), 0.25), np.eye(2))  # a marker's mean corner, repeated on its 4 corners
_SHIFT8 = np.kron(np.ones((4, 4)), np.eye(2))  # the covariance of a unit common shift of its 4 corners
_EYE8 = np.eye(8)


class _PartSums(NamedTuple):
    """The sums of one Jacobian ``J`` (8M, 6) and corners ``q`` (M, 4, 2) that the closed forms of
    :mod:`._noise_fast` share: ``K_S``, ``K_g`` (6, 6), the growths ``grow`` (M, 8) and ``h`` (M, 6); and
    ``G = (J^T J)^-1`` when computed (None: not yet)."""

    K_S: np.ndarray
    K_g: np.ndarray
    grow: np.ndarray
    h: np.ndarray
    G: np.ndarray | None = None


@dataclass(frozen=True)
class _NoiseParts:
    """The noise of one pose's corners: ``a`` (px^2), ``b`` (px^2), ``c`` (relative^2), the common size
    error ``size`` (relative), and the degrees of freedom ``nu`` of the pose's
    covariance (Satterthwaite; None when nothing was estimated). ``sums``: the closed forms' sums of the
    Jacobian the parts were measured at (:func:`._noise_fast._noise_parts_fast`), for the covariance at that
    same Jacobian (None when not computed)."""

    a: float
    b: float
    c: float
    size: float = 0.0
    nu: float | None = None
    sums: _PartSums | None = field(default=None, compare=False, repr=False)


def _blocks(Xb: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``sum_m X_m^T C_m X_m`` for per-marker blocks ``Xb`` (M, 8, k) and ``C`` (M, 8, 8) or (8, 8)."""
    k = Xb.shape[-1]
    return Xb.reshape(-1, k).T @ (C @ Xb).reshape(-1, k)  # two products: einsum's one loop over 5 indices is slower


def _parts_cov(grow: np.ndarray) -> list[np.ndarray]:
    """Each part's per-marker covariance of unit size: corners (8, 8), shift (8, 8), size (M, 8, 8)."""
    return [_EYE8, _SHIFT8, grow[:, :, None] * grow[:, None, :]]


def _expected(S: np.ndarray, C: np.ndarray, Xb: np.ndarray, G: np.ndarray, XSX: np.ndarray) -> float:
    """``E[r^T S r]`` under a per-marker covariance ``C``, ``r = (I - H) e``, ``H = X G X^T``:
    ``tr(S C) - 2 tr(H S C) + tr(H S H C)``, S and C block-diagonal and symmetric."""
    SC = S @ C
    M = len(Xb)
    tr_sc = float(np.trace(SC, axis1=-2, axis2=-1).sum()) * (M if SC.ndim == 2 else 1)
    return tr_sc - 2.0 * float(np.sum(G * _blocks(Xb, SC))) + float(np.sum((G @ XSX @ G) * _blocks(Xb, C)))


def _measure(r: np.ndarray, J: np.ndarray, q: np.ndarray, a_given: float | None) -> tuple[np.ndarray, float]:
    """The moment estimates ``(a, b, c)`` from the residuals ``r`` (8M,), the Jacobian ``J`` (8M, 6) and the
    corners ``q`` (M, 4, 2) (``a`` fixed when given), and the common size error."""
    from scipy.optimize import nnls  # scipy loads on first use: ``import fidlearn`` stays quick

    M = len(q)
    grow = (q - q.mean(axis=1, keepdims=True)).reshape(M, 8)
    X = np.column_stack([J, grow.reshape(-1)])
    G = np.linalg.inv(X.T @ X)
    coef = G @ (X.T @ r)
    rb = (r - X @ coef).reshape(M, 8)
    Xb = X.reshape(M, 8, 7)
    size = np.einsum("mi,mj->mij", grow, grow) / np.einsum("mi,mi->m", grow, grow)[:, None, None]
    stats = [_MEAN8, size, _EYE8 - _MEAN8 - size]  # the markers' means, their sizes, the rest
    parts = _parts_cov(grow)
    A = np.empty((3, 3))
    y = np.empty(3)
    for i, S in enumerate(stats):
        XSX = _blocks(Xb, S)
        y[i] = float(np.einsum("mi,...ij,mj->", rb, S, rb) if S.ndim == 2 else np.einsum("mi,mij,mj->", rb, S, rb))
        A[i] = [_expected(S, C, Xb, G, XSX) for C in parts]
    theta = nnls(A, y)[0] if a_given is None else np.r_[a_given, nnls(A[:, 1:], y - A[:, 0] * a_given)[0]]
    return theta, float(coef[6])


def _noise_parts(r: np.ndarray, J: np.ndarray, q: np.ndarray, corner_sigma_px: float | None) -> _NoiseParts:
    """The noise of a pose's corners from its residuals (see the module's docstring).

    ``corner_sigma_px`` given: ``a`` is its square; the shift and size are measured with
    :data:`SPLIT_MIN_MARKERS` markers or more, else left out (the Cramer-Rao bound of that corner noise).
    Estimated, with fewer markers: one scale of the prior's mix, from the sum of squares with ``8M - 6``
    degrees of freedom blended with ``PRIOR_DOF`` of the prior; with more, the three measured (the corner
    noise blended with ``PRIOR_SIGMA_PX`` worth ``PRIOR_DOF``). The degrees of freedom of the pose's covariance
    are Satterthwaite's over the parts' own (about ``5M``, ``2M - 6`` and ``M - 1``).
    """
    M = len(q)
    if M < SPLIT_MIN_MARKERS:
        if corner_sigma_px is not None:
            return _NoiseParts(float(corner_sigma_px) ** 2, 0.0, 0.0)
        prior = np.array([PRIOR_SIGMA_PX**2, PRIOR_SHIFT_PX**2, PRIOR_SIZE_REL**2])
        grow = (q - q.mean(axis=1, keepdims=True)).reshape(M, 8)
        Jb = J.reshape(M, 8, 6)
        G = np.linalg.pinv(J.T @ J)
        parts = _parts_cov(grow)
        expected = sum(p * _expected(_EYE8, C, Jb, G, _blocks(Jb, _EYE8)) for p, C in zip(prior, parts))
        dof = max(8 * M - 6, 0)
        scale = (PRIOR_DOF + float(r @ r) / max(expected, 1e-300) * dof) / (PRIOR_DOF + dof)
        a, b, c = (float(v) for v in scale * prior)
        return _NoiseParts(a, b, c, nu=dof + PRIOR_DOF)
    theta, size = _measure(r, J, q, None if corner_sigma_px is None else float(corner_sigma_px) ** 2)
    nus = _blend_prior(theta, M, corner_sigma_px)
    a, b, c = (float(v) for v in theta)
    return _NoiseParts(a, b, c, size, nu=_satterthwaite(J, q, theta, nus))


def _blend_prior(theta: np.ndarray, M: int, corner_sigma_px: float | None) -> np.ndarray:
    """The degrees of freedom (3,) of the three parts ``theta`` measured from ``M`` markers' residuals (about
    ``5M``, ``2M - 6`` and ``M - 1``). With the corner noise estimated (``corner_sigma_px`` None), ``theta[0]``
    is blended in place with ``PRIOR_SIGMA_PX`` worth ``PRIOR_DOF`` degrees of freedom, which its own gain;
    given, it has infinitely many."""
    if corner_sigma_px is not None:
        return np.array([np.inf, 2.0 * M - 6.0, M - 1.0])
    nus = np.array([5.0 * M - 1.0, 2.0 * M - 6.0, M - 1.0])
    theta[0] = (PRIOR_DOF * PRIOR_SIGMA_PX**2 + nus[0] * theta[0]) / (PRIOR_DOF + nus[0])
    nus[0] += PRIOR_DOF
    return nus


def _pose_parts(J: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """``(J^T J)^-1``, each part's unit contribution to the pose's covariance, and the pose's response to a
    unit common size error."""
    M = len(q)
    grow = (q - q.mean(axis=1, keepdims=True)).reshape(M, 8)
    Jb = J.reshape(M, 8, 6)
    Minv = np.linalg.inv(J.T @ J)
    unit = [Minv @ _blocks(Jb, C) @ Minv for C in _parts_cov(grow)]
    return Minv, unit, Minv @ (J.T @ grow.reshape(-1))


def _satterthwaite(J: np.ndarray, q: np.ndarray, theta: np.ndarray, nus: np.ndarray) -> float:
    """Degrees of freedom of the pose's (trace of) covariance, a sum of parts each estimated with its own."""
    _, unit, _ = _pose_parts(J, q)
    v = np.array([t * float(np.trace(u)) for t, u in zip(theta, unit)])
    ok = nus > 0
    den = float(np.sum(v[ok] ** 2 / nus[ok]))
    return float(np.sum(v) ** 2 / den) if den > 0 else math.inf


@functools.lru_cache(maxsize=256)
def _inflation(nu: float) -> float:
    """``3 F(3, nu; 0.95) / chi2(3; 0.95)``: the 95 % region with the noise estimated from ``nu`` degrees of freedom."""
    if not math.isfinite(nu):
        return 1.0
    nu = max(nu, 1.0)
    return 3.0 * _stats.f_isf(0.05, 3, nu) / _stats.chi2_ppf(0.95, 3)


def _pose_covariance(J: np.ndarray, q: np.ndarray, parts: _NoiseParts) -> np.ndarray | None:
    """The covariance (6, 6) of a pose fitted by least squares to corners of noise ``parts``: the sandwich
    ``(J^T J)^-1 J^T Sigma J (J^T J)^-1`` plus the common size error's effect (its square), widened for the estimate
    (Hotelling, ``nu``); None when the pose is not determined."""
    try:
        _, unit, d = _pose_parts(J, q)
    except np.linalg.LinAlgError:
        return None
    cov = parts.a * unit[0] + parts.b * unit[1] + parts.c * unit[2]
    cov = cov + np.outer(d, d) * parts.size**2  # E[size^2] = the true common size error^2 + its variance
    if parts.nu is not None:
        cov = cov * _inflation(round(parts.nu, 1))
    if not np.all(np.isfinite(cov)):
        return None
    return (cov + cov.T) / 2


def _calibration_covariance(J: np.ndarray, J_k: np.ndarray, cov_k: np.ndarray) -> np.ndarray:
    """The pose's covariance (6, 6) from the error of the intrinsics it was fitted with.

    The pose is the least-squares fit of the corners, so an error ``dk`` of the intrinsics moves it by
    ``dp = -(J^T J)^-1 J^T J_k dk`` (``J`` and ``J_k`` the projection's Jacobians on the pose and on
    the intrinsics): its covariance is ``A cov_k A^T`` with ``A = (J^T J)^-1 J^T J_k``. No residual
    shows this error (it is the same in every pose made with the calibration), so it is added after the
    widening for the noise's estimate.
    """
    A = np.linalg.solve(J.T @ J, J.T @ J_k)
    cov = A @ cov_k @ A.T
    return (cov + cov.T) / 2
