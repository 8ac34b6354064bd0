"""A room seen from above, coloured by the predicted position error.

:func:`plan_room` evaluates :func:`~fidlearn.planning.predict.predict_accuracy` on a grid of
camera positions at one height: once looking toward the markers (or a point you choose), and
over a full turn of level headings (the worst and the median of those that see a marker).
:func:`~fidlearn.planning.suggest_markers` scores its changes on the same grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import FidlearnError
from ..frames import look_at
from ..markermap import MarkerMap
from . import _checks
from .predict import _CachedMap, _check_px, _check_rel, _predict

__all__ = ["RoomPlan", "plan_room", "default_area", "default_step"]

#: Most grid cells a plan evaluates (each costs one prediction per heading).
MAX_CELLS = 40_000
#: Fraction of the area within the target at which it counts as met: suggest_markers stops there.
AREA_MET = 0.999


@dataclass(frozen=True, repr=False)
class RoomPlan:
    """Predicted camera-position error over a horizontal grid at one height.

    Attributes
    ----------
    x_mm, y_mm : ndarray, shapes (nx,), (ny,)
        Grid coordinates (mm, world).
    height_mm : float
        Camera height (world Z, mm).
    toward_mm : ndarray, shape (ny, nx)
        Median position error (mm) of a camera there looking toward ``target_mm``; inf where
        no pose is possible.
    median_mm, worst_mm : ndarray, shape (ny, nx)
        Median and worst error over the level headings that see a marker; inf where none does.
    seen_fraction : ndarray, shape (ny, nx)
        Fraction of the level headings from which a pose is possible.
    flip : ndarray of bool, shape (ny, nx)
        Where the planar flip is likely when looking toward ``target_mm``.
    target_mm : ndarray, shape (3,)
        The point the cameras of ``toward_mm`` look at.
    step_mm : float
        The grid's spacing (mm), along X and Y alike.
    toward_p90_mm : ndarray, shape (ny, nx), or None
        The 90th percentile of the position error looking toward ``target_mm``
        (:attr:`~fidlearn.planning.Prediction.position_p90_mm`): nine poses in ten are within it.
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    height_mm: float
    toward_mm: np.ndarray
    median_mm: np.ndarray
    worst_mm: np.ndarray
    seen_fraction: np.ndarray
    flip: np.ndarray
    target_mm: np.ndarray
    step_mm: float = math.nan
    toward_p90_mm: np.ndarray | None = None

    def fraction_within(self, error_mm: float, which: str = "toward") -> float:
        """Fraction of the grid where the predicted error is at most ``error_mm``.

        Parameters
        ----------
        error_mm : float
            The largest acceptable camera-position error, mm.
        which : {"toward", "median", "worst"}
            Which grid: looking toward the markers, or the median or worst over level headings.

        Returns
        -------
        float
            From 0 to 1; places where no pose is possible count as outside.

        Raises
        ------
        FidlearnError
            For another ``which``, or an ``error_mm`` that is not a number.
        """
        if not _checks.is_number(error_mm) or math.isnan(error_mm):
            raise FidlearnError(f"error_mm must be a number of mm, got {error_mm!r}")
        grid = {"toward": self.toward_mm, "median": self.median_mm, "worst": self.worst_mm}.get(str(which))
        if not isinstance(which, str) or grid is None:
            raise FidlearnError(f"which must be 'toward', 'median' or 'worst', got {which!r}")
        return float(np.mean(grid <= error_mm))

    def places(self) -> str:
        """The grid in words: ``"12x9 places, 250 mm apart, camera at 300 mm"``.

        Returns
        -------
        str
            Places across (X) and down (Y), their spacing and the camera's height.
        """
        return f"{len(self.x_mm)}x{len(self.y_mm)} places, {self.step_mm:g} mm apart, camera at {self.height_mm:g} mm"

    def __repr__(self) -> str:
        ok = np.isfinite(self.toward_mm)
        med = float(np.median(self.toward_mm[ok])) if ok.any() else math.inf
        return (
            f"RoomPlan({self.places()}: pose possible "
            f"at {100 * ok.mean():.0f} %, median error {med:.1f} mm looking at the markers)"
        )


