"""Every difference between the OpenCV releases fidlearn supports (4.8 to 5.x), in one place.

The rest of fidlearn calls these helpers and never branches on the OpenCV
version itself.  Known differences:

* ``cv2.aruco.Dictionary_get``, ``DetectorParameters_create`` and the free
  function ``cv2.aruco.detectMarkers`` are gone since 4.7; detection goes
  through ``cv2.aruco.ArucoDetector``.
* ``ids`` comes back shaped (N, 1) before OpenCV 5 and (N,) from 5.0; ``None``
  when nothing is found.
* The numbers of the ``SOLVEPNP_*`` flags changed in 5.0 (IPPE is 6 in 4.x and
  4 in 5.x; DLS and UPNP were removed): always look flags up by name.
* ``cv2.aruco.calibrateCameraCharuco`` and ``estimatePoseSingleMarkers`` are
  gone; ChArUco corners come from ``cv2.aruco.CharucoDetector`` and calibration
  from ``cv2.calibrateCamera``.
* ``cv2.calibrateCamera`` optimises differently in 5.0: on a poorly
  conditioned problem (OpenCV's four ChArUco tutorial photos, the very same
  96 corners) 4.14 settles at fx 479.8, cy 256.8 and 5.0 at fx 457.3,
  cy 275.6, with the same RMS; judge such results by their standard deviations.
* Not a difference but a trap on both: ``cv2.VideoCapture(-1)`` crashes the
  interpreter (segmentation fault) when no camera is attached; never pass a
  negative camera index. ``cv2.Rodrigues`` returns a zero vector for rotations
  below 1e-5 rad (``frames.rvec_tvec_from_transform`` takes the skew part there).
"""

from __future__ import annotations

import re
from functools import lru_cache
from typing import Any

import cv2
import numpy as np

from .errors import DictionaryError, FidlearnError

OPENCV_VERSION: tuple[int, int, int] = tuple(int(x) for x in re.findall(r"\d+", cv2.__version__)[:3])  # type: ignore[assignment]

#: ``cv2.aruco``, or None when this OpenCV has none (checked by :func:`require_aruco` before each use).
_ARUCO: Any = getattr(cv2, "aruco", None)

#: Readable dictionary names (without the ``DICT_`` prefix) to OpenCV constants.
DICTIONARIES: dict[str, int] = {}
if _ARUCO is not None:
    for _attr in dir(_ARUCO):
        if _attr.startswith("DICT_"):
            _name = _attr[len("DICT_") :]
            # OpenCV spells the AprilTag families both 36h11 and 36H11: keep the lower-case one.
            if _name.upper() == _name and _name.startswith(("APRILTAG_", "ARUCO_MIP_")):
                continue
            DICTIONARIES[_name] = getattr(_ARUCO, _attr)


def first_line(exc: BaseException) -> str:
    """The informative line of a ``cv2.error`` (OpenCV's messages span several lines).

    Parameters
    ----------
    exc : BaseException

    Returns
    -------
    str
        The text after OpenCV's ``error:``, or the last line.
    """
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    for ln in lines:
        if "error:" in ln:
            return ln.split("error:", 1)[1].strip()
    return lines[-1] if lines else type(exc).__name__


def require_aruco() -> None:
    """Raise a clear error when the installed OpenCV has no ``aruco`` module."""
    if _ARUCO is None or not hasattr(_ARUCO, "ArucoDetector"):
        raise FidlearnError(
            f"OpenCV {cv2.__version__} has no cv2.aruco.ArucoDetector; install "
            "'opencv-contrib-python-headless>=4.8' and remove other OpenCV wheels "
            "(run 'fidlearn doctor')"
        )


