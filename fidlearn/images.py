"""Reading pictures and videos: image files, folders of them, video files and live cameras.

Everything fidlearn reads as pixels comes through here: :func:`load_image` for one
picture (checked from its header before a pixel is decoded), :func:`expand_inputs`
for the files and folders a command line names, and :func:`read_frames` for the
frames of all of them, videos and a live camera included.

Pixel convention: OpenCV's (BGR order, the centre of the top-left pixel is (0, 0)).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np

from . import _cv, _files
from ._files import IMAGE_SUFFIXES, VIDEO_SUFFIXES
from ._io import atomic_write
from .errors import FidlearnError, FidlearnWarning, ImageError, UsageError

__all__ = [
    "IMAGE_SUFFIXES",
    "VIDEO_SUFFIXES",
    "Frame",
    "load_image",
    "as_gray",
    "write_image",
    "expand_inputs",
    "open_capture",
    "declared_frames",
    "read_capture",
    "read_frames",
]


class Frame(NamedTuple):
    """One picture to work on, from a file, a video or a camera.

    Attributes
    ----------
    name : str
        The file's name, or ``"video.mp4#7"`` (frame 7, counted from 0), or ``"camera0#7"``.
    image : ndarray, shape (H, W) or (H, W, 3) or (H, W, 4)
        The pixels as decoded (uint8 or uint16), BGR order.
    source : str
        Where it comes from: the image's or the video's path, or ``"camera0"``. Consecutive
        frames of one video (or camera) share it.
    kind : str
        ``"image"``, ``"video"`` or ``"camera"``.
    """

    name: str
    image: np.ndarray
    source: str
    kind: str


def load_image(path: str | os.PathLike, max_pixels: int = _files.MAX_IMAGE_PIXELS) -> np.ndarray:
    """Read an image file as OpenCV does (BGR or gray, uint8), with a clear error when it cannot.

    Only a regular file is read (a folder, a FIFO or a device is refused before it is opened),
    and the picture's size is read from its header first: one larger than ``max_pixels``
    (100 megapixels unless raised) or a PNG or JPEG cut short is refused before decoding.
    Safe to call from several threads.

    Parameters
    ----------
    path : str or os.PathLike
        The picture (PNG, JPEG, BMP, TIFF, ... whatever OpenCV decodes).
    max_pixels : int
        Largest picture to decode, width times height.

    Returns
    -------
    ndarray, shape (H, W) or (H, W, 3) or (H, W, 4)
        The pixels as stored (uint8, or uint16 for 16-bit files), BGR order.

    Raises
    ------
    ImageError
        The file is missing, not a regular file, empty, too large, cut short or not a picture;
        the message names the file.

    Examples
    --------
    >>> import fidlearn
    >>> load_image(fidlearn.data_path("scenes/scene_00.png")).shape
    (720, 1280)
    """
    if isinstance(max_pixels, bool) or not isinstance(max_pixels, (int, np.integer)) or max_pixels < 1:
        raise ImageError(f"max_pixels must be a positive whole number of pixels, got {max_pixels!r}")
    path, data = _files.read_bytes(path, ImageError, "picture", _files.MAX_IMAGE_BYTES)
    if not data:
        raise ImageError(f"{path}: the file is empty; expected a PNG or JPEG image")
    _files.check_image_bytes(path, data, ImageError, int(max_pixels))
    try:
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:
        raise ImageError(
            f"{path}: OpenCV cannot decode it ({_cv.first_line(exc)}); is it truncated or another file type?"
        ) from None
    if image is None or image.size == 0:
        raise ImageError(
            f"{path}: not an image OpenCV can read (PNG, JPEG, BMP, TIFF...); is it truncated or another file type?"
        )
    return image


def write_image(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Encode an image by its file suffix and write it atomically (whole, or not at all).

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; its suffix (``.png``, ``.jpg``, ...) chooses the encoding.
    image : ndarray, shape (H, W) or (H, W, 3)
        The pixels, BGR order.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    FidlearnError
        OpenCV cannot encode that suffix, or the file cannot be written.
    """
    data = encode_image(path, image)
    return atomic_write(path, lambda tmp: tmp.write_bytes(data))


def encode_image(path: str | os.PathLike, image: np.ndarray) -> bytes:
    """The bytes of an image file, encoded by the suffix of ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        The file's name; its suffix (``.png``, ``.jpg``, ...) chooses the encoding.
    image : ndarray, shape (H, W) or (H, W, 3)
        The pixels, BGR order.

    Returns
    -------
    bytes
        The encoded file.

    Raises
    ------
    FidlearnError
        OpenCV cannot encode that suffix.
    """
    path = Path(path)
    ok, buf = cv2.imencode(path.suffix.lower(), image)
    if not ok:
        raise FidlearnError(f"{path}: OpenCV cannot encode a {path.suffix} image; use .png")
    return buf.tobytes()


