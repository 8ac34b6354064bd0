"""The noise of a pose's corners and its covariance (:mod:`fidlearn.pose._noise`) in closed forms for 6 x 6.

:func:`._noise._noise_parts` and :func:`._noise._pose_covariance` write the model's algebra as it reads: a
trace and a sandwich per part, each through the (8M, 8M) block-diagonal covariances. Every pose pays for them,
and with one to three markers they cost more than the Levenberg-Marquardt fit itself. Here the same numbers
come from three 6 x 6 matrices, one per part of the noise:

    K_I = J^T J,    K_S = sum_m (s_m s_m^T + t_m t_m^T),    K_g = sum_m h_m h_m^T

``s_m``, ``t_m`` the sums of marker m's four u rows and four v rows of ``J`` (a common shift of its corners),
``h_m = J_m^T g_m`` (its growth). With ``G = (J^T J)^-1`` the hat matrix ``H = J G J^T`` is a projection, so the
expected sum of squares of the residuals under a per-marker covariance ``C`` is ``tr(C) - tr(G J^T C J)``, and the
pose's covariance is the single sandwich ``G (a K_I + b K_S + c K_g) G``. The results equal the straightforward
ones to round-off (``tests/test_pose_fast_paths.py`` compares them). The noise of a pose and its covariance at the
same Jacobian share the sums: :func:`_noise_parts_fast` returns them in its result (``_NoiseParts.sums``), and the
caller hands them to :func:`_pose_covariance_fast`.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from . import _noise
from ._noise import PRIOR_SHIFT_PX, PRIOR_SIZE_REL, SPLIT_MIN_MARKERS, _blend_prior, _NoiseParts, _PartSums
from ._stats import PRIOR_DOF, PRIOR_SIGMA_PX

_PRIOR = (PRIOR_SIGMA_PX**2, PRIOR_SHIFT_PX**2, PRIOR_SIZE_REL**2)
#: A marker's 8 coordinates (u0, v0, ..., u3, v3) times this: its u sum and its v sum (one product, not a reduction).
_SUM_UV = np.kron(np.ones((4, 1)), np.eye(2))
_SUM_UV_T = _SUM_UV.T.copy()
#: A marker's corners (4, 2) times this: the same corners about their mean (one product, not a mean and a difference).
_CENTRE4 = np.eye(4) - 0.25


@functools.cache
def _scipy_nnls():
    """``scipy.optimize.nnls``, imported on first use (``import fidlearn`` stays quick) and kept: an import
    statement in the function that calls it costs a Python call into importlib each time."""
    from scipy.optimize import nnls

    return nnls


def _part_matrices(J: np.ndarray, q: np.ndarray) -> _PartSums:
    """``K_S``, ``K_g`` (6, 6), the growths ``g`` (M, 8) and ``h`` (M, 6) of the markers' corners ``q`` (M, 4, 2)."""
    M = len(q)
    grow = (q - q.sum(axis=1, keepdims=True) * 0.25).reshape(M, 8)
    Jb = J.reshape(M, 8, 6)
    s = J.reshape(M, 4, 2, 6).sum(axis=1).reshape(2 * M, 6)  # each marker's u rows summed, then its v rows
    h = np.einsum("mk,mkj->mj", grow, Jb)
    return _PartSums(s.T @ s, h.T @ h, grow, h)


def _inverse(JtJ: np.ndarray) -> np.ndarray | None:
    """``JtJ^-1`` by LU (numpy's overhead is five times the work on 6 x 6), None when singular."""
    ok, inv = cv2.invert(JtJ)
    return inv if ok else None