def dictionary_name(name: str) -> str:
    """Normalise a dictionary name: ``"DICT_6X6_250"``, ``"6x6_250"`` -> ``"6X6_250"``.

    Parameters
    ----------
    name : str
        A dictionary name, any case, with or without ``DICT_``.

    Returns
    -------
    str
        The name as :data:`DICTIONARIES` spells it.

    Raises
    ------
    DictionaryError
        Not a name OpenCV knows (the message suggests close ones).

    Examples
    --------
    >>> dictionary_name("dict_6x6_250")
    '6X6_250'
    """
    if not isinstance(name, str) or not name.strip():
        raise DictionaryError(f"dictionary name {name!r} is not a non-empty string; try 'ARUCO_ORIGINAL'")
    key = name.strip()
    if key.upper().startswith("DICT_"):
        key = key[5:]
    for known in DICTIONARIES:
        if known.upper() == key.upper():
            return known
    close = [k for k in DICTIONARIES if key.upper().split("_")[0] in k.upper()]
    hint = f" (did you mean {', '.join(close[:4])}?)" if close else ""
    raise DictionaryError(f"unknown ArUco dictionary {name!r}{hint}; known: {', '.join(sorted(DICTIONARIES))}")


def get_dictionary(name: str):
    """The ``cv2.aruco.Dictionary`` for a readable name.

    Parameters
    ----------
    name : str
        A dictionary name (see :func:`dictionary_name`).

    Returns
    -------
    cv2.aruco.Dictionary
    """
    require_aruco()
    return _ARUCO.getPredefinedDictionary(DICTIONARIES[dictionary_name(name)])


@lru_cache(maxsize=64)
def dictionary_size(name: str) -> int:
    """How many markers a dictionary holds (ids run from 0 to size - 1).

    Parameters
    ----------
    name : str

    Returns
    -------
    int
        Markers in it, e.g. 250 for ``6X6_250``.

    Examples
    --------
    >>> dictionary_size("6X6_250"), dictionary_size("ARUCO_ORIGINAL")
    (250, 1024)
    """
    return int(get_dictionary(name).bytesList.shape[0])


def dictionary_marker_bits(name: str) -> int:
    """The marker's inner grid side in cells (6 for 6X6_250), without the black border.

    Parameters
    ----------
    name : str

    Returns
    -------
    int
        Inner cells per side.
    """
    return int(get_dictionary(name).markerSize)


def make_detector_parameters(**overrides):
    """``cv2.aruco.DetectorParameters`` with attributes set by name.

    Parameters
    ----------
    **overrides
        Field values by name, e.g. ``minMarkerPerimeterRate=0.02``.

    Returns
    -------
    cv2.aruco.DetectorParameters

    Raises
    ------
    FidlearnError
        An unknown field, or a value of the wrong type.
    """
    require_aruco()
    params = _ARUCO.DetectorParameters()
    for key, value in overrides.items():
        if not hasattr(params, key):
            raise FidlearnError(f"OpenCV's DetectorParameters has no field {key!r}")
        try:
            setattr(params, key, value)
        except (TypeError, ValueError, OverflowError, cv2.error) as exc:
            raise FidlearnError(f"detector parameter {key}={value!r}: {first_line(exc)}") from None
    return params


def sub_dictionary(name: str, ids) -> cv2.aruco.Dictionary:
    """A ``cv2.aruco.Dictionary`` holding only ``ids`` of a predefined dictionary, in that order.

    A detector built on it reports the index into ``ids``, not the id. It finds the
    same markers as the whole dictionary: a predefined dictionary corrects fewer bits
    than half the distance between any two of its markers, so a marker outside ``ids``
    can never be read as one inside. It is faster, because OpenCV compares every
    candidate quad that does not decode with every marker of the dictionary (1024 for
    ARUCO_ORIGINAL).

    Parameters
    ----------
    name : str
        A predefined dictionary's name.
    ids : iterable of int
        The markers to keep, in the order the detector will index them.

    Returns
    -------
    cv2.aruco.Dictionary
    """
    require_aruco()
    full = get_dictionary(name)
    ids = np.asarray(list(ids), dtype=np.int64)
    return _ARUCO.Dictionary(full.bytesList[ids], int(full.markerSize), int(full.maxCorrectionBits))


def make_detector(dictionary: str, params=None, ids=None):
    """A ``cv2.aruco.ArucoDetector`` for a dictionary name (only ``ids`` of it, if given).

    Parameters
    ----------
    dictionary : str
    params : cv2.aruco.DetectorParameters, optional
        OpenCV's defaults when None.
    ids : iterable of int, optional
        Only these markers (see :func:`sub_dictionary`: the detector then reports indices into ``ids``).

    Returns
    -------
    cv2.aruco.ArucoDetector
    """
    require_aruco()
    if params is None:
        params = make_detector_parameters()
    d = get_dictionary(dictionary) if ids is None else sub_dictionary(dictionary, ids)
    return _ARUCO.ArucoDetector(d, params)


