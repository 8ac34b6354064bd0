"""Camera files in ROS's ``camera_info`` YAML (the camera_calibration layout), both ways, without a YAML library.

The layout is fixed (``camera_calibration_parsers`` writes it, ``camera_info_manager`` reads it)::

    image_width: 640
    image_height: 480
    camera_name: camera
    camera_matrix:
      rows: 3
      cols: 3
      data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]
    distortion_model: plumb_bob
    distortion_coefficients:
      rows: 1
      cols: 5
      data: [k1, k2, p1, p2, k3]
    rectification_matrix: {rows: 3, cols: 3, data: identity}
    projection_matrix: {rows: 3, cols: 4, data: [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0]}

so a small reader for exactly that (block mappings of scalars and matrices, flow or block
lists, comments) is enough. Pixel convention: ROS's camera_info is OpenCV's (pixel centres at
integers), so K is copied as it is. A ``sensor_msgs/msg/CameraInfo`` message is read through the same
reader (:func:`camera_from_message`).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from .. import _files
from .._io import write_text_atomic
from ..camera import Camera
from ..errors import CameraError, RosFormatError

#: ROS distortion models fidlearn reads and writes, with their number of coefficients. ``equidistant`` is
#: OpenCV's fisheye model (``image_geometry`` calls ``cv::fisheye`` for it): a Camera with ``model="fisheye"``.
MODELS = {"plumb_bob": 5, "rational_polynomial": 8, "equidistant": 4}
#: The largest width, height, rows or cols read (larger image sides are refused by :class:`Camera`).
MAX_COUNT = 1e9
_NAME = re.compile(r"^[A-Za-z0-9_]+$")


def _num(v: float) -> str:
    """The shortest text that reads back to the same float, with a dot in its mantissa: YAML 1.1 (PyYAML, ROS's
    Python ``camera_info_manager``) reads ``1e-05`` as a string, ``1.0e-05`` as a number."""
    text = repr(float(v) + 0.0)
    mantissa, e, exponent = text.partition("e")
    return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text


def _matrix(name: str, rows: int, cols: int, data) -> list[str]:
    return [f"{name}:", f"  rows: {rows}", f"  cols: {cols}", "  data: [" + ", ".join(_num(v) for v in data) + "]"]


def camera_info_yaml(camera: Camera, camera_name: str = "camera") -> str:
    """The camera as ROS ``camera_info`` YAML text (camera_calibration's layout).

    Parameters
    ----------
    camera : Camera
        The camera. A pinhole distortion with 4 or 5 coefficients becomes ``plumb_bob`` (k3 = 0 added), 8
        ``rational_polynomial``; a fisheye camera ``equidistant``; the projection matrix is ``[K | 0]`` and
        the rectification the identity (a single camera).
    camera_name : str
        Letters, digits and underscores (ROS's camera names).

    Returns
    -------
    str
        The YAML text.

    Raises
    ------
    RosFormatError
        A distortion with 12 or 14 coefficients (thin prism, tilt: no ROS model), or a bad name.

    Examples
    --------
    >>> cam = Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], None, (640, 480))
    >>> print(camera_info_yaml(cam).splitlines()[6])
      data: [600.0, 0.0, 319.5, 0.0, 600.0, 239.5, 0.0, 0.0, 1.0]
    """
    if not isinstance(camera, Camera):
        raise RosFormatError(f"expected a fidlearn Camera, got {type(camera).__name__}")
    if not isinstance(camera_name, str) or not _NAME.match(camera_name):
        raise RosFormatError(f"camera_name {camera_name!r}: use letters, digits and underscores only")
    d = np.asarray(camera.dist, dtype=float).reshape(-1)
    if camera.model == "fisheye":
        model: str | None = "equidistant"
    else:
        if d.size == 4:
            d = np.r_[d, 0.0]
        model = {5: "plumb_bob", 8: "rational_polynomial"}.get(d.size)
    if model is None:
        raise RosFormatError(
            f"{camera.source or 'camera'}: {d.size} distortion coefficients (thin prism or tilt) have no ROS "
            "distortion model; ROS knows plumb_bob (5), rational_polynomial (8) and equidistant (fisheye, 4): "
            "calibrate with the 5- or 8-coefficient model for ROS"
        )
    K = camera.K
    P = np.hstack([K, np.zeros((3, 1))])
    lines = [f"image_width: {camera.width}", f"image_height: {camera.height}", f"camera_name: {camera_name}"]
    lines += _matrix("camera_matrix", 3, 3, K.reshape(-1))
    lines.append(f"distortion_model: {model}")
    lines += _matrix("distortion_coefficients", 1, d.size, d)
    lines += _matrix("rectification_matrix", 3, 3, np.eye(3).reshape(-1))
    lines += _matrix("projection_matrix", 3, 4, P.reshape(-1))
    return "\n".join(lines) + "\n"


def save_camera_info(camera: Camera, path: str | os.PathLike, camera_name: str = "camera") -> Path:
    """Write the camera as a ROS ``camera_info`` YAML file, atomically.

    Parameters
    ----------
    camera : Camera
        The camera.
    path : path-like
        The file (``.yaml`` or ``.yml``).
    camera_name : str
        As for :func:`camera_info_yaml`.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    RosFormatError
        As for :func:`camera_info_yaml`.
    """
    text = camera_info_yaml(camera, camera_name)
    return write_text_atomic(_files.as_path(path, RosFormatError, "camera_info YAML file"), text)


# -- reading -------------------------------------------------------------------------------------------
def _strip(line: str) -> str:
    k = line.find("#")
    return (line if k < 0 else line[:k]).rstrip()


def _scalar(text: str):
    t = text.strip().strip("'\"")
    try:
        return float(t) if re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", t) else t
    except ValueError:
        return t


def _flow_list(text: str, source: str, key: str) -> list:
    inner = text.strip()
    if not (inner.startswith("[") and inner.endswith("]")):
        raise RosFormatError(f"{source}: {key}: expected a list [a, b, ...]")
    items = [v for v in inner[1:-1].split(",") if v.strip()]
    return [_scalar(v) for v in items]


def _value(rest: str, lines: list[str], k: int, source: str, key: str):
    """The value after ``key:`` on line ``k`` (a scalar, a list, an inline mapping), or None when a block
    mapping follows; and the index of the value's last line."""
    if rest.startswith("[") and "]" not in rest:  # a flow list over several lines
        while "]" not in rest and k + 1 < len(lines):
            k += 1
            rest += " " + lines[k].strip()
    if rest.startswith("{"):
        parts = [p.partition(":") for p in rest.strip("{} ").split(",")]
        return {p[0].strip(): _scalar(p[2]) for p in parts}, k
    if rest.startswith("["):
        return _flow_list(rest, source, key), k
    if rest:
        return _scalar(rest), k
    if k + 1 < len(lines) and lines[k + 1].strip().startswith("-"):  # a block list
        items = []
        while k + 1 < len(lines) and lines[k + 1].strip().startswith("-"):
            k += 1
            items.append(_scalar(lines[k].strip()[1:]))
        return items, k
    return None, k