def expand_inputs(paths: Sequence[str | os.PathLike], videos: bool, *, once: bool = False) -> list[tuple[str, Path]]:
    """Files and folders as ``[("image" | "video", path), ...]``, checked before any is read.

    Parameters
    ----------
    paths : sequence of str or os.PathLike
        Pictures, videos, and folders (each stands for its pictures, sorted by name).
    videos : bool
        Whether video files are accepted.
    once : bool
        Refuse a picture given twice (by two names, or in a folder given twice): in a calibration or a survey
        each photo is one piece of evidence, and a copy would halve the stated uncertainty.

    Returns
    -------
    list of (str, Path)
        In the order given, a folder's pictures in name order.

    Raises
    ------
    UsageError
        A path that does not exist, a folder without pictures, a file that is not a picture (or a
        video) by its suffix, a FIFO or a device (which would block), or with ``once`` a picture
        given twice.

    Examples
    --------
    >>> import fidlearn
    >>> items = expand_inputs([fidlearn.data_path("scenes")], videos=True)
    >>> len(items), items[0][0], items[0][1].name
    (10, 'image', 'scene_00.png')
    """
    items: list[tuple[str, Path]] = []
    for path in paths:
        path = Path(path)
        if path.is_dir():
            found = _files.folder_images(path)
            if not found:
                raise UsageError(_files.no_images_reason(path))
            items += [("image", p) for p in found]
        elif not path.exists():
            raise UsageError(f"{path}: no such file or folder; check the path")
        elif not path.is_file():
            what = "a picture or a video file" if videos else "a picture file"
            raise UsageError(f"{path}: is {_files._kind(path.stat().st_mode)}; give {what} or a folder of pictures")
        elif videos and path.suffix.lower() in VIDEO_SUFFIXES:
            items.append(("video", path))
        elif path.suffix.lower() in IMAGE_SUFFIXES:
            items.append(("image", path))
        elif path.suffix.lower() in _files.UNREADABLE_PHOTO_SUFFIXES:
            raise UsageError(f"{path}: {_files.HEIC_HINT}")
        else:
            kinds = IMAGE_SUFFIXES + (VIDEO_SUFFIXES if videos else ())
            raise UsageError(
                f"{path}: not an image{' or a video' if videos else ''} by its name; expected {', '.join(kinds)}"
            )
    repeats = _files.repeated_paths(p for _, p in items) if once else []
    if repeats:
        k, i = repeats[0]
        first, again = items[k][1], items[i][1]
        also = "" if str(first) == str(again) else f" (also as {first})"
        raise UsageError(f"{again} is given twice{also}: each photo counts once; give it once")
    return items


def open_capture(source: str | int, what: str) -> cv2.VideoCapture:
    """An opened ``cv2.VideoCapture`` for a video file or a camera index.

    Parameters
    ----------
    source : str or int
        A video file's path, or a camera's index (0 is the first camera).
    what : str
        The name used in the error message.

    Returns
    -------
    cv2.VideoCapture
        Opened; release it when done.

    Raises
    ------
    ImageError
        OpenCV cannot open it.
    """
    cap = cv2.VideoCapture(source)
    if not cap.isOpened():
        cap.release()
        if isinstance(source, int):
            raise ImageError(f"camera {source}: cannot open it; check --camera-index (0 is the first camera)")
        raise ImageError(f"{what}: OpenCV cannot open this video; is it truncated, or a codec OpenCV lacks?")
    return cap