CORNER_REFINE = {
    "none": "CORNER_REFINE_NONE",
    "subpix": "CORNER_REFINE_SUBPIX",
    "contour": "CORNER_REFINE_CONTOUR",
    "apriltag": "CORNER_REFINE_APRILTAG",
}


def corner_refine_flag(name: str) -> int:
    """OpenCV's corner refinement constant for ``none``, ``subpix``, ``contour`` or ``apriltag``.

    Parameters
    ----------
    name : str
        ``"none"``, ``"subpix"``, ``"contour"`` or ``"apriltag"``.

    Returns
    -------
    int
        The ``cv2.aruco.CORNER_REFINE_*`` value.
    """
    require_aruco()
    return int(getattr(_ARUCO, CORNER_REFINE[name]))


def detect(detector, gray: np.ndarray) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
    """Run a detector; return corners as a list of (4, 2) float64, ids as (N,) int, and rejected quads.

    Parameters
    ----------
    detector : cv2.aruco.ArucoDetector
    gray : ndarray, shape (H, W), uint8

    Returns
    -------
    corners : list of ndarray, shape (4, 2), float64
        Pixel corners TL, TR, BR, BL, unrefined beyond the detector's own refinement.
    ids : ndarray, shape (N,), int64
        The ids (indices into ``ids`` for a detector made with some ids only).
    rejected : list of ndarray, shape (4, 2), float64
        Candidate quads that did not decode.

    Raises
    ------
    FidlearnError
        OpenCV refused the detector parameters.
    """
    corners, ids, rejected = _detect_markers(detector, gray)
    return normalize_detections(corners, ids) + (rejected_quads(rejected),)


def _detect_markers(detector, gray: np.ndarray):
    try:
        return detector.detectMarkers(gray)
    except cv2.error as exc:  # OpenCV checks the detector parameters only now
        raise FidlearnError(
            f"OpenCV refused the detector parameters ({first_line(exc)}); "
            "see cv2.aruco.DetectorParameters for each field's valid range"
        ) from None


def normalize_detections(corners, ids) -> tuple[list[np.ndarray], np.ndarray]:
    """Corners (list of (4, 2) float64) and ids ((N,) int64) from any OpenCV release's output.

    Parameters
    ----------
    corners : sequence of array-like
        OpenCV's corners, (1, 4, 2) or (4, 2) each.
    ids : array-like or None
        OpenCV's ids, (N, 1) or (N,); None when nothing was found.

    Returns
    -------
    corners : list of ndarray, shape (4, 2), float64
    ids : ndarray, shape (N,), int64
    """
    if ids is None or len(corners) == 0:
        return [], np.zeros((0,), dtype=np.int64)
    ids = np.asarray(ids).reshape(-1).astype(np.int64)
    return [np.asarray(c, dtype=np.float64).reshape(4, 2) for c in corners], ids


def solvepnp_flag(name: str) -> int:
    """The ``cv2.SOLVEPNP_*`` constant for a name such as ``"IPPE"``; the numbers differ between releases.

    Parameters
    ----------
    name : str
        A method name, any case, e.g. ``"ippe"``, ``"sqpnp"``.

    Returns
    -------
    int
        The ``cv2.SOLVEPNP_*`` value.

    Raises
    ------
    FidlearnError
        This OpenCV has no such method (the message lists the known ones).
    """
    attr = "SOLVEPNP_" + name.upper()
    if not hasattr(cv2, attr):
        known = sorted(
            a[len("SOLVEPNP_") :] for a in dir(cv2) if a.startswith("SOLVEPNP_") and a != "SOLVEPNP_MAX_COUNT"
        )
        raise FidlearnError(
            f"this OpenCV ({cv2.__version__}) has no solvePnP method {name!r}; known: {', '.join(known)}"
        )
    return int(getattr(cv2, attr))


