"""ROS 2 bags out: poses as ``geometry_msgs``, ``nav_msgs`` and ``tf2_msgs`` messages, the map as markers.

A bag is written to a hidden folder beside its name and takes its name only when it is closed whole
(:meth:`BagWriter.close`): ``OUT.mcap`` is a lone MCAP file (what Foxglove and ``ros2 bag`` open),
any other name a rosbag2 folder (``metadata.yaml`` and its MCAP file). An existing path is never
written over.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from .. import frames
from .._staged import signals_deferred
from ..errors import RosFormatError
from ..filtering import TrackedPose
from ..filtering._so3 import quaternion_xyzw
from ..markermap import MarkerMap
from ..pose import Pose
from ._messages import build, stamp_dict, typestore
from ._pose import ros_pose

POSE_TOPIC = "/fidlearn/pose"
ODOMETRY_TOPIC = "/fidlearn/odometry"
MARKERS_TOPIC = "/fidlearn/markers"
#: The located frames, drawn (``BagWriter.write_image``): JPEG, as image viewers subscribe to them.
ANNOTATED_TOPIC = "/fidlearn/image_annotated/compressed"
TOPICS = {
    POSE_TOPIC: "geometry_msgs/msg/PoseWithCovarianceStamped",
    ODOMETRY_TOPIC: "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    MARKERS_TOPIC: "visualization_msgs/msg/MarkerArray",
    ANNOTATED_TOPIC: "sensor_msgs/msg/CompressedImage",
}


class _Target:
    """A bag written in a hidden folder beside ``path``, renamed to ``path`` when whole."""

    def __init__(self, path, what: str):
        if isinstance(path, bool) or not isinstance(path, (str, os.PathLike)):
            raise RosFormatError(f"{what}: give a path (a .mcap file or a new folder), got {type(path).__name__}")
        self.path = Path(path)
        self.lone = self.path.suffix.lower() == ".mcap"
        folder = self.path.parent if str(self.path.parent) else Path(".")
        if os.path.lexists(self.path):
            raise RosFormatError(f"{self.path} exists; a bag is never written over: give a new name")
        if not folder.is_dir():
            raise RosFormatError(f"{self.path}: the folder {folder} does not exist; create it first")
        try:
            with signals_deferred():
                self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", dir=folder))
        except OSError as exc:
            raise RosFormatError(f"{self.path}: cannot write in {folder} ({exc.strerror})") from None
        self.bag = self.tmp / (self.path.stem if self.lone else self.path.name)

    def commit(self) -> None:
        with signals_deferred():
            try:
                if self.lone:
                    (inner,) = sorted(self.bag.glob("*.mcap"))
                    os.replace(inner, self.path)
                elif os.path.lexists(self.path):
                    raise RosFormatError(f"{self.path} appeared while the bag was written; it is left as it was")
                else:
                    os.rename(self.bag, self.path)
            except OSError as exc:
                raise RosFormatError(f"{self.path}: cannot write it ({exc.strerror})") from None
            finally:
                shutil.rmtree(self.tmp, ignore_errors=True)

    def abort(self) -> None:
        with signals_deferred():
            shutil.rmtree(self.tmp, ignore_errors=True)


class _Bag:
    """rosbags' writer (MCAP storage) with one connection per topic, messages serialized as CDR."""

    def __init__(self, path, what: str):
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.target = _Target(path, what)
        self.store = typestore()
        self.writer = Writer(self.target.bag, version=8, storage_plugin=StoragePlugin.MCAP)
        self.connections: dict = {}
        self.count = 0
        try:
            self.writer.open()
        except Exception as exc:
            self.target.abort()
            raise RosFormatError(f"{self.target.path}: cannot write it ({exc})") from None

    def put(self, topic: str, typename: str, message, stamp_ns: int) -> None:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, typename, typestore=self.store)
        data = self.store.serialize_cdr(message, typename)
        try:
            self.writer.write(self.connections[topic], int(stamp_ns), data)
        except OSError as exc:
            raise RosFormatError(
                f"{self.target.path}: cannot write it ({exc.strerror}); check the free disk space"
            ) from None
        self.count += 1

    def close(self) -> Path:
        try:
            with signals_deferred():
                self.writer.close()
        except OSError as exc:
            self.target.abort()
            raise RosFormatError(f"{self.target.path}: cannot write it ({exc.strerror})") from None
        self.target.commit()
        return self.target.path

    def abort(self) -> None:
        with contextlib.suppress(Exception):  # the bag is thrown away: an error closing it changes nothing
            self.writer.close()
        self.target.abort()