def _parse(text: str, source: str) -> dict:
    """The fixed camera_info layout as nested dicts of scalars and lists."""
    lines = [_strip(raw) for raw in text.splitlines()]
    lines = [ln for ln in lines if ln.strip() and ln.strip() != "---" and not ln.startswith("%")]
    out: dict = {}
    stack: list[tuple[int, dict]] = [(-1, out)]
    k = 0
    while k < len(lines):
        line = lines[k]
        indent = len(line) - len(line.lstrip(" "))
        body = line.strip()
        while indent <= stack[-1][0]:
            stack.pop()
        key, sep, rest = body.partition(":")
        if not sep or body.startswith("-"):
            raise RosFormatError(f"{source}: cannot read the line {body!r}; expected 'key: value'")
        value, k = _value(rest.strip(), lines, k, source, key.strip())
        if value is None:
            value = {}
            stack[-1][1][key.strip()] = value
            stack.append((indent, value))
        else:
            stack[-1][1][key.strip()] = value
        k += 1
    return out


def _whole(v, low: float = 1) -> bool:
    """Whether ``v`` (as :func:`_scalar` read it) is a whole number ``>= low`` that fits any camera file."""
    return isinstance(v, float) and math.isfinite(v) and low <= v <= MAX_COUNT and v == int(v)


