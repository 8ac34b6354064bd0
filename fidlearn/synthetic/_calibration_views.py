"""Calibration views: a printed checkerboard or ChArUco board held in front of the camera, with the truth."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from .. import _cv, _cv_charuco, frames
from ..calibration.boards import checkerboard_points
from ..camera import Camera
from ..errors import FidlearnError
from ._checks import (
    DEFAULT_GRAYS,
    MAX_FRAMES,
    _check_indices,
    _check_length_mm,
    _check_pattern,
    _check_render_work,
    _check_seed,
)
from ._renderer import _check_render_options, _render, _Sheet


@dataclass(eq=False)
class CalibrationViews:
    """Synthetic calibration pictures of a board, with the truth behind them.

    The world frame is the board's own (OpenCV's object-point frame): x along
    the pattern's rows, y down the board, z into the paper (the printed face
    looks along -z), mm.

    Attributes
    ----------
    images : list of ndarray (H, W) uint8
        The pictures.
    camera : Camera
        The true camera that took them.
    T_world_camera : list of ndarray (4, 4)
        The camera's pose in the board frame (mm), per view.
    object_points : ndarray (N, 3)
        The board's corners in the board frame (mm), in the order OpenCV
        reports them (``cv2.findChessboardCorners`` for a checkerboard,
        ``getChessboardCorners()`` ids 0..N-1 for ChArUco).
    image_points : list of ndarray (N, 2)
        True pixel positions of those corners per view (``cv2.projectPoints``).
    pattern_size : (int, int)
        Checkerboard: inner corners (columns, rows); ChArUco: squares (x, y).
    square_size_mm, marker_size_mm : float
        The printed sizes (``marker_size_mm`` is 0 for a checkerboard).
    charuco : bool
        Whether the board is ChArUco.
    dictionary : str
        ChArUco's marker dictionary ("" for a checkerboard).
    """

    images: list
    camera: Camera
    T_world_camera: list
    object_points: np.ndarray
    image_points: list
    pattern_size: tuple
    square_size_mm: float
    marker_size_mm: float = 0.0
    charuco: bool = False
    dictionary: str = ""
    seed: int = 0
    render_kwargs: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.images)

    @property
    def T_camera_board(self) -> list:
        """The board's pose in each camera frame (4, 4), mm: what ``cv2.calibrateCamera`` estimates."""
        return [frames.invert_transform(T) for T in self.T_world_camera]

    def board(self):
        """The ChArUco board of the views.

        Returns
        -------
        cv2.aruco.CharucoBoard
            Sizes in mm.

        Raises
        ------
        FidlearnError
            For a checkerboard, which has none.
        """
        if not self.charuco:
            raise FidlearnError("a checkerboard has no cv2.aruco board; use pattern_size and square_size_mm")
        return _cv_charuco.charuco_board(self.pattern_size, self.square_size_mm, self.marker_size_mm, self.dictionary)

    def __repr__(self) -> str:
        kind = (
            f"ChArUco {self.pattern_size[0]}x{self.pattern_size[1]} squares, {self.dictionary}"
            if self.charuco
            else f"checkerboard {self.pattern_size[0]}x{self.pattern_size[1]} inner corners"
        )
        w, h = self.camera.image_size
        return (
            f"CalibrationViews({len(self)} views {w}x{h}, {kind}, square {self.square_size_mm:g} mm, {self.camera!r})"
        )


def _checkerboard_sheet(
    pattern_size: tuple[int, int], square_size_mm: float, tps: int, margin_squares: float, grays: dict
) -> _Sheet:
    cols, rows = pattern_size[0] + 1, pattern_size[1] + 1  # squares
    m = int(round(margin_squares * tps))
    jj, ii = np.mgrid[0:rows, 0:cols]
    squares = np.where((ii + jj) % 2 == 0, grays["ink"], grays["paper"]).astype(np.float32)  # top-left square black
    tex = np.full((rows * tps + 2 * m, cols * tps + 2 * m), grays["paper"], dtype=np.float32)
    tex[m : m + rows * tps, m : m + cols * tps] = np.kron(squares, np.ones((tps, tps), dtype=np.float32))
    step = square_size_mm / tps
    # inner corner (0, 0) is the board's origin; the outer edge of the squares is one square before it
    off = 0.5 * step - (square_size_mm + m * step)
    A = np.array([[step, 0.0, off], [0.0, step, off], [0.0, 0.0, 0.0]])
    return _Sheet(tex, A, label="checkerboard")


