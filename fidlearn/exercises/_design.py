"""Lesson 08's design exercise: a layout of markers on the wall X = 0, judged by its rules and its predicted error.

:class:`_WallTask` holds what the learner is given; :meth:`_WallTask.verdict` says what breaks the rules
of the wall (count, size, units, facing, place, overlap) and, for a layout that keeps them, whether
enough of the floor area is predicted within the target (``fidlearn.plan_room``), and where not.
"""

from __future__ import annotations

import contextlib
import itertools
import math

import numpy as np

from ..camera import Camera
from ..frames import look_at
from ..markermap import MarkerMap
from ..planning import plan_room, predict_accuracy

#: Unit slips: factor the positions must be multiplied by to be mm, and what the numbers then were.
_UNIT_SLIPS = {1000.0: "metres", 304.8: "feet", 25.4: "inches", 10.0: "centimetres"}


class _WallTask:
    """One learner's design exercise: the camera, the floor area, the wall's free part, the target."""

    def __init__(self, camera: Camera, height_mm, area_mm, marker_size_mm, target_mm, fraction, span_mm, heights_mm):
        self.camera, self.height_mm, self.area_mm = camera, height_mm, tuple(area_mm)
        self.size, self.target, self.fraction = marker_size_mm, target_mm, fraction
        self.span, self.heights = tuple(span_mm), tuple(heights_mm)
        self.step_mm = 250.0
        self._cache: tuple = (None, None)  # (map, its plan): compare and the notes share one plan

    # -- the prediction --------------------------------------------------------------------
    def plan(self, m: MarkerMap) -> np.ndarray:
        """Predicted error (mm) looking toward the markers on the check's grid, shape (ny, nx); inf: no pose."""
        if self._cache[0] is m:
            return self._cache[1]
        try:
            grid = plan_room(
                m, self.camera, height_mm=self.height_mm, area=self.area_mm, step_mm=self.step_mm, headings=0
            ).toward_mm
        except Exception:  # a place the prediction cannot handle: judge the others, that one counts as outside
            grid = self._plan_by_place(m)
        self._cache = (m, grid)
        return grid

    def _plan_by_place(self, m: MarkerMap) -> np.ndarray:
        xs, ys = self.xs_ys()
        target = np.mean([m.marker_corners(i).mean(axis=0) for i in m.ids], axis=0)
        grid = np.full((len(ys), len(xs)), math.inf)
        for (j, y), (i, x) in itertools.product(enumerate(ys), enumerate(xs)):
            with contextlib.suppress(Exception):
                grid[j, i] = predict_accuracy(m, self.camera, look_at([x, y, self.height_mm], target)).position_error_mm
        return grid

    def xs_ys(self) -> tuple[np.ndarray, np.ndarray]:
        """The grid's place centres along X (nx,) and Y (ny,), mm, as plan_room lays them."""
        x0, y0, x1, y1 = self.area_mm
        return np.arange(x0 + self.step_mm / 2, x1, self.step_mm), np.arange(y0 + self.step_mm / 2, y1, self.step_mm)

    # -- the verdict -----------------------------------------------------------------------
    def verdict(self, m: MarkerMap, _expected=None) -> str | None:
        """None when the layout keeps the rules and enough of the area is within the target, else why not."""
        return _rule_problem(self, m) or _coverage_problem(self, m)

    def praise(self, m: MarkerMap) -> str:
        """What a right layout achieves: the part of the area within the target, the worst place."""
        grid = self.plan(m)
        ok = np.isfinite(grid)
        worst = f"the worst place {np.max(grid[ok]):.1f} mm" if ok.any() else ""
        if not ok.all():
            worst += f", no pose from {int(np.sum(~ok))} places (spread a little less)"
        return (
            f"well done: {100 * np.mean(grid <= self.target):.0f} % of the area is predicted within "
            f"{self.target:g} mm ({100 * self.fraction:.0f} % asked); {worst}"
        )


def _inside(task: _WallTask, tls: np.ndarray, tol: float = 0.5) -> bool:
    """Whether markers with these top-left corners (N, 3), mm, fit the wall's span and heights."""
    s = task.size
    return bool(
        np.all(np.abs(tls[:, 0]) <= tol)
        and np.all(tls[:, 1] >= task.span[0] - tol)
        and np.all(tls[:, 1] + s <= task.span[1] + tol)
        and np.all(tls[:, 2] - s >= task.heights[0] - tol)
        and np.all(tls[:, 2] <= task.heights[1] + tol)
    )


def _units_problem(task: _WallTask, m: MarkerMap) -> str | None:
    tls = np.array([m.placements[i].translation_mm for i in m.ids], dtype=float)
    if _inside(task, tls):
        return None
    for factor, unit in _UNIT_SLIPS.items():
        if _inside(task, tls * factor, tol=0.05 * factor + 50):
            return (
                f"your markers are at {np.round(tls[:, 1:], 1).tolist()} (Y, Z in mm), next to the room's origin and "
                f"far off the wall's free part: the numbers look like {unit} read as mm; give the positions in mm, or "
                f"say the map's units"
            )
        if _inside(task, tls / factor, tol=50):
            return (
                f"your markers are {np.max(np.abs(tls)) / 1000:.0f} m away, far off the wall: the numbers look like mm "
                f'read as {unit} (the map\'s units multiply them); say "units": "mm"'
            )
    return None


