"""The two calibration functions: :func:`calibrate_checkerboard` and :func:`calibrate_charuco`."""

from __future__ import annotations

import glob
import math
import os
import warnings
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import CalibrationError, FidlearnWarning
from ..images import IMAGE_SUFFIXES
from .boards import _Charuco, _Checkerboard
from .result import Calibration
from .run import ProgressFn, _run

__all__ = ["calibrate_checkerboard", "calibrate_charuco"]


def _entries(images: Any) -> list[tuple[str, Any]]:
    """(name, path or array) for each input; a folder or a glob pattern expands to its image files, sorted."""
    if isinstance(images, (str, os.PathLike)):
        folder = Path(images)
        if folder.is_dir():
            files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
            if not files:
                raise CalibrationError(f"{folder}: no image files (.png, .jpg, ...) in this folder")
            images = files
        elif any(ch in str(images) for ch in "*?[") and not folder.exists():
            files = sorted(glob.glob(str(images)))
            if not files:
                raise CalibrationError(f"{images}: no file matches this pattern; check the folder and the extension")
            images = files
        else:
            images = [images]
    elif isinstance(images, np.ndarray) and (images.ndim == 2 or (images.ndim == 3 and images.shape[2] in (1, 3, 4))):
        raise CalibrationError(
            f"images is one array of shape {images.shape}; pass a list of images (arrays or paths), "
            "one per view of the board"
        )
    try:
        items = list(images)
    except TypeError:
        raise CalibrationError(
            f"images must be a list of image arrays or paths (or a folder), got {type(images).__name__}"
        ) from None
    out: list[tuple[str, Any]] = []
    seen: Counter = Counter()
    for i, item in enumerate(items):
        if isinstance(item, (str, os.PathLike)):
            name = str(item)
        elif isinstance(item, np.ndarray):
            name = f"image {i}"
        else:
            raise CalibrationError(
                f"images[{i}] is a {type(item).__name__}; each entry must be an image array or a path"
            )
        seen[name] += 1
        if seen[name] > 1:
            name = f"{name} ({seen[name]})"
        out.append((name, item))
    return out


