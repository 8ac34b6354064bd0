"""A room seen from above, coloured by the predicted position error, and where to add a marker.

:func:`plan_room` evaluates :func:`~fidlearn.planning.predict.predict_accuracy` on a grid of
camera positions at one height: once looking toward the markers (or a point you choose), and
over a full turn of level headings (the worst and the median of those that see a marker).
:func:`suggest_markers` then adds markers one at a time, greedily, where they bring the most of
the area within a target error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import FidlearnError
from ..markermap import UNITS_TO_MM, MarkerMap
from ..synthetic import look_at
from .predict import _check_px, _check_rel, _predict, predict_accuracy

__all__ = ["RoomPlan", "Suggestion", "plan_room", "suggest_markers", "default_area"]

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
            For another ``which``.
        """
        grid = {"toward": self.toward_mm, "median": self.median_mm, "worst": self.worst_mm}.get(which)
        if grid is None:
            raise FidlearnError(f"which must be 'toward', 'median' or 'worst', got {which!r}")
        return float(np.mean(grid <= error_mm))

    def __repr__(self) -> str:
        ok = np.isfinite(self.toward_mm)
        med = float(np.median(self.toward_mm[ok])) if ok.any() else math.inf
        return (
            f"RoomPlan({len(self.x_mm)}x{len(self.y_mm)} places at {self.height_mm:.0f} mm: pose possible "
            f"at {100 * ok.mean():.0f} %, median error {med:.1f} mm looking at the markers)"
        )


