"""Camera files in OpenCV's FileStorage format (YAML or XML), read with care and written atomically."""

from __future__ import annotations

import difflib
import math
import re
from pathlib import Path

import cv2
import numpy as np

from . import _files
from ._io import atomic_write
from .errors import CameraError

#: Deepest nesting a FileStorage camera file may have (OpenCV's own files have 2); OpenCV's parser
#: recurses once per level and a file nested 100,000 deep crashed the interpreter.
MAX_FILESTORAGE_DEPTH = 16


def _filestorage_text(path: Path, data: bytes) -> str:
    """The file as text, refused before OpenCV parses it when it cannot be a camera file."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise CameraError(
            f"{path}: not UTF-8 text (byte {exc.start}); an OpenCV camera file is YAML or XML text"
        ) from None
    if not text.strip():
        raise CameraError(f"{path}: the file is empty; expected an OpenCV FileStorage camera file")
    head = text.lstrip()[:16]
    if not (head.startswith("%YAML") or head.startswith("<?xml") or head.startswith("<opencv_storage")):
        raise CameraError(f"{path}: not an OpenCV FileStorage file; it should start with %YAML:1.0 or <?xml")
    if head.startswith("%YAML"):
        deepest = _yaml_depth(text)
    else:
        depth = deepest = 0
        for m in re.finditer(r"<(/?)[A-Za-z_][^>]*?(/?)>", text):
            if m.group(1):
                depth -= 1
            elif not m.group(2):
                depth += 1
                deepest = max(deepest, depth)
    if deepest > MAX_FILESTORAGE_DEPTH:
        raise CameraError(
            f"{path}: nested {deepest} levels deep; an OpenCV camera file has 2 or 3 "
            f"({MAX_FILESTORAGE_DEPTH} at most): is it the right file?"
        )
    return text


def _yaml_depth(text: str) -> int:
    """How deep YAML text nests: its brackets, and its block indentation (2 spaces a level), not counting
    brackets in comments or quotes, or the indentation of a bracketed list's continued lines (OpenCV aligns
    a matrix's ``data: [ ... ]`` so)."""
    depth = deepest = 0
    for line in text.splitlines():
        body = line.lstrip(" ")
        if body and not body.startswith("#") and depth == 0:
            deepest = max(deepest, (len(line) - len(body)) // 2)
        quote = None
        for k, ch in enumerate(line):
            if quote is not None:
                quote = None if ch == quote else quote
            elif ch in "\"'":
                quote = ch
            elif ch == "#" and (k == 0 or line[k - 1] in " \t"):
                break
            elif ch in "[{":
                depth += 1
                deepest = max(deepest, depth)
            elif ch in "]}":
                depth = max(depth - 1, 0)
    return deepest


def _filestorage_matrix(node, path: Path, name: str) -> np.ndarray | None:
    """A FileStorage node's matrix, or CameraError when it is not a well-formed !!opencv-matrix."""
    if not node.isMap():
        raise CameraError(
            f"{path}: {name} is not an !!opencv-matrix (a map with rows, cols, dt and data); "
            "write it as OpenCV's calibration sample does"
        )
    dt = node.getNode("dt")
    kind = dt.string() if not dt.empty() and dt.isString() else ""
    if kind not in ("d", "f"):
        raise CameraError(
            f"{path}: {name} has dt: {kind or '?'}; a camera's numbers are real: write dt: d (or f), "
            "as OpenCV's calibration sample does (dt: u would clip them to 0..255)"
        )
    try:
        return node.mat()
    except cv2.error:
        raise CameraError(
            f"{path}: {name} is a malformed !!opencv-matrix: rows x cols must equal the number of values in data"
        ) from None


def _filestorage_pixels(node, path: Path, name: str) -> int:
    """A FileStorage node holding a positive whole number of pixels."""
    value = node.real() if node.isReal() or node.isInt() else None
    if value is None or not math.isfinite(value) or value != int(value):
        raise CameraError(f"{path}: {name} must be a whole number of pixels, e.g. {name}: 640")
    return int(value)


#: Other names tools give OpenCV's FileStorage fields (keys in lower case, ``_`` for ``-`` and spaces).
_FILESTORAGE_ALIASES = {
    **{k: "distortion_coefficients" for k in ("dist_coeffs", "dist_coefs", "distortion", "dist", "d", "distcoeffs")},
    **{k: "camera_matrix" for k in ("k", "intrinsics", "matrix", "cameramatrix", "intrinsic_matrix")},
}


def _spelt(keys: list[str], field: str) -> str:
    """``", but 'dist_coeffs': did you mean 'distortion_coefficients'?"`` when one of the file's ``keys`` is
    another spelling of ``field``, else ``""``."""
    for key in keys:
        norm = key.strip().lower().replace("-", "_").replace(" ", "_")
        named = _FILESTORAGE_ALIASES.get(norm) or _FILESTORAGE_ALIASES.get(norm.replace("_", ""))
        if key != field and (named == field or named is None and difflib.get_close_matches(norm, [field], 1, 0.8)):
            return f", but {key!r}: did you mean {field!r}?"
    return ""


def _filestorage_model(node, path: Path) -> str:
    """The lens model of OpenCV's calibration sample's ``fisheye_model`` (0 or 1; absent: pinhole)."""
    if node.empty():
        return "pinhole"
    value = node.real() if node.isReal() or node.isInt() else None
    if value not in (0, 1):
        raise CameraError(f"{path}: fisheye_model must be 0 (pinhole) or 1 (cv2.fisheye), as OpenCV's sample writes")
    return "fisheye" if value == 1 else "pinhole"


def _lens_nodes(fs, path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """``camera_matrix`` and ``distortion_coefficients`` (None when absent) of an open FileStorage; a misspelt name
    of either is a CameraError naming it (a misspelt distortion would be read as a lens without distortion)."""
    keys = list(fs.root().keys()) if fs.root().isMap() else []
    node_K = fs.getNode("camera_matrix")
    if node_K.empty():
        raise CameraError(
            f"{path}: no camera_matrix field"
            + (_spelt(keys, "camera_matrix") or "; OpenCV's calibration files name it camera_matrix")
        )
    K = _filestorage_matrix(node_K, path, "camera_matrix")
    if K is None:
        raise CameraError(f"{path}: camera_matrix is not an !!opencv-matrix")
    node_d = fs.getNode("distortion_coefficients")
    if node_d.empty() and _spelt(keys, "distortion_coefficients"):
        raise CameraError(
            f"{path}: no distortion_coefficients field{_spelt(keys, 'distortion_coefficients')} (without it "
            "the lens is taken as free of distortion)"
        )
    return K, None if node_d.empty() else _filestorage_matrix(node_d, path, "distortion_coefficients")


def read_filestorage(path, image_size) -> tuple[Path, np.ndarray, np.ndarray | None, tuple[int, int], str]:
    """Read an OpenCV FileStorage camera file (YAML or XML).

    Parameters
    ----------
    path : path-like
        The file.
    image_size : (int, int) or None
        ``(width, height)`` in pixels; required when the file has no ``image_width``/``image_height``,
        and must agree with them when it has.

    Returns
    -------
    path : Path
    K : ndarray, shape (3, 3)
        ``camera_matrix``, pixels.
    dist : ndarray or None
        ``distortion_coefficients``, or None when the file has none.
    image_size : (int, int)
        (width, height), pixels.
    model : str
        ``"fisheye"`` when the file says ``fisheye_model: 1`` (OpenCV's calibration sample), else ``"pinhole"``.

    Raises
    ------
    CameraError
        With the fix: not readable, not FileStorage, nested too deep, a missing or malformed matrix,
        no image size, or one that disagrees with ``image_size``.
    """
    path, data = _files.read_bytes(path, CameraError, "camera", _files.MAX_TEXT_BYTES)
    text = _filestorage_text(path, data)
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except (cv2.error, SystemError) as exc:  # OpenCV 5 wraps parse errors in SystemError
        cause = exc.__cause__ or exc.__context__ or exc
        text = str(cause).strip()
        msg = text.splitlines()[-1].strip() if text else "parse error"
        raise CameraError(
            f"{path}: not a readable OpenCV FileStorage file ({msg}); it should start with %YAML:1.0 or <?xml"
        ) from None
    try:
        if not fs.isOpened():
            raise CameraError(f"{path}: OpenCV cannot open it as FileStorage YAML/XML")
        K, dist = _lens_nodes(fs, path)
        model = _filestorage_model(fs.getNode("fisheye_model"), path)
        w_node, h_node = fs.getNode("image_width"), fs.getNode("image_height")
        file_size = None
        if not w_node.empty() and not h_node.empty():
            file_size = (
                _filestorage_pixels(w_node, path, "image_width"),
                _filestorage_pixels(h_node, path, "image_height"),
            )
    finally:
        fs.release()
    if file_size is None and image_size is None:
        raise CameraError(
            f"{path}: no image_width/image_height; pass image_size=(width, height), the resolution "
            "the camera was calibrated at (the command line: --image-size WxH)"
        )
    if file_size is not None and image_size is not None and tuple(image_size) != file_size:
        raise CameraError(
            f"{path}: the file says {file_size[0]}x{file_size[1]}, the caller says "
            f"{image_size[0]}x{image_size[1]}; use Camera.scaled() to change resolution"
        )
    return path, K, dist, file_size or tuple(image_size), model


def write_filestorage(
    path: Path, K: np.ndarray, dist: np.ndarray, image_size: tuple[int, int], model: str = "pinhole"
) -> Path:
    """Write a camera as OpenCV FileStorage (XML for ``.xml``, YAML otherwise), atomically.

    Parameters
    ----------
    path : Path
        The file to write.
    K : ndarray, shape (3, 3)
        The intrinsic matrix, pixels.
    dist : ndarray
        The distortion coefficients.
    image_size : (int, int)
        (width, height), pixels.
    model : str
        ``"fisheye"`` adds ``fisheye_model: 1``, as OpenCV's calibration sample writes it.

    Returns
    -------
    Path
        The file written.
    """

    def write(tmp: Path) -> None:
        fs = cv2.FileStorage(
            str(tmp),
            cv2.FILE_STORAGE_WRITE
            | (cv2.FILE_STORAGE_FORMAT_XML if path.suffix.lower() == ".xml" else cv2.FILE_STORAGE_FORMAT_YAML),
        )
        fs.write("image_width", int(image_size[0]))
        fs.write("image_height", int(image_size[1]))
        if model == "fisheye":
            fs.write("fisheye_model", 1)
        fs.write("camera_matrix", K)
        fs.write("distortion_coefficients", dist.reshape(1, -1))
        fs.release()

    return atomic_write(path, write)