def _read_matrix(d: dict, key: str, shape, source: str) -> np.ndarray:
    m = d.get(key)
    if not isinstance(m, dict) or "data" not in m:
        raise RosFormatError(f"{source}: missing {key} (rows, cols, data)")
    data = m["data"]
    if not isinstance(data, list) or not all(isinstance(v, float) for v in data):
        raise RosFormatError(f"{source}: {key}.data must be a list of numbers")
    rows: Any = m.get("rows")  # checked next
    cols: Any = m.get("cols")
    for name, v in (("rows", rows), ("cols", cols)):
        if not _whole(v, 0):
            raise RosFormatError(f"{source}: {key}.{name} must be a whole number >= 0, got {v!r}")
    if rows * cols != len(data):
        raise RosFormatError(f"{source}: {key} says rows {rows} x cols {cols} but holds {len(data)} numbers")
    if shape is not None and (int(rows), int(cols)) != shape:
        raise RosFormatError(f"{source}: {key} must be {shape[0]}x{shape[1]}, got {int(rows)}x{int(cols)}")
    return np.array(data, dtype=float).reshape(int(rows), int(cols))


def camera_from_camera_info(text: str, source: str = "camera_info") -> Camera:
    """A camera from ROS ``camera_info`` YAML text (see :func:`load_camera_info`).

    Parameters
    ----------
    text : str
        The YAML text in camera_calibration's layout.
    source : str
        Where it came from, named in messages.

    Returns
    -------
    Camera
        K from ``camera_matrix``, the distortion from ``distortion_coefficients`` and the size from
        ``image_width``, ``image_height`` (the raw image's model: rectification and projection are
        for rectified stereo images and are not used); ``equidistant`` makes a fisheye camera.

    Raises
    ------
    RosFormatError
        A missing field, a matrix of the wrong size, an unknown distortion model.
    CameraError
        Values no camera has (as :class:`fidlearn.Camera` checks them).
    """
    if not isinstance(source, str):
        raise RosFormatError(f"source must be text (where the YAML came from), got {type(source).__name__}")
    if not isinstance(text, str):
        raise RosFormatError(f"{source}: expected the camera_info YAML as text, got {type(text).__name__}")
    d = _parse(text, source)
    for key in ("image_width", "image_height"):
        v = d.get(key)
        if not _whole(v):
            raise RosFormatError(f"{source}: {key} must be a whole number of pixels > 0, got {v!r}")
    model = d.get("distortion_model", "plumb_bob")
    if not isinstance(model, str):
        raise RosFormatError(f"{source}: distortion_model must be a name ({', '.join(MODELS)}), got {model!r}")
    K = _read_matrix(d, "camera_matrix", (3, 3), source)
    dist = _read_matrix(d, "distortion_coefficients", None, source).reshape(-1)
    if model not in MODELS:
        raise RosFormatError(
            f"{source}: distortion_model {model!r} is not one fidlearn reads; it reads {', '.join(MODELS)}"
        )
    if dist.size not in (0, MODELS[model]) and not (model == "plumb_bob" and dist.size == 4):
        raise RosFormatError(f"{source}: {model} has {MODELS[model]} coefficients, the file gives {dist.size}")
    try:
        size = (int(d["image_width"]), int(d["image_height"]))
        lens = "fisheye" if model == "equidistant" else "pinhole"
        return Camera(K, dist if dist.size else None, size, source=source, model=lens)
    except CameraError as exc:
        raise CameraError(f"{source}: {exc}") from None


def load_camera_info(path: str | os.PathLike) -> Camera:
    """Read a ROS ``camera_info`` YAML file (as ``camera_calibration`` writes it) into a Camera.

    Parameters
    ----------
    path : path-like
        The YAML file.

    Returns
    -------
    Camera
        Its ``source`` is the path.

    Raises
    ------
    RosFormatError
        An unreadable or malformed file (see :func:`camera_from_camera_info`).
    CameraError
        Values no camera has.
    """
    path, data = _files.read_bytes(path, RosFormatError, "camera_info YAML file", _files.MAX_TEXT_BYTES)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise RosFormatError(f"{path}: not UTF-8 text; give the camera_info YAML file") from None
    return camera_from_camera_info(text, str(path))


#: Two cameras that put one ray this many pixels apart anywhere in the picture are two calibrations.
AGREE_PX = 1.0


