"""The "edges" corner refinement on a fisheye picture: the bias of fitting straight lines to curved sides, removed.

The "edges" refinement (:mod:`fidlearn.refinement`) fits a straight line to each side of a marker and intersects
them. A fisheye bends a marker's straight sides into curves, so the lines are chords of the curves and their
intersections miss the true corners (a quarter of a pixel and more on a 160-degree lens, enough to shift a pose by
a millimetre at half a metre where a pinhole's corners leave a tenth of that). The bias is a matter of geometry: the
marker's corners, undistorted, give its straight sides; the lens bends them; lines fitted to the bent sides where the
refinement samples them meet at the biased corners. Their difference from the bent sides' true corners is the bias,
subtracted from each detected corner.
"""

from __future__ import annotations

import cv2
import numpy as np

from ._lens import fisheye_rays, pixels_from_normalized, project_points
from .camera import Camera
from .refinement import (
    _CHECK_CONTRAST,
    _FIT_CONTRAST,
    _NEXT,
    _PREV,
    _edge_offsets,
    _levels,
    _profile_grid,
    _read_at,
)

#: Points sampled along each side, as the refinement samples it (``refinement._refine_edges``' ``n_lines``).
N_SAMPLES = 16
#: Profiles across each side in :func:`refine_edges_fisheye`.
PROFILES_PER_SIDE = 16


def straighten_edges_fisheye(corners: np.ndarray, camera: Camera, cells: int) -> np.ndarray:
    """Corners (M, 4, 2) refined by "edges" on a fisheye picture, without the bias of their straight-line fits.

    Parameters
    ----------
    corners : ndarray, shape (M, 4, 2)
        Each marker's corners, pixels, TL, TR, BR, BL, as the "edges" refinement placed them.
    camera : Camera
        The fisheye camera of the picture (a pinhole camera's corners are returned as they are).
    cells : int
        The marker's side in cells, its border included (e.g. 7 for ARUCO_ORIGINAL): where along each side the
        refinement samples it.

    Returns
    -------
    ndarray, shape (M, 4, 2)
        The corners less each one's bias; a marker with a corner 90 degrees or more off the axis is left as it is.
    """
    c = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    if camera.model != "fisheye" or len(c) == 0:
        return c.copy()
    q = camera.undistort_points(c.reshape(-1, 2)).reshape(-1, 4, 2)  # the ideal (straight-sided) corners
    ok = np.isfinite(q).all(axis=(1, 2))
    q = np.where(ok[:, None, None], q, 0.0)
    side = np.roll(c, -1, axis=1) - c
    L = np.maximum(np.linalg.norm(side, axis=2), 1e-9)  # (M, 4) sides, px
    cell = L.sum(axis=1) / (4 * cells)
    margin = np.minimum((0.5 * cell[:, None] + 1.5) / L, 0.3)  # the refinement keeps clear of the corners
    u = np.linspace(0.0, 1.0, N_SAMPLES)
    t = margin[..., None] + (1 - 2 * margin)[..., None] * u  # (M, 4, S)
    q_next = np.roll(q, -1, axis=1)
    ideal = q[:, :, None, :] + t[..., None] * (q_next - q)[:, :, None, :]  # (M, 4, S, 2)
    bent = _pixels(camera, ideal.reshape(-1, 2)).reshape(ideal.shape)
    centre = bent.mean(axis=2)  # (M, 4, 2): each fitted line's point ...
    d = bent - centre[:, :, None, :]
    sxx, syy, sxy = (d[..., 0] ** 2).sum(-1), (d[..., 1] ** 2).sum(-1), (d[..., 0] * d[..., 1]).sum(-1)
    ang = 0.5 * np.arctan2(2 * sxy, sxx - syy)
    direction = np.stack([np.cos(ang), np.sin(ang)], axis=-1)  # ... and direction (total least squares)
    biased = _intersect(np.roll(centre, 1, axis=1), np.roll(direction, 1, axis=1), centre, direction)
    true = _pixels(camera, q.reshape(-1, 2)).reshape(q.shape)
    fixed = c - (biased - true)
    good = ok & np.isfinite(fixed).all(axis=(1, 2)) & (np.abs(biased - true).max(axis=(1, 2)) < 0.5 * cell + 1.0)
    return np.where(good[:, None, None], fixed, c)


