"""Rigid transforms ``T_a_b`` (4, 4): make, invert, compose, apply, and OpenCV's rvec/tvec."""

from __future__ import annotations

from collections.abc import Iterable

import cv2
import numpy as np

from ..errors import TransformError
from ._checks import as_float_array, check_rotation, check_transform
from ._rotations import _rotvec


def make_transform(R: np.ndarray | None = None, t: Iterable[float] | None = None) -> np.ndarray:
    """Homogeneous transform from a rotation and a translation.

    Parameters
    ----------
    R : array-like, shape (3, 3), optional
        Rotation ``R_a_b`` (identity if None).
    t : array-like, shape (3,), optional
        Translation: frame b's origin in frame a, mm (zero if None).

    Returns
    -------
    ndarray, shape (4, 4)
        ``T_a_b = [[R, t], [0, 0, 0, 1]]``.

    Raises
    ------
    TransformError
        ``R`` is not a rotation or ``t`` is not 3 finite numbers.

    Examples
    --------
    >>> make_transform(t=[1000, 0, 500])
    array([[   1.,    0.,    0., 1000.],
           [   0.,    1.,    0.,    0.],
           [   0.,    0.,    1.,  500.],
           [   0.,    0.,    0.,    1.]])
    """
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

    Parameters
    ----------
    T_a_b : array-like, shape (4, 4)
        Rigid transform (frame b in frame a, mm).

    Returns
    -------
    ndarray, shape (4, 4)
        ``T_b_a`` (frame a in frame b, mm).

    Raises
    ------
    TransformError
        ``T_a_b`` is not a rigid transform (see :func:`check_transform`).

    Examples
    --------
    A camera 1 m along world X with yaw 180 (its x axis along world -X): the world
    origin lies 1000 mm along the camera's x axis.

    >>> from fidlearn.frames import rotation_from_rpy_deg
    >>> T_world_camera = make_transform(rotation_from_rpy_deg(0, 0, 180), [1000, 0, 0])
    >>> T_camera_world = invert_transform(T_world_camera)
    >>> T_camera_world[:3, 3].tolist()
    [1000.0, 0.0, 0.0]
    """
    T_a_b = check_transform(T_a_b)
    R = T_a_b[:3, :3]
    t = T_a_b[:3, 3]
    T_b_a = np.eye(4)
    T_b_a[:3, :3] = R.T
    T_b_a[:3, 3] = -R.T @ t
    return T_b_a


def compose(*transforms: np.ndarray) -> np.ndarray:
    """Product of rigid transforms, left to right: ``compose(T_a_b, T_b_c) = T_a_c``.

    Parameters
    ----------
    *transforms : array-like, shape (4, 4)
        Rigid transforms whose frames chain (mm).

    Returns
    -------
    ndarray, shape (4, 4)
        Their product (the identity when none is given).

    Raises
    ------
    TransformError
        One of them is not a rigid transform.

    Examples
    --------
    >>> from fidlearn.frames import rotation_from_rpy_deg
    >>> T_a_b = make_transform(t=[100, 0, 0])
    >>> T_b_c = make_transform(rotation_from_rpy_deg(0, 0, 90), [0, 50, 0])
    >>> compose(T_a_b, T_b_c)[:3, 3].tolist()
    [100.0, 50.0, 0.0]
    """
    if not transforms:
        return np.eye(4)
    out = check_transform(transforms[0])
    for T in transforms[1:]:
        out = out @ check_transform(T)
    return out


def transform_points(T_a_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Map points from frame *b* to frame *a*: ``p_a = R p_b + t``.

    Parameters
    ----------
    T_a_b : array-like, shape (4, 4)
        Rigid transform (frame b in frame a, mm).
    points_b : array-like, shape (N, 3) or (3,)
        Points in frame b, mm.

    Returns
    -------
    ndarray, shape (N, 3) or (3,)
        The same points in frame a, mm (one point in, one point out).

    Raises
    ------
    TransformError
        ``T_a_b`` is not a rigid transform, or the points are not 3D.

    Examples
    --------
    >>> from fidlearn.frames import rotation_from_rpy_deg
    >>> T_world_camera = make_transform(rotation_from_rpy_deg(0, 0, 90), [1000, 0, 500])
    >>> transform_points(T_world_camera, [[100, 0, 0]]).round(9).tolist()
    [[1000.0, 100.0, 500.0]]
    """
    T_a_b = check_transform(T_a_b)
    points_b = as_float_array(points_b, "points")
    single = points_b.ndim == 1
    pts = np.atleast_2d(points_b)
    if pts.shape[-1] != 3:
        raise TransformError(f"points have shape {points_b.shape}, expected (N, 3)")
    out = pts @ T_a_b[:3, :3].T + T_a_b[:3, 3]
    return out[0] if single else out


def transform_from_rvec_tvec(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """Transform from OpenCV's Rodrigues vector and translation.

    ``solvePnP`` returns the rvec/tvec of ``T_camera_world`` (the extrinsic
    matrix), so ``transform_from_rvec_tvec(rvec, tvec)`` is ``T_camera_world``.

    Parameters
    ----------
    rvec : array-like, shape (3,) or (3, 1)
        Rotation vector (axis times angle, radians).
    tvec : array-like, shape (3,) or (3, 1)
        Translation, mm.

    Returns
    -------
    ndarray, shape (4, 4)
        The rigid transform.

    Raises
    ------
    TransformError
        ``rvec`` or ``tvec`` is not 3 finite numbers.

    Examples
    --------
    >>> import numpy as np
    >>> T = transform_from_rvec_tvec([0, 0, np.pi / 2], [10, 20, 30])
    >>> np.round(T[:3, :3] @ [1, 0, 0], 12).tolist(), T[:3, 3].tolist()
    ([0.0, 1.0, 0.0], [10.0, 20.0, 30.0])
    """
    rvec = as_float_array(rvec, "rvec").reshape(-1)
    if rvec.shape != (3,):
        raise TransformError(f"rvec has {rvec.size} values, expected 3 (a Rodrigues vector)")
    if not np.all(np.isfinite(rvec)):
        raise TransformError("rvec contains NaN or infinity")
    R, _ = cv2.Rodrigues(rvec)
    return make_transform(R, tvec)


def rvec_tvec_from_transform(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rodrigues vector and translation of a rigid transform, as ``cv2.solvePnP`` gives them.

    Exact for tiny rotations too (see :func:`_rotvec`).

    Parameters
    ----------
    T : array-like, shape (4, 4)
        Rigid transform, mm (usually ``T_camera_world``).

    Returns
    -------
    rvec : ndarray, shape (3,)
        Rotation vector (axis times angle, radians).
    tvec : ndarray, shape (3,)
        Translation, mm.

    Raises
    ------
    TransformError
        ``T`` is not a rigid transform.

    Examples
    --------
    >>> from fidlearn.frames import rot_z
    >>> rvec, tvec = rvec_tvec_from_transform(make_transform(rot_z(0.5), [10, 20, 30]))
    >>> rvec.round(12).tolist(), tvec.tolist()
    ([0.0, 0.0, 0.5], [10.0, 20.0, 30.0])
    """
    T = check_transform(T)
    return _rotvec(T[:3, :3]), T[:3, 3].copy()
