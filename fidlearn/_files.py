"""Private helpers that read a user's file safely: a regular file, of bounded size, with a readable error.

Everything fidlearn reads goes through :func:`read_bytes`: a FIFO, a device (``/dev/zero``), a
folder or a path with a NUL byte is refused before it is opened for reading (a FIFO would block
forever, a device would be read without end), and a file larger than the stated limit is refused
before it is read. Pictures are checked from their header (:func:`image_size_from_header`) before
any pixel is decoded, so a 74-byte PNG that declares 100000 x 100000 pixels costs nothing.
"""

from __future__ import annotations

import difflib
import os
import stat
import struct
from collections.abc import Iterable, Mapping
from pathlib import Path

from .errors import FidlearnError

#: File suffixes read as pictures (a folder stands for its files with these suffixes).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm")
#: File suffixes read as videos.
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm")

#: Largest map or camera file read (bytes): far above any real one.
MAX_TEXT_BYTES = 10 * 1024 * 1024
#: Largest picture file read (bytes).
MAX_IMAGE_BYTES = 512 * 1024 * 1024
#: Largest picture decoded by default (pixels); ``load_image(max_pixels=...)`` raises it.
MAX_IMAGE_PIXELS = 100_000_000


def as_path(path, error: type[FidlearnError], what: str) -> Path:
    """``path`` as a Path.

    Parameters
    ----------
    path : str, bytes or path-like
        What the user gave.
    error : type of FidlearnError
        The error class to raise (``MapError`` for a map, ``CameraError`` for a camera, ...).
    what : str
        What the file is, for the message ("camera", "world map").

    Returns
    -------
    Path

    Raises
    ------
    FidlearnError
        ``error``, when ``path`` is not a path, is empty, or holds a NUL character or undecodable bytes.
    """
    if isinstance(path, bytes):
        try:
            path = os.fsdecode(path)
        except UnicodeDecodeError:
            raise error(f"{what}: the path {path!r} is not valid text") from None
    if not isinstance(path, (str, os.PathLike)):
        raise error(f"{what}: expected a file path (str or pathlib.Path), got {type(path).__name__}")
    text = os.fspath(path)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if "\0" in text:
        raise error(f"{what}: the path {text!r} contains a NUL character; no file can have that name")
    if not text.strip():
        raise error(f"{what}: the path is empty; give a file name")
    return Path(text)


#: Phone photos OpenCV cannot decode (HEIF); named so when they are given.
UNREADABLE_PHOTO_SUFFIXES = (".heic", ".heif")
#: How to get pictures OpenCV reads from a phone that stores HEIF.
HEIC_HINT = (
    "OpenCV cannot read HEIC photos: export them as JPEG (on an iPhone: Settings > Camera > Formats > Most Compatible)"
)


def folder_images(folder: Path) -> list[Path]:
    """The picture files of a folder, sorted: those named with an image suffix, hidden names left out.

    A hidden name is no photo of the user's: macOS keeps ``._scene.png`` beside a file copied to a USB stick,
    and fidlearn stages its own outputs under hidden names while it writes them.

    Parameters
    ----------
    folder : Path
        A folder.

    Returns
    -------
    list of Path
        The pictures (maybe none).
    """
    return sorted(
        p for p in folder.iterdir() if not p.name.startswith(".") and p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()
    )


def no_images_reason(folder: Path) -> str:
    """Why a folder gives no picture: its HEIC photos named, else the suffixes read.

    Parameters
    ----------
    folder : Path
        A folder without pictures (:func:`folder_images` empty).

    Returns
    -------
    str
        The message, starting with the folder's name.
    """
    heic = [p for p in folder.iterdir() if p.suffix.lower() in UNREADABLE_PHOTO_SUFFIXES and not p.name.startswith(".")]
    if heic:
        return f"{folder}: {len(heic)} HEIC photo{'s' if len(heic) != 1 else ''} and no other pictures; {HEIC_HINT}"
    return f"{folder}: no images ({', '.join(IMAGE_SUFFIXES)}) in this folder"


