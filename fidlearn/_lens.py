"""OpenCV's lens models on normalized points, and their exact inverses.

``Camera.project`` and ``Camera.undistort_points``, the renderer (``fidlearn.synthetic``), the survey's residuals
and the planners use these, so that projection and undistortion are one model everywhere:

* ``"pinhole"``: OpenCV's 4, 5, 8, 12 or 14 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tau_x tau_y]]]]),
  as ``cv2.projectPoints`` computes them;
* ``"fisheye"``: OpenCV's Kannala-Brandt model (``cv2.fisheye``), 4 coefficients k1..k4: a ray at angle
  ``theta`` from the optical axis lands at the distance
  ``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)`` from the principal point (in
  focal lengths), as ``cv2.fisheye.projectPoints`` computes it.

Normalized points are ``(X / Z, Y / Z)`` for both models, so a fisheye ray must stay within 90 degrees of the axis.
"""

from __future__ import annotations

import cv2
import numpy as np

#: Largest pixel error the exact inversion stops at (machine precision for pixel coordinates up to ~1e4).
EXACT_TOL_PX = 1e-9
#: The lens models, by the name ``Camera.model`` holds.
MODELS = ("pinhole", "fisheye")


def tilt_matrix(tau_x: float, tau_y: float) -> np.ndarray:
    """OpenCV's tilted-sensor projection (3, 3) (``computeTiltProjectionMatrix``): rotations about x by
    ``tau_x`` then y by ``tau_y`` (radians), projected back along the optical axis."""
    cx, sx, cy, sy = np.cos(tau_x), np.sin(tau_x), np.cos(tau_y), np.sin(tau_y)
    rot = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]]
    )
    back = np.array([[rot[2, 2], 0.0, -rot[0, 2]], [0.0, rot[2, 2], -rot[1, 2]], [0.0, 0.0, 1.0]])
    return back @ rot


def _fisheye_theta_d(theta: np.ndarray, dist: np.ndarray) -> np.ndarray:
    t2 = theta * theta
    k1, k2, k3, k4 = np.ravel(dist)[:4]
    return theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))


def _fisheye_distort(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """``cv2.fisheye``'s distortion on normalized points (N, 2), its guard at the axis included."""
    r = np.hypot(xy[:, 0], xy[:, 1])
    big = r > 1e-8
    safe_r = np.where(big, r, 1.0)
    scale = np.where(big, _fisheye_theta_d(np.arctan(r), dist) / safe_r, 1.0)
    return xy * scale[:, None]


def distort_normalized(xy: np.ndarray, dist: np.ndarray, model: str = "pinhole") -> np.ndarray:
    """The lens's distortion on normalized points (N, 2): ideal -> distorted normalized (a tilted sensor too)."""
    if model == "fisheye":
        return _fisheye_distort(xy, dist)
    d = np.zeros(14)
    d[: dist.size] = np.ravel(dist)
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d[:12].tolist()
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    # The terms of coefficients that are zero are left out: each would add exactly 0 (or divide by exactly 1).
    xd, yd = x, y
    if k1 or k2 or k3 or k4 or k5 or k6:
        radial = 1 + k1 * r2 + k2 * r4 + k3 * r6
        if k4 or k5 or k6:
            radial = radial / (1 + k4 * r2 + k5 * r4 + k6 * r6)
        xd, yd = x * radial, y * radial
    if p1 or p2:
        xd, yd = xd + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), yd + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    if s1 or s2 or s3 or s4:
        xd, yd = xd + s1 * r2 + s2 * r4, yd + s3 * r2 + s4 * r4
    if d[12] or d[13]:
        m = tilt_matrix(d[12], d[13])
        w = m[2, 0] * xd + m[2, 1] * yd + m[2, 2]
        w = np.where(w != 0, 1.0 / np.where(w != 0, w, 1.0), 1.0)
        xd, yd = (m[0, 0] * xd + m[0, 1] * yd + m[0, 2]) * w, (m[1, 0] * xd + m[1, 1] * yd + m[1, 2]) * w
    return np.stack([xd, yd], axis=1)