def _check_positive(value: Any, what: str, fix: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise CalibrationError(f"{what} must be a number, got {value!r}; {fix}") from None
    if not math.isfinite(v) or v <= 0:
        raise CalibrationError(f"{what} must be positive, got {value!r}; {fix}")
    return v


def _warn_if_metres(value_mm: float, what: str) -> None:
    """A printed square or marker under 1 mm is almost surely a size in metres (OpenCV's tutorials use metres)."""
    if value_mm < 1.0:
        warnings.warn(
            f"{what}={value_mm:g} means {value_mm:g} mm, smaller than any printed square; if that is metres, "
            f"give millimetres ({value_mm * 1000:g}; command line: --square-mm): K is right either way, "
            "but every distance (the board poses, and the poses computed from them) comes out 1000 times too small",
            FidlearnWarning,
            stacklevel=3,
        )


#: Most inner corners of a board (a checkerboard's pattern, a ChArUco board's chess corners): 50 x 50. A larger
#: count is a typing slip, and its search and calibration would run for minutes.
MAX_BOARD_CORNERS = 2500


def _pattern(pattern_size: Any) -> tuple[int, int]:
    if isinstance(pattern_size, str):
        parts = pattern_size.lower().replace("*", "x").split("x")
    else:
        try:
            parts = list(pattern_size)
        except TypeError:
            parts = []
    try:
        cols, rows = (int(p) for p in parts)
        ok = all(float(p) == int(p) for p in parts)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise CalibrationError(
            f"pattern_size {pattern_size!r} must be two whole numbers (columns, rows) of inner corners, e.g. (9, 6)"
        )
    if cols < 3 or rows < 3:
        raise CalibrationError(
            f"pattern_size {(cols, rows)} counts inner corners and needs at least 3 each way; "
            "a board of 10x7 squares has 9x6 inner corners"
        )
    if cols * rows > MAX_BOARD_CORNERS:
        raise CalibrationError(
            f"pattern_size {(cols, rows)} has {cols * rows} inner corners, more than {MAX_BOARD_CORNERS}, the most "
            "fidlearn searches a photo for; count the inner corners again (a board of 10x7 squares has 9x6)"
        )
    return cols, rows


def calibrate_checkerboard(
    images: Sequence[Any] | str | os.PathLike,
    pattern_size: tuple[int, int] | str,
    square_size_mm: float,
    *,
    progress: ProgressFn | None = None,
    reject_outliers: bool = True,
    reject_duplicates: bool = False,
    corner_finder: str = "classic",
    flags: int = 0,
    criteria: tuple | None = None,
) -> Calibration:
    """Calibrate a camera from photos of a printed checkerboard.

    Parameters
    ----------
    images : sequence of (ndarray or path), or a folder, or a glob pattern
        The photos, gray or BGR arrays and/or image files, mixed as you like
        (a folder stands for its image files, ``"photos/*.jpg"`` for the
        files it matches, sorted). Each is reported by
        its path, or ``"image i"`` (i from 0) for an array.
    pattern_size : (int, int) or str
        INNER corners (columns, rows), e.g. ``(9, 6)`` or ``"9x6"``: a board
        of 10x7 squares has 9x6 inner corners.
    square_size_mm : float
        Side of one printed square, measured on the print (mm). It scales
        the board poses only, never ``K``.
    progress : callable(i, n, name), optional
        Called after each image is searched (i from 1 to n); nothing is
        printed otherwise.
    reject_outliers : bool
        Drop views whose RMS exceeds ``max(3 x median, median + 0.5 px)`` and
        calibrate again (see the module docstring).
    reject_duplicates : bool
        Drop a view whose every corner lies within 1 px of an earlier view's
        (a burst of photos of a still board adds weight, not geometry: four
        copies of one photo give a wildly wrong fx with a small claimed
        standard deviation). Off by default: the command line warns instead.
    corner_finder : {"classic", "sb"}
        ``findChessboardCorners`` + capped ``cornerSubPix`` (default, measured
        more accurate) or ``findChessboardCornersSB``.
    flags, criteria :
        Passed to ``cv2.calibrateCamera`` (e.g. ``cv2.CALIB_RATIONAL_MODEL``).

    Returns
    -------
    Calibration
        The camera, the errors per view, and ``warnings``: what makes it less trustworthy
        than its RMS says (too few views, too alike, parts of the picture empty).

    Raises
    ------
    CalibrationError
        Bad arguments, or fewer than 3 usable views (the message says why
        the others failed, and suggests the inner-corner count when the
        squares were counted instead).

    Examples
    --------
    >>> import fidlearn
    >>> photos = sorted(fidlearn.data_path("calibration").glob("view_*.png"))  # 20 rendered views, fx 615
    >>> cal = calibrate_checkerboard(photos[:5], (9, 6), 25.0)
    >>> round(cal.camera.fx), len(cal.used), cal.coverage.shape
    (615, 5, (3, 3))
    >>> for sentence in cal.warnings:  # what the RMS does not tell
    ...     print(sentence[:40])
    only 5 views were used; take at least 10
    few board corners in the bottom-left, bo

    """
    pattern = _pattern(pattern_size)
    square = _check_positive(square_size_mm, "square_size_mm", "measure one printed square in millimetres")
    _warn_if_metres(square, "square_size_mm")
    finder = _Checkerboard(pattern, square, corner_finder)
    entries = _entries(images)
    return _run(
        entries,
        finder,
        lambda g: {0: finder.find(g)},
        progress,
        reject_outliers,
        flags,
        criteria,
        "calibrate_checkerboard",
        reject_duplicates,
    )


def calibrate_charuco(
    images: Sequence[Any] | str | os.PathLike,
    squares: tuple[int, int] = (5, 7),
    square_size_mm: float = 40.0,
    marker_size_mm: float = 20.0,
    *,
    dictionary: str = "6X6_250",
    legacy: bool | str = "auto",
    progress: ProgressFn | None = None,
    reject_outliers: bool = True,
    reject_duplicates: bool = False,
    min_corners: int = 6,
    flags: int = 0,
    criteria: tuple | None = None,
) -> Calibration:
    """Calibrate a camera from photos of a ChArUco board (a checkerboard with ArUco markers in its white squares).

    Each chess corner is identified by the markers around it, so views where
    part of the board is hidden or outside the picture still count.

    Parameters
    ----------
    images : sequence of (ndarray or path), or a folder
        As for :func:`calibrate_checkerboard`.
    squares : (int, int)
        SQUARES (x, y) of the board, as ``cv2.aruco.CharucoBoard`` counts them
        (OpenCV's tutorial board: (5, 7)).
    square_size_mm, marker_size_mm : float
        Printed side of a chess square and of a marker (mm), marker < square.
    dictionary : str
        The markers' ArUco dictionary, e.g. ``"6X6_250"``.
    legacy : bool or "auto"
        The marker layout of boards made before OpenCV 4.6 (matters only with
        an even number of rows); ``"auto"`` keeps whichever finds more corners.
    progress, reject_outliers, reject_duplicates, flags, criteria :
        As for :func:`calibrate_checkerboard`.
    min_corners : int
        Fewest chess corners a view must show to be used.

    Returns
    -------
    Calibration

    Raises
    ------
    CalibrationError
        Bad arguments, or fewer than 3 usable views (the message says why the others failed,
        and suggests swapped squares or the other marker layout when nothing was found).
    """
    try:
        sq = tuple(int(v) for v in squares)
        if len(sq) != 2:
            raise ValueError
    except (TypeError, ValueError):
        raise CalibrationError(
            f"squares {squares!r} must be two whole numbers (x, y) of chess squares, e.g. (5, 7)"
        ) from None
    if min(sq) < 2:
        raise CalibrationError(f"squares {sq} must count at least 2 chess squares each way, e.g. (5, 7)")
    if (sq[0] - 1) * (sq[1] - 1) > MAX_BOARD_CORNERS:
        raise CalibrationError(
            f"squares {sq} make {(sq[0] - 1) * (sq[1] - 1)} chess corners, more than {MAX_BOARD_CORNERS}, the most "
            "fidlearn searches a photo for; count the squares again (OpenCV's tutorial board: (5, 7))"
        )
    square = _check_positive(square_size_mm, "square_size_mm", "measure one printed chess square in millimetres")
    marker = _check_positive(
        marker_size_mm, "marker_size_mm", "measure one printed marker's black square in millimetres"
    )
    _warn_if_metres(square, "square_size_mm")
    if marker >= square:
        raise CalibrationError(
            f"marker_size_mm ({marker:g}) must be smaller than square_size_mm ({square:g}): the markers sit inside "
            "the white squares (OpenCV's tutorial board: 40 mm squares, 20 mm markers)"
        )
    if int(min_corners) < 4:
        raise CalibrationError(f"min_corners must be at least 4, got {min_corners}")
    finder = _Charuco(sq, square, marker, dictionary, legacy, min_corners)
    entries = _entries(images)
    return _run(
        entries,
        finder,
        finder.find_all,
        progress,
        reject_outliers,
        flags,
        criteria,
        "calibrate_charuco",
        reject_duplicates,
    )
