"""The print's scale from one photo: how much larger or smaller than the map says the markers came out of the printer.

Each map marker in the photo is placed alone (IPPE_SQUARE on its four corners with its map size,
:func:`~fidlearn.survey._geometry.placement_from_photo`, in the camera's frame). A marker printed at 98 % looks
like a marker of the map's size 1/0.98 times as far away, so the photo's room of top-left corners is the true one
scaled by 1/0.98 about the camera. Laying it on the map's top-left corners with a similarity (Umeyama) gives that
scale, and its standard error, exactly as the survey learns the print scale from many photos
(:func:`~fidlearn.survey._variance.print_scale`, markers far off the fit left out). The top-left corners are what
a tape measures, so they stay where the map puts them whatever the print.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..detection import as_gray, detect_markers, load_image
from ..errors import SurveyError
from ..markermap import MarkerMap
from ..pose._inputs import _as_camera, _as_map
from ._geometry import placement_from_photo
from ._gross import _consensus, _similarity
from ._variance import print_scale, print_scale_kept

#: A print scale needs at least this many markers of the map in the photo.
MIN_PRINT_MARKERS = 4


@dataclass(frozen=True)
class PrintCheck:
    """The markers' print scale from one photo (:func:`check_print`).

    Attributes
    ----------
    scale : float
        Printed size over the map's size, common to the markers (0.987 for a print at 98.7 %).
    scale_std : float
        Its standard error.
    marker_ids : tuple
        The map's markers the scale comes from.
    sizes_mm : dict
        Each of those markers' side as printed, ``scale * marker_size(key)``, mm.
    left_out : tuple
        The map's markers in the photo that were not counted: placed too far from where the map says, beside the
        others (moved after it was measured, or a wrong id), so the scale does not come from them.
    repeated : tuple
        The map's markers detected twice or more in the photo (a reflection, or one id printed twice), not
        counted: which of the two is where the map says is unknowable.
    """

    scale: float
    scale_std: float
    marker_ids: tuple
    sizes_mm: dict
    left_out: tuple = ()
    repeated: tuple = ()

    def advice(self) -> str:
        """One line: the scale in %, and what to write in the map or how to print.

        Returns
        -------
        str
            e.g. ``"your markers print at 98.7 % +/- 0.2 %: set size_mm to 78.96 or reprint at 100 %"``.
        """
        pct, err = 100 * self.scale, 100 * self.scale_std
        digits = 1 if err >= 0.05 else 2
        head = f"your markers print at {pct:.{digits}f} % +/- {err:.{digits}f} %"
        if abs(self.scale - 1) <= max(2 * self.scale_std, 0.001):
            return f"{head}: as the map says, nothing to change"
        sizes = sorted(set(round(v, 2) for v in self.sizes_mm.values()))
        return f"{head}: set size_mm to {' / '.join(f'{v:.2f}' for v in sizes)} or reprint at 100 %"


def check_print(image: np.ndarray, marker_map: MarkerMap, camera: Camera) -> PrintCheck:
    """The common scale of the printed markers against the map's sizes, from one photo of 4 or more of them.

    Parameters
    ----------
    image : ndarray, (H, W) gray or (H, W, 3) BGR, or path
        A photo showing at least :data:`MIN_PRINT_MARKERS` markers of the map, not all in one line.
    marker_map : MarkerMap or path
        Where the markers' top-left corners are (taped) and the sizes they should have.
    camera : Camera or path
        The calibrated camera (its focal length sets the scale: calibrate well).

    Returns
    -------
    PrintCheck
        ``scale`` (printed / map), its standard error and the printed sizes. The scale comes from the markers
        where the map puts them beside each other (a similarity fitted robustly): a marker taped elsewhere is
        ``left_out``, one detected twice ``repeated``.

    Raises
    ------
    SurveyError
        Fewer than 4 map markers in the photo (a marker detected twice is not counted), fewer than 4 where the
        map puts them beside each other (the others named), or a scale that cannot be fitted (markers all in a
        line, a map whose distances do not fit the photo).
    ImageError, MapError, CameraError
        Bad inputs.
    """
    if isinstance(image, (str, os.PathLike)):
        image = load_image(image)
    as_gray(image, where="check_print's image")  # an ImageError saying what a picture is, for anything else
    marker_map, camera = _as_map(marker_map), _as_camera(camera).for_image(image)
    seen, repeated = _placed_alone(image, marker_map, camera)
    if len(seen) < MIN_PRINT_MARKERS:
        raise SurveyError(_too_few(list(seen), repeated))
    keys = list(seen)
    src = np.array([seen[k] for k in keys])
    dst = np.array([marker_map.placements[k].translation_mm for k in keys], float)
    distance = _distances(src, dst, max(marker_map.marker_size(k) for k in keys), marker_map) + 1e-9
    kept = print_scale_kept(distance)
    scale, err = print_scale(src, dst, distance, _similarity)
    used = tuple(k for k, ok in zip(keys, kept) if ok)
    out = tuple(k for k, ok in zip(keys, kept) if not ok)
    if len(used) < MIN_PRINT_MARKERS:
        raise SurveyError(_disagree(used, out))
    if not (math.isfinite(scale) and math.isfinite(err)):
        raise SurveyError(_no_fit(marker_map))
    sizes = {k: scale * marker_map.marker_size(k) for k in used}
    return PrintCheck(float(scale), float(err), used, sizes, out, repeated)


def _placed_alone(image: np.ndarray, marker_map: MarkerMap, camera: Camera) -> tuple[dict, tuple]:
    """``(top-left corners, repeated)``: each map marker detected once, placed alone in the camera's frame (mm).

    A marker detected twice or more (a reflection, one id printed twice) is ``repeated``, not placed.
    """
    names = marker_map.dictionaries
    dets = detect_markers(image, names if len(names) > 1 else names[0])
    keys = [marker_map.key(d.id, d.dictionary) for d in dets]
    repeated = tuple(dict.fromkeys(k for k in keys if k in marker_map and keys.count(k) > 1))
    seen: dict = {}
    for key, d in zip(keys, dets):
        if key in marker_map and key not in repeated:
            placed = placement_from_photo(d.corners_px, camera, np.eye(4), marker_map.marker_size(key))
            if placed is not None:
                seen[key] = placed[1]
    return seen, repeated


def _distances(src: np.ndarray, dst: np.ndarray, floor_mm: float, marker_map: MarkerMap) -> np.ndarray:
    """Each marker's distance (mm) from the map's top-left corner after a similarity fitted robustly.

    The similarity is the one most markers agree with within ``floor_mm`` (seeded by triples of markers, as the
    survey's gross test does), refitted on them, so one marker taped elsewhere cannot drag it.
    """
    inliers = _consensus(src, dst, floor_mm)
    sim = _similarity(src[inliers], dst[inliers]) if int(inliers.sum()) >= 3 else _similarity(src, dst)
    if sim is None:
        raise SurveyError(_no_fit(marker_map))
    s, R, t = sim
    return np.linalg.norm(dst - (s * src @ R.T + t), axis=1)


def _too_few(seen: list, repeated: tuple) -> str:
    twice = f", and {[str(k) for k in repeated]} twice (not counted)" if repeated else ""
    return (
        f"the photo shows {len(seen)} marker{'s' if len(seen) != 1 else ''} of the map "
        f"({[str(k) for k in seen]}){twice}; the print's scale needs at least {MIN_PRINT_MARKERS}: take a photo "
        "with more of them in view, spread out"
    )


def _disagree(used: tuple, out: tuple) -> str:
    verb = "is" if len(out) == 1 else "are"
    return (
        f"only {len(used)} of the {len(used) + len(out)} markers of the map in the photo ({[str(k) for k in used]}) "
        f"are where the map puts them beside each other, {[str(k) for k in out]} {verb} not (moved after they were "
        f"measured, or a wrong id?); the print's scale needs {MIN_PRINT_MARKERS} that agree: take a photo with "
        "more of them in view, or measure those again"
    )


def _no_fit(marker_map: MarkerMap) -> str:
    return (
        f"the markers in the photo do not fit the map ({marker_map.source}) at any scale near 1: check the map's "
        "units and positions, or take a photo with the markers spread out (not all in one line)"
    )
