"""Finding ArUco markers in an image: ids and pixel corners in TL, TR, BR, BL order.

Pixel convention: OpenCV's, the centre of the top-left pixel is (0, 0).

:func:`detect_markers` wraps OpenCV's ``ArucoDetector`` (cached, so calling it
on every frame of a video costs only the detection itself) and then refines the
corners. The default refinement, ``"edges"``, is fidlearn's own: it fits a
straight line to each of the marker's four outer edges from sub-pixel edge
positions sampled across the edge, and intersects neighbouring lines. Why it is
the default, with the measurements, is in ``docs/corner_refinement.md``. Whatever the refinement, every
decoded quad must be its marker's outline (its four outer edges fitted there); the detector parameters
fidlearn changes, and why, are in :data:`DEFAULT_DETECTOR_PARAMS`.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from . import _cv
from ._detector import DEFAULT_DETECTOR_PARAMS, _detector, _dictionary_name, _wanted_ids
from .errors import DetectionError, DictionaryError, FidlearnError
from .images import as_gray, load_image
from .refinement import _refine_edges, refine_corners_edges

__all__ = [
    "Detection",
    "as_gray",
    "load_image",
    "detect_markers",
    "detect_markers_with_rejected",
    "dictionaries_in",
    "DetectionsWithRejected",
    "refine_corners_edges",
    "REFINE_METHODS",
    "DEFAULT_REFINE",
    "DEFAULT_DETECTOR_PARAMS",
]

CORNER_NAMES = ("TL", "TR", "BR", "BL")

#: Corner refinements :func:`detect_markers` knows: OpenCV's four and fidlearn's ``"edges"``.
REFINE_METHODS = ("none", "subpix", "contour", "apriltag", "edges")

#: The refinement used when none is asked for, chosen by measurement (docs/corner_refinement.md).
DEFAULT_REFINE = "edges"


@dataclass(frozen=True, eq=False, init=False)
class Detection:
    """One detected marker.

    Parameters
    ----------
    id : int
        The marker's id in its dictionary (a whole number >= 0).
    corners_px : array-like, shape (4, 2)
        Pixel corners in the order TL, TR, BR, BL (the marker's own top-left,
        whatever its rotation in the image), OpenCV pixel-centre convention.
    dictionary : str, optional
        The dictionary the marker was read in (:func:`detect_markers` says it). None: the map's own,
        whichever map the detection meets. A marker is (dictionary, id): a map matches a detection
        to its marker ``marker_map.key(id, dictionary)``.

    Attributes
    ----------
    id : int
        The marker's id.
    corners_px : ndarray, shape (4, 2), float64
        Pixel corners TL, TR, BR, BL.
    dictionary : str or None
        As given.

    Raises
    ------
    DetectionError
        The id is not a whole number >= 0, or the corners are not (4, 2) numbers.

    Examples
    --------
    >>> d = Detection(7, [[10, 10], [30, 10], [30, 30], [10, 30]])
    >>> d.id, d.corners_px.shape, d.side_px
    (7, (4, 2), 20.0)
    >>> d.center.tolist()
    [20.0, 20.0]
    """

    id: int
    corners_px: np.ndarray
    dictionary: str | None

    def __init__(self, id: int, corners_px: Any = None, dictionary: str | None = None) -> None:  # noqa: A002
        if corners_px is None:
            raise DetectionError(f"marker {id!r}: corners_px missing, (4, 2) pixels TL, TR, BR, BL")
        object.__setattr__(self, "id", id)
        object.__setattr__(self, "corners_px", corners_px)
        if dictionary is not None:
            try:
                dictionary = _dictionary_name(dictionary)
            except (DictionaryError, TypeError, AttributeError):
                raise DetectionError(f"marker {id!r}: unknown dictionary {dictionary!r}") from None
        object.__setattr__(self, "dictionary", dictionary)
        self.__post_init__()

    def __post_init__(self) -> None:
        mid = self.id
        not_integral = isinstance(mid, (bool, np.bool_)) or not isinstance(mid, numbers.Integral)
        if not_integral and not (isinstance(mid, numbers.Real) and float(mid).is_integer()):
            raise DetectionError(f"Detection id must be a whole marker id, got {mid!r}")
        if int(mid) < 0:
            raise DetectionError(f"Detection id {int(mid)} is negative; marker ids start at 0")
        try:
            c = np.asarray(self.corners_px, dtype=np.float64)
        except (TypeError, ValueError):
            raise DetectionError(f"marker {int(mid)}: corners must be numbers, (4, 2) pixels TL, TR, BR, BL") from None
        if (c.size != 8 or c.shape[-1:] != (2,)) and c.shape != (8,):  # (4, 2), OpenCV's (1, 4, 2), or (8,)
            hint = ": one row per corner, transpose it" if c.shape == (2, 4) else ""
            raise DetectionError(
                f"marker {int(mid)}: corners have shape {c.shape}, expected (4, 2) pixels in the order TL, TR, BR, "
                f"BL{hint}"
            )
        object.__setattr__(self, "id", int(mid))
        object.__setattr__(self, "corners_px", c.reshape(4, 2))
        if not hasattr(self, "dictionary"):
            object.__setattr__(self, "dictionary", None)

    def _with_corners(self, corners_px: np.ndarray) -> Detection:
        """The same marker with other corners, (4, 2) float64 that the caller made from checked ones (an
        undistortion, a refinement): the id and dictionary were checked when ``self`` was built, so
        nothing is checked again (``estimate_pose`` and ``locate`` move every corner of every frame)."""
        out = object.__new__(Detection)
        object.__setattr__(out, "id", self.id)
        object.__setattr__(out, "corners_px", corners_px)
        object.__setattr__(out, "dictionary", self.dictionary)
        return out

    @property
    def center(self) -> np.ndarray:
        """Mean of the four corners (2,), pixels."""
        return self.corners_px.mean(axis=0)

    @property
    def side_px(self) -> float:
        """Mean side length in pixels."""
        return float(np.mean(np.linalg.norm(self.corners_px - np.roll(self.corners_px, -1, axis=0), axis=1)))

    def __repr__(self) -> str:
        pts = ", ".join(f"{n}=({x:.1f}, {y:.1f})" for n, (x, y) in zip(CORNER_NAMES, self.corners_px))
        return f"Detection(id={self.id}, {pts})"


# ----------------------------------------------------------------------------------------------
# Detection
# ----------------------------------------------------------------------------------------------


def _refine_name(refine: Any) -> str:
    if isinstance(refine, str) and refine.strip().lower() in REFINE_METHODS:
        return refine.strip().lower()
    raise FidlearnError(
        f"unknown corner refinement {refine!r}; use one of {', '.join(repr(m) for m in REFINE_METHODS)} "
        f"(default {DEFAULT_REFINE!r}, see docs/corner_refinement.md)"
    )


def _detect(image: np.ndarray, dictionary: Any, refine: str, detector_params: Any, ids: Any):
    """Detections sorted by id (then dictionary, in the order given); OpenCV's raw rejected candidates and the quads
    that are no marker's outline. Several dictionaries: one detector each (OpenCV 4 and 5 alike), ``ids`` then a
    mapping of dictionary to ids (a dictionary it does not name is not searched)."""
    if isinstance(dictionary, (list, tuple)):
        return _detect_several(image, dictionary, refine, detector_params, ids)
    return _detect_one(as_gray(image), dictionary, refine, detector_params, ids)


def _detect_several(image: np.ndarray, dictionaries: Any, refine: str, detector_params: Any, ids: Any):
    if not dictionaries:
        raise DictionaryError("no dictionary to detect; give one name such as 'ARUCO_ORIGINAL', or a list of names")
    gray = as_gray(image)
    names = list(
        dict.fromkeys(_dictionary_name(d) if isinstance(d, str) else _cv.dictionary_name(d) for d in dictionaries)
    )
    if ids is not None and not isinstance(ids, Mapping):
        raise FidlearnError(
            f"with several dictionaries, ids must map each dictionary to its ids, e.g. {{{names[0]!r}: [0, 1]}}; "
            f"got {type(ids).__name__}"
        )
    wanted = None if ids is None else {_dictionary_name(k): v for k, v in ids.items()}
    dets: list[Detection] = []
    rejected: list = []
    for name in names:
        if wanted is not None and not wanted.get(name):
            continue
        found, rej = _detect_one(gray, name, refine, detector_params, None if wanted is None else wanted[name])
        dets += found
        rejected += list(rej)
    order = {n: k for k, n in enumerate(names)}
    dets.sort(
        key=lambda d: (d.id, order.get(d.dictionary or "", 0), float(d.corners_px[0, 1]), float(d.corners_px[0, 0]))
    )
    return dets, tuple(rejected)


def _detect_one(gray: np.ndarray, dictionary: Any, refine: str, detector_params: Any, ids: Any):
    name = _dictionary_name(dictionary) if isinstance(dictionary, str) else _cv.dictionary_name(dictionary)
    method = _refine_name(refine)
    wanted = None if ids is None else _wanted_ids(ids, name)
    detector, cells, inverted = _detector(name, method, detector_params, wanted)

    lookup = None if wanted is None else np.asarray(wanted, dtype=np.int64)

    def find(img: np.ndarray, x0: int = 0, y0: int = 0) -> tuple[np.ndarray, np.ndarray, Any]:
        corners, found, rejected = _cv.detect_stacked(detector, img)
        if lookup is not None and len(found):
            found = lookup[found]
        return (corners + (x0, y0) if x0 or y0 else corners), found, rejected

    corners, found, rejected = find(gray)
    dets, dropped = _outlined(gray, corners, found, cells, inverted, method == "edges", name)
    if dropped:
        dets = _read_inside(gray, find, dets, dropped, cells, inverted, method == "edges", name)
    return dets, (*(rejected or ()), *(q.astype(np.float32).reshape(1, 4, 2) for _, q in dropped))


def _outlined(
    gray: np.ndarray,
    corners: Any,
    ids: Any,
    cells: int,
    inverted: bool,
    refine: bool,
    dictionary: str | None = None,
):
    """The detections, sorted by id, whose quads are their markers' outlines, and ``(id, quad)`` of the others.

    Every quad's four outer edges are fitted as the ``"edges"`` refinement does (profiles across each side
    only, O(markers x side)); a quad whose sides show no dark border inside a light surround, or whose edges lie
    farther from it than the profiles reach (``refinement._move_limit``), is not the marker's outline: a decoder
    that samples large cells can read a quad around a marker and its white margin as that marker, a quarter turn
    off (``data/survey/photo_14.jpg``, marker 0). ``corners``: (M, 4, 2) or a list of (4, 2); ``ids``: (M,).
    ``refine``: report the fitted corners, else OpenCV's. ``dictionary``: what each Detection says."""
    if len(corners) == 0:
        return [], []
    C = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    ids = np.asarray(ids, dtype=np.int64).reshape(-1)
    fitted, ok = _refine_edges(gray, C, cells, None if inverted else False)
    if refine:
        C = fitted
    keep = np.flatnonzero(ok)
    # by id, then the first corner's y and x (a stable sort, as sorted() with that key)
    keep = keep[np.lexsort((C[keep, 0, 0], C[keep, 0, 1], ids[keep]))]
    dropped = [(int(ids[k]), C[k]) for k in np.flatnonzero(~ok)]
    return [_detection(i, c, dictionary) for i, c in zip(ids[keep].tolist(), C[keep])], dropped


