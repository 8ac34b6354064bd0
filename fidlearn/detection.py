"""Finding ArUco markers in an image: ids and pixel corners in TL, TR, BR, BL order.

Pixel convention: OpenCV's, the centre of the top-left pixel is (0, 0).

:func:`detect_markers` wraps OpenCV's ``ArucoDetector`` (cached, so calling it
on every frame of a video costs only the detection itself) and then refines the
corners. The default refinement, ``"edges"``, is fidlearn's own: it fits a
straight line to each of the marker's four outer edges from sub-pixel edge
positions sampled across the edge, and intersects neighbouring lines. Why it is
the default, with the measurements, is in ``docs/corner_refinement.md``.
"""

from __future__ import annotations

import numbers
import os
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import cv2
import numpy as np

from . import _cv, _files
from .errors import DetectionError, DictionaryError, FidlearnError, ImageError

__all__ = [
    "Detection",
    "as_gray",
    "load_image",
    "detect_markers",
    "draw_detections",
    "refine_corners_edges",
    "REFINE_METHODS",
    "DEFAULT_REFINE",
]

CORNER_NAMES = ("TL", "TR", "BR", "BL")

#: Corner refinements :func:`detect_markers` knows: OpenCV's four and fidlearn's ``"edges"``.
REFINE_METHODS = ("none", "subpix", "contour", "apriltag", "edges")

#: The refinement used when none is asked for, chosen by measurement (docs/corner_refinement.md).
DEFAULT_REFINE = "edges"


@dataclass(frozen=True, eq=False)
class Detection:
    """One detected marker.

    Attributes
    ----------
    id : int
        The marker's id in its dictionary.
    corners : ndarray, shape (4, 2), float64
        Pixel corners in the order TL, TR, BR, BL (the marker's own top-left,
        whatever its rotation in the image), OpenCV pixel-centre convention.
    """

    id: int
    corners: np.ndarray

    def __post_init__(self) -> None:
        mid = self.id
        if isinstance(mid, (bool, np.bool_)) or not isinstance(mid, numbers.Integral):
            if not (isinstance(mid, numbers.Real) and float(mid).is_integer()):
                raise DetectionError(f"Detection id must be a whole marker id, got {mid!r}")
        if int(mid) < 0:
            raise DetectionError(f"Detection id {int(mid)} is negative; marker ids start at 0")
        try:
            c = np.asarray(self.corners, dtype=np.float64)
        except (TypeError, ValueError):
            raise DetectionError(f"marker {int(mid)}: corners must be numbers, (4, 2) pixels TL, TR, BR, BL") from None
        if c.size != 8:
            raise DetectionError(
                f"marker {int(mid)}: corners have shape {c.shape}, expected (4, 2) pixels in the order TL, TR, BR, BL"
            )
        object.__setattr__(self, "id", int(mid))
        object.__setattr__(self, "corners", c.reshape(4, 2))

    @property
    def center(self) -> np.ndarray:
        """Mean of the four corners (2,), pixels."""
        return self.corners.mean(axis=0)

    @property
    def side_px(self) -> float:
        """Mean side length in pixels."""
        return float(np.mean(np.linalg.norm(self.corners - np.roll(self.corners, -1, axis=0), axis=1)))

    def __repr__(self) -> str:
        pts = ", ".join(f"{n}=({x:.1f}, {y:.1f})" for n, (x, y) in zip(CORNER_NAMES, self.corners))
        return f"Detection(id={self.id}, {pts})"


