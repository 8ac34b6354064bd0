"""Fast localization for video: look for the markers only where the last pose says they are.

In a video the camera moves little from one frame to the next, and the world
map says where every marker is. :class:`MarkerTracker` predicts the camera's
pose for the new frame from the last two poses (constant velocity), projects
every marker of the map with it, and runs OpenCV's ``ArucoDetector`` only in
small windows around those predictions (merged where they overlap much), then
refines the corners exactly as :func:`fidlearn.detect_markers` does and
estimates the pose with :func:`fidlearn.estimate_pose`. A full-frame detection
runs instead on the first frame, after a frame without a pose, every
``full_every`` frames, when the windows would cover half the image or more, and
again on the same frame when most of the markers seen in the last frame and
predicted well inside the image are not found in their windows, nor in larger
windows around each (a fast turn, a wrong prediction). A wrong prediction
therefore costs time, not markers; a marker that OpenCV finds in one frame and
not in the next (too small, a reflection) costs one larger window.

The detector knows only the map's markers (a dictionary made of the map's ids):
OpenCV compares every candidate quad that does not decode with every marker of
the dictionary, which with the 1024 markers of ``ARUCO_ORIGINAL`` is most of a
plain ``detectMarkers``' time. Markers that are not in the map are never reported.

Why windows rather than OpenCV's ArUco3 mode (``useAruco3Detection``): ArUco3
thresholds a downscaled image, which is fast only when the smallest marker is
large, and it loses markers of 20-30 px; the measurements are in
``docs/benchmarks.md``.

Inside a window OpenCV's size limits (``minMarkerPerimeterRate``,
``maxMarkerPerimeterRate``, fractions of the image's longer side) are rescaled
so that they mean the same number of pixels as on the full frame: the same
markers qualify, and the window does not fill with the tiny candidates a
fraction of a small window would admit (each costs OpenCV milliseconds).

Pixel convention: OpenCV's (pixel centres at integers); window corners are
shifted back by the window's integer offset, so they are exact.

Examples
--------
>>> import fidlearn
>>> m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
>>> cam = fidlearn.Camera.from_fov(60, (640, 480))
>>> drive = fidlearn.render_trajectory(m, cam, n_frames=40, frames_to_render=range(30, 34))
>>> tracker = MarkerTracker(m, cam)
>>> poses = [tracker.locate(frame) for frame in drive.images]
>>> [p.marker_ids for p in poses]
[(0, 1, 2), (0, 1, 2), (0, 1, 2), (0, 1, 2)]
>>> tracker.frames, tracker.full_detections    # the first frame is searched whole, the others in windows
(4, 1)
"""

from __future__ import annotations

import dataclasses
from typing import Any

import cv2
import numpy as np

from . import _cv
from ._detector import _detector_fields, _limits_scaled
from ._fisheye_edges import refine_edges_fisheye
from ._lens import pixels_from_normalized, project_points
from ._windows import boxes_around, merge_boxes
from ._wpilib import outside_field
from .camera import Camera
from .detection import DEFAULT_REFINE, Detection, _outlined, _refine_name, as_gray
from .errors import FidlearnError, NoMarkersError, PoseError
from .markermap import MarkerMap
from .pose import Pose, estimate_pose
from .pose._inputs import _check_pose_options
from .pose._locate import chess_corners_seen

__all__ = ["MarkerTracker"]

#: Largest margin (px) searched around a marker's predicted place: beyond it a full detection is as cheap.
MAX_SEARCH_PX = 100_000.0
#: Windows covering more than this fraction of the image: a full detection is as cheap.
_MAX_WINDOW_FRACTION = 0.5
#: Window lengths are rounded up to this many pixels for the detector cache (the window's
#: size limits are then at most this many pixels' worth more lenient than the full frame's).
_LENGTH_STEP_PX = 8


