"""The survey's inputs: photos (files, arrays or detections) to detected corners, and the checks.

Each photo becomes a :class:`_Photo`: its label, the camera fitted to it, and the detected
corners of every marker of the map's dictionaries (``{key: (4, 2) px}``, TL, TR, BR, BL; the key is
the map's, :meth:`fidlearn.MarkerMap.key`: the plain id in the map's own dictionary, a
:class:`~fidlearn.MarkerKey` in another).
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._files import repeated_paths
from ..camera import Camera
from ..detection import Detection, detect_markers
from ..errors import ImageError, SurveyError
from ..images import load_image
from ..markermap import MarkerKey, MarkerMap
from ..pose._inputs import _as_camera, _as_map

#: At least this many photos must give a camera pose.
MIN_PHOTOS = 2
#: Largest tape sigma (mm) and corner noise (px) taken: beyond them the weights underflow.
MAX_MAP_SIGMA_MM = 1e5
MAX_CORNER_SIGMA_PX = 100.0
#: Smallest tape sigma (mm) and corner noise (px) taken: no tape measures finer (a placement known
#: exactly is a fixed marker), no detector finds corners finer, and below them the weights overflow.
MIN_MAP_SIGMA_MM = 0.01
MIN_CORNER_SIGMA_PX = 0.001
#: Most photos in one survey, refused before any is read (a room needs 20 to 100).
MAX_PHOTOS = 400
#: Most sightings (a marker detected in a photo) in one survey: the adjustment's work grows faster
#: than them (about 20 s for 1,200, some 240 photos of 5 markers, on a busy 2-core machine).
MAX_SIGHTINGS = 1200
#: Detected corners farther than this many image sizes outside the image are refused.
MAX_CORNER_OUTSIDE = 10


@dataclass
class _Photo:
    label: str
    camera: Camera
    corners: dict[int, np.ndarray]
    T_world_camera: np.ndarray | None = None
    reason: str = ""
    extra: dict = field(default_factory=dict)


def _check_options(marker_map, camera, map_sigma_mm, fixed_ids, corner_sigma_px) -> tuple:
    """``(marker_map, camera, sigma_mm, fixed)`` checked; raises SurveyError with the fix."""
    marker_map = _as_map(marker_map)
    camera = _as_camera(camera)
    sigma = _sigma_mm(map_sigma_mm)
    fixed = _fixed_ids(fixed_ids, marker_map)
    if np.any(np.asarray(camera.dist, float).ravel()[12:]):
        raise SurveyError(
            f"{camera.source or 'the camera'}: the survey's projection has no tilted-sensor terms (tauX, tauY, "
            "distortion coefficients 13 and 14); calibrate without CALIB_TILTED_MODEL"
        )
    if sigma is not None and math.isinf(sigma) and not fixed:
        raise SurveyError(
            "with map_sigma_mm=inf nothing ties the photos to the world: give fixed_ids (a marker whose "
            "placement is exact) or a finite map_sigma_mm"
        )
    if corner_sigma_px is not None and not (
        isinstance(corner_sigma_px, (int, float, np.floating, np.integer))
        and not isinstance(corner_sigma_px, bool)
        and MIN_CORNER_SIGMA_PX <= corner_sigma_px <= MAX_CORNER_SIGMA_PX
    ):
        raise SurveyError(
            f"corner_sigma_px must be a number of pixels above 0, from {MIN_CORNER_SIGMA_PX:g} to "
            f"{MAX_CORNER_SIGMA_PX:g}, or None to estimate it, got {_short(corner_sigma_px)}"
        )
    return marker_map, camera, sigma, fixed


def _short(value) -> str:
    """``repr(value)`` on one line, at most 60 characters (an array shows as one)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 60 else text[:57] + "..."


def _sigma_mm(map_sigma_mm) -> float | None:
    """The tape's sigma checked (mm); None to learn it from the tape residuals."""
    if map_sigma_mm is None:
        return None
    sigma = None
    if not isinstance(map_sigma_mm, (bool, str, bytes)):
        with contextlib.suppress(TypeError, ValueError):
            sigma = float(map_sigma_mm)
    if sigma is None:
        raise SurveyError(
            f"map_sigma_mm must be a length in mm (e.g. 10), or None to learn it, got {_short(map_sigma_mm)}"
        )
    if not (MIN_MAP_SIGMA_MM <= sigma <= MAX_MAP_SIGMA_MM or sigma == math.inf):
        raise SurveyError(
            f"map_sigma_mm must be above 0, from {MIN_MAP_SIGMA_MM:g} to {MAX_MAP_SIGMA_MM:g} mm (a placement "
            f"known exactly is a fixed marker: fixed_ids), or math.inf to trust the photos alone, "
            f"got {_short(map_sigma_mm)}"
        )
    return sigma


def _fixed_ids(fixed_ids, marker_map: MarkerMap) -> tuple[int, ...]:
    if fixed_ids is None:
        return ()
    if isinstance(fixed_ids, (int, np.integer)) and not isinstance(fixed_ids, bool):
        fixed_ids = [fixed_ids]
    if isinstance(fixed_ids, (str, bytes)):
        raise SurveyError(f"fixed_ids must be marker ids (whole numbers), got {_short(fixed_ids)}")
    try:
        if any(isinstance(i, bool) for i in fixed_ids):  # True is 1 to a set: [True, 1] would pass as [1]
            raise ValueError
        # a MarkerKey (a marker of another dictionary than the map's) stays itself: int() would make it its namesake
        keys = {i if isinstance(i, MarkerKey) else int(i) for i in fixed_ids if isinstance(i, MarkerKey) or int(i) == i}
        ids = tuple(sorted(keys, key=lambda k: (int(k), str(k))))
        if len(ids) != len(set(fixed_ids)):
            raise ValueError
    except (TypeError, ValueError, OverflowError):
        raise SurveyError(f"fixed_ids must be marker ids (whole numbers), got {_short(fixed_ids)}") from None
    missing = [i for i in ids if i not in marker_map]
    if missing:
        known = ", ".join(str(k) for k in marker_map.ids)
        raise SurveyError(
            f"fixed_ids has marker {missing[0]}, which is not in the map {marker_map.source} (markers {known}); "
            "a fixed marker must have a placement"
        )
    return ids


