"""Homogeneous transforms, Rodrigues vectors and roll-pitch-yaw angles.

Conventions (see ``docs/conventions.md``):

* ``T_a_b`` is the 4x4 pose of frame *b* expressed in frame *a*, so that
  ``p_a = T_a_b @ p_b`` and names chain:
  ``T_world_marker = T_world_camera @ T_camera_marker``.
* Lengths are millimetres; angles are radians inside the maths and degrees only
  at the edges, in names ending ``_deg``.
* Roll, pitch and yaw are rotations about the *fixed* world X, Y and Z axes,
  applied in that order: ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (ROS REP-103).

Examples
--------
>>> import numpy as np
>>> T_world_camera = make_transform(rotation_from_rpy_deg(0, 0, 90), [1000, 0, 500])
>>> T_camera_world = invert_transform(T_world_camera)
>>> np.allclose(T_world_camera @ T_camera_world, np.eye(4))
True
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import cv2
import numpy as np

from .errors import TransformError

__all__ = [
    "rot_x",
    "rot_y",
    "rot_z",
    "rotation_from_rpy_deg",
    "rpy_deg_from_rotation",
    "make_transform",
    "invert_transform",
    "compose",
    "transform_points",
    "transform_from_rvec_tvec",
    "rvec_tvec_from_transform",
    "check_rotation",
    "check_transform",
    "rotation_angle_deg",
]


def rot_x(angle_rad: float) -> np.ndarray:
    """Rotation matrix (3, 3) about the X axis by ``angle_rad`` (right hand rule)."""
    angle_rad = _angle(angle_rad, "angle_rad")
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle_rad: float) -> np.ndarray:
    """Rotation matrix (3, 3) about the Y axis by ``angle_rad`` (right hand rule)."""
    angle_rad = _angle(angle_rad, "angle_rad")
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle_rad: float) -> np.ndarray:
    """Rotation matrix (3, 3) about the Z axis by ``angle_rad`` (right hand rule)."""
    angle_rad = _angle(angle_rad, "angle_rad")
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def as_float_array(value, name: str, error: type = TransformError) -> np.ndarray:
    """``value`` as a float array, or ``error`` naming ``name`` when it holds something that is no number."""
    if isinstance(value, (str, bytes)):
        raise error(f"{name} is text ({value!r}); give numbers")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise error(f"{name} must hold numbers, got {type(value).__name__} {str(value)[:40]!r}") from None


def _angle(value, name: str) -> float:
    """A finite angle as a float, or TransformError naming it."""
    if isinstance(value, (bool, str, bytes, np.bool_)):
        raise TransformError(f"{name} must be a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError, OverflowError):
        raise TransformError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(out) or abs(out) > 1e9:
        raise TransformError(f"{name} is {out:g}; an angle must be a finite number")
    return out


def _exact_trig_deg(angle_deg: float) -> float:
    return math.radians(_angle(angle_deg, "an angle in degrees (roll, pitch or yaw)"))


def rotation_from_rpy_deg(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """Rotation (3, 3) from roll, pitch, yaw in degrees about the fixed X, Y, Z axes.

    ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``. Multiples of 90 degrees give exact
    zeros and ones, so corner coordinates of markers on walls stay exact.

    >>> np.round(rotation_from_rpy_deg(0, 0, 90) @ [1, 0, 0], 12)
    array([0., 1., 0.])
    """
    R = rot_z(_exact_trig_deg(yaw_deg)) @ rot_y(_exact_trig_deg(pitch_deg)) @ rot_x(_exact_trig_deg(roll_deg))
    R[np.abs(R) < 1e-15] = 0.0  # sin(pi) is 1.2e-16, not 0: keep right angles exact
    return R


def rpy_deg_from_rotation(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw in degrees (3,) of a rotation, inverse of :func:`rotation_from_rpy_deg`.

    Pitch is in [-90, 90]; at pitch = +-90 (gimbal lock) roll is set to 0 and
    the whole rotation about Z is reported as yaw.
    """
    R = check_rotation(R)
    sy = -R[2, 0]
    if abs(sy) >= 1.0 - 1e-12:
        pitch = math.copysign(math.pi / 2, sy)
        roll = 0.0
        yaw = math.atan2(-R[0, 1], R[1, 1])
    else:
        pitch = math.asin(sy)
        roll = math.atan2(R[2, 1], R[2, 2])
        yaw = math.atan2(R[1, 0], R[0, 0])
    return np.degrees([roll, pitch, yaw])


