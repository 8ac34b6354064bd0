"""Starting values: each photo's camera pose from the tape map, new markers from the photos, the units check.

The photos that show mapped markers are located with :func:`fidlearn.estimate_pose` on the tape
map (its outlier rejection leaves a badly taped marker out). A marker absent from the map is
placed from every located photo that shows it (IPPE_SQUARE on its four corners, chained with the
photo's pose), keeping the placement that reprojects best in all of them; it needs two photos.
Then photos that showed only new markers are located in turn, until nothing changes.
"""

from __future__ import annotations

import math

import numpy as np

from ..detection import Detection
from ..errors import FidlearnError, MapError
from ..markermap import UNITS_TO_MM, MarkerMap
from ..pose import estimate_pose
from ._geometry import local_corners, placement_from_photo, placement_of
from ._inputs import _Photo

#: The map's distances may differ from the photos' by this factor before its units are called wrong.
UNITS_FACTOR_LIMIT = 1.6
#: A new marker's placement is tried from this many photos (where it looks largest), judged in this many.
NEW_CANDIDATES = 6
NEW_JUDGES = 24
#: A new marker's side is measured from its photos when their rays to it spread by at least this much (degrees).
MIN_RAY_ANGLE_DEG = 5.0
#: A new marker measured this much larger or smaller than the map's ``marker_size_mm`` (a fraction) gets
#: its measured side; closer, the map's (a print a little off is the print scale's, not another size).
NEW_SIZE_RTOL = 0.05


def _map_of(placed: dict[int, tuple[np.ndarray, np.ndarray]], tape: MarkerMap, sizes: dict) -> MarkerMap:
    """A MarkerMap (mm) of the placements ``{id: (R_world_place, top_left_mm)}``, each marker of side ``sizes[id]``."""
    pl = {i: placement_of(i, R, p, sizes.get(i)) for i, (R, p) in placed.items()}
    return MarkerMap(pl, tape.marker_size_mm, dictionary=tape.dictionary, units=tape.units, source=tape.source)


def _locate(photo: _Photo, current: MarkerMap) -> None:
    dets = [Detection(int(i), c, getattr(i, "dictionary", None)) for i, c in photo.corners.items() if i in current]
    if not dets:
        seen = sorted(photo.corners)
        photo.reason = (
            f"shows no marker of the map (it shows {seen or 'no marker'}); take it again so that it also shows "
            "a marker of the map"
            if not seen
            else f"shares no marker with the map or the other photos (it shows {seen}); take a photo that "
            f"shows one of {seen} together with a mapped marker"
        )
        return
    try:
        photo.T_world_camera = estimate_pose(dets, current, photo.camera).T_world_camera
        photo.reason = ""
    except FidlearnError as exc:
        photo.reason = f"no camera pose from the map ({exc})"


def _place_new(marker_id: int, photos: list[_Photo], size_mm: float):
    """The best placement of a new marker over the located photos that show it (None if none works).

    Candidates come from the ``NEW_CANDIDATES`` photos where it looks largest, each judged by its
    reprojection in up to ``NEW_JUDGES`` photos (evenly spread): the work grows with the photos, not
    with their square.
    """
    local = local_corners(size_mm)
    best, best_err = None, np.inf
    area = [-_area(ph.corners[marker_id]) for ph in photos]
    judges = [photos[k] for k in np.linspace(0, len(photos) - 1, min(len(photos), NEW_JUDGES)).astype(int)]
    for ph in [photos[k] for k in np.argsort(area, kind="stable")[:NEW_CANDIDATES]]:
        cand = placement_from_photo(ph.corners[marker_id], ph.camera, ph.T_world_camera, size_mm)
        if cand is None:
            continue
        world = local @ cand[0].T + cand[1]
        err = sum(
            float(np.sum((q.camera.project(world, q.T_world_camera) - q.corners[marker_id]) ** 2)) for q in judges
        )
        if err < best_err:
            best, best_err = cand, err
    return best


def side_from_photos(marker_id: int, photos: list[_Photo]) -> float | None:
    """A marker's side (mm) from two or more located photos: its four corners triangulated, the mean edge.

    Each corner is the point nearest (least squares) to its rays from the photos' cameras (their
    poses from the markers of known size). None when the rays spread less than ``MIN_RAY_ANGLE_DEG``
    (``MIN_RAY_ANGLE_DEG``: photos from nearly one place cannot tell a small near marker from a large far one).
    """
    rays = []
    for ph in photos:
        px = ph.camera.undistort_points(ph.corners[marker_id])
        T = ph.T_world_camera
        if T is None or not np.all(np.isfinite(px)):
            continue
        d = np.c_[px, np.ones(4)] @ np.linalg.inv(ph.camera.K).T @ T[:3, :3].T
        rays.append((T[:3, 3], d / np.linalg.norm(d, axis=1, keepdims=True)))
    if len(rays) < 2:
        return None
    spread = max(float(np.degrees(np.arccos(np.clip(a[1][0] @ b[1][0], -1, 1)))) for a in rays for b in rays)
    if spread < MIN_RAY_ANGLE_DEG:
        return None
    corners = []
    for k in range(4):
        A, b = np.zeros((3, 3)), np.zeros(3)
        for o, d in rays:
            P = np.eye(3) - np.outer(d[k], d[k])
            A += P
            b += P @ o
        corners.append(np.linalg.solve(A, b))
    side = float(np.mean([np.linalg.norm(corners[k] - corners[(k + 1) % 4]) for k in range(4)]))
    return side if side > 0 and math.isfinite(side) else None


