"""The planar flip: how likely the other planar solution of coplanar markers fits noisy corners better.

Coplanar markers seen from afar admit two poses that fit their corners almost alike (IPPE's two
solutions); :func:`flip_probability` says how often the wrong one wins, from how badly it fits the
exact corners.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .. import _lens, frames
from ..camera import Camera
from ._checks import check_flip_inputs

__all__ = ["FLIP_MIN_ANGLE_DEG", "flip_probability"]

#: A second planar solution counts as a flip when its rotation is this far from the true one
#: (degrees); nearer, the two are one answer within the noise.
FLIP_MIN_ANGLE_DEG = 5.0


def flip_probability(
    points_world: np.ndarray, points_px: np.ndarray, camera: Camera, corner_sigma_px: np.ndarray
) -> float:
    """Chance that the other planar solution fits noisy corners better than the true pose.

    With exact corners ``points_px``, the second IPPE solution refined by Levenberg-Marquardt
    leaves a weighted sum of squared residuals ``D^2``. With Gaussian corner noise the
    difference of the two fits is about ``D^2 + 2 D sigma z``, so the wrong branch wins with
    probability ``Phi(-D / 2)`` (``D`` in units of sigma). A second solution within
    :data:`FLIP_MIN_ANGLE_DEG` of the true rotation is no flip (seen face-on the two meet);
    0 when the points are not coplanar.

    Parameters
    ----------
    points_world : ndarray, shape (N, 3)
        Marker corners (mm).
    points_px : ndarray, shape (N, 2)
        Their exact projections (px; a fisheye's in its own picture, :meth:`~fidlearn.Camera.project`).
    camera : Camera
        The camera that sees them, a pinhole or a fisheye (whose corners are solved undistorted, as
        :func:`fidlearn.estimate_pose` solves them, and whose residuals are weighed in its picture's pixels).
    corner_sigma_px : ndarray, shape (N,)
        Corner noise of each point (px per axis).

    Returns
    -------
    float
        The probability, in [0, 0.5].

    Raises
    ------
    PoseError
        If the arrays are not finite, of these shapes with 4 to 10000 points, or ``corner_sigma_px`` not positive.
    """
    P, points_px, corner_sigma_px = check_flip_inputs(points_world, points_px, camera, corner_sigma_px)
    return _flip(P, points_px, camera, corner_sigma_px)[0]


def _flip(
    P: np.ndarray, points_px: np.ndarray, camera: Camera, corner_sigma_px: np.ndarray, blocks: list | None = None
) -> tuple[float, np.ndarray]:
    """:func:`flip_probability` on checked inputs, and the camera centre (mm, world) of the other solution;
    with ``blocks`` (each marker's (8, 8) corner covariance) the residuals are weighed by them instead
    (NaN when there is none)."""
    none = (0.0, np.full(3, np.nan))
    centred = P - P.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[2] > 1e-6 * max(s[0], 1.0):
        return none
    # a fisheye's corners are solved as the distortion-free pinhole of the same K sees them, as estimate_pose does
    fisheye = camera.model == "fisheye"
    solve_px, dist = (camera.undistort_points(points_px), np.zeros(5)) if fisheye else (points_px, camera.dist)
    if not np.all(np.isfinite(solve_px)):
        return none
    n, rvecs, tvecs, _ = cv2.solvePnPGeneric(
        P.reshape(-1, 1, 3), solve_px.reshape(-1, 1, 2), camera.K, dist, flags=cv2.SOLVEPNP_IPPE
    )
    found = []  # (weighted squared residual, rotation matrix, camera centre) of each solution
    for rvec, tvec in zip(rvecs[:n], tvecs[:n]):
        if not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
            continue  # IPPE gives NaN for a marker seen at a grazing angle: no second solution there
        rvec, tvec = cv2.solvePnPRefineLM(P, solve_px, camera.K, dist, rvec.copy(), tvec.copy())
        R = cv2.Rodrigues(rvec)[0]
        proj = _lens.project_points(P @ R.T + tvec.ravel(), camera.K, camera.dist, camera.model)  # picture px
        r = (proj - points_px).reshape(-1, 8) if blocks is not None else None
        d2 = (
            float(sum(rm @ np.linalg.pinv(C) @ rm for rm, C in zip(r, blocks)))
            if r is not None and blocks is not None
            else float(np.sum(np.sum((proj - points_px) ** 2, axis=1) / corner_sigma_px**2))
        )
        found.append((d2, R, -R.T @ tvec.ravel()))
    found = [f for f in found if math.isfinite(f[0]) and np.all(np.isfinite(f[1]))]
    if len(found) < 2:
        return none
    found.sort(key=lambda f: f[0])
    R_true = found[0][1]  # exact corners: the true pose fits them exactly
    others = [(d2, C) for d2, R, C in found[1:] if frames.rotation_angle_deg(R, R_true) > FLIP_MIN_ANGLE_DEG]
    if not others:
        return none
    best, C_other = others[0]
    return 0.5 * math.erfc(math.sqrt(best) / 2 / math.sqrt(2)), C_other
