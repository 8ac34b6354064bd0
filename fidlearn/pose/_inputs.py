"""The checks of estimate_pose's and locate's arguments: the map, the camera, the detections and the options."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import cv2
import numpy as np

from ..camera import Camera
from ..detection import Detection
from ..errors import PoseError
from ..markermap import MarkerMap
from ._refine import _residuals
from ._solvers import METHODS

_ESTIMATE_OPTIONS = frozenset({"method", "refine_lm", "reject_outliers", "corner_sigma_px"})

#: The picture's move (px) by which a fisheye corner's ideal pinhole pixel must still move almost along a line for
#: the pose's pinhole stage to take the corner. A corner ``theta`` off the axis lies at ``r = tan(theta)`` in
#: normalized ideal coordinates; a picture move ``d`` (px) turns it by ``d / (f theta_d'(theta))`` (``f`` the
#: lens's pixels per radian, ``theta_d`` its Kannala-Brandt angle), and ``r``'s second-order change over its first
#: is ``r`` times that angle. Where it reaches 1 the ideal pixel of a one-pixel error is as much curve as line
#: (89.8 degrees for an equidistant lens of 286 px per radian: ``tan(theta) = 286``): the unweighted pinhole solve
#: and the outlier screen, linear in ideal pixels, cannot read such a corner (its noise alone stretches to
#: hundreds of thousands of ideal px). Such a marker is left out before the solve and reported in
#: ``Pose.rejected_ids`` (see :func:`_rim_markers`).
RIM_PICTURE_PX = 1.0


def _as_map(marker_map) -> MarkerMap:
    """The MarkerMap itself, or the one loaded from a path (MarkerMap.load)."""
    if isinstance(marker_map, MarkerMap):
        return marker_map
    if isinstance(marker_map, (str, os.PathLike)):
        return MarkerMap.load(marker_map)
    swapped = " (arguments swapped? the order is marker_map, camera)" if isinstance(marker_map, Camera) else ""
    raise PoseError(
        f"marker_map must be a fidlearn.MarkerMap or the path of a map file, got {type(marker_map).__name__}"
        f"{swapped}; load a file with MarkerMap.load(path)"
    )


def _as_camera(camera) -> Camera:
    """The Camera itself, or the one loaded from a path (Camera.load)."""
    if isinstance(camera, Camera):
        return camera
    if isinstance(camera, (str, os.PathLike)):
        return Camera.load(camera)
    swapped = " (arguments swapped? the order is marker_map, camera)" if isinstance(camera, MarkerMap) else ""
    raise PoseError(
        f"camera must be a fidlearn.Camera or the path of a camera file, got {type(camera).__name__}{swapped}; "
        "load a file with Camera.load(path) (or make one with Camera(K, dist, image_size))"
    )


def _check_options(method, refine_lm, reject_outliers, corner_sigma_px) -> str:
    """Validate estimate_pose's options; return the method in lower case."""
    if not isinstance(method, str):
        raise PoseError(f"method must be a string, 'auto' or one of {', '.join(METHODS)}; got {method!r}")
    method = method.lower()
    if method != "auto" and method not in METHODS:
        raise PoseError(f"unknown method {method!r}; use 'auto' or one of {', '.join(METHODS)}")
    if refine_lm is not None and not isinstance(refine_lm, (bool, np.bool_)):
        raise PoseError(f"refine_lm must be True, False or None (the method's default), got {refine_lm!r}")
    if not isinstance(reject_outliers, (bool, np.bool_)):
        raise PoseError(f"reject_outliers must be True or False, got {reject_outliers!r}")
    if corner_sigma_px is not None:
        ok = isinstance(corner_sigma_px, (int, float, np.integer, np.floating)) and not isinstance(
            corner_sigma_px, bool
        )
        if not (ok and 0 < float(corner_sigma_px) < math.inf):  # NaN fails too; float() of 10**40 is 1e40
            raise PoseError(f"corner_sigma_px must be a positive number of pixels, got {corner_sigma_px!r}")
    return method


