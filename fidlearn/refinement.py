"""fidlearn's corner refinement ``"edges"``: a straight line fitted to each outer edge of a marker.

:func:`refine_corners_edges` samples sub-pixel edge positions across each of the marker's four
outer edges, fits a line to each side and intersects neighbouring lines. Why it is
:func:`fidlearn.detect_markers`' default, with the measurements, is in ``docs/corner_refinement.md``.

Pixel convention: OpenCV's, the centre of the top-left pixel is (0, 0).
"""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np

__all__ = ["refine_corners_edges"]


_NEXT = np.array([1, 2, 3, 0])
#: Gray levels between a side's dark border and light surround below which its edge is not fitted (the
#: corners stay as they came), and below which the side is taken as no marker's outline at all.
_FIT_CONTRAST, _CHECK_CONTRAST = 20.0, 8.0
_PREV = np.array([3, 0, 1, 2])


@lru_cache(maxsize=8)
def _profile_grid(n_lines: int, n_samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions 0..1 along a side (N,), -1..1 across it (S,), and [1, u, u^2] (N, 3); read-only, made once."""
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
        whose corners would move farther than the edges can be found (:func:`_move_limit`) keeps its input corners;
        one whose corners the last pass moved ``max(3, cell / 2)`` px or more is fitted once more from there.
    """
    _check_arguments(gray, corners, cells, n_lines, n_samples, iterations, expand_px, gamma)
    return _refine_edges(gray, corners, cells, inverted, n_lines, n_samples, iterations, expand_px, gamma)[0]


def _check_arguments(gray, corners, cells, n_lines, n_samples, iterations, expand_px, gamma) -> None:
    """ImageError or DetectionError, with the fix, for what :func:`refine_corners_edges` cannot use."""
    from .errors import DetectionError, ImageError  # noqa: PLC0415

    if not isinstance(gray, np.ndarray) or gray.ndim != 2 or gray.dtype != np.uint8 or min(gray.shape) < 2:
        what = f"{gray.dtype} array of shape {gray.shape}" if isinstance(gray, np.ndarray) else type(gray).__name__
        raise ImageError(
            f"refine_corners_edges: gray must be a uint8 picture (H, W), got a {what}; convert it with "
            "fidlearn.detection.as_gray"
        )
    c = np.asarray(corners, dtype=float) if isinstance(corners, (np.ndarray, list, tuple)) else np.zeros(1)
    if c.size % 8 or not np.isfinite(c).all():  # none at all is fine: none to refine
        raise DetectionError(f"refine_corners_edges: corners must be finite (M, 4, 2) pixels, got shape {c.shape}")
    for name, value, least in (
        ("cells", cells, 3),
        ("n_lines", n_lines, 2),
        ("n_samples", n_samples, 3),
        ("iterations", iterations, 1),
    ):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise DetectionError(f"refine_corners_edges: {name} must be a whole number >= {least}, got {value!r:.40}")
    for name, value, positive in (("expand_px", expand_px, False), ("gamma", gamma, True)):
        ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
        if not (ok and math.isfinite(value) and (value > 0 if positive else abs(value) < 100)):
            what = "a finite number above 0" if positive else "a finite number of pixels"
            raise DetectionError(f"refine_corners_edges: {name} must be {what}, got {value!r:.40}")


def _refine_edges(
    gray: np.ndarray,
    corners: np.ndarray,
    cells: int,
    inverted: bool | None = False,
    n_lines: int = 16,
    n_samples: int = 13,
    iterations: int = 1,
    expand_px: float = 0.5,
    gamma: float = 1.0,
    refit: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`refine_corners_edges`' corners (M, 4, 2) and whether each marker's four edges were fitted (M,) bool.

    False says that no dark border meets a light surround along the quad's sides, or that the edges found
    lie farther from them than :func:`_move_limit` allows: the quad is not the outline of a marker's black border
    (a marker's white margin decoded as the marker, ``data/survey/photo_14.jpg``), or too faint to fit."""
    C = np.ascontiguousarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    M = C.shape[0]
    if M == 0:
        return C.copy(), np.ones(0, dtype=bool)
    u, v, U3 = _profile_grid(int(n_lines), int(n_samples))
    Z = C.view(np.complex128)[..., 0]  # (M, 4) corners as x + iy
    shift = float(expand_px)
    fitted = np.ones(M, dtype=bool)
    for _ in range(iterations):
        Dz, L, nz, cell, h, margin, span, prof = _profiles_across(gray, Z, cells, u, v, shift)
        prof, dark, light, level = _levels_across(prof, inverted, gamma)
        off, w = _edge_offsets_across(prof, level, dark, light, h, shift, _CHECK_CONTRAST)
        alpha, beta, sw, det = _fit_lines(w, off, u, U3)
        b = beta / span  # the same line in t (0 at corner k, 1 at corner k+1)
        a = alpha - b * margin
        # Side k's line: through A = Z[k] + a n, direction Dz + b n; corner k = line k-1 x line k.
        A, d = Z + a * nz, Dz + b * nz
        Ap, dp = A[:, _PREV], d[:, _PREV]
        den = (dp.conj() * d).imag
        ok = ((sw >= 4) & (det > 1e-9) & (np.abs(den) > 1e-9 * L * L)).all(1)
        new = Ap + ((A - Ap).conj() * d).imag / np.where(ok[:, None], den, 1.0) * dp
        moved = np.abs(new - Z).max(1)
        ok &= moved < _move_limit(cell, h, shift)
        fitted &= ok
        # the corners move only where every side's contrast is enough to fit a line to it
        Z = np.where((ok & (light - dark > _FIT_CONTRAST).all(1))[:, None], new, Z)
        shift = 0.0
    out = np.stack([Z.real, Z.imag], axis=-1)
    if refit and iterations > 0:
        far = fitted & (light - dark > _FIT_CONTRAST).all(1) & (moved >= np.maximum(3.0, 0.5 * cell))
        if far.any():
            _fit_far_again(gray, C, out, fitted, far, cells, inverted, n_lines, n_samples, gamma)
    return out, fitted


def _profiles_across(gray: np.ndarray, Z: np.ndarray, cells: int, u: np.ndarray, v: np.ndarray, shift: float):
    """The quads' geometry and the gray profiles across each side, sample by sample: (S, M, 4, N) uint8.

    Each sample's points are one operation over every profile of every marker (``centre + v h n`` in x and y
    at once), and so is each step along the profiles afterwards, where profile by profile (M, 4, N, S) each
    operation ran a loop of S for every profile. The sampled points are ``Z + t Dz + (shift + v h) n`` as
    before this layout, summed in another order (float32 maps the same but for the last bit, rarely)."""
    M = Z.shape[0]
    n_lines, n_samples = u.size, v.size
    Dz = Z[:, _NEXT] - Z  # (M, 4) side vectors
    L = np.maximum(np.abs(Dz), 1e-9)  # side lengths, px
    # Outward unit normal: -i times the side direction when the corners turn clockwise on screen
    # (y down), as OpenCV reports them for a marker seen from its front.
    nz = Dz * (np.where((Dz[:, 0].conj() * Dz[:, 1]).imag >= 0, -1j, 1j)[:, None] / L)
    cell = L.sum(1) * (0.25 / cells)  # (M,) px per cell
    h = np.minimum(np.maximum(0.6 * cell, 1.5), 5.0)  # profile half-length, px
    margin = np.minimum((0.5 * cell[:, None] + 1.5) / L, 0.3)  # keep clear of the corners
    span = 1.0 - 2.0 * margin
    t = margin[..., None] + span[..., None] * u  # (M, 4, N) along the side, 0..1
    centre = Z[..., None] + t * Dz[..., None] + shift * nz[..., None]  # (M, 4, N) each profile's centre
    step = np.repeat(h[:, None] * nz, n_lines)  # (M 4 N,) its half-length along the normal
    # (x, y) pairs, each sample one operation over every profile: centre + v h n; one row per sample and
    # marker (_read_at keeps within remap's 32767 rows and columns)
    maps = np.multiply.outer(v, step.view(np.float64))
    maps += centre.view(np.float64).reshape(-1)
    maps = maps.astype(np.float32).reshape(n_samples * M, 4 * n_lines, 2)
    prof = _read_at(gray, maps, cv2.INTER_LINEAR)
    return Dz, L, nz, cell, h, margin, span, prof.reshape(n_samples, M, 4, n_lines)


#: Most points :func:`_read_at` reads in one call (remap takes fewer than 32767 columns).
_ROW_POINTS = 32766


def _read_at(gray: np.ndarray, maps: np.ndarray, interpolation: int) -> np.ndarray:
    """``cv2.remap`` of ``gray`` at the points of ``maps`` (R, C, 2) float32 (the border replicated), (R, C).

    The points are read as one row, :data:`_ROW_POINTS` at a time: remap shares its rows among OpenCV's threads,
    and for the few thousand samples of a picture's profiles the threads' start and wait cost as much CPU as the
    reading (twice its CPU time for the same wall time on 2 cores; a 100-marker picture's profiles read in a
    row take half a millisecond, a tenth of its detection's wall time). The same values either way."""
    shape = maps.shape[:2]
    flat = maps.reshape(1, -1, 2)
    # a two-channel map1 needs no map2, which OpenCV's type stubs do not allow for
    parts = [
        cv2.remap(gray, flat[:, k : k + _ROW_POINTS], None, interpolation, borderMode=cv2.BORDER_REPLICATE)  # type: ignore[call-overload]
        for k in range(0, flat.shape[1], _ROW_POINTS)
    ]
    return (parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)).reshape(shape)


def _levels_across(prof: np.ndarray, inverted: bool | None, gamma: float):
    """:func:`_levels` of profiles sample by sample, (S, M, 4, N) uint8: the same levels, each the least or most
    sample over the first axis. ``prof`` comes back as it came for markers with a dark border (``inverted``
    False: the gray levels are the polarity's), else float32 times each side's polarity."""
    n_samples, n_lines = prof.shape[0], prof.shape[3]
    half, mid_sample = n_lines // 2, n_samples // 2
    pin, pout = prof[: mid_sample + 1], prof[mid_sample:]
    f32 = np.float32
    if inverted is None:  # which way round is the contrast larger?
        imin, imax = pin.min(0).astype(f32), pin.max(0).astype(f32)
        omin, omax = pout.min(0).astype(f32), pout.max(0).astype(f32)
        normal = ((omax - imin) >= (imax - omin)).mean(-1) >= 0.5  # (M, 4): dark inside
        dark = _kth(np.where(normal[..., None], imin, -imax), half)  # levels x polarity
        light = _kth(np.where(normal[..., None], omax, -omin), half)
        prof = prof.astype(f32) * np.where(normal, 1.0, -1.0).astype(f32)[..., None]
    elif inverted:
        dark = _kth(-pin.max(0).astype(f32), half)
        light = _kth(-pout.min(0).astype(f32), half)
        prof = -prof.astype(f32)
    else:
        dark = _kth(pin.min(0).astype(f32), half)
        light = _kth(pout.max(0).astype(f32), half)
    return prof, dark, light, _edge_level(dark, light, gamma)


def _edge_offsets_across(prof, level, dark, light, h, shift: float, min_contrast: float):
    """:func:`_edge_offsets` of profiles sample by sample, (S, M, 4, N): the same first crossing of each
    profile's level, found by running along the samples for all profiles at once, and the same arithmetic on
    its two samples."""
    n_samples = prof.shape[0]
    M, _, n_lines = prof.shape[1:]
    flat = prof.reshape(n_samples, -1)
    lev = np.repeat(level.ravel(), n_lines)  # (M 4 N,) each profile's level
    # The edge: the first sample at or above the mid level, k, and the one before it (outward from
    # there the profile may fall again where a narrow quiet zone meets a darker wall). For floats,
    # a - b >= 0 exactly when a >= b: no difference is formed where it is not needed.
    k = np.maximum(np.argmax(flat >= lev, axis=0), 1)
    at = k * flat.shape[1] + np.arange(flat.shape[1])  # sample k of each profile, in the flat array
    z0 = flat.ravel()[at - flat.shape[1]] - lev
    z1 = flat.ravel()[at] - lev
    return _crossing_offsets(k, z0, z1, (M, 4, n_lines), n_samples, h, shift, light - dark > min_contrast)


def _levels(prof: np.ndarray, inverted: bool | None, gamma: float):
    """Each side's dark and light level and the edge level between them (x polarity: dark inside)."""
    n_lines, n_samples = prof.shape[2], prof.shape[3]
    half, mid_sample = n_lines // 2, n_samples // 2
    # Levels: the darkest sample of the inner half and the brightest of the outer half (a narrow
    # quiet zone with a darker wall beyond still gives the paper's level), median over each side.
    pin, pout = prof[..., : mid_sample + 1], prof[..., mid_sample:]
    if inverted is None:  # which way round is the contrast larger?
        imin, imax, omin, omax = _least(pin), _most(pin), _least(pout), _most(pout)
        normal = ((omax - imin) >= (imax - omin)).mean(-1) >= 0.5  # (M, 4): dark inside
        dark = _kth(np.where(normal[..., None], imin, -imax), half)  # levels x polarity
        light = _kth(np.where(normal[..., None], omax, -omin), half)
        prof = prof * np.where(normal, 1.0, -1.0).astype(np.float32)[..., None, None]
    elif inverted:
        dark = _kth(-_most(pin), half)
        light = _kth(-_least(pout), half)
        prof = -prof
    else:
        dark = _kth(_least(pin), half)
        light = _kth(_most(pout), half)
    return prof, dark, light, _edge_level(dark, light, gamma)


def _edge_level(dark: np.ndarray, light: np.ndarray, gamma: float) -> np.ndarray:
    """The edge level between each side's dark and light levels (x polarity): half-way in gray level, or with
    ``gamma`` other than 1 half-way in light (levels are polarity x gray, ``|.|`` the gray)."""
    if gamma == 1.0:
        return 0.5 * (dark + light)
    g = float(gamma)
    lin = 0.5 * ((np.abs(dark) / 255.0) ** g + (np.abs(light) / 255.0) ** g)
    return np.where(light < 0, -255.0, 255.0) * lin ** (1.0 / g)


def _least(a: np.ndarray) -> np.ndarray:
    """``a.min(-1)``, the same values, as one reduction over the few samples of the last axis (numpy's reduction
    along a short last axis is several times slower)."""
    return np.minimum.reduce([a[..., k] for k in range(a.shape[-1])])


def _most(a: np.ndarray) -> np.ndarray:
    """``a.max(-1)``, as :func:`_least` computes the minimum."""
    return np.maximum.reduce([a[..., k] for k in range(a.shape[-1])])


def _kth(a: np.ndarray, k: int) -> np.ndarray:
    """The k-th smallest value (0-based) along axis 2: ``np.sort(a, axis=2)[..., k]``, without the full sort."""
    return np.partition(a, k, axis=2)[..., k]


def _edge_offsets(prof, level, dark, light, h, shift: float, min_contrast: float):
    """Each profile's edge position outside the quad's side (px, (M, 4, N)) and its weight (0 or 1)."""
    M, _, n_lines, n_samples = prof.shape
    rows = np.arange(M * 4 * n_lines)
    zf = (prof - level[..., None, None]).reshape(-1, n_samples)  # < 0 inside the edge
    # The edge: the first sample at or above the mid level, k, and the one before it (outward from
    # there the profile may fall again where a narrow quiet zone meets a darker wall).
    k = np.maximum(np.argmax(zf >= 0, axis=-1), 1)
    z0, z1 = zf[rows, k - 1], zf[rows, k]
    return _crossing_offsets(k, z0, z1, (M, 4, n_lines), n_samples, h, shift, light - dark > min_contrast)


def _crossing_offsets(k, z0, z1, shape: tuple, n_samples: int, h, shift: float, contrast_ok):
    """Edge positions outside the quads' sides (px, ``shape`` (M, 4, N)) and weights (0 or 1) from each profile's
    first sample at or above its level, ``k``, and the profile less the level there (``z1``) and one sample before
    (``z0``): the crossing interpolated between them, where they straddle the level and the side's contrast is
    enough (``contrast_ok`` (M, 4))."""
    dz = z0 - z1
    found = (z0 <= 0) & (dz < 0)
    pos = k + z0 / np.where(found, dz, -1.0)  # in samples, + 1
    off = (pos.reshape(shape[0], -1) - (n_samples // 2 + 1)) * (h * (2.0 / (n_samples - 1)))[:, None] + shift
    w = (found.reshape(shape) & contrast_ok[..., None]).astype(np.float64)
    return off.reshape(shape), w


def _fit_lines(w, off, u, U3):
    """Weighted least squares off = alpha + beta u (u: the fixed 0..1 grid of profiles), twice:
    the second time without the profiles 0.75 px off the first line."""
    for final in (False, True):
        s3 = w @ U3  # (M, 4, 3): sums of w, w u, w u^2
        s2 = (w * off) @ U3[:, :2]  # sums of w off, w u off
        sw, su, suu = s3[..., 0], s3[..., 1], s3[..., 2]
        det = np.maximum(sw * suu - su * su, 1e-12)
        alpha = (suu * s2[..., 0] - su * s2[..., 1]) / det
        beta = (sw * s2[..., 1] - su * s2[..., 0]) / det
        if not final:
            w = w * (np.abs(off - alpha[..., None] - beta[..., None] * u) < 0.75)
    return alpha, beta, sw, det


def _move_limit(cell: np.ndarray, h: np.ndarray, shift: float) -> np.ndarray:
    """How far (px, (M,)) a marker's corners may move in one pass of the edge fit: ``max(3, cell / 2)``, or where
    that is shorter, as far as the profiles find edges along both of a corner's sides, ``sqrt(2) (h + shift)``
    (each profile reaches ``h`` px either side of its centre, ``shift`` px outside the side).

    The profiles' reach is the bound: a fit that moves a corner farther has extrapolated its lines, not found the
    edges. ``max(3, cell / 2)`` alone is shorter than that reach for markers of about 3 to 15 px a cell and dropped
    good markers whose unrefined corners are that far off: the 36h11 tags of Kalibr's AprilGrid
    (``data/real/tumvi_aprilgrid``; a 2-bit border, 3.1-5.5 px a cell), whose corners touch the grid's small
    squares, come out of OpenCV up to 3.5 px off, 0.7-0.9 of the reach (``tests/test_real_aprilgrid.py``)."""
    return np.maximum(np.maximum(3.0, 0.5 * cell), np.sqrt(2.0) * (h + shift))


def _fit_far_again(gray, C, out, fitted, far, cells, inverted, n_lines, n_samples, gamma) -> None:
    """The markers ``far`` whose corners the last pass moved ``max(3, cell / 2)`` px or more, fitted once more from
    the corners it found (``out`` and ``fitted`` updated in place; ``C`` the input corners).

    Edges that far out lie near the ends of the profiles, which then reach too little of the surround for its
    level: the corners come out biased (0.3-1.1 px at 2.9-3.6 px moves on a hand-drawn 40 px marker of 10 cells),
    and a second pass, its profiles centred on the edges found, puts them within 0.1 px
    (``tests/test_edge_reach.py``). A marker that pass does not fit is not fitted, and keeps ``C``."""
    again, ok = _refine_edges(gray, out[far], cells, inverted, n_lines, n_samples, 1, 0.0, gamma, refit=False)
    out[far] = np.where(ok[:, None, None], again, C[far])
    fitted[far] = ok
