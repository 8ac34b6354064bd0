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

import numpy as np

from ._lens import pixels_from_normalized
from .camera import Camera

#: Points sampled along each side, as the refinement samples it (``refinement._refine_edges``' ``n_lines``).
N_SAMPLES = 16


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
