"""locate: detect the map's markers in an image and estimate the camera's pose."""

from __future__ import annotations

import os

import numpy as np

from .. import _cv
from .._cv_charuco import interpolate_charuco
from .._fisheye_edges import refine_edges_fisheye
from .._wpilib import outside_field
from ..camera import Camera
from ..detection import DEFAULT_REFINE, Detection, _refine_name, as_gray, detect_markers
from ..errors import ImageError, PoseError
from ..markermap import BoardEntry, MarkerMap
from ._estimate import estimate_pose
from ._inputs import _as_camera, _as_map, _check_pose_options
from ._result import Pose
from ._second_look import _border_bits, missed_in_view, read_again

__all__ = ["locate"]


def locate(
    image: np.ndarray,
    marker_map: MarkerMap | str | os.PathLike,
    camera: Camera | str | os.PathLike,
    *,
    refine: str | None = None,
    detector_params=None,
    only_map_markers: bool = True,
    **kw,
) -> Pose:
    """Detect the map's markers in an image and estimate the camera's pose.

    By default only the map's markers are looked for: OpenCV compares every
    candidate quad with every marker it looks for, so this costs a fraction of a
    detection with the whole dictionary (1024 markers for ARUCO_ORIGINAL) and
    finds the same markers at the same corners. Other markers of the dictionary
    in view are then not reported in :attr:`Pose.ignored_ids` unless
    ``only_map_markers=False``; when none of the map's markers is found, the
    whole dictionary is searched once so that the error says which ids were seen.
    A map marker that the pose puts whole in the picture, facing the camera, but that the
    detector missed (OpenCV can keep the outline of its white margin instead of its own) is
    read again inside its predicted outline, and the pose estimated again with it
    (:mod:`fidlearn.pose._second_look`).

    Parameters
    ----------
    image : ndarray
        Gray or BGR image (read a file with :func:`fidlearn.detection.load_image`).
    marker_map : MarkerMap or path
        The world map; its dictionary is used for detection. A path (str or
        ``pathlib.Path``) is read with :meth:`MarkerMap.load` (in a loop over
        many images, load it once and pass the MarkerMap).
    camera : Camera or path
        Fitted to the image with :meth:`Camera.for_image` (rescaled with a
        :class:`FidlearnWarning` when only the resolution differs; a
        :class:`CameraError` when the aspect ratio differs). A path is read
        with :meth:`Camera.load`.
    refine : str, optional
        Corner refinement for :func:`fidlearn.detection.detect_markers`:
        ``"edges"`` (its default), ``"none"``, ``"subpix"``, ``"contour"`` or
        ``"apriltag"``; None for the default.
    detector_params : dict or cv2.aruco.DetectorParameters, optional
        OpenCV detector parameters, passed to ``detect_markers(detector_params=...)``.
    only_map_markers : bool
        Look only for the map's ids (the default, faster); False to detect the
        whole dictionary and list the other ids in ``Pose.ignored_ids``.
    **kw
        Passed to :func:`estimate_pose` (``method``, ``refine_lm``,
        ``reject_outliers``, ``corner_sigma_px``). A ChArUco board entry of the map
        seen in the image adds its chess corners, interpolated from its detected markers
        and refined on the image (OpenCV's ``CharucoDetector``), to the pose
        (``estimate_pose(board_corners=...)``; a pinhole camera's).

    Returns
    -------
    Pose
        The camera's pose in the world (``T_world_camera``, mm) with its uncertainty.

    Raises
    ------
    ImageError
        ``image`` is not an image array.
    NoMarkersError
        No marker of the map is detected (the message lists the ids seen, the map's ids and
        dictionary, and what to check). A missing pose is never returned as None;
        :meth:`fidlearn.MarkerTracker.locate` raises the same way for a video frame.
    PoseError
        Bad arguments, or the corners do not give a pose (see :func:`estimate_pose`).

    Examples
    --------
    >>> import numpy as np, fidlearn
    >>> from fidlearn.detection import load_image
    >>> image = load_image(fidlearn.data_path("scenes", "scene_00.png"))   # rendered from [1000, 190, 230] mm
    >>> pose = locate(image, fidlearn.data_path("world_map.json"), fidlearn.data_path("scenes", "camera.json"))
    >>> pose.marker_ids, np.round(pose.position_mm, -1).tolist()
    ((0, 1, 2), [1000.0, 190.0, 230.0])
    """
    # every argument is checked before the (costly) detection
    if not isinstance(image, np.ndarray):
        raise ImageError(
            f"image must be a numpy array (use fidlearn.detection.load_image for a file), got {type(image).__name__}"
        )
    _check_pose_options(kw, "locate()", "refine, detector_params")
    marker_map = _as_map(marker_map)
    camera = _as_camera(camera).for_image(image)
    detections = _detect_map_markers(image, marker_map, refine, detector_params, only_map_markers)
    straighten = camera.model == "fisheye" and (DEFAULT_REFINE if refine is None else _refine_name(refine)) == "edges"
    if straighten:
        detections = _straightened(image, detections, camera, marker_map.dictionary, detector_params)
    pinhole = camera.model != "fisheye"  # a ChArUco board entry's chess corners join a pinhole's pose
    chess = chess_corners_seen(image, marker_map, detections) if pinhole else None
    pose = estimate_pose(detections, marker_map, camera, board_corners=chess, **kw)
    found = {marker_map.key(d.id, d.dictionary) for d in detections}
    missed = missed_in_view(marker_map, camera, pose.T_world_camera, found, detector_params)
    more = read_again(image, missed, refine, detector_params) if missed else []
    if more:  # markers the detector missed, found where the pose puts them
        if straighten:
            more = _straightened(image, more, camera, marker_map.dictionary, detector_params)
        chess = chess_corners_seen(image, marker_map, detections + more) if pinhole else None
        pose = estimate_pose(detections + more, marker_map, camera, board_corners=chess, **kw)
    problem = outside_field(marker_map, pose.position_mm, pose.marker_ids)  # a field layout's mirrored corners
    if problem is not None:
        raise PoseError(problem)
    return pose