def _stamp_ns(value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < 2**31 * 10**9:
        raise RosFormatError(
            f"a stamp is a whole number of nanoseconds, 0 to 2^31 s (a ROS time's seconds are an int32: until "
            f"2038), got {value!r:.40}"
        )
    return int(value)


def _transform_dict(T_mm: np.ndarray) -> dict:
    q = quaternion_xyzw(T_mm[:3, :3])
    t = T_mm[:3, 3] / 1000.0
    return {
        "translation": dict(zip("xyz", (float(v) for v in t))),
        "rotation": dict(zip("xyzw", (float(v) for v in q))),
    }


def _tf(stamp_ns: int, parent: str, child: str, T_mm: np.ndarray):
    header = {"stamp": stamp_dict(stamp_ns), "frame_id": parent}
    return build(
        "tf2_msgs/msg/TFMessage",
        {"transforms": [{"header": header, "child_frame_id": child, "transform": _transform_dict(T_mm)}]},
    )


def marker_array(marker_map: MarkerMap, stamp_ns: int = 0, frame_id: str = "map"):
    """The map's markers as a ``visualization_msgs/msg/MarkerArray``: a thin square and its id for each.

    Parameters
    ----------
    marker_map : MarkerMap
        The map (mm; written in metres).
    stamp_ns : int
        The header stamp, nanoseconds.
    frame_id : str
        The frame the markers are placed in.

    Returns
    -------
    object
        The message: namespace ``fidlearn_markers`` (CUBE, the marker's side by its side by 1 mm, at its
        centre, white) and ``fidlearn_marker_ids`` (TEXT_VIEW_FACING with the id), the marker's id as
        each message's id.
    """
    header = {"stamp": stamp_dict(_stamp_ns(stamp_ns)), "frame_id": str(frame_id)}
    markers = []
    for mid in marker_map.ids:
        T = marker_map.T_world_marker(mid)
        c = marker_map.marker_corners(mid)
        side = float(np.linalg.norm(c[1] - c[0])) / 1000.0
        pose = _transform_dict(T)
        pose = {"position": pose["translation"], "orientation": pose["rotation"]}
        markers.append(
            {"header": header, "ns": "fidlearn_markers", "id": int(mid), "type": 1, "pose": pose,
             "scale": {"x": side, "y": side, "z": 0.001}, "color": {"r": 1.0, "g": 1.0, "b": 1.0, "a": 1.0}}
        )  # fmt: skip
        markers.append(
            {"header": header, "ns": "fidlearn_marker_ids", "id": int(mid), "type": 9, "pose": pose,
             "scale": {"z": side / 2}, "color": {"r": 1.0, "g": 0.6, "b": 0.0, "a": 1.0}, "text": str(mid)}
        )  # fmt: skip
    return build("visualization_msgs/msg/MarkerArray", {"markers": markers})


def _twist(tracked: TrackedPose, T_body: np.ndarray) -> tuple[list[float], list[float]]:
    """The body's linear and angular velocity in its own axes (as nav_msgs/Odometry has it), m/s and rad/s."""
    w = np.zeros(3) + np.asarray(tracked.angular_velocity_rad_s, dtype=float)
    v = (
        np.zeros(3)
        + np.asarray(tracked.velocity_mm_s, dtype=float)
        + np.cross(w, T_body[:3, 3] - tracked.T_world_camera[:3, 3])
    )
    R = T_body[:3, :3].T
    lin, ang = R @ v / 1000.0, R @ w
    return [float(x) for x in lin], [float(x) for x in ang]


def mount_tf(T_camera_base, stamp_ns: int, camera_frame: str):
    """The mount as ``tf2_msgs/msg/TFMessage``: ``base_link`` -> the camera's frame (for ``/tf_static``).

    Parameters
    ----------
    T_camera_base : array_like, shape (4, 4)
        The mount (mm).
    stamp_ns : int
        The header stamp, nanoseconds.
    camera_frame : str
        The camera's TF frame.

    Returns
    -------
    object
        The message.
    """
    T_base_camera = frames.invert_transform(frames.check_transform(T_camera_base, "T_camera_base"))
    return _tf(_stamp_ns(stamp_ns), "base_link", camera_frame, T_base_camera)


def pose_messages(stamp_ns: int, pose: Pose | TrackedPose, camera_frame: str = "camera") -> list[tuple[str, object]]:
    """One frame's pose as ROS 2 messages: ``[(topic, message), ...]`` for ``/fidlearn/pose``, ``/tf``, odometry.

    Parameters
    ----------
    stamp_ns : int
        The image's stamp, nanoseconds.
    pose : Pose or TrackedPose
        The frame's pose (a Pose: the camera's) or the tracker's (the robot base's with a mount):
        ``/fidlearn/odometry`` is written for a tracked pose only.
    camera_frame : str
        The camera's TF frame (the child of ``map`` on ``/tf`` without a mount).

    Returns
    -------
    list of (str, object)
        The topics (see :data:`TOPICS` for their types) and rosbags messages: the fields of
        :func:`fidlearn.ros.ros_pose`'s dict, the TF the same position and rotation.

    Raises
    ------
    RosFormatError
        A pose without covariance, a bad stamp.
    """
    stamp_ns = _stamp_ns(stamp_ns)
    tracked = pose if isinstance(pose, TrackedPose) else None
    body = "base_link" if tracked is not None and tracked.T_world_base is not None else "camera_optical_frame"
    msg = ros_pose(pose, stamp_ns / 1e9, body=body)
    child = "base_link" if msg["child_frame_id"] == "base_link" else camera_frame
    types = typestore().types
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                          frame_id=msg["header"]["frame_id"])  # fmt: skip
    p, q = msg["pose"]["pose"]["position"], msg["pose"]["pose"]["orientation"]
    position, rotation = (p["x"], p["y"], p["z"]), (q["x"], q["y"], q["z"], q["w"])
    with_cov = types["geometry_msgs/msg/PoseWithCovariance"](
        pose=types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](*position),
            orientation=types["geometry_msgs/msg/Quaternion"](*rotation),
        ),
        covariance=np.asarray(msg["pose"]["covariance"], dtype=np.float64),
    )
    transform = types["geometry_msgs/msg/Transform"](
        translation=types["geometry_msgs/msg/Vector3"](*position),
        rotation=types["geometry_msgs/msg/Quaternion"](*rotation),
    )
    tf = types["geometry_msgs/msg/TransformStamped"](header=header, child_frame_id=child, transform=transform)
    out = [
        (POSE_TOPIC, types[TOPICS[POSE_TOPIC]](header=header, pose=with_cov)),
        ("/tf", types[TOPICS["/tf"]](transforms=[tf])),
    ]
    if tracked is not None:
        T = np.asarray(tracked.T_world_base if body == "base_link" else pose.T_world_camera, dtype=float)
        lin, ang = _twist(tracked, T)
        twist = types["geometry_msgs/msg/Twist"](
            linear=types["geometry_msgs/msg/Vector3"](*lin), angular=types["geometry_msgs/msg/Vector3"](*ang)
        )
        unknown = np.zeros(36)
        unknown[0] = -1.0
        twist = types["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=unknown)
        odo = types[TOPICS[ODOMETRY_TOPIC]](header=header, child_frame_id=child, pose=with_cov, twist=twist)
        out.append((ODOMETRY_TOPIC, odo))
    return out


class BagWriter:
    """Poses into a ROS 2 bag (MCAP storage), each at its image's stamp; written whole or not at all.

    Topics: ``/fidlearn/pose`` (``geometry_msgs/msg/PoseWithCovarianceStamped``), ``/fidlearn/odometry``
    (``nav_msgs/msg/Odometry``, tracked poses only: the velocities in the body's axes, their covariance
    unknown: -1 first), ``/tf`` (``map`` -> the camera frame, or ``map`` -> ``base_link`` with a mount),
    ``/tf_static`` (``base_link`` -> the camera frame: the mount) and ``/fidlearn/markers``
    (``visualization_msgs/msg/MarkerArray``, the map, once at the first stamp). Metres, REP-103,
    covariances in ROS's order (:func:`fidlearn.ros.ros_covariance`).

    Parameters
    ----------
    path : path-like
        ``OUT.mcap`` (a lone MCAP file) or a new folder (a rosbag2 folder); it must not exist.
    marker_map : MarkerMap, optional
        Written as markers.
    T_camera_base : array_like, shape (4, 4), optional
        The camera's mount on the robot (mm), written on ``/tf_static``.
    camera_frame : str
        The camera's TF frame (the images' ``header.frame_id``).

    Raises
    ------
    RosFormatError
        The path exists or its folder does not.

    Examples
    --------
    >>> import fidlearn, tempfile, os
    >>> from fidlearn.filtering import TrackedPose
    >>> T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with BagWriter(os.path.join(folder, "poses.mcap")) as bag:
    ...         bag.write(1_700_000_000_500_000_000, TrackedPose(0.5, T, np.eye(6), "measured"))
    ...     sorted(os.listdir(folder))
    ['poses.mcap']
    """

    def __init__(self, path, marker_map: MarkerMap | None = None, *, T_camera_base=None, camera_frame="camera"):
        if marker_map is not None and not isinstance(marker_map, MarkerMap):
            raise RosFormatError(f"marker_map must be a fidlearn MarkerMap, got {type(marker_map).__name__}")
        if not isinstance(camera_frame, str) or not camera_frame.strip() or camera_frame.strip() != camera_frame:
            raise RosFormatError(f"camera_frame must be a TF frame name like 'camera', got {camera_frame!r:.40}")
        self.mount = None if T_camera_base is None else frames.check_transform(T_camera_base, "T_camera_base")
        self.marker_map, self.camera_frame = marker_map, camera_frame
        self._bag = _Bag(path, "BagWriter")
        self.path = self._bag.target.path
        self.poses = 0
        self._started = False

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def _start(self, stamp_ns: int) -> None:
        if self._started:
            return
        self._started = True
        if self.mount is not None:
            mount = mount_tf(self.mount, stamp_ns, self.camera_frame)
            self._bag.put("/tf_static", TOPICS["/tf_static"], mount, stamp_ns)
        if self.marker_map is not None:
            self._bag.put(MARKERS_TOPIC, TOPICS[MARKERS_TOPIC], marker_array(self.marker_map, stamp_ns), stamp_ns)

    def write(self, stamp_ns: int, pose: Pose | TrackedPose) -> None:
        """One frame's pose: ``/fidlearn/pose``, ``/tf`` and, for a tracked pose, ``/fidlearn/odometry``.

        Parameters
        ----------
        stamp_ns : int
            The image's stamp, nanoseconds (the messages' header stamp and the bag's time).
        pose : Pose or TrackedPose
            The frame's pose (a Pose: the camera's), or the tracker's (the robot base's with a mount).

        Raises
        ------
        RosFormatError
            A pose without covariance, a bad stamp, a full disk.
        """
        stamp_ns = _stamp_ns(stamp_ns)
        found = pose_messages(stamp_ns, pose, self.camera_frame)
        self._start(stamp_ns)
        for topic, message in found:
            self._bag.put(topic, TOPICS[topic], message, stamp_ns)
        self.poses += 1

    def write_image(self, stamp_ns: int, image: np.ndarray) -> None:
        """One frame drawn (the detections and the pose, see :func:`fidlearn.draw_pose`) on
        ``/fidlearn/image_annotated/compressed`` (``sensor_msgs/msg/CompressedImage``, JPEG) at its image's stamp.

        Parameters
        ----------
        stamp_ns : int
            The image's stamp, nanoseconds.
        image : ndarray, (H, W, 3) BGR or (H, W) gray, uint8
            The drawn frame.

        Raises
        ------
        RosFormatError
            Not a picture, a bad stamp, a full disk.
        """
        import cv2  # noqa: PLC0415 (only when images are written)

        stamp_ns = _stamp_ns(stamp_ns)
        image = np.asarray(image)
        if image.dtype != np.uint8 or image.ndim not in (2, 3) or image.size == 0:
            raise RosFormatError(
                f"write_image takes a uint8 picture (H, W) or (H, W, 3), got {image.dtype} {image.shape}"
            )
        ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
        if not ok:
            raise RosFormatError(f"write_image: OpenCV could not encode a {image.shape} picture as JPEG")
        header = {"stamp": stamp_dict(stamp_ns), "frame_id": self.camera_frame}
        message = build(TOPICS[ANNOTATED_TOPIC], {"header": header, "format": "jpeg", "data": jpeg.reshape(-1)})
        self._start(stamp_ns)
        self._bag.put(ANNOTATED_TOPIC, TOPICS[ANNOTATED_TOPIC], message, stamp_ns)

    def close(self) -> Path:
        """Finish the bag and give it its name.

        Returns
        -------
        Path
            The bag written.

        Raises
        ------
        RosFormatError
            The disk refused; nothing is left behind.
        """
        return self._bag.close()

    def abort(self) -> None:
        """Throw the bag away: nothing is left behind."""
        self._bag.abort()
