"""ROS 2 bags in: the frames of an image topic with their header stamps and the camera of their CameraInfo.

A bag is a rosbag2 folder (``metadata.yaml`` beside its ``.mcap`` or ``.db3`` files), a lone ``.mcap``
file or a ROS 1 ``.bag`` file, read with the pure-Python ``rosbags`` library (no ROS installation). Images are
``sensor_msgs/msg/Image`` (mono8, mono16, bgr8, rgb8, bgra8, rgba8, bayer_rggb8, bayer_bggr8,
bayer_gbrg8, bayer_grbg8, yuv422 (UYVY) and yuv422_yuy2) or ``sensor_msgs/msg/CompressedImage`` (JPEG,
PNG); the camera comes from the ``sensor_msgs/msg/CameraInfo`` beside them, read by the same reader as a
``camera_info`` YAML file (:func:`fidlearn.ros.camera_from_camera_info`), so the distortion models it knows
are the ones a bag may use. Rectified images (``image_proc``'s ``image_rect`` and ``image_rect_color`` topics) have the
CameraInfo's projection P as their camera, without distortion.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import cv2
import numpy as np

from ..camera import Camera
from ..errors import CameraError, FidlearnError, RosFormatError
from ._camera_info import _field, camera_disagreement, camera_from_message, is_rectified_topic
from ._mcap_index import topic_messages
from ._messages import typestore

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
#: A lone bag file: ROS 2's MCAP, or ROS 1's bag format (rosbags reads both; a ROS 1 message's
#: type is named as in ROS 2, ``sensor_msgs/msg/Image``).
BAG_SUFFIXES = (".mcap", ".bag")

#: ``encoding`` -> (channels, bytes per channel, OpenCV conversion to BGR or None).
ENCODINGS: dict[str, tuple[int, int, int | None]] = {
    "mono8": (1, 1, None),
    "8UC1": (1, 1, None),
    "mono16": (1, 2, None),
    "16UC1": (1, 2, None),
    "bgr8": (3, 1, None),
    "8UC3": (3, 1, None),
    "rgb8": (3, 1, cv2.COLOR_RGB2BGR),
    "bgra8": (4, 1, cv2.COLOR_BGRA2BGR),
    "rgba8": (4, 1, cv2.COLOR_RGBA2BGR),
    # ROS names the mosaic by its first row's colours, OpenCV by the second row's (as cv_bridge converts)
    "bayer_rggb8": (1, 1, cv2.COLOR_BayerBG2BGR),
    "bayer_bggr8": (1, 1, cv2.COLOR_BayerRG2BGR),
    "bayer_gbrg8": (1, 1, cv2.COLOR_BayerGR2BGR),
    "bayer_grbg8": (1, 1, cv2.COLOR_BayerGB2BGR),
    # two pixels in four bytes, their colour shared (what usb_cam and v4l2_camera publish): ROS's yuv422 is UYVY
    "yuv422": (2, 1, cv2.COLOR_YUV2BGR_UYVY),
    "uyvy": (2, 1, cv2.COLOR_YUV2BGR_UYVY),
    "yuv422_yuy2": (2, 1, cv2.COLOR_YUV2BGR_YUY2),
    "yuyv": (2, 1, cv2.COLOR_YUV2BGR_YUY2),
}


class BagFrame(NamedTuple):
    """One image of a bag.

    Attributes
    ----------
    stamp : int
        The image's header stamp, nanoseconds since the epoch (the time the bag was recorded at when
        the header has none).
    image : ndarray, shape (H, W) or (H, W, 3)
        The pixels, BGR order (uint8; uint16 for mono16).
    camera : Camera or None
        The camera of the CameraInfo in force at the image (the latest one stamped at or before it,
        else the first); None when the bag has no CameraInfo topic.
    """

    stamp: int
    image: np.ndarray
    camera: Camera | None

    @property
    def t_s(self) -> float:
        """The stamp in seconds."""
        return self.stamp / 1e9


def _check_path(path) -> Path:
    if isinstance(path, bool) or not isinstance(path, (str, os.PathLike)):
        raise RosFormatError(f"a bag is a folder, a .mcap or a ROS 1 .bag file path, got {type(path).__name__}")
    path = Path(path)
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise RosFormatError(f"{path}: a ROS 2 bag folder holds metadata.yaml; this one does not")
    elif not path.exists():
        raise RosFormatError(f"{path}: no such bag; give a ROS 2 bag folder, a .mcap or a ROS 1 .bag file")
    elif path.suffix.lower() not in BAG_SUFFIXES:
        raise RosFormatError(
            f"{path}: not a bag by its name; give a ROS 2 bag folder (metadata.yaml), a .mcap file or a ROS 1 .bag file"
        )
    return path


def is_bag(path) -> bool:
    """Whether a path names a bag: a ROS 2 folder with ``metadata.yaml``, a ``.mcap`` file or a ROS 1 ``.bag`` file.

    Parameters
    ----------
    path : path-like
        The path.

    Returns
    -------
    bool
        True for a bag folder, a ``.mcap`` or a ``.bag`` file (its content is not read).
    """
    p = Path(path)
    return (p.is_dir() and (p / "metadata.yaml").is_file()) or (p.suffix.lower() in BAG_SUFFIXES and not p.is_dir())


def _broken(path: Path, exc: BaseException) -> RosFormatError:
    what = " ".join(str(exc).split())[:200] or type(exc).__name__
    return RosFormatError(
        f"{path}: cannot read this {'ROS 1' if path.suffix.lower() == '.bag' else 'ROS 2'} bag ({what}); "
        "is it whole (was the recording stopped cleanly)?"
    )


def _check_topic_names(example: str, **names) -> None:
    """Each given topic name (keyword: value) a string, else RosFormatError naming the keyword."""
    for name, v in names.items():
        if v is not None and not isinstance(v, str):
            raise RosFormatError(f"{name} must be a topic name like {example!r}, got {type(v).__name__}")


#: The command line's option for each topic argument of read_bag and read_bag_odometry.
_OPTIONS = {"image_topic": "--image-topic", "camera_info_topic": "--camera-info-topic", "topic": "--odometry-topic"}


def _choose(argument: str) -> str:
    """How to choose a topic, on the command line and in Python."""
    return f"choose one with {_OPTIONS[argument]} (in Python: {argument}=)"


def _topic(topics: dict[str, str], types: tuple[str, ...], given: str | None, path: Path, what: str, option: str):
    found = sorted(t for t, typ in topics.items() if typ in types)
    if given is not None:
        if given not in topics:
            raise RosFormatError(
                f"{path}: no topic {given!r} in this bag; its {what} topics: {', '.join(found) or 'none'}"
            )
        if topics[given] not in types:
            raise RosFormatError(f"{path}: topic {given} carries {topics[given]}, not {' or '.join(types)}")
        return given
    if len(found) > 1:
        raise RosFormatError(f"{path}: {len(found)} {what} topics ({', '.join(found)}); {_choose(option)}")
    return found[0] if found else None


def _info_topic(topics: dict[str, str], image_topic: str, given: str | None, path: Path) -> str | None:
    if given is not None:
        return _topic(topics, (CAMERA_INFO,), given, path, "CameraInfo", "camera_info_topic")
    found = sorted(t for t, typ in topics.items() if typ == CAMERA_INFO)
    beside = info_topic_beside(image_topic)
    if beside in found:
        return beside
    if len(found) > 1:
        raise RosFormatError(
            f"{path}: {len(found)} CameraInfo topics ({', '.join(found)}) and none beside {image_topic}; "
            + _choose("camera_info_topic")
        )
    return found[0] if found else None


def info_topic_beside(image_topic: str) -> str:
    """The CameraInfo topic beside an image topic, as image_transport names them.

    Parameters
    ----------
    image_topic : str
        E.g. ``/cam/image_raw`` or ``/cam/image_raw/compressed``.

    Returns
    -------
    str
        ``/cam/camera_info`` for both.
    """
    topic = image_topic[: -len("/compressed")] if image_topic.endswith("/compressed") else image_topic
    return topic.rsplit("/", 1)[0] + "/camera_info"


def _stamp_ns(header, logtime: int) -> int:
    ns = int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
    return ns if ns > 0 else int(logtime)


def decode_image(msg, source: str = "image") -> np.ndarray:
    """The pixels of a ``sensor_msgs/msg/Image`` or ``CompressedImage`` message, BGR order.

    Parameters
    ----------
    msg : object
        An Image (``height``, ``width``, ``encoding``, ``is_bigendian``, ``step``, ``data``) or a
        CompressedImage (``format``, ``data``: JPEG or PNG).
    source : str
        Named in messages.

    Returns
    -------
    ndarray, shape (H, W) or (H, W, 3)
        uint8 (uint16 for mono16), gray or BGR; Bayer mosaics demosaiced.

    Raises
    ------
    RosFormatError
        An encoding fidlearn does not read, or data shorter than the image it says it holds.
    """
    data = np.asarray(msg.data, dtype=np.uint8).reshape(-1)
    if hasattr(msg, "format"):
        image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
        if image is None or "compressedDepth" in str(msg.format):
            raise RosFormatError(f"{source}: a CompressedImage that is not a JPEG or PNG picture ({msg.format!r:.40})")
        return image if image.ndim == 2 else image[:, :, :3]
    enc = str(msg.encoding)
    if enc not in ENCODINGS:
        raise RosFormatError(f"{source}: image encoding {enc!r:.40} is not one fidlearn reads ({', '.join(ENCODINGS)})")
    ch, nbytes, code = ENCODINGS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h <= 0 or w <= 0 or step < w * ch * nbytes or data.size < step * h:
        raise RosFormatError(
            f"{source}: a {w}x{h} {enc} image with step {step} needs {step * h} bytes; the message holds {data.size}"
        )
    if ch == 2 and w % 2:
        raise RosFormatError(f"{source}: a {enc} image holds pixels in pairs; its width {w} is odd")
    rows = data[: step * h].reshape(h, step)[:, : w * ch * nbytes]
    if nbytes == 2:
        rows = np.ascontiguousarray(rows).view(">u2" if msg.is_bigendian else "<u2").astype(np.uint16)
    image = np.ascontiguousarray(rows.reshape(h, w, ch) if ch > 1 else rows.reshape(h, w))
    return cv2.cvtColor(image, code) if code is not None else image


class BagFrames:
    """The frames of one image topic of a ROS 2 bag, read one at a time (see :func:`read_bag`).

    Attributes
    ----------
    path : Path
        The bag.
    image_topic : str
        The topic read.
    camera_info_topic : str or None
        The CameraInfo topic the cameras come from; None when there is none.
    count : int
        The number of image messages on the topic.
    frame_id : str or None
        The images' ``header.frame_id`` (the camera's TF frame), known once the first image is read.
    """

    def __init__(self, path: Path, image_topic: str, camera_info_topic: str | None, count: int):
        self.path, self.image_topic, self.camera_info_topic, self.count = path, image_topic, camera_info_topic, count
        self.frame_id: str | None = None
        self.given: Camera | None = None  # a camera file's camera, standing in for the CameraInfo
        self._cameras: list[tuple[int, Camera]] | None = None
        self._store: Any = None  # the typestore, message types and counts read_bag found (an indexed MCAP file
        self._types: dict[str, str] = {}  # is read without a reader, its index checked against the counts)
        self._counts: dict[str, int] = {}

    def __repr__(self) -> str:
        return f"BagFrames({str(self.path)!r}, {self.image_topic!r}, {self.count} images)"

    def __len__(self) -> int:
        return self.count

    def cameras(self) -> list[tuple[int, Camera]]:
        """Every CameraInfo of the topic as ``(stamp ns, Camera)``, in stamp order (empty without a topic).

        Read once (when :func:`read_bag` checks them) and kept.

        Returns
        -------
        list of (int, Camera)
            Consecutive equal calibrations share one Camera.

        Raises
        ------
        RosFormatError
            An unreadable bag or CameraInfo.
        """
        if self.camera_info_topic is None:
            return []
        if self._cameras is None:
            self._cameras = self._read_cameras(None)
        return list(self._cameras)

    def _read_cameras(self, reader) -> list[tuple[int, Camera]]:
        if self.camera_info_topic is None:
            return []
        out: list[tuple[int, Camera]] = []
        seen: dict[tuple, Camera] = {}
        source = f"{self.path.name} {self.camera_info_topic}"
        rectified = is_rectified_topic(self.image_topic)
        for msg, logtime in self._messages(self.camera_info_topic, reader):
            k, d = _field(msg, "p" if rectified else "k"), _field(msg, "d")
            if self.given is not None and not np.any(np.asarray(k, dtype=float)):
                continue  # uncalibrated, as a driver publishes before calibration: the given camera stands in
            key = (msg.width, msg.height, str(msg.distortion_model), tuple(k), tuple(d))
            if key not in seen:
                seen[key] = camera_from_message(msg, source, rectified=rectified)
                differs = None if self.given is None else camera_disagreement(seen[key], self.given)
                if differs is not None:
                    raise CameraError(
                        f"{source}: the camera given is not the bag's: {differs}; give the camera these images "
                        "were taken with, or leave it out to use the bag's CameraInfo"
                    )
            out.append((_stamp_ns(msg.header, logtime), seen[key]))
        return sorted(out, key=lambda sc: sc[0])

    def _messages(self, topic: str, reader=None) -> Iterator[tuple[Any, int]]:
        """The topic's messages, deserialized, with their log times (from ``reader`` if open, else a new one)."""
        try:
            with contextlib.ExitStack() as stack:
                indexed = _indexed(self.path, topic, self._counts, stack) if self._store is not None else None
                if indexed is not None:
                    deserialize, msgtype = self._store.deserialize_cdr, self._types[topic]
                    for logtime, raw in indexed:
                        yield deserialize(raw, msgtype), logtime
                    return
                bag = reader if reader is not None else stack.enter_context(contextlib.closing(_open(self.path)))
                conns = [c for c in bag.connections if c.topic == topic]
                for conn, logtime, raw in bag.messages(connections=conns):
                    yield bag.deserialize(raw, conn.msgtype), logtime
        except (FidlearnError, GeneratorExit, KeyboardInterrupt):
            raise
        except Exception as exc:  # rosbags' and its storage libraries' errors: a file cut short or not a bag
            raise _broken(self.path, exc) from None

    def __iter__(self) -> Iterator[BagFrame]:
        cameras = self.cameras()
        k = 0
        for n, (msg, logtime) in enumerate(self._messages(self.image_topic)):
            stamp = _stamp_ns(msg.header, logtime)
            if self.frame_id is None:
                self.frame_id = str(msg.header.frame_id)
            while k + 1 < len(cameras) and cameras[k + 1][0] <= stamp:
                k += 1
            image = decode_image(msg, f"{self.path.name} {self.image_topic} message {n}")
            yield BagFrame(stamp, image, self.given or (cameras[k][1] if cameras else None))