def _detection(id: int, corners_px: np.ndarray, dictionary: str | None) -> Detection:  # noqa: A002
    """A Detection of checked parts, built without checking them again: ``id`` an int >= 0 from the detector,
    ``corners_px`` (4, 2) float64, ``dictionary`` a name :func:`_dictionary_name` gave (or None). What
    ``Detection(id, corners_px, dictionary)`` makes, at a fifth of its cost (50 markers a frame)."""
    out = object.__new__(Detection)
    object.__setattr__(out, "id", id)
    object.__setattr__(out, "corners_px", corners_px)
    object.__setattr__(out, "dictionary", dictionary)
    return out


def _read_inside(
    gray: np.ndarray, find, dets: list, dropped: list, cells: int, inverted: bool, refine: bool, dictionary=None
):
    """``dets`` with the markers read again inside the quads :func:`_outlined` dropped: the same detector on the
    quad's bounding box (4 px more each side) with everything outside the quad, one pixel in, painted white, so
    that the marker's own outline is the only one left; kept when it has the dropped quad's id and passes the
    same check. O(quad's area), for the dropped quads only."""
    H, W = gray.shape
    corners, ids = [], []
    for i, q in dropped:
        x0, y0 = np.maximum(np.floor(q.min(axis=0)).astype(int) - 4, 0)
        x1, y1 = np.minimum(np.ceil(q.max(axis=0)).astype(int) + 5, [W, H])
        if min(x1 - x0, y1 - y0) < 16:
            continue
        inside = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.fillConvexPoly(inside, np.round(q - (x0, y0)).astype(np.int32), 1)
        crop = np.where(cv2.erode(inside, np.ones((3, 3), np.uint8)) > 0, gray[y0:y1, x0:x1], 255).astype(np.uint8)
        c, k, _ = find(crop, int(x0), int(y0))
        corners += [cc for cc, kk in zip(c, k) if kk == i]
        ids += [int(kk) for kk in k if kk == i]
    new, _ = _outlined(gray, corners, ids, cells, inverted, refine, dictionary)
    new = [d for d in new if not any(e.id == d.id and np.abs(e.corners_px - d.corners_px).max() < 2.0 for e in dets)]
    if not new:
        return dets
    return sorted(dets + new, key=lambda d: (d.id, float(d.corners_px[0, 1]), float(d.corners_px[0, 0])))