def _check_pose_options(options: Mapping[str, Any], caller: str, takes: str) -> dict[str, Any]:
    """Check the options that another function passes on to :func:`estimate_pose`, before any costly work.

    The one check of these options for :func:`locate` and :class:`~fidlearn.MarkerTracker`.

    Parameters
    ----------
    options : mapping of str to object
        Keyword options meant for estimate_pose: ``method``, ``refine_lm``, ``reject_outliers``,
        ``corner_sigma_px``.
    caller : str
        The function they were given to, for the message, e.g. ``"locate()"``.
    takes : str
        The caller's own options, for the message, e.g. ``"refine, detector_params"``.

    Returns
    -------
    dict
        A copy of ``options``.

    Raises
    ------
    PoseError
        An option estimate_pose does not take, or a value it refuses (see :func:`_check_options`).
    """
    unknown = sorted(set(options) - _ESTIMATE_OPTIONS)
    if unknown:
        raise PoseError(
            f"{caller} got unknown option{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}; it takes "
            f"{takes} and estimate_pose's {', '.join(sorted(_ESTIMATE_OPTIONS))}"
        )
    _check_options(
        options.get("method", "auto"),
        options.get("refine_lm"),
        options.get("reject_outliers", True),
        options.get("corner_sigma_px"),
    )
    return dict(options)


def _check_inputs(detections, marker_map, camera) -> tuple[list[Detection], MarkerMap, Camera]:
    """The checked detections, map and camera (a fisheye's detections undistorted: see :func:`_as_pinhole`)."""
    dets, marker_map, camera, _, _ = _check_inputs_lens(detections, marker_map, camera)
    return dets, marker_map, camera


def _check_inputs_lens(
    detections, marker_map, camera
) -> tuple[list[Detection], MarkerMap, Camera, Camera | None, list[Detection]]:
    """:func:`_check_inputs`, the fisheye camera the detections were undistorted from (None for a pinhole) and the
    detections left out for a corner 90 degrees or more off its axis (:func:`_as_pinhole`)."""
    marker_map = _as_map(marker_map)
    camera = _as_camera(camera)
    if isinstance(detections, Detection):
        detections = [detections]
    if isinstance(detections, (str, bytes, np.ndarray)) or not hasattr(detections, "__iter__"):
        raise PoseError(
            f"detections must be a list of fidlearn Detection (from detect_markers), got {type(detections).__name__}"
        )
    dets = list(detections)
    for k, d in enumerate(dets):
        if not isinstance(d, Detection):
            raise PoseError(
                f"detections[{k}] is a {type(d).__name__}, expected a Detection(id, corners (4, 2)); "
                "build one with fidlearn.detection.Detection(marker_id, corners_px)"
            )
    if dets:
        _refuse_bad_corners(dets, np.concatenate([d.corners_px for d in dets]), camera)
    if camera.model == "fisheye":
        pinhole_dets, pinhole, beyond = _as_pinhole(dets, camera)
        return pinhole_dets, marker_map, pinhole, camera, beyond
    return dets, marker_map, camera, None, []


#: How far (a fraction of the picture's larger side) a detected corner may lie outside the camera's picture.
OFF_PICTURE_FRACTION = 0.25


def _refuse_bad_corners(dets: list[Detection], c: np.ndarray, camera: Camera) -> None:
    """PoseError for a NaN or infinite corner, or one far outside the camera's picture: detections from a picture
    of another size (a frame at full resolution with the camera of a smaller one) fit a pose with no residual, in
    the wrong place. ``c`` (N, 2): every detection's corners, px."""
    w, h = camera.image_size
    slack = OFF_PICTURE_FRACTION * max(w, h)
    (x0, y0), (x1, y1) = c.min(axis=0).tolist(), c.max(axis=0).tolist()
    if x0 >= -slack and y0 >= -slack and x1 <= w + slack and y1 <= h + slack:
        return  # the usual case, in one pass (a NaN fails these comparisons too)
    if not np.isfinite(c).all():
        k, d = next((k, d) for k, d in enumerate(dets) if not np.isfinite(d.corners_px).all())
        raise PoseError(f"detections[{k}] (marker {d.id}) has NaN or infinite corners: {d.corners_px.tolist()}")
    out = (c < -slack) | (c > [w + slack, h + slack])
    if out.any():
        far = c[int(np.flatnonzero(out.any(axis=1))[0])]  # a corner that is out, on whichever side
        raise PoseError(
            f"a detected corner lies at ({far[0]:.0f}, {far[1]:.0f}) px, far outside the camera's {w}x{h} picture: "
            "were they detected in a picture of another size? Use camera.for_image(image), or detect in the "
            "picture the camera was calibrated for"
        )