def _pixels(camera: Camera, ideal_px: np.ndarray) -> np.ndarray:
    """The fisheye's pixels (N, 2) of ideal pinhole pixels (N, 2) (the inverse of ``Camera.undistort_points``)."""
    K = camera.K
    y = (ideal_px[:, 1] - K[1, 2]) / K[1, 1]
    x = (ideal_px[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return pixels_from_normalized(np.stack([x, y], axis=1), K, camera.dist, "fisheye")


def _intersect(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Where the lines ``p1 + s d1`` and ``p2 + t d2`` (arrays (..., 2)) meet (NaN where they are parallel)."""
    den = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
    w = p2 - p1
    s = (w[..., 0] * d2[..., 1] - w[..., 1] * d2[..., 0]) / np.where(np.abs(den) > 1e-12, den, np.nan)
    return p1 + s[..., None] * d1


def refine_edges_fisheye(gray: np.ndarray, corners: np.ndarray, camera: Camera, cells: int) -> np.ndarray:
    """Corners (M, 4, 2) of markers on a fisheye picture, their sides fitted as the lens bends them.

    Each side is a straight line in the world, so its rays lie in one plane through the camera: profiles are
    sampled across the side's curve in the picture (where the lens bends the line between the input corners),
    each profile's edge crossing (but those 0.75 px off the side's median) is taken back to its ray through the
    lens's exact inverse, a plane is fitted to each side's rays and each corner is the ray where its two sides'
    planes meet, projected through the lens. The edge level is half-way between the marker's darkest border and
    its lightest surround over all four sides: a lens that squeezes a marker along the radius leaves its white
    margin there too narrow for the profile to reach the paper's level, which put those edges inside the
    marker (0.1 px on a 160-degree lens at 2 px per cell, the pose's largest error). The profiles are read with
    bicubic interpolation: bilinear's error depends on where the edge falls between pixel centres, and along a
    side that runs with the pixel rows that error does not average out; the corners of markers of 13 to 22 px
    came out 25 to 40 % closer to the truth, and their outlines no longer 0.02 to 0.05 px inside
    (``python benchmarks/bench_planning.py --noise --fisheye``).

    Parameters
    ----------
    gray : ndarray (H, W) uint8
        The fisheye picture.
    corners : ndarray, shape (M, 4, 2)
        Each marker's corners, pixels, TL, TR, BR, BL (e.g. from the "edges" refinement).
    camera : Camera
        The fisheye camera of the picture.
    cells : int
        The marker's side in cells, its border included (e.g. 7 for ARUCO_ORIGINAL).

    Returns
    -------
    ndarray, shape (M, 4, 2)
        The refined corners; a marker whose sides cannot all be fitted (too little contrast, too few crossings,
        a corner 90 degrees or more off the axis, a move of more than ``max(3, cell / 2)`` px) keeps the corners
        :func:`straighten_edges_fisheye` gives it.
    """
    C = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    if camera.model != "fisheye" or len(C) == 0:
        return C.copy()
    u, v, _ = _profile_grid(PROFILES_PER_SIDE, 13)
    Z = C[..., 0] + 1j * C[..., 1]
    L = np.maximum(np.abs(Z[:, _NEXT] - Z), 1e-9)
    cell = L.sum(1) * (0.25 / cells)
    h = np.minimum(np.maximum(0.6 * cell, 1.5), 5.0)
    margin = np.minimum((0.5 * cell[:, None] + 1.5) / L, 0.3)
    t = margin[..., None] + (1 - 2 * margin)[..., None] * u  # (M, 4, N) along each side
    with np.errstate(invalid="ignore", divide="ignore"):
        r = _rays(C, camera)
        P, nz = _side_curves(C, r, camera, t)
        ok = (np.isfinite(P) & np.isfinite(nz)).all(axis=(1, 2))  # every profile's samples finite
        prof = _read_at(gray, _sample_map(P, nz, h, v, ok), cv2.INTER_CUBIC)
        prof = prof.reshape(len(C), 4, len(u), len(v)).astype(np.float32)
        prof, dark, light, _ = _levels(prof, False, 1.0)
        dark = np.broadcast_to(dark.min(axis=1, keepdims=True), dark.shape)  # the marker's own levels
        light = np.broadcast_to(light.max(axis=1, keepdims=True), light.shape)
        off, w = _edge_offsets(prof, 0.5 * (dark + light), dark, light, h, 0.0, _CHECK_CONTRAST)
        # the profiles are centred on the input corners' bent sides: a crossing 0.75 px off the side's median is
        # another edge
        w = w * (np.abs(off - _median_of(off, w > 0)) < 0.75)  # a side with no crossing has no weight
        new, fitted = _fit_planes(P + off * nz, w, camera, r)
    ok &= fitted & (np.abs(new - C).max(axis=(1, 2)) < np.maximum(3.0, 0.5 * cell))
    ok &= (light - dark > _FIT_CONTRAST).all(axis=1)
    out = np.where(ok[:, None, None], new, C)
    if not ok.all():
        out[~ok] = straighten_edges_fisheye(C[~ok], camera, cells)
    return out


def _sample_map(P: np.ndarray, nz: np.ndarray, h: np.ndarray, v: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """``cv2.remap``'s map (M * 4, N * S, 2) float32 of the samples ``P + h v nz`` across each side (``P``, ``nz``
    (M, 4, N) complex, ``h`` (M,), ``v`` (S,)): x and y each in one product and sum, in double precision, then
    single (the values of the complex sum). A marker not ``ok`` (a point or normal not finite) is read far
    outside the picture (its profiles are not used)."""
    M, _, N = P.shape
    hv = (h[:, None] * v)[:, None, None, :]  # (M, 1, 1, S)
    out = np.empty((M, 4, N, len(v), 2), np.float32)
    np.add(P.real[..., None], hv * nz.real[..., None], out=out[..., 0], casting="same_kind")
    np.add(P.imag[..., None], hv * nz.imag[..., None], out=out[..., 1], casting="same_kind")
    if not ok.all():
        out[~ok] = -10.0
    return out.reshape(M * 4, N * len(v), 2)


def _median_of(x: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The median (M, 4, 1) of each side's valid values along the last axis (NaN for a side with none), as
    ``np.nanmedian`` gives it, by one sort."""
    n = valid.sum(axis=-1, keepdims=True)
    ordered = np.sort(np.where(valid, x, np.inf), axis=-1)
    lo = np.take_along_axis(ordered, np.maximum(n - 1, 0) // 2, axis=-1)
    hi = np.take_along_axis(ordered, np.minimum(n // 2, x.shape[-1] - 1), axis=-1)
    return np.where(n > 0, 0.5 * (lo + hi), np.nan)


def _rays(px: np.ndarray, camera: Camera) -> np.ndarray:
    """Unit rays (..., 3) of fisheye pixels (..., 2) (NaN where no ray reaches)."""
    return fisheye_rays(px.reshape(-1, 2), camera.K, camera.dist).reshape(px.shape[:-1] + (3,))


def _to_pixels(rays: np.ndarray, camera: Camera) -> np.ndarray:
    """Fisheye pixels (..., 2) of rays (..., 3) in front of the camera."""
    return project_points(rays.reshape(-1, 3), camera.K, camera.dist, "fisheye").reshape(rays.shape[:-1] + (2,))


def _side_curves(C: np.ndarray, r: np.ndarray, camera: Camera, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (M, 4, N) on each side's bent line at ``t`` and the outward unit normals there (complex x + iy);
    ``r`` (M, 4, 3): the corners' rays."""
    r_next = r[:, _NEXT]

    q = _to_pixels(r[:, :, None, :] * (1 - t)[..., None] + r_next[:, :, None, :] * t[..., None], camera)
    P = np.ascontiguousarray(q).view(np.complex128)[..., 0]  # x + iy, the same values, without a copy
    # the profiles are evenly spaced along the side: central differences, one-sided at the ends (np.gradient's,
    # less its factor 1/2 inside, which the unit normal does not see)
    tangent = np.empty_like(P)
    np.subtract(P[..., 2:], P[..., :-2], out=tangent[..., 1:-1])
    np.subtract(P[..., 1:2], P[..., :1], out=tangent[..., :1])
    np.subtract(P[..., -1:], P[..., -2:-1], out=tangent[..., -1:])
    Z = C[..., 0] + 1j * C[..., 1]
    Dz = Z[:, _NEXT] - Z
    # outward: -i times the direction when the corners turn clockwise on screen, as OpenCV reports them
    turn = np.where((Dz[:, 0].conj() * Dz[:, 1]).imag >= 0, -1j, 1j)
    return P, tangent / np.abs(tangent) * turn[:, None, None]


def _fit_planes(E: np.ndarray, w: np.ndarray, camera: Camera, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corners (M, 4, 2) where planes fitted to each side's edge rays meet, and whether all four sides fitted;
    ``r`` (M, 4, 3): the input corners' rays (which side of the camera each corner is)."""
    rays = _rays(np.ascontiguousarray(E)[..., None].view(np.float64), camera)  # (M, 4, N, 3)
    finite = np.isfinite(rays)
    if not finite.all():  # no ray reaches a crossing (or none was found): it has no weight
        w = np.where(finite.all(-1), w, 0.0)
        rays = np.where(finite, rays, 0.0)
    # (M, 4, 3): the plane through the camera that the side's rays lie in
    normal = _least_eigenvector((rays * w[..., None]).swapaxes(-1, -2) @ rays, _cross(r, r[:, _NEXT]))
    X = _cross(normal[:, _PREV], normal)  # corner k: sides k - 1 and k
    X = X * np.sign(np.einsum("mki,mki->mk", X, r))[..., None]
    new = _to_pixels(X, camera)
    return new, (w.sum(-1) >= 4).all(1) & np.isfinite(new).all(axis=(1, 2)) & (X[..., 2] > 0).all(1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross(a, b)`` of vectors (..., 3), the same values, in six products (np.cross's axis handling costs
    more than the arithmetic on a few hundred vectors)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


#: Inverse iterations of :func:`_least_eigenvector`.
EIGEN_STEPS = 4


def _least_eigenvector(A: np.ndarray, start: np.ndarray) -> np.ndarray:
    """The unit eigenvector (..., 3) of the smallest eigenvalue of symmetric 3 x 3 matrices ``A`` (..., 3, 3), by
    inverse iteration from ``start`` (..., 3), each step one product with the adjugate (``det(A) A^-1``: no
    division, defined where ``A`` is singular, which an exact plane's rays make it).

    Each step shrinks the parts along the other eigenvectors by the ratio of the smallest eigenvalue to theirs;
    a side's rays lie in a plane to within the edges' noise, far less than their spread along the side, and the
    plane through its two corner rays starts within a few degrees of theirs: four steps meet
    ``np.linalg.eigh``'s vector to rounding (up to sign), in a third of its time on a few hundred matrices. NaN
    where ``A`` has rank 1 or less (no plane: a side with no weight).
    """
    a, b, c = A[..., 0, 0], A[..., 1, 1], A[..., 2, 2]
    d, e, f = A[..., 0, 1], A[..., 1, 2], A[..., 0, 2]
    adj = np.empty(A.shape)
    adj[..., 0, 0] = b * c - e * e
    adj[..., 1, 1] = a * c - f * f
    adj[..., 2, 2] = a * b - d * d
    adj[..., 0, 1] = adj[..., 1, 0] = f * e - d * c
    adj[..., 1, 2] = adj[..., 2, 1] = d * f - a * e
    adj[..., 0, 2] = adj[..., 2, 0] = d * e - b * f
    v = start[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):  # 0 / 0 where there is no plane
        for _ in range(EIGEN_STEPS):
            v = adj @ v
            v = v / np.sqrt((v * v).sum(axis=-2, keepdims=True))
    return v[..., 0]