def detect_markers(
    image: np.ndarray,
    dictionary: str | Sequence[str] = "ARUCO_ORIGINAL",
    refine: str = DEFAULT_REFINE,
    detector_params: Any = None,
    *,
    ids=None,
) -> list[Detection]:
    """Find the markers of one dictionary in an image.

    Parameters
    ----------
    image : ndarray, (H, W) gray or (H, W, 3) BGR or (H, W, 4) BGRA, uint8 or uint16
        The picture (see :func:`as_gray` for what is accepted).
    dictionary : str or sequence of str
        The ArUco dictionary by readable name: ``"ARUCO_ORIGINAL"``, ``"6X6_250"``,
        ``"APRILTAG_36h11"``... (the ``DICT_`` prefix and the case do not matter). Several names
        (a map's ``dictionaries``): each is searched with its own detector, and every detection says
        its dictionary, so the same id in two dictionaries comes out as two markers.
    refine : str
        Corner refinement: ``"edges"`` (the default: line fits to the four outer
        edges, about 0.03 px RMS on sharp synthetic markers of 30 px and more),
        or OpenCV's own ``"none"``, ``"subpix"``, ``"contour"``, ``"apriltag"``.
        See ``docs/corner_refinement.md`` for the measurements.
    detector_params : None, dict or cv2.aruco.DetectorParameters
        OpenCV detector parameters, as an object (used as it is) or as ``{field: value}``
        overrides of fidlearn's defaults (:data:`DEFAULT_DETECTOR_PARAMS`, which change three of
        OpenCV's for recall and speed). ``refine`` always sets ``cornerRefinementMethod``.
    ids : iterable of int, optional
        Look only for these markers of the dictionary (a world map's ids). The
        same markers come out as with the whole dictionary (none of the others
        can be mistaken for one of these), several times faster with a large
        dictionary: OpenCV compares every candidate quad with every marker it
        looks for. Markers outside ``ids`` are then not reported at all. With several
        dictionaries, a mapping ``{dictionary: ids}``.

    Returns
    -------
    list of Detection
        Sorted by id (then by dictionary, in the order given), each with its ``dictionary``; each
        ``corners_px`` is (4, 2) float64 pixels, TL, TR, BR, BL. Only quads that are
        their marker's outline: OpenCV's decoded quads whose four outer edges are fitted (a dark border
        inside a light surround on every side, the fitted edges within the profiles' reach of the quad;
        profiles across the sides only, as the ``"edges"`` refinement samples them, whatever ``refine`` is).
        A quad that is not (a marker and its white margin read as the marker, a quarter turn off) is
        dropped, and the same detector reads its inside again with everything outside it painted white: the
        marker found there with the same id, and passing the same check, is reported instead.

    Raises
    ------
    ImageError
        ``image`` is not an image.
    DictionaryError
        Unknown dictionary name.
    FidlearnError
        Unknown refinement or parameter name.

    See Also
    --------
    detect_markers_with_rejected : the same, with the candidates that did not decode.

    Examples
    --------
    >>> from fidlearn import _cv
    >>> marker = _cv.generate_marker("6X6_250", 23, 120)
    >>> image = np.pad(marker, 40, constant_values=255)
    >>> [d.id for d in detect_markers(image, "6X6_250")]
    [23]
    """
    return _detect(image, dictionary, refine, detector_params, ids)[0]


