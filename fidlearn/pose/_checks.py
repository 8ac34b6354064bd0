"""Answers no camera can give: image corners that are no marker seen from its printed side, and poses that
would see a marker from behind or have corners behind the camera."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..errors import PoseError
from ._observations import _NEXT, _UNCHECKED, _Candidate, _Obs

#: Below this area (px^2) for every triangle of three of a marker's image corners, they are on a
#: line or repeat a point. (Noisy corners of a marker seen exactly edge-on span more: in 60000
#: benchmark-like views with 0.3-2 px of noise the smallest was 0.26 px^2.)
_MIN_QUAD_AREA_PX2 = 0.01
#: A marker's corners are called mirrored or out of order only when a triangle of them (or the
#: quad) has the wrong orientation by more than this many times ``d`` px^2, ``d`` the RMS of its
#: diagonals (px): five standard deviations of that area for corners 1 px off. A marker seen
#: nearly edge-on, a few pixels wide, can fold over under corner noise; it is not judged.
_QUAD_MARGIN_PX = 5.0
#: A marker counts as seen from behind when the camera is more than this far (degrees) behind
#: its plane: a marker seen at a grazing angle may be estimated a little behind it.
_BEHIND_TOL_DEG = 10.0
_SIN_BEHIND_TOL = math.sin(math.radians(_BEHIND_TOL_DEG))
_EDGES = np.eye(4)[_NEXT] - np.eye(4)  # a marker's corners (4, 2) times this: its edges c[k+1] - c[k]
_NEXT_EDGES = _EDGES[_NEXT]  # ... the edges c[k+2] - c[k+1]
_TURN = np.array([[0.0, -1.0], [1.0, 0.0]])  # a row (x, y) times this: (y, -x)


def _check_quads(ids: Sequence[int], img: np.ndarray) -> None:
    """Raise PoseError when a marker's image corners cannot be a marker seen from its printed side.

    TL, TR, BR, BL of a marker seen from its printed side run clockwise in the image (y points
    down), as every detector reports them: a convex quad whose four corner triangles (and
    shoelace area) are positive. Refused: corners on a line or repeated (no area), corners
    anticlockwise (mirrored), and corners that fold or cross (out of order), each only when
    clearly so (``_QUAD_MARGIN_PX``), so that noisy corners of a marker seen edge-on pass.
    """
    q = img.reshape(-1, 4, 2)  # the markers' corners, TL, TR, BR, BL
    # edges e_k = c[k+1] - c[k] and the next ones turned, (y_k+1, -x_k+1), as products with constant matrices
    # (exact: differences of two corners): fewer numpy calls than gathering and subtracting
    e = _EDGES @ q
    tri = (e * (_NEXT_EDGES @ q @ _TURN)).sum(axis=2)  # (n, 4) twice the signed triangle areas
    if min(tri.ravel().tolist()) > 0:
        return  # the usual case: convex and clockwise
    nxt = q[:, _NEXT]
    tri = 0.5 * tri
    area = 0.5 * np.sum(q[..., 0] * nxt[..., 1] - nxt[..., 0] * q[..., 1], axis=1)
    d = np.sqrt(0.5 * (np.sum((q[:, 2] - q[:, 0]) ** 2, axis=1) + np.sum((q[:, 3] - q[:, 1]) ** 2, axis=1)))
    margin = _QUAD_MARGIN_PX * d
    flat = np.abs(tri).max(axis=1) < _MIN_QUAD_AREA_PX2
    mirrored = (area < -margin) & (tri.max(axis=1) < margin)
    folded = tri.min(axis=1) < -margin
    bad = flat | mirrored | folded
    if not bad.any():
        return
    k = int(np.flatnonzero(bad)[0])
    i, c = ids[k], np.round(q[k], 1).tolist()
    if flat[k]:
        raise PoseError(
            f"marker {i}: its image corners {c} enclose no area (they lie on a line or repeat a point): no "
            "detector reports such a marker and no pose follows from it; check how the corners were made"
        )
    if mirrored[k]:
        raise PoseError(
            f"marker {i}: its image corners {c} run anticlockwise on the screen, the mirror image of a marker "
            "seen from its printed side (detection reports TL, TR, BR, BL clockwise, y pointing down): are "
            "they listed TL, BL, BR, TR? corners[[0, 3, 2, 1]] puts them right. (A camera behind the marker, "
            "or a mirrored picture, gives this too.)"
        )
    raise PoseError(
        f"marker {i}: its image corners {c} do not form a convex quadrilateral (the outline crosses itself or "
        "folds in): they are not in the order TL, TR, BR, BL around the marker"
    )


def _cheirality(obs: _Obs, c: _Candidate) -> str | None:
    """None when a candidate sees every marker from its printed side and every corner in front of it.

    Otherwise a message saying which markers break it and what is likely wrong. A mirror image
    of the markers (camera behind them, or behind the camera) can fit the corners perfectly:
    a pose is only one that a camera can have when both hold.
    """
    if c.problem is not _UNCHECKED:
        return c.problem
    f = obs.faces()
    height = f[:, 3:6] @ c.C - f[:, 6]  # the camera's height above each marker's plane: > 0 on the printed side
    z = c.R_wc[:, 2]  # the camera's optical axis in the world
    depth = (obs.obj - c.C) @ z  # > 0: in front of the camera
    if min(height.tolist()) > 0 and min(depth.tolist()) > 0:  # (builtin min: cheaper on a few values)
        c.problem = None
        return None
    # a grazing view may come out a little behind: allowed up to _BEHIND_TOL_DEG of elevation
    to_camera = c.C - f[:, :3]
    seen = (height > 0) | (height * height < _SIN_BEHIND_TOL**2 * (to_camera * to_camera).sum(axis=1))
    if seen.all() and depth.min() > 0:
        c.problem = None
        return None
    rms = math.sqrt(c.sse / len(obs.obj))
    backs = [i for i, ok in zip(obs.ids, seen) if not ok]
    if backs:
        c.problem, c.problem_short = _from_behind_message(obs, backs, rms)
        return c.problem
    behind = [i for i, d in zip(obs.ids, depth.reshape(-1, 4).min(axis=1)) if not d > 0]
    if behind:
        c.problem, c.problem_short = _behind_camera_message(behind, rms)
        return c.problem
    c.problem = None
    return None


def _from_behind_message(obs: _Obs, backs: list[int], rms: float) -> tuple[str, str]:
    """What :func:`_cheirality` says (in full, and in one sentence) of markers a pose sees from behind."""
    one = len(backs) == 1
    which = f"marker{'' if one else 's'} {backs[0] if one else backs}"
    problem = (
        f"{which} would be seen from behind (from the back of {'its' if one else 'their'} printed face) by the "
        f"pose that fits the corners best (reprojection error {rms:.1f} px): "
        f"{'is its rotation' if one else 'are their rotations'} "
        "in the map wrong (yaw 180, facing into the wall instead of out of it; a marker on a wall facing +X has "
        "rotation [0, 0, 0]), or the corners mirrored (TL, BL, BR, TR instead of TL, TR, BR, BL)?"
        + (
            f" With markers {obs.ids} in view, the wrong rotation may be another one's."
            if len(backs) < len(obs.ids)
            else ""
        )
    )
    return problem, f"Even that best fit would see {which} from behind."


def _behind_camera_message(behind: list[int], rms: float) -> tuple[str, str]:
    """What :func:`_cheirality` says (in full, and in one sentence) of markers a pose has behind the camera."""
    one = len(behind) == 1
    which = f"marker{'' if one else 's'} {behind[0] if one else behind}"
    problem = (
        f"{which} would be behind the camera in the pose that fits the corners best (reprojection error "
        f"{rms:.1f} px): the corners do not fit the map; check the map's positions and rotations, the marker "
        "size and the corner order (TL, TR, BR, BL)"
    )
    return problem, f"Even that best fit would have {which} behind the camera."
