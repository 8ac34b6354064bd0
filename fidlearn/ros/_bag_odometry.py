"""A robot's odometry from a ROS 2 bag: the ``nav_msgs/msg/Odometry`` topic as :class:`fidlearn.ros.Odometry`.

Each message's ``pose.pose`` is the base's pose in the odometry frame (``header.frame_id``, e.g. ``odom``, ->
``child_frame_id``, e.g. ``base_link``), in metres, at its header stamp; the times are seconds from a start
stamp (the first image's, so that they run on the tracked frames' clock). As with the odometry CSV only the
motion between frames is used, with the step uncertainty ``drift``: an odometry message's pose covariance
describes the pose in the drifting odometry frame, not a step, and drivers often leave it zero.
"""

from __future__ import annotations

import contextlib
import os

import numpy as np

from .. import frames
from ..errors import FidlearnError, RosFormatError, TransformError
from ..filtering._so3 import rotation_from_xyzw
from ._bag import COMPRESSED, IMAGE, _broken, _check_path, _check_topic_names, _open, _stamp_ns, _topic
from ._inputs import MAX_ODOMETRY_MM, Odometry

ODOMETRY = "nav_msgs/msg/Odometry"


def _first_stamp(reader, path, image_topic: str) -> int:
    conns = [c for c in reader.connections if c.topic == image_topic]
    for conn, logtime, raw in reader.messages(connections=conns):
        return _stamp_ns(reader.deserialize(raw, conn.msgtype).header, logtime)
    raise RosFormatError(f"{path}: the topic {image_topic} holds no images")


def _samples(reader, path, topic: str) -> dict[int, np.ndarray]:
    """Each message's stamp (ns) and T_odom_base (mm); a later message at the same stamp replaces an earlier one."""
    out: dict[int, np.ndarray] = {}
    conns = [c for c in reader.connections if c.topic == topic]
    for n, (conn, logtime, raw) in enumerate(reader.messages(connections=conns)):
        msg = reader.deserialize(raw, conn.msgtype)
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        t = np.array([p.x, p.y, p.z], dtype=float) * 1000.0
        xyzw = np.array([q.x, q.y, q.z, q.w], dtype=float)
        if not (np.isfinite(t).all() and np.isfinite(xyzw).all()) or np.linalg.norm(xyzw) < 1e-9:
            raise RosFormatError(f"{path} {topic} message {n}: a position or quaternion that is not finite, or zero")
        if np.abs(t).max() > MAX_ODOMETRY_MM:
            raise RosFormatError(
                f"{path} {topic} message {n}: {np.abs(t).max() / 1000:.3g} m from the odometry's origin; "
                f"a robot's odometry stays within {MAX_ODOMETRY_MM / 1e6:g} km of it"
            )
        try:
            R = rotation_from_xyzw(xyzw)
        except TransformError as exc:
            raise RosFormatError(f"{path} {topic} message {n}: {exc}") from None
        out[_stamp_ns(msg.header, logtime)] = frames.make_transform(R, t)
    return out


def read_bag_odometry(
    path: str | os.PathLike,
    topic: str | None = None,
    drift: float = 0.02,
    *,
    image_topic: str | None = None,
    start_ns: int | None = None,
) -> Odometry:
    """The robot's odometry recorded in a ROS 2 bag, on the clock of the bag's images.

    Parameters
    ----------
    path : path-like
        A rosbag2 folder (``metadata.yaml``) or a ``.mcap`` file.
    topic : str, optional
        The ``nav_msgs/msg/Odometry`` topic; default the bag's only one.
    drift : float
        Each step's uncertainty as a fraction of the distance and of the angle moved (see
        :class:`fidlearn.ros.Odometry`).
    image_topic : str, optional
        The image topic whose first stamp is the time origin; default the bag's only one. Ignored with
        ``start_ns``.
    start_ns : int, optional
        The time origin, nanoseconds (default the first image's stamp, as ``fidlearn locate BAG --track``
        times its frames).

    Returns
    -------
    Odometry
        Samples at the messages' header stamps, seconds from the origin (negative before it).

    Raises
    ------
    RosFormatError
        No such bag or topic, several Odometry topics and none chosen, fewer than two messages, a message
        that is no pose (not finite, a zero quaternion), a broken bag.

    Examples
    --------
    >>> read_bag_odometry("no_such.mcap")
    Traceback (most recent call last):
    ...
    fidlearn.errors.RosFormatError: no_such.mcap: no such bag; give a ROS 2 bag folder, a .mcap or a ROS 1 .bag file
    """
    path = _check_path(path)
    _check_topic_names("/odom", topic=topic, image_topic=image_topic)
    if start_ns is not None and (isinstance(start_ns, bool) or not isinstance(start_ns, (int, np.integer))):
        raise RosFormatError(f"start_ns must be a stamp in nanoseconds (an int), got {start_ns!r:.40}")
    with contextlib.closing(_open(path)) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        odo = _topic(topics, (ODOMETRY,), topic, path, "Odometry", "topic")
        if odo is None:
            raise RosFormatError(f"{path}: no nav_msgs/msg/Odometry topic in this bag")
        try:
            if start_ns is None:
                images = _topic(topics, (IMAGE, COMPRESSED), image_topic, path, "image", "image_topic")
                if images is None:
                    raise RosFormatError(f"{path}: no image topic to time the odometry by; give start_ns")
                start_ns = _first_stamp(reader, path, images)
            samples = _samples(reader, path, odo)
        except FidlearnError:
            raise
        except Exception as exc:  # rosbags' and its storage libraries' errors: a file cut short
            raise _broken(path, exc) from None
    if len(samples) < 2:
        raise RosFormatError(f"{path}: the topic {odo} holds {len(samples)} odometry message(s); the motion needs two")
    stamps = sorted(samples)
    times = [(s - int(start_ns)) / 1e9 for s in stamps]
    try:
        return Odometry(times, [samples[s] for s in stamps], drift)
    except RosFormatError as exc:
        raise RosFormatError(f"{path} {odo}: {exc}") from None


__all__ = ["read_bag_odometry", "ODOMETRY"]
