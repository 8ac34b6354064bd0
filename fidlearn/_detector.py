"""OpenCV's ``ArucoDetector`` made from fidlearn's detector parameters, cached by what makes it, and the marker
ids a caller asks for, checked against the dictionary.

:mod:`fidlearn.detection` finds markers with these detectors; :mod:`fidlearn.tracking` and
:func:`fidlearn.locate` read the same parameters (the border's width in cells) to look again where a marker
should be.
"""

from __future__ import annotations

from collections import OrderedDict
from functools import lru_cache
from types import MappingProxyType
from typing import Any

from . import _cv
from .errors import DictionaryError, FidlearnError

#: OpenCV detector parameters fidlearn changes from OpenCV's defaults, by measurement
#: (``benchmarks/bench_detection.py``, docs/benchmarks.md: recall, false ids and wrong corners on a video,
#: rendered rooms, walls of large markers, rooms in hard light and the bundled survey photos, ArUco and AprilTag
#: dictionaries): ``minMarkerDistanceRate`` 0.065 (OpenCV's 0.125 drops a marker's outline for another quad when
#: its white margin is one cell wide), ``perspectiveRemovePixelPerCell`` 8 (a small marker's cells read at 8
#: samples, not 4) and threshold windows 3 and 23 px (step 20), which find 99.6 % of the video's markers
#: against OpenCV's 98.9 % in about 0.7 x its time. Larger cells can also decode a quad around a marker and
#: its white margin as the marker, a quarter turn off (``data/survey/photo_14.jpg``, marker 0): every
#: detection's quad is checked to be its marker's outline, and read again inside when it is not (see
#: :func:`detect_markers`). A ``detector_params`` dict overrides these field by field; a
#: ``cv2.aruco.DetectorParameters`` object is used as it is.
DEFAULT_DETECTOR_PARAMS: MappingProxyType = MappingProxyType(
    {"minMarkerDistanceRate": 0.065, "perspectiveRemovePixelPerCell": 8, "adaptiveThreshWinSizeStep": 20}
)

_DETECTOR_CACHE: OrderedDict[tuple, Any] = OrderedDict()
_DETECTOR_CACHE_SIZE = 16


def _params_key(params: Any) -> Any:
    """A hashable summary of ``params`` that is cheap for the usual cases (None, a dict)."""
    if params is None:
        return None
    if isinstance(params, dict):
        key = ("dict", tuple(sorted(params.items(), key=lambda kv: str(kv[0]))))
        try:
            hash(key)
        except TypeError:
            raise FidlearnError(
                f"detector parameter values must be numbers or booleans, got {params!r}; "
                "e.g. detector_params={'minMarkerPerimeterRate': 0.02}"
            ) from None
        return key
    return ("fields", tuple(sorted(_cv.detector_parameter_fields(params).items())))


def _detector_fields(params: Any) -> dict:
    """Every OpenCV detector field for ``params``: fidlearn's defaults (:data:`DEFAULT_DETECTOR_PARAMS`)
    under a dict of overrides (or None), a ``DetectorParameters`` object as it is."""
    if params is None or isinstance(params, dict):
        params = {**DEFAULT_DETECTOR_PARAMS, **(params or {})}
    return _cv.detector_parameter_fields(params)


def _limits_scaled(fields: dict, picture_px: float, image_px: float) -> dict:
    """``fields`` with the marker size limits (``minMarkerPerimeterRate``, ``maxMarkerPerimeterRate``: fractions of
    the image's longer side) of an image whose longer side is ``image_px`` set to the pixels they mean on one of
    ``picture_px``: a window of a frame, or a sheet of crops, admits the markers the whole picture would."""
    scale = picture_px / image_px
    return {
        **fields,
        "minMarkerPerimeterRate": float(fields["minMarkerPerimeterRate"]) * scale,
        "maxMarkerPerimeterRate": float(fields["maxMarkerPerimeterRate"]) * scale,
    }


def _detector(dictionary: str, refine: str, params: Any, ids: tuple[int, ...] | None = None):
    """The cached ``ArucoDetector`` for (dictionary, refinement, parameters, ids), its marker's side in
    cells and whether inverted markers (light border) may come out."""
    key = (dictionary, refine, _params_key(params), ids)
    hit = _DETECTOR_CACHE.get(key)
    if hit is not None:
        _DETECTOR_CACHE.move_to_end(key)
        return hit
    fields = _detector_fields(params)
    # fidlearn's "edges" starts from OpenCV's unrefined corners.
    fields["cornerRefinementMethod"] = _cv.corner_refine_flag("none" if refine == "edges" else refine)
    try:
        cv_params = _cv.make_detector_parameters(**fields)
    except TypeError as exc:  # OpenCV names the type it wanted, not the field
        given = {k: v for k, v in (params or {}).items()} if isinstance(params, dict) else params
        raise FidlearnError(
            f"detector parameters {given!r}: {exc}; check each field's type in cv2.aruco.DetectorParameters"
        ) from None
    detector = _cv.make_detector(dictionary, cv_params, ids=ids)
    cells = _cv.dictionary_marker_bits(dictionary) + 2 * int(fields["markerBorderBits"])
    hit = _DETECTOR_CACHE[key] = (detector, cells, bool(fields["detectInvertedMarker"]))
    while len(_DETECTOR_CACHE) > _DETECTOR_CACHE_SIZE:
        _DETECTOR_CACHE.popitem(last=False)
    return hit


@lru_cache(maxsize=64)
def _dictionary_name(name: str) -> str:
    return _cv.dictionary_name(name)


def _wanted_ids(ids: Any, dictionary: str) -> tuple[int, ...]:
    """``ids`` as a sorted tuple of distinct ids that exist in ``dictionary``; a map's ids (a list of ints) are
    checked once and remembered (``locate`` passes the same 50 ids with every frame)."""
    if type(ids) in (list, tuple) and all(type(i) is int for i in ids):
        try:
            return _wanted_int_ids(tuple(ids), dictionary)
        except FidlearnError:
            pass  # raised again below, naming the ids as they were given
    return _checked_ids(ids, dictionary)


@lru_cache(maxsize=32)
def _wanted_int_ids(ids: tuple[int, ...], dictionary: str) -> tuple[int, ...]:
    """:func:`_checked_ids` of a tuple of ints, remembered (an error is not)."""
    return _checked_ids(ids, dictionary)


def _checked_ids(ids: Any, dictionary: str) -> tuple[int, ...]:
    """``ids`` as a sorted tuple of distinct ids that exist in ``dictionary``."""
    try:
        wanted = tuple(sorted({int(i) for i in ids if float(i) == int(i)} if not isinstance(ids, (str, bytes)) else ()))
        whole = len(wanted) == len(set(ids))
    except (TypeError, ValueError, OverflowError):
        wanted, whole = (), False
    if not wanted or not whole:
        raise FidlearnError(f"ids must be whole marker ids such as [0, 1, 2] (a map's ids), got {ids!r}")
    size = _cv.dictionary_size(dictionary)
    if wanted[0] < 0 or wanted[-1] >= size:
        raise DictionaryError(f"dictionary {dictionary} has ids 0 to {size - 1}; ids {list(wanted)} do not all fit")
    return wanted
