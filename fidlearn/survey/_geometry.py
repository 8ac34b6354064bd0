"""The survey's geometry: a marker's corners in its placement frame, its placement seen in one photo, and the
motion that lays one set of points on another.

Rotation unknowns step on SO(3) with :mod:`fidlearn.frames._so3` (re-exported here for the survey's modules).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..frames import rpy_deg_from_rotation
from ..frames._so3 import exp_so3, left_jacobian, left_jacobian_inv, log_so3, skew
from ..markermap import MARKER_CORNERS_LOCAL, MarkerPlacement

__all__ = [
    "exp_so3",
    "fit_motion",
    "left_jacobian",
    "left_jacobian_inv",
    "local_corners",
    "log_so3",
    "placement_of",
    "marker_sizes",
    "placement_from_photo",
    "skew",
]

#: Placement axes (top-left corner frame: face normal X, along the top edge Y, up Z) from
#: OpenCV's marker frame (x along the top edge, y up, z out of the face): ``R_place = R_m @ _M_TO_PLACE``.
_M_TO_PLACE = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def local_corners(marker_size_mm: float) -> np.ndarray:
    """A marker's corners (4, 3) in its placement frame (top-left corner at the origin), mm, TL, TR, BR, BL."""
    return MARKER_CORNERS_LOCAL * float(marker_size_mm)


def placement_from_photo(
    corners_px: np.ndarray, camera, T_world_camera: np.ndarray, marker_size_mm: float
) -> tuple[np.ndarray, np.ndarray] | None:
    """One marker's placement seen in one photo: ``(R_world_place (3, 3), top-left corner (3,), mm)``.

    IPPE_SQUARE on the four corners in the marker's own frame, then chained with the camera's
    pose in the world. A fisheye's corners are undistorted exactly first (``camera.undistort_points``),
    as OpenCV's solvePnP models the pinhole lens only. None when OpenCV finds no pose.
    """
    s = float(marker_size_mm)
    obj = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0], [-s / 2, -s / 2, 0]])
    px, dist = np.asarray(corners_px, float).reshape(4, 2), camera.dist
    if getattr(camera, "model", "pinhole") == "fisheye":
        px, dist = camera.undistort_points(px), np.zeros(5)
        if not np.all(np.isfinite(px)):
            return None
    ok, rvec, tvec = cv2.solvePnP(obj, px.reshape(4, 1, 2), camera.K, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    if not ok or not np.all(np.isfinite(rvec)):
        return None
    R_cm = cv2.Rodrigues(rvec)[0]
    R_wm = T_world_camera[:3, :3] @ R_cm
    centre = T_world_camera[:3, :3] @ tvec.reshape(3) + T_world_camera[:3, 3]
    top_left = centre + R_wm @ obj[0]
    return R_wm @ _M_TO_PLACE, top_left


def placement_of(
    marker_id: int, R_world_place: np.ndarray, top_left_mm: np.ndarray, size_mm: float | None = None
) -> MarkerPlacement:
    """The :class:`MarkerPlacement` of a rotation (3, 3) and a top-left corner (3,), mm.

    ``marker_id`` is a map's key: a :class:`~fidlearn.MarkerKey` keeps its dictionary; ``size_mm`` the
    marker's own side (None: the map's).
    """
    x, y, z = (float(v) for v in top_left_mm)
    roll, pitch, yaw = (float(a) for a in rpy_deg_from_rotation(R_world_place))
    return MarkerPlacement(
        int(marker_id), (x, y, z), (roll, pitch, yaw), size_mm, getattr(marker_id, "dictionary", None)
    )


def marker_sizes(tape, keys, scale: float = 1.0) -> dict:
    """Each key's marker side (mm) times ``scale``: the map's own size for its markers, the map's default else."""
    return {k: scale * (tape.marker_size(k) if k in tape else tape.marker_size_mm) for k in keys}


def fit_motion(a: np.ndarray, b: np.ndarray, scaled: bool = False, limit: float = math.inf):
    """``(s, R, t)`` with ``s R a + t`` closest to points ``b`` in least squares (Umeyama 1991), a proper rotation.

    ``s`` is 1 unless ``scaled``. None when the points ``a`` coincide or are not finite, or the fitted scale is
    not within ``(1 / limit, limit)``.
    """
    ca, cb = a - a.mean(axis=0), b - b.mean(axis=0)
    var = float(np.sum(ca**2))
    if var <= 0 or not math.isfinite(var):
        return None
    u, sv, vt = np.linalg.svd(cb.T @ ca)
    d = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(u @ vt)) or 1.0)])
    R = u @ d @ vt
    s = float(np.sum(sv * np.diag(d))) / var if scaled else 1.0
    if not (1 / limit < s < limit):
        return None
    return s, R, b.mean(axis=0) - s * R @ a.mean(axis=0)