def _noise_parts_fast(
    r: np.ndarray, J: np.ndarray, q: np.ndarray, corner_sigma_px: float | None, JtJ: np.ndarray | None = None
) -> _NoiseParts:
    """:func:`._noise._noise_parts`, the prior's scale for fewer than ``SPLIT_MIN_MARKERS`` markers in closed form
    (``JtJ``: ``J^T J`` when the caller has it); with the sums of ``J`` it computed (``sums``, for
    :func:`_pose_covariance_fast` at the same ``J``)."""
    M = len(q)
    if M >= SPLIT_MIN_MARKERS:
        return _split_parts(r, J, q, corner_sigma_px, JtJ)
    if corner_sigma_px is not None:
        return _NoiseParts(float(corner_sigma_px) ** 2, 0.0, 0.0)
    JtJ = J.T @ J if JtJ is None else JtJ
    G = _inverse(JtJ)
    if G is None or not np.isfinite(G).all():
        return _noise._noise_parts(r, J, q, corner_sigma_px)  # the pseudo-inverse's way
    sums = _part_matrices(J, q)._replace(G=G)
    K_S, K_g, grow, _, _ = sums
    a0, b0, c0 = _PRIOR
    traces = (a0 + b0) * 8.0 * M + c0 * float(np.einsum("mi,mi->", grow, grow))
    expected = traces - float(np.sum(G * (a0 * JtJ + b0 * K_S + c0 * K_g)))
    dof = max(8 * M - 6, 0)
    scale = (PRIOR_DOF + float(r @ r) / max(expected, 1e-300) * dof) / (PRIOR_DOF + dof)
    return _NoiseParts(float(scale * a0), float(scale * b0), float(scale * c0), nu=dof + PRIOR_DOF, sums=sums)


def _split_parts(
    r: np.ndarray, J: np.ndarray, q: np.ndarray, corner_sigma_px: float | None, JtJ: np.ndarray | None = None
) -> _NoiseParts:
    """:func:`._noise._noise_parts` with ``SPLIT_MIN_MARKERS`` markers or more: the three parts measured
    (:func:`_measure_fast`), the corner noise blended with the prior when estimated, Satterthwaite's degrees of
    freedom."""
    M = len(q)
    a_given = None if corner_sigma_px is None else float(corner_sigma_px) ** 2
    theta, size, sums = _measure_fast(r, J, q, a_given)
    nus = _blend_prior(theta, M, corner_sigma_px)
    a, b, c = theta.tolist()
    nu, G = _satterthwaite_fast(J, sums, theta, nus, JtJ)
    return _NoiseParts(a, b, c, size, nu=nu, sums=_PartSums(*sums[:4], G))


def _measure_fast(
    r: np.ndarray, J: np.ndarray, q: np.ndarray, a_given: float | None
) -> tuple[np.ndarray, float, _PartSums]:
    """:func:`._noise._measure`: the moment equations of the three statistics (the markers' means, their sizes,
    the rest: projections ``P_mean``, ``P_size``, ``P_rest`` of each marker's 8 coordinates) under the three
    parts (``I = P_mean + P_size + P_rest``, the shift ``4 P_mean``, the size ``|g|^2 P_size``, as the growth
    ``g`` of a marker is centred), so every product of a statistic and a part is one of the projections: the
    nine expectations come from four 7 x 7 sums ``X^T P X``. The residuals ride along as an 8th column,
    ``Z = [X r]``: those left by the fit of ``X`` are ``Z w``, ``w = [-coef, 1]``, so each statistic is the
    quadratic form ``w^T Z^T P Z w`` of the same sums (8 x 8), with no array of residuals formed (numpy's cost
    here is its calls, not its arithmetic). Also :func:`_part_matrices`, the sums' 6 x 6 corners."""
    nnls = _scipy_nnls()
    M = len(q)
    grow = (_CENTRE4 @ q).reshape(M, 8)
    Z = np.concatenate((J, grow.reshape(-1, 1), r.reshape(-1, 1)), axis=1)  # X = [J, the growths], the residuals
    Zb = Z.reshape(M, 8, 8)
    zs = (_SUM_UV_T @ Zb).reshape(2 * M, 8)  # each marker's u rows summed, then its v rows
    hz = (grow[:, None, :] @ Zb)[:, 0]  # Z_m^T g_m
    g2 = hz[:, 6]  # |g_m|^2
    S = np.empty((4, 8, 8))  # the four sums Z^T P Z: means, sizes, the rest, g g^T
    S[0] = (zs.T @ zs) * 0.25  # sum of Z_m^T P_mean Z_m (P_mean = SHIFT8 / 4)
    S[1] = (hz / g2[:, None]).T @ hz  # ... P_size = g g^T / |g|^2
    S[3] = hz.T @ hz  # ... g g^T
    ZtZ = Z.T @ Z
    S[2] = ZtZ - S[0] - S[1]
    XtX = ZtZ[:7, :7]  # (a view: OpenCV reads its rows where they are)
    G = _inverse(XtX)
    if G is None:
        G = np.linalg.inv(XtX)  # (as the straightforward one: a singular fit raises here as it does there)
    coef = G @ ZtZ[:7, 7]
    w = np.empty(8)
    w[:7], w[7] = -coef, 1.0
    y = (S[:3] @ w) @ w  # the residuals' means, sizes and the rest: w^T S w
    # sum(G * P) of the four sums, and tr(G X^T S X G X^T C X) of each statistic S and part C at once: the
    # parts' sums X^T C X are XtX (the sum of the first three), 4 S[0] and S[3]
    S7 = S[:, :7, :7].reshape(4, 49)
    tm, ts, tr, tg = (S7 @ G.reshape(49)).tolist()
    T = ((G @ S[:3, :7, :7] @ G).reshape(3, 49) @ S7.T).tolist()  # (3, 4): statistic by sum
    (t00, t01, t02), (t10, t11, t12), (t20, t21, t22) = ((s0 + s1 + s2, 4.0 * s0, s3) for s0, s1, s2, s3 in T)
    # per statistic (rows: means, sizes, the rest) and part (columns: corners, shift, size): tr(S C)
    # - 2 sum(G * X^T S C X) + the third term, every S C one of the projections (or zero)
    g2_sum = float(ZtZ[6, 6])  # sum of |g_m|^2
    A = np.array(
        [
            [2.0 * M - 2.0 * tm + t00, 8.0 * M - 8.0 * tm + t01, t02],
            [1.0 * M - 2.0 * ts + t10, t11, g2_sum - 2.0 * tg + t12],
            [5.0 * M - 2.0 * tr + t20, t21, t22],
        ]
    )
    theta = nnls(A, y)[0] if a_given is None else np.r_[a_given, nnls(A[:, 1:], y - A[:, 0] * a_given)[0]]
    return theta, float(coef[6]), _PartSums(4.0 * S[0, :6, :6], S[3, :6, :6], grow, hz[:, :6])


