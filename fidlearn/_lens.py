"""OpenCV's lens model on normalized points, and its exact inverse.

``Camera.undistort_points``, the renderer (``fidlearn.synthetic``) and the survey's residuals use these, so that
projection and undistortion are one model everywhere.
"""

from __future__ import annotations

import cv2
import numpy as np

#: Largest pixel error the exact inversion stops at (machine precision for pixel coordinates up to ~1e4).
EXACT_TOL_PX = 1e-9


def distort_normalized(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """OpenCV's distortion model on normalized points (N, 2): ideal -> distorted normalized (no tilted sensor)."""
    d = np.zeros(14)
    d[: dist.size] = dist
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d[:12]
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
    return np.stack([xd, yd], axis=1)


def pixels_from_normalized(xy: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of ideal normalized points (N, 2): the distortion, then ``K``."""
    xd = distort_normalized(xy, dist)
    return np.stack([K[0, 0] * xd[:, 0] + K[0, 1] * xd[:, 1] + K[0, 2], K[1, 1] * xd[:, 1] + K[1, 2]], axis=1)


def undistort_cv_iter(px: np.ndarray, K: np.ndarray, dist: np.ndarray, max_count: int = 200, eps: float = 1e-15):
    """Normalized points (N, 2) by OpenCV's fixed-point undistortion with explicit stopping criteria.

    OpenCV 4 calls it ``cv2.undistortPointsIter``; OpenCV 5 folds it into ``cv2.undistortPoints(..., criteria=)``.
    """
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, max_count, eps)
    src = np.asarray(px, dtype=np.float64).reshape(-1, 1, 2)
    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(src, K, dist, None, None, crit).reshape(-1, 2)
    return cv2.undistortPoints(src, K, dist, R=None, P=None, criteria=crit).reshape(-1, 2)


def _tilted(dist: np.ndarray) -> bool:
    return dist.size == 14 and bool(np.any(dist[12:]))


def undistort_exact(px: np.ndarray, K: np.ndarray, dist: np.ndarray, iterations: int = 6) -> np.ndarray:
    """Normalized ideal coordinates (N, 2) of pixels (N, 2), exact to about 1e-9 px.

    ``cv2.undistortPoints`` alone stops after a few fixed-point steps (up to
    half a pixel off at the corners of a wide lens); Newton steps on OpenCV's
    own distortion model finish the job. A tilted sensor (14 coefficients)
    is inverted by OpenCV's iteration run to 1e-15 (:func:`undistort_cv_iter`).
    """
    px = np.asarray(px, dtype=np.float64).reshape(-1, 2)
    if _tilted(dist):
        return undistort_cv_iter(px, K, dist)
    xy = cv2.undistortPoints(px.reshape(-1, 1, 2), K, dist).reshape(-1, 2)
    if not np.any(dist):
        return xy
    h = 1e-7
    for _ in range(iterations):
        base = pixels_from_normalized(xy, K, dist)
        r = base - px
        if np.abs(r).max() < EXACT_TOL_PX:
            break
        jx = (pixels_from_normalized(xy + [h, 0.0], K, dist) - base) / h
        jy = (pixels_from_normalized(xy + [0.0, h], K, dist) - base) / h
        det = jx[:, 0] * jy[:, 1] - jy[:, 0] * jx[:, 1]
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        dx = (jy[:, 1] * r[:, 0] - jy[:, 0] * r[:, 1]) / det
        dy = (-jx[:, 1] * r[:, 0] + jx[:, 0] * r[:, 1]) / det
        xy = xy - np.stack([dx, dy], axis=1)
    return xy


def undistort_pixels(px: np.ndarray, K: np.ndarray, dist: np.ndarray, exact: bool = True) -> np.ndarray:
    """Ideal pinhole pixels (N, 2) of observed pixels (N, 2): exact, or OpenCV's few fixed-point steps."""
    if not exact:
        return cv2.undistortPoints(px.reshape(-1, 1, 2), K, dist, P=K).reshape(-1, 2)
    xy = undistort_exact(px, K, dist)
    return np.stack([K[0, 0] * xy[:, 0] + K[0, 1] * xy[:, 1] + K[0, 2], K[1, 1] * xy[:, 1] + K[1, 2]], axis=1)
