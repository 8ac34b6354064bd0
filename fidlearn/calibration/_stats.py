"""A calibration's per-view errors and the standard deviations of its intrinsics, from one projection pass.

``cv2.calibrateCameraExtended`` gives both, but inverts the whole normal matrix (the
intrinsics and six pose parameters per view) by an eigen-decomposition: that alone made it
cost up to 2.8 times ``cv2.calibrateCamera`` at 60 views. Here ``cv2.calibrateCamera``
runs, then:

* the per-view errors come from projecting every view's board points with the returned
  camera and poses, in one call: the RMS (px) of each view's residuals;
* the standard deviations come from the same normal matrix ``J^T J`` (its Jacobian from
  ``cv2.projectPoints`` at the returned parameters, the parameters OpenCV holds fixed left
  out), reduced to the intrinsics by the Schur complement of the per-view pose blocks: the
  diagonal of ``(J^T J)^-1`` for the intrinsics, times ``sigma^2 = rms^2 N / (2N - p)``
  (``N`` points, ``p`` free parameters), as OpenCV does.

The per-view errors are OpenCV's to rounding (1e-12 relative at most); the standard
deviations agree with ``calibrateCameraExtended``'s to about 1e-8 relative with the default
5-coefficient model, 1e-5 with the rational one, whose ``J^T J`` is worse conditioned
(``tests/test_calibration_stats.py``).
"""

from __future__ import annotations

import cv2
import numpy as np

from .. import _lens

__all__: list[str] = []


def free_intrinsics(flags: int, n_dist: int) -> np.ndarray:
    """Which of ``fx, fy, cx, cy`` and the distortion coefficients ``cv2.calibrateCamera`` fits.

    The rules of OpenCV's ``calibrateCameraInternal``, for ``4 + n_dist`` parameters.
    """
    free = np.ones(18, dtype=bool)
    if n_dist < 8:
        flags |= cv2.CALIB_FIX_K4 | cv2.CALIB_FIX_K5 | cv2.CALIB_FIX_K6 | (cv2.CALIB_FIX_K3 if n_dist < 5 else 0)
    if not flags & cv2.CALIB_RATIONAL_MODEL:
        flags |= cv2.CALIB_FIX_K4 | cv2.CALIB_FIX_K5 | cv2.CALIB_FIX_K6
    if not flags & cv2.CALIB_THIN_PRISM_MODEL:
        flags |= cv2.CALIB_FIX_S1_S2_S3_S4
    if not flags & cv2.CALIB_TILTED_MODEL:
        flags |= cv2.CALIB_FIX_TAUX_TAUY
    fixed = {
        0: cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_FIX_FOCAL_LENGTH,
        1: cv2.CALIB_FIX_FOCAL_LENGTH,
        2: cv2.CALIB_FIX_PRINCIPAL_POINT,
        3: cv2.CALIB_FIX_PRINCIPAL_POINT,
        4: cv2.CALIB_FIX_K1,
        5: cv2.CALIB_FIX_K2,
        6: cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_TANGENT_DIST,
        7: cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_TANGENT_DIST,
        8: cv2.CALIB_FIX_K3,
        9: cv2.CALIB_FIX_K4,
        10: cv2.CALIB_FIX_K5,
        11: cv2.CALIB_FIX_K6,
        12: cv2.CALIB_FIX_S1_S2_S3_S4,
        13: cv2.CALIB_FIX_S1_S2_S3_S4,
        14: cv2.CALIB_FIX_S1_S2_S3_S4,
        15: cv2.CALIB_FIX_S1_S2_S3_S4,
        16: cv2.CALIB_FIX_TAUX_TAUY,
        17: cv2.CALIB_FIX_TAUX_TAUY,
    }
    for i, mask in fixed.items():
        free[i] = not flags & mask
    return free[: 4 + n_dist]


