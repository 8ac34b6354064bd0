"""How trustworthy a calibration's set of views is: coverage of the picture, variety of the board poses.

A calibration can reach a small RMS and still be wrong where nothing was measured: with too
few views, with views that all show the board face-on (the focal length and the distance
cannot be told apart), or with parts of the picture where the board never was (the lens
distortion there is extrapolated). :func:`quality_warnings` says so in sentences;
:class:`~fidlearn.calibration.Calibration` carries them as ``.warnings`` and
``fidlearn calibrate`` prints them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import frames

__all__ = [
    "coverage_grid",
    "view_diversity",
    "ViewDiversity",
    "DuplicateViews",
    "quality_warnings",
    "few_views_warning",
    "MIN_GOOD_VIEWS",
    "SPARSE_CELL_SHARE",
    "MIN_TILT_SPREAD_DEG",
    "DUPLICATE_DEG",
    "DUPLICATE_FRACTION",
]

#: Fewer used views than this earns a warning: OpenCV's advice is 10 to 20 varied views.
MIN_GOOD_VIEWS = 10
#: A ninth of the picture with fewer corners than this share of an even spread (but some) earns a warning.
SPARSE_CELL_SHARE = 0.1
#: A calibration whose board normals all lie within this angle (deg) of each other is too flat a set.
MIN_TILT_SPREAD_DEG = 10.0
#: Two views closer than this (deg and fraction of the distance) are near duplicates.
DUPLICATE_DEG, DUPLICATE_FRACTION = 2.0, 0.02
_CELL_NAMES = (("top-left", "top", "top-right"), ("left", "centre", "right"), ("bottom-left", "bottom", "bottom-right"))


def coverage_grid(points_px: Iterable, image_size: tuple[int, int], grid: tuple[int, int] = (3, 3)) -> np.ndarray:
    """Board points counted per cell of a grid over the image.

    Parameters
    ----------
    points_px : iterable of array-like, shape (N, 2)
        One array of pixels per view (pixel centres at integers, so the image spans
        -0.5 .. width - 0.5).
    image_size : (int, int)
        The image's width and height, pixels.
    grid : (int, int)
        Columns and rows of the grid (default 3x3: the ninths of the picture).

    Returns
    -------
    ndarray, shape (rows, cols), int
        Points per cell, row 0 at the top, column 0 at the left.

    Examples
    --------
    >>> coverage_grid([[[0, 0], [639, 479]], [[320, 240]]], (640, 480))
    array([[1, 0, 0],
           [0, 1, 0],
           [0, 0, 1]])
    >>> coverage_grid([[[0, 0], [639, 479]]], (640, 480), grid=(2, 1))
    array([[1, 1]])
    """
    w, h = image_size
    cols, rows = grid
    arrays = [np.asarray(pts, dtype=float).reshape(-1, 2) for pts in points_px]
    pts = np.concatenate(arrays) if arrays else np.zeros((0, 2))
    c = np.clip(((pts[:, 0] + 0.5) * cols // w).astype(int), 0, cols - 1)
    r = np.clip(((pts[:, 1] + 0.5) * rows // h).astype(int), 0, rows - 1)
    return np.bincount(r * cols + c, minlength=rows * cols).reshape(rows, cols)


@dataclass(frozen=True)
class DuplicateViews:
    """Two views whose board poses are nearly the same (see :func:`view_diversity`).

    Attributes
    ----------
    a, b : str
        The two views' names, in the order they were given.
    angle_deg : float
        The rotation between the two board poses, degrees (below ``DUPLICATE_DEG``).
    moved_fraction : float
        How far the board moved between them, as a fraction of its distance in ``a`` (below
        ``DUPLICATE_FRACTION``).
    """

    a: str
    b: str
    angle_deg: float
    moved_fraction: float


@dataclass(frozen=True)
class ViewDiversity:
    """How different a calibration's board poses are (what :func:`view_diversity` returns).

    Attributes
    ----------
    spread_deg : float
        The largest angle (deg) between the board's normals over all pairs of views (0 for one view).
    duplicates : list of DuplicateViews
        The near-duplicate pairs: views whose board turned less than ``DUPLICATE_DEG`` and moved
        less than ``DUPLICATE_FRACTION`` of its distance.
    """

    spread_deg: float
    duplicates: list[DuplicateViews] = field(default_factory=list)


def view_diversity(T_camera_board: Mapping) -> ViewDiversity:
    """How different the board poses are.

    Parameters
    ----------
    T_camera_board : mapping of str to array-like, shape (4, 4)
        Each view's board pose in the camera frame (mm).

    Returns
    -------
    ViewDiversity
        ``spread_deg``, the largest angle between the board's normals, and ``duplicates``, the
        pairs of nearly identical views.

    Examples
    --------
    >>> import fidlearn
    >>> T = fidlearn.make_transform(np.eye(3), [0, 0, 500])
    >>> T2 = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(30, 0, 0), [0, 0, 500])
    >>> diversity = view_diversity({"a": T, "b": T, "c": T2})
    >>> round(diversity.spread_deg, 6), [(d.a, d.b) for d in diversity.duplicates]
    (30.0, [('a', 'b')])
    """
    names = list(T_camera_board)
    if len(names) < 2:
        return ViewDiversity(0.0, [])
    R, t = _rotations_and_translations(T_camera_board, names)
    i, j = np.triu_indices(len(names), k=1)  # every pair, in the order (0, 1), (0, 2), ..., (1, 2), ...
    normals = R[:, :, 2]
    cos = np.clip(np.abs(np.sum(normals[i] * normals[j], axis=1)), -1.0, 1.0)
    spread = float(np.degrees(np.arccos(cos)).max())
    # the angle of R_i^T R_j from its trace, the sum of the element-wise products
    trace = np.sum(R[i] * R[j], axis=(1, 2))
    angle = np.degrees(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0)))
    moved = np.linalg.norm(t[i] - t[j], axis=1) / np.maximum(np.linalg.norm(t[i], axis=1), 1e-9)
    close = np.flatnonzero((angle < DUPLICATE_DEG) & (moved < DUPLICATE_FRACTION))
    duplicates = [DuplicateViews(names[i[k]], names[j[k]], float(angle[k]), float(moved[k])) for k in close]
    return ViewDiversity(spread, duplicates)


def _rotations_and_translations(T_camera_board: Mapping, names: list) -> tuple[np.ndarray, np.ndarray]:
    """The views' rotations (n, 3, 3), checked at once (TransformError if one is not a rotation), translations."""
    T = [np.asarray(T_camera_board[n], dtype=float) for n in names]
    R = np.array([M[:3, :3] for M in T])
    t = np.array([M[:3, 3] for M in T])
    ok = np.isfinite(R).all(axis=(1, 2))
    ok[ok] &= np.abs(np.transpose(R[ok], (0, 2, 1)) @ R[ok] - np.eye(3)).max(axis=(1, 2)) <= 1e-6
    ok[ok] &= np.linalg.det(R[ok]) > 0
    for k in np.flatnonzero(~ok):  # the one check that says what is wrong
        frames.check_rotation(R[k], names[k])
    return R, t