def _as_pinhole(dets: list[Detection], camera: Camera) -> tuple[list[Detection], Camera, list[Detection]]:
    """A fisheye's detections as the distortion-free pinhole camera with the same K sees them, that camera, and the
    detections left out.

    Each corner is undistorted exactly (``Camera.undistort_points``, the inverse of ``Camera.project``); a
    marker with a corner 90 degrees or more off the axis has no pinhole picture and is left out (the limit of the
    rim test, which :func:`estimate_pose` reports both alike in ``Pose.rejected_ids``). The pose's
    reprojection errors are then in those ideal pixels, which are wider than the picture's own away from
    the centre (about 1 / cos^2 of the angle off the axis); :func:`estimate_pose` leaves out the markers
    whose ideal pixels a one-pixel error in the picture bends (:func:`_rim_markers`).
    """
    ideal = camera.undistort_points(np.concatenate([d.corners_px for d in dets])) if dets else np.zeros((0, 2))
    ideal = ideal.reshape(-1, 4, 2)
    whole = np.asarray(np.isfinite(ideal).all(axis=(1, 2)))
    out = [d._with_corners(ideal[k]) for k, d in enumerate(dets) if whole[k]]
    pinhole = Camera(camera.K, None, camera.image_size, source=f"{camera.source or 'camera'} undistorted")
    return out, pinhole, [d for k, d in enumerate(dets) if not whole[k]]


def _rim_markers(corners_px: Mapping[int, np.ndarray], lens: Camera) -> list[int]:
    """The markers with an ideal pinhole corner (4, 2), px, that a picture's ``RIM_PICTURE_PX`` move bends.

    ``corners_px`` are a fisheye's corners undistorted to the pinhole with its K (:func:`_as_pinhole`), ``lens``
    the fisheye. A corner at normalized radius ``r`` (``theta = atan(r)`` off the axis) is left out when
    ``r * RIM_PICTURE_PX / (f theta_d'(theta)) > 1``, ``f = sqrt(fx fy)`` (see ``RIM_PICTURE_PX``). None is
    left out when that would leave no marker: the pose then comes from them all.
    """
    K = lens.K
    keys = list(corners_px)
    px = np.stack([corners_px[k] for k in keys]).reshape(-1, 2)  # one pass over every corner
    y = (px[:, 1] - K[1, 2]) / K[1, 1]
    x = (px[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    r = np.sqrt(x * x + y * y)
    k1, k2, k3, k4 = np.ravel(lens.dist)[:4]
    t2 = np.arctan(r) ** 2
    slope = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))  # d theta_d / d theta
    bent = (r * RIM_PICTURE_PX > math.sqrt(K[0, 0] * K[1, 1]) * slope).reshape(-1, 4).any(axis=1)
    rim = [k for k, b in zip(keys, bent) if b]
    return rim if len(rim) < len(corners_px) else []


