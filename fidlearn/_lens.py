"""OpenCV's lens model on normalized points, and its exact inverse.

``Camera.project`` and ``Camera.undistort_points``, the renderer (``fidlearn.synthetic``), the survey's residuals
and the planners use these, so that projection and undistortion are one model everywhere: OpenCV's 4, 5, 8, 12 or
14 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tau_x tau_y]]]]), as ``cv2.projectPoints`` computes them.
"""

from __future__ import annotations

import cv2
import numpy as np

#: Largest pixel error the exact inversion stops at (machine precision for pixel coordinates up to ~1e4).
EXACT_TOL_PX = 1e-9


def tilt_matrix(tau_x: float, tau_y: float) -> np.ndarray:
    """OpenCV's tilted-sensor projection (3, 3) (``computeTiltProjectionMatrix``): rotations about x by
    ``tau_x`` then y by ``tau_y`` (radians), projected back along the optical axis."""
    cx, sx, cy, sy = np.cos(tau_x), np.sin(tau_x), np.cos(tau_y), np.sin(tau_y)
    rot = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]]
    )
    back = np.array([[rot[2, 2], 0.0, -rot[0, 2]], [0.0, rot[2, 2], -rot[1, 2]], [0.0, 0.0, 1.0]])
    return back @ rot


def distort_normalized(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """OpenCV's distortion model on normalized points (N, 2): ideal -> distorted normalized (a tilted sensor too)."""
    d = np.zeros(14)
    d[: dist.size] = np.ravel(dist)
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d[:12]
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
    if d[12] or d[13]:
        m = tilt_matrix(d[12], d[13])
        w = m[2, 0] * xd + m[2, 1] * yd + m[2, 2]
        w = np.where(w != 0, 1.0 / np.where(w != 0, w, 1.0), 1.0)
        xd, yd = (m[0, 0] * xd + m[0, 1] * yd + m[0, 2]) * w, (m[1, 0] * xd + m[1, 1] * yd + m[1, 2]) * w
    return np.stack([xd, yd], axis=1)


def pixels_from_normalized(xy: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of ideal normalized points (N, 2): the distortion, then ``K``."""
    xd = distort_normalized(xy, dist)
    return np.stack([K[0, 0] * xd[:, 0] + K[0, 1] * xd[:, 1] + K[0, 2], K[1, 1] * xd[:, 1] + K[1, 2]], axis=1)


def project_points(points: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of points (N, 3) in the camera frame, as ``cv2.projectPoints`` gives them.

    Divided by their depth (a depth of 0 is taken as 1, as OpenCV does; points behind the camera get
    meaningless pixels), then :func:`pixels_from_normalized`.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    z = pts[:, 2:3]
    inv = np.where(z != 0, 1.0 / np.where(z != 0, z, 1.0), 1.0)
    return pixels_from_normalized(pts[:, :2] * inv, K, dist)


def undistort_cv_iter(px: np.ndarray, K: np.ndarray, dist: np.ndarray, max_count: int = 200, eps: float = 1e-15):
    """Normalized points (N, 2) by OpenCV's fixed-point undistortion with explicit stopping criteria.

    OpenCV 4 calls it ``cv2.undistortPointsIter``; OpenCV 5 folds it into ``cv2.undistortPoints(..., criteria=)``.
    """
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, max_count, eps)
    src = np.asarray(px, dtype=np.float64).reshape(-1, 1, 2)
    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(src, K, dist, None, None, crit).reshape(-1, 2)
    return cv2.undistortPoints(src, K, dist, R=None, P=None, criteria=crit).reshape(-1, 2)


def _newton_step(xy: np.ndarray, px: np.ndarray, K: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Newton step (N, 2) on ``xy`` towards the pixels ``px``, and the residual (N, 2) in pixels at ``xy``."""
    h = 1e-7
    base = pixels_from_normalized(xy, K, dist)
    r = base - px
    jx = (pixels_from_normalized(xy + [h, 0.0], K, dist) - base) / h
    jy = (pixels_from_normalized(xy + [0.0, h], K, dist) - base) / h
    det = jx[:, 0] * jy[:, 1] - jy[:, 0] * jx[:, 1]
    det = np.where(np.abs(det) < 1e-12, 1e-12, det)
    dx = (jy[:, 1] * r[:, 0] - jy[:, 0] * r[:, 1]) / det
    dy = (-jx[:, 1] * r[:, 0] + jx[:, 0] * r[:, 1]) / det
    return np.stack([dx, dy], axis=1), r


def undistort_exact(px: np.ndarray, K: np.ndarray, dist: np.ndarray, iterations: int = 6) -> np.ndarray:
    """Normalized ideal coordinates (N, 2) of pixels (N, 2), exact to about 1e-9 px.

    ``cv2.undistortPoints`` alone stops after a few fixed-point steps (up to
    half a pixel off at the corners of a wide lens); Newton steps on OpenCV's
    own distortion model (:func:`pixels_from_normalized`, a tilted sensor
    too) finish the job. Pixels beyond the fold of a lens whose distortion
    turns back (no ray reaches them) are left where the steps end.
    """
    px = np.asarray(px, dtype=np.float64).reshape(-1, 2)
    xy = cv2.undistortPoints(px.reshape(-1, 1, 2), K, dist).reshape(-1, 2)
    if not np.any(dist):
        return xy
    for _ in range(iterations):
        step, r = _newton_step(xy, px, K, dist)
        if np.abs(r).max() < EXACT_TOL_PX:
            break
        xy = xy - step
    return xy


def undistort_pixels(px: np.ndarray, K: np.ndarray, dist: np.ndarray, exact: bool = True) -> np.ndarray:
    """Ideal pinhole pixels (N, 2) of observed pixels (N, 2): exact, or OpenCV's few fixed-point steps."""
    if not exact:
        return cv2.undistortPoints(px.reshape(-1, 1, 2), K, dist, P=K).reshape(-1, 2)
    xy = undistort_exact(px, K, dist)
    return np.stack([K[0, 0] * xy[:, 0] + K[0, 1] * xy[:, 1] + K[0, 2], K[1, 1] * xy[:, 1] + K[1, 2]], axis=1)