def _charuco_sheet(
    board, squares_xy: tuple[int, int], square_size_mm: float, tps: int, margin_squares: float, grays: dict
) -> _Sheet:
    m = int(round(margin_squares * tps))
    size = (squares_xy[0] * tps + 2 * m, squares_xy[1] * tps + 2 * m)
    img = board.generateImage(size, marginSize=m, borderBits=1).astype(np.float32) / 255.0
    tex = (grays["ink"] + (grays["paper"] - grays["ink"]) * img).astype(np.float32)
    step = square_size_mm / tps
    off = (0.5 - m) * step  # the board's origin (its top-left outer corner) is texel edge m - 0.5
    A = np.array([[step, 0.0, off], [0.0, step, off], [0.0, 0.0, 0.0]])
    return _Sheet(tex, A, label="charuco")


def _board_pose(
    camera: Camera,
    rng: np.random.Generator,
    target_px,
    distance_mm: float,
    tilt_deg: float,
    roll_deg: float,
    centre_board: np.ndarray,
) -> np.ndarray:
    """``T_camera_board``: the board's centre on the ray through ``target_px`` at ``distance_mm``, tilted."""
    # OpenCV's undistortion aims the board (a sub-pixel miss does not matter; the stored views keep their poses)
    ray = camera.undistort_points(np.asarray(target_px, dtype=float).reshape(1, 2), exact=False)[0]
    ray = np.array([(ray[0] - camera.cx) / camera.fx, (ray[1] - camera.cy) / camera.fy, 1.0])
    centre_cam = ray / np.linalg.norm(ray) * distance_mm
    axis_angle = rng.uniform(0, 2 * math.pi)
    axis = np.array([math.cos(axis_angle), math.sin(axis_angle), 0.0])
    R_tilt, _ = cv2.Rodrigues(axis * math.radians(tilt_deg))
    R = R_tilt @ frames.rot_z(math.radians(roll_deg))
    # face the camera roughly: the board's z (into the paper) along the viewing ray, then tilt
    z = centre_cam / np.linalg.norm(centre_cam)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R_face = np.column_stack([x, y, z])
    R_camera_board = R_face @ R
    t = centre_cam - R_camera_board @ centre_board
    return frames.make_transform(R_camera_board, t)


@dataclass(eq=False)
class _Board:
    """A calibration board's geometry, in its own frame (mm): what the views are made of."""

    pattern_size: tuple
    square_size_mm: float
    marker_size_mm: float | None
    cv_board: Any  # cv2.aruco.CharucoBoard, or None for a checkerboard
    squares: tuple | None  # ChArUco's squares (x, y)
    object_points: np.ndarray  # (N, 3), mm
    centre: np.ndarray  # (3,), mm
    width_mm: float
    outline: np.ndarray  # (4, 3), mm: the part that must stay in view


def _board_geometry(charuco: bool, pattern_size, square_size_mm, marker_size_mm, dictionary) -> _Board:
    """The board's corners, centre, width and outline; ChArUco's defaults filled in."""
    board = squares = None
    pattern_size = _check_pattern(pattern_size, 2)
    square_size_mm = _check_length_mm(square_size_mm, "square_size_mm")
    if marker_size_mm is not None:
        marker_size_mm = _check_length_mm(marker_size_mm, "marker_size_mm")
    if charuco:
        if tuple(pattern_size) == (9, 6):
            pattern_size = (5, 7)
        if square_size_mm == 25.0 and marker_size_mm is None:
            square_size_mm, marker_size_mm = 40.0, 20.0
        if marker_size_mm is None:
            marker_size_mm = square_size_mm / 2
        if not 0 < marker_size_mm < square_size_mm:
            raise FidlearnError(
                f"marker_size_mm ({marker_size_mm}) must be between 0 and square_size_mm ({square_size_mm})"
            )
        board = _cv_charuco.charuco_board(pattern_size, square_size_mm, marker_size_mm, dictionary)
        object_points = np.asarray(board.getChessboardCorners(), dtype=np.float64).reshape(-1, 3)
        squares = tuple(int(v) for v in pattern_size)
        centre = np.array([squares[0] * square_size_mm / 2, squares[1] * square_size_mm / 2, 0.0])
        board_w = squares[0] * square_size_mm
    else:
        pattern_size = tuple(int(v) for v in pattern_size)
        if min(pattern_size) < 2:
            raise FidlearnError(f"pattern_size {pattern_size} must count at least 2 x 2 inner corners")
        object_points = checkerboard_points(pattern_size, square_size_mm)
        centre = np.array([(pattern_size[0] - 1) * square_size_mm / 2, (pattern_size[1] - 1) * square_size_mm / 2, 0.0])
        board_w = (pattern_size[0] + 1) * square_size_mm
    # the outline that must stay in view: the pattern's corners plus a little of the outer squares
    lo, hi = object_points.min(axis=0), object_points.max(axis=0)
    pad = 0.6 * square_size_mm
    outline = np.array(
        [
            [lo[0] - pad, lo[1] - pad, 0],
            [hi[0] + pad, lo[1] - pad, 0],
            [hi[0] + pad, hi[1] + pad, 0],
            [lo[0] - pad, hi[1] + pad, 0],
        ]
    )
    return _Board(pattern_size, square_size_mm, marker_size_mm, board, squares, object_points, centre, board_w, outline)


