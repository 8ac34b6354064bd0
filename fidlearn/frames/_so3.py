"""The Lie group of rotations, for the estimators that step on it (the tracker, the survey).

A rotation unknown is a rotation vector ``w`` applied on the left of a reference rotation,
``R = exp([w]x) @ R0``; its derivatives use the left Jacobian of SO(3)::

    exp([w + dw]x) = exp([J_l(w) dw]x) exp([w]x)     (to first order)

Every function takes one vector (3,) or a stack (..., 3): the tracker calls them on one rotation per
frame (a plain-float path, a few microseconds), the survey on all its markers at once.
"""

from __future__ import annotations

import math

import numpy as np

from ._rotations import _rotvec

__all__ = ["exp_so3", "left_jacobian", "left_jacobian_inv", "log_so3", "skew"]


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices (..., 3, 3) of vectors (..., 3): ``skew(a) @ b == cross(a, b)``."""
    v = np.asarray(v, dtype=float)
    if v.ndim == 1:
        x, y, z = float(v[0]), float(v[1]), float(v[2])
        return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    zero = np.zeros(v.shape[:-1])
    return np.stack(
        [
            np.stack([zero, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], zero, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], zero], -1),
        ],
        -2,
    )


def exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors (..., 3), rad (Rodrigues' formula, exact near 0)."""
    w = np.asarray(w, dtype=float)
    K = skew(w)
    if w.ndim == 1:
        th2 = float(w @ w)
        if th2 < 1e-12:  # second order: the error is th^3 / 6, below 1e-18
            return np.eye(3) + K + 0.5 * (K @ K)
        th = math.sqrt(th2)
        return np.eye(3) + (math.sin(th) / th) * K + ((1.0 - math.cos(th)) / th2) * (K @ K)
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    small = theta < 1e-8
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6, np.sin(t) / t)
    b = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(t)) / t**2)
    return np.eye(3) + a * K + b * (K @ K)


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,), rad, of a rotation matrix (3, 3), the inverse of :func:`exp_so3` for angles up to
    pi: :func:`fidlearn.frames._rotvec`, exact for tiny angles too (``cv2.Rodrigues`` alone returns zero
    below about 1e-5 rad)."""
    return _rotvec(R)


def left_jacobian(w: np.ndarray) -> np.ndarray:
    """Left Jacobians (..., 3, 3) of SO(3) at rotation vectors (..., 3): ``exp(w + d) ~= exp(J_l(w) d) exp(w)``."""
    w = np.asarray(w, dtype=float)
    K = skew(w)
    if w.ndim == 1:
        th2 = float(w @ w)
        if th2 < 1e-12:
            return np.eye(3) + 0.5 * K
        th = math.sqrt(th2)
        return np.eye(3) + ((1.0 - math.cos(th)) / th2) * K + ((th - math.sin(th)) / (th2 * th)) * (K @ K)
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    small = theta < 1e-6
    t = np.where(small, 1.0, theta)
    a = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(t)) / t**2)
    b = np.where(small, 1.0 / 6 - theta**2 / 120, (t - np.sin(t)) / t**3)
    return np.eye(3) + a * K + b * (K @ K)


def left_jacobian_inv(w: np.ndarray) -> np.ndarray:
    """Inverse (3, 3) of the left Jacobian of SO(3) at a rotation vector (3,)."""
    w = np.asarray(w, dtype=float)
    theta = float(np.linalg.norm(w))
    K = skew(w)
    if theta < 1e-6:
        c = 1.0 / 12 + theta**2 / 720
    else:
        c = 1 / theta**2 - (1 + math.cos(theta)) / (2 * theta * math.sin(theta))
    return np.eye(3) - 0.5 * K + c * (K @ K)