def generate_marker(dictionary: str, marker_id: int, side_px: int, border_bits: int = 1) -> np.ndarray:
    """The marker's image (side_px x side_px, uint8, black border included).

    Parameters
    ----------
    dictionary : str
    marker_id : int
    side_px : int
        The image's side, pixels.
    border_bits : int
        Width of the black border, in cells.

    Returns
    -------
    ndarray, shape (side_px, side_px), uint8
    """
    require_aruco()
    d = get_dictionary(dictionary)
    return _ARUCO.generateImageMarker(d, int(marker_id), int(side_px), borderBits=int(border_bits))


def detector_parameter_fields(params=None) -> dict:
    """Every field of ``cv2.aruco.DetectorParameters`` as ``{name: value}``.

    ``params`` is ``None`` (OpenCV's defaults), a dict of overrides of the
    defaults, or a ``DetectorParameters`` object. The field set differs between
    releases (5.x adds e.g. ``relativeCornerRefinmentWinSize``), so it is read
    from the object rather than listed here. The values are plain numbers, so
    the sorted items make a cache key.

    Parameters
    ----------
    params : None, dict or cv2.aruco.DetectorParameters

    Returns
    -------
    dict
        ``{field: value}`` for every field.

    Raises
    ------
    FidlearnError
        Another type of ``params``, or a dict naming a field OpenCV does not have.
    """
    require_aruco()
    overrides = {}
    if params is None:
        base = _ARUCO.DetectorParameters()
    elif isinstance(params, dict):
        base, overrides = _ARUCO.DetectorParameters(), params
    elif isinstance(params, _ARUCO.DetectorParameters):
        base = params
    else:
        raise FidlearnError(
            f"detector parameters must be None, a dict of field overrides or cv2.aruco.DetectorParameters, "
            f"got {type(params).__name__}"
        )
    fields = {}
    for name in dir(base):
        if name.startswith("_"):
            continue
        value = getattr(base, name)
        if callable(value):
            continue
        fields[name] = value
    for key, value in overrides.items():
        if key not in fields:
            raise FidlearnError(f"OpenCV's DetectorParameters has no field {key!r}; known: {', '.join(sorted(fields))}")
        fields[key] = value
    return fields


def detect_with_raw_rejected(detector, gray: np.ndarray) -> tuple[list[np.ndarray], np.ndarray, tuple]:
    """Like :func:`detect`, but the rejected candidates stay as OpenCV returns them (converting
    hundreds of them costs time a caller that does not look at them need not pay); pass them to
    :func:`rejected_quads` when they are wanted.

    Parameters
    ----------
    detector : cv2.aruco.ArucoDetector
    gray : ndarray, shape (H, W), uint8

    Returns
    -------
    corners : list of ndarray, shape (4, 2), float64
    ids : ndarray, shape (N,), int64
    rejected : tuple
        OpenCV's rejected candidates, unconverted.
    """
    corners, ids, rejected = _detect_markers(detector, gray)
    return normalize_detections(corners, ids) + (rejected if rejected is not None else (),)


def detect_stacked(detector, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
    """Like :func:`detect_with_raw_rejected`, with the corners as one array: the same values, converted in one
    call rather than one a marker.

    Parameters
    ----------
    detector : cv2.aruco.ArucoDetector
    gray : ndarray, shape (H, W), uint8

    Returns
    -------
    corners : ndarray, shape (N, 4, 2), float64
    ids : ndarray, shape (N,), int64
    rejected : tuple
        OpenCV's rejected candidates, unconverted.
    """
    corners, ids, rejected = _detect_markers(detector, gray)
    rejected = rejected if rejected is not None else ()
    if ids is None or len(corners) == 0:
        return np.zeros((0, 4, 2)), np.zeros((0,), dtype=np.int64), rejected
    return (
        np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2),
        np.asarray(ids).reshape(-1).astype(np.int64),
        rejected,
    )


def rejected_quads(rejected) -> list[np.ndarray]:
    """Rejected candidates from OpenCV as a list of (4, 2) float64 pixel corners.

    Parameters
    ----------
    rejected : sequence of array-like or None

    Returns
    -------
    list of ndarray, shape (4, 2), float64
    """
    return [np.asarray(r, dtype=np.float64).reshape(4, 2) for r in (rejected or ())]