def per_view_rms(
    obj: list, img: list, K: np.ndarray, dist: np.ndarray, rotations, tvecs, model: str = "pinhole"
) -> np.ndarray:
    """RMS reprojection error (px) of each view at the given camera and poses, in one projection (``model``:
    the lens, ``fidlearn._lens``'s for a fisheye).

    ``obj[i]`` (N_i, 1, 3) and ``img[i]`` (N_i, 1, 2) as passed to ``cv2.calibrateCamera``;
    ``rotations[i]`` (3, 3) the rotation of view i's rvec, ``tvecs[i]`` its translation.
    """
    counts = np.array([len(o) for o in obj])
    in_camera = np.concatenate(
        [o.reshape(-1, 3).astype(np.float64) @ R.T + np.reshape(t, 3) for o, R, t in zip(obj, rotations, tvecs)]
    )
    if model == "fisheye":
        proj = _lens.project_points(in_camera, K, dist, model)
    else:
        proj, _ = cv2.projectPoints(in_camera, np.zeros(3), np.zeros(3), K, dist)
    e = proj.reshape(-1, 2) - np.concatenate([p.reshape(-1, 2) for p in img]).astype(np.float64)
    return np.sqrt(np.add.reduceat(np.sum(e * e, axis=1), np.cumsum(counts) - counts) / counts)


def std_intrinsics(obj: list, K, dist, rvecs, tvecs, rms_px: float, flags: int) -> np.ndarray:
    """Standard deviations of ``fx, fy, cx, cy, dist...`` (0 for a parameter held fixed), as OpenCV's.

    The arguments are those of ``cv2.calibrateCamera`` and what it returned (``rms_px`` its RMS).
    """
    dist = np.asarray(dist, dtype=np.float64).reshape(-1)
    free = free_intrinsics(int(flags), len(dist))
    aspect = K[0, 0] / K[1, 1] if flags & cv2.CALIB_FIX_ASPECT_RATIO else 0.0
    n_free = int(free.sum())
    schur = np.zeros((n_free, n_free))
    total = 0
    for o, r, t in zip(obj, rvecs, tvecs):
        _, J = cv2.projectPoints(o.astype(np.float64), r, t, K, dist, aspectRatio=aspect)
        J_pose, J_int = J[:, :6], J[:, 6 : 10 + len(dist)][:, free]
        W = J_int.T @ J_pose
        schur += J_int.T @ J_int - W @ np.linalg.solve(J_pose.T @ J_pose, W.T)
        total += len(o)
    return _std_from_schur(schur, free, rms_px, total, len(obj))


def std_intrinsics_fisheye(obj: list, K, dist, rvecs, tvecs, rms_px: float, free=None) -> np.ndarray:
    """Standard deviations of ``fx, fy, cx, cy, k1..k4`` of a ``cv2.fisheye.calibrate`` result (skew fixed at 0).

    The same reduction as :func:`std_intrinsics`, with the Jacobian of ``cv2.fisheye.projectPoints``
    (columns: f (2), c (2), k (4), rvec (3), tvec (3), skew). ``free`` (8,) bool: the parameters the flags let
    the fit move (default all); the others are 0.
    """
    D = np.asarray(dist, dtype=np.float64).reshape(1, 4)
    free = np.ones(8, dtype=bool) if free is None else np.asarray(free, dtype=bool)
    n = int(free.sum())
    schur = np.zeros((n, n))
    total = 0
    for o, r, t in zip(obj, rvecs, tvecs):
        pts = np.asarray(o, np.float64).reshape(-1, 1, 3)
        _, J = cv2.fisheye.projectPoints(pts, np.reshape(r, (3, 1)), np.reshape(t, (3, 1)), K, D)
        J_pose, J_int = J[:, 8:14], J[:, :8][:, free]
        W = J_int.T @ J_pose
        schur += J_int.T @ J_int - W @ np.linalg.solve(J_pose.T @ J_pose, W.T)
        total += len(pts)
    return _std_from_schur(schur, free, rms_px, total, len(obj))


def _std_from_schur(schur: np.ndarray, free: np.ndarray, rms_px: float, total: int, n_views: int) -> np.ndarray:
    """Standard deviations from the Schur complement of the pose blocks (the free intrinsics), 0 for fixed ones."""
    n_free = int(free.sum())
    # the pose blocks eliminated: the intrinsics' block of the inverse is the inverse of the Schur complement
    diag = np.diag(schur).copy()
    diag[~(diag > 0)] = 1.0  # a parameter no view constrains: left unscaled (and pinv below)
    scale = np.outer(1.0 / np.sqrt(diag), 1.0 / np.sqrt(diag))
    try:
        cov = np.linalg.inv(schur * scale) * scale
    except np.linalg.LinAlgError:  # singular, as OpenCV's eigen-decomposition allows: the pseudo-inverse
        cov = np.linalg.pinv(schur * scale) * scale
    sigma2 = rms_px**2 * total / (2 * total - n_free - 6 * n_views)
    out = np.zeros(len(free))
    out[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None) * sigma2)
    return out
