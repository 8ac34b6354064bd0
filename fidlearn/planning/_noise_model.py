"""The pose's covariance and bias from every part of :func:`~fidlearn.planning.predict_accuracy`'s noise model.

First-order error propagation through ``estimate_pose``'s unweighted least squares: each marker's corner
covariance (its sides' lines, :func:`~fidlearn.planning.noise.corner_covariance`; a shift of the whole marker; a
fisheye's outline offset, :func:`~fidlearn.planning._corner_lines.edge_offset_covariance`; each marker's own size
error), the markers' common size spread, and the biases of a known common size error and of a fisheye's outlines.
"""

from __future__ import annotations

import numpy as np

from ..markermap import MarkerMap
from . import noise
from ._corner_lines import edge_offset_motion, offset_covariance

__all__ = ["covariance_and_bias"]


def _least_squares_covariance(J: np.ndarray, JtJ: np.ndarray, blocks: list) -> np.ndarray:
    """Covariance ``A J^T S J A`` (``A = (J^T J)^-1``) of an unweighted least-squares fit.

    ``J`` is (8M, 6), the rows of M markers' corners; ``blocks`` their (8, 8) corner covariances.
    """
    Jm = J.reshape(len(blocks), 8, 6)
    middle = np.einsum("mia,mij,mjb->ab", Jm, np.asarray(blocks), Jm)
    A = np.linalg.inv(JtJ)
    cov = A @ middle @ A
    return (cov + cov.T) / 2


def _size_motion(marker_map: MarkerMap, ids: list[int], J: np.ndarray, about_centre: bool = False) -> np.ndarray:
    """(M, 8) pixel motion of each marker's corners per unit of relative size, growing from its top-left
    corner (or its centre).

    ``J``'s camera-centre columns are minus the corners' pixels against their world position.
    """
    corners = [marker_map.marker_corners(i) for i in ids]
    grow = np.concatenate([c - (c.mean(axis=0) if about_centre else c[0]) for c in corners])
    u = -np.einsum("nij,nj->ni", J.reshape(-1, 2, 6)[:, :, 3:], grow)
    return u.reshape(len(ids), 8)


def covariance_and_bias(
    marker_map: MarkerMap,
    ids: list[int],
    seen: dict,
    sigmas: dict,
    J: np.ndarray,
    JtJ: np.ndarray,
    shift_px: float,
    size_rel_std: float,
    size_rel_std_each: float,
    size_rel_error: float,
    edges: dict,
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray], np.ndarray]:
    """The pose's 6x6 covariance from every part of the noise model, the camera position's bias (mm) from
    the markers' known common size error and the outlines' offset (``edges``: ``{id: (spread, bias)}`` px, a
    fisheye's), each marker's (8, 8) corner covariance and the camera position's (3, 3) covariance from the
    common size spread alone."""
    # the outline's motion when it grows by a pixel: its spread (covariance) and its bias (below)
    motion = {i: edge_offset_motion(seen[i]) for i in ids} if edges else {}
    blocks = [
        noise.corner_covariance(seen[i], sigmas[i], edges[i][2] if edges else None)
        + noise.marker_shift_covariance(shift_px)
        + (offset_covariance(motion[i], edges[i][0]) if edges else 0.0)
        for i in ids
    ]
    u = _size_motion(marker_map, ids, J) if size_rel_std or size_rel_std_each else np.zeros((len(ids), 8))
    if size_rel_std_each:
        blocks = [b + size_rel_std_each**2 * np.outer(um, um) for b, um in zip(blocks, u)]
    cov = _least_squares_covariance(J, JtJ, blocks)
    common = np.zeros((3, 3))
    if size_rel_std:
        v = np.linalg.solve(JtJ, J.T @ u.ravel())
        cov = cov + size_rel_std**2 * np.outer(v, v)
        common = size_rel_std**2 * np.outer(v[3:], v[3:])
    bias = np.zeros(3)
    if size_rel_error:
        u_centre = _size_motion(marker_map, ids, J, about_centre=True)
        bias = size_rel_error * np.linalg.solve(JtJ, J.T @ u_centre.ravel())[3:]
    if edges:
        u_edge = np.concatenate([np.zeros(8) if motion[i] is None else edges[i][1] * motion[i] for i in ids])
        bias = bias + np.linalg.solve(JtJ, J.T @ u_edge)[3:]
    return cov, bias, blocks, common
