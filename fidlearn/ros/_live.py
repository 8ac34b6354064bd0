"""A live view for Foxglove: the frames, poses, path and markers served over Foxglove's WebSocket protocol.

:class:`LiveView` serves on ``ws://127.0.0.1:PORT`` (loopback only) with ``foxglove-sdk``; Foxglove
(the desktop app or app.foxglove.dev) connects with *Open connection* -> *Foxglove WebSocket*. Every
channel carries ROS 2 messages (``ros2msg`` schemas, CDR), the same as :class:`fidlearn.ros.BagWriter`
writes, so Foxglove's 3D panel draws the pose with its covariance, the path, the markers and the TF
tree, and its Image panel the annotated frames.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import cv2
import numpy as np

from ..errors import FidlearnError, RosFormatError
from ..filtering import TrackedPose
from ..markermap import MarkerMap
from ..pose import Pose
from ._bag_out import MARKERS_TOPIC, POSE_TOPIC, TOPICS, marker_array, mount_tf, pose_messages
from ._messages import build, stamp_dict, typestore

IMAGE_TOPIC = "/fidlearn/image/compressed"
PATH_TOPIC = "/fidlearn/path"
LIVE_TOPICS = {
    **TOPICS,
    IMAGE_TOPIC: "sensor_msgs/msg/CompressedImage",
    PATH_TOPIC: "nav_msgs/msg/Path",
}


def _listener(foxglove):
    """A foxglove.ServerListener that notes the first subscription (its ``subscribed`` event)."""

    class Listener(foxglove.ServerListener):
        def __init__(self):
            self.subscribed = threading.Event()

        def on_subscribe(self, client, channel) -> None:  # noqa: ARG002 (the callback's signature)
            self.subscribed.set()

    return Listener()


class LiveView:
    """A Foxglove WebSocket server on this machine's loopback, fed frame by frame.

    Parameters
    ----------
    port : int
        The port (0: any free one; :attr:`port` says which).
    marker_map : MarkerMap, optional
        Sent as markers with every frame (a late viewer sees them too).
    T_camera_base : array_like, shape (4, 4), optional
        The camera's mount (mm), sent on ``/tf_static``.
    camera_frame : str
        The camera's TF frame.

    Raises
    ------
    RosFormatError
        The port is taken or not one, or foxglove-sdk cannot start a server.
    """

    def __init__(
        self, port: int = 8765, marker_map: MarkerMap | None = None, *, T_camera_base=None, camera_frame="camera"
    ):
        import foxglove

        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise RosFormatError(f"the live view's port must be 0 to 65535, got {port!r:.40}")
        self.marker_map, self.mount, self.camera_frame = marker_map, T_camera_base, camera_frame
        self.store = typestore()
        self._context = foxglove.Context()
        self._listener = _listener(foxglove)
        self._channels = {}
        for topic, typename in LIVE_TOPICS.items():
            msgdef, _ = self.store.generate_msgdef(typename, ros_version=2)
            schema = foxglove.Schema(name=typename, encoding="ros2msg", data=msgdef.encode())
            self._channels[topic] = foxglove.Channel(
                topic, schema=schema, message_encoding="cdr", context=self._context
            )
        try:
            self.server = foxglove.start_server(
                name="fidlearn", host="127.0.0.1", port=port, context=self._context, server_listener=self._listener
            )
        except Exception as exc:  # foxglove's own error: the port taken, most often
            raise RosFormatError(
                f"cannot serve the live view on port {port} ({exc}); give another --live PORT"
            ) from None
        self.port = int(self.server.port)
        self.path: list[dict] = []
        self.frames = 0

    @property
    def url(self) -> str:
        """``ws://127.0.0.1:PORT``, what Foxglove's *Open connection* takes."""
        return f"ws://127.0.0.1:{self.port}"

    def wait_for_viewer(self, timeout_s: float) -> bool:
        """Wait until a viewer subscribes to a channel (True), or ``timeout_s`` seconds (False).

        Parameters
        ----------
        timeout_s : float
            The longest wait.

        Returns
        -------
        bool
            Whether a viewer subscribed.
        """
        seen = self._listener.subscribed.wait(timeout_s)
        if seen:
            time.sleep(0.3)  # its other subscriptions, sent with the first, arrive
        return seen

    def _send(self, topic: str, message, stamp_ns: int) -> None:
        data = self.store.serialize_cdr(message, LIVE_TOPICS[topic])
        self._channels[topic].log(bytes(data), log_time=int(stamp_ns))

    def frame(self, stamp_ns: int, image: np.ndarray | None, pose: Pose | TrackedPose | None) -> None:
        """One frame: its annotated image, its pose (with covariance), the path so far, the markers.

        Parameters
        ----------
        stamp_ns : int
            The frame's stamp, nanoseconds.
        image : ndarray or None
            The picture to show (BGR or gray uint8), e.g. with the detections drawn.
        pose : Pose or TrackedPose or None
            The frame's pose; None or one without covariance sends no pose.
        """
        header = {"stamp": stamp_dict(stamp_ns), "frame_id": self.camera_frame}
        if image is not None:
            ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
            if not ok:
                raise FidlearnError("OpenCV could not encode the frame as JPEG")
            msg = build(LIVE_TOPICS[IMAGE_TOPIC], {"header": header, "format": "jpeg", "data": jpeg.reshape(-1)})
            self._send(IMAGE_TOPIC, msg, stamp_ns)
        if self.mount is not None:
            self._send("/tf_static", mount_tf(self.mount, stamp_ns, self.camera_frame), stamp_ns)
        if self.marker_map is not None:
            self._send(MARKERS_TOPIC, marker_array(self.marker_map, stamp_ns), stamp_ns)
        if pose is not None and pose.covariance is not None:
            message: Any
            for topic, message in pose_messages(stamp_ns, pose, self.camera_frame):
                self._send(topic, message, stamp_ns)
                if topic == POSE_TOPIC:
                    self.path.append({"header": {"stamp": stamp_dict(stamp_ns), "frame_id": "map"},
                                      "pose": {"position": _fields(message.pose.pose.position),
                                               "orientation": _fields(message.pose.pose.orientation)}})  # fmt: skip
            path = {"header": {"stamp": stamp_dict(stamp_ns), "frame_id": "map"}, "poses": self.path}
            self._send(PATH_TOPIC, build(LIVE_TOPICS[PATH_TOPIC], path), stamp_ns)
        self.frames += 1

    def close(self) -> None:
        """Stop serving."""
        self.server.stop()


def _fields(message) -> dict:
    """A flat message's fields as a dict (``x``, ``y``, ``z``, ``w``).

    Parameters
    ----------
    message : object
        A rosbags Point or Quaternion.

    Returns
    -------
    dict
        Its numeric fields.
    """
    return {k: float(getattr(message, k)) for k in ("x", "y", "z", "w") if hasattr(message, k)}
