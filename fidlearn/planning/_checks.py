"""Checks of what the planning functions are given: each says which argument is wrong and how to mend it."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from .. import frames
from .._camera_checks import refuse_fisheye
from ..camera import Camera
from ..errors import CalibrationError, FidlearnError, PoseError

#: Most views the coach judges, and most board points a view may have (a 9x6 board has 54).
MAX_VIEWS, MAX_BOARD_POINTS = 1000, 5000


def is_number(value) -> bool:
    """A real number (not a bool, not a string)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def check_number(value, name: str, low: float, high: float, error=FidlearnError, unit: str = "") -> float:
    """``value`` as a float if it is a finite number with ``low <= value <= high``, else ``error``."""
    if not is_number(value) or not low <= value <= high:  # NaN fails the comparison
        raise error(f"{name} must be a number from {low:g} to {high:g}{unit}, got {value!r}")
    return float(value)


def check_camera(camera, error=CalibrationError, *, allow_fisheye: bool = False) -> Camera:
    """``camera`` if it is a :class:`~fidlearn.Camera` (a fisheye only with ``allow_fisheye``)."""
    if not isinstance(camera, Camera):
        raise error(f"camera must be a fidlearn.Camera (Camera.load(path) reads one), got {type(camera).__name__}")
    if not allow_fisheye:
        refuse_fisheye(camera, "the planner", error)
    return camera


def float_array(value, name: str, shape: tuple, error=FidlearnError) -> np.ndarray:
    """``value`` as a finite float array of ``shape`` (``-1``: any length, at least 1)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        a = None
    want = ", ".join("N" if s == -1 else str(s) for s in shape) + ("," if len(shape) == 1 else "")
    ok = a is not None and a.ndim == len(shape) and all(s in (-1, n) for s, n in zip(shape, a.shape))
    if a is None or not ok or a.size == 0:
        got = "nothing usable" if a is None else f"shape {a.shape}"
        raise error(f"{name} must be an array of shape ({want}) of numbers, got {got}")
    if not np.all(np.isfinite(a)):
        raise error(f"{name} holds NaN or infinity; give finite numbers")
    return a


def check_views(camera, board_points_mm, image_points_px, T_camera_board, *, pixels: bool = True) -> tuple:
    """The coach's inputs, checked: the camera and three dicts by view name of float arrays.

    Returns ``(board, image, poses)``; ``image`` is empty without ``pixels``.
    """
    check_camera(camera, allow_fisheye=True)  # the coach and the bent-board test model both lenses
    given = [("board_points_mm", board_points_mm), ("T_camera_board", T_camera_board)]
    if pixels:
        given.append(("image_points_px", image_points_px))
    for name, d in given:
        if not isinstance(d, Mapping):
            raise CalibrationError(
                f"{name} must be a dict by view name, as a Calibration holds it (calibration.{name}), "
                f"got {type(d).__name__}"
            )
    names = list(T_camera_board)
    if len(names) > MAX_VIEWS:
        raise CalibrationError(f"T_camera_board has {len(names)} views, more than {MAX_VIEWS}: judge fewer views")
    board, image, poses = {}, {}, {}
    for n in names:
        for name, d in given[:1] + given[2:]:
            if n not in d:
                raise CalibrationError(f"view {n!r} of T_camera_board is missing from {name}: give every view in all")
        board[n] = _board(board_points_mm[n], f"board_points_mm[{n!r}]")
        if pixels:
            image[n] = float_array(image_points_px[n], f"image_points_px[{n!r}]", (len(board[n]), 2), CalibrationError)
            _within(image[n], f"image_points_px[{n!r}]", "px")
        T = float_array(T_camera_board[n], f"T_camera_board[{n!r}]", (4, 4), CalibrationError)
        poses[n] = frames.check_transform(T, f"T_camera_board[{n!r}]")
        _within(T[:3, 3], f"T_camera_board[{n!r}]'s translation", "mm")
        if T[2, 3] <= 0:
            raise CalibrationError(f"T_camera_board[{n!r}] puts the board behind the camera (z <= 0): give its pose")
    return board, image, poses


#: Largest coordinate (mm or px) the coach takes: 1000 km, a billion pixels.
MAX_COORD = 1e9


def _within(a: np.ndarray, name: str, unit: str) -> None:
    if np.max(np.abs(a)) > MAX_COORD:
        raise CalibrationError(f"{name} has a value beyond {MAX_COORD:g} {unit}: give it in {unit}")


def _board(points, name: str) -> np.ndarray:
    """A view's board points: (N, 3), 4 to MAX_BOARD_POINTS of them, not all at one place."""
    P = float_array(points, name, (-1, 3), CalibrationError)
    if not 4 <= len(P) <= MAX_BOARD_POINTS:
        raise CalibrationError(
            f"{name} has {len(P)} points: a board has from 4 to {MAX_BOARD_POINTS} (a 9x6 board has 54)"
        )
    _within(P, name, "mm")
    if np.ptp(P[:, :2], axis=0).min() <= 0:
        raise CalibrationError(f"{name}: the points lie on one line or one spot; give the board's corners (x, y, 0)")
    return P


