"""Camera calibration from photos of a checkerboard or a ChArUco board.

Calibration finds the camera's intrinsics ``K`` and lens distortion from
several views of a flat board whose geometry is known: each view gives
pairs (board point in mm, its pixel), and ``cv2.calibrateCamera`` finds the
camera (and each view's board pose) that reprojects the board points onto
their pixels best. The result is a :class:`Calibration`: the
:class:`~fidlearn.camera.Camera`, the reprojection error overall and per
view, the standard deviations of the intrinsics, and every rejected image
with its reason.

How the checkerboard corners are found, and why
-----------------------------------------------
``cv2.findChessboardCorners`` then ``cv2.cornerSubPix``, the recipe of
OpenCV's own calibration sample, with the refinement window capped so it
cannot reach the next corner: half-size ``min(11, floor(0.6 * s))`` px, ``s``
the shortest corner spacing in the view (the sample's fixed 11 whenever
squares are at least 19 px apart). Measured with OpenCV 5.0
(``benchmarks/bench_calibration.py`` repeats these):

* ``data/calibration`` (20 synthetic 640x480 views, true corners known):
  corners 0.046 px RMS from the truth (max 0.12), fx 0.01 % off, 0.2 s;
  ``cv2.findChessboardCornersSB`` with ``CALIB_CB_ACCURACY``: 0.096 px RMS
  (max 0.39), fx 0.43 % off, about 40 times slower.
* A harder rendered set (20 views, k1 = -0.28, blur 1 px, tilts 30 to 55
  degrees, squares 8 to 22 px apart at their narrowest): this recipe
  0.036 px RMS, fx 0.01 % off; OpenCV's fixed 11 px half-window reaches the
  next corner on the small squares: corners 3.4 px RMS (12 px at worst), fx
  8 % off; the sector detector 0.15 px, fx 0.3 % off.
* OpenCV's 13 ``right*.jpg`` photos: this recipe finds the board in all 13
  and agrees with OpenCV's sample exactly (fx 542.35, RMS 0.459 px); the
  sector detector misses one and lands 1.4 % lower in fx (534.6) with a
  lower RMS (0.25 px), which the synthetic bias above suggests is not a
  better camera.

``corner_finder="sb"`` selects ``findChessboardCornersSB`` for comparison
(both finders exist unchanged from OpenCV 4.0 to 5.x).

ChArUco
-------
``cv2.aruco.CharucoDetector`` finds the markers and interpolates the chess
corners between them (each corner has an id, so a partly hidden board still
counts); ``board.matchImagePoints`` pairs them with the board's points; then
the same ``cv2.calibrateCamera``. Boards printed before OpenCV 4.6 with an
even number of rows use another marker layout (``legacy=True``); the
default ``legacy="auto"`` tries both on such boards and keeps the one that
finds more corners (for an odd number of rows the layouts are the same).

Outlier views
-------------
After a first calibration, a view whose RMS reprojection error exceeds
``max(3 x median, median + 0.5 px)`` (median over the views) is rejected and
the camera is calibrated again without it, once. A blurred photo or a
mis-refined corner shows up this way; the rejection is reported with the
view's error.

Board frame (``T_camera_board``), mm, z into the paper: a checkerboard's
origin is the first inner corner OpenCV reports, x along the pattern's first
row, y down the board (the pattern is symmetric, so a view's origin may sit at
the opposite end of the board); a ChArUco board's is its own: the outer corner
of the top-left square, x along the top edge (``board.getChessboardCorners()``).
"""

from __future__ import annotations

import math
import os
import warnings
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from . import _cv, frames
from .camera import Camera
from .detection import as_gray, load_image
from .errors import CalibrationError, FidlearnWarning, ImageError

__all__ = [
    "Calibration",
    "ViewResult",
    "calibrate_checkerboard",
    "calibrate_charuco",
    "find_checkerboard_corners",
    "MIN_VIEWS",
]