#: The largest dictionary of each family: a smaller one of the family is its first markers, printed alike.
_FAMILIES = ("ARUCO_ORIGINAL", "4X4_1000", "5X5_1000", "6X6_1000", "7X7_1000", "APRILTAG_36h11", "APRILTAG_25h9")


def dictionaries_in(image: np.ndarray, exclude: str | Sequence[str] = ()) -> dict[str, list[int]]:
    """Which dictionaries' markers a picture shows: for a picture in which the expected dictionary finds none.

    A detector sees only the markers of its own dictionary, so a map of ``ARUCO_ORIGINAL`` markers finds
    nothing in a photo of printed ``4X4_50`` markers. This searches the picture with the largest dictionary
    of each family (ArUco original, 4x4, 5x5, 6x6 and 7x7, AprilTag 36h11 and 25h9) and names each family
    found by its smallest dictionary that holds every id seen (``4X4_50`` for ids under 50).

    Parameters
    ----------
    image : ndarray
        The picture, as :func:`detect_markers` takes it.
    exclude : str or sequence of str
        Dictionaries already searched (a map's): their family is left out.

    Returns
    -------
    dict of str to list of int
        ``{dictionary: sorted ids}``, empty when the picture shows no marker of any family.

    Raises
    ------
    ImageError
        ``image`` is not an image.
    DictionaryError
        An unknown name in ``exclude``.

    Examples
    --------
    >>> from fidlearn import _cv
    >>> image = np.pad(_cv.generate_marker("4X4_50", 7, 120), 40, constant_values=255)
    >>> dictionaries_in(image, exclude="ARUCO_ORIGINAL")
    {'4X4_50': [7]}
    """
    skip = {_family(_dictionary_name(n)) for n in ([exclude] if isinstance(exclude, str) else exclude)}
    found: dict[str, list[int]] = {}
    for name in _FAMILIES:
        if _family(name) in skip:
            continue
        ids = sorted({d.id for d in detect_markers(image, name, refine="none")})
        if ids:
            found[_smallest_holding(name, ids[-1])] = ids
    return found


