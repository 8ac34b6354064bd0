"""A camera driver's bag: images with their CameraInfo (and a robot's odometry) written as a ROS 2 bag.

What a robot records, made from pictures fidlearn renders or reads: the input of ``fidlearn locate BAG`` for
tests, benchmarks and the course, with stamps and a camera that are known.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from .. import frames
from ..camera import Camera
from ..errors import FidlearnError, RosFormatError
from ._bag import info_topic_beside
from ._bag_out import _Bag, _stamp_ns, _transform_dict
from ._camera_info import camera_info_yaml
from ._messages import build, stamp_dict


def write_image_bag(
    path,
    images: Sequence[np.ndarray],
    camera: Camera | None,
    stamps_ns: Sequence[int],
    *,
    image_topic: str = "/camera/image_raw",
    encoding: str = "bgr8",
    frame_id: str = "camera",
    odometry: Sequence[tuple[int, np.ndarray]] | None = None,
    odometry_topic: str = "/odom",
) -> Path:
    """Images (and the camera's CameraInfo beside each) into a ROS 2 bag, as a camera driver records them.

    Parameters
    ----------
    path : path-like
        ``OUT.mcap`` or a new folder (see :class:`BagWriter`).
    images : sequence of ndarray
        uint8 pictures, gray or BGR.
    camera : Camera or None
        Written as ``sensor_msgs/msg/CameraInfo`` on the image topic's ``camera_info`` (None: none).
    stamps_ns : sequence of int
        Each image's header stamp, nanoseconds.
    image_topic : str
        The topic; ``.../compressed`` writes ``sensor_msgs/msg/CompressedImage`` (PNG).
    encoding : str
        ``bgr8``, ``rgb8``, ``mono8`` or ``bayer_rggb8`` (a BGR picture sampled to the mosaic).
    frame_id : str
        The images' ``header.frame_id``.
    odometry : sequence of (int, ndarray (4, 4)), optional
        The robot's odometry, ``(stamp ns, T_odom_base mm)`` per sample, written as ``nav_msgs/msg/Odometry``
        (``odom`` -> ``base_link``, metres) on ``odometry_topic``, as a robot's driver records it.
    odometry_topic : str
        Its topic.

    Returns
    -------
    Path
        The bag.

    Raises
    ------
    RosFormatError
        As for :class:`BagWriter`; an encoding not listed; as many stamps as images needed.
    """
    if encoding not in ("bgr8", "rgb8", "mono8", "bayer_rggb8"):
        raise RosFormatError(f"encoding {encoding!r:.40}: write bgr8, rgb8, mono8 or bayer_rggb8")
    if len(images) != len(stamps_ns):
        raise RosFormatError(f"{len(images)} images and {len(stamps_ns)} stamps: give one stamp per image")
    bag = _Bag(path, "write_image_bag")
    try:
        info_topic = info_topic_beside(image_topic)
        info = _camera_info(camera) if camera is not None else None
        for image, stamp in zip(images, stamps_ns):
            header = {"stamp": stamp_dict(_stamp_ns(stamp)), "frame_id": frame_id}
            typename, msg = _image_message(np.asarray(image), header, encoding, image_topic.endswith("/compressed"))
            bag.put(image_topic, typename, build(typename, msg), stamp)
            if info is not None:
                bag.put(
                    info_topic,
                    "sensor_msgs/msg/CameraInfo",
                    build("sensor_msgs/msg/CameraInfo", {**info, "header": header}),
                    stamp,
                )  # noqa: E501
        for stamp, T in odometry or ():
            bag.put(odometry_topic, "nav_msgs/msg/Odometry", _odometry_message(stamp, T), stamp)
    except BaseException:
        bag.abort()
        raise
    return bag.close()


def _odometry_message(stamp_ns: int, T_odom_base) -> object:
    T = frames.check_transform(T_odom_base, "odometry pose")
    pose = _transform_dict(T)
    return build(
        "nav_msgs/msg/Odometry",
        {
            "header": {"stamp": stamp_dict(_stamp_ns(stamp_ns)), "frame_id": "odom"},
            "child_frame_id": "base_link",
            "pose": {"pose": {"position": pose["translation"], "orientation": pose["rotation"]}},
        },
    )


def _camera_info(camera: Camera) -> dict:
    if not isinstance(camera, Camera):
        raise RosFormatError(f"camera must be a fidlearn Camera or None, got {type(camera).__name__}")
    text = camera_info_yaml(camera)  # the distortion models ROS knows (and fidlearn's refusal of the others)
    model = text.split("distortion_model: ", 1)[1].split("\n", 1)[0]
    d = np.asarray(camera.dist, dtype=float).reshape(-1)
    d = np.r_[d, 0.0] if d.size == 4 and model == "plumb_bob" else d  # equidistant has its own 4
    P = np.hstack([camera.K, np.zeros((3, 1))])
    return {"height": camera.height, "width": camera.width, "distortion_model": model, "d": d,
            "k": camera.K.reshape(-1), "r": np.eye(3).reshape(-1), "p": P.reshape(-1)}  # fmt: skip


def _image_message(image: np.ndarray, header: dict, encoding: str, compressed: bool) -> tuple[str, dict]:
    if image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise RosFormatError("images must be uint8 pictures, gray (H, W) or BGR (H, W, 3)")
    bgr = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if compressed:
        ok, png = cv2.imencode(".png", image)
        if not ok:
            raise FidlearnError("OpenCV could not encode the picture as PNG")
        return "sensor_msgs/msg/CompressedImage", {"header": header, "format": "png", "data": png.reshape(-1)}
    if encoding == "mono8":
        pixels = bgr[:, :, 0] if image.ndim == 2 else cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    elif encoding == "rgb8":
        pixels = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    elif encoding == "bayer_rggb8":
        pixels = np.empty(bgr.shape[:2], np.uint8)  # R G / G B: row 0 red and green, row 1 green and blue
        pixels[0::2, 0::2], pixels[0::2, 1::2] = bgr[0::2, 0::2, 2], bgr[0::2, 1::2, 1]
        pixels[1::2, 0::2], pixels[1::2, 1::2] = bgr[1::2, 0::2, 1], bgr[1::2, 1::2, 0]
    else:
        pixels = bgr
    h, w = pixels.shape[:2]
    step = pixels.strides[0] if pixels.flags.c_contiguous else w * (3 if pixels.ndim == 3 else 1)
    data = np.ascontiguousarray(pixels).reshape(-1)
    msg = {
        "header": header,
        "height": h,
        "width": w,
        "encoding": encoding,
        "is_bigendian": 0,
        "step": step,
        "data": data,
    }
    return "sensor_msgs/msg/Image", msg