def _read_photos(images, marker_map: MarkerMap, camera: Camera, progress: Callable | None) -> list[_Photo]:
    """Detect the map's dictionaries' markers in every photo (or take the detections given)."""
    if isinstance(images, (str, os.PathLike, np.ndarray)) or not isinstance(images, Sequence):
        raise SurveyError(
            f"images must be a list of photos (paths, arrays or lists of Detection), got {type(images).__name__}"
        )
    if len(images) < MIN_PHOTOS:
        raise SurveyError(
            f"a survey needs at least {MIN_PHOTOS} photos, got {len(images)}; take photos that each show two or "
            "more markers, every marker in at least two of them"
        )
    if len(images) > MAX_PHOTOS:
        raise SurveyError(
            f"a survey takes at most {MAX_PHOTOS} photos, got {len(images)}; keep the {MAX_PHOTOS} that show the "
            "most markers (a room needs 20 to 100), or survey the room in parts that share markers"
        )
    if progress is not None and not callable(progress):
        raise SurveyError(f"progress must be a function progress(i, n, label) or None, got {type(progress).__name__}")
    repeats = repeated_paths(images)  # one file twice would count its corners twice
    if repeats:
        k, i = repeats[0]
        raise SurveyError(f"photos {k} and {i} are one file ({os.fspath(images[i])}): each photo counts once")
    photos = []
    for i, item in enumerate(images):
        photos.append(_one_photo(i, item, marker_map, camera))
        if progress is not None:
            _report(progress, i + 1, len(images), photos[-1].label)
    sightings = sum(len(ph.corners) for ph in photos)
    if sightings > MAX_SIGHTINGS:
        raise SurveyError(
            f"the {len(photos)} photos show markers {sightings} times, a survey takes at most {MAX_SIGHTINGS} "
            "sightings; keep fewer photos (a room needs 20 to 100), or survey the room in parts that share markers"
        )
    return photos


def _report(progress: Callable, i: int, n: int, label: str) -> None:
    """Call ``progress``; whatever it raises becomes a SurveyError naming it (the original as its cause)."""
    try:
        progress(i, n, label)
    except Exception as exc:
        raise SurveyError(
            f"the progress function raised {type(exc).__name__} ({exc}) {_at(i, n, label)}; the survey "
            "stopped: mend the function (it is called as progress(i, n, label))"
        ) from exc


def _at(i: int, n: int, label: str) -> str:
    """Where the survey was when ``progress(i, n, label)`` was called: after a photo, or at a stage."""
    return f"at {label!r}" if label in STAGES else f"after photo {i} of {n}"


#: The adjustment's stages, each reported as ``progress(n, n, stage)`` once the ``n`` photos are read.
STAGES = ("checking the tape", "adjusting", "adjusting with more photos")


def _one_photo(i: int, item, marker_map: MarkerMap, camera: Camera) -> _Photo:
    if isinstance(item, (str, os.PathLike)):
        label, item = str(item), load_image(item)
    else:
        label = f"photo {i}"
    if isinstance(item, np.ndarray):
        cam = camera.for_image(item)
        names = marker_map.dictionaries
        dets = detect_markers(item, dictionary=names[0] if len(names) == 1 else names)
    elif isinstance(item, Sequence) and all(isinstance(d, Detection) for d in item):
        cam, dets = camera, list(item)
    else:
        raise ImageError(f"images[{i}] is a {type(item).__name__}; give a path, an image array or a list of Detection")
    corners: dict[int, np.ndarray] = {}
    _check_corners(i, dets, cam)
    for d in dets:
        key = marker_map.key(d.id, getattr(d, "dictionary", None))
        if key in corners:  # the same marker twice in one photo: which one is where is unknowable
            corners[key] = None  # type: ignore[assignment]
        else:
            corners[key] = np.asarray(d.corners_px, float)
    kept = {k: v for k, v in corners.items() if v is not None}
    if cam.model == "fisheye":  # a ray 90 degrees or more off the axis has no normalized point: left out
        kept = {k: v for k, v in kept.items() if np.all(np.isfinite(cam.undistort_points(v)))}
    return _Photo(label, cam, kept)


def _check_corners(i: int, dets, cam: Camera) -> None:
    """Refuse corners that are not finite, or far outside the image (``MAX_CORNER_OUTSIDE`` image sizes)."""
    limit = MAX_CORNER_OUTSIDE * max(cam.image_size)
    for d in dets:
        c = np.asarray(d.corners_px, float)
        if not np.all(np.isfinite(c)) or np.abs(c).max() > limit:
            raise ImageError(
                f"images[{i}]: marker {d.id}'s corners ({', '.join(f'{v:.4g}' for v in c.ravel()[:2])}, ...) are not "
                f"finite pixels within {limit:g} of the "
                f"image ({cam.image_size[0]}x{cam.image_size[1]}); give the detections of that photo as detected"
            )