def check_grid(grid) -> tuple[int, int]:
    """A grid of (columns, rows) cells, each from 1 to 200."""
    try:
        cols, rows = grid
        ok = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and 1 <= v <= 200 for v in (cols, rows))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise CalibrationError(f"grid must be two whole numbers (columns, rows) from 1 to 200, got {grid!r}")
    return int(cols), int(rows)


def check_covariance(covariance, n: int) -> np.ndarray:
    """An (n, n) finite covariance of the camera's ``n`` intrinsics."""
    C = float_array(covariance, "covariance", (n, n), CalibrationError)
    return C


def finite_distance(distance_mm) -> float:
    """A positive distance (mm) up to 1e9."""
    d = check_number(distance_mm, "distance_mm", 0.0, 1e9, CalibrationError, " mm")
    if d <= 0 or not math.isfinite(d):
        raise CalibrationError(f"distance_mm must be a positive number of mm, got {distance_mm!r}")
    return d


def check_flip_inputs(points_world, points_px, camera, corner_sigma_px) -> tuple:
    """The inputs of :func:`~fidlearn.planning.flip_probability`, checked: (N, 3), (N, 2) and (N,) float arrays."""
    check_camera(camera, PoseError, allow_fisheye=True)
    P = float_array(points_world, "points_world", (-1, 3), PoseError)
    if not 4 <= len(P) <= 10_000:
        raise PoseError(f"points_world has {len(P)} points: give 4 to 10000 marker corners")
    q = float_array(points_px, "points_px", (len(P), 2), PoseError)
    s = float_array(corner_sigma_px, "corner_sigma_px", (len(P),), PoseError)
    if np.any(s <= 0) or np.max(np.abs(P)) > 1e9 or np.max(np.abs(q)) > 1e9:
        raise PoseError("corner_sigma_px must be positive and the points within 1e9 mm and px: check the units")
    return P, q, s


#: Largest corner noise or marker shift (px) a prediction takes: beyond it no detector finds a marker.
MAX_NOISE_PX = 100.0


def _check_px(value, name: str, zero: bool) -> None:
    """A positive (or, with ``zero``, non-negative) number of pixels up to :data:`MAX_NOISE_PX`, or None."""
    if value is None:
        return
    ok = isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or value < 0 or (value == 0 and not zero) or value > MAX_NOISE_PX:
        what = "non-negative" if zero else "positive"
        raise FidlearnError(f"{name} must be a {what} number of pixels up to {MAX_NOISE_PX:g}, got {value!r}")


def _check_rel(value, name: str, signed: bool = False) -> float:
    """A relative size error: a number from 0 (or, ``signed``, above -0.5) up to below 0.5; None counts as 0."""
    if value is None:
        return 0.0
    ok = isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or not ((value > -0.5) if signed else (value >= 0)) or value >= 0.5:
        span = "above -0.5 to below 0.5 (-0.01 for 1 % smaller)" if signed else "0 to below 0.5 (0.01 for 1 %)"
        raise FidlearnError(f"{name} must be a fraction of the marker size from {span}, got {value!r}")
    return float(value)