#: Fewest usable views a calibration accepts.
MIN_VIEWS = 3

#: Names of ``cv2.calibrateCameraExtended``'s ``stdDeviationsIntrinsics`` entries, in order.
INTRINSIC_NAMES = (
    "fx",
    "fy",
    "cx",
    "cy",
    "k1",
    "k2",
    "p1",
    "p2",
    "k3",
    "k4",
    "k5",
    "k6",
    "s1",
    "s2",
    "s3",
    "s4",
    "tau_x",
    "tau_y",
)

#: Outlier rule: a view is an outlier above max(OUTLIER_FACTOR * median, median + OUTLIER_MARGIN_PX).
OUTLIER_FACTOR = 3.0
OUTLIER_MARGIN_PX = 0.5

_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm")
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)

ProgressFn = Callable[[int, int, str], Any]


# ----------------------------------------------------------------------------------------------
# Results
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ViewResult:
    """What happened to one input image.

    Attributes
    ----------
    name : str
        The image's path as given, or ``"image i"`` (i counted from 0) for an array.
    status : str
        ``"used"``, ``"not found"``, ``"outlier"``, ``"duplicate"`` (the board where an earlier
        view had it, with ``reject_duplicates=True``), ``"other size"`` or ``"unreadable"``.
    n_points : int
        Board points found (0 when the board was not found or the image not read).
    rms_px : float or None
        RMS reprojection error of the view's points (px); for an outlier, its
        error in the first calibration. None when the board was not found.
    reason : str
        Why the view was rejected ("" when used).
    """

    name: str
    status: str
    n_points: int = 0
    rms_px: float | None = None
    reason: str = ""

    @property
    def found(self) -> bool:
        return self.n_points > 0


