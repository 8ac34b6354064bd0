"""The coach's derivatives for both lens models: a board view's pixels on its pose and the intrinsics, a ray's
pixel on the intrinsics and a small turn of the camera, and the ray through a pixel.

The pinhole camera uses ``cv2.projectPoints``'s Jacobian, the fisheye (Kannala-Brandt, ``cv2.fisheye``) its
own ``cv2.fisheye.projectPoints``'s; both in the order ``[fx, fy, cx, cy, dist...]``. The fisheye's rays are
unit vectors found by the angle ``theta`` from the axis (``_lens.fisheye_angles``), so a lens of 180 degrees
and more keeps the rays at 90 degrees and beyond, where ``(X / Z, Y / Z)`` does not exist.
"""

from __future__ import annotations

import cv2
import numpy as np

from .. import _lens, frames
from ..camera import Camera


def n_intrinsics(camera: Camera) -> int:
    """The coach's intrinsics ``[fx, fy, cx, cy, dist...]``: 9 for OpenCV's 5 coefficients, 8 for a fisheye."""
    return 4 + len(camera.dist)


def view_jacobians(camera: Camera, points_mm: np.ndarray, T_camera_board: np.ndarray):
    """A view's pixels (N, 2) and their Jacobians on its pose ``[rvec, tvec]`` (2N, 6) and the intrinsics (2N, n)."""
    P = np.asarray(points_mm, dtype=float).reshape(-1, 1, 3)
    rvec, tvec = frames.rvec_tvec_from_transform(T_camera_board)
    n = n_intrinsics(camera)
    if camera.model == "fisheye":  # columns: f (2), c (2), k (4), rvec (3), tvec (3), skew
        D = camera.dist.reshape(1, 4)
        px, jac = cv2.fisheye.projectPoints(P, rvec.reshape(3, 1), tvec.reshape(3, 1), camera.K, D)
        return px.reshape(-1, 2), jac[:, 8:14], jac[:, :n]
    px, jac = cv2.projectPoints(P, rvec, tvec, camera.K, camera.dist)
    return px.reshape(-1, 2), jac[:, :6], jac[:, 6 : 6 + n]


def fisheye_ray_pixels(rays: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of rays (N, 3) of any direction through the fisheye model: ``cv2.fisheye``'s for Z > 0, and
    on beyond 90 degrees from the axis (the angle taken as ``atan2(sqrt(X^2 + Y^2), Z)``)."""
    xd = _fisheye_distorted(rays, dist)
    return np.column_stack([K[0, 0] * xd[:, 0] + K[0, 2], K[1, 1] * xd[:, 1] + K[1, 2]])


def _fisheye_distorted(rays: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The distorted normalized points (N, 2) of rays (N, 3): ``theta_d`` along the ray's direction in the image."""
    x, y, z = np.asarray(rays, dtype=float).reshape(-1, 3).T
    r = np.hypot(x, y)
    theta = np.arctan2(r, z)
    tiny = r < 1e-12 * np.maximum(np.abs(z), 1e-300)  # on the axis: theta_d / r tends to 1 / z
    scale = np.where(tiny, 1.0 / np.where(z > 0, z, 1.0), _lens._fisheye_theta_d(theta, dist) / np.where(tiny, 1, r))
    return np.column_stack([x * scale, y * scale])


def pixel_rays(camera: Camera, px: np.ndarray) -> np.ndarray:
    """Unit rays (N, 3) in the camera frame whose pixels are ``px`` (N, 2).

    A fisheye's ray is NaN where none reaches the pixel (beyond the fold of its model's polynomial); a pinhole's is
    where OpenCV's undistortion with Newton steps ends (``_lens.undistort_exact``), as the coach always took it.
    """
    px = np.asarray(px, dtype=float).reshape(-1, 2)
    if camera.model == "fisheye":
        rays = _lens.fisheye_rays(px, camera.K, camera.dist)
    else:
        xy = _lens.undistort_exact(px, camera.K, camera.dist)
        rays = np.column_stack([xy, np.ones(len(xy))])
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)


def ray_jacobians(camera: Camera, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pixel of each ray (N, 3; finite) on the intrinsics (2N, n) and on a small turn of the camera (2N, 3)."""
    rays = np.asarray(rays, dtype=float).reshape(-1, 3)
    if camera.model != "fisheye":
        pts = rays / rays[:, 2:3]
        _, jac = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, camera.dist)
        return jac[:, 6 : 6 + n_intrinsics(camera)], jac[:, :3]
    fx, fy = camera.K[0, 0], camera.K[1, 1]
    xd = _fisheye_distorted(rays, camera.dist)
    theta = np.arctan2(np.hypot(rays[:, 0], rays[:, 1]), rays[:, 2])
    along = xd / np.where(theta > 0, _lens._fisheye_theta_d(theta, camera.dist), 1.0)[:, None]  # theta_d's share
    Ji = np.zeros((len(rays), 2, 8))
    Ji[:, 0, 0], Ji[:, 1, 1], Ji[:, 0, 2], Ji[:, 1, 3] = xd[:, 0], xd[:, 1], 1.0, 1.0
    for k in range(4):  # theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8): d / d k_i = theta^(2 i + 1)
        Ji[:, :, 4 + k] = along * theta[:, None] ** (2 * k + 3) * [fx, fy]
    h, Jr = 1e-6, np.zeros((len(rays), 2, 3))
    for k in range(3):  # a turn about axis k, by central differences
        R_plus, R_minus = (cv2.Rodrigues(s * h * np.eye(3)[k])[0] for s in (1.0, -1.0))
        diff = fisheye_ray_pixels(rays @ R_plus.T, camera.K, camera.dist)
        Jr[:, :, k] = (diff - fisheye_ray_pixels(rays @ R_minus.T, camera.K, camera.dist)) / (2 * h)
    return Ji.reshape(-1, 8), Jr.reshape(-1, 3)