def repeated_paths(items: Iterable[object]) -> list[tuple[int, int]]:
    """The entries that name a file named by an earlier entry, as ``(first, again)`` index pairs.

    Two entries are one file when their real paths are equal (``os.path.realpath``: relative to the
    working folder, symbolic links followed, ``.`` and ``..`` removed), so ``a.png``, ``./a.png`` and
    a link to ``a.png`` are one photo. In a calibration or a survey each photo is one piece of
    evidence: a photo counted twice halves the stated uncertainty.

    Parameters
    ----------
    items : iterable
        Paths (str or path-like), possibly among other things (image arrays, detections), which
        are skipped but counted in the indices. A path that cannot be resolved (one with a NUL
        character) is compared as written.

    Returns
    -------
    list of (int, int)
        For each repeated entry, in order: the index of the first entry naming its file, and its
        own index. Empty when every file is named once.

    Examples
    --------
    >>> repeated_paths(["a.png", "b.png", "./a.png", None, "a.png"])
    [(0, 2), (0, 4)]
    >>> repeated_paths(["a.png", "b.png"])
    []
    """
    first: dict[object, int] = {}
    repeats = []
    for i, item in enumerate(items):
        if not isinstance(item, (str, os.PathLike)):
            continue
        try:
            key: object = os.path.realpath(item)
        except (ValueError, OSError):  # a NUL character: the read that follows refuses it with a message
            key = os.fspath(item)
        k = first.setdefault(key, i)
        if k != i:
            repeats.append((k, i))
    return repeats


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def read_bytes(path, error: type[FidlearnError], what: str, limit: int) -> tuple[Path, bytes]:
    """Read a whole regular file of at most ``limit`` bytes.

    Parameters
    ----------
    path : str, bytes or path-like
        The file.
    error : type of FidlearnError
        The error class to raise.
    what : str
        What the file is, for the message.
    limit : int
        Largest size read, bytes.

    Returns
    -------
    path : Path
    data : bytes

    Raises
    ------
    FidlearnError
        ``error`` with the path and the fix: no such file, no permission, a folder, FIFO or device, or
        a file over ``limit``.
    """
    path = as_path(path, error, what)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(f"{path}: no such file; check the path of the {what}") from None
    except PermissionError:
        raise error(f"{path}: permission denied; check the file's permissions") from None
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror or exc}); check the path of the {what}") from None
    if not stat.S_ISREG(st.st_mode):
        article = "an" if what[:1].lower() in "aeiou" else "a"
        raise error(f"{path}: is {_kind(st.st_mode)}, not a file; give the path of {article} {what} file")
    if st.st_size > limit:
        raise error(
            f"{path}: {st.st_size / 1e6:.1f} MB is more than a {what} file can be "
            f"({limit / 1e6:.0f} MB at most); is it the right file?"
        )
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except PermissionError:
        raise error(f"{path}: permission denied; check the file's permissions") from None
    except OSError as exc:
        raise error(f"{path}: cannot be opened ({exc.strerror or exc}); check the path") from None
    try:
        with os.fdopen(fd, "rb") as f:
            data = f.read(limit + 1)
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise error(f"{path}: more than {limit / 1e6:.0f} MB; a {what} file is far smaller")
    return path, data


def image_size_from_header(data: bytes) -> tuple[str, int, int] | None:
    """The format and size a picture's header declares, read without decoding a pixel.

    Parameters
    ----------
    data : bytes
        The file's content (or at least its beginning).

    Returns
    -------
    (str, int, int) or None
        ``(format, width, height)`` for PNG, JPEG, BMP, GIF or TIFF (-1 for a size the header does
        not give); None for another format.

    Examples
    --------
    >>> image_size_from_header(b"GIF89a" + bytes([64, 0, 48, 0]))
    ('GIF', 64, 48)
    """
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        if len(data) >= 24 and data[12:16] == b"IHDR":
            w, h = struct.unpack(">II", data[16:24])
            return "PNG", w, h
        return "PNG", -1, -1
    if data[:2] == b"\xff\xd8":
        return ("JPEG", *_jpeg_size(data))
    if data[:2] == b"BM" and len(data) >= 26:
        w, h = struct.unpack("<ii", data[18:26])
        return "BMP", abs(w), abs(h)
    if data[:6] in (b"GIF87a", b"GIF89a") and len(data) >= 10:
        w, h = struct.unpack("<HH", data[6:10])
        return "GIF", w, h
    if data[:4] in (b"II*\x00", b"MM\x00*"):
        return ("TIFF", *_tiff_size(data))
    return None


