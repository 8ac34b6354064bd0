"""Checks of rotations and rigid transforms: the matrix as floats, or an error that says what is wrong."""

from __future__ import annotations

import math

import numpy as np

from ..errors import TransformError


def as_float_array(value, name: str, error: type = TransformError) -> np.ndarray:
    """``value`` as a float array, or an error naming ``name`` when it holds something that is no number.

    Parameters
    ----------
    value : array-like
        Numbers of any shape.
    name : str
        What ``value`` is, for the message (e.g. ``"points_world"``).
    error : type
        The :class:`FidlearnError` subclass to raise (default :class:`TransformError`).

    Returns
    -------
    ndarray
        ``value`` as float64, same shape.

    Raises
    ------
    error
        ``value`` is text or holds something that is not a number.

    Examples
    --------
    >>> as_float_array([1, 2, 3], "translation")
    array([1., 2., 3.])
    """
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


def check_rotation(R: np.ndarray, name: str = "R", tol: float = 1e-6) -> np.ndarray:
    """Return ``R`` as a float rotation matrix, or raise :class:`TransformError` saying what is wrong.

    Parameters
    ----------
    R : array-like, shape (3, 3)
        The matrix to check.
    name : str
        What it is, for the message.
    tol : float
        Largest ``|R^T R - I|`` accepted.

    Returns
    -------
    ndarray, shape (3, 3)
        ``R`` as float64.

    Raises
    ------
    TransformError
        Wrong shape, NaN or infinity, not orthonormal, or a reflection (determinant -1).

    Examples
    --------
    >>> import numpy as np
    >>> check_rotation(np.diag([1, 1, -1]))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    fidlearn.errors.TransformError: R has determinant -1.000: it is a reflection, not a rotation ...
    """
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
    """Return ``T`` as a float rigid transform, or raise :class:`TransformError` saying what is wrong.

    Parameters
    ----------
    T : array-like, shape (4, 4)
        The matrix to check.
    name : str
        What it is, for the message (e.g. ``"T_world_camera"``).
    tol : float
        Largest deviation accepted of the bottom row and of the rotation's orthonormality.

    Returns
    -------
    ndarray, shape (4, 4)
        ``T`` as float64.

    Raises
    ------
    TransformError
        Wrong shape, NaN or infinity, bottom row not ``[0, 0, 0, 1]``, or a rotation part
        that is not a rotation.

    Examples
    --------
    >>> import numpy as np
    >>> check_transform(np.eye(3), "T_world_camera")
    Traceback (most recent call last):
    ...
    fidlearn.errors.TransformError: T_world_camera has shape (3, 3), expected a (4, 4) homogeneous transform
    """
    T = as_float_array(T, name)
    if T.shape != (4, 4):
        raise TransformError(f"{name} has shape {T.shape}, expected a (4, 4) homogeneous transform")
    if not np.all(np.isfinite(T)):
        raise TransformError(f"{name} contains NaN or infinity")
    if np.abs(T[3] - [0.0, 0.0, 0.0, 1.0]).max() > tol:
        raise TransformError(f"{name} has bottom row {np.round(T[3], 6).tolist()}, expected [0, 0, 0, 1]")
    check_rotation(T[:3, :3], name=f"the rotation part of {name}", tol=tol)
    return T