def _check_area(area) -> tuple[float, float, float, float]:
    try:
        x0, y0, x1, y1 = (float(v) for v in area)
    except (TypeError, ValueError):
        raise FidlearnError(f"area must be four numbers x0, y0, x1, y1 (mm), got {area!r}") from None
    if not all(map(math.isfinite, (x0, y0, x1, y1))) or x1 <= x0 or y1 <= y0:
        raise FidlearnError(f"area must be finite with x0 < x1 and y0 < y1 (mm), got {area!r}")
    return x0, y0, x1, y1


def default_area(marker_map: MarkerMap) -> tuple[float, float, float, float]:
    """The floor area in front of the markers: 0.1 to 3 m out from them, 1 m beyond them sideways.

    Parameters
    ----------
    marker_map : MarkerMap

    Returns
    -------
    (float, float, float, float)
        ``x0, y0, x1, y1``, world frame, mm.

    Raises
    ------
    FidlearnError
        If ``marker_map`` is not a MarkerMap or has no markers.
    """
    if not isinstance(marker_map, MarkerMap):
        raise FidlearnError(f"marker_map must be a fidlearn.MarkerMap, got {type(marker_map).__name__}")
    if not len(marker_map):
        raise FidlearnError("the map has no markers: there is nothing to plan around")
    pts: list[np.ndarray] = []
    for mid in marker_map.ids:
        c = marker_map.marker_corners(mid).mean(axis=0)
        n = marker_map.normal(mid)
        side = np.cross([0.0, 0.0, 1.0], n)
        side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-6 else np.zeros(3)
        pts += [c + out * n + lat * side for out in (100.0, 3000.0) for lat in (-1000.0, 1000.0)]
    xy = np.array(pts)[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def _markers_centre(marker_map: MarkerMap) -> np.ndarray:
    return np.mean([marker_map.marker_corners(i).mean(axis=0) for i in marker_map.ids], axis=0)


def _level_pose(eye: np.ndarray, heading_rad: float) -> np.ndarray:
    return look_at(eye.tolist(), (eye + [math.cos(heading_rad), math.sin(heading_rad), 0.0]).tolist())


def _noise(
    corner_sigma_px, marker_shift_px, marker_size_rel_std, marker_size_rel_std_each, marker_size_rel_error
) -> dict:
    """The noise options of :func:`predict_accuracy`, checked, as its keyword arguments."""
    _check_px(corner_sigma_px, "corner_sigma_px", zero=False)
    _check_px(marker_shift_px, "marker_shift_px", zero=True)
    return {
        "corner_sigma_px": corner_sigma_px,
        "marker_shift_px": 0.0 if marker_shift_px is None else marker_shift_px,
        "marker_size_rel_std": _check_rel(marker_size_rel_std, "marker_size_rel_std"),
        "marker_size_rel_std_each": _check_rel(marker_size_rel_std_each, "marker_size_rel_std_each"),
        "marker_size_rel_error": _check_rel(marker_size_rel_error, "marker_size_rel_error", signed=True),
    }


def _cell(marker_map, camera, eye, target, headings, kw: dict, with_flip: bool) -> tuple:
    """``(toward, median, worst, seen fraction, flip, toward's 90th percentile)`` of one place; the flip only
    ``with_flip``."""
    args = (
        kw["corner_sigma_px"],
        kw["marker_shift_px"],
        kw["marker_size_rel_std"],
        kw["marker_size_rel_std_each"],
        kw["marker_size_rel_error"],
    )
    if math.hypot(*(target - eye)) < 1.0:
        toward, flip, p90 = math.inf, False, math.inf
    else:  # straight down or up at the point: the picture's top towards +x, as no side is up then
        d = target - eye
        up = (0.0, 0.0, 1.0) if math.hypot(d[0], d[1]) > 1e-6 * abs(d[2]) else (1.0, 0.0, 0.0)
        p = _predict(marker_map, camera, look_at(eye, target, up=up), args[0], with_flip, *args[1:])
        toward, flip, p90 = p.position_error_mm, p.flip_likely, p.position_p90_mm
    errs = []
    for h in headings:
        p = _predict(marker_map, camera, _level_pose(eye, h), args[0], False, *args[1:])
        if p.possible:
            errs.append(p.position_error_mm)
    med = float(np.median(errs)) if errs else math.inf
    worst = float(np.max(errs)) if errs else math.inf
    return toward, med, worst, len(errs) / max(len(headings), 1), flip, p90


#: Largest coordinate (mm) of a plan's area, height and look-at point: 1000 km.
MAX_COORD_MM = 1e9


def _number(v, name: str) -> float:
    """A finite number of mm within :data:`MAX_COORD_MM`."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not abs(v) <= MAX_COORD_MM:
        raise FidlearnError(f"{name} must be a finite number of mm, at most {MAX_COORD_MM:g} in size, got {v!r}")
    return float(v)


def default_step(area) -> float:
    """The grid spacing of :func:`plan_room` and :func:`~fidlearn.planning.suggest_markers` when none is given.

    Parameters
    ----------
    area : sequence of 4 floats
        ``x0, y0, x1, y1`` (mm, world).

    Returns
    -------
    float
        250 mm, or a quarter of the area's shorter side where that is smaller (a desk, a board), mm.

    Raises
    ------
    FidlearnError
        If ``area`` is not four finite numbers with ``x0 < x1`` and ``y0 < y1``.

    Examples
    --------
    >>> default_step((0, -1000, 3000, 1000)), default_step((300, -200, 700, 100))
    (250.0, 75.0)
    """
    x0, y0, x1, y1 = _check_area(area)
    return min(250.0, min(x1 - x0, y1 - y0) / 4)


def _grid(marker_map: MarkerMap, area, height_mm, step_mm, headings) -> tuple[np.ndarray, np.ndarray, float]:
    """The grid's place centres ``xs`` (N,) and ``ys`` (M,), mm, world, and its step, after checking the options."""
    area = _check_area(default_area(marker_map) if area is None else area)
    x0, y0, x1, y1 = (_number(v, "each number of area") for v in area)
    _number(height_mm, "height_mm")
    step_mm = default_step(area) if step_mm is None else _number(step_mm, "step_mm")
    if step_mm <= 0:
        raise FidlearnError(f"step_mm must be positive, got {step_mm!r}")
    if isinstance(headings, bool) or not isinstance(headings, (int, np.integer)) or not 0 <= headings <= 360:
        raise FidlearnError(f"headings must be a whole number from 0 to 360, got {headings!r}")
    nx, ny = (max(0.0, (hi - lo - step_mm / 2) / step_mm) for lo, hi in ((x0, x1), (y0, y1)))
    if nx * ny > MAX_CELLS:  # before any array is made (a step of 1e-300 mm would be too many to count)
        raise FidlearnError(
            f"the grid would have about {nx * ny:.3g} places, more than {MAX_CELLS}: "
            "use a larger step_mm or a smaller area"
        )
    xs = np.arange(x0 + step_mm / 2, x1, step_mm)
    ys = np.arange(y0 + step_mm / 2, y1, step_mm)
    if len(xs) == 0 or len(ys) == 0:
        raise FidlearnError(f"the area is smaller than one step of {step_mm:g} mm: use a smaller step_mm")
    return xs, ys, float(step_mm)


def _look_at_point(look_at_mm, marker_map: MarkerMap) -> np.ndarray:
    """The point the cameras look at: ``look_at_mm`` checked, or the markers' centre."""
    if look_at_mm is None:
        return _markers_centre(marker_map)
    try:
        target = np.asarray(look_at_mm, dtype=float)
    except (TypeError, ValueError):
        target = None
    if target is None or target.shape != (3,) or not np.all(np.isfinite(target)):
        raise FidlearnError(f"look_at_mm must be three finite numbers x, y, z (mm, world), got {look_at_mm!r}")
    return target


def _check_inputs(marker_map, camera, progress) -> None:
    if not isinstance(marker_map, MarkerMap) or not len(marker_map):
        raise FidlearnError("plan_room needs a fidlearn.MarkerMap with at least one marker")
    if not isinstance(camera, Camera):
        raise FidlearnError(f"camera must be a fidlearn.Camera, got {type(camera).__name__}")
    if progress is not None and not callable(progress):
        raise FidlearnError(f"progress must be a function progress(done, total) or None, got {progress!r}")


def _plan(marker_map, camera, grid, height_mm, look_at_mm, headings, kw, progress=None, with_flip=True) -> RoomPlan:
    """The plan on checked inputs: ``grid`` from :func:`_grid`, ``kw`` from :func:`_noise`."""
    xs, ys, step = grid
    target = _look_at_point(look_at_mm, marker_map)
    hs = [2 * math.pi * k / headings for k in range(headings)]
    out = np.empty((6, len(ys), len(xs)))
    cached = _CachedMap(marker_map)
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            out[:, j, i] = _cell(cached, camera, np.array([x, y, height_mm]), target, hs, kw, with_flip)
        if progress is not None:
            progress(j + 1, len(ys))
    return RoomPlan(xs, ys, float(height_mm), out[0], out[1], out[2], out[3], out[4].astype(bool), target, step, out[5])


def plan_room(
    marker_map: MarkerMap,
    camera: Camera,
    *,
    height_mm: float = 300.0,
    area=None,
    look_at_mm=None,
    step_mm: float | None = None,
    headings: int = 16,
    corner_sigma_px: float | None = None,
    progress=None,
    marker_shift_px: float = 0.0,
    marker_size_rel_std: float = 0.0,
    marker_size_rel_std_each: float = 0.0,
    marker_size_rel_error: float = 0.0,
) -> RoomPlan:
    """Predicted position error of a camera at every place of a horizontal grid.

    Parameters
    ----------
    marker_map : MarkerMap
    camera : Camera
    height_mm : float
        Camera height above the world's Z = 0 (mm): a robot's camera, 300 mm by default.
    area : sequence of 4 floats, optional
        ``x0, y0, x1, y1`` (mm, world); by default :func:`default_area`.
    look_at_mm : sequence of 3 floats, optional
        The point the cameras of :attr:`RoomPlan.toward_mm` look at; by default the centre
        of the markers. A far point works too: the cameras then all look the same way.
    step_mm : float, optional
        Grid spacing (mm); by default :func:`default_step`: 250 mm, less on an area under 1 m across.
    headings : int
        Level headings per place for :attr:`RoomPlan.median_mm` and :attr:`RoomPlan.worst_mm`
        (0 to skip them).
    corner_sigma_px : float, optional
        Corner noise, as in :func:`predict_accuracy`.
    progress : callable, optional
        Called as ``progress(done, total)`` after each grid row.
    marker_shift_px, marker_size_rel_std, marker_size_rel_std_each, marker_size_rel_error : float
        A shift common to a marker's corners (px), the markers' relative size error (a spread common to
        all, a spread of each marker on its own, a known error common to all), as in
        :func:`predict_accuracy`; 0 by default (a :class:`~fidlearn.planning.noise.PhotoNoise` has them).

    Returns
    -------
    RoomPlan
        The predicted errors (mm) on the grid, and where a pose is possible.

    Raises
    ------
    FidlearnError
        If the map or the camera is not one, ``progress`` is not callable, or an option is out of range
        (the area, the height or the look-at point not finite or beyond :data:`MAX_COORD_MM`, a step that
        is not positive, more than :data:`MAX_CELLS` places, headings outside 0 to 360), or a noise option
        out of range.
    """
    _check_inputs(marker_map, camera, progress)
    grid = _grid(marker_map, area, height_mm, step_mm, headings)
    kw = _noise(corner_sigma_px, marker_shift_px, marker_size_rel_std, marker_size_rel_std_each, marker_size_rel_error)
    return _plan(marker_map, camera, grid, float(height_mm), look_at_mm, headings, kw, progress)