def _jpeg_size(data: bytes) -> tuple[int, int]:
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            i += 1
            continue
        marker = data[i + 1]
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7 or marker == 0xFF:
            i += 1 if marker == 0xFF else 2
            continue
        length = struct.unpack(">H", data[i + 2 : i + 4])[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", data[i + 5 : i + 9])
            return w, h
        i += 2 + length
    return -1, -1


def _tiff_size(data: bytes) -> tuple[int, int]:
    endian = "<" if data[:2] == b"II" else ">"
    try:
        (offset,) = struct.unpack(endian + "I", data[4:8])
        (count,) = struct.unpack(endian + "H", data[offset : offset + 2])
        w = h = -1
        for k in range(count):
            entry = data[offset + 2 + 12 * k : offset + 14 + 12 * k]
            tag, kind = struct.unpack(endian + "HH", entry[:4])
            value = struct.unpack(endian + ("H" if kind == 3 else "I"), entry[8:10] if kind == 3 else entry[8:12])[0]
            if tag == 256:
                w = value
            elif tag == 257:
                h = value
        return w, h
    except (struct.error, IndexError):
        return -1, -1


def check_image_bytes(path: Path, data: bytes, error: type[FidlearnError], max_pixels: int) -> None:
    """Refuse, before decoding, a picture that is cut short or larger than ``max_pixels``.

    Parameters
    ----------
    path : Path
        The picture's path, for the message.
    data : bytes
        The file's content.
    error : type of FidlearnError
        The error class to raise.
    max_pixels : int
        Largest width x height accepted.

    Raises
    ------
    FidlearnError
        ``error``, when the header declares an empty or too large picture, or a PNG or JPEG has no end.
    """
    head = image_size_from_header(data)
    if head is None:
        return
    fmt, w, h = head
    if w == 0 or h == 0 or w < -1 or h < -1:
        raise error(f"{path}: the {fmt} header says {w}x{h} pixels; the file is damaged")
    if w > 0 and h > 0 and w * h > max_pixels:
        raise error(
            f"{path}: the {fmt} header says {w}x{h} pixels ({w * h / 1e6:.3g} megapixels), more than the "
            f"limit of {max_pixels / 1e6:.3g} megapixels; to read it, raise the limit: load_image(max_pixels=...) "
            "or 'fidlearn locate --max-megapixels'"
        )
    if fmt == "PNG" and b"IEND" not in data[-16:]:
        raise error(f"{path}: the PNG file is cut short (it has no end chunk); copy it again")
    if fmt == "JPEG" and not data.rstrip(b"\0\r\n ").endswith(b"\xff\xd9"):
        raise error(f"{path}: the JPEG file is cut short (it has no end marker); copy it again")


def did_you_mean(field: object, known: Iterable[str], aliases: Mapping[str, str] | None = None) -> str:
    """``": did you mean 'x'?"`` for a misspelt field name, or ``""`` when nothing is close.

    Parameters
    ----------
    field : object
        The field name the user wrote (compared stripped and in lower case).
    known : iterable of str
        The field names that exist.
    aliases : mapping of str to str, optional
        Other spellings of known names (keys in lower case, ``_`` for ``-`` and spaces, as in
        ``{"k": "camera_matrix"}``); with them, ``-`` and spaces in ``field`` count as ``_`` and an
        alias wins over a merely close name.

    Returns
    -------
    str
        The suffix to append to the message that names the unknown field.

    Examples
    --------
    >>> did_you_mean("Markers ", ["markers", "units"])
    ": did you mean 'markers'?"
    >>> did_you_mean("intrinsics", ["camera_matrix"], aliases={"intrinsics": "camera_matrix"})
    ": did you mean 'camera_matrix'?"
    >>> did_you_mean("colour", ["units"])
    ''
    """
    key = str(field).strip().lower()
    guess = None
    if aliases is not None:
        key = key.replace("-", "_").replace(" ", "_")
        guess = aliases.get(key) or aliases.get(key.replace("_", ""))
    if guess is None:
        close = difflib.get_close_matches(key, sorted(known), n=1, cutoff=0.6)
        guess = close[0] if close else None
    return f": did you mean {guess!r}?" if guess else ""
