"""A marker's corners as the ``edges`` refinement makes them: where the lines of neighbouring sides meet.

Each side's line moves along its normal at its two ends (its offset and its slope); a corner moves as its two
sides' lines do. :func:`line_end_matrix` maps the corners' pixel motion to those eight line-end motions, so its
inverse takes a model of the lines' errors back to the corners (:func:`fidlearn.planning.noise.corner_covariance`,
:func:`edge_offset_covariance`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["line_end_matrix", "edge_offset_covariance", "edge_offset_motion", "offset_covariance"]


def line_end_matrix(q: np.ndarray) -> np.ndarray:
    """(8, 8) map from the corners' motion ``[x0, y0, ..., x3, y3]`` to each side's line motion along its normal.

    Rows ``2 k`` and ``2 k + 1`` are side ``k``'s line (corner ``k`` to corner ``k + 1``) at its start and at its
    end; every normal is on the same hand of the way round (inward for corners in the detector's order in a
    picture whose y axis points down).
    """
    side = np.roll(q, -1, axis=0) - q  # side k from corner k to corner k + 1
    normal = np.column_stack([-side[:, 1], side[:, 0]]) / np.linalg.norm(side, axis=1)[:, None]
    M = np.zeros((8, 8))
    for k in range(4):
        j = (k + 1) % 4
        M[2 * k, 2 * k : 2 * k + 2] = normal[k]
        M[2 * k + 1, 2 * j : 2 * j + 2] = normal[k]
    return M


def edge_offset_motion(q: np.ndarray) -> np.ndarray | None:
    """(8,) motion of the corners when every side's line moves 1 px outward (the marker's outline grown by a
    pixel all round); None for a degenerate quad."""
    try:
        return np.linalg.solve(line_end_matrix(q), -np.ones(8))
    except np.linalg.LinAlgError:
        return None


def edge_offset_covariance(corners_px: np.ndarray, offset_px: float) -> np.ndarray:
    """Covariance (8, 8) of a marker's corners when its four sides move out (or in) together by ``offset_px``
    (standard deviation, px): the edge found at levels a little off the marker's own dark and light.

    Zero for a degenerate quad. ``corners_px`` (4, 2) in the detector's order.

    >>> C = edge_offset_covariance(np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]), 0.1)
    >>> np.round(C[0, :4] / 0.1**2, 2).tolist()  # the top-left corner moves up-left, the top-right up-right
    [1.0, 1.0, -1.0, 1.0]
    """
    return offset_covariance(edge_offset_motion(np.asarray(corners_px, dtype=float)), offset_px)


def offset_covariance(motion: np.ndarray | None, offset_px: float) -> np.ndarray:
    """:func:`edge_offset_covariance` from the outline's motion (:func:`edge_offset_motion`) already found."""
    return np.zeros((8, 8)) if motion is None else float(offset_px) ** 2 * np.outer(motion, motion)
