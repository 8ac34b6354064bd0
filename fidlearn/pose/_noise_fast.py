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
ones to round-off (``tests/test_pose_fast_paths.py`` compares them).
"""

from __future__ import annotations

import cv2
import numpy as np

from . import _noise
from ._noise import PRIOR_SHIFT_PX, PRIOR_SIZE_REL, SPLIT_MIN_MARKERS, _NoiseParts
from ._stats import PRIOR_DOF, PRIOR_SIGMA_PX

_PRIOR = (PRIOR_SIGMA_PX**2, PRIOR_SHIFT_PX**2, PRIOR_SIZE_REL**2)


def _part_matrices(J: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``K_S``, ``K_g`` (6, 6), the growths ``g`` (M, 8) and ``h`` (M, 6) of the markers' corners ``q`` (M, 4, 2)."""
    M = len(q)
    grow = (q - q.mean(axis=1, keepdims=True)).reshape(M, 8)
    Jb = J.reshape(M, 8, 6)
    s = J.reshape(M, 4, 2, 6).sum(axis=1).reshape(2 * M, 6)  # each marker's u rows summed, then its v rows
    h = np.einsum("mk,mkj->mj", grow, Jb)
    return s.T @ s, h.T @ h, grow, h


def _inverse(JtJ: np.ndarray) -> np.ndarray | None:
    """``JtJ^-1`` by LU (numpy's overhead is five times the work on 6 x 6), None when singular."""
    ok, inv = cv2.invert(JtJ)
    return inv if ok else None


def _noise_parts_fast(
    r: np.ndarray, J: np.ndarray, q: np.ndarray, corner_sigma_px: float | None, JtJ: np.ndarray | None = None
) -> _NoiseParts:
    """:func:`._noise._noise_parts`, the prior's scale for fewer than ``SPLIT_MIN_MARKERS`` markers in closed form
    (``JtJ``: ``J^T J`` when the caller has it)."""
    M = len(q)
    if M >= SPLIT_MIN_MARKERS or corner_sigma_px is not None:
        return _noise._noise_parts(r, J, q, corner_sigma_px)
    JtJ = J.T @ J if JtJ is None else JtJ
    G = _inverse(JtJ)
    if G is None or not np.all(np.isfinite(G)):
        return _noise._noise_parts(r, J, q, corner_sigma_px)  # the pseudo-inverse's way
    K_S, K_g, grow, _ = _part_matrices(J, q)
    a0, b0, c0 = _PRIOR
    traces = (a0 + b0) * 8.0 * M + c0 * float(np.einsum("mi,mi->", grow, grow))
    expected = traces - float(np.sum(G * (a0 * JtJ + b0 * K_S + c0 * K_g)))
    dof = max(8 * M - 6, 0)
    scale = (PRIOR_DOF + float(r @ r) / max(expected, 1e-300) * dof) / (PRIOR_DOF + dof)
    return _NoiseParts(float(scale * a0), float(scale * b0), float(scale * c0), nu=dof + PRIOR_DOF)


def _pose_covariance_fast(
    J: np.ndarray, q: np.ndarray, parts: _NoiseParts, JtJ: np.ndarray | None = None
) -> np.ndarray | None:
    """:func:`._noise._pose_covariance` as one sandwich ``G (a K_I + b K_S + c K_g) G`` plus the common size
    error's ``d d^T``, ``d = G J^T g`` (``JtJ``: ``J^T J`` when the caller has it)."""
    JtJ = J.T @ J if JtJ is None else JtJ
    G = _inverse(JtJ)
    if G is None:
        return None
    K_S, K_g, _, h = _part_matrices(J, q)
    cov = G @ (parts.a * JtJ + parts.b * K_S + parts.c * K_g) @ G
    if parts.size:
        d = G @ h.sum(axis=0)
        cov = cov + np.outer(d, d) * parts.size**2
    if parts.nu is not None:
        cov = cov * _noise._inflation(round(parts.nu, 1))
    if not np.all(np.isfinite(cov)):
        return None
    return (cov + cov.T) / 2