def load_image(path: str | os.PathLike, max_pixels: int = _files.MAX_IMAGE_PIXELS) -> np.ndarray:
    """Read an image file as OpenCV does (BGR or gray, uint8), with a clear error when it cannot.

    Only a regular file is read (a folder, a FIFO or a device is refused before it is opened),
    and the picture's size is read from its header first: one larger than ``max_pixels``
    (100 megapixels unless raised) or a PNG or JPEG cut short is refused before decoding.
    Every failure is an :class:`ImageError` naming the file. Safe to call from several threads.

    Parameters
    ----------
    path : str or os.PathLike
        The picture (PNG, JPEG, BMP, TIFF, ... whatever OpenCV decodes).
    max_pixels : int
        Largest picture to decode, width times height.

    Returns
    -------
    ndarray, shape (H, W) or (H, W, 3) or (H, W, 4)
        The pixels as stored (uint8, or uint16 for 16-bit files), BGR order.
    """
    if isinstance(max_pixels, bool) or not isinstance(max_pixels, (int, np.integer)) or max_pixels < 1:
        raise ImageError(f"max_pixels must be a positive whole number of pixels, got {max_pixels!r}")
    path, data = _files.read_bytes(path, ImageError, "picture", _files.MAX_IMAGE_BYTES)
    if not data:
        raise ImageError(f"{path}: the file is empty; expected a PNG or JPEG image")
    _files.check_image_bytes(path, data, ImageError, int(max_pixels))
    try:
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:
        raise ImageError(
            f"{path}: OpenCV cannot decode it ({_cv.first_line(exc)}); is it truncated or another file type?"
        ) from None
    if image is None or image.size == 0:
        raise ImageError(
            f"{path}: not an image OpenCV can read (PNG, JPEG, BMP, TIFF...); is it truncated or another file type?"
        )
    return image


def as_gray(image: np.ndarray, where: str = "image") -> np.ndarray:
    """An 8-bit single-channel view of a gray, BGR or BGRA image (uint8 or uint16).

    16-bit images are scaled to 8 bits by the bits they use (a 12-bit camera's
    0..4095 in a 16-bit PNG becomes 0..255, a full-range one is shifted by 8);
    float images in [0, 1] are accepted too. Anything else raises :class:`ImageError` saying what was received.
    """
    if not isinstance(image, np.ndarray):
        raise ImageError(
            f"{where}: expected a numpy array (use fidlearn.detection.load_image for a file), got {type(image).__name__}"
        )
    if image.size == 0:
        raise ImageError(f"{where}: the image is empty (shape {image.shape})")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] not in (3, 4)):
        raise ImageError(f"{where}: shape {image.shape} is not an image; expected (H, W) gray or (H, W, 3) BGR")
    if image.dtype == np.uint16:
        # Shift by the bits the picture uses, not always 8: a 10- or 12-bit camera saved as 16-bit
        # PNG (0..1023, 0..4095) became a black 0..3 / 0..15 picture in which nothing is found.
        shift = max(int(image.max()).bit_length() - 8, 0)
        image = (image >> shift).astype(np.uint8)
    elif image.dtype in (np.float32, np.float64):
        if not np.all(np.isfinite(image)):
            raise ImageError(f"{where}: the float image contains NaN or infinity")
        if image.min() < 0 or image.max() > 1:
            raise ImageError(f"{where}: a float image must hold values in [0, 1], got {image.min():g}..{image.max():g}")
        image = np.round(image * 255).astype(np.uint8)
    elif image.dtype != np.uint8:
        raise ImageError(f"{where}: pixel type {image.dtype} is not supported; use uint8 (or uint16)")
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    if min(image.shape[:2]) < 8:
        raise ImageError(f"{where}: {image.shape[1]}x{image.shape[0]} pixels is too small to hold a marker")
    return np.ascontiguousarray(image)


# ----------------------------------------------------------------------------------------------
# Detection
# ----------------------------------------------------------------------------------------------

_DETECTOR_CACHE: OrderedDict[tuple, Any] = OrderedDict()
_DETECTOR_CACHE_SIZE = 16


def _refine_name(refine: Any) -> str:
    if isinstance(refine, str) and refine.strip().lower() in REFINE_METHODS:
        return refine.strip().lower()
    raise FidlearnError(
        f"unknown corner refinement {refine!r}; use one of {', '.join(repr(m) for m in REFINE_METHODS)} "
        f"(default {DEFAULT_REFINE!r}, see docs/corner_refinement.md)"
    )


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
                "e.g. params={'minMarkerPerimeterRate': 0.02}"
            ) from None
        return key
    return ("fields", tuple(sorted(_cv.detector_parameter_fields(params).items())))


def _detector(dictionary: str, refine: str, params: Any, ids: tuple[int, ...] | None = None):
    """The cached ``ArucoDetector`` for (dictionary, refinement, parameters, ids), its marker's side in
    cells and whether inverted markers (light border) may come out."""
    key = (dictionary, refine, _params_key(params), ids)
    hit = _DETECTOR_CACHE.get(key)
    if hit is not None:
        _DETECTOR_CACHE.move_to_end(key)
        return hit
    fields = _cv.detector_parameter_fields(params)
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


