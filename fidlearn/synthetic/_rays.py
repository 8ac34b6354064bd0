"""Camera rays: the normalized (undistorted) coordinates of every pixel and sub-pixel, by the camera's lens model
(``fidlearn._lens``, the one ``Camera.project`` and ``Camera.undistort_points`` use)."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from .._lens import undistort_exact
from ..camera import Camera
from ..errors import CameraError


@lru_cache(maxsize=4)
def _normalized_map_cached(key: bytes, width: int, height: int, model: str = "pinhole") -> np.ndarray:
    K_dist = np.frombuffer(key, dtype=np.float64)
    K, dist = K_dist[:9].reshape(3, 3), K_dist[9:]
    u, v = np.meshgrid(np.arange(-1.0, width + 1.0), np.arange(-1.0, height + 1.0))
    px = np.stack([u.ravel(), v.ravel()], axis=1)
    xy = undistort_exact(px, K, dist, model=model)
    out = xy.reshape(height + 2, width + 2, 2).astype(np.float32)
    out.setflags(write=False)
    return out


def _normalized_map(camera: Camera) -> np.ndarray:
    """Normalized ray coordinates (H + 2, W + 2, 2), float32, of every pixel, with a one-pixel margin.

    Entry ``[j, i]`` belongs to the pixel centre ``u = i - 1``, ``v = j - 1``.
    """
    assert camera.dist is not None  # Camera makes it an array
    if camera.dist.size == 14 and np.any(camera.dist[12:]):
        raise CameraError(
            f"{camera.source or 'camera'}: the renderer does not model a tilted sensor (tau_x, tau_y = "
            f"{camera.dist[12]:g}, {camera.dist[13]:g}); use at most 12 distortion coefficients"
        )
    key = np.concatenate([camera.K.ravel(), camera.dist.ravel()]).astype(np.float64).tobytes()
    return _normalized_map_cached(key, camera.width, camera.height, camera.model)


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