class MarkerTracker:
    """Localize the camera frame after frame, detecting markers only near where they are expected.

    Parameters
    ----------
    marker_map : MarkerMap
        The world map; its dictionary is used for detection.
    camera : Camera
        The camera; fitted to the frames' size on the first frame
        (:meth:`Camera.for_image`: rescaled with a warning when only the
        resolution differs).
    refine : str, optional
        Corner refinement, as for :func:`fidlearn.detect_markers` (default its default, ``"edges"``).
    detector_params : None, dict or cv2.aruco.DetectorParameters
        OpenCV detector parameters, as for ``detect_markers(detector_params=...)``.
    full_every : int
        A full-frame detection at least every this many frames (1: every frame,
        no windows). It finds what the windows cannot: a marker that came out
        from behind something while its prediction lay elsewhere.
    search_px : float
        Fixed margin (pixels) added around each predicted marker, on top of half
        the marker's side and the predicted motion of its corners.
    **pose_options
        Passed to :func:`fidlearn.estimate_pose` (``method``, ``refine_lm``,
        ``reject_outliers``, ``corner_sigma_px``), checked here as :func:`fidlearn.locate`
        checks them.

    Raises
    ------
    FidlearnError
        A bad argument, with what to give instead (:class:`PoseError` for a pose option).

    Attributes
    ----------
    frames : int
        Frames seen since creation or :meth:`reset`.
    full_detections : int
        How many of them ran a full-frame detection.
    last_pose : Pose or None
        The pose of the last frame (None when :meth:`locate` raised for it).
    last_detections : list of Detection
        The last frame's detections (the map's markers only).
    last_full : bool
        Whether the last frame ran a full-frame detection.
    """

    def __init__(
        self,
        marker_map: MarkerMap,
        camera: Camera,
        *,
        refine: str = DEFAULT_REFINE,
        detector_params: Any = None,
        full_every: int = 30,
        search_px: float = 10.0,
        **pose_options: Any,
    ) -> None:
        if not isinstance(marker_map, MarkerMap):
            raise FidlearnError(
                "marker_map must be a fidlearn.MarkerMap (use MarkerMap.load('map.json')), "
                f"got {type(marker_map).__name__}"
            )
        if not isinstance(camera, Camera):
            raise FidlearnError(
                f"camera must be a fidlearn.Camera (use Camera.load('camera.json')), got {type(camera).__name__}"
            )
        if isinstance(full_every, bool) or not isinstance(full_every, (int, np.integer)) or full_every < 1:
            raise FidlearnError(f"full_every must be a whole number of frames >= 1, got {full_every!r}")
        if not (
            isinstance(search_px, (int, float, np.number))
            and not isinstance(search_px, bool)
            and 0 <= search_px <= MAX_SEARCH_PX  # NaN and 10**40 fail too
        ):
            raise FidlearnError(
                f"search_px must be a number of pixels >= 0 (at most {MAX_SEARCH_PX:g}), got {search_px!r:.40}"
            )
        self.marker_map = marker_map
        self.camera = camera
        self.refine = _refine_name(refine)
        self.detector_params = detector_params
        self.full_every = int(full_every)
        self.search_px = float(search_px)
        self.pose_options = _check_pose_options(
            pose_options, "MarkerTracker()", "refine, detector_params, full_every, search_px"
        )
        fields = _detector_fields(detector_params)  # checks the parameters now, not on frame 1
        fields["cornerRefinementMethod"] = _cv.corner_refine_flag("none" if self.refine == "edges" else self.refine)
        self._fields = fields
        self._inverted = bool(fields["detectInvertedMarker"])
        self._detectors: dict[tuple[int, int, int], Any] = {}
        self._index_map(marker_map, 2 * int(fields["markerBorderBits"]))
        self.reset()

    def _index_map(self, marker_map: MarkerMap, border: int) -> None:
        """The map's markers as the detectors see them: keys, world corners, normals, one group per dictionary
        ``(name, keys, cells per side)`` and its dictionary of the map's ids only."""
        keys = marker_map.ids  # a marker is (dictionary, id): its map key
        self._ids = np.empty(len(keys), dtype=object)
        self._ids[:] = keys
        self._world = np.stack([marker_map.marker_corners(i) for i in keys]) if keys else np.zeros((0, 4, 3))
        self._normals = np.stack([marker_map.normal(i) for i in keys]) if keys else np.zeros((0, 3))
        self._centres = self._world.mean(axis=1)
        # Per dictionary of the map, the map's markers only: OpenCV compares every candidate that does not decode
        # with every marker of the dictionary (most of detectMarkers' time with 1024-marker ARUCO_ORIGINAL).
        self._groups = [
            (
                name,
                [marker_map.key(i, name) for i in marker_map.ids_in(name)],
                _cv.dictionary_marker_bits(name) + border,
            )
            for name in marker_map.dictionaries
        ]
        self._dictionaries = [_cv.sub_dictionary(name, marker_map.ids_in(name)) for name in marker_map.dictionaries]

    def __repr__(self) -> str:
        return (
            f"MarkerTracker({len(self.marker_map)} markers, {' and '.join(self.marker_map.dictionaries)}, "
            f"refine={self.refine!r}, "
            f"full_every={self.full_every}; {self.frames} frames, {self.full_detections} full detections)"
        )

    def reset(self) -> None:
        """Forget the past frames: the next frame runs a full detection."""
        self.frames = 0
        self.full_detections = 0
        self.last_pose: Pose | None = None
        self.last_detections: list[Detection] = []
        self.last_full = False
        self._prev_T: np.ndarray | None = None  # T_world_camera two frames ago (for the velocity)
        self._since_full = 0
        self._size: tuple[int, int] | None = None
        self._cam: Camera | None = None

    # -- public -----------------------------------------------------------------------------
    def locate(self, image: np.ndarray) -> Pose:
        """The camera's pose in the next frame.

        A frame without a pose raises, as :func:`fidlearn.locate` does: catch
        :class:`~fidlearn.errors.NoMarkersError` (or its base
        :class:`~fidlearn.errors.FidlearnError`) to skip it. The tracker carries on:
        :attr:`last_pose` is then None and the next frame runs a full detection.

        Parameters
        ----------
        image : ndarray, shape (H, W) or (H, W, 3)
            Gray or BGR frame, pixels (see :func:`fidlearn.detection.as_gray`). A frame
            of another size than the last one starts the tracking afresh.

        Returns
        -------
        Pose
            The camera's pose in the world (mm), what :func:`fidlearn.locate` gives for
            the frame when it finds the same markers. The frame's detections (corners
            (4, 2) float64 pixels, TL, TR, BR, BL, refined as
            :func:`fidlearn.detect_markers` does) are in :attr:`last_detections`.

        Raises
        ------
        NoMarkersError
            No marker of the map is found in the frame, not even by a full-frame detection.
        PoseError
            The markers found give no pose (see :func:`fidlearn.estimate_pose`).
        ImageError
            ``image`` is not an image.
        CameraError
            The frame's aspect ratio differs from the camera's.

        Examples
        --------
        >>> import numpy as np, fidlearn
        >>> m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
        >>> tracker = MarkerTracker(m, fidlearn.Camera.from_fov(60, (640, 480)))
        >>> try:
        ...     tracker.locate(np.full((480, 640), 128, np.uint8))   # a blank wall
        ... except fidlearn.NoMarkersError as e:
        ...     print(str(e)[:22])
        no marker was detected
        """
        gray = as_gray(image, where="frame")
        pose, error = self._estimate(gray, self._detect(gray))
        if pose is None and not self.last_full:
            # the windows found too little to solve: look at the whole frame before giving up
            pose, error = self._estimate(gray, self._detect_full(gray))
        self._prev_T = None if self.last_pose is None else self.last_pose.T_world_camera
        self.last_pose = pose
        if pose is None:
            assert error is not None  # _estimate gives a pose or why not
            raise error
        return pose

    # -- internals --------------------------------------------------------------------------
    def _detect(self, gray: np.ndarray) -> list[Detection]:
        """The frame's markers: in windows around the predicted ones, or in the whole frame."""
        size = (gray.shape[1], gray.shape[0])
        if size != self._size:  # first frame, or the video changed resolution
            cam = self.camera.for_image(size)
            self.reset()
            self._size, self._cam = size, cam
        self.frames += 1
        self._since_full += 1
        predicted = self._predict() if self.last_pose is not None and self._since_full < self.full_every else None
        dets = None
        if predicted is not None:
            dets = self._detect_windows(gray, predicted)
        if dets is None:
            return self._detect_full(gray)
        self.last_full = False
        self.last_detections = dets
        return dets

    def _detect_full(self, gray: np.ndarray) -> list[Detection]:
        H, W = gray.shape
        found: list = []
        for g, (_, keys, _) in enumerate(self._groups):
            c, i, _ = _cv.detect(self._window_detector(W, H, W, H, g), gray)
            found += [(ck, keys[ik], g) for ck, ik in zip(c, i)]
        dets = self._finish(gray, found)
        self.full_detections += 1
        self._since_full = 0
        self.last_full = True
        self.last_detections = dets
        return dets

    def _finish(self, gray: np.ndarray, found: list) -> list[Detection]:
        """Check and refine the corners ``[(corners, key, group)]`` as detect_markers does (on a fisheye, as locate
        does) and sort by id."""
        out: list[Detection] = []
        fisheye = self._cam is not None and self._cam.model == "fisheye" and self.refine == "edges"
        for g, (name, _, cells) in enumerate(self._groups):
            mine = [(c, int(k)) for c, k, gk in found if gk == g]
            dets = _outlined(
                gray, [c for c, _ in mine], [k for _, k in mine], cells, self._inverted, self.refine == "edges"
            )[0]
            if fisheye and dets and self._cam is not None:
                fixed = refine_edges_fisheye(gray, np.stack([d.corners_px for d in dets]), self._cam, cells)
                dets = [dataclasses.replace(d, corners_px=f) for d, f in zip(dets, fixed)]
            out += [Detection(d.id, d.corners_px, name) for d in dets]
        if len(self._groups) > 1:
            order = {n: k for k, (n, _, _) in enumerate(self._groups)}
            out.sort(key=lambda d: (d.id, order[str(d.dictionary)]))
        return out

    def _estimate(self, gray: np.ndarray, dets: list[Detection]) -> tuple[Pose | None, FidlearnError | None]:
        """The pose from the detections, or None and why not (the options were checked when the tracker was made).

        A ChArUco board entry's chess corners join the pose as in :func:`fidlearn.locate` (a pinhole camera's).
        """
        assert self._cam is not None  # set by _detect
        chess = chess_corners_seen(gray, self.marker_map, dets) if self._cam.model != "fisheye" else None
        try:
            pose = estimate_pose(dets, self.marker_map, self._cam, board_corners=chess, **self.pose_options)
        except (NoMarkersError, PoseError) as e:  # no marker of the map, or a degenerate frame
            return None, e
        problem = outside_field(self.marker_map, pose.position_mm, pose.marker_ids)  # a field layout's mirror
        return (pose, None) if problem is None else (None, PoseError(problem))

    def _predict(self) -> dict | None:
        """The map's markers that may be in view under the predicted pose: ``{'ids': (K,), 'corners': (K, 4, 2) px,
        'motion': (K,) px}``, motion being how far the velocity moved each marker's corners; None if none is."""
        assert self.last_pose is not None  # called only after a pose was found
        assert self._cam is not None
        T_last = self.last_pose.T_world_camera
        if self._prev_T is not None:  # constant velocity: the last step once more
            step = T_last @ _inverse(self._prev_T) @ T_last
            T_pred = np.eye(4)  # what make_transform gives, without re-checking the rotation made here
            T_pred[:3, :3], T_pred[:3, 3] = _nearest_rotation(step[:3, :3]), step[:3, 3]
        else:
            T_pred = T_last
        cam = self._cam
        T_cw = _inverse(T_pred)
        eye = T_pred[:3, 3]
        pc = self._world @ T_cw[:3, :3].T + T_cw[:3, 3]  # (M, 4, 3) camera frame, mm
        facing = np.einsum("ij,ij->i", self._normals, eye - self._centres) > 0
        front = (pc[..., 2] > 10.0).all(axis=1)
        keep = facing & front
        if keep.any():
            keep[np.flatnonzero(keep)[~_near_view(cam, pc[keep])]] = False
        if not keep.any():
            return None
        sel = np.flatnonzero(keep)
        px = self._project(sel, T_cw)
        motion = np.zeros(len(sel))
        if T_pred is not T_last:  # how far the prediction moved each marker: the velocity is that uncertain
            px_last = self._project(sel, _inverse(T_last))
            motion = np.abs(px - px_last).max(axis=(1, 2))
        return {"ids": self._ids[sel], "corners": px, "motion": motion}

    def _project(self, sel: np.ndarray, T_cw: np.ndarray) -> np.ndarray:
        """The pixels (K, 4, 2) of markers ``sel`` seen from ``T_camera_world`` (a pose found or predicted, rigid
        already): :meth:`fidlearn.Camera.project`'s arithmetic, without its checks."""
        assert self._cam is not None
        pc = self._world[sel].reshape(-1, 3) @ T_cw[:3, :3].T + T_cw[:3, 3]
        return project_points(pc, self._cam.K, self._cam.dist, self._cam.model).reshape(-1, 4, 2)

    def _detect_windows(self, gray: np.ndarray, predicted: dict) -> list[Detection] | None:
        """Detect in windows around the predicted markers; None when a full detection is called for."""
        H, W = gray.shape
        corners, motion, ids = predicted["corners"], predicted["motion"], predicted["ids"]
        side = np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=2).max(axis=1)
        pad = 0.25 * side + 0.5 * motion + self.search_px
        lo = np.floor(corners.min(axis=1) - pad[:, None]).astype(int)
        hi = np.ceil(corners.max(axis=1) + pad[:, None]).astype(int) + 1
        lo = np.maximum(lo, 0)
        hi = np.minimum(hi, [W, H])
        ok = (hi > lo + 8).all(axis=1)  # some of the window is in the image
        boxes = merge_boxes([(*a, *b) for a, b in zip(lo[ok], hi[ok])])
        if sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in boxes) > _MAX_WINDOW_FRACTION * W * H:
            return None
        found: list = []
        self._search(gray, boxes, found)
        # Markers seen last frame and predicted whole and well inside the image, but not found: once more in
        # larger windows (a wrong prediction); if most are still missing, the prediction failed: a full detection.
        inside = ((corners.min(axis=1) > pad[:, None]) & (corners.max(axis=1) < [W, H] - pad[:, None])).all(axis=1)
        seen = {self.marker_map.key(d.id, d.dictionary) for d in self.last_detections}
        expected = {i for i, ins in zip(ids, inside) if ins} & seen
        missing = [k for k, i in enumerate(ids) if i in expected and all(i != f[1] for f in found)]
        if missing:
            big = side[missing] + 2.0 * motion[missing] + 3.0 * self.search_px
            lo2 = np.maximum(np.floor(corners[missing].min(axis=1) - big[:, None]).astype(int), 0)
            hi2 = np.minimum(np.ceil(corners[missing].max(axis=1) + big[:, None]).astype(int) + 1, [W, H])
            self._search(gray, merge_boxes([(*a, *b) for a, b in zip(lo2, hi2)]), found)
            if 2 * len(expected - {f[1] for f in found}) > len(expected):
                return None
        self._search_where_last_seen(gray, found)
        return self._finish(gray, found)

    def _search_where_last_seen(self, gray: np.ndarray, found: list) -> None:
        """Markers seen last frame and not found: once more where they were. A turn that stops at once leaves
        them there while the motion model carries them on, out of the picture, where no window looks."""
        H, W = gray.shape
        have = {f[1] for f in found}
        last = [d.corners_px for d in self.last_detections if self.marker_map.key(d.id, d.dictionary) not in have]
        if not last:
            return
        c = np.asarray(last, dtype=float)
        pad = np.linalg.norm(c - np.roll(c, -1, axis=1), axis=2).max(axis=1) + self.search_px
        self._search(gray, boxes_around(c, pad, W, H), found)

    def _search(self, gray: np.ndarray, boxes: list, found: list) -> None:
        """Detect in each window ``(x0, y0, x1, y1)`` with each dictionary's detector; append ``(corners (full-frame
        pixels), key, dictionary's group)`` of the markers not found yet."""
        H, W = gray.shape
        for x0, y0, x1, y1 in boxes:
            for g, (_, keys, _) in enumerate(self._groups):
                c, i, _ = _cv.detect(self._window_detector(x1 - x0, y1 - y0, W, H, g), gray[y0:y1, x0:x1])
                for ck, ik in zip(c, i):
                    ck, key = ck + [x0, y0], keys[ik]
                    if any(j == key and np.abs(cj - ck).max() < 2.0 for cj, j, _ in found):
                        continue  # the same marker in an overlapping window
                    found.append((ck, key, g))

    def _window_detector(self, w: int, h: int, W: int, H: int, group: int = 0):
        """An ArucoDetector of one of the map's dictionaries whose marker size limits, in pixels, are those of the
        full W x H frame."""
        q = max(W, H) if (w, h) == (W, H) else -(-max(w, h) // _LENGTH_STEP_PX) * _LENGTH_STEP_PX
        key = (q, max(W, H), group)
        det = self._detectors.get(key)
        if det is None:
            fields = _limits_scaled(self._fields, max(W, H), q)
            det = self._detectors[key] = cv2.aruco.ArucoDetector(
                self._dictionaries[group], _cv.make_detector_parameters(**fields)
            )
        return det


def _near_view(cam: Camera, pc: np.ndarray) -> np.ndarray:
    """Which markers (corners (K, 4, 3) in the camera frame, mm, in front of it) land within half a picture of it.

    A pinhole's by its ideal pixels (far outside the view its distortion polynomial folds back); a fisheye's by
    its own projection, which grows with the angle off the axis up to 90 degrees (its ideal pixels would run
    off to infinity there and drop the markers near the edge of the picture).
    """
    xy = (pc[..., :2] / pc[..., 2:3]).reshape(-1, 2)
    if cam.model == "fisheye":
        px = pixels_from_normalized(xy, cam.K, cam.dist, "fisheye")
    else:
        px = xy * [cam.fx, cam.fy] + [cam.cx, cam.cy]
    px = px.reshape(-1, 4, 2)
    slack = 0.5 * max(cam.width, cam.height)
    inside = (px > [-slack, -slack]) & (px < [cam.width + slack, cam.height + slack])
    return np.asarray(inside.all(axis=(1, 2)))


def _inverse(T: np.ndarray) -> np.ndarray:
    """``T``'s inverse as :func:`fidlearn.frames.invert_transform` makes it, for a ``T`` known to be rigid."""
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


def _nearest_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation matrix closest to ``R`` (removes rounding drift of a product of rotations)."""
    U, _, Vt = np.linalg.svd(R)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt
