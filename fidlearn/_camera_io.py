"""A camera's files: fidlearn's JSON (``to_dict``/``from_dict``) and the choice of format by suffix.

The OpenCV FileStorage side is :mod:`fidlearn._filestorage`; ROS's camera_info is :mod:`fidlearn.ros`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from . import _files
from ._camera_checks import _ALIASES, CAMERA_FIELDS, _as_size
from ._filestorage import read_filestorage, write_filestorage
from ._io import read_json, write_json_atomic
from .errors import CameraError

__all__: list[str] = []

_FILESTORAGE_SUFFIXES = (".yml", ".yaml", ".xml")


def camera_to_dict(camera: Any) -> dict:
    """fidlearn's JSON layout of a camera (``model`` written only for a fisheye: older readers stay able)."""
    d = {
        "camera_matrix": camera.K.tolist(),
        "dist_coeffs": camera.dist.tolist(),
        "image_size": list(camera.image_size),
        "source": camera.source,
    }
    if camera.model != "pinhole":
        d["model"] = camera.model
    if camera.intrinsics_covariance is not None:  # written only when known: older readers stay able
        d["intrinsics_covariance"] = camera.intrinsics_covariance.tolist()
    return d


#: The longest ``source`` record kept from a camera file (characters).
_SOURCE_CHARS = 300


def camera_from_dict(cls: Any, d: Any, source: str) -> Any:
    """A ``cls`` (Camera) from fidlearn's JSON layout; a file without ``model`` is a pinhole camera."""
    if not isinstance(d, dict):
        raise CameraError(f"{source}: expected a JSON object with camera_matrix, dist_coeffs, image_size")
    if "camera_matrix" not in d and (
        "markers" in d or "units" in d or any(isinstance(v, dict) and "translation" in v for v in d.values())
    ):
        raise CameraError(
            f"{source}: missing field camera_matrix: this is a world map (marker placements), not a camera "
            "file; give the camera file "
            "(camera_matrix, dist_coeffs, image_size, as 'fidlearn calibrate' writes it) as the camera "
            "(command line: --camera) and the map as the map (--map)"
        )
    unknown = [k for k in d if k not in CAMERA_FIELDS]
    if unknown:
        hint = _files.did_you_mean(unknown[0], CAMERA_FIELDS, _ALIASES)
        raise CameraError(
            f"{source}: unknown field {unknown[0]!r}{hint}; a camera file holds {', '.join(CAMERA_FIELDS)}"
        )
    missing = [k for k in ("camera_matrix", "image_size") if k not in d]
    if missing:
        raise CameraError(
            f"{source}: missing field {', '.join(missing)}; a camera file needs camera_matrix (3x3), "
            "dist_coeffs and image_size [width, height]"
        )
    camera = cls(  # checked under the file's name: an error names the file, not what the file says made it
        d["camera_matrix"],
        d.get("dist_coeffs"),
        d["image_size"],
        source=source,
        model=d.get("model", "pinhole"),
        intrinsics_covariance=d.get("intrinsics_covariance"),
    )
    if d.get("source"):  # the record of what made it, one printable line of reasonable length
        text = "".join(ch if ch.isprintable() else " " for ch in str(d["source"]))
        camera.source = text if len(text) <= _SOURCE_CHARS else text[: _SOURCE_CHARS - 3] + "..."
    return camera


def save_camera(camera: Any, path: str | os.PathLike) -> Path:
    """Write ``camera`` to ``path``: OpenCV FileStorage for ``.yml``/``.yaml``/``.xml``, JSON otherwise."""
    path = Path(path)
    if path.suffix.lower() in _FILESTORAGE_SUFFIXES:
        return write_filestorage(path, camera.K, camera.dist, camera.image_size, camera.model)
    return write_json_atomic(path, camera_to_dict(camera))


def load_camera(cls: Any, path: str | os.PathLike, image_size: Any) -> Any:
    """Read a ``cls`` (Camera) from fidlearn's JSON or OpenCV FileStorage (see ``Camera.load``)."""
    path = _files.as_path(path, CameraError, "camera")
    if image_size is not None:
        image_size = _as_size(image_size, str(path))
    if path.suffix.lower() in _FILESTORAGE_SUFFIXES:
        path, K, dist, size, model = read_filestorage(path, image_size)
        return cls(K, dist, size, source=str(path), model=model)
    if path.suffix.lower() in _files.IMAGE_SUFFIXES + _files.VIDEO_SUFFIXES:
        raise CameraError(
            f"{path}: this is an image, not a camera file; give the camera.json that 'fidlearn calibrate' "
            "wrote (or OpenCV's calibration YAML) as the camera, and the image as an image"
        )
    d = read_json(path, CameraError, "camera")
    cam = camera_from_dict(cls, d, str(path))
    if image_size is not None and tuple(image_size) != cam.image_size:
        raise CameraError(
            f"{path}: the file says image_size {list(cam.image_size)}, the caller says {list(image_size)}; "
            "use Camera.scaled() to change resolution"
        )
    return cam
