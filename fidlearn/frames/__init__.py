"""Homogeneous transforms, Rodrigues vectors and roll-pitch-yaw angles.

Conventions (see ``docs/conventions.md``):

* ``T_a_b`` is the 4x4 pose of frame *b* expressed in frame *a*, so that
  ``p_a = T_a_b @ p_b`` and names chain:
  ``T_world_marker = T_world_camera @ T_camera_marker``.
* Lengths are millimetres; angles are radians inside the maths and degrees only
  at the edges, in names ending ``_deg``.
* Roll, pitch and yaw are rotations about the *fixed* world X, Y and Z axes,
  applied in that order: ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (ROS REP-103).

* Quaternions are ``(x, y, z, w)``, scalar last (ROS's ``geometry_msgs/Quaternion`` order), unit length,
  returned in the canonical form ``w >= 0`` (``q`` and ``-q`` are the same rotation).

The functions live in five files, imported from here: ``_rotations.py`` (about one axis, roll-pitch-yaw,
angles, rotation vectors), ``_quaternions.py`` (to and from rotation matrices), ``_transforms.py`` (make,
invert, compose, apply, OpenCV's rvec/tvec), ``_look_at.py`` (a camera's pose aimed at a point: camera x right,
y down, z forward) and ``_checks.py`` (the checks that raise :class:`~fidlearn.errors.TransformError`).

Examples
--------
>>> import numpy as np
>>> T_world_camera = make_transform(rotation_from_rpy_deg(0, 0, 90), [1000, 0, 500])
>>> T_camera_world = invert_transform(T_world_camera)
>>> np.allclose(T_world_camera @ T_camera_world, np.eye(4))
True
"""

from __future__ import annotations

from ._checks import check_rotation, check_transform
from ._look_at import look_at
from ._quaternions import matrix_from_quaternion, quaternion_from_matrix
from ._rotations import (
    rot_x,
    rot_y,
    rot_z,
    rotation_angle_deg,
    rotation_from_rpy_deg,
    rpy_deg_from_rotation,
)
from ._transforms import (
    compose,
    invert_transform,
    make_transform,
    rvec_tvec_from_transform,
    transform_from_rvec_tvec,
    transform_points,
)

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
    "quaternion_from_matrix",
    "matrix_from_quaternion",
    "look_at",
]

# The public functions say they are fidlearn.frames': help(), repr() and the docs show the path to import.
for _public in (globals()[_name] for _name in __all__):
    _public.__module__ = __name__
del _public
