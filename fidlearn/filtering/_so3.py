"""Rotations on the manifold: the exponential and logarithm of SO(3), its left Jacobian, and chi-square(6).

Everything here is small dense numpy (no OpenCV call per frame): the filter runs these a few
times per frame and must cost far less than the detection.
"""

from __future__ import annotations

import math

import numpy as np

from ..frames import matrix_from_quaternion, quaternion_from_matrix
from ..pose._stats import _chi2_isf_even


def skew(v: np.ndarray) -> np.ndarray:
    """The cross-product matrix (3, 3) of ``v`` (3,): ``skew(v) @ u == cross(v, u)``."""
    x, y, z = float(v[0]), float(v[1]), float(v[2])
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of the rotation vector ``w`` (3,), rad (Rodrigues' formula, exact near 0)."""
    th2 = float(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    K = skew(w)
    if th2 < 1e-12:  # second order: the error is th^3 / 6, below 1e-18
        return np.eye(3) + K + 0.5 * (K @ K)
    th = math.sqrt(th2)
    return np.eye(3) + (math.sin(th) / th) * K + ((1.0 - math.cos(th)) / th2) * (K @ K)


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,), rad, of the rotation matrix ``R`` (3, 3): the inverse of :func:`exp_so3`.

    Angles up to pi; near pi the axis comes from the symmetric part (the skew part vanishes there).
    """
    c = max(-1.0, min(1.0, (float(R[0, 0] + R[1, 1] + R[2, 2]) - 1.0) / 2.0))
    v = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s = math.sqrt(float(v @ v))  # sin(angle)
    th = math.atan2(s, c)
    if th < 1e-6:
        return v * (1.0 + th * th / 6.0)
    if th < math.pi - 1e-3:
        return v * (th / s)
    # near pi: sym(R) = c I + (1 - c) a a^T: the axis from the largest column of a a^T
    A = (0.5 * (R + R.T) - c * np.eye(3)) / (1.0 - c)
    k = int(np.argmax(np.diag(A)))
    a = A[:, k] / math.sqrt(max(A[k, k], 1e-300))
    if a @ v < 0:  # the sign that agrees with the (small) skew part
        a = -a
    return a * th


def left_jacobian(w: np.ndarray) -> np.ndarray:
    """Left Jacobian (3, 3) of SO(3) at ``w`` (3,): ``exp(w + d) ~= exp(J_l(w) d) exp(w)``."""
    th2 = float(w @ w)
    K = skew(w)
    if th2 < 1e-12:
        return np.eye(3) + 0.5 * K
    th = math.sqrt(th2)
    return np.eye(3) + ((1.0 - math.cos(th)) / th2) * K + ((th - math.sin(th)) / (th2 * th)) * (K @ K)


def chi2_6_quantile(probability: float) -> float:
    """The ``probability`` quantile of chi-square with 6 degrees of freedom (the closed-form even-dof
    distribution of :mod:`fidlearn.pose`); e.g. 0.99 -> 16.812, 0.999 -> 22.458."""
    return _chi2_isf_even(1.0 - probability, 6)


#: Quaternions are fidlearn.frames' own: (x, y, z, w), canonical w >= 0 (see there).
quaternion_xyzw = quaternion_from_matrix
rotation_from_xyzw = matrix_from_quaternion