def pixels_from_normalized(xy: np.ndarray, K: np.ndarray, dist: np.ndarray, model: str = "pinhole") -> np.ndarray:
    """Pixels (N, 2) of ideal normalized points (N, 2): the distortion, then ``K``."""
    xd = distort_normalized(xy, dist, model)
    return np.stack([K[0, 0] * xd[:, 0] + K[0, 1] * xd[:, 1] + K[0, 2], K[1, 1] * xd[:, 1] + K[1, 2]], axis=1)


def project_points(points: np.ndarray, K: np.ndarray, dist: np.ndarray, model: str = "pinhole") -> np.ndarray:
    """Pixels (N, 2) of points (N, 3) in the camera frame, as ``cv2.projectPoints`` (or ``cv2.fisheye``'s) gives them.

    Divided by their depth (a depth of 0 is taken as 1, as OpenCV does; points behind the camera get
    meaningless pixels), then :func:`pixels_from_normalized`.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    z = pts[:, 2:3]
    inv = np.where(z != 0, 1.0 / np.where(z != 0, z, 1.0), 1.0)
    return pixels_from_normalized(pts[:, :2] * inv, K, dist, model)


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


def fisheye_angles(px: np.ndarray, K: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each pixel's ray angle ``theta`` (N,) from the axis through the fisheye model (radians, up to pi; NaN
    where no ray reaches: beyond the lens's fold), its distorted normalized point (N, 2) and ``theta_d`` (N,).

    Newton steps on ``theta_d(theta) = |distorted normalized point|``, to machine precision.
    """
    yd = (px[:, 1] - K[1, 2]) / K[1, 1]
    xd = (px[:, 0] - K[0, 2] - K[0, 1] * yd) / K[0, 0]
    theta_d = np.hypot(xd, yd)
    k1, k2, k3, k4 = np.ravel(dist)[:4]
    s1, s2, s3 = 3 * k1, 5 * k2, 7 * k3  # the slope d theta_d / d theta: 1 + s1 t2 + s2 t2^2 + s3 t2^3 + 9 k4 t2^4

    # theta_d(theta) and its slope share theta^2: the values of _fisheye_theta_d and of the slope's own
    # polynomial, with half the products (np.minimum of np.maximum for np.clip: the same values, a third the cost)
    theta = np.minimum(theta_d, np.pi)
    for _ in range(50):
        t2 = theta * theta
        s = 1 + t2 * (s1 + t2 * (s2 + t2 * (s3 + t2 * 9 * k4)))
        step = (theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - theta_d) / np.where(s > 0, s, 1.0)
        theta = np.minimum(np.maximum(theta - step, 0.0), np.pi)
        if np.all(np.abs(step) < 1e-15):
            break
    t2 = theta * theta
    miss = np.abs(theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - theta_d)
    reached = (miss <= 1e-12 * np.maximum(1.0, theta_d)) & (1 + t2 * (s1 + t2 * (s2 + t2 * (s3 + t2 * 9 * k4))) > 0)
    theta = np.where(reached, theta, np.nan)
    return theta, np.stack([xd, yd], axis=1), theta_d