def _coverage_warnings(grid: np.ndarray) -> list[str]:
    """Sentences about the ninths of the picture with no board point, or with few."""
    out = []
    empty = [_CELL_NAMES[r][k] for r in range(3) for k in range(3) if grid[r, k] == 0]
    even_share = grid.sum() / 9.0
    sparse = [_CELL_NAMES[r][k] for r in range(3) for k in range(3) if 0 < grid[r, k] < SPARSE_CELL_SHARE * even_share]
    if empty:
        out.append(
            f"no board corner in the {', '.join(empty)} of the picture; hold the board there too, "
            "or the lens distortion is guessed where nothing was measured"
        )
    if sparse:
        counts = ", ".join(f"{grid[r, k]}" for r in range(3) for k in range(3) if _CELL_NAMES[r][k] in sparse)
        out.append(
            f"few board corners in the {', '.join(sparse)} of the picture ({counts}, under a tenth of the "
            f"{even_share:.0f} an even spread gives); hold the board there too, or the lens distortion "
            "is guessed where almost nothing was measured"
        )
    return out


def few_views_warning(n_used: int) -> str:
    """The one sentence for a calibration from too few views (fewer than :data:`MIN_GOOD_VIEWS`).

    The calibration's ``warnings`` and the calibration coach's flags both use it, so ``fidlearn calibrate``
    gives this advice once.

    Parameters
    ----------
    n_used : int
        Views the camera was computed from.

    Returns
    -------
    str
        The warning, with its advice.

    Examples
    --------
    >>> few_views_warning(5)
    'only 5 views were used; take at least 10 (15 to 25 is usual)'
    """
    return f"only {n_used} views were used; take at least {MIN_GOOD_VIEWS} (15 to 25 is usual)"


def quality_warnings(n_used: int, T_camera_board: Mapping, grid: np.ndarray) -> list[str]:
    """What is wrong with a set of calibration views, one sentence each (empty when nothing is).

    Parameters
    ----------
    n_used : int
        Views the camera was computed from.
    T_camera_board : mapping of str to array-like, shape (4, 4)
        Each used view's board pose in the camera frame (mm).
    grid : ndarray, shape (3, 3), int
        Board points per ninth of the picture (:func:`coverage_grid`).

    Returns
    -------
    list of str
        In this order: too few views, views too alike, near-duplicate views, ninths of the
        picture with no board point, ninths with few.

    Examples
    --------
    >>> import fidlearn
    >>> T = fidlearn.make_transform(np.eye(3), [0, 0, 500])
    >>> for w in quality_warnings(1, {"a": T}, np.full((3, 3), 10)):
    ...     print(w[:40])
    only 1 views were used; take at least 10
    """
    out = []
    if n_used < MIN_GOOD_VIEWS:
        out.append(few_views_warning(n_used))
    diversity = view_diversity(T_camera_board)
    spread, duplicates = diversity.spread_deg, diversity.duplicates
    if n_used > 1 and spread < MIN_TILT_SPREAD_DEG:
        out.append(
            f"views too similar: the board faces the camera within {spread:.1f} deg in every view; "
            "tilt it 20 to 45 deg in different directions, or the focal length stays uncertain"
        )
    if duplicates:
        a, b = duplicates[0].a, duplicates[0].b
        out.append(
            f"{len(duplicates)} pair(s) of nearly identical views (e.g. {Path(a).name} and {Path(b).name}); "
            "they add no information: move or tilt the board between photos"
        )
    return out + _coverage_warnings(grid)