@dataclass(frozen=True)
class Suggestion:
    """One step of :func:`suggest_markers`: what to change, and the area within the target after it.

    Attributes
    ----------
    text : str
        The change, in words ("print the markers at 120 mm instead of 80 mm", "add marker 7 beside marker 3 ...").
    fraction_before, fraction_after : float
        Fraction of the grid within the target before and after the change (0 to 1).
    marker_map : MarkerMap
        The map after the change.
    """

    text: str
    fraction_before: float
    fraction_after: float
    marker_map: MarkerMap


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
        If the map has no markers.
    """
    if not len(marker_map):
        raise FidlearnError("the map has no markers: there is nothing to plan around")
    pts = []
    for mid in marker_map.ids:
        c = marker_map.marker_corners(mid).mean(axis=0)
        n = marker_map.normal(mid)
        side = np.cross([0.0, 0.0, 1.0], n)
        side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-6 else np.zeros(3)
        pts += [c + out * n + lat * side for out in (100.0, 3000.0) for lat in (-1000.0, 1000.0)]
    pts = np.array(pts)[:, :2]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def _markers_centre(marker_map: MarkerMap) -> np.ndarray:
    return np.mean([marker_map.marker_corners(i).mean(axis=0) for i in marker_map.ids], axis=0)


def _level_pose(eye: np.ndarray, heading_rad: float) -> np.ndarray:
    return look_at(eye, eye + [math.cos(heading_rad), math.sin(heading_rad), 0.0])


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


def _cell(marker_map, camera, eye, target, headings, kw: dict) -> tuple[float, float, float, float, bool]:
    if np.linalg.norm(target - eye) < 1.0:
        toward, flip = math.inf, False
    else:
        p = predict_accuracy(marker_map, camera, look_at(eye, target), **kw)
        toward, flip = p.position_error_mm, p.flip_likely
    errs = []
    for h in headings:
        p = _predict(
            marker_map,
            camera,
            _level_pose(eye, h),
            kw["corner_sigma_px"],
            with_flip=False,
            shift_px=kw["marker_shift_px"],
            size_rel_std=kw["marker_size_rel_std"],
            size_rel_std_each=kw["marker_size_rel_std_each"],
            size_rel_error=kw["marker_size_rel_error"],
        )
        if p.possible:
            errs.append(p.position_error_mm)
    med = float(np.median(errs)) if errs else math.inf
    worst = float(np.max(errs)) if errs else math.inf
    return toward, med, worst, len(errs) / max(len(headings), 1), flip


def _grid(marker_map: MarkerMap, area, height_mm, step_mm, headings) -> tuple[np.ndarray, np.ndarray]:
    """The grid's place centres ``xs`` (N,) and ``ys`` (M,), mm, world, after checking the options."""
    x0, y0, x1, y1 = _check_area(default_area(marker_map) if area is None else area)
    for name, v in (("height_mm", height_mm), ("step_mm", step_mm)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
            raise FidlearnError(f"{name} must be a finite number of mm, got {v!r}")
    if step_mm <= 0:
        raise FidlearnError(f"step_mm must be positive, got {step_mm!r}")
    if isinstance(headings, bool) or not isinstance(headings, (int, np.integer)) or not 0 <= headings <= 360:
        raise FidlearnError(f"headings must be a whole number from 0 to 360, got {headings!r}")
    xs = np.arange(x0 + step_mm / 2, x1, step_mm)
    ys = np.arange(y0 + step_mm / 2, y1, step_mm)
    if len(xs) * len(ys) > MAX_CELLS:
        raise FidlearnError(
            f"the grid has {len(xs) * len(ys)} places, more than {MAX_CELLS}: use a larger step_mm or a smaller area"
        )
    if len(xs) == 0 or len(ys) == 0:
        raise FidlearnError(f"the area is smaller than one step of {step_mm} mm: use a smaller step_mm")
    return xs, ys


def plan_room(
    marker_map: MarkerMap,
    camera: Camera,
    *,
    height_mm: float = 300.0,
    area=None,
    look_at_mm=None,
    step_mm: float = 250.0,
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
        of the markers.
    step_mm : float
        Grid spacing (mm).
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
        If the map or the camera is not one, or an option is out of range (the area, a step that
        is not positive, more than :data:`MAX_CELLS` places, headings outside 0 to 360), or a noise option
        out of range.
    """
    if not isinstance(marker_map, MarkerMap) or not len(marker_map):
        raise FidlearnError("plan_room needs a fidlearn.MarkerMap with at least one marker")
    if not isinstance(camera, Camera):
        raise FidlearnError(f"camera must be a fidlearn.Camera, got {type(camera).__name__}")
    xs, ys = _grid(marker_map, area, height_mm, step_mm, headings)
    kw = _noise(corner_sigma_px, marker_shift_px, marker_size_rel_std, marker_size_rel_std_each, marker_size_rel_error)
    target = _markers_centre(marker_map) if look_at_mm is None else np.asarray(look_at_mm, dtype=float).reshape(3)
    hs = [2 * math.pi * k / headings for k in range(headings)]
    out = np.empty((5, len(ys), len(xs)))
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            out[:, j, i] = _cell(marker_map, camera, np.array([x, y, height_mm]), target, hs, kw)
        if progress is not None:
            progress(j + 1, len(ys))
    return RoomPlan(xs, ys, float(height_mm), out[0], out[1], out[2], out[3], out[4].astype(bool), target)


def _walls(marker_map: MarkerMap) -> list[tuple[int, np.ndarray]]:
    """One reference marker per wall (markers with the same normal and plane), with the wall's horizontal direction."""
    walls: list[tuple[int, np.ndarray, np.ndarray, float]] = []
    for mid in marker_map.ids:
        n = marker_map.normal(mid)
        d = float(n @ marker_map.marker_corners(mid)[0])
        if any(np.allclose(n, wn, atol=1e-3) and abs(d - wd) < 50.0 for _, _, wn, wd in walls):
            continue
        along = np.cross([0.0, 0.0, 1.0], n)
        if np.linalg.norm(along) < 1e-6:  # a marker on the floor or ceiling: its own X direction
            along = marker_map.marker_corners(mid)[1] - marker_map.marker_corners(mid)[0]
        walls.append((mid, along / np.linalg.norm(along), n, d))
    return [(mid, along) for mid, along, _, _ in walls]


def _with_marker(marker_map: MarkerMap, ref_id: int, centre_mm: np.ndarray, new_id: int) -> MarkerMap:
    d = marker_map.to_dict()
    scale = UNITS_TO_MM[d["units"]]
    s = marker_map.marker_size_mm
    tl_ref, tr_ref, _, bl_ref = marker_map.marker_corners(ref_id)
    right, down = (tr_ref - tl_ref) / s, (bl_ref - tl_ref) / s
    tl = centre_mm - s / 2 * (right + down)
    ref = d["markers"][str(ref_id)]
    d["markers"][str(new_id)] = {
        "translation": [round(float(v) / scale, 6) for v in tl],
        "rotation": list(ref["rotation"]),
    }
    return MarkerMap.from_dict(d)


def _with_size(marker_map: MarkerMap, size_mm: float) -> MarkerMap:
    d = marker_map.to_dict()
    d["marker_size_mm"] = size_mm
    return MarkerMap.from_dict(d)


def _candidates(marker_map: MarkerMap, area, step_mm: float):
    x0, y0, x1, y1 = area
    new_id = max(marker_map.ids) + 1
    for ref, along in _walls(marker_map):
        centre = marker_map.marker_corners(ref).mean(axis=0)
        span = max(x1 - x0, y1 - y0)
        for k in np.arange(-span, span + 1, step_mm):
            c = centre + k * along
            inside = x0 - 500.0 <= c[0] <= x1 + 500.0 and y0 - 500.0 <= c[1] <= y1 + 500.0
            if inside and all(
                np.linalg.norm(c - marker_map.marker_corners(i).mean(axis=0)) > 1.5 * marker_map.marker_size_mm
                for i in marker_map.ids
            ):
                yield (
                    _with_marker(marker_map, ref, c, new_id),
                    f"add marker {new_id} beside marker {ref} at [{c[0]:.0f}, {c[1]:.0f}, {c[2]:.0f}] mm (its centre)",
                )


def _check_target(target_mm) -> None:
    if (
        isinstance(target_mm, bool)
        or not isinstance(target_mm, (int, float, np.integer, np.floating))
        or not math.isfinite(target_mm)
        or target_mm <= 0
    ):
        raise FidlearnError(f"target_mm must be a positive number of mm, got {target_mm!r}")


def suggest_markers(
    marker_map: MarkerMap,
    camera: Camera,
    target_mm: float,
    *,
    height_mm: float = 300.0,
    area=None,
    step_mm: float | None = None,
    max_markers: int = 3,
    size_factors=(1.5, 2.0),
    corner_sigma_px: float | None = None,
    marker_shift_px: float = 0.0,
    marker_size_rel_std: float = 0.0,
    marker_size_rel_std_each: float = 0.0,
    marker_size_rel_error: float = 0.0,
) -> list[Suggestion]:
    """Changes that bring more of the area within ``target_mm``: a larger print, then added markers.

    First the whole map at larger marker sizes (``size_factors`` times the current one) is tried;
    then markers of the chosen size are added one at a time (up to ``max_markers``) on the walls
    the map already uses, each where it brings the largest fraction of the grid (looking toward
    the markers) within ``target_mm``. Stops when the whole area is within the target or no
    candidate helps.

    Parameters
    ----------
    marker_map : MarkerMap
        The markers as they are (mm, world). The map comes first, then the camera.
    camera : Camera
    target_mm : float
        The camera-position error to reach, mm.
    height_mm, area, corner_sigma_px, marker_shift_px, marker_size_rel_std, marker_size_rel_std_each, \
    marker_size_rel_error :
        As for :func:`plan_room`.
    step_mm : float, optional
        Spacing of the grid that scores each change and of the places tried along the walls, mm.
        By default 500 mm, a coarser grid than :func:`plan_room`'s, or a quarter of the area's
        shorter side where that is smaller, so that a small area (a desk, a board) has places too.
    max_markers : int
        Most markers to add.
    size_factors : sequence of float
        Marker sizes to try, as multiples of the current one.

    Returns
    -------
    list of Suggestion
        In the order to apply them; each carries the map after the change.

    Raises
    ------
    FidlearnError
        If ``target_mm`` is not a positive number, or as :func:`plan_room`.
    """
    _check_target(target_mm)
    area = _check_area(default_area(marker_map) if area is None else area)
    if step_mm is None:
        step_mm = min(500.0, min(area[2] - area[0], area[3] - area[1]) / 4)
    target_point = _markers_centre(marker_map)
    kw = _noise(corner_sigma_px, marker_shift_px, marker_size_rel_std, marker_size_rel_std_each, marker_size_rel_error)

    def score(m: MarkerMap) -> float:
        return plan_room(
            m,
            camera,
            height_mm=height_mm,
            area=area,
            look_at_mm=target_point,
            step_mm=step_mm,
            headings=0,
            **kw,
        ).fraction_within(target_mm)

    current, now = marker_map, score(marker_map)
    steps: list[Suggestion] = []
    for factor in sorted(size_factors):
        size = round(marker_map.marker_size_mm * float(factor))
        bigger = _with_size(marker_map, size)
        f = score(bigger)
        if f > now + 0.02:
            steps.append(
                Suggestion(
                    f"print the markers at {size} mm instead of {marker_map.marker_size_mm:g} mm", now, f, bigger
                )
            )
            current, now = bigger, f
            break
    for _ in range(max_markers):
        if now >= AREA_MET:
            break
        best = max(
            ((score(m), m, text) for m, text in _candidates(current, area, step_mm)), key=lambda t: t[0], default=None
        )
        if best is None or best[0] <= now + 0.01:
            break
        steps.append(Suggestion(best[2], now, best[0], best[1]))
        current, now = best[1], best[0]
    return steps
