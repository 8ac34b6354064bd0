"""Rotations for the survey: rotation vectors, their Jacobians, and a marker's placement from a photo.

A rotation unknown is a rotation vector ``phi`` applied on the left of a reference rotation:
``R = exp([phi]x) @ R0``. Its derivatives use the left Jacobian of SO(3)::

    exp([phi + dphi]x) = exp([J_l(phi) dphi]x) exp([phi]x)     (to first order)
"""

from __future__ import annotations

import cv2
import numpy as np

from ..frames import _rotvec
from ..markermap import MARKER_CORNERS_LOCAL

#: Placement axes (top-left corner frame: face normal X, along the top edge Y, up Z) from
#: OpenCV's marker frame (x along the top edge, y up, z out of the face): ``R_place = R_m @ _M_TO_PLACE``.
_M_TO_PLACE = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices of vectors (..., 3): ``skew(a) @ b == cross(a, b)``."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    return np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], z, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], z], -1),
        ],
        -2,
    )


def exp_so3(phi: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors (..., 3) (Rodrigues' formula)."""
    phi = np.asarray(phi, dtype=float)
    theta = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = theta < 1e-8
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6, np.sin(t) / t)
    b = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(t)) / t**2)
    return np.eye(3) + a * K + b * (K @ K)


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) of a rotation matrix (3, 3): :func:`fidlearn.frames._rotvec`, exact for tiny
    angles too (``cv2.Rodrigues`` alone returns zero below about 1e-5 rad)."""
    return _rotvec(R)


def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """Left Jacobians (..., 3, 3) of SO(3) at rotation vectors (..., 3)."""
    phi = np.asarray(phi, dtype=float)
    theta = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = theta < 1e-6
    t = np.where(small, 1.0, theta)
    a = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(t)) / t**2)
    b = np.where(small, 1.0 / 6 - theta**2 / 120, (t - np.sin(t)) / t**3)
    return np.eye(3) + a * K + b * (K @ K)


def left_jacobian_inv(phi: np.ndarray) -> np.ndarray:
    """Inverse (3, 3) of the left Jacobian of SO(3) at a rotation vector (3,)."""
    phi = np.asarray(phi, dtype=float)
    theta = float(np.linalg.norm(phi))
    K = skew(phi)
    if theta < 1e-6:
        c = 1.0 / 12 + theta**2 / 720
    else:
        c = 1 / theta**2 - (1 + np.cos(theta)) / (2 * theta * np.sin(theta))
    return np.eye(3) - 0.5 * K + c * (K @ K)


def local_corners(marker_size_mm: float) -> np.ndarray:
    """A marker's corners (4, 3) in its placement frame (top-left corner at the origin), mm, TL, TR, BR, BL."""
    return MARKER_CORNERS_LOCAL * float(marker_size_mm)


def placement_from_photo(
    corners_px: np.ndarray, camera, T_world_camera: np.ndarray, marker_size_mm: float
) -> tuple[np.ndarray, np.ndarray] | None:
    """One marker's placement seen in one photo: ``(R_world_place (3, 3), top-left corner (3,), mm)``.

    IPPE_SQUARE on the four corners in the marker's own frame, then chained with the camera's
    pose in the world. None when OpenCV finds no pose.
    """
    s = float(marker_size_mm)
    obj = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0], [-s / 2, -s / 2, 0]])
    ok, rvec, tvec = cv2.solvePnP(
        obj, np.asarray(corners_px, float).reshape(4, 1, 2), camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE
    )
    if not ok or not np.all(np.isfinite(rvec)):
        return None
    R_cm = cv2.Rodrigues(rvec)[0]
    R_wm = T_world_camera[:3, :3] @ R_cm
    centre = T_world_camera[:3, :3] @ tvec.reshape(3) + T_world_camera[:3, 3]
    top_left = centre + R_wm @ obj[0]
    return R_wm @ _M_TO_PLACE, top_left