#: Where the board's centre aims, as fractions of the image (x, y): a 3 x 3 grid, visited in turn.
_GRID = [(gx, gy) for gy in (0.22, 0.5, 0.78) for gx in (0.2, 0.5, 0.8)]


def _place_board(camera: Camera, rng: np.random.Generator, view: int, board: _Board, options: tuple) -> np.ndarray:
    """``T_world_camera`` (board frame, mm) of one view, drawn until the whole outline is in the image."""
    tilt_range_deg, fill_range = options
    w, h = camera.image_size
    gx, gy = _GRID[view % len(_GRID)]
    for attempt in range(200):
        shrink = 1.0 - min(attempt, 100) / 120.0  # pull the target toward the centre if it keeps failing
        jitter = rng.uniform(-0.06, 0.06, size=2) if view >= len(_GRID) else np.zeros(2)
        tx = (0.5 + (gx - 0.5) * shrink + jitter[0]) * (w - 1)
        ty = (0.5 + (gy - 0.5) * shrink + jitter[1]) * (h - 1)
        fill = rng.uniform(*fill_range)
        distance = camera.fx * board.width_mm / (fill * w)
        tilt = rng.uniform(*tilt_range_deg)
        roll = rng.uniform(-20.0, 20.0)
        T_camera_board = _board_pose(camera, rng, (tx, ty), distance, tilt, roll, board.centre)
        T_world_camera = frames.invert_transform(T_camera_board)
        if not np.all(camera.points_in_front(board.outline, T_world_camera, min_depth_mm=50.0)):
            continue
        px = camera.project(board.outline, T_world_camera)
        if np.all((px >= 8) & (px <= [w - 9, h - 9])):
            return T_world_camera
    raise FidlearnError(f"could not place the board in view {view} of a {w}x{h} camera; try a smaller fill_range")


def _board_sheet(board: _Board, charuco: bool, widest_px: float, margin_squares: float, grays: dict) -> _Sheet:
    """One texture for all views, fine enough for the closest one (``widest_px``: its width in sub-pixels)."""
    cells = board.pattern_size[0] if charuco else board.pattern_size[0] + 1
    tps = int(np.clip(math.ceil(widest_px / cells), 8, 160))
    if charuco:
        return _charuco_sheet(board.cv_board, board.squares, board.square_size_mm, tps, margin_squares, grays)
    return _checkerboard_sheet(board.pattern_size, board.square_size_mm, tps, margin_squares, grays)


def _render_view(
    camera: Camera, T_world_camera: np.ndarray, sheet: _Sheet, seed: int, view: int, grays: dict, render_kwargs: dict
) -> np.ndarray:
    """The picture of view ``view``: its own seed and illumination direction, so any view renders alone the same."""
    return _render(
        camera,
        T_world_camera,
        [sheet],
        seed=int(seed) * 1000 + view,
        gradient_angle_deg=(137.5 * view) % 360.0,
        wall_gray=grays["wall"],
        bgr=False,
        **render_kwargs,
    )