@dataclass(eq=False, repr=False)
class Calibration:
    """The outcome of a calibration run.

    Attributes
    ----------
    camera : Camera
        The calibrated camera; its ``source`` describes the run.
    rms_px : float
        RMS reprojection error over every point of the used views (px), as
        ``cv2.calibrateCamera`` returns it.
    per_view_rms_px : dict {str: float}
        RMS reprojection error of each used view (px), by name.
    used : list of str
        Names of the views the camera was computed from, in input order.
    std_intrinsics : dict {str: float}
        Standard deviations of ``fx, fy, cx, cy`` (px) and of the distortion
        coefficients ``k1, k2, p1, p2, k3, ...`` (``stdDeviationsIntrinsics``
        of ``cv2.calibrateCameraExtended``).
    rejected : list of (str, str)
        ``(name, reason)`` for every image not used.
    T_camera_board : dict {str: ndarray (4, 4)}
        Each used view's board pose in the camera frame (mm); see the module
        docstring for the board frame.
    views : list of ViewResult
        Every input image, in input order (for :meth:`table`).
    board : str
        The board, in words.
    image_points_px : dict {str: ndarray (N, 2)}
        Each used view's detected board points (px, pixel centres at integers).
    board_points_mm : dict {str: ndarray (N, 3)}
        The same points on the board (mm, board frame, z = 0).
    first_rms_px : float or None
        RMS of the first calibration, before outlier views were removed
        (None when none were).
    """

    camera: Camera
    rms_px: float
    per_view_rms_px: dict
    used: list
    std_intrinsics: dict
    rejected: list
    T_camera_board: dict = field(default_factory=dict)
    views: list = field(default_factory=list)
    board: str = ""
    image_points_px: dict = field(default_factory=dict)
    board_points_mm: dict = field(default_factory=dict)
    first_rms_px: float | None = None

    @property
    def T_board_camera(self) -> dict:
        """Each used view's camera pose in the board frame (4, 4), mm."""
        return {name: frames.invert_transform(T) for name, T in self.T_camera_board.items()}

    def table(self) -> str:
        """A text table of every input image: name, found, points, RMS (px), status and reason."""
        names, folder = _display_names([v.name for v in self.views])
        wn = max([4] + [len(n) for n in names])
        lines = [f"views in {folder}"] if folder else []
        lines.append(f"{'view':<{wn}}  found  points  rms px  status")
        for n, v in zip(names, self.views):
            rms = f"{v.rms_px:6.3f}" if v.rms_px is not None else "     -"
            status = v.status if not v.reason else f"{v.status}: {v.reason}"
            lines.append(f"{n:<{wn}}  {'yes' if v.found else 'no':<5}  {v.n_points:6d}  {rms}  {status}")
        return "\n".join(lines)

    def summary(self) -> str:
        """The camera, its uncertainty, and the table of views."""
        s = self.std_intrinsics
        std = ", ".join(f"{k} {s[k]:.2f}" for k in ("fx", "fy", "cx", "cy") if k in s)
        head = [
            f"Calibration of {self.board}: {len(self.used)} of {len(self.views)} views used, RMS {self.rms_px:.3f} px",
            f"  {self.camera!r}",
            f"  standard deviations (px): {std}",
        ]
        if self.first_rms_px is not None:
            head.append(f"  RMS before removing outlier views: {self.first_rms_px:.3f} px")
        if "fx" in s and s["fx"] > 0.01 * self.camera.fx:
            head.append(
                f"  fx is uncertain to {100 * s['fx'] / self.camera.fx:.1f} %: add views with the board "
                "tilted in other directions and nearer the image's corners"
            )
        return "\n".join(head) + "\n" + self.table()

    def __repr__(self) -> str:
        c = self.camera
        s = self.std_intrinsics
        rej = f", rejected={[n for n, _ in self.rejected]}" if self.rejected else ""
        return (
            f"Calibration({len(self.used)}/{len(self.views)} views, rms={self.rms_px:.3f} px, "
            f"fx={c.fx:.2f}±{s.get('fx', float('nan')):.2f}, fy={c.fy:.2f}±{s.get('fy', float('nan')):.2f}, "
            f"cx={c.cx:.2f}±{s.get('cx', float('nan')):.2f}, cy={c.cy:.2f}±{s.get('cy', float('nan')):.2f}, "
            f"dist=[{', '.join(f'{v:.4g}' for v in c.dist)}], {c.width}x{c.height}{rej})"
        )

    def _repr_pretty_(self, p, cycle) -> None:  # IPython / Jupyter: the full summary
        p.text(repr(self) if cycle else self.summary())


def _display_names(names: list[str]) -> tuple[list[str], str]:
    """Names without the folder they all share (and that folder), for a narrower table."""
    dirs = {os.path.dirname(n) for n in names if not n.startswith("image ")}
    if len(dirs) == 1 and all(not n.startswith("image ") for n in names) and next(iter(dirs)):
        folder = next(iter(dirs))
        return [_short(os.path.basename(n)) for n in names], folder
    return [_short(n) for n in names], ""


def _short(name: str, width: int = 40) -> str:
    return name if len(name) <= width else "..." + name[-(width - 3) :]


# ----------------------------------------------------------------------------------------------
# Inputs
# ----------------------------------------------------------------------------------------------


def _entries(images: Any) -> list[tuple[str, Any]]:
    """(name, path or array) for each input; a folder or a glob pattern expands to its image files, sorted."""
    if isinstance(images, (str, os.PathLike)):
        folder = Path(images)
        if folder.is_dir():
            files = sorted(p for p in folder.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES)
            if not files:
                raise CalibrationError(f"{folder}: no image files (.png, .jpg, ...) in this folder")
            images = files
        elif any(ch in str(images) for ch in "*?[") and not folder.exists():
            import glob as _glob

            files = sorted(_glob.glob(str(images)))
            if not files:
                raise CalibrationError(f"{images}: no file matches this pattern; check the folder and the extension")
            images = files
        else:
            images = [images]
    elif isinstance(images, np.ndarray):
        if images.ndim == 2 or (images.ndim == 3 and images.shape[2] in (1, 3, 4)):
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
            f"give millimetres ({value_mm * 1000:g}; command line: --square-mm): K is right either way, but every distance (the board "
            "poses, and the poses computed from them) comes out 1000 times too small",
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
    if cols < 3 or rows < 3:
        raise CalibrationError(
            f"pattern_size {(cols, rows)} counts inner corners and needs at least 3 each way; "
            "a board of 10x7 squares has 9x6 inner corners"
        )
    return cols, rows