def declared_frames(cap: cv2.VideoCapture) -> int:
    """The frame count a video file's header announces (0 when it does not say).

    Parameters
    ----------
    cap : cv2.VideoCapture
        An opened video.

    Returns
    -------
    int
        Frames announced, 0 when unknown.
    """
    try:
        count = float(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    except cv2.error:
        return 0
    return int(count) if count > 0 and count == count and count < 1e9 else 0


def read_capture(cap: cv2.VideoCapture, prefix: str) -> Iterator[tuple[str, np.ndarray]]:
    """Every frame of an opened capture as ``(f"{prefix}#{k}", frame)``, k from 0, until it ends.

    Parameters
    ----------
    cap : cv2.VideoCapture
        An opened video or camera.
    prefix : str
        The start of each frame's name.

    Yields
    ------
    (str, ndarray)
        The frame's name and its BGR pixels, (H, W, 3) uint8.
    """
    k = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            return
        yield f"{prefix}#{k}", frame
        k += 1


def _video_frames(path: Path) -> Iterator[Frame]:
    cap = open_capture(str(path), str(path))
    try:
        n = 0
        for name, frame in read_capture(cap, path.name):
            n += 1
            yield Frame(name, frame, str(path), "video")
        if n == 0:
            raise ImageError(f"{path}: the video has no frame OpenCV can decode")
        declared = declared_frames(cap)
        if declared > n:
            warnings.warn(
                f"{path}: the video ended after {n} of the {declared} frames its header announces; "
                "the file may be truncated (an interrupted copy or recording)",
                FidlearnWarning,
                stacklevel=2,
            )
    finally:
        cap.release()


def read_frames(
    items: Sequence[tuple[str, Path]], camera_index: int | None = None, max_pixels: int = _files.MAX_IMAGE_PIXELS
) -> Iterator[Frame]:
    """Every picture, every video frame, then every live camera frame, as :class:`Frame`.

    Every video (and the camera) is opened once before the first frame, so a video that
    cannot be read stops the run before anything is done.

    Parameters
    ----------
    items : sequence of (str, Path)
        ``("image" | "video", path)``, as :func:`expand_inputs` gives them.
    camera_index : int, optional
        Also read this live camera, after the files, until it stops.
    max_pixels : int
        Largest picture decoded (see :func:`load_image`).

    Yields
    ------
    Frame

    Raises
    ------
    ImageError
        A picture or video that cannot be read, or a camera that cannot be opened.
    """
    for kind, path in items:
        if kind == "video":
            open_capture(str(path), str(path)).release()
    if camera_index is not None:
        open_capture(int(camera_index), "").release()
    for kind, path in items:
        if kind == "image":
            yield Frame(path.name, load_image(path, max_pixels=max_pixels), str(path), "image")
        else:
            yield from _video_frames(path)
    if camera_index is not None:
        cap = open_capture(int(camera_index), "")
        try:
            for name, frame in read_capture(cap, f"camera{camera_index}"):
                yield Frame(name, frame, f"camera{camera_index}", "camera")
        finally:
            cap.release()


def as_gray(image: np.ndarray, where: str = "image") -> np.ndarray:
    """An 8-bit single-channel view of a gray, BGR or BGRA image (uint8 or uint16).

    16-bit images are scaled to 8 bits by the bits they use (a 12-bit camera's
    0..4095 in a 16-bit PNG becomes 0..255, a full-range one is shifted by 8);
    float images in [0, 1] are accepted too. Anything else raises :class:`ImageError` saying what was received.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 1) or (H, W, 3) or (H, W, 4)
        Gray, BGR or BGRA; uint8, uint16, or float32/float64 in [0, 1].
    where : str
        What the image is, for the error message (a file name, ``"frame"``).

    Returns
    -------
    ndarray, shape (H, W), uint8
        Contiguous; the input itself when it already is one.

    Raises
    ------
    ImageError
        Not an array, empty, not an image's shape, an unsupported pixel type, NaN in a float
        image, or smaller than 8 pixels a side.

    Examples
    --------
    >>> g = as_gray(np.full((10, 12, 3), 1.0))
    >>> g.shape, g.dtype.name, int(g.max())
    ((10, 12), 'uint8', 255)
    """
    if not isinstance(image, np.ndarray):
        raise ImageError(
            f"{where}: expected a numpy array (use fidlearn.detection.load_image for a file), "
            f"got {type(image).__name__}"
        )
    if image.size == 0:
        raise ImageError(f"{where}: the image is empty (shape {image.shape})")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] not in (3, 4)):
        raise ImageError(f"{where}: shape {image.shape} is not an image; expected (H, W) gray or (H, W, 3) BGR")
    if image.dtype == np.uint16:
        # Shift by the bits the picture uses, not always 8: a 10- or 12-bit camera saved as 16-bit
        # PNG (0..1023, 0..4095) became a black 0..3 / 0..15 picture in which nothing is found.
        shift = max(int(image.max()).bit_length() - 8, 0)
        image = (image >> shift).astype(np.uint8)
    elif image.dtype in (np.float32, np.float64):
        if not np.all(np.isfinite(image)):
            raise ImageError(f"{where}: the float image contains NaN or infinity")
        if image.min() < 0 or image.max() > 1:
            raise ImageError(f"{where}: a float image must hold values in [0, 1], got {image.min():g}..{image.max():g}")
        image = np.round(image * 255).astype(np.uint8)
    elif image.dtype != np.uint8:
        raise ImageError(f"{where}: pixel type {image.dtype} is not supported; use uint8 (or uint16)")
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    if min(image.shape[:2]) < 8:
        raise ImageError(f"{where}: {image.shape[1]}x{image.shape[0]} pixels is too small to hold a marker")
    return np.ascontiguousarray(image)