def _lens_jacobians(lens: Camera, ideal_px: np.ndarray) -> np.ndarray:
    """``d(picture px) / d(ideal px)`` (N, 2, 2) of a fisheye at each undistorted corner (N, 2).

    The inverse of the undistortion's local Jacobian: a picture's corner noise ``sigma^2 I`` is
    ``sigma^2 D^-1 D^-T`` in the ideal pixels (wider near the picture's edge). The Kannala-Brandt model's own
    derivative: a normalized point ``x`` at ``r = |x|`` lands at ``g(r) x``, ``g = theta_d(theta) / r``,
    ``theta = atan(r)``, so ``d(g x) / dx = g I + (g'(r) / r) x x^T``, carried to pixels by ``K``'s upper 2 x 2
    ``A`` (``A (d(g x) / dx) A^-1``). Central differences of ``Camera.project``'s model 0.01 ideal px apart gave
    the same to 1e-7 (:mod:`tests.test_fisheye_fast_paths`), in twice the time.
    """
    ideal = np.asarray(ideal_px, dtype=float).reshape(-1, 2)
    K = lens.K
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    y = (ideal[:, 1] - cy) / fy
    x = (ideal[:, 0] - cx - s * y) / fx
    r2 = x * x + y * y
    r = np.sqrt(r2)
    k1, k2, k3, k4 = np.ravel(lens.dist)[:4]
    theta = np.arctan(r)
    t2 = theta * theta
    theta_d = theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    slope = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))  # d theta_d / d theta
    big = r > 1e-8  # at the axis g = 1 and g'/r times x x^T vanishes (OpenCV's guard too)
    safe = np.where(big, r, 1.0)
    g = np.where(big, theta_d / safe, 1.0)
    h = np.where(big, (slope * r / (1 + r2) - theta_d) / (safe * safe * safe), 0.0)  # g'(r) / r
    hxy = h * x * y
    j00, j01, j11 = g + h * x * x, hxy, g + h * y * y  # d(g x) / dx, symmetric
    a00, a01 = fx * j00 + s * hxy, fx * j01 + s * j11  # A J
    a10, a11 = fy * hxy, fy * j11
    D = np.empty((len(ideal), 2, 2))
    D[:, 0, 0] = a00 / fx
    D[:, 1, 0] = a10 / fx
    D[:, 0, 1] = a01 / fy - a00 * (s / (fx * fy))  # (A J) A^-1
    D[:, 1, 1] = a11 / fy - a10 * (s / (fx * fy))
    return D


def _lens_sse(D: np.ndarray, r: np.ndarray) -> float:
    """The sum of squared residuals (2N,) in ideal px, as the picture's pixels measure them (``D r`` per corner)."""
    w = np.einsum("nij,nj->ni", D, r.reshape(-1, 2))
    return float(np.sum(w * w))


def _lens_covariance(D: np.ndarray, J: np.ndarray, sigma: float) -> np.ndarray | None:
    """The pose covariance (6, 6) of the least-squares fit in ideal pixels, for a fisheye's picture noise ``sigma``.

    The fit weighs every ideal pixel alike, ``(J^T J)^-1 J^T e``; each corner's noise ``e`` is
    ``sigma^2 D^-1 D^-T`` (:func:`_lens_jacobians`), so the covariance is the sandwich
    ``sigma^2 (J^T J)^-1 (sum_i J_i^T D_i^-1 D_i^-T J_i) (J^T J)^-1``, ``J_i`` the corner's two rows of the
    pose Jacobian ``J`` (2N, 6) in ideal pixels. Corners near the edge, which the undistortion stretches,
    weigh more in it. None when the pose is not determined.
    """
    G = np.linalg.inv(D)  # (N, 2, 2): d(ideal px) / d(picture px)
    GJ = (G @ J.reshape(-1, 2, 6)).reshape(-1, 6)
    ok, bread = cv2.invert(J.T @ J)
    if not ok:
        return None
    cov = sigma**2 * bread @ (GJ.T @ GJ) @ bread
    if not np.all(np.isfinite(cov)):
        return None
    return (cov + cov.T) / 2


