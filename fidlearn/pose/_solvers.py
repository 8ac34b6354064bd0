"""The PnP solvers: IPPE, IPPE_SQUARE, SQPnP and OpenCV's others, the choice among them, and the candidate
poses they give, ranked (refined by Levenberg-Marquardt, those a camera can have first)."""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from .. import _cv
from ..camera import Camera
from ..errors import PoseError
from ..markermap import MarkerMap
from ._checks import _cheirality
from ._observations import _Candidate, _Obs
from ._refine import _lm_full, _residuals
from ._stats import _sigma

#: The solvers ``method=`` accepts besides ``"auto"``, with their OpenCV names.
METHODS = {
    "ippe": "IPPE",
    "ippe_square": "IPPE_SQUARE",
    "sqpnp": "SQPNP",
    "iterative": "ITERATIVE",
    "epnp": "EPNP",
}

#: The other planar solutions are refined only when they start within this many sigma^2
#: of the best one's refined sum of squared residuals (else they are kept as IPPE gave them).
REFINE_GAP_CHI2 = 100.0

#: solvePnPGeneric reports sqrt(sse / 2N) for N points, the RMS per coordinate (OpenCV 4 and 5): the
#: sum of squared residuals is rms^2 * 2 * N.
_RMS_COORDS = 2

_PLANAR_TOL_MM = 1.0
_PLANAR_TOL_REL = 0.01
#: Off-plane thickness below this fraction of the extent: SQPnP's answer competes with IPPE's.
_NEAR_PLANAR_REL = 0.1


def _plane_fit(points: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray, np.ndarray]:
    """Thickness (mm), extent (mm), centroid (3,), rotation (3, 3) whose 3rd row is the plane normal, and the
    points in the plane's frame (N, 3), flattened onto it (z = 0: what IPPE takes)."""
    c = points.mean(axis=0)
    q = points - c
    _, s, vt = np.linalg.svd(q, full_matrices=False)
    if vt.shape[0] < 3:
        vt = np.vstack([vt, np.cross(vt[0], vt[1])])
    if np.linalg.det(vt) < 0:
        vt[2] = -vt[2]
    thickness = float(np.abs(q @ vt[2]).max())
    extent = float(np.abs(q @ vt[0]).max()) * 2
    local = q @ vt.T
    local[:, 2] = 0.0
    return thickness, extent, c, vt, local


_PLANE_CACHE: dict[bytes, tuple] = {}