def detect_markers(
    image: np.ndarray,
    dictionary: str = "ARUCO_ORIGINAL",
    refine: str = DEFAULT_REFINE,
    params: Any = None,
    *,
    ids=None,
    return_rejected: bool = False,
):
    """Find the markers of one dictionary in an image.

    Parameters
    ----------
    image : ndarray, (H, W) gray or (H, W, 3) BGR or (H, W, 4) BGRA, uint8 or uint16
        The picture (see :func:`as_gray` for what is accepted).
    dictionary : str
        The ArUco dictionary by readable name: ``"ARUCO_ORIGINAL"``, ``"6X6_250"``,
        ``"APRILTAG_36h11"``... (the ``DICT_`` prefix and the case do not matter).
    refine : str
        Corner refinement: ``"edges"`` (the default: line fits to the four outer
        edges, about 0.03 px RMS on sharp synthetic markers of 30 px and more),
        or OpenCV's own ``"none"``, ``"subpix"``, ``"contour"``, ``"apriltag"``.
        See ``docs/corner_refinement.md`` for the measurements.
    params : None, dict or cv2.aruco.DetectorParameters
        OpenCV detector parameters, as an object or as ``{field: value}``
        overrides of the defaults. ``refine`` always sets ``cornerRefinementMethod``.
    ids : iterable of int, optional
        Look only for these markers of the dictionary (a world map's ids). The
        same markers come out as with the whole dictionary (none of the others
        can be mistaken for one of these), several times faster with a large
        dictionary: OpenCV compares every candidate quad with every marker it
        looks for. Markers outside ``ids`` are then not reported at all.
    return_rejected : bool
        Also return the candidate quads that did not decode as a marker.

    Returns
    -------
    list of Detection
        Sorted by id; each ``corners`` is (4, 2) float64 pixels, TL, TR, BR, BL.
    list of ndarray (4, 2), only with ``return_rejected=True``
        The rejected candidates' corners (pixels, unrefined).

    Raises
    ------
    ImageError
        ``image`` is not an image.
    DictionaryError
        Unknown dictionary name.
    FidlearnError
        Unknown refinement or parameter name.

    Examples
    --------
    >>> from fidlearn import _cv
    >>> marker = _cv.generate_marker("6X6_250", 23, 120)
    >>> image = np.pad(marker, 40, constant_values=255)
    >>> [d.id for d in detect_markers(image, "6X6_250")]
    [23]
    """
    gray = as_gray(image)
    name = _dictionary_name(dictionary) if isinstance(dictionary, str) else _cv.dictionary_name(dictionary)
    method = _refine_name(refine)
    wanted = None if ids is None else _wanted_ids(ids, name)
    detector, cells, inverted = _detector(name, method, params, wanted)
    corners, ids, rejected = _cv.detect_with_raw_rejected(detector, gray)
    if wanted is not None and len(ids):
        ids = np.asarray(wanted, dtype=np.int64)[np.asarray(ids, dtype=np.int64)]
    if len(corners) and method == "edges":
        corners = list(refine_corners_edges(gray, np.stack(corners), cells, inverted=None if inverted else False))
    order = sorted(range(len(ids)), key=lambda k: (int(ids[k]), float(corners[k][0, 1]), float(corners[k][0, 0])))
    detections = [Detection(int(ids[k]), corners[k]) for k in order]
    if return_rejected:
        return detections, _cv.rejected_quads(rejected)
    return detections


# ----------------------------------------------------------------------------------------------
# Edge-line corner refinement
# ----------------------------------------------------------------------------------------------

_NEXT = np.array([1, 2, 3, 0])
_PREV = np.array([3, 0, 1, 2])


