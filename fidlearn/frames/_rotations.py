"""Rotations: about one axis, from and to roll-pitch-yaw, their angle and their rotation vector."""

from __future__ import annotations

import math

import cv2
import numpy as np

from ._checks import _angle, as_float_array, check_rotation


def rot_x(angle_rad: float) -> np.ndarray:
    """Rotation matrix about the X axis (right hand rule).

    Parameters
    ----------
    angle_rad : float
        Angle, radians.

    Returns
    -------
    ndarray, shape (3, 3)
        ``R`` such that ``R @ p`` turns the vector ``p`` by ``angle_rad`` about X.

    Raises
    ------
    TransformError
        ``angle_rad`` is not a finite number.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(rot_x(np.pi / 2) @ [0, 1, 0], 12)    # Y turns into Z
    array([0., 0., 1.])
    """
    angle_rad = _angle(angle_rad, "angle_rad")
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle_rad: float) -> np.ndarray:
    """Rotation matrix about the Y axis (right hand rule).

    Parameters
    ----------
    angle_rad : float
        Angle, radians.

    Returns
    -------
    ndarray, shape (3, 3)
        ``R`` such that ``R @ p`` turns the vector ``p`` by ``angle_rad`` about Y.

    Raises
    ------
    TransformError
        ``angle_rad`` is not a finite number.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(rot_y(np.pi / 2) @ [0, 0, 1], 12)    # Z turns into X
    array([1., 0., 0.])
    """
    angle_rad = _angle(angle_rad, "angle_rad")
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle_rad: float) -> np.ndarray:
    """Rotation matrix about the Z axis (right hand rule).

    Parameters
    ----------
    angle_rad : float
        Angle, radians.

    Returns
    -------
    ndarray, shape (3, 3)
        ``R`` such that ``R @ p`` turns the vector ``p`` by ``angle_rad`` about Z.

    Raises
    ------
    TransformError
        ``angle_rad`` is not a finite number.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(rot_z(np.pi / 2) @ [1, 0, 0], 12)    # X turns into Y
    array([0., 1., 0.])
    """
    angle_rad = _angle(angle_rad, "angle_rad")
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _exact_trig_deg(angle_deg: float) -> float:
    return math.radians(_angle(angle_deg, "an angle in degrees (roll, pitch or yaw)"))


def rotation_from_rpy_deg(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """Rotation from roll, pitch, yaw in degrees about the fixed X, Y, Z axes.

    ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``. Multiples of 90 degrees give exact
    zeros and ones, so corner coordinates of markers on walls stay exact.

    Parameters
    ----------
    roll_deg, pitch_deg, yaw_deg : float
        Angles about the fixed X, Y and Z axes, degrees, applied in that order.

    Returns
    -------
    ndarray, shape (3, 3)
        The rotation matrix ``R_a_b`` (columns: frame b's axes in frame a).

    Raises
    ------
    TransformError
        An angle is not a finite number.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(rotation_from_rpy_deg(0, 0, 90) @ [1, 0, 0], 12)
    array([0., 1., 0.])
    """
    R = rot_z(_exact_trig_deg(yaw_deg)) @ rot_y(_exact_trig_deg(pitch_deg)) @ rot_x(_exact_trig_deg(roll_deg))
    R[np.abs(R) < 1e-15] = 0.0  # sin(pi) is 1.2e-16, not 0: keep right angles exact
    return R


def rpy_deg_from_rotation(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw in degrees of a rotation, inverse of :func:`rotation_from_rpy_deg`.

    Pitch is in [-90, 90]; at pitch = +-90 (gimbal lock) roll is set to 0 and
    the whole rotation about Z is reported as yaw.

    Parameters
    ----------
    R : array-like, shape (3, 3)
        A rotation matrix.

    Returns
    -------
    ndarray, shape (3,)
        ``[roll, pitch, yaw]``, degrees, about the fixed X, Y, Z axes.

    Raises
    ------
    TransformError
        ``R`` is not a rotation matrix (see :func:`check_rotation`).

    Examples
    --------
    >>> rpy_deg_from_rotation(rotation_from_rpy_deg(10, -20, 30)).round(6).tolist()
    [10.0, -20.0, 30.0]
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


def rotation_angle_deg(R_a: np.ndarray, R_b: np.ndarray | None = None) -> float:
    """Angle of a rotation, or the angle between two.

    Parameters
    ----------
    R_a : array-like, shape (3, 3) or (4, 4)
        A rotation, or a rigid transform whose rotation part is used.
    R_b : array-like, shape (3, 3) or (4, 4), optional
        A second one: the angle of ``R_a^T R_b`` is returned.

    Returns
    -------
    float
        Degrees, in [0, 180].

    Raises
    ------
    TransformError
        An argument is not a rotation or a rigid transform.

    Examples
    --------
    >>> round(rotation_angle_deg(rotation_from_rpy_deg(0, 0, 30), rotation_from_rpy_deg(0, 0, 75)), 9)
    45.0
    """

    def rotation(value, name: str) -> np.ndarray:
        M = as_float_array(value, name)
        return check_rotation(M[:3, :3] if M.shape == (4, 4) else M, name)

    R = rotation(R_a, "R_a")
    if R_b is not None:
        R = R.T @ rotation(R_b, "R_b")
    c = (np.trace(R) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,), rad, of a rotation matrix (3, 3): the log map, exact for tiny angles too.

    ``cv2.Rodrigues`` returns exactly zero for every rotation below about 1e-5 rad (OpenCV 4.x and
    5.x), which moved projected points by up to 0.02 px on an HD camera. There ``sin(angle) = angle``
    to 1e-10, so the skew part of ``R`` is the rotation vector.
    """
    R = np.ascontiguousarray(R, dtype=np.float64)
    r = cv2.Rodrigues(R)[0].reshape(3)
    if not r.any():
        r = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return r