def remeasured_sides(cams: list[_Photo], problem, x: np.ndarray, ids: list) -> dict:
    """:func:`side_from_photos` of the markers ``ids`` again, the cameras where the adjustment ``x`` puts them."""
    R_cam, t_cam, _, _ = problem.poses(x)
    located = []
    for c, ph in enumerate(cams):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R_cam[c].T, -R_cam[c].T @ t_cam[c]
        located.append(_Photo(ph.label, ph.camera, ph.corners, T))
    sides = {i: side_from_photos(i, [ph for ph in located if i in ph.corners]) for i in ids}
    return {i: v for i, v in sides.items() if v is not None}


def _area(c: np.ndarray) -> float:
    """Area (px^2) of a detected marker's outline (shoelace)."""
    x, y = c[:, 0], c[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def initial_values(photos: list[_Photo], tape: MarkerMap, sizes: dict | None = None) -> tuple[dict, dict[int, str]]:
    """Locate the photos and place new markers; ``(placed, unplaced)``.

    ``placed`` is ``{id: (R_world_place, top_left_mm)}`` for the map's markers and the new ones
    placed; ``unplaced`` is ``{id: reason}`` for markers seen but not placed. ``sizes`` (``{id: side
    mm}``) gives the sides of markers the map does not hold; a new marker it lacks is measured in the
    located photos (:func:`side_from_photos`) and gets that side (written into ``sizes``) when it
    differs from the map's ``marker_size_mm`` by more than ``NEW_SIZE_RTOL``, else the map's.
    """
    placed = {i: (p.R_world_marker, np.asarray(p.translation_mm, float)) for i, p in tape.placements.items()}
    sizes = {} if sizes is None else sizes
    sizes.update({i: tape.marker_size(i) for i in tape.ids})
    current = tape
    while True:
        for ph in photos:
            if ph.T_world_camera is None:
                _locate(ph, current)
        located = [ph for ph in photos if ph.T_world_camera is not None]
        new = sorted({i for ph in located for i in ph.corners if i not in placed})
        added = [i for i in new if _add_new(i, located, tape, sizes, placed)]
        if not added:
            break
        current = _map_of(placed, tape, sizes)
    return placed, _unplaced(photos, placed)


def _add_new(i, located: list[_Photo], tape: MarkerMap, sizes: dict, placed: dict) -> bool:
    """Place the new marker ``i`` from the located photos that show it (two or more), its side measured first."""
    showing = [ph for ph in located if i in ph.corners]
    if len(showing) < 2:
        return False
    side = side_from_photos(i, showing) if i not in sizes else None
    if side is not None and abs(side / tape.marker_size_mm - 1) > NEW_SIZE_RTOL:
        sizes[i] = side
    cand = _place_new(i, showing, sizes.get(i, tape.marker_size_mm))
    if cand is not None:
        placed[i] = cand
    return cand is not None


def _unplaced(photos: list[_Photo], placed: dict) -> dict[int, str]:
    out = {}
    for i in sorted({i for ph in photos for i in ph.corners if i not in placed}):
        showing = [ph for ph in photos if i in ph.corners and ph.T_world_camera is not None]
        if len(showing) == 1:
            out[i] = (
                f"marker {i} is not in the map and is seen in only one photo ({showing[0].label}): take another "
                f"photo that shows marker {i} together with a marker already placed"
            )
        elif not showing:
            out[i] = (
                f"marker {i} is not in the map and is seen only in photos that share no marker with it: take a photo "
                f"that shows marker {i} together with a mapped marker"
            )
        else:
            out[i] = f"marker {i}: no placement fits its corners in the photos that show it; check its id and size"
    return out


def check_units(photos: list[_Photo], tape: MarkerMap) -> None:
    """Refuse a map whose distances disagree with the photos' by a factor (units written wrong).

    In each photo, every pair of mapped markers gives a distance from the photo alone (the marker's
    printed size sets the scale); the median ratio of the map's distances to these must be within
    ``UNITS_FACTOR_LIMIT`` of 1.
    """
    ratios = []
    for ph in photos:
        ids = [i for i in ph.corners if i in tape]
        if len(ids) < 2:
            continue
        seen = {i: placement_from_photo(ph.corners[i], ph.camera, np.eye(4), tape.marker_size(i)) for i in ids}
        tl = {i: p.translation_mm for i, p in tape.placements.items()}
        for a in range(len(ids)):
            for b in range(a + 1, len(ids)):
                i, j = ids[a], ids[b]
                si, sj = seen[i], seen[j]
                d_photo = np.linalg.norm(si[1] - sj[1]) if si and sj else 0.0
                if d_photo > 2 * max(tape.marker_size(i), tape.marker_size(j)):
                    ratios.append(np.linalg.norm(np.subtract(tl[i], tl[j])) / d_photo)
    if not ratios:
        return
    r = float(np.median(ratios))
    if 1 / UNITS_FACTOR_LIMIT < r < UNITS_FACTOR_LIMIT:
        return
    raise MapError(_units_message(r, tape))


def _units_message(r: float, tape: MarkerMap) -> str:
    scale = UNITS_TO_MM[tape.units]
    guess = min(UNITS_TO_MM, key=lambda u: abs(np.log(UNITS_TO_MM[u] * r / scale)))
    hint = (
        f"; the distances fit units {guess!r}"
        if guess != tape.units and abs(np.log(UNITS_TO_MM[guess] * r / scale)) < 0.4
        else ""
    )
    return (
        f"{tape.source}: the map's distances between markers are {r:.3g} times those the photos show: its units "
        f"({tape.units}) or its marker_size_mm ({tape.marker_size_mm:g}) look wrong{hint}; fix the map, or check "
        "the marker size with a ruler on one printed marker"
    )