def make_transform(R: np.ndarray | None = None, t: Iterable[float] | None = None) -> np.ndarray:
    """4x4 homogeneous transform from a rotation (3, 3) and a translation (3,) in mm."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = check_rotation(R)
    if t is not None:
        t = as_float_array(t, "translation").reshape(-1)
        if t.shape != (3,):
            raise TransformError(f"translation has {t.size} values, expected 3 (x, y, z)")
        if not np.all(np.isfinite(t)):
            raise TransformError("translation contains NaN or infinity")
        T[:3, 3] = t
    return T


def invert_transform(T_a_b: np.ndarray) -> np.ndarray:
    """Inverse ``T_b_a`` of a rigid transform, in closed form: ``[R^T, -R^T t]``.

    This is exact and cheaper than a general matrix inverse, and it keeps the
    rotation orthonormal.
    """
    T_a_b = check_transform(T_a_b)
    R = T_a_b[:3, :3]
    t = T_a_b[:3, 3]
    T_b_a = np.eye(4)
    T_b_a[:3, :3] = R.T
    T_b_a[:3, 3] = -R.T @ t
    return T_b_a


def compose(*transforms: np.ndarray) -> np.ndarray:
    """Product of rigid transforms, left to right: ``compose(T_a_b, T_b_c) = T_a_c``."""
    if not transforms:
        return np.eye(4)
    out = check_transform(transforms[0])
    for T in transforms[1:]:
        out = out @ check_transform(T)
    return out


def transform_points(T_a_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Map points (N, 3) from frame *b* to frame *a*."""
    T_a_b = check_transform(T_a_b)
    points_b = as_float_array(points_b, "points")
    single = points_b.ndim == 1
    pts = np.atleast_2d(points_b)
    if pts.shape[-1] != 3:
        raise TransformError(f"points have shape {points_b.shape}, expected (N, 3)")
    out = pts @ T_a_b[:3, :3].T + T_a_b[:3, 3]
    return out[0] if single else out


def transform_from_rvec_tvec(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """4x4 transform from OpenCV's Rodrigues vector (3,) and translation (3,).

    ``solvePnP`` returns the rvec/tvec of ``T_camera_world`` (the extrinsic
    matrix), so ``transform_from_rvec_tvec(rvec, tvec)`` is ``T_camera_world``.
    """
    rvec = as_float_array(rvec, "rvec").reshape(-1)
    if rvec.shape != (3,):
        raise TransformError(f"rvec has {rvec.size} values, expected 3 (a Rodrigues vector)")
    if not np.all(np.isfinite(rvec)):
        raise TransformError("rvec contains NaN or infinity")
    R, _ = cv2.Rodrigues(rvec)
    return make_transform(R, tvec)


def rvec_tvec_from_transform(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rodrigues vector (3,) and translation (3,) of a rigid transform."""
    T = check_transform(T)
    R = np.ascontiguousarray(T[:3, :3])
    rvec, _ = cv2.Rodrigues(R)
    rvec = rvec.reshape(3)
    if not rvec.any():
        # cv2.Rodrigues returns exactly zero for every rotation below about 1e-5 rad (4.x and
        # 5.x), which moved projected points by up to 0.02 px on an HD camera. There
        # sin(angle) = angle to 1e-10, so the skew part of R is the rotation vector.
        rvec = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return rvec, T[:3, 3].copy()


def check_rotation(R: np.ndarray, name: str = "R", tol: float = 1e-6) -> np.ndarray:
    """Return ``R`` as a float (3, 3) array, or raise :class:`TransformError` saying what is wrong."""
    R = as_float_array(R, name)
    if R.shape != (3, 3):
        raise TransformError(f"{name} has shape {R.shape}, expected a (3, 3) rotation matrix")
    if not np.all(np.isfinite(R)):
        raise TransformError(f"{name} contains NaN or infinity")
    err = np.abs(R.T @ R - np.eye(3)).max()
    if err > tol:
        raise TransformError(
            f"{name} is not orthonormal (|R^T R - I| = {err:.2g}); a rotation's columns must be "
            "unit vectors at right angles: build it with rotation_from_rpy_deg or cv2.Rodrigues"
        )
    det = np.linalg.det(R)
    if det < 0:
        raise TransformError(
            f"{name} has determinant {det:.3f}: it is a reflection, not a rotation "
            "(one axis is flipped, a left-handed frame); negate one column or fix the axis order"
        )
    return R


def check_transform(T: np.ndarray, name: str = "T", tol: float = 1e-6) -> np.ndarray:
    """Return ``T`` as a float (4, 4) array, or raise :class:`TransformError` saying what is wrong."""
    T = as_float_array(T, name)
    if T.shape != (4, 4):
        raise TransformError(f"{name} has shape {T.shape}, expected a (4, 4) homogeneous transform")
    if not np.all(np.isfinite(T)):
        raise TransformError(f"{name} contains NaN or infinity")
    if np.abs(T[3] - [0.0, 0.0, 0.0, 1.0]).max() > tol:
        raise TransformError(f"{name} has bottom row {np.round(T[3], 6).tolist()}, expected [0, 0, 0, 1]")
    check_rotation(T[:3, :3], name=f"the rotation part of {name}", tol=tol)
    return T


def rotation_angle_deg(R_a: np.ndarray, R_b: np.ndarray | None = None) -> float:
    """Angle in degrees of the rotation ``R_a`` (or of ``R_a^T R_b``, the angle between two)."""

    def rotation(value, name: str) -> np.ndarray:
        M = as_float_array(value, name)
        return check_rotation(M[:3, :3] if M.shape == (4, 4) else M, name)

    R = rotation(R_a, "R_a")
    if R_b is not None:
        R = R.T @ rotation(R_b, "R_b")
    c = (np.trace(R) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))
