"""Where to add a marker, and how large to print them, to bring more of a room within a target error.

:func:`suggest_markers` tries the whole map printed larger, then adds markers one at a time,
greedily, where they bring the most of the area within the target. Every change is scored by the
plan :func:`~fidlearn.planning.plan_room` makes of the changed map with the same options (the same
grid, camera height, look-at point and noise), so each :attr:`Suggestion.fraction_after` is what a
new plan of :attr:`Suggestion.marker_map` says.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import FidlearnError
from ..markermap import UNITS_TO_MM, MarkerMap
from .room import AREA_MET, _check_area, _check_inputs, _grid, _noise, _plan, default_area

__all__ = ["Suggestion", "suggest_markers"]

#: Most predictions a search may make (grid places times the maps it scores): about a minute.
MAX_PREDICTIONS = 40_000
#: Most markers :func:`suggest_markers` adds, and the largest size factor it tries.
MAX_ADDED, MAX_SIZE_FACTOR = 20, 10.0


@dataclass(frozen=True)
class Suggestion:
    """One step of :func:`suggest_markers`: what to change, and the area within the target after it.

    Attributes
    ----------
    text : str
        The change, in words ("print the markers at 120 mm instead of 80 mm", "add marker 7 beside marker 3 ...").
    fraction_before, fraction_after : float
        Fraction of the grid within the target before and after the change (0 to 1): what
        :meth:`RoomPlan.fraction_within` of a plan of the map before and after says, the plan made with
        the options given to :func:`suggest_markers`.
    marker_map : MarkerMap
        The map after the change.
    """

    text: str
    fraction_before: float
    fraction_after: float
    marker_map: MarkerMap


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
    """The map with a marker of its own size and dictionary centred at ``centre_mm``, turned as the marker
    ``ref_id`` is (a single marker, or one of a board or a bundle; of its own size or the map's)."""
    d = marker_map.to_dict()
    scale = UNITS_TO_MM[d["units"]]
    s, s_ref = marker_map.marker_size_mm, marker_map.marker_size(ref_id)
    tl_ref, tr_ref, _, bl_ref = marker_map.marker_corners(ref_id)
    right, down = (tr_ref - tl_ref) / s_ref, (bl_ref - tl_ref) / s_ref  # unit vectors along the reference's sides
    tl = centre_mm - s / 2 * (right + down)
    d.setdefault("markers", {})[str(new_id)] = {
        "translation": [round(float(v) / scale, 6) for v in tl],
        "rotation": [float(v) for v in marker_map.placements[ref_id].rotation_deg],
    }
    return MarkerMap.from_dict(d)


def _with_size(marker_map: MarkerMap, size_mm: float) -> MarkerMap:
    d = marker_map.to_dict()
    d["marker_size_mm"] = size_mm
    return MarkerMap.from_dict(d)


def _places(marker_map: MarkerMap, area, spacing_mm: float) -> list[tuple[int, np.ndarray]]:
    """``(reference marker, centre)`` of every place tried for a new marker: along each wall, near the area,
    away from the markers there."""
    x0, y0, x1, y1 = area
    span = max(x1 - x0, y1 - y0)
    centres = [(marker_map.marker_corners(i).mean(axis=0), marker_map.marker_size(i)) for i in marker_map.ids]
    out = []
    for ref, along in _walls(marker_map):
        centre = marker_map.marker_corners(ref).mean(axis=0)
        for k in np.arange(-span, span + 1, spacing_mm):
            c = centre + k * along
            inside = x0 - 500.0 <= c[0] <= x1 + 500.0 and y0 - 500.0 <= c[1] <= y1 + 500.0
            if inside and all(np.linalg.norm(c - o) > 0.75 * (size + marker_map.marker_size_mm) for o, size in centres):
                out.append((ref, c))
    return out


def _candidates(marker_map: MarkerMap, places: list):
    new_id = max(marker_map.ids) + 1
    for ref, c in places:
        text = f"add marker {new_id} beside marker {ref} at [{c[0]:.0f}, {c[1]:.0f}, {c[2]:.0f}] mm (its centre)"
        yield _with_marker(marker_map, ref, c, new_id), text


def _check_options(target_mm, max_markers, size_factors) -> list[float]:
    """Check the search's own options; the size factors, sorted."""
    if (
        isinstance(target_mm, bool)
        or not isinstance(target_mm, (int, float, np.integer, np.floating))
        or not math.isfinite(target_mm)
        or target_mm <= 0
    ):
        raise FidlearnError(f"target_mm must be a positive number of mm, got {target_mm!r}")
    if isinstance(max_markers, bool) or not isinstance(max_markers, (int, np.integer)) or not max_markers >= 0:
        raise FidlearnError(f"max_markers must be a whole number from 0 to {MAX_ADDED}, got {max_markers!r}")
    if max_markers > MAX_ADDED:
        raise FidlearnError(f"max_markers must be a whole number from 0 to {MAX_ADDED}, got {max_markers!r}")
    try:
        factors = list(itertools.islice(size_factors, MAX_ADDED + 1))  # an endless iterator: refused, not read
    except TypeError:
        factors = None
    ok = (
        factors is not None
        and len(factors) <= MAX_ADDED
        and all(isinstance(f, (int, float, np.integer, np.floating)) and not isinstance(f, bool) for f in factors)
    )
    if factors is None or not ok or not all(1 < f <= MAX_SIZE_FACTOR for f in factors):  # NaN fails the comparison too
        raise FidlearnError(
            f"size_factors must be up to {MAX_ADDED} numbers above 1 and at most {MAX_SIZE_FACTOR:g} (the larger "
            f"prints to try, as multiples of the map's marker size; () for none), got {size_factors!r}"
        )
    return sorted(float(f) for f in factors)


def _check_work(marker_map: MarkerMap, area, grid, spacing: float, n_factors: int, max_markers: int) -> None:
    """Refuse, before any prediction, a search that would make more than :data:`MAX_PREDICTIONS` of them."""
    cells = len(grid[0]) * len(grid[1])
    along = len(_walls(marker_map)) * (2 * max(area[2] - area[0], area[3] - area[1]) / spacing + 1)
    if cells * along > 10 * MAX_PREDICTIONS:  # before listing them: a long wall at a fine step has too many
        raise FidlearnError(
            f"the search would try about {along:.0f} places along the walls, each over {cells} grid places: "
            f"use a larger step_mm or a smaller area"
        )
    tried = len(_places(marker_map, area, spacing))
    work = cells * (1 + n_factors + max_markers * tried)  # at most: later rounds try no more places
    if work > MAX_PREDICTIONS:
        raise FidlearnError(
            f"the search would make up to {work} predictions ({tried} places along the walls, each over {cells} "
            f"grid places), more than {MAX_PREDICTIONS}: use a larger step_mm, a smaller area or fewer max_markers"
        )


def _larger_print(marker_map: MarkerMap, factors: list[float], score) -> tuple[list[Suggestion], float]:
    """The first larger print that brings 2 % more of the area within the target, as a list of one (or none),
    and the map's own score."""
    now = score(marker_map)
    for factor in factors:
        size = round(marker_map.marker_size_mm * factor)
        if size <= marker_map.marker_size_mm:  # markers under 2 mm: nothing larger to print in whole mm
            continue
        bigger = _with_size(marker_map, size)
        f = score(bigger)
        if f > now + 0.02:
            text = f"print the markers at {size} mm instead of {marker_map.marker_size_mm:g} mm"
            return [Suggestion(text, now, f, bigger)], now
    return [], now


def suggest_markers(
    marker_map: MarkerMap,
    camera: Camera,
    target_mm: float,
    *,
    height_mm: float = 300.0,
    area=None,
    look_at_mm=None,
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
    the map already uses, at places two grid steps apart (at most 500 mm, and at least one step), each
    where it brings the largest fraction of the grid (looking toward the markers) within ``target_mm``.
    Stops when the whole area is within the target or no candidate helps. Every fraction is that of
    :func:`~fidlearn.planning.plan_room` on the changed map with the same options: the plan of the
    last suggestion's map meets what it promises.

    Parameters
    ----------
    marker_map : MarkerMap
        The markers as they are (mm, world). The map comes first, then the camera.
    camera : Camera
    target_mm : float
        The camera-position error to reach, mm.
    height_mm, area, look_at_mm, step_mm, corner_sigma_px, marker_shift_px, marker_size_rel_std, \
    marker_size_rel_std_each, marker_size_rel_error :
        As for :func:`~fidlearn.planning.plan_room`, whose defaults they share (without ``look_at_mm``
        the cameras look at the centre of each changed map's markers, as a new plan's would).
    max_markers : int
        Most markers to add (0 to :data:`MAX_ADDED`).
    size_factors : sequence of float
        Marker sizes to try, as multiples of the current one (each above 1, at most
        :data:`MAX_SIZE_FACTOR`).

    Returns
    -------
    list of Suggestion
        In the order to apply them; each carries the map after the change.

    Raises
    ------
    FidlearnError
        If ``target_mm`` is not a positive number, ``max_markers`` or ``size_factors`` out of range, the
        search would need more than :data:`MAX_PREDICTIONS` predictions, or as
        :func:`~fidlearn.planning.plan_room`.
    """
    factors = _check_options(target_mm, max_markers, size_factors)
    _check_inputs(marker_map, camera, None)
    area = _check_area(default_area(marker_map) if area is None else area)
    grid = _grid(marker_map, area, height_mm, step_mm, 0)
    kw = _noise(corner_sigma_px, marker_shift_px, marker_size_rel_std, marker_size_rel_std_each, marker_size_rel_error)

    spacing = max(grid[2], min(2 * grid[2], 500.0))  # the places tried along the walls
    _check_work(marker_map, area, grid, spacing, len(factors), max_markers)

    def score(m: MarkerMap) -> float:
        return _plan(m, camera, grid, float(height_mm), look_at_mm, 0, kw, with_flip=False).fraction_within(target_mm)

    steps, now = _larger_print(marker_map, factors, score)
    current, now = (steps[-1].marker_map, steps[-1].fraction_after) if steps else (marker_map, now)
    for _ in range(max_markers):
        if now >= AREA_MET:
            break
        places = _places(current, area, spacing)
        best = max(((score(m), m, text) for m, text in _candidates(current, places)), key=lambda t: t[0], default=None)
        if best is None or best[0] <= now + 0.01:
            break
        steps.append(Suggestion(best[2], now, best[0], best[1]))
        current, now = best[1], best[0]
    # searched with the quick model (no planar flip, no missed marker); promised with plan_room's own
    full = [
        _plan(m, camera, grid, float(height_mm), look_at_mm, 0, kw).fraction_within(target_mm)
        for m in [marker_map, *(s.marker_map for s in steps)]
    ]
    return [Suggestion(s.text, full[k], full[k + 1], s.marker_map) for k, s in enumerate(steps)]