def fisheye_rays(px: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Unit rays (N, 3) in the camera frame of fisheye pixels (N, 2), through :func:`fisheye_angles` (rays up to
    180 degrees off the axis; NaN where none reaches the pixel)."""
    theta, xyd, theta_d = fisheye_angles(px, K, dist)
    safe = np.where(theta_d > 1e-300, theta_d, 1.0)
    along = np.where(theta_d[:, None] > 1e-300, xyd / safe[:, None], 0.0)  # the unit direction in the image
    return np.column_stack([along * np.sin(theta)[:, None], np.cos(theta)])


def _fisheye_undistort(px: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Normalized ideal coordinates (N, 2) of pixels (N, 2) through the fisheye model (:func:`fisheye_angles`).

    NaN for a pixel whose ray is 90 degrees or more off the axis (no normalized point), or that no ray reaches.
    """
    theta, xyd, theta_d = fisheye_angles(px, K, dist)
    ok = theta < np.pi / 2 - 1e-9  # NaN compares False
    safe = np.where(ok, theta, 0.0)
    scale = np.where(theta_d > 1e-12, np.tan(safe) / np.where(theta_d > 1e-12, theta_d, 1.0), 1.0)
    xy = xyd * scale[:, None]
    xy[~ok] = np.nan
    return xy


def undistort_exact(
    px: np.ndarray, K: np.ndarray, dist: np.ndarray, iterations: int = 6, model: str = "pinhole"
) -> np.ndarray:
    """Normalized ideal coordinates (N, 2) of pixels (N, 2), exact to about 1e-9 px.

    The fisheye model is inverted along the radius (:func:`_fisheye_undistort`), to machine precision;
    pixels no ray in front of the camera reaches are NaN there.

    ``cv2.undistortPoints`` alone stops after a few fixed-point steps (up to
    half a pixel off at the corners of a wide lens); Newton steps on OpenCV's
    own distortion model (:func:`pixels_from_normalized`, a tilted sensor
    too) finish the job. Pixels beyond the fold of a lens whose distortion
    turns back (no ray reaches them) are left where the steps end.
    """
    px = np.asarray(px, dtype=np.float64).reshape(-1, 2)
    if model == "fisheye":
        return _fisheye_undistort(px, K, dist)
    xy = cv2.undistortPoints(px.reshape(-1, 1, 2), K, dist).reshape(-1, 2)
    if not np.any(dist):
        return xy
    for _ in range(iterations):
        step, r = _newton_step(xy, px, K, dist)
        if np.abs(r).max() < EXACT_TOL_PX:
            break
        xy = xy - step
    return xy


def _fisheye_in_front(px: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Whether a ray less than 90 degrees off the axis reaches each fisheye pixel (N, 2): bool (N,), its
    distorted radius below the largest the lens's ``theta_d`` takes from 0 to 90 degrees."""
    yd = (px[:, 1] - K[1, 2]) / K[1, 1]
    xd = (px[:, 0] - K[0, 2] - K[0, 1] * yd) / K[0, 0]
    return np.hypot(xd, yd) < _fisheye_theta_d(np.linspace(0.0, np.pi / 2, 4097), dist).max()


def undistort_pixels(
    px: np.ndarray, K: np.ndarray, dist: np.ndarray, exact: bool = True, model: str = "pinhole"
) -> np.ndarray:
    """Ideal pinhole pixels (N, 2) of observed pixels (N, 2): exact, or OpenCV's few fixed-point steps.

    A fisheye pixel that no ray less than 90 degrees off the axis reaches is NaN either way (OpenCV's own
    answer there is the mirror image of a ray in front, on the other side of the picture).
    """
    if not exact:
        src = px.reshape(-1, 1, 2).astype(np.float64)
        if model == "fisheye":
            out = cv2.fisheye.undistortPoints(src, K, dist.reshape(1, 4), P=K).reshape(-1, 2)
            out[~_fisheye_in_front(src.reshape(-1, 2), K, dist)] = np.nan
            return out
        return cv2.undistortPoints(src, K, dist, P=K).reshape(-1, 2)
    xy = undistort_exact(px, K, dist, model=model)
    return np.stack([K[0, 0] * xy[:, 0] + K[0, 1] * xy[:, 1] + K[0, 2], K[1, 1] * xy[:, 1] + K[1, 2]], axis=1)


def new_camera_matrix(
    K: np.ndarray, dist: np.ndarray, model: str, size: tuple[int, int], alpha: float, new_size: tuple[int, int]
) -> np.ndarray:
    """The camera matrix (3, 3) of the undistorted picture: OpenCV's choice for each model.

    ``cv2.getOptimalNewCameraMatrix`` with ``alpha`` (pinhole) or
    ``cv2.fisheye.estimateNewCameraMatrixForUndistortRectify`` with ``balance=alpha`` (fisheye): 0 keeps only
    pixels with picture behind them, 1 keeps every pixel of the picture. A fisheye whose picture's edges
    reach more than :data:`FISHEYE_EDGE_MAX_DEG` off the axis gets OpenCV's rule with those edges taken at
    that angle (:func:`_fisheye_new_camera_matrix`).
    """
    if model == "fisheye":
        return _fisheye_new_camera_matrix(K, dist, size, alpha, new_size)
    newK, _ = cv2.getOptimalNewCameraMatrix(K, dist, tuple(size), float(alpha), tuple(new_size))
    return newK


#: The largest angle (degrees) off the axis at which a fisheye's edge is kept in an undistorted picture.
FISHEYE_EDGE_MAX_DEG = 80.0


def _fisheye_new_camera_matrix(
    K: np.ndarray, dist: np.ndarray, size: tuple[int, int], alpha: float, new_size: tuple[int, int]
) -> np.ndarray:
    """``cv2.fisheye.estimateNewCameraMatrixForUndistortRectify``'s camera matrix (3, 3), its edges held within
    :data:`FISHEYE_EDGE_MAX_DEG` of the axis.

    OpenCV centres the new camera on the mean of the picture's edge middles undistorted to ideal normalized
    points and fits its focal length between them; an edge seen near or past 90 degrees off the axis has no
    such point (infinite or behind the camera), and OpenCV's choice then shows a fraction of the picture with
    its principal point far from the middle. Such an edge's middle is taken on its own ray at the largest
    angle: ``alpha`` 0 still keeps only pixels with picture behind them, 1 keeps the picture up to that angle.
    """
    w, h = size
    mids = np.array([[w // 2, 0], [w, h // 2], [w // 2, h], [0, h // 2]], dtype=np.float64)  # OpenCV's points
    theta, xyd, theta_d = fisheye_angles(mids, K, dist)
    limit = np.radians(FISHEYE_EDGE_MAX_DEG)
    if np.all(theta <= limit):
        return cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(
            K, dist.reshape(1, 4), tuple(size), np.eye(3), balance=float(alpha), new_size=tuple(new_size)
        )
    theta = np.where(np.isfinite(theta), np.minimum(theta, limit), limit)  # beyond the lens's fold: its edge too
    pts = xyd * (np.tan(theta) / np.where(theta_d > 1e-12, theta_d, 1.0))[:, None]
    aspect = K[0, 0] / K[1, 1]
    pts[:, 1] *= aspect
    cn = pts.mean(axis=0)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    half = np.array([w * 0.5, w * 0.5, h * 0.5 * aspect, h * 0.5 * aspect])
    fs = half / np.array([cn[0] - lo[0], hi[0] - cn[0], cn[1] - lo[1], hi[1] - cn[1]])
    f = alpha * fs.min() + (1.0 - alpha) * fs.max()
    c = -cn * f + np.array([w, h * aspect]) * 0.5
    rx, ry = new_size[0] / w, new_size[1] / h
    return np.array([[f * rx, 0.0, c[0] * rx], [0.0, f / aspect * ry, c[1] / aspect * ry], [0.0, 0.0, 1.0]])


def undistort_maps(
    K: np.ndarray, dist: np.ndarray, model: str, new_K: np.ndarray, new_size: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Maps (H, W) float32 for ``cv2.remap``: where each pixel of the ideal camera ``new_K`` is in the picture.

    Each output pixel's ray goes through the lens model (:func:`pixels_from_normalized`), as
    ``cv2.initUndistortRectifyMap`` (or ``cv2.fisheye``'s) does it.
    """
    w, h = int(new_size[0]), int(new_size[1])
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    y = (v.ravel() - new_K[1, 2]) / new_K[1, 1]
    x = (u.ravel() - new_K[0, 2] - new_K[0, 1] * y) / new_K[0, 0]
    px = pixels_from_normalized(np.stack([x, y], axis=1), K, dist, model)
    return px[:, 0].reshape(h, w).astype(np.float32), px[:, 1].reshape(h, w).astype(np.float32)


def fisheye_fov_deg(K: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> tuple[float, float]:
    """A fisheye's horizontal and vertical field of view (degrees): the ray angles at the picture's edges
    through the principal point (NaN where an edge is beyond the lens's reach)."""
    w, h = size
    cx, cy = K[0, 2], K[1, 2]
    ends = np.array([[-0.5, cy], [w - 0.5, cy], [cx, -0.5], [cx, h - 0.5]])
    ang = np.degrees(fisheye_angles(ends, K, dist)[0])
    return (float(ang[0] + ang[1]), float(ang[2] + ang[3]))