def _indexed(path: Path, topic: str, counts: dict, stack: contextlib.ExitStack) -> Iterator[tuple[int, bytes]] | None:
    """A lone MCAP file's ``(log time, CDR bytes)`` on ``topic`` read by its index (the file closed with ``stack``);
    None for other bags, for MCAP files without an index or with compressed chunks, and when the index does not
    hold as many of the topic's messages as the bag says it has."""
    if path.suffix.lower() != ".mcap" or not path.is_file() or topic not in counts:
        return None
    return topic_messages(stack.enter_context(open(path, "rb")), topic, counts[topic])


def read_bag(
    path: str | os.PathLike,
    image_topic: str | None = None,
    camera_info_topic: str | None = None,
    camera: Camera | None = None,
) -> BagFrames:
    """The frames of a ROS 2 bag: each image with its header stamp and its camera, in the order recorded.

    Parameters
    ----------
    path : path-like
        A rosbag2 folder (with ``metadata.yaml``; MCAP or SQLite3 storage) or a ``.mcap`` file.
    image_topic : str, optional
        The ``sensor_msgs/msg/Image`` or ``CompressedImage`` topic; default the bag's only one.
    camera_info_topic : str, optional
        The ``sensor_msgs/msg/CameraInfo`` topic; default the one beside the image topic
        (``/cam/image_raw`` -> ``/cam/camera_info``), else the bag's only one, else none. The images of
        an ``image_rect`` or ``image_rect_color`` topic (``image_proc``'s) are rectified: their camera is
        the CameraInfo's projection ``P[:3, :3]``, without distortion.
    camera : Camera, optional
        A camera file's camera for the images, then every frame's camera. The bag's CameraInfo must agree with
        it (one ray within 1 px anywhere in the picture); an uncalibrated CameraInfo (K all zeros) is skipped.

    Returns
    -------
    BagFrames
        Iterable (once or more) of :class:`BagFrame` ``(stamp, image, camera)``. The bag, its topics
        and its CameraInfo are checked at the call, before any image is read.

    Raises
    ------
    RosFormatError
        No such bag, a broken file, no image topic (or several and none chosen), a topic of another
        type, a bag with no image messages, an image encoding or distortion model fidlearn does not read.
    CameraError
        A CameraInfo no camera has (uncalibrated: K all zeros, without ``camera``), or one that is not
        ``camera``.

    Examples
    --------
    >>> frames = read_bag("no_such.mcap")
    Traceback (most recent call last):
    ...
    fidlearn.errors.RosFormatError: no_such.mcap: no such bag; give a ROS 2 bag folder, a .mcap or a ROS 1 .bag file
    """
    path = _check_path(path)
    _check_topic_names("/camera/image_raw", image_topic=image_topic, camera_info_topic=camera_info_topic)
    if camera is not None and not isinstance(camera, Camera):
        raise CameraError(f"camera={camera!r}: give a fidlearn.Camera (fidlearn.Camera.load(path) reads a file)")
    with contextlib.closing(_open(path)) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        counts: dict[str, int] = {}
        for c in reader.connections:
            counts[c.topic] = counts.get(c.topic, 0) + int(c.msgcount)
        topic = _topic(topics, (IMAGE, COMPRESSED), image_topic, path, "image", "image_topic")
        if topic is None:
            raise RosFormatError(f"{path}: no sensor_msgs/msg/Image or CompressedImage topic in this bag")
        if counts.get(topic, 0) == 0:
            raise RosFormatError(f"{path}: the topic {topic} holds no images")
        frames = BagFrames(path, topic, _info_topic(topics, topic, camera_info_topic, path), counts[topic])
        frames._store, frames._types, frames._counts = reader.typestore, topics, counts
        frames.given = camera
        frames._cameras = frames._read_cameras(reader)  # checked now: an unknown camera before any image
    return frames


#: rosbags' typestores made from bags' own message definitions, by those definitions: a bag opened
#: again (read_bag checks it, then its frames are read) deserializes with the code compiled the first time.
_STORES: dict[tuple, Any] = {}


def _open(path: Path):
    """An open rosbags AnyReader (to close), or the bag's error said plainly."""
    from rosbags.highlevel import AnyReader

    reader = None
    try:
        reader = AnyReader([path], default_typestore=typestore())
        reader.open()
    except Exception as exc:  # not a bag, cut short, an unknown storage
        # rosbags 0.11.0 leaves the file of the reader that failed to open; closed here
        for part in getattr(reader, "readers", ()):
            with contextlib.suppress(Exception):
                part.close()
        raise _broken(path, exc) from None
    key = tuple(sorted({(c.msgtype, str(c.msgdef.format), c.msgdef.data, c.digest) for c in reader.connections}))
    if key in _STORES:
        reader.typestore = _STORES[key]
    else:
        if len(_STORES) >= 8:
            _STORES.pop(next(iter(_STORES)), None)
        _STORES[key] = reader.typestore
    return reader