@lru_cache(maxsize=8)
def _profile_grid(n_lines: int, n_samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions 0..1 along a side (N,), -1..1 across it (S,), and [1, u, u^2] (N, 3); read-only."""
    u = np.linspace(0.0, 1.0, n_lines)
    v = np.linspace(-1.0, 1.0, n_samples)
    U3 = np.column_stack([np.ones_like(u), u, u * u])
    for a in (u, v, U3):
        a.flags.writeable = False
    return u, v, U3


def refine_corners_edges(
    gray: np.ndarray,
    corners: np.ndarray,
    cells: int,
    *,
    inverted: bool | None = False,
    n_lines: int = 16,
    n_samples: int = 13,
    iterations: int = 1,
    expand_px: float = 0.5,
    gamma: float = 1.0,
) -> np.ndarray:
    """Refine marker corners by fitting a straight line to each outer edge.

    For each side of each quad, ``n_lines`` short profiles are sampled across
    the edge (bilinear, one ``cv2.remap`` for every marker at once); each
    profile's first crossing of the gray level half-way between the black
    border and the white quiet zone gives a sub-pixel edge position; a
    least-squares line goes through them (refitted once without the profiles
    0.75 px off it); each corner is the intersection of its two sides' lines.
    Blur rounds a corner but not the middle of an edge, so the intersection
    lands on the true corner where windowed corner detectors are pulled
    inwards. Numpy on arrays of all markers at once, points as complex numbers
    (x + iy): about 0.25-0.45 ms for six markers.

    Parameters
    ----------
    gray : ndarray (H, W) uint8
    corners : ndarray (M, 4, 2) float
        Pixel corners TL, TR, BR, BL of M markers: OpenCV's unrefined ones.
    cells : int
        Marker side in cells, black border included (8 for 6X6 with a 1-cell
        border). Profiles reach 0.6 cell (1.5 to 5 px) each side of the edge,
        so that they stay in the black border and the white quiet zone.
    inverted : bool or None
        Markers with a light border on a dark surround (OpenCV's
        ``detectInvertedMarker``); None: tell each side by its contrast.
    n_lines, n_samples : int
        Profiles per side, samples per profile.
    iterations : int
        Passes; a second one starts from the first's corners (a little better below 30 px).
    expand_px : float
        Where the first pass centres its profiles, outside the input quad: OpenCV's
        unrefined contour runs through the outermost dark pixels' centres, about
        half a pixel inside the edge.
    gamma : float
        The edge is where the light reaching the sensor is half-way between
        black and white. With 1 (the default) gray levels are taken as
        proportional to light, as in fidlearn's synthetic pictures; a camera that
        encodes its pictures with a gamma curve (sRGB: about 2.2) puts that point
        at a higher gray level, and ``gamma=2.2`` finds it there
        (docs/corner_refinement.md: real photos).

    Returns
    -------
    ndarray (M, 4, 2) float64
        Refined pixel corners (pixel centres at integers). A marker whose four
        edges cannot all be fitted (too little contrast, too few crossings) or
        whose corners would move more than ``max(3, cell / 2)`` px keeps its input corners.
    """
    C = np.ascontiguousarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    M = C.shape[0]
    if M == 0:
        return C.copy()
    u, v, U3 = _profile_grid(int(n_lines), int(n_samples))
    n_lines, n_samples = u.size, v.size
    half, mid_sample = n_lines // 2, n_samples // 2
    rows = np.arange(M * 4 * n_lines)
    Z = C.view(np.complex128)[..., 0]  # (M, 4) corners as x + iy
    shift = float(expand_px)
    for _ in range(iterations):
        Dz = Z[:, _NEXT] - Z  # (M, 4) side vectors
        L = np.maximum(np.abs(Dz), 1e-9)  # side lengths, px
        # Outward unit normal: -i times the side direction when the corners turn clockwise on screen
        # (y down), as OpenCV reports them for a marker seen from its front.
        nz = Dz * (np.where((Dz[:, 0].conj() * Dz[:, 1]).imag >= 0, -1j, 1j)[:, None] / L)
        cell = L.sum(1) * (0.25 / cells)  # (M,) px per cell
        h = np.clip(0.6 * cell, 1.5, 5.0)  # profile half-length, px
        margin = np.minimum((0.5 * cell[:, None] + 1.5) / L, 0.3)  # keep clear of the corners
        span = 1.0 - 2.0 * margin
        t = margin[..., None] + span[..., None] * u  # (M, 4, N) along the side, 0..1
        pts = (Z[..., None] + t * Dz[..., None])[..., None] + (shift + h[:, None] * v)[:, None, None, :] * nz[
            ..., None, None
        ]
        # (x, y) pairs, one row per side: remap wants fewer than 32767 rows and columns
        maps = pts.astype(np.complex64).view(np.float32).reshape(M * 4, n_lines * n_samples, 2)
        prof = cv2.remap(gray, maps, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        prof = prof.reshape(M, 4, n_lines, n_samples).astype(np.float32)
        # Levels: the darkest sample of the inner half and the brightest of the outer half (a narrow
        # quiet zone with a darker wall beyond still gives the paper's level), median over each side.
        pin, pout = prof[..., : mid_sample + 1], prof[..., mid_sample:]
        if inverted is None:  # which way round is the contrast larger?
            imin, imax, omin, omax = pin.min(-1), pin.max(-1), pout.min(-1), pout.max(-1)
            normal = ((omax - imin) >= (imax - omin)).mean(-1) >= 0.5  # (M, 4): dark inside
            dark = np.sort(np.where(normal[..., None], imin, -imax), axis=2)[..., half]  # levels x polarity
            light = np.sort(np.where(normal[..., None], omax, -omin), axis=2)[..., half]
            prof = prof * np.where(normal, 1.0, -1.0).astype(np.float32)[..., None, None]
        elif inverted:
            dark = np.sort(-pin.max(-1), axis=2)[..., half]
            light = np.sort(-pout.min(-1), axis=2)[..., half]
            prof = -prof
        else:
            dark = np.sort(pin.min(-1), axis=2)[..., half]
            light = np.sort(pout.max(-1), axis=2)[..., half]
        level = 0.5 * (dark + light)
        if gamma != 1.0:  # half-way in light, not in gray level: levels are polarity x gray, |.| the gray
            g = float(gamma)
            lin = 0.5 * ((np.abs(dark) / 255.0) ** g + (np.abs(light) / 255.0) ** g)
            level = np.where(light < 0, -255.0, 255.0) * lin ** (1.0 / g)
        zf = (prof - level[..., None, None]).reshape(-1, n_samples)  # < 0 inside the edge
        # The edge: the first sample at or above the mid level, k, and the one before it (outward from
        # there the profile may fall again where a narrow quiet zone meets a darker wall).
        k = np.maximum(np.argmax(zf >= 0, axis=-1), 1)
        z0, z1 = zf[rows, k - 1], zf[rows, k]
        dz = z0 - z1
        found = (z0 <= 0) & (dz < 0)
        pos = k + z0 / np.where(found, dz, -1.0)  # in samples, + 1
        off = (pos.reshape(M, -1) - (mid_sample + 1)) * (h * (2.0 / (n_samples - 1)))[:, None] + shift
        off = off.reshape(M, 4, n_lines)  # edge position outside the quad's side, px
        w = (found.reshape(M, 4, n_lines) & (light - dark > 20.0)[..., None]).astype(np.float64)
        # Weighted least squares off = alpha + beta u (u: the fixed 0..1 grid of profiles), twice:
        # the second time without the profiles 0.75 px off the first line.
        for final in (False, True):
            s3 = w @ U3  # (M, 4, 3): sums of w, w u, w u^2
            s2 = (w * off) @ U3[:, :2]  # sums of w off, w u off
            sw, su, suu = s3[..., 0], s3[..., 1], s3[..., 2]
            det = np.maximum(sw * suu - su * su, 1e-12)
            alpha = (suu * s2[..., 0] - su * s2[..., 1]) / det
            beta = (sw * s2[..., 1] - su * s2[..., 0]) / det
            if not final:
                w = w * (np.abs(off - alpha[..., None] - beta[..., None] * u) < 0.75)
        b = beta / span  # the same line in t (0 at corner k, 1 at corner k+1)
        a = alpha - b * margin
        # Side k's line: through A = Z[k] + a n, direction Dz + b n; corner k = line k-1 x line k.
        A, d = Z + a * nz, Dz + b * nz
        Ap, dp = A[:, _PREV], d[:, _PREV]
        den = (dp.conj() * d).imag
        ok = ((sw >= 4) & (det > 1e-9) & (np.abs(den) > 1e-9 * L * L)).all(1)
        new = Ap + ((A - Ap).conj() * d).imag / np.where(ok[:, None], den, 1.0) * dp
        ok &= np.abs(new - Z).max(1) < np.maximum(3.0, 0.5 * cell)
        Z = np.where(ok[:, None], new, Z)
        shift = 0.0
    return np.stack([Z.real, Z.imag], axis=-1)


# ----------------------------------------------------------------------------------------------
# Drawing
# ----------------------------------------------------------------------------------------------


def _as_bgr(image: np.ndarray) -> np.ndarray:
    if isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3:
        return image.copy()
    if isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return cv2.cvtColor(as_gray(image), cv2.COLOR_GRAY2BGR)


def _label(
    img: np.ndarray, text: str, org: tuple[float, float], scale: float, thick: int, color, center: bool = True
) -> None:
    """Text with a dark box behind it so it reads on any background; ``org`` is its centre."""
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
    x = int(round(org[0] - tw / 2)) if center else int(round(org[0]))
    y = int(round(org[1] + th / 2))
    H, W = img.shape[:2]
    x = min(max(x, 1), max(W - tw - 2, 1))
    y = min(max(y, th + 2), max(H - base - 1, th + 2))
    pad = max(1, thick)
    cv2.rectangle(img, (x - pad, y - th - pad), (x + tw + pad, y + base), (0, 0, 0), -1)
    cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, color, thick, cv2.LINE_AA)


def draw_detections(
    image: np.ndarray,
    detections: Sequence[Detection],
    color: tuple[int, int, int] = (0, 200, 0),
    *,
    corner_labels: bool = True,
    show_ids: bool = True,
    rejected: Sequence[np.ndarray] | None = None,
) -> np.ndarray:
    """A BGR copy of ``image`` with each marker's outline, id and named corners drawn.

    The outline is drawn at sub-pixel precision; the first corner (TL) is a
    filled red dot and every corner carries its name (TL, TR, BR, BL) outside
    the marker, so the winding order is visible; the id sits in the middle.
    Text size follows the image size (readable on 640x480).

    Parameters
    ----------
    image : ndarray
        Gray, BGR or BGRA image (not modified).
    detections : sequence of Detection
    color : (b, g, r)
        Outline colour.
    corner_labels, show_ids : bool
        Draw the corner names / the ids.
    rejected : sequence of (4, 2) arrays, optional
        Candidate quads that did not decode (from ``detect_markers(..., return_rejected=True)``),
        drawn thin in magenta.

    Returns
    -------
    ndarray (H, W, 3) uint8
        The annotated copy.
    """
    out = _as_bgr(image)
    if isinstance(detections, (str, bytes)) or not hasattr(detections, "__iter__"):
        raise DetectionError(
            f"detections must be a list of Detection (from detect_markers), got {type(detections).__name__}"
        )
    detections = list(detections)
    for det in detections:
        if not isinstance(det, Detection):
            raise DetectionError(
                f"detections must hold Detection objects (from detect_markers), got {type(det).__name__}"
            )
    H, W = out.shape[:2]
    unit = max(H, W) / 640.0
    thick = max(1, int(round(1.5 * unit)))
    scale = 0.42 * unit
    shift = 4  # sub-pixel drawing: coordinates in 1/16 px
    for quad in rejected or ():
        q = np.round((np.asarray(quad, np.float64).reshape(4, 2)) * (1 << shift)).astype(np.int32)
        cv2.polylines(out, [q], True, (255, 0, 255), 1, cv2.LINE_AA, shift)
    for det in detections:
        c = np.asarray(det.corners, np.float64).reshape(4, 2)
        q = np.round(c * (1 << shift)).astype(np.int32)
        cv2.polylines(out, [q], True, color, thick, cv2.LINE_AA, shift)
        centre = c.mean(axis=0)
        for k, (name, p) in enumerate(zip(CORNER_NAMES, c)):
            dot = (0, 0, 255) if k == 0 else (255, 128, 0)
            cv2.circle(
                out,
                tuple(int(v) for v in np.round(p * (1 << shift))),
                int(round((2.5 + thick) * (1 << shift))),
                dot,
                -1,
                cv2.LINE_AA,
                shift,
            )
            if corner_labels:
                away = p - centre
                away = away / max(float(np.linalg.norm(away)), 1e-9)
                at = p + away * 10.0 * unit
                _label(out, name, (float(at[0]), float(at[1])), 0.8 * scale, max(1, thick - 1), (255, 255, 255))
        if show_ids:
            _label(out, str(det.id), (float(centre[0]), float(centre[1])), scale * 1.2, thick, (0, 255, 255))
    return out