def _straightened(
    image: np.ndarray, detections: list[Detection], camera: Camera, dictionary: str, detector_params
) -> list[Detection]:
    """Fisheye corners refined again with their sides fitted as the lens bends them (:mod:`fidlearn._fisheye_edges`).

    Each marker is corrected with its own dictionary's cells (a map may mix dictionaries); ``dictionary``
    stands in for a detection that does not say its own.
    """
    if not detections:
        return []
    border = _border_bits(detector_params)
    out = list(detections)
    gray = as_gray(image)
    for name in {d.dictionary or dictionary for d in detections}:
        mine = [k for k, d in enumerate(detections) if (d.dictionary or dictionary) == name]
        cells = _cv.dictionary_marker_bits(name) + 2 * border
        fixed = refine_edges_fisheye(gray, np.stack([detections[k].corners_px for k in mine]), camera, cells)
        for k, f in zip(mine, fixed):
            out[k] = detections[k]._with_corners(f)
    return out


def _detect_map_markers(
    image: np.ndarray, marker_map: MarkerMap, refine: str | None, detector_params, only_map_markers: bool
) -> list[Detection]:
    """The map's markers in the image (every marker of the dictionary with ``only_map_markers=False``).

    When none of the map's markers is found, the whole dictionary is searched once (without corner
    refinement) so that estimate_pose's :class:`NoMarkersError` can say which ids were seen.
    """
    det_kw = {} if refine is None else {"refine": refine}
    if detector_params is not None:
        det_kw["detector_params"] = detector_params
    if not isinstance(only_map_markers, (bool, np.bool_)):
        raise PoseError(f"only_map_markers must be True or False, got {only_map_markers!r}")
    names = marker_map.dictionaries  # one detector per dictionary the map uses
    dictionary = names[0] if len(names) == 1 else names
    ids = None
    if only_map_markers:
        ids = marker_map.ids if len(names) == 1 else {n: marker_map.ids_in(n) for n in names}
    detections = detect_markers(image, dictionary=dictionary, ids=ids, **det_kw)
    if not detections and only_map_markers:
        # nothing of the map: detect the whole dictionary once, so the error lists what is in view
        detections = detect_markers(image, dictionary=dictionary, **{**det_kw, "refine": "none"})
    return detections


def chess_corners_seen(image: np.ndarray, marker_map: MarkerMap, detections: list[Detection]) -> dict | None:
    """The chess corners of each ChArUco board entry whose markers were detected: ``{name: (ids, px)}``, or None."""
    boards = {n: e for n, e in marker_map.entries.items() if isinstance(e, BoardEntry) and e.kind == "charuco"}
    if not boards:
        return None
    gray = as_gray(image)  # as detection reads it: (H, W, 1), BGRA, uint16 and float pictures too
    out = {}
    for name, entry in boards.items():
        mine = [d for d in detections if marker_map.owner.get(marker_map.key(d.id, d.dictionary)) == name]
        if not mine:
            continue
        corners, ids = interpolate_charuco(entry.cv_board(), gray, [d.corners_px for d in mine], [d.id for d in mine])
        if len(ids):
            out[name] = (ids, corners)
    return out or None
