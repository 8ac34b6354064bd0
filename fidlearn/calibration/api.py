"""The two calibration functions: :func:`calibrate_checkerboard` and :func:`calibrate_charuco`."""

from __future__ import annotations

import glob
import math
import numbers
import os
import warnings
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._files import folder_images, no_images_reason, repeated_paths
from ..boards import Board
from ..errors import CalibrationError, FidlearnWarning
from ._models import check_model
from .boards import _Charuco, _Checkerboard
from .result import Calibration
from .run import ProgressFn, _run

__all__ = ["calibrate_checkerboard", "calibrate_charuco"]


def _entries(images: Any) -> list[tuple[str, Any]]:
    """(name, path or array) for each input; a folder or a glob pattern expands to its image files, sorted."""
    if isinstance(images, (str, os.PathLike)):
        folder = Path(images)
        if folder.is_dir():
            files: list[Path] | list[str] = folder_images(folder)
            if not files:
                raise CalibrationError(no_images_reason(folder))
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
    _refuse_repeats(items)
    return out


def _refuse_repeats(items: list[Any]) -> None:
    """Refuse a file given twice (by two names, a link, or a folder's link to a file already in it)."""
    repeats = repeated_paths(items)
    if repeats:
        k, i = repeats[0]
        first, again = str(items[k]), str(items[i])
        also = "" if first == again else f" (also as {first})"
        raise CalibrationError(
            f"{again} is given twice{also}: each photo counts once (a copy would halve the stated "
            "uncertainty); give it once"
        )


def _check_positive(value: Any, what: str, fix: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise CalibrationError(f"{what} must be a number, got {value!r}; {fix}") from None
    if not math.isfinite(v) or v <= 0:
        raise CalibrationError(f"{what} must be positive, got {value!r}; {fix}")
    return v


#: A printed square under this many mm, given as millimetres, is more likely a size in centimetres.
CENTIMETRE_LIKE_MM = 5.0


def _warn_if_metres(value_mm: float, what: str) -> None:
    """A printed square or marker under 1 mm is almost surely a size in metres (OpenCV's tutorials use metres),
    one under ``CENTIMETRE_LIKE_MM`` one in centimetres (2.5 for a 25 mm square)."""
    if 1.0 <= value_mm < CENTIMETRE_LIKE_MM:
        warnings.warn(
            f"{what}={value_mm:g} means {value_mm:g} mm, smaller than a printed board's squares usually are; if that "
            f"is centimetres, give millimetres ({value_mm * 10:g}; command line: --square-mm): K is right either "
            "way, but every distance (the board poses, and the poses computed from them) comes out 10 times too small",
            FidlearnWarning,
            stacklevel=3,
        )
    if value_mm < 1.0:
        warnings.warn(
            f"{what}={value_mm:g} means {value_mm:g} mm, smaller than any printed square; if that is metres, "
            f"give millimetres ({value_mm * 1000:g}; command line: --square-mm): K is right either way, "
            "but every distance (the board poses, and the poses computed from them) comes out 1000 times too small",
            FidlearnWarning,
            stacklevel=3,
        )


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
    return cols, rows


def _checkerboard(pattern_size: Any, square_size_mm: Any, board: Any) -> Board:
    """The board of :func:`calibrate_checkerboard`: ``board``, or made from ``pattern_size`` and ``square_size_mm``."""
    if board is not None:
        if pattern_size is not None or square_size_mm is not None:
            raise CalibrationError(
                "give the board once: board=Board.checkerboard(...) or pattern_size and square_size_mm, not both"
            )
        if not isinstance(board, Board) or board.is_charuco:
            raise CalibrationError(
                f"board must be a fidlearn.Board.checkerboard(inner_corners, square_size_mm), got {board!r:.80}; "
                "a ChArUco board goes to calibrate_charuco"
            )
    elif pattern_size is None or square_size_mm is None:
        raise CalibrationError(
            "calibrate_checkerboard needs the board: board=Board.checkerboard((9, 6), 25) "
            "or pattern_size=(9, 6), square_size_mm=25 (inner corners, and one printed square in mm)"
        )
    else:
        cols, rows = _pattern(pattern_size)
        square = _check_positive(square_size_mm, "square_size_mm", "measure one printed square in millimetres")
        if cols < 3 or rows < 3:
            raise CalibrationError(
                f"pattern_size {(cols, rows)} counts inner corners and needs at least 3 each way; "
                "a board of 10x7 squares has 9x6 inner corners"
            )
        board = Board.checkerboard((cols, rows), square)
    if min(board.inner_corners) < 3:
        raise CalibrationError(
            f"{board.describe()}: OpenCV's finder needs at least 3 inner corners each way; "
            "a board of 10x7 squares has 9x6 inner corners"
        )
    return board


def calibrate_checkerboard(
    images: Sequence[Any] | str | os.PathLike,
    pattern_size: tuple[int, int] | str | None = None,
    square_size_mm: float | None = None,
    *,
    board: Board | None = None,
    progress: ProgressFn | None = None,
    reject_outliers: bool = True,
    reject_duplicates: bool = False,
    corner_finder: str = "classic",
    flags: int = 0,
    criteria: tuple | None = None,
    model: str = "pinhole",
) -> Calibration:
    """Calibrate a camera from photos of a printed checkerboard.

    Parameters
    ----------
    images : sequence of (ndarray or path), or a folder, or a glob pattern
        The photos, gray or BGR arrays and/or image files, mixed as you like
        (a folder stands for its image files, ``"photos/*.jpg"`` for the
        files it matches, sorted). Each is reported by
        its path, or ``"image i"`` (i from 0) for an array. A file given
        twice (by two names, or through a link) is refused: each photo
        counts once.
    pattern_size : (int, int) or str, optional
        INNER corners (columns, rows), e.g. ``(9, 6)`` or ``"9x6"``: a board
        of 10x7 squares has 9x6 inner corners. With ``square_size_mm``, the
        same as ``board=Board.checkerboard(pattern_size, square_size_mm)``.
    square_size_mm : float, optional
        Side of one printed square, measured on the print (mm). It scales
        the board poses only, never ``K``.
    board : Board, optional
        The checkerboard (:meth:`fidlearn.Board.checkerboard`), in place of
        ``pattern_size`` and ``square_size_mm``.
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
        Passed to ``cv2.calibrateCamera`` (e.g. ``cv2.CALIB_RATIONAL_MODEL``), or to
        ``cv2.fisheye.calibrate`` with ``model="fisheye"`` (by default ``CALIB_RECOMPUTE_EXTRINSIC`` and
        ``CALIB_FIX_SKEW``; ``CALIB_FIX_SKEW`` always, a Camera has no skew; give
        ``CALIB_RECOMPUTE_EXTRINSIC`` with flags of your own, or the fit may stall).
    model : {"pinhole", "fisheye", "auto"}
        The lens model: OpenCV's pinhole model (``cv2.calibrateCamera``), its fisheye model
        (``cv2.fisheye.calibrate``, lenses of 120 degrees and more), or ``"auto"``: the fisheye when its
        reprojection error on views left out of its calibration is at least 10 % below the pinhole's (5
        groups of views held out in turn; ``Calibration.held_out_rms_px`` holds both errors), the pinhole
        otherwise. ``"auto"`` takes no ``flags``.

    Returns
    -------
    Calibration
        The camera, the errors per view, and ``warnings``: what makes it less trustworthy
        than its RMS says (too few views, too alike, parts of the picture empty).

    Raises
    ------
    CalibrationError
        Bad arguments (among them a photo file given twice), or fewer than 3
        usable views (the message says why the others failed, and suggests
        the inner-corner count when the squares were counted instead).

    Examples
    --------
    >>> import fidlearn
    >>> from fidlearn import Board
    >>> photos = sorted(fidlearn.data_path("calibration").glob("view_*.png"))  # 20 rendered views, fx 615
    >>> cal = calibrate_checkerboard(photos[:5], board=Board.checkerboard((9, 6), 25.0))
    >>> round(cal.camera.fx), len(cal.used), cal.coverage.shape
    (615, 5, (3, 3))
    >>> for sentence in cal.warnings:  # what the RMS does not tell
    ...     print(sentence[:40])
    only 5 views were used; take at least 10
    few board corners in the bottom-left, bo

    """
    board = _checkerboard(pattern_size, square_size_mm, board)
    model = check_model(model, flags)
    _warn_if_metres(board.square_size_mm, "square_size_mm")
    finder = _Checkerboard(board, corner_finder)
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
        model=model,
    )