def _lens_refine(
    obj: np.ndarray, img: np.ndarray, camera: Camera, D: np.ndarray, R_wc: np.ndarray, C: np.ndarray, start=None
):
    """The pose that fits the corners as the fisheye's picture measures them (each residual ``D r``), from a start.

    Gauss-Newton on the ideal-pixel residuals weighted by :func:`_lens_jacobians` (``D^T D`` per corner): the
    maximum-likelihood pose for equal noise in the picture, where the fit in ideal pixels trusts the stretched
    corners near the edge too much. Returns R_wc, C, the weighted Jacobian (2N, 6) there and the plain
    residuals (2N,) and Jacobian (2N, 6) in ideal pixels there; the start when no step lowers the weighted sum
    of squares. It stops when a step lowers the sum by less than 1e-10 of it, or when the next step is predicted
    to (``step . J^T r``, the decrease of the linearized sum: Gauss-Newton's last step is not tried, as the
    fit would take it and stop, moving the pose by 1e-4 of its standard deviation or less). ``start``: the plain
    residuals and Jacobian at the start when the caller has them (a Levenberg-Marquardt fit ends with them).
    """

    def weighted(R, c, plain=None):
        r, J = _residuals(obj, img, camera.K, camera.dist, R, c, True) if plain is None else plain
        Dr = np.einsum("nij,nj->ni", D, r.reshape(-1, 2)).reshape(-1)
        DJ = (D @ J.reshape(-1, 2, 6)).reshape(-1, 6)  # a batched product: 4x faster than einsum's loop
        return float(Dr @ Dr), Dr, DJ, (r, J)

    sse, r, J, plain = weighted(R_wc, C, start)
    for _ in range(10):
        g = J.T @ r
        ok, step = cv2.solve(J.T @ J, g.reshape(6, 1))
        if not ok:
            break
        step = step.reshape(6)
        if step @ g < 1e-10 * max(sse, 1e-12) + 1e-12:  # the step's predicted decrease: converged, not tried
            break
        dR, _ = cv2.Rodrigues(step[:3].reshape(3, 1))
        sse_new, r_new, J_new, plain_new = weighted(dR @ R_wc, C + step[3:])
        if not sse_new < sse:
            break
        done = sse - sse_new < 1e-10 * max(sse, 1e-12) + 1e-12
        R_wc, C, sse, r, J, plain = dR @ R_wc, C + step[3:], sse_new, r_new, J_new, plain_new
        if done:
            break
    return R_wc, C, J, plain[0], plain[1]


_NO_PAIRS = (np.zeros((0, 3)), np.zeros((0, 2)))  # (empty, read-only: shared by every call without chess corners)
_NO_PAIRS[0].flags.writeable = _NO_PAIRS[1].flags.writeable = False


def _chess_pairs(board_corners, marker_map: MarkerMap) -> tuple[np.ndarray, np.ndarray]:
    """The 2D-3D pairs of ChArUco board entries' chess corners: world (N, 3), mm, and pixels (N, 2).

    ``board_corners`` maps a ChArUco board entry's name to ``(ids (N,), corners_px (N, 2))`` as OpenCV's
    ChArUco interpolation gives them (:func:`fidlearn._cv_charuco.interpolate_charuco`); None: no pairs.
    Raises :class:`PoseError` for a name the map has no ChArUco board by, an id the board has not, or corners
    that are not finite pixels.
    """
    if board_corners is None:
        return _NO_PAIRS
    if not isinstance(board_corners, Mapping):
        raise PoseError("board_corners must map a ChArUco board entry's name to (ids, corners_px), or be None")
    world = marker_map.chess_corners()
    obj, img = [np.zeros((0, 3))], [np.zeros((0, 2))]
    for name, value in board_corners.items():
        if name not in world:
            raise PoseError(
                f"board_corners names {name!r}, but the map's ChArUco boards are {sorted(world)}; "
                "give the chess corners of a board entry of the map"
            )
        try:
            ids = np.asarray(value[0]).reshape(-1)
            px = np.asarray(value[1], dtype=float).reshape(len(ids), 2)
        except (TypeError, ValueError, IndexError):
            raise PoseError(f"board_corners[{name!r}] must be (ids (N,), corners_px (N, 2))") from None
        if not (np.issubdtype(ids.dtype, np.integer) and ids.size == len(set(ids.tolist()))):
            raise PoseError(f"board_corners[{name!r}]: the ids must be distinct whole numbers")
        if ids.size and (ids.min() < 0 or ids.max() >= len(world[name])):
            raise PoseError(f"board_corners[{name!r}]: ids run 0 to {len(world[name]) - 1} on that board")
        if not np.isfinite(px).all():
            raise PoseError(f"board_corners[{name!r}] has NaN or infinite corners")
        obj.append(world[name][ids])
        img.append(px)
    return np.concatenate(obj), np.concatenate(img)