def _placement_problem(task: _WallTask, m: MarkerMap) -> str | None:
    for mid in m.ids:
        n = m.normal(mid)
        c = m.marker_corners(mid)
        if n[0] < 0.9998:
            away = " (it faces the wall: a yaw of 180 deg turns it around)" if n[0] < -0.99 else ""
            return (
                f"marker {mid} faces {np.round(n, 3).tolist()}{away}; on the wall X = 0 a marker faces into the room, "
                "+X: rotation [0, 0, 0]"
            )
        if np.max(np.abs(c[:, 0])) > 1.0:
            return (
                f"marker {mid} is not on the wall: its corners are at X = {np.max(np.abs(c[:, 0])):.0f} mm; the wall "
                "is the plane X = 0 (translation [0, y, z])"
            )
        lo, hi = c.min(axis=0), c.max(axis=0)
        if lo[1] < task.span[0] - 0.5 or hi[1] > task.span[1] + 0.5:
            return (
                f"marker {mid} reaches from Y = {lo[1]:.0f} to {hi[1]:.0f} mm, outside the wall's free part "
                f"(Y from {task.span[0]:.0f} to {task.span[1]:.0f} mm): keep every corner within it"
            )
        if lo[2] < task.heights[0] - 0.5 or hi[2] > task.heights[1] + 0.5:
            return (
                f"marker {mid} reaches from Z = {lo[2]:.0f} to {hi[2]:.0f} mm, outside the heights allowed "
                f"({task.heights[0]:.0f} to {task.heights[1]:.0f} mm); the translation is the top-left corner, "
                "the marker hangs below it by its side"
            )
    return None


def _overlap_problem(task: _WallTask, m: MarkerMap) -> str | None:
    gap_needed = round(0.1 * task.size)
    for a, b in itertools.combinations(m.ids, 2):
        ca, cb = m.marker_corners(a), m.marker_corners(b)
        gaps = [max(cb[:, k].min() - ca[:, k].max(), ca[:, k].min() - cb[:, k].max()) for k in (1, 2)]
        gap = max(gaps)
        if gap < gap_needed:
            what = "overlap" if gap < 0 else f"are only {gap:.0f} mm apart"
            return (
                f"markers {a} and {b} {what}: leave a white margin of at least {gap_needed} mm between two markers "
                "(the detector needs it), and spread them out"
            )
    return None


def _rule_problem(task: _WallTask, m: MarkerMap) -> str | None:
    if len(m) != 3:
        return f"your map has {len(m)} marker{'s' * (len(m) != 1)}; the task asks for exactly three"
    if abs(m.marker_size_mm - task.size) > 0.01:
        return (
            f"marker_size_mm is {m.marker_size_mm:g}; the markers you may print are {task.size:g} mm "
            "(marker_size_mm is in mm whatever the map's units)"
        )
    return _units_problem(task, m) or _placement_problem(task, m) or _overlap_problem(task, m)


def _spread_mm(m: MarkerMap) -> float:
    centres = [m.marker_corners(i).mean(axis=0) for i in m.ids]
    return max(float(np.linalg.norm(p - q)) for p, q in itertools.combinations(centres, 2))


def _worst_part(task: _WallTask, grid: np.ndarray) -> str:
    """The third of the area (near, middle or far; -Y side, middle, +Y side) with the most places over the target."""
    xs, ys = task.xs_ys()
    bad = grid > task.target
    rows, cols = np.array_split(np.arange(len(ys)), 3), np.array_split(np.arange(len(xs)), 3)
    (j, i) = max(
        itertools.product(range(3), range(3)),
        key=lambda ji: (int(bad[np.ix_(rows[ji[0]], cols[ji[1]])].sum()), ji[1]),
    )
    part = grid[np.ix_(rows[j], cols[i])]
    where = (
        f"{['near the wall', 'in the middle distance', 'at the far end'][i]} "
        f"({['on the -Y side', 'in the middle', 'on the +Y side'][j]}: x {xs[cols[i][0]]:.0f} to {xs[cols[i][-1]]:.0f} "
        f"mm, y {ys[rows[j][0]]:.0f} to {ys[rows[j][-1]]:.0f} mm)"
    )
    if not np.all(np.isfinite(part[part > task.target])):
        return (
            f"worst {where}: no pose is possible from {int(np.sum(~np.isfinite(part)))} places there: a camera "
            "looking at the middle of your markers sees none of them whole (spread them less, or lower, for the near "
            "places)"
        )
    worst = float(np.max(part))
    return (
        f"worst {where}: up to {worst:.1f} mm, {worst / task.target:.1f} times the target (the error grows with the "
        "square of the distance: a wider, taller layout tells the far places the tilt of the wall better)"
    )


def _coverage_problem(task: _WallTask, m: MarkerMap) -> str | None:
    grid = task.plan(m)
    within = float(np.mean(grid <= task.target))
    if within >= task.fraction:
        return None
    share = (
        f"{100 * within:.0f} % of the area is predicted within {task.target:g} mm, {100 * task.fraction:.0f} % is asked"
    )
    spread = _spread_mm(m)
    if spread < task.area_mm[2] / 5:
        return (
            f"your three markers are within {spread:.0f} mm of each other: from {task.area_mm[2] / 1000:.1f} m away "
            "they act as one small marker, whose corners barely tell a small tilt of the wall from a sideways shift "
            f"of the camera; {share}. Spread them along the wall, and not all at one height"
        )
    return f"{share}; {_worst_part(task, grid)}"
