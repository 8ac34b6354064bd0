"""Unit quaternions: to and from rotation matrices, in ROS's (x, y, z, w) order."""

from __future__ import annotations

import math

import numpy as np

from ..errors import TransformError
from ._checks import as_float_array, check_rotation

#: Largest ``| |q| - 1 |`` that :func:`matrix_from_quaternion` accepts (and then divides out).
QUATERNION_NORM_TOL = 1e-3


def quaternion_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(x, y, z, w)`` of a rotation matrix, in canonical form ``w >= 0``.

    A rotation by ``theta`` about the unit axis ``k`` is
    ``q = (k sin(theta/2), cos(theta/2))``, vector part first, scalar last: the
    order of ROS's ``geometry_msgs/Quaternion`` and of ``scipy``'s ``as_quat``.
    ``q`` and ``-q`` are the same rotation (the double cover); this function
    returns the one with ``w >= 0`` (for ``w = 0``, a half turn, the first
    non-zero of ``x, y, z`` is made positive), so equal rotations give equal
    quaternions. Computed with Shepperd's method: the largest of ``w, x, y, z``
    is taken from the diagonal first, so no square root of a tiny number is
    divided by.

    Parameters
    ----------
    R : array-like, shape (3, 3) or (4, 4)
        A rotation ``R_a_b``, or a rigid transform ``T_a_b`` whose rotation part is used.

    Returns
    -------
    ndarray, shape (4,)
        ``[x, y, z, w]``, unit norm, ``w >= 0``; the same rotation ``R_a_b``
        (frame b's orientation in frame a).

    Raises
    ------
    TransformError
        ``R`` is not a rotation matrix or a rigid transform (see :func:`check_rotation`).

    Examples
    --------
    >>> import numpy as np
    >>> Rz90 = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])   # 90 deg about Z
    >>> quaternion_from_matrix(Rz90).round(6).tolist()         # (0, 0, sin 45, cos 45)
    [0.0, 0.0, 0.707107, 0.707107]
    """
    M = as_float_array(R, "R")
    M = check_rotation(M[:3, :3] if M.shape == (4, 4) else M, "R")
    m = M
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    # 4 w^2 = 1 + trace, 4 x^2 = 1 + m00 - m11 - m22, ...: start from the largest
    squares = [1.0 + trace, 1.0 + m[0, 0] - m[1, 1] - m[2, 2], 1.0 - m[0, 0] + m[1, 1] - m[2, 2]]
    squares.append(1.0 - m[0, 0] - m[1, 1] + m[2, 2])
    k = int(np.argmax(squares))
    s = 2.0 * math.sqrt(squares[k])  # 4 * (the largest component)
    if k == 0:
        q = np.array([(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4.0])
    elif k == 1:
        q = np.array([s / 4.0, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s])
    elif k == 2:
        q = np.array([(m[0, 1] + m[1, 0]) / s, s / 4.0, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s])
    else:
        q = np.array([(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4.0, (m[1, 0] - m[0, 1]) / s])
    q /= np.linalg.norm(q)
    if abs(q[3]) <= 1e-12:  # a half turn: w is 0 up to rounding; make the first clear non-zero positive
        q[3] = 0.0
        first = q[:3][np.abs(q[:3]) > 1e-12][0]
        return (q if first > 0 else -q) + 0.0
    return (q if q[3] > 0 else -q) + 0.0  # + 0.0: no negative zeros


def matrix_from_quaternion(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion ``(x, y, z, w)`` (ROS order, scalar last).

    Written out (row by row)::

        [1 - 2(y^2 + z^2),   2(xy - wz),         2(xz + wy)      ]
        [2(xy + wz),         1 - 2(x^2 + z^2),   2(yz - wx)      ]
        [2(xz - wy),         2(yz + wx),         1 - 2(x^2 + y^2)]

    ``q`` and ``-q`` give the same matrix. A quaternion read from a file or a
    message with a few digits is not exactly of unit length: one within
    ``QUATERNION_NORM_TOL`` (1e-3) of 1 is divided by its norm first.

    Parameters
    ----------
    q : array-like, shape (4,)
        ``[x, y, z, w]``: vector part first, scalar ``w`` last; unit length to 1e-3.

    Returns
    -------
    ndarray, shape (3, 3)
        The rotation ``R_a_b`` that ``q`` stands for.

    Raises
    ------
    TransformError
        ``q`` is not 4 finite numbers, or its norm is not 1 within 1e-3 (a ``(w, x, y, z)``
        quaternion is still unit length: the order cannot be checked, only stated).

    Examples
    --------
    >>> import numpy as np
    >>> s = np.sqrt(0.5)
    >>> matrix_from_quaternion([0, 0, s, s]).round(12) + 0.0   # 90 deg about Z
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    v = as_float_array(q, "q")
    if v.shape != (4,) or not np.all(np.isfinite(v)):
        raise TransformError(f"q must be 4 finite numbers [x, y, z, w], got shape {v.shape}: {np.ravel(v)[:8]}")
    norm = float(np.linalg.norm(v))
    if abs(norm - 1.0) > QUATERNION_NORM_TOL:
        raise TransformError(
            f"q = {v.tolist()} has norm {norm:.6g}, not 1: a rotation's quaternion has unit length; "
            "divide it by its norm if it is a scaled rotation, or check that it is [x, y, z, w]"
        )
    x, y, z, w = v / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