def _satterthwaite_fast(
    J: np.ndarray, sums: _PartSums, theta: np.ndarray, nus: np.ndarray, JtJ: np.ndarray | None = None
) -> tuple[float, np.ndarray | None]:
    """:func:`._noise._satterthwaite`: each part's trace ``tr(G K G)`` from the 6 x 6 sums ``sums``
    (:func:`_part_matrices`); and ``G = (J^T J)^-1`` (``JtJ``: ``J^T J`` when the caller has it)."""
    JtJ = J.T @ J if JtJ is None else JtJ
    G = _inverse(JtJ)
    if G is None:
        return _noise._satterthwaite(J, sums.grow.reshape(-1, 4, 2), theta, nus), None  # (raises as it does)
    traces = np.array((JtJ, sums.K_S, sums.K_g)).reshape(3, 36) @ (G @ G).reshape(36)  # tr(G K G), one product
    v = (theta * traces).tolist()
    den = sum(x * x / n for x, n in zip(v, nus.tolist()) if n > 0)
    return (sum(v) ** 2 / den if den > 0 else math.inf), G


def _pose_covariance_fast(
    J: np.ndarray, q: np.ndarray, parts: _NoiseParts, JtJ: np.ndarray | None = None, sums: _PartSums | None = None
) -> np.ndarray | None:
    """:func:`._noise._pose_covariance` as one sandwich ``G (a K_I + b K_S + c K_g) G`` plus the common size
    error's ``d d^T``, ``d = G J^T g`` (``JtJ``: ``J^T J`` when the caller has it; ``sums``: those of this very
    ``J`` and ``q``, ``parts.sums`` when ``parts`` were measured at it)."""
    JtJ = J.T @ J if JtJ is None else JtJ
    if sums is None:
        sums = _part_matrices(J, q)
    G = _inverse(JtJ) if sums.G is None else sums.G
    if G is None:
        return None
    K_S, K_g, _, h, _ = sums
    cov = G @ (parts.a * JtJ + parts.b * K_S + parts.c * K_g) @ G
    if parts.size:
        d = G @ h.sum(axis=0)
        cov = cov + d[:, None] * d * parts.size**2  # (np.outer's product, without its Python wrapper)
    inflation = _noise._inflation(round(parts.nu, 1)) if parts.nu is not None else 1.0
    cov = (cov + cov.T) * (0.5 * inflation)  # symmetric, widened for the estimate, in one pass
    return cov if np.isfinite(cov).all() else None