def _family(name: str) -> str:
    """``"4X4"`` for ``"4X4_250"``; a dictionary without sizes is its own family."""
    head, _, size = name.rpartition("_")
    return head if size.isdigit() and "X" in head else name


def _smallest_holding(name: str, largest_id: int) -> str:
    """The smallest dictionary of ``name``'s family with an id ``largest_id``."""
    if _family(name) == name:
        return name
    return next(f"{_family(name)}_{n}" for n in (50, 100, 250, 1000) if largest_id < n)


@dataclass(frozen=True)
class DetectionsWithRejected:
    """What :func:`detect_markers_with_rejected` returns.

    Attributes
    ----------
    detections : list of Detection
        Exactly what :func:`detect_markers` returns.
    rejected : list of ndarray, shape (4, 2)
        The rejected candidates' corners (pixels, unrefined), then the decoded quads that were no
        marker's outline, for ``draw_detections(..., rejected=...)``.
    """

    detections: list[Detection]
    rejected: list[np.ndarray]


def detect_markers_with_rejected(
    image: np.ndarray,
    dictionary: str | Sequence[str] = "ARUCO_ORIGINAL",
    refine: str = DEFAULT_REFINE,
    detector_params: Any = None,
    *,
    ids=None,
) -> DetectionsWithRejected:
    """Find the markers as :func:`detect_markers` does, and the candidate quads that did not decode.

    Parameters
    ----------
    image, dictionary, refine, detector_params, ids :
        As for :func:`detect_markers`.

    Returns
    -------
    DetectionsWithRejected
        ``detections``, exactly what :func:`detect_markers` returns, and ``rejected``, the
        candidate quads (4, 2) that did not decode (see :func:`detect_markers`).

    Raises
    ------
    ImageError, DictionaryError, FidlearnError
        As for :func:`detect_markers`.

    Examples
    --------
    >>> from fidlearn import _cv
    >>> image = np.pad(_cv.generate_marker("6X6_250", 23, 120), 40, constant_values=255)
    >>> found = detect_markers_with_rejected(image, "6X6_250")
    >>> [d.id for d in found.detections], type(found.rejected).__name__
    ([23], 'list')
    """
    detections, rejected = _detect(image, dictionary, refine, detector_params, ids)
    return DetectionsWithRejected(detections, _cv.rejected_quads(rejected))
