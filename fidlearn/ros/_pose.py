"""Poses in ROS's conventions (REP-103, REP-105) and TUM trajectory files."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .. import _files, frames
from .._io import write_text_atomic
from ..errors import RosFormatError
from ..filtering import TrackedPose
from ..filtering._so3 import quaternion_xyzw
from ..pose import Pose

#: ``R_optical_link``: REP-103's camera body axes (x forward, y left, z up) in the optical frame
#: (OpenCV's and fidlearn's camera frame: x right, y down, z forward).
R_OPTICAL_LINK = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])

#: The frames a pose can be given for (the ``child`` of the ``map`` frame).
BODIES = ("base_link", "camera_optical_frame", "camera_link")


def _body_pose(pose, body: str | None) -> tuple[np.ndarray, np.ndarray, str]:
    """``(T_world_body (4, 4) mm, covariance (6, 6) fidlearn order, body name)``."""
    if not isinstance(pose, (TrackedPose, Pose)):
        raise RosFormatError(f"expected a fidlearn TrackedPose or Pose, got {type(pose).__name__}")
    base = getattr(pose, "T_world_base", None)
    if body is None:
        body = "base_link" if base is not None else "camera_optical_frame"
    if not isinstance(body, str) or body not in BODIES:
        raise RosFormatError(f"body {body!r:.40} is not one of {', '.join(BODIES)}")
    if pose.covariance is None:
        raise RosFormatError("this pose has no covariance (not determined); ROS's message needs one")
    if body == "base_link":
        if base is None or not isinstance(pose, TrackedPose):  # a Pose has no base
            raise RosFormatError(
                "base_link needs the mount: give the tracker T_camera_base (the command line: --mount mount.json), "
                "or ask for camera_optical_frame or camera_link"
            )
        return base, np.asarray(pose.base_covariance, dtype=float), body
    T = np.asarray(pose.T_world_camera, dtype=float)
    if body == "camera_link":  # a pure rotation about the camera centre: same error coordinates
        T = T.copy()
        T[:3, :3] = T[:3, :3] @ R_OPTICAL_LINK
    return T, np.asarray(pose.covariance, dtype=float), body


def ros_covariance(covariance: np.ndarray) -> list[float]:
    """fidlearn's 6x6 pose covariance as ROS's 36 numbers (row-major, order x, y, z, rotX, rotY, rotZ; m, rad).

    Parameters
    ----------
    covariance : array_like, shape (6, 6)
        ``[dtheta (rad, world axes), position (mm, world)]``, as :attr:`fidlearn.Pose.covariance`.

    Returns
    -------
    list of float
        36 numbers, row-major: position first, in m^2, m rad and rad^2; the rotations about the
        fixed (world, ``map``) axes, as ``geometry_msgs/PoseWithCovariance`` says.

    Raises
    ------
    RosFormatError
        Not a 6x6 array of finite numbers.

    Examples
    --------
    >>> c = ros_covariance(np.diag([1e-4, 1e-4, 1e-4, 4.0, 9.0, 16.0]))
    >>> [round(c[k * 7], 12) for k in range(6)]
    [4e-06, 9e-06, 1.6e-05, 0.0001, 0.0001, 0.0001]
    """
    try:
        C = np.asarray(covariance, dtype=float)
    except (TypeError, ValueError, OverflowError):
        C = np.zeros(0)
    if C.shape != (6, 6) or not np.isfinite(C).all():
        raise RosFormatError("a pose covariance must be a 6x6 array of finite numbers")
    order = [3, 4, 5, 0, 1, 2]
    scale = np.array([1e-3, 1e-3, 1e-3, 1.0, 1.0, 1.0])  # mm -> m on the position rows and columns
    out = C[np.ix_(order, order)] * np.outer(scale, scale)
    return [float(v) for v in out.reshape(-1)]


def _stamp(t_s: float) -> dict:
    if not (isinstance(t_s, (int, float, np.integer, np.floating)) and math.isfinite(t_s) and t_s >= 0):
        raise RosFormatError(f"a ROS time stamp must be a finite time >= 0 s, got {t_s!r}")
    sec = math.floor(t_s)
    nanosec = int(round((t_s - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return {"sec": int(sec), "nanosec": nanosec}


def ros_pose(pose, t_s: float | None = None, *, body: str | None = None, frame_id: str = "map") -> dict:
    """A pose as ``geometry_msgs/PoseWithCovarianceStamped``, as a plain dict (ROS 2 field names).

    REP-103 axes (the world is already right-handed, Z up), REP-105 frames (``map`` ->
    ``base_link``), metres, radians, quaternion ``(x, y, z, w)`` with ``w >= 0``.

    Parameters
    ----------
    pose : TrackedPose or Pose
        The pose (mm). A :class:`~fidlearn.filtering.TrackedPose` carries its time.
    t_s : float, optional
        The stamp, seconds (default the TrackedPose's ``t_s``; required for a Pose).
    body : str, optional
        Whose pose: ``"base_link"`` (the robot, needs the tracker's mount), ``"camera_optical_frame"``
        (the camera frame of OpenCV and fidlearn: x right, y down, z forward) or ``"camera_link"``
        (REP-103's camera body: x forward, y left, z up). Default base_link when the mount is known,
        else camera_optical_frame.
    frame_id : str
        The header's frame, REP-105's ``map`` by default (the fidlearn world).

    Returns
    -------
    dict
        ``{"header": {"stamp": {"sec", "nanosec"}, "frame_id"}, "pose": {"pose": {"position": {x, y, z},
        "orientation": {x, y, z, w}}, "covariance": [36 floats]}}`` plus ``"child_frame_id"`` (the body,
        not part of the message: where the pose is of).

    Raises
    ------
    RosFormatError
        An unknown body, base_link without a mount, no time, or a pose without covariance.

    Examples
    --------
    >>> import fidlearn
    >>> from fidlearn.filtering import TrackedPose
    >>> T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])
    >>> msg = ros_pose(TrackedPose(12.5, T, np.eye(6), "measured"))
    >>> msg["pose"]["pose"]["position"], msg["pose"]["pose"]["orientation"]
    ({'x': 1.0, 'y': 0.15, 'z': 0.25}, {'x': -0.5, 'y': -0.5, 'z': 0.5, 'w': 0.5})
    """
    T, cov, body = _body_pose(pose, body)
    if t_s is None:
        t_s = getattr(pose, "t_s", None)
        if t_s is None:
            raise RosFormatError("a Pose has no time: give t_s")
    x, y, z = (float(v) / 1000.0 for v in T[:3, 3])
    qx, qy, qz, qw = (float(v) for v in quaternion_xyzw(T[:3, :3]))
    return {
        "header": {"stamp": _stamp(t_s), "frame_id": str(frame_id)},
        "child_frame_id": body,
        "pose": {
            "pose": {"position": {"x": x, "y": y, "z": z}, "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}},
            "covariance": ros_covariance(cov),
        },
    }


def tum_line(t_s: float, T_world_body: np.ndarray) -> str:
    """One line of a TUM trajectory: ``t x y z qx qy qz qw`` (seconds, metres, quaternion w last, w >= 0).

    Parameters
    ----------
    t_s : float
        The time, seconds.
    T_world_body : array_like, shape (4, 4)
        The pose, mm (written in metres).

    Returns
    -------
    str
        The line, without its newline; 9 decimals for times and metres, 12 for the quaternion.

    Raises
    ------
    RosFormatError
        A time or pose that is not finite.

    Examples
    --------
    >>> tum_line(1.5, np.diag([1.0, -1.0, -1.0, 1.0]))   # turned 180 degrees about x, at the origin
    '1.500000000 0.000000000 0.000000000 0.000000000 1.000000000000 0.000000000000 0.000000000000 0.000000000000'
    """
    if isinstance(t_s, bool) or not isinstance(t_s, (int, float, np.integer, np.floating)) or not abs(t_s) < 1e12:
        raise RosFormatError(f"a TUM line needs a finite time in seconds (at most 1e12), got {t_s!r:.40}")
    T = frames.check_transform(T_world_body, "T_world_body")
    q = quaternion_xyzw(T[:3, :3])
    p = T[:3, 3] / 1000.0 + 0.0
    return f"{float(t_s):.9f} " + " ".join(f"{v:.9f}" for v in p) + " " + " ".join(f"{v:.12f}" for v in q)


def write_tum(path: str | os.PathLike, poses: Sequence, *, body: str | None = None) -> Path:
    """Write a TUM trajectory file (``# timestamp tx ty tz qx qy qz qw`` then one line per pose), atomically.

    Parameters
    ----------
    path : path-like
        The file (``.txt`` or ``.tum`` by custom).
    poses : sequence of TrackedPose
        The poses, in time order.
    body : str, optional
        As for :func:`ros_pose` (default base_link with a mount, else camera_optical_frame).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    RosFormatError
        Poses that are not a list of TrackedPose; else as for :func:`ros_pose`.
    """
    if isinstance(poses, (str, bytes, dict)) or not hasattr(poses, "__iter__"):
        raise RosFormatError(f"poses must be a list of TrackedPose, got {type(poses).__name__}")
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    for p in poses:
        if not isinstance(p, TrackedPose):
            raise RosFormatError(f"a TUM file is written from TrackedPose (they carry t_s), got {type(p).__name__}")
        T, _, _ = _body_pose(p, body)
        lines.append(tum_line(p.t_s, T))
    return write_text_atomic(_files.as_path(path, RosFormatError, "TUM file"), "\n".join(lines) + "\n")
