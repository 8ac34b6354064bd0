"""The checks of estimate_pose's and locate's arguments: the map, the camera, the detections and the options."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..camera import Camera
from ..detection import Detection
from ..errors import PoseError
from ..markermap import MarkerMap
from ._solvers import METHODS

_ESTIMATE_OPTIONS = frozenset({"method", "refine_lm", "reject_outliers", "corner_sigma_px"})


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
    if dets and not np.isfinite(np.stack([d.corners_px for d in dets])).all():
        k, d = next((k, d) for k, d in enumerate(dets) if not np.isfinite(d.corners_px).all())
        raise PoseError(f"detections[{k}] (marker {d.id}) has NaN or infinite corners: {d.corners_px.tolist()}")
    if camera.model == "fisheye":
        dets, camera = _as_pinhole(dets, camera)
    return dets, marker_map, camera


def _as_pinhole(dets: list[Detection], camera: Camera) -> tuple[list[Detection], Camera]:
    """A fisheye's detections as the distortion-free pinhole camera with the same K sees them.

    Each corner is undistorted exactly (``Camera.undistort_points``, the inverse of ``Camera.project``); a
    marker with a corner 90 degrees or more off the axis has no pinhole picture and is left out. The pose's
    reprojection errors are then in those ideal pixels, which are wider than the picture's own away from
    the centre (about 1 / cos^2 of the angle off the axis).
    """
    ideal = camera.undistort_points(np.concatenate([d.corners_px for d in dets])) if dets else np.zeros((0, 2))
    out = []
    for k, d in enumerate(dets):
        corners = ideal[4 * k : 4 * k + 4]
        if np.isfinite(corners).all():
            out.append(dataclasses.replace(d, corners_px=corners))
    pinhole = Camera(camera.K, None, camera.image_size, source=f"{camera.source or 'camera'} undistorted")
    return out, pinhole