# ----------------------------------------------------------------------------------------------
# Board finders: gray image -> (board points mm (N, 3), pixels (N, 2)) or a reason
# ----------------------------------------------------------------------------------------------


class _Checkerboard:
    def __init__(self, pattern_size: tuple[int, int], square_size_mm: float, corner_finder: str):
        self.pattern_size = pattern_size
        self.square_size_mm = square_size_mm
        if corner_finder not in ("classic", "sb"):
            raise CalibrationError(f"corner_finder {corner_finder!r} is unknown; use 'classic' or 'sb'")
        self.corner_finder = corner_finder
        cols, rows = pattern_size
        jj, ii = np.mgrid[0:rows, 0:cols]
        self.object_points = np.column_stack([ii.ravel(), jj.ravel(), np.zeros(ii.size)]) * square_size_mm
        self.description = f"checkerboard {cols}x{rows} inner corners, {square_size_mm:g} mm squares"

    def find(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
        corners = find_checkerboard_corners(gray, self.pattern_size, self.corner_finder)
        if corners is None:
            cols, rows = self.pattern_size
            return (
                f"board not found ({cols}x{rows} inner corners): is the whole board in the picture, "
                "sharp and evenly lit?"
            )
        return self.object_points, corners

    def diagnose(self, grays: list[np.ndarray]) -> str:
        """A hint when the board was found nowhere: squares counted instead of inner corners?"""
        cols, rows = self.pattern_size
        if cols - 1 < 3 or rows - 1 < 3:
            return ""
        for gray in grays:
            if find_checkerboard_corners(gray, (cols - 1, rows - 1), "classic", refine=False) is not None:
                example = "" if (cols, rows) == (10, 7) else " (a board of 10x7 squares has 9x6 inner corners)"
                return (
                    f"the board is found with pattern_size=({cols - 1}, {rows - 1}) (command line: --pattern "
                    f"{cols - 1}x{rows - 1}): pattern_size counts inner corners, not squares: a board of "
                    f"{cols}x{rows} squares has {cols - 1}x{rows - 1} inner corners{example}"
                )
        return ""


def find_checkerboard_corners(
    gray: np.ndarray, pattern_size: tuple[int, int], corner_finder: str = "classic", refine: bool = True
) -> np.ndarray | None:
    """Inner corners of a checkerboard, (cols * rows, 2) float64 px in OpenCV's order, or None.

    ``"classic"``: ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix`` with
    the half-window ``min(11, floor(0.6 * s))``, ``s`` the shortest spacing
    between neighbouring corners (px); ``"sb"``: ``cv2.findChessboardCornersSB``
    with ``CALIB_CB_ACCURACY``. Pixel centres at integer coordinates.
    """
    cols, rows = pattern_size
    if corner_finder == "sb":
        flags = cv2.CALIB_CB_ACCURACY | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE
        ok, corners = cv2.findChessboardCornersSB(gray, (cols, rows), flags=flags)
        return np.asarray(corners, dtype=np.float64).reshape(-1, 2) if ok else None
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, corners = cv2.findChessboardCorners(gray, (cols, rows), flags=flags)
    if not ok or corners is None:
        return None
    if not refine:
        return np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    grid = corners.reshape(rows, cols, 2)
    spacing = min(
        np.linalg.norm(np.diff(grid, axis=1), axis=2).min(), np.linalg.norm(np.diff(grid, axis=0), axis=2).min()
    )
    half = int(np.clip(math.floor(0.6 * spacing), 2, 11))
    corners = cv2.cornerSubPix(gray, corners.astype(np.float32), (half, half), (-1, -1), _SUBPIX_CRITERIA)
    return np.asarray(corners, dtype=np.float64).reshape(-1, 2)


class _Charuco:
    def __init__(
        self,
        squares: tuple[int, int],
        square_size_mm: float,
        marker_size_mm: float,
        dictionary: str,
        legacy: bool | str,
        min_corners: int,
    ):
        self.squares = squares
        self.square_size_mm, self.marker_size_mm = square_size_mm, marker_size_mm
        self.dictionary = _cv.dictionary_name(dictionary)
        self.min_corners = int(min_corners)
        if legacy not in (True, False, "auto"):
            raise CalibrationError(f"legacy must be True, False or 'auto', got {legacy!r}")
        # an odd number of rows lays the markers out the same either way
        if legacy == "auto":
            candidates = [False, True] if squares[1] % 2 == 0 else [False]
        else:
            candidates = [bool(legacy)]
        self.detectors = []
        for flag in candidates:
            board = _cv.charuco_board(squares, square_size_mm, marker_size_mm, self.dictionary, legacy=flag)
            self.detectors.append((flag, board, _cv.charuco_detector(board)))
        self.legacy = candidates[0]
        self.auto = len(candidates) > 1
        self.description = (
            f"ChArUco {squares[0]}x{squares[1]} squares, {square_size_mm:g} mm squares, "
            f"{marker_size_mm:g} mm markers, {self.dictionary}"
        )
        self.n_corners = (squares[0] - 1) * (squares[1] - 1)

    def find_all(self, gray: np.ndarray) -> dict:
        """{legacy flag: points or reason} for every candidate layout."""
        return {flag: self._find(board, det, gray) for flag, board, det in self.detectors}

    def _find(self, board, detector, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
        corners, ids, n_markers = _cv.detect_charuco(detector, gray)
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
            board = _cv.charuco_board(squares, self.square_size_mm, self.marker_size_mm, self.dictionary, legacy=legacy)
            detector = _cv.charuco_detector(board)
            if any(len(_cv.detect_charuco(detector, g)[1]) >= self.min_corners for g in grays):
                return hint
        return ""


# ----------------------------------------------------------------------------------------------
# The run
# ----------------------------------------------------------------------------------------------


@dataclass
class _View:
    name: str
    status: str = "used"
    reason: str = ""
    size: tuple[int, int] | None = None
    points: dict = field(default_factory=dict)  # layout key -> (obj, img) or reason
    obj: np.ndarray | None = None
    img: np.ndarray | None = None
    rms_px: float | None = None
    n_found: int = 0


def _read_gray(name: str, item: Any) -> np.ndarray:
    image = load_image(item) if isinstance(item, (str, os.PathLike)) else item
    return as_gray(image, where=name)


def _detect_all(entries, find: Callable[[np.ndarray], dict], progress: ProgressFn | None, keep_failed: int = 3):
    """Detect the board in every entry; returns views and up to ``keep_failed`` gray images where nothing was found."""
    views: list[_View] = []
    failed_grays: list[np.ndarray] = []
    n = len(entries)
    for i, (name, item) in enumerate(entries):
        view = _View(name)
        try:
            gray = _read_gray(name, item)
        except ImageError as exc:
            view.status, view.reason = "unreadable", str(exc)
        else:
            view.size = (gray.shape[1], gray.shape[0])
            view.points = find(gray)
            if all(isinstance(p, str) for p in view.points.values()) and len(failed_grays) < keep_failed:
                failed_grays.append(gray)
        views.append(view)
        if progress is not None:
            progress(i + 1, n, name)
    return views, failed_grays


def _choose_size(views: list[_View]) -> tuple[int, int] | None:
    sizes = [v.size for v in views if v.size is not None]
    if not sizes:
        return None
    counts = Counter(sizes)
    best = max(counts.values())
    return next(s for s in sizes if counts[s] == best)  # the most common; on a tie, the first seen


def _reject_duplicates(views: list[_View], tol_px: float = 1.0) -> None:
    """Reject views whose board sits where an earlier view's did: they add no information, only weight."""
    kept: list[_View] = []
    for v in views:
        if v.status != "used":
            continue
        for k in kept:
            if k.img.shape != v.img.shape or not np.allclose(k.obj, v.obj):
                continue
            d = min(np.abs(k.img - v.img).max(), np.abs(k.img[::-1] - v.img).max())
            if d < tol_px:
                v.status = "duplicate"
                v.reason = (
                    f"the board sits where it sat in {k.name} (every corner within {tol_px:g} px): "
                    "move or tilt the board between photos"
                )
                break
        else:
            kept.append(v)


def _calibrate_points(obj: list, img: list, image_size, flags: int, criteria):
    args = dict(flags=int(flags))
    if criteria is not None:
        args["criteria"] = criteria
    try:
        out = cv2.calibrateCameraExtended(
            [o.astype(np.float32).reshape(-1, 1, 3) for o in obj],
            [p.astype(np.float32).reshape(-1, 1, 2) for p in img],
            tuple(int(v) for v in image_size),
            None,
            None,
            **args,
        )
    except cv2.error as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "failed"
        raise CalibrationError(
            f"cv2.calibrateCamera failed ({msg}); take more views with the board tilted in different directions"
        ) from None
    rms, K, dist, rvecs, tvecs, std_int, _std_ext, per_view = out
    return (
        float(rms),
        K,
        np.asarray(dist, dtype=np.float64).reshape(-1),
        rvecs,
        tvecs,
        np.asarray(std_int).reshape(-1),
        np.asarray(per_view).reshape(-1),
    )


def _too_few(views: list[_View], size, hint: str, min_views: int) -> CalibrationError:
    n_used = sum(v.status == "used" for v in views)
    groups: dict[str, list[str]] = {}
    for v in views:
        if v.status != "used":
            groups.setdefault(v.status, []).append(v.name)
    parts = []
    for status, names in groups.items():
        shown = ", ".join(_short(os.path.basename(n) or n, 30) for n in names[:4]) + (", ..." if len(names) > 4 else "")
        first = next(v.reason for v in views if v.status == status)
        parts.append(f"{status}: {len(names)} ({shown}; {first})")
    why = "; ".join(parts) if parts else "no images were given"
    fix = hint[0].upper() + hint[1:] + ". " if hint else ""
    return CalibrationError(
        f"calibration needs at least {min_views} views with the board found, got {n_used} of {len(views)}: {why}. "
        f"{fix}Take 10 to 20 sharp photos of the whole board at different tilts and positions"
    )


def _run(
    entries,
    finder,
    find: Callable,
    progress,
    reject_outliers: bool,
    flags: int,
    criteria,
    kind: str,
    reject_duplicates: bool = False,
    min_views: int = MIN_VIEWS,
) -> Calibration:
    if not entries:
        raise CalibrationError(f"no images given; calibration needs at least {min_views} views of the board")
    views, failed_grays = _detect_all(entries, find, progress)

    # one layout for every view (ChArUco legacy 'auto': the one that finds more corners)
    keys = list(next((v.points for v in views if v.points), {0: None}).keys())
    if len(keys) > 1:
        totals = {
            k: sum(len(v.points[k][0]) for v in views if v.points and not isinstance(v.points[k], str)) for k in keys
        }
        key = max(keys, key=lambda k: totals[k])
        finder.legacy = key
    else:
        key = keys[0]
    for v in views:
        if v.status != "used":
            continue
        found = v.points[key]
        if isinstance(found, str):
            v.status, v.reason = "not found", found
        else:
            v.obj, v.img = found
            v.n_found = len(v.img)

    size = _choose_size(views)
    for v in views:
        if v.size is not None and v.size != size:
            v.status = "other size"
            v.reason = (
                f"image is {v.size[0]}x{v.size[1]} but the others are {size[0]}x{size[1]}; "
                "calibrate at the resolution you run at, with every photo at that one resolution"
            )
            v.obj = v.img = None

    if reject_duplicates:
        _reject_duplicates(views)
    usable = [v for v in views if v.status == "used"]
    if len(usable) < min_views:
        hint = finder.diagnose(failed_grays) if not usable else ""
        raise _too_few(views, size, hint, min_views)

    rms, K, dist, rvecs, tvecs, std, per_view = _calibrate_points(
        [v.obj for v in usable], [v.img for v in usable], size, flags, criteria
    )
    first_rms = None
    if reject_outliers and len(usable) > min_views:
        med = float(np.median(per_view))
        limit = max(OUTLIER_FACTOR * med, med + OUTLIER_MARGIN_PX)
        bad = [i for i, e in enumerate(per_view) if e > limit]
        if bad and len(usable) - len(bad) >= min_views:
            for i in bad:
                v = usable[i]
                v.status, v.rms_px = "outlier", float(per_view[i])
                v.reason = (
                    f"reprojection RMS {per_view[i]:.2f} px, above {limit:.2f} px "
                    f"(max of {OUTLIER_FACTOR:g} x the median {med:.2f} px and median + {OUTLIER_MARGIN_PX:g} px): "
                    "blurred, or a corner found in the wrong place?"
                )
            first_rms = rms
            usable = [v for v in views if v.status == "used"]
            rms, K, dist, rvecs, tvecs, std, per_view = _calibrate_points(
                [v.obj for v in usable], [v.img for v in usable], size, flags, criteria
            )

    T_camera_board = {}
    for v, e, r, t in zip(usable, per_view, rvecs, tvecs):
        v.rms_px = float(e)
        T_camera_board[v.name] = frames.transform_from_rvec_tvec(np.asarray(r).reshape(3), np.asarray(t).reshape(3))
    names = INTRINSIC_NAMES[: 4 + len(dist)]
    std_intrinsics = {n: float(s) for n, s in zip(names, std)}
    board = finder.description + (", legacy layout" if getattr(finder, "legacy", False) else "")
    source = f"{kind}: {len(usable)} of {len(views)} views of a {board}, RMS {rms:.3f} px, OpenCV {cv2.__version__}"
    camera = Camera(K, dist, size, source=source)
    return Calibration(
        camera=camera,
        rms_px=rms,
        per_view_rms_px={v.name: v.rms_px for v in usable},
        used=[v.name for v in usable],
        std_intrinsics=std_intrinsics,
        rejected=[(v.name, f"{v.status}: {v.reason}") for v in views if v.status != "used"],
        T_camera_board=T_camera_board,
        views=[ViewResult(v.name, v.status, v.n_found, v.rms_px, v.reason) for v in views],
        board=board,
        image_points_px={v.name: v.img for v in usable},
        board_points_mm={v.name: v.obj for v in usable},
        first_rms_px=first_rms,
    )


# ----------------------------------------------------------------------------------------------
# Public functions
# ----------------------------------------------------------------------------------------------


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

    Raises
    ------
    CalibrationError
        Bad arguments, or fewer than 3 usable views (the message says why
        the others failed, and suggests the inner-corner count when the
        squares were counted instead).

    Examples
    --------
    >>> from fidlearn import Camera, synthetic
    >>> truth = Camera([[600, 0, 320], [0, 600, 240], [0, 0, 1]], [-0.1, 0.02, 0, 0, 0], (640, 480))
    >>> views = synthetic.render_calibration_views(truth, n_views=6, seed=1)
    >>> cal = calibrate_checkerboard(views.images, (9, 6), 25.0)
    >>> abs(cal.camera.fx / 600 - 1) < 0.01, len(cal.used)
    (True, 6)
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
    dictionary: str = "6X6_250",
    *,
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
