"""Camera rays: the normalized (undistorted) coordinates of every pixel and sub-pixel, with OpenCV's distortion."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from ..camera import Camera
from ..errors import CameraError


def _distort_normalized(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """OpenCV's distortion model on normalized points (N, 2): ideal -> distorted normalized."""
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


def _pixels_from_normalized(xy: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    xd = _distort_normalized(xy, dist)
    return np.stack([K[0, 0] * xd[:, 0] + K[0, 1] * xd[:, 1] + K[0, 2], K[1, 1] * xd[:, 1] + K[1, 2]], axis=1)


def _undistort_exact(px: np.ndarray, K: np.ndarray, dist: np.ndarray, iterations: int = 6) -> np.ndarray:
    """Normalized ideal coordinates (N, 2) of pixels (N, 2), exact to about 1e-9 px.

    ``cv2.undistortPoints`` alone stops after a few fixed-point steps (up to
    half a pixel off at the corners of a wide lens); Newton steps on OpenCV's
    own distortion model finish the job.
    """
    xy = cv2.undistortPoints(px.reshape(-1, 1, 2).astype(np.float64), K, dist).reshape(-1, 2)
    if not np.any(dist):
        return xy
    h = 1e-7
    for _ in range(iterations):
        base = _pixels_from_normalized(xy, K, dist)
        r = base - px
        if np.abs(r).max() < 1e-9:
            break
        jx = (_pixels_from_normalized(xy + [h, 0.0], K, dist) - base) / h
        jy = (_pixels_from_normalized(xy + [0.0, h], K, dist) - base) / h
        det = jx[:, 0] * jy[:, 1] - jy[:, 0] * jx[:, 1]
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        dx = (jy[:, 1] * r[:, 0] - jy[:, 0] * r[:, 1]) / det
        dy = (-jx[:, 1] * r[:, 0] + jx[:, 0] * r[:, 1]) / det
        xy = xy - np.stack([dx, dy], axis=1)
    return xy


@lru_cache(maxsize=4)
def _normalized_map_cached(key: bytes, width: int, height: int) -> np.ndarray:
    K_dist = np.frombuffer(key, dtype=np.float64)
    K, dist = K_dist[:9].reshape(3, 3), K_dist[9:]
    u, v = np.meshgrid(np.arange(-1.0, width + 1.0), np.arange(-1.0, height + 1.0))
    px = np.stack([u.ravel(), v.ravel()], axis=1)
    xy = _undistort_exact(px, K, dist)
    out = xy.reshape(height + 2, width + 2, 2).astype(np.float32)
    out.setflags(write=False)
    return out


def _normalized_map(camera: Camera) -> np.ndarray:
    """Normalized ray coordinates (H + 2, W + 2, 2), float32, of every pixel, with a one-pixel margin.

    Entry ``[j, i]`` belongs to the pixel centre ``u = i - 1``, ``v = j - 1``.
    """
    if camera.dist.size == 14 and np.any(camera.dist[12:]):
        raise CameraError(
            f"{camera.source or 'camera'}: the renderer does not model a tilted sensor (tau_x, tau_y = "
            f"{camera.dist[12]:g}, {camera.dist[13]:g}); use at most 12 distortion coefficients"
        )
    key = np.concatenate([camera.K.ravel(), camera.dist.ravel()]).astype(np.float64).tobytes()
    return _normalized_map_cached(key, camera.width, camera.height)


def _fine_rays(nmap: np.ndarray, u0: int, u1: int, v0: int, v1: int, k: int) -> np.ndarray:
    """Normalized coordinates (k (v1 - v0), k (u1 - u0), 2), float32, of the sub-pixels of some output pixels.

    The output pixels are ``u0..u1-1`` by ``v0..v1-1``.

    Bilinear interpolation of the per-pixel map (the distortion is smooth: error
    below 1e-4 px). ``cv2.resize`` maps a fine sample ``x_d`` to the coarse
    coordinate ``(x_d + 0.5) / k - 0.5``, the same pixel-centre rule as the
    supersampling, and the one-pixel margin keeps it from clamping at the edge.
    """
    patch = nmap[v0 : v1 + 2, u0 : u1 + 2]
    if k == 1:
        return np.ascontiguousarray(patch[1:-1, 1:-1])
    h, w = patch.shape[:2]
    fine = cv2.resize(patch, (w * k, h * k), interpolation=cv2.INTER_LINEAR)
    return np.ascontiguousarray(fine[k : k + k * (v1 - v0), k : k + k * (u1 - u0)])