def camera_disagreement(bag_camera: Camera, given: Camera) -> str | None:
    """How ``given`` (a camera file) differs from a bag's CameraInfo camera, or None when they agree.

    They agree when both are for one image size and every pixel of a 9x7 grid over the picture,
    taken back to its ray by ``bag_camera`` and projected again by ``given``, lands within
    :data:`AGREE_PX` of itself: a calibration saved twice (rounded, in another file format) agrees, another
    calibration does not.

    Parameters
    ----------
    bag_camera, given : Camera
        The bag's camera and the one given for it.

    Returns
    -------
    str or None
        What differs, in words, or None.
    """
    if (bag_camera.width, bag_camera.height) != (given.width, given.height):
        bag_size, given_size = (f"{c.width}x{c.height}" for c in (bag_camera, given))
        return f"the CameraInfo is for {bag_size}, the camera given for {given_size}"
    u, v = np.meshgrid(np.linspace(0, bag_camera.width - 1, 9), np.linspace(0, bag_camera.height - 1, 7))
    px = np.column_stack([u.ravel(), v.ravel()])
    from ..calibration.compare import _rays  # noqa: PLC0415 (the rays compare_calibrations takes its grid back to)

    rays = _rays(bag_camera, px)
    seen = np.isfinite(rays).all(axis=1)
    back = given.project(rays[seen], np.eye(4))
    apart = float(np.max(np.linalg.norm(back - px[seen], axis=1), initial=0.0))
    if np.isfinite(apart) and apart <= AGREE_PX:
        return None
    said = ", ".join(
        f"{name} {c.model} fx {c.fx:.1f} fy {c.fy:.1f} cx {c.cx:.1f} cy {c.cy:.1f}"
        for name, c in (("CameraInfo", bag_camera), ("given", given))
    )
    return f"the two cameras put one ray up to {apart:.1f} px apart ({said})"


#: The names ``image_proc`` gives its rectified images: their camera is the CameraInfo's projection P.
RECTIFIED = ("image_rect", "image_rect_color")


def _field(msg, name: str):
    """A CameraInfo's ``k``, ``d`` or ``p``: ROS 1 names them ``K``, ``D`` and ``P``."""
    return getattr(msg, name) if hasattr(msg, name) else getattr(msg, name.upper())


def is_rectified_topic(image_topic: str) -> bool:
    """Whether an image topic carries rectified images, as ``image_proc`` names them.

    Parameters
    ----------
    image_topic : str
        E.g. ``/cam/image_rect``, ``/cam/image_rect_color/compressed``.

    Returns
    -------
    bool
        True for ``image_rect`` and ``image_rect_color`` (with or without ``/compressed``).
    """
    topic = image_topic[: -len("/compressed")] if image_topic.endswith("/compressed") else image_topic
    return topic.rsplit("/", 1)[-1] in RECTIFIED


def camera_from_message(msg, source: str = "CameraInfo", *, rectified: bool = False) -> Camera:
    """A camera from a ``sensor_msgs/msg/CameraInfo`` message (any object with its fields).

    Parameters
    ----------
    msg : object
        With ``width``, ``height``, ``distortion_model``, ``d`` (the coefficients), ``k`` (K, 9
        numbers row-major) and ``p`` (the projection, 12 numbers row-major), as ``rosbags`` or ``rclpy``
        give it.
    source : str
        Named in messages (e.g. the bag and topic).
    rectified : bool
        The camera of rectified images (``image_rect``): the projection's intrinsics ``P[:3, :3]`` and
        no distortion, as ROS's ``image_geometry`` models them. Default the raw image's: K and D.

    Returns
    -------
    Camera
        As :func:`fidlearn.ros.camera_from_camera_info` reads the same fields from YAML.

    Raises
    ------
    RosFormatError
        A distortion model fidlearn does not read, or missing fields.
    CameraError
        An uncalibrated camera (K all zeros) or values no camera has.
    """
    try:
        K = [float(v) for v in np.asarray(_field(msg, "k"), dtype=float).reshape(-1)]
        d = [float(v) for v in np.asarray(_field(msg, "d"), dtype=float).reshape(-1)]
        w, h, model = int(msg.width), int(msg.height), str(msg.distortion_model or "plumb_bob")
        if rectified:
            K = [float(v) for v in np.asarray(_field(msg, "p"), dtype=float).reshape(3, 4)[:, :3].reshape(-1)]
            d, model = [0.0] * 5, "plumb_bob"
    except (AttributeError, TypeError, ValueError):
        raise RosFormatError(f"{source}: not a CameraInfo message (width, height, distortion_model, d, k, p)") from None
    if not any(K):
        raise CameraError(
            f"{source}: the camera is not calibrated ({'P' if rectified else 'K'} is all zeros); give a camera file "
            "(--camera CAMERA on the command line, camera= to read_bag)"
        )
    text = (
        f"image_width: {w}\nimage_height: {h}\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: {K!r}\n"
        f"distortion_model: {model}\ndistortion_coefficients:\n  rows: 1\n  cols: {len(d)}\n  data: {d!r}\n"
    )
    return camera_from_camera_info(text, source)
