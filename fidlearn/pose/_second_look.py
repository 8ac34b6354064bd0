"""A second look for the map's markers the pose puts whole in the picture but the detector missed.

OpenCV drops a candidate quad that lies closer than ``minMarkerDistanceRate`` x its perimeter to a larger
one and keeps the larger: the outline of a marker's white margin on a darker wall can push the marker's own
outline out when the margin is about one cell wide, and the marker is then not found at all though it is
whole and sharp (a 200 mm 4X4_50 marker 60 px wide in ``benchmarks/bench_maps.py``). Lowering the rate for
the whole picture loses other markers (``docs/benchmarks.md``, detection). Once the other markers give a
pose, each map marker it predicts whole in the picture, facing the camera, and not detected is read again
in its predicted outline, half a cell wider each side, with everything outside painted white: the margin's
outline is gone and the marker's is the only quad left. O(the missed markers' areas); nothing when every
marker predicted in view was found.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from .. import _cv
from .._detector import _detector_fields, _limits_scaled
from .._lens import project_points
from ..camera import Camera
from ..detection import DEFAULT_REFINE, Detection, _refine_name, as_gray, detect_markers
from ..markermap import MarkerMap
from ._observations import _world

#: Smallest predicted side (px) worth a second look; OpenCV needs about this many to decode a marker.
MIN_SIDE_PX = 16.0


def missed_in_view(
    marker_map: MarkerMap, camera: Camera, T_world_camera: np.ndarray, found: set, detector_params
) -> list[tuple[int, str, np.ndarray]]:
    """``(key, dictionary, predicted corners)`` of the map's markers not in ``found`` that the pose puts whole
    in the picture (their outline half a cell wider plus 4 px inside it), facing the camera, with sides of
    :data:`MIN_SIDE_PX` or more. One projection for all of them (the map's corners cached per map)."""
    corners, faces = _world(marker_map)
    keys = [k for k in corners if k not in found]
    if not keys:
        return []
    T = np.asarray(T_world_camera, dtype=np.float64)
    face = np.array([faces[k] for k in keys])
    # the printed side towards the camera: the normal points at the camera's centre
    facing = face[:, 3:6] @ T[:3, 3] - face[:, 6] > 0
    keys = [k for k, f in zip(keys, facing) if f]
    if not keys:
        return []
    world = np.concatenate([corners[k] for k in keys])
    depth = (world - T[:3, 3]) @ T[:3, 2]
    R = T[:3, :3]  # the camera frame's points as Camera.project finds them, without checking the pose again
    q = project_points(world @ R + (-R.T @ T[:3, 3]), camera.K, camera.dist, camera.model).reshape(-1, 4, 2)
    ok = (depth.reshape(-1, 4) > 0).all(axis=1) & np.isfinite(q).all(axis=(1, 2))
    side = np.linalg.norm(np.roll(q, -1, axis=1) - q, axis=2).min(axis=1)
    border = _border_bits(detector_params)
    names = [marker_map.marker_dictionary(k) for k in keys]
    cells = {n: _cv.dictionary_marker_bits(n) + 2 * border for n in set(names)}
    wide = _widened(q, np.array([cells[n] for n in names]))
    W, H = camera.image_size
    ok &= (side >= MIN_SIDE_PX) & (wide >= 4).all(axis=(1, 2))
    ok &= (wide[:, :, 0] <= W - 5).all(axis=1) & (wide[:, :, 1] <= H - 5).all(axis=1)
    return [(keys[k], names[k], q[k]) for k in np.flatnonzero(ok)]


def read_again(image: np.ndarray, missed: list, refine: str | None, detector_params) -> list[Detection]:
    """The markers of ``missed`` (from :func:`missed_in_view`) found by ``detect_markers`` (the same
    refinement and parameters) in their predicted outline half a cell wider each side, the outside painted
    white; each found with its own id and dictionary, corners in the whole picture's pixels, in the order of
    ``missed``.

    With the default "edges" refinement the crops of one dictionary are read in one call: laid side by side in a
    white picture, :data:`GAP_PX` apart (farther than the detector's thresholds and the edge fit look), with the
    picture's marker size limits (``minMarkerPerimeterRate`` and ``maxMarkerPerimeterRate`` mean the pixels they
    mean in ``image``, as the tracker's windows keep them); a call per crop cost each crop a start of OpenCV's
    threads, twice the CPU of the read on 2 cores. The corners are those of a crop read alone to 0.006 px (the
    edge fit samples at larger coordinates). OpenCV's own refinements ("subpix", "contour", "apriltag") place
    corners up to a pixel apart in the shared picture, so each of their crops is read alone, as it always was.
    The detector decodes the missed markers' ids; each is kept only in its own crop, and not when the outline
    found is the paint's (:func:`_the_paints`)."""
    if not missed:
        return []
    gray = as_gray(image)
    H, W = gray.shape
    kw = {} if refine is None else {"refine": refine}
    crops, lows, wides = _crops(gray, missed, _border_bits(detector_params))
    found: dict[int, Detection] = {}
    together = _refine_name(DEFAULT_REFINE if refine is None else refine) == "edges"
    if together:  # one call per dictionary
        names = dict.fromkeys(n for _, n, _ in missed)
        groups = [[k for k, (_, n, _) in enumerate(missed) if n == name] for name in names]
    else:
        groups = [[k] for k in range(len(missed))]
    for mine in groups:
        name = missed[mine[0]][1]
        if together:
            fields = _fields(detector_params)
            gap = max(GAP_PX, int(fields["adaptiveThreshWinSizeMax"]) // 2 + 16)  # a user's wider windows too
            sheet, at = _side_by_side([crops[k] for k in mine], gap)
            params = _limits_scaled(fields, max(W, H), max(sheet.shape))
        else:  # OpenCV's refinements: each crop alone, as it always was
            sheet, at, params = crops[mine[0]], [(0, 0)], detector_params
        wanted = sorted({int(missed[k][0]) for k in mine})
        dets = detect_markers(sheet, name, ids=wanted, detector_params=params, **kw)
        for k, xy in zip(mine, at):
            own = _own(dets, int(missed[k][0]), name, xy, crops[k].shape, lows[k], wides[k])
            if own is not None:
                found[k] = own
    return [found[k] for k in sorted(found)]


def _own(dets: list, plain: int, name: str, xy, shape, low, wide: np.ndarray) -> Detection | None:
    """The first of ``dets`` (as ``detect_markers`` orders them) with id ``plain`` in the crop at ``xy`` (of
    ``shape``; the picture's ``low`` its top left) and not the paint's outline ``wide``, in the picture's pixels."""
    h, w = shape
    for d in dets:
        corners = d.corners_px - xy + low
        c = corners.mean(axis=0) - low
        if d.id == plain and 0 <= c[0] < w and 0 <= c[1] < h and not _the_paints(corners, wide):
            return Detection(plain, corners, name)
    return None


def _crops(gray: np.ndarray, missed: list, border: int) -> tuple[list[np.ndarray], list, np.ndarray]:
    """Each missed marker's crop of ``gray`` (its predicted outline half a cell wider, 4 px more each side), the
    outside of that outline painted white; each crop's top left (x, y) in the picture; the outlines (M, 4, 2)."""
    H, W = gray.shape
    cells = {name: _cv.dictionary_marker_bits(name) + 2 * border for _, name, _ in missed}
    wides = _widened(np.array([q for _, _, q in missed]), np.array([cells[name] for _, name, _ in missed]))
    lows = np.maximum(np.floor(wides.min(axis=1)).astype(int) - 4, 0).tolist()  # one bounding box per marker
    highs = np.minimum(np.ceil(wides.max(axis=1)).astype(int) + 5, [W, H]).tolist()
    crops = []
    for wide, (x0, y0), (x1, y1) in zip(wides, lows, highs):
        inside = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.fillConvexPoly(inside, np.round(wide - (x0, y0)).astype(np.int32), 1)
        crops.append(np.where(inside > 0, gray[y0:y1, x0:x1], 255).astype(np.uint8))
    return crops, lows, wides


#: A marker found with every corner this close (px) to its crop's painted outline's is taken as that outline.
PAINT_PX = 1.0


def _the_paints(corners: np.ndarray, painted: np.ndarray) -> bool:
    """Whether the outline found is the painted one's (every corner within :data:`PAINT_PX` of it): a marker the
    pose placed more than half a cell off is cut by the paint, and its black border ends there (a fisheye's AprilGrid
    tag at the rim, ``data/real/tumvi_aprilgrid``, 3.6 px off: the pose's error tripled). Corners found in 700
    renders lay 1.5 px or more from it."""
    return bool((np.linalg.norm(corners - painted, axis=1) < PAINT_PX).all())


#: White pixels between two crops read together: more than the detector's adaptive threshold windows (23 px by
#: fidlearn's defaults; half a wider window a user sets, and 16 px) and the edge fit's profiles (the corners' reach
#: and a second fit beyond it) see.
GAP_PX = 48


def _side_by_side(crops: list[np.ndarray], gap: int = GAP_PX) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The crops in one white picture, in a row ``gap`` px apart and from its edges, and each one's top left (x, y)
    there."""
    width = sum(c.shape[1] for c in crops) + gap * (len(crops) + 1)
    height = max(c.shape[0] for c in crops) + 2 * gap
    sheet = np.full((height, width), 255, np.uint8)
    at, x = [], gap
    for c in crops:
        sheet[gap : gap + c.shape[0], x : x + c.shape[1]] = c
        at.append((x, gap))
        x += c.shape[1] + gap
    return sheet, at


def _fields(detector_params) -> dict:
    """The detector's fields (:func:`_detector._detector_fields`; fidlearn's defaults' read once). Not to be
    changed in place."""
    if detector_params is None:
        return _default_fields()
    return _detector_fields(detector_params)


@lru_cache(maxsize=1)
def _default_fields() -> dict:
    return _detector_fields(None)


def _border_bits(detector_params) -> int:
    """The detector's ``markerBorderBits``."""
    return int(_fields(detector_params)["markerBorderBits"])


def _widened(q: np.ndarray, cells) -> np.ndarray:
    """Quads ``q`` (..., 4, 2) grown about their centres by half a cell each side (``cells`` across each
    marker: a number, or one per quad)."""
    c = q.mean(axis=-2, keepdims=True)
    grow = 1.0 + 1.0 / np.asarray(cells, dtype=np.float64)
    return c + (q - c) * np.reshape(grow, np.shape(grow) + (1, 1))
