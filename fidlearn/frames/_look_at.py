"""``look_at``: the pose of a camera at one point looking at another (camera x right, y down, z forward)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import FidlearnError
from ._checks import as_float_array
from ._rotations import rot_z
from ._transforms import make_transform


def look_at(
    eye_mm: ArrayLike, target_mm: ArrayLike, up: Sequence[float] = (0.0, 0.0, 1.0), roll_deg: float = 0.0
) -> np.ndarray:
    """The pose of a camera at ``eye_mm`` looking at ``target_mm``.

    The camera frame is OpenCV's (x right, y down, z forward); ``up`` (world)
    points up in the image, and ``roll_deg`` then turns the camera about its
    optical axis (positive: clockwise as the image shows it).

    Parameters
    ----------
    eye_mm : array_like, shape (3,)
        The camera's position in the world frame, mm.
    target_mm : array_like, shape (3,)
        The point it looks at, world frame, mm.
    up : array_like, shape (3,)
        The world direction that points up in the image; not parallel to the view direction.
    roll_deg : float
        Turn about the optical axis after aiming, degrees.

    Returns
    -------
    ndarray, shape (4, 4)
        ``T_world_camera``, mm: column 2 of its rotation is the view direction.

    Raises
    ------
    FidlearnError
        If the points are not 3 finite numbers, are the same point, or the view is parallel to ``up``.

    Examples
    --------
    >>> T = look_at([1500, 0, 300], [0, 0, 300])   # 1.5 m in front of the north wall
    >>> T[:3, 2].round(3).tolist()                 # the camera looks along -X
    [-1.0, 0.0, 0.0]
    >>> T[:3, 3].tolist()                          # and stands at the eye
    [1500.0, 0.0, 300.0]
    """
    eye, target = (
        as_float_array(v, name, FidlearnError).reshape(-1)
        for v, name in ((eye_mm, "look_at: eye_mm"), (target_mm, "look_at: target_mm"))
    )
    if eye.shape != (3,) or target.shape != (3,) or not np.all(np.isfinite(eye)) or not np.all(np.isfinite(target)):
        raise FidlearnError(
            f"look_at: eye_mm and target_mm must be 3 finite numbers (x, y, z in mm), got "
            f"{np.shape(eye_mm)} and {np.shape(target_mm)}"
        )
    z = target - eye
    if not np.all(np.isfinite(z)) or math.hypot(*z) < 1e-9:
        what = "the same point" if np.all(np.isfinite(z)) else "too far apart to subtract"
        raise FidlearnError(f"look_at: the eye {eye.tolist()} and the target are {what}; move one of them")
    if np.max(np.abs(z)) > 1e150:  # a far target: scaled first, so that the norm does not overflow
        z /= np.max(np.abs(z))
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, dtype=float))
    if np.linalg.norm(x) < 1e-9:
        raise FidlearnError(
            f"look_at: the view direction {z.round(3).tolist()} is parallel to up={list(up)}; choose another up"
        )
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.column_stack([x, y, z])
    if roll_deg:  # no product for no roll: the rotation keeps the signs of its zeros
        R = R @ rot_z(math.radians(roll_deg))
    return make_transform(R, eye)
