"""Board finders: a gray image in, the board's points (mm) and their pixels out, or the reason why not.

Pixel convention: OpenCV's, pixel centres at integer coordinates. Board frame: see
:mod:`fidlearn.calibration`.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np

from .. import _cv_charuco
from ..boards import Board
from ..errors import BoardNotFoundError, CalibrationError

__all__ = ["find_checkerboard_corners"]

_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)


class _Checkerboard:
    def __init__(self, board: Board, corner_finder: str):
        self.board = board
        self.pattern_size = board.inner_corners
        if corner_finder not in ("classic", "sb"):
            raise CalibrationError(f"corner_finder {corner_finder!r} is unknown; use 'classic' or 'sb'")
        self.corner_finder = corner_finder
        self.object_points = board.object_points()
        self.description = board.describe()

    def find(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
        try:
            corners = find_checkerboard_corners(gray, self.pattern_size, self.corner_finder)
        except BoardNotFoundError as exc:
            return str(exc)
        return self.object_points, corners

    def diagnose(self, grays: list[np.ndarray]) -> str:
        """A hint when the board was found nowhere: squares counted instead of inner corners?"""
        cols, rows = self.pattern_size
        if cols - 1 < 3 or rows - 1 < 3:
            return ""
        for gray in grays:
            try:
                find_checkerboard_corners(gray, (cols - 1, rows - 1), "classic", refine=False)
            except BoardNotFoundError:
                continue
            example = "" if (cols, rows) == (10, 7) else " (a board of 10x7 squares has 9x6 inner corners)"
            return (
                f"the board is found with pattern_size=({cols - 1}, {rows - 1}) (command line: --pattern "
                f"{cols - 1}x{rows - 1}): pattern_size counts inner corners, not squares: a board of "
                f"{cols}x{rows} squares has {cols - 1}x{rows - 1} inner corners{example}"
            )
        return ""


def find_checkerboard_corners(
    gray: np.ndarray, pattern_size: tuple[int, int], corner_finder: str = "classic", refine: bool = True
) -> np.ndarray:
    """Inner corners of a checkerboard, (cols * rows, 2) float64 px in OpenCV's order.

    ``"classic"``: ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix`` with
    the half-window ``min(11, floor(0.6 * s))``, ``s`` the shortest spacing
    between neighbouring corners (px); ``"sb"``: ``cv2.findChessboardCornersSB``
    with ``CALIB_CB_ACCURACY``. Pixel centres at integer coordinates.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
        The photo, gray.
    pattern_size : (int, int)
        Inner corners (columns, rows).
    corner_finder : {"classic", "sb"}
        Which OpenCV finder.
    refine : bool
        Refine the classic finder's corners with ``cv2.cornerSubPix`` (False: as found).

    Returns
    -------
    ndarray, shape (cols * rows, 2), float64
        The corners (pixels), row by row.

    Raises
    ------
    BoardNotFoundError
        The board (all its ``cols x rows`` inner corners) is not found in the picture.

    Examples
    --------
    >>> from fidlearn import Camera, synthetic
    >>> cam = Camera.from_fov(60, (640, 480))
    >>> view = synthetic.render_calibration_views(cam, n_views=1, seed=1).images[0]
    >>> find_checkerboard_corners(view, (9, 6)).shape
    (54, 2)
    """
    cols, rows = pattern_size
    if corner_finder == "sb":
        flags = cv2.CALIB_CB_ACCURACY | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE
        ok, corners = cv2.findChessboardCornersSB(gray, (cols, rows), flags=flags)
        if not ok:
            raise _not_found(pattern_size)
        return np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, corners = cv2.findChessboardCorners(gray, (cols, rows), flags=flags)
    if not ok or corners is None:
        raise _not_found(pattern_size)
    if not refine:
        return np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    grid = corners.reshape(rows, cols, 2)
    along, down = grid[:, 1:] - grid[:, :-1], grid[1:] - grid[:-1]
    # the shortest spacing (px): sqrt of the least squared distance, as np.linalg.norm computes it, in 1/3 the time
    spacing = np.sqrt(min(np.add.reduce(along * along, axis=2).min(), np.add.reduce(down * down, axis=2).min()))
    half = min(max(math.floor(0.6 * spacing), 2), 11)
    corners = cv2.cornerSubPix(gray, corners, (half, half), (-1, -1), _SUBPIX_CRITERIA)  # float32, refined in place
    return np.asarray(corners, dtype=np.float64).reshape(-1, 2)


def _not_found(pattern_size: tuple[int, int]) -> BoardNotFoundError:
    """The error for a checkerboard that is not in the picture, with what to check."""
    cols, rows = pattern_size
    return BoardNotFoundError(
        f"board not found ({cols}x{rows} inner corners): is the whole board in the picture, sharp and evenly lit?"
    )


class _Charuco:
    def __init__(self, board: Board, legacy: bool | str, min_corners: int):
        self.board = board
        squares = self.squares = board.squares
        self.dictionary = board.dictionary
        self.min_corners = int(min_corners)
        if legacy not in (True, False, "auto"):
            raise CalibrationError(f"legacy must be True, False or 'auto', got {legacy!r}")
        # an odd number of rows lays the markers out the same either way
        both = [False, True] if squares[1] % 2 == 0 else [False]
        candidates = both if legacy == "auto" else [bool(legacy)]
        self.detectors = []
        for flag in candidates:
            cv_board = board.cv_board(legacy=flag)
            self.detectors.append((flag, cv_board, _cv_charuco.charuco_detector(cv_board)))
        self.legacy = candidates[0]
        self.auto = len(candidates) > 1
        self.description = board.describe()
        self.n_corners = (squares[0] - 1) * (squares[1] - 1)

    def find_all(self, gray: np.ndarray) -> dict:
        """{legacy flag: points or reason} for every candidate layout."""
        return {flag: self._find(board, det, gray) for flag, board, det in self.detectors}

    def _find(self, board, detector, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
        corners, ids, n_markers = _cv_charuco.detect_charuco(detector, gray)
        if len(ids) < self.min_corners:
            if n_markers == 0:
                return (
                    f"board not found: no {self.dictionary} marker in the picture; check the dictionary "
                    "and that the board is in view and sharp"
                )
            hint = "show more of the board"
            if len(ids) == 0 and n_markers >= 4:
                hint = f"check squares={self.squares} (x, y) against the printed board"
                if self.squares[1] % 2 == 0 and not self.auto:
                    hint = (
                        "a board with an even number of rows printed before OpenCV 4.6 needs "
                        f"legacy={not self.legacy} (or legacy='auto')"
                    )
            return (
                f"board not found: {n_markers} markers but only {len(ids)} chess corners "
                f"(need {self.min_corners}); {hint}"
            )
        obj, img = board.matchImagePoints(
            corners.reshape(-1, 1, 2).astype(np.float32), ids.reshape(-1, 1).astype(np.int32)
        )
        obj = np.asarray(obj, dtype=np.float64).reshape(-1, 3)
        img = np.asarray(img, dtype=np.float64).reshape(-1, 2)
        centred = obj[:, :2] - obj[:, :2].mean(axis=0)
        if np.linalg.svd(centred, compute_uv=False)[-1] < 1e-6 * max(1.0, np.abs(centred).max()):
            return f"board not found: its {len(ids)} chess corners lie on one line; show more of the board"
        return obj, img

    def diagnose(self, grays: list[np.ndarray]) -> str:
        """A hint when the board was found nowhere: squares swapped, or the other marker layout?"""
        x, y = self.squares
        tries = []
        if x != y:
            tries.append(
                (
                    (y, x),
                    self.legacy,
                    f"the board is found with squares=({y}, {x}): squares "
                    "counts (x, y), along the board's width first, as it was generated",
                )
            )
        if not self.auto and y % 2 == 0:
            tries.append(
                (
                    (x, y),
                    not self.legacy,
                    f"the board is found with legacy={not self.legacy}: boards with "
                    "an even number of rows made before OpenCV 4.6 use the legacy layout",
                )
            )
        for squares, legacy, hint in tries:
            detector = _cv_charuco.charuco_detector(replace(self.board, squares=squares).cv_board(legacy=legacy))
            if any(len(_cv_charuco.detect_charuco(detector, g)[1]) >= self.min_corners for g in grays):
                return hint
        return ""
