"""What the solvers work on: the used markers' world and pixel corners (:class:`_Obs`), a candidate pose
(:class:`_Candidate`), and the map's corners and faces, cached per map."""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..markermap import MarkerMap


@dataclass
class _Obs:
    ids: list[int]
    obj: np.ndarray  # (4n, 3) world corners, mm
    img: np.ndarray  # (4n, 2) pixel corners
    _faces: np.ndarray | None = field(default=None, init=False, repr=False)

    def faces(self) -> np.ndarray:
        """Rows (n, 7): centre (mm), unit normal and normal . centre of each marker's printed face (world)."""
        if self._faces is None:
            self._faces = _faces_of(self.obj)
        return self._faces


_UNCHECKED = "unchecked"
_BOTTOM_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_YZX, _ZXY = np.array([1, 2, 0]), np.array([2, 0, 1])


@dataclass
class _Candidate:
    R_wc: np.ndarray  # (3, 3) camera orientation in the world
    C: np.ndarray  # (3,) camera centre in the world, mm
    sse: float  # sum of squared residuals, px^2
    r: np.ndarray | None  # (2N,) residuals, observed minus projected, px (None: not computed yet)
    refined: bool = False  # whether Levenberg-Marquardt ran from it
    JtJ: np.ndarray | None = None  # (6, 6) J^T J at this pose, when LM left it behind
    J: np.ndarray | None = None  # (2N, 6) the Jacobian of the residuals' projections there, likewise
    problem: str | None = _UNCHECKED  # why it cannot be the camera (None: it can); see _cheirality
    problem_short: str = ""  # the same in one sentence, to follow another message
    marker_stats: object = field(default=_UNCHECKED, repr=False)  # _outliers._marker_stats at this pose, once

    @property
    def T_world_camera(self) -> np.ndarray:
        T = np.empty((4, 4))  # (np.eye is a Python function: three times the cost)
        T[:3, :3] = self.R_wc
        T[:3, 3] = self.C
        T[3] = _BOTTOM_ROW
        return T


_NEXT = np.array([1, 2, 3, 0])


def _side_px(img: np.ndarray) -> np.ndarray:
    """Mean side length (n,), px, of each marker's four image corners (4n, 2)."""
    q = img.reshape(-1, 4, 2)
    e = q[:, _NEXT] - q
    return np.sqrt((e * e).sum(axis=2)).mean(axis=1)


_WORLD_CACHE: weakref.WeakKeyDictionary[MarkerMap, tuple] = weakref.WeakKeyDictionary()


def _faces_of(points: np.ndarray) -> np.ndarray:
    """Rows (n, 7) ``[centre (3), unit normal (3), normal . centre]`` of markers' faces from their corners (4n, 3)."""
    q = points.reshape(-1, 4, 3)
    # x from TL to TR, y from BL to TL, z = x cross y out of the printed face (MarkerMap.normal)
    a, b = q[:, 1] - q[:, 0], q[:, 0] - q[:, 3]
    n = a[:, _YZX] * b[:, _ZXY] - a[:, _ZXY] * b[:, _YZX]
    n /= np.sqrt((n * n).sum(axis=1))[:, None]
    centres = q.mean(axis=1)
    return np.column_stack([centres, n, (n * centres).sum(axis=1)])


def _world(marker_map: MarkerMap) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """``marker_map.corners()`` and each marker's face row (:func:`_faces_of`), cached per map.

    The cache holds while the map's placements and marker size stay the same.
    """
    key: tuple | None = (marker_map.marker_size_mm, tuple(marker_map.placements.values()))
    try:
        hit = _WORLD_CACHE.get(marker_map)
    except TypeError:  # an unhashable map: no cache
        hit, key = None, None
    if hit is not None and hit[0] == key:
        return hit[1], hit[2]
    corners = marker_map.corners()
    for c in corners.values():
        c.flags.writeable = False
    ids = list(corners)
    rows = _faces_of(np.concatenate([corners[i] for i in ids])) if ids else np.zeros((0, 7))
    faces = dict(zip(ids, rows))
    if key is not None:
        _WORLD_CACHE[marker_map] = (key, corners, faces)
    return corners, faces


def _make_obs(
    ids: Sequence[int],
    corners_px: dict[int, np.ndarray],
    world: dict[int, np.ndarray],
    faces: dict[int, np.ndarray] | None = None,
) -> _Obs:
    ids = list(ids)
    obs = _Obs(ids, np.concatenate([world[i] for i in ids]), np.concatenate([corners_px[i] for i in ids]))
    if faces is not None:
        obs._faces = np.array([faces[i] for i in ids])
    return obs