def _plane_fit_cached(points: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_plane_fit`, remembered for the last few point sets (a map seen again and again)."""
    key = points.tobytes()
    hit = _PLANE_CACHE.get(key)
    if hit is None:
        hit = _plane_fit(points)
        hit[2].flags.writeable = hit[3].flags.writeable = hit[4].flags.writeable = False
        if len(_PLANE_CACHE) >= 64:
            _PLANE_CACHE.pop(next(iter(_PLANE_CACHE)))
        _PLANE_CACHE[key] = hit
    return hit


def _from_R_t(obs: _Obs, camera: Camera, R_cw: np.ndarray, t: np.ndarray, sse: float | None = None) -> _Candidate:
    """A candidate from T_camera_world's rotation (3, 3) and translation (3,) (float64, as the solvers give them),
    not refined.

    With ``sse`` given (the solver's own reprojection error) the residuals are left for later.
    """
    R_wc = np.ascontiguousarray(R_cw.T)
    C = -R_wc @ t
    if sse is not None:
        return _Candidate(R_wc, C, float(sse), None)
    r, _ = _residuals(obs.obj, obs.img, camera.K, camera.dist, R_wc, C, False)
    return _Candidate(R_wc, C, float(r @ r), r)


def _lm_candidate(obs: _Obs, camera: Camera, start: _Candidate) -> _Candidate:
    R_wc, C, sse, r, J, JtJ = _lm_full(obs.obj, obs.img, camera.K, camera.dist, start.R_wc, start.C)
    return _Candidate(R_wc, C, sse, r, True, JtJ, J)


_solvepnp_flag = functools.lru_cache(maxsize=None)(_cv.solvepnp_flag)  # (looked up by name on every solve)


def _generic(flag_name: str, obj: np.ndarray, img: np.ndarray, camera: Camera):
    """``cv2.solvePnPGeneric`` on float64 points ``obj`` (N, 3) and ``img`` (N, 2) (OpenCV reads them as the
    (N, 1, 3) and (N, 1, 2) it documents): a list of (R_cw (3, 3), t (3,), sse px^2, from the solver's reported
    RMS); empty when the solver fails."""
    try:
        n, rvecs, tvecs, rms = cv2.solvePnPGeneric(
            obj,
            img,
            camera.K,
            camera.dist,
            flags=_solvepnp_flag(flag_name),
        )
    except cv2.error:
        return []
    rms_list = rms.ravel().tolist() if rms is not None else []
    out = []
    for k, (r, t) in enumerate(list(zip(rvecs, tvecs))[:n]):  # float64 arrays (3, 1) each
        t = t.reshape(3)
        if all(map(math.isfinite, r.ravel().tolist() + t.tolist())):  # (on 6 numbers: a fifth of numpy's cost)
            ok = k < len(rms_list) and math.isfinite(rms_list[k])
            sse = rms_list[k] ** 2 * _RMS_COORDS * len(obj) if ok else None
            out.append((cv2.Rodrigues(r)[0], t, sse))
    return out


_MARKER_POSE_CACHE: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}


def _marker_pose_cached(marker_map: MarkerMap, obs: _Obs) -> tuple[np.ndarray, np.ndarray]:
    """R (3, 3) and t (3,), mm, of ``marker_map.T_world_marker`` of the one marker in ``obs``, remembered by its
    world corners (which fix it) for the last few markers."""
    key = obs.obj.tobytes()
    hit = _MARKER_POSE_CACHE.get(key)
    if hit is None:
        T = marker_map.T_world_marker(obs.ids[0])
        hit = (T[:3, :3].copy(), T[:3, 3].copy())
        hit[0].flags.writeable = hit[1].flags.writeable = False
        if len(_MARKER_POSE_CACHE) >= 256:
            _MARKER_POSE_CACHE.pop(next(iter(_MARKER_POSE_CACHE)))
        _MARKER_POSE_CACHE[key] = hit
    return hit


def _solve_ippe_square(obs: _Obs, marker_map: MarkerMap, camera: Camera):
    """IPPE_SQUARE in the marker's own frame (centre origin, x right, y up), moved to the world."""
    s = marker_map.marker_size(obs.ids[0])
    local = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0], [-s / 2, -s / 2, 0]])
    R_wm, t_wm = _marker_pose_cached(marker_map, obs)
    # T_camera_world = T_camera_marker @ inv(T_world_marker)
    return [
        (R_cm @ R_wm.T, t_cm - R_cm @ R_wm.T @ t_wm, sse)
        for R_cm, t_cm, sse in _generic("IPPE_SQUARE", local, obs.img, camera)
    ]


def _solve_ippe(obs: _Obs, camera: Camera, plane) -> list:
    """IPPE on the points flattened onto their best plane (IPPE refuses points even 1 mm off it), ``plane``
    :func:`_plane_fit`'s of ``obs.obj``."""
    _, _, c, vt, local = plane
    # T_camera_world = T_camera_plane @ T_plane_world, T_plane_world = [vt, -vt c]
    out = []
    for R_cp, t_cp, sse in _generic("IPPE", local, obs.img, camera):
        R_cw = R_cp @ vt
        out.append((R_cw, t_cp - R_cw @ c, sse))
    return out


def _solve(obs: _Obs, marker_map: MarkerMap, camera: Camera, method: str, refine_lm: bool):
    """Candidate poses, ranked, from the solver ``method`` (``"auto"``: the one the data call for).

    Returns
    -------
    cands : list of _Candidate
        Those a camera can have first, each group by reprojection error; refined by
        Levenberg-Marquardt when ``refine_lm`` (see :func:`_rank`).
    unrefined : list of _Candidate
        The solver's own poses by reprojection error (``cands`` itself without ``refine_lm``).
    method_used : str
        The solver's name, ``"+lm"`` appended when refined.
    """
    plane = _plane_fit_cached(obs.obj)
    thickness, extent = plane[:2]
    planar = thickness <= max(_PLANAR_TOL_MM, _PLANAR_TOL_REL * extent)
    if method == "auto":
        method_used, raw = _solve_auto(obs, marker_map, camera, plane, planar)
    else:
        method_used, raw = method, _solve_named(obs, marker_map, camera, method, plane, planar)
    if not raw:
        raise PoseError(
            f"the PnP solver ({method_used}) found no pose from markers {obs.ids}; are the map's corners "
            "in TL, TR, BR, BL order and the marker size right?"
        )
    return _rank(obs, camera, raw, refine_lm, method_used)


def _solve_auto(obs: _Obs, marker_map: MarkerMap, camera: Camera, plane, planar: bool) -> tuple[str, list]:
    """The solver the data call for (see the package's docstring) and its raw solutions (R_cw, t, sse)."""
    thickness, extent = plane[:2]
    if len(obs.ids) == 1:
        method_used, raw = "ippe_square", _with_sqpnp_if_off(obs, camera, _solve_ippe_square(obs, marker_map, camera))
    elif planar:
        method_used, raw = "ippe", _with_sqpnp_if_off(obs, camera, _solve_ippe(obs, camera, plane))
    else:
        method_used, raw = "sqpnp", _generic("SQPNP", obs.obj, obs.img, camera)
        if thickness < _NEAR_PLANAR_REL * extent:
            # a wall measured a little unevenly: IPPE's two flattened solutions compete too
            raw = raw + _solve_ippe(obs, camera, plane)
    if not raw:  # degenerate data: fall back on the general solvers
        for name in ("SQPNP", "ITERATIVE"):
            raw = _generic(name, obs.obj, obs.img, camera)
            if raw:
                method_used = name.lower()
                break
    return method_used, raw


#: IPPE's best solution leaving more than this RMS (px, per coordinate) asks SQPnP too. Corners 1 px off leave
#: IPPE's best about 1 px half the time; at 3 px SQPnP's start was missed in some of those frames, where LM from it
#: reaches a better minimum (poses up to 5.4 mm apart, and one wrong planar branch unflagged in 400 frames).
_IPPE_OFF_RMS_PX = 1.0


def _with_sqpnp_if_off(obs: _Obs, camera: Camera, raw: list) -> list:
    """IPPE's raw solutions, with SQPnP's added when IPPE's best leaves more than ``_IPPE_OFF_RMS_PX``.

    OpenCV's IPPE (and IPPE_SQUARE) return a pose that fits nothing when the image of the points is exactly
    mirror-symmetric (a rendered marker seen level and straight from the side: 21 px off for a 29 px marker),
    where SQPnP is exact. Real corners are never that symmetric, and a frame IPPE fits costs nothing more.
    """
    sses = [sse for _, _, sse in raw if sse is not None]
    if raw and sses and min(sses) <= _IPPE_OFF_RMS_PX**2 * _RMS_COORDS * len(obs.obj):
        return raw
    return raw + _generic("SQPNP", obs.obj, obs.img, camera)


def _solve_named(obs: _Obs, marker_map: MarkerMap, camera: Camera, method: str, plane, planar: bool) -> list:
    """The raw solutions (R_cw, t, sse) of the solver ``method`` (a key of METHODS), or PoseError when it
    cannot solve this data."""
    n_pts = len(obs.obj)
    if method == "ippe_square":
        if len(obs.ids) != 1:
            raise PoseError(
                f"method='ippe_square' solves one marker, but {len(obs.ids)} markers {obs.ids} are in view; "
                "use method='ippe' (coplanar markers) or 'auto'"
            )
        return _solve_ippe_square(obs, marker_map, camera)
    if method == "ippe":
        if not planar:
            raise PoseError(
                f"method='ippe' needs coplanar points, but the corners of markers {obs.ids} are up to "
                f"{plane[0]:.1f} mm off their best plane (markers on several walls); use method='sqpnp', "
                "'epnp', 'iterative' or 'auto'"
            )
        return _solve_ippe(obs, camera, plane)
    if (method == "sqpnp" and n_pts < 3) or (method in ("epnp", "iterative") and n_pts < 4):
        raise PoseError(f"method={method!r} needs more points than the {n_pts} corners in view")
    return _generic(METHODS[method], obs.obj, obs.img, camera)


def _rank(obs: _Obs, camera: Camera, raw: list, refine_lm: bool, method_used: str):
    """Candidates from raw solutions: ``(cands, unrefined, method_used)`` as :func:`_solve` returns them."""
    if not refine_lm:
        unrefined = [_from_R_t(obs, camera, R_cw, t) for R_cw, t, _ in raw]
        unrefined.sort(key=lambda k: k.sse)
        unrefined = _front_first(obs, camera, unrefined, False)
        return unrefined, unrefined, method_used
    # ranked by the solver's own reprojection error; LM computes the residuals anyway
    unrefined = [_from_R_t(obs, camera, R_cw, t, sse) for R_cw, t, sse in raw]
    unrefined.sort(key=lambda k: k.sse)
    # LM from the best start; from the others only when they might end near it (within
    # REFINE_GAP_CHI2 sigma^2): a flip that starts thousands of sigma^2 worse never becomes
    # a rival, and each LM run from afar costs a dozen projections.
    best = _lm_candidate(obs, camera, unrefined[0])
    cands = [best]
    sigma2 = _sigma(best.sse, 2 * len(obs.obj) - 6, None) ** 2
    for u in unrefined[1:]:
        cands.append(_lm_candidate(obs, camera, u) if u.sse - best.sse < REFINE_GAP_CHI2 * sigma2 else u)
    cands.sort(key=lambda k: k.sse)
    return _front_first(obs, camera, cands, True), unrefined, method_used + "+lm"


def _front_first(obs: _Obs, camera: Camera, cands: list, refine_lm: bool) -> list:
    """The candidates with those a camera can have (:func:`_cheirality`) first, each group by error.

    Costs nothing more in the usual case (the best candidate passes). Otherwise the best one
    that passes is refined if it was not.
    """
    if _cheirality(obs, cands[0]) is None:
        return cands
    ok = [c for c in cands if _cheirality(obs, c) is None]
    bad = [c for c in cands if c.problem is not None]
    if ok and refine_lm and not ok[0].refined:
        r = _lm_candidate(obs, camera, ok[0])
        if _cheirality(obs, r) is None:
            ok[0] = r
            ok.sort(key=lambda k: k.sse)
    return ok + bad