def render_calibration_views(
    camera: Camera,
    *,
    n_views: int = 20,
    pattern_size: tuple[int, int] = (9, 6),
    square_size_mm: float = 25.0,
    seed: int = 0,
    charuco: bool = False,
    marker_size_mm: float | None = None,
    dictionary: str = "6X6_250",
    tilt_range_deg: tuple[float, float] = (10.0, 45.0),
    fill_range: tuple[float, float] = (0.35, 0.7),
    margin_squares: float = 1.0,
    blur_px: float = 0.4,
    noise_std_gray: float = 1.5,
    gradient: float = 0.15,
    supersample: int = 4,
    wall_texture_std_gray: float = 3.0,
    views: Sequence[int] | None = None,
) -> CalibrationViews:
    """Pictures of a printed calibration board held as a careful person would, with the truth.

    The board visits the image's corners, edges and centre in turn (a 3 x 3
    grid, then again with jitter), at several distances (it spans
    ``fill_range`` of the image width) and tilted 10 to 45 degrees about a
    random axis, with a random roll of up to 20 degrees. Every corner of the
    pattern stays inside the image.

    Parameters
    ----------
    camera : Camera
        The true camera (its distortion included).
    n_views : int
        How many pictures.
    pattern_size : (int, int)
        Checkerboard: inner corners (columns, rows), OpenCV's ``patternSize``.
        ChArUco: squares (x, y); ``(9, 6)`` is taken to mean the usual
        ``(5, 7)`` when ``charuco=True``.
    square_size_mm : float
        Side of a printed square (mm). ChArUco defaults to 40 mm squares
        with 20 mm markers when ``square_size_mm`` is left at 25.
    seed : int
        Seed of ``numpy.random.default_rng``: poses, wall texture and noise.
    charuco : bool
        A ChArUco board (``cv2.aruco.CharucoBoard``) instead of a checkerboard.
    marker_size_mm, dictionary :
        ChArUco's marker side (default half a square) and dictionary.
    blur_px, noise_std_gray, gradient, supersample, wall_texture_std_gray :
        As for :func:`render_scene`, applied to every view.
    views : sequence of int, optional
        Render only these views (indices into the ``n_views`` poses, which are
        drawn all the same): view ``i`` comes out identical to view ``i`` of
        the full set. The result then holds only those views.

    Returns
    -------
    CalibrationViews
        Images, the true camera, the true poses and corner pixels.

    Raises
    ------
    FidlearnError
        If the board is malformed (fewer than 2 x 2 inner corners, a ChArUco marker not smaller
        than its square), ``n_views`` < 1, a view index does not exist, or the board cannot be
        placed in the picture.

    Examples
    --------
    >>> cam = Camera([[600, 0, 320], [0, 600, 240], [0, 0, 1]], [-0.1, 0.02, 0, 0, 0], (640, 480))
    >>> views = render_calibration_views(cam, n_views=2, seed=1)
    >>> len(views), views.images[0].shape, views.image_points[0].shape
    (2, (480, 640), (54, 2))
    """
    if not isinstance(camera, Camera):
        raise FidlearnError(f"camera must be a fidlearn.Camera, got {type(camera).__name__}")
    if isinstance(n_views, bool) or not isinstance(n_views, (int, np.integer)) or not 1 <= n_views <= MAX_FRAMES:
        raise FidlearnError(f"n_views must be a whole number from 1 to {MAX_FRAMES}, got {n_views!r:.40}")
    chosen = _check_indices(views, n_views, "views")
    _check_render_options(camera, supersample, blur_px, noise_std_gray, wall_texture_std_gray)
    board = _board_geometry(charuco, pattern_size, square_size_mm, marker_size_mm, dictionary)
    _check_render_work(camera, supersample, len(chosen), "views")
    rng = np.random.default_rng(_check_seed(seed))
    w = camera.image_size[0]
    options = (tilt_range_deg, fill_range)
    poses = [_place_board(camera, rng, view, board, options) for view in range(n_views)]
    points = [camera.project(board.object_points, T) for T in poses]
    grays = dict(DEFAULT_GRAYS)
    sheet = _board_sheet(board, charuco, fill_range[1] * w * 1.2 * supersample, margin_squares, grays)
    render_kwargs = dict(
        blur_px=blur_px,
        noise_std_gray=noise_std_gray,
        gradient=gradient,
        supersample=supersample,
        wall_texture_std_gray=wall_texture_std_gray,
    )
    images = [_render_view(camera, poses[view], sheet, seed, view, grays, render_kwargs) for view in chosen]
    return CalibrationViews(
        images=images,
        camera=camera,
        T_world_camera=[poses[v] for v in chosen],
        object_points=board.object_points,
        image_points=[points[v] for v in chosen],
        pattern_size=tuple(board.pattern_size),
        square_size_mm=float(board.square_size_mm),
        marker_size_mm=float(board.marker_size_mm or 0.0),
        charuco=bool(charuco),
        dictionary=_cv.dictionary_name(dictionary) if charuco else "",
        seed=int(seed),
        render_kwargs=render_kwargs,
    )