def calibrate_charuco(
    images: Sequence[Any] | str | os.PathLike,
    board: Board,
    *,
    legacy: bool | str = "auto",
    progress: ProgressFn | None = None,
    reject_outliers: bool = True,
    reject_duplicates: bool = False,
    min_corners: int = 6,
    flags: int = 0,
    criteria: tuple | None = None,
    model: str = "pinhole",
) -> Calibration:
    """Calibrate a camera from photos of a ChArUco board (a checkerboard with ArUco markers in its white squares).

    Each chess corner is identified by the markers around it, so views where
    part of the board is hidden or outside the picture still count.

    Parameters
    ----------
    images : sequence of (ndarray or path), or a folder
        As for :func:`calibrate_checkerboard`.
    board : Board
        The ChArUco board (:meth:`fidlearn.Board.charuco`): its SQUARES (x, y), as
        ``cv2.aruco.CharucoBoard`` counts them (OpenCV's tutorial board: (5, 7)), the printed
        side of a chess square and of a marker (mm), and the markers' dictionary.
    legacy : bool or "auto"
        The marker layout of boards made before OpenCV 4.6 (matters only with
        an even number of rows); ``"auto"`` keeps whichever finds more corners.
    progress, reject_outliers, reject_duplicates, flags, criteria, model :
        As for :func:`calibrate_checkerboard`.
    min_corners : int
        Fewest chess corners a view must show to be used.

    Returns
    -------
    Calibration

    Raises
    ------
    CalibrationError
        Bad arguments (among them a photo file given twice), or fewer than 3 usable views (the message
        says why the others failed, and suggests swapped squares or the other marker layout when
        nothing was found).
    """
    if not isinstance(board, Board) or not board.is_charuco:
        raise CalibrationError(
            f"board must be a fidlearn.Board.charuco(squares, square_size_mm, marker_size_mm, dictionary), "
            f"got {board!r:.80}; a checkerboard goes to calibrate_checkerboard"
        )
    model = check_model(model, flags)
    _warn_if_metres(board.square_size_mm, "square_size_mm")
    if isinstance(min_corners, bool) or not isinstance(min_corners, numbers.Integral) or min_corners < 4:
        raise CalibrationError(f"min_corners must be a whole number, at least 4, got {min_corners!r:.40}")
    finder = _Charuco(board, legacy, min_corners)
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
        model=model,
    )
