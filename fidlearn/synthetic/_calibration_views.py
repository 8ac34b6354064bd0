"""Calibration views: a printed checkerboard or ChArUco board held in front of the camera, with the truth."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from .. import frames
from ..boards import Board
from ..camera import Camera
from ..errors import FidlearnError
from ._checks import (
    DEFAULT_GRAYS,
    MAX_FRAMES,
    _check_indices,
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
    board : Board
        The printed board (``views.board.cv_board()`` is OpenCV's ChArUco board).
    """

    images: list
    camera: Camera
    T_world_camera: list
    object_points: np.ndarray
    image_points: list
    board: Board
    seed: int = 0
    render_kwargs: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.images)

    @property
    def T_camera_board(self) -> list:
        """The board's pose in each camera frame (4, 4), mm: what ``cv2.calibrateCamera`` estimates."""
        return [frames.invert_transform(T) for T in self.T_world_camera]

    def __repr__(self) -> str:
        w, h = self.camera.image_size
        return f"CalibrationViews({len(self)} views {w}x{h}, {self.board.describe()}, {self.camera!r})"


def _checkerboard_sheet(
    squares_xy: tuple[int, int], square_size_mm: float, tps: int, margin_squares: float, grays: dict
) -> _Sheet:
    cols, rows = squares_xy
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
class _Geometry:
    """A calibration board's geometry, in its own frame (mm): what the views are made of."""

    board: Board
    object_points: np.ndarray  # (N, 3), mm
    centre: np.ndarray  # (3,), mm
    width_mm: float
    outline: np.ndarray  # (4, 3), mm: the part that must stay in view


def _board_geometry(board: Board) -> _Geometry:
    """The board's corners, centre, width and outline."""
    if not isinstance(board, Board):
        raise FidlearnError(
            f"board must be a fidlearn.Board (Board.checkerboard(...) or Board.charuco(...)), got {board!r:.60}"
        )
    s = board.square_size_mm
    object_points = board.object_points()
    width_mm = board.squares[0] * s
    # the printed squares' centre; the outline that must stay in view: the corners plus a little of the outer squares
    lo, hi = object_points.min(axis=0), object_points.max(axis=0)
    centre = (lo + hi) / 2
    pad = 0.6 * s
    outline = np.array(
        [
            [lo[0] - pad, lo[1] - pad, 0],
            [hi[0] + pad, lo[1] - pad, 0],
            [hi[0] + pad, hi[1] + pad, 0],
            [lo[0] - pad, hi[1] + pad, 0],
        ]
    )
    return _Geometry(board, object_points, centre, width_mm, outline)


#: Where the board's centre aims, as fractions of the image (x, y): a 3 x 3 grid, visited in turn.
_GRID = [(gx, gy) for gy in (0.22, 0.5, 0.78) for gx in (0.2, 0.5, 0.8)]


def _place_board(camera: Camera, rng: np.random.Generator, view: int, board: _Geometry, options: tuple) -> np.ndarray:
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


def _board_sheet(board: Board, widest_px: float, margin_squares: float, grays: dict) -> _Sheet:
    """One texture for all views, fine enough for the closest one (``widest_px``: its width in sub-pixels)."""
    tps = int(np.clip(math.ceil(widest_px / board.squares[0]), 8, 160))
    if board.is_charuco:
        return _charuco_sheet(board.cv_board(), board.squares, board.square_size_mm, tps, margin_squares, grays)
    return _checkerboard_sheet(board.squares, board.square_size_mm, tps, margin_squares, grays)


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
    board: Board | None = None,
    seed: int = 0,
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
    board : Board, optional
        The printed board: ``Board.checkerboard((9, 6), 25)`` when not given;
        a ChArUco board (``Board.charuco((5, 7), 40, 20)``) renders
        ``cv2.aruco.CharucoBoard``'s own picture.
    seed : int
        Seed of ``numpy.random.default_rng``: poses, wall texture and noise.
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
        If ``board`` is not a :class:`~fidlearn.Board`, ``n_views`` < 1, a view index does not
        exist, or the board cannot be placed in the picture.

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
    geometry = _board_geometry(Board.checkerboard((9, 6), 25.0) if board is None else board)
    _check_render_work(camera, supersample, len(chosen), "views")
    rng = np.random.default_rng(_check_seed(seed))
    w = camera.image_size[0]
    options = (tilt_range_deg, fill_range)
    poses = [_place_board(camera, rng, view, geometry, options) for view in range(n_views)]
    points = [camera.project(geometry.object_points, T) for T in poses]
    grays = dict(DEFAULT_GRAYS)
    sheet = _board_sheet(geometry.board, fill_range[1] * w * 1.2 * supersample, margin_squares, grays)
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
        object_points=geometry.object_points,
        image_points=[points[v] for v in chosen],
        board=geometry.board,
        seed=int(seed),
        render_kwargs=render_kwargs,
    )
