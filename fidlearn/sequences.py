"""Poses over a run of frames: pictures, videos, a live camera; located one by one or tracked over time.

:class:`FrameLocator` gives each :class:`fidlearn.images.Frame` its pose as ``fidlearn locate``
prints it: a picture with :func:`fidlearn.locate`'s detection and :func:`fidlearn.estimate_pose`,
the frames of one video (or camera) with one :class:`fidlearn.MarkerTracker`. The camera is fitted
to each resolution once (:meth:`fidlearn.Camera.for_image`: one warning when it is rescaled, a
:class:`CameraError` naming the frame when the aspect ratio differs). A frame without a pose is
reported with the reason, not raised.

:func:`track` runs the frames' poses through one :class:`fidlearn.PoseTracker`, ``1 / fps``
seconds apart from t = 0 s, with the camera's mount on a robot and the robot's odometry when
given (``fidlearn locate --track``).

Examples
--------
>>> import fidlearn
>>> from fidlearn.images import Frame
>>> m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
>>> cam = fidlearn.Camera.from_fov(60, (640, 480))
>>> drive = fidlearn.render_trajectory(m, cam, n_frames=40, frames_to_render=range(30, 34))
>>> run = [Frame(f"drive#{k}", image, "drive", "video") for k, image in enumerate(drive.images)]
>>> [(step.tracked.status, step.located.pose.marker_ids) for step in track(run, m, cam, fps=30)]
[('started', (0, 1, 2)), ('measured', (0, 1, 2)), ('measured', (0, 1, 2)), ('measured', (0, 1, 2))]
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .camera import Camera
from .detection import Detection, detect_markers
from .errors import CameraError, NoMarkersError, OdometryRangeError, PoseError, TrackingError
from .filtering import DEFAULT_PROCESS_NOISE, PoseTracker, TrackedPose
from .images import Frame
from .io import image_size_from_header
from .markermap import MarkerMap
from .pose import Pose, estimate_pose
from .pose._inputs import _as_camera, _as_map
from .pose._locate import _detect_map_markers
from .ros import Odometry
from .tracking import MarkerTracker

__all__ = ["NO_MARKER", "FrameLocator", "FramePose", "TrackStep", "check_picture_sizes", "track"]

#: The reason given for a frame in which no marker of the map is found.
NO_MARKER = "no known marker"
#: How much of a picture is read to find its size in its header (a JPEG's EXIF block comes first).
_HEADER_BYTES = 256 * 1024


@dataclass
class FramePose:
    """One frame's pose, the markers found in it, and why there is no pose when there is none.

    Attributes
    ----------
    frame : fidlearn.images.Frame
        The frame.
    camera : Camera
        The camera fitted to the frame's resolution.
    pose : Pose or None
        The camera's pose in the world; None when the frame gives none.
    detections : list of Detection
        The markers to draw: those the pose was estimated from or, without a pose, every marker of
        the map's dictionary in view (so a frame can say which ids it saw).
    reason : str
        ``""`` with a pose; :data:`NO_MARKER` or ``"no pose: ..."`` (the :class:`PoseError`'s
        message on one line) without.
    """

    frame: Frame
    camera: Camera
    pose: Pose | None
    detections: list[Detection] = field(default_factory=list)
    reason: str = ""

    @property
    def seen_ids(self) -> list[int]:
        """The ids detected in the frame, sorted, each once."""
        return sorted({d.id for d in self.detections})


class FrameLocator:
    """The camera's pose in frame after frame: pictures one by one, each video with a MarkerTracker.

    Parameters
    ----------
    marker_map : MarkerMap or path
        The world map (a path is read with :meth:`MarkerMap.load`).
    camera : Camera or path
        The camera, fitted to each frame's resolution once (a path is read with :meth:`Camera.load`).
    refine : str, optional
        Corner refinement (see :func:`fidlearn.detect_markers`); None for its default.

    Raises
    ------
    FidlearnError
        A map or camera that is not one.

    Examples
    --------
    >>> import fidlearn
    >>> from fidlearn.images import Frame, load_image
    >>> path = fidlearn.data_path("scenes", "scene_00.png")
    >>> locator = FrameLocator(fidlearn.data_path("world_map.json"), fidlearn.data_path("scenes", "camera.json"))
    >>> located = locator.locate(Frame("scene_00.png", load_image(path), str(path), "image"))
    >>> located.pose.marker_ids, located.reason
    ((0, 1, 2), '')
    """

    def __init__(self, marker_map: MarkerMap | str | os.PathLike, camera: Camera | str | os.PathLike, *, refine=None):
        self.marker_map = _as_map(marker_map)
        self.camera = _as_camera(camera)
        self.refine = refine
        self._cameras: dict[tuple[int, int], Camera] = {}
        self._trackers: dict[tuple[str, tuple[int, int]], MarkerTracker] = {}

    def __repr__(self) -> str:
        return f"FrameLocator({len(self.marker_map)} markers, camera {self.camera.width}x{self.camera.height})"

    def camera_for(self, frame: Frame) -> Camera:
        """The camera fitted to the frame's resolution (rescaled, with one warning, once per resolution).

        Parameters
        ----------
        frame : fidlearn.images.Frame
            The frame.

        Returns
        -------
        Camera
            The camera for the frame's width and height.

        Raises
        ------
        CameraError
            The frame has another aspect ratio; the message starts with the frame's name.
        """
        size = (frame.image.shape[1], frame.image.shape[0])
        if size not in self._cameras:
            try:
                self._cameras[size] = self.camera.for_image(size)
            except CameraError as exc:  # say which picture, in a folder of many
                raise CameraError(f"{frame.name}: {exc}") from None
        return self._cameras[size]

    def _tracker(self, frame: Frame, cam: Camera) -> MarkerTracker:
        key = (frame.source, (cam.width, cam.height))
        if key not in self._trackers:
            options = {"refine": self.refine} if self.refine is not None else {}
            self._trackers[key] = MarkerTracker(self.marker_map, cam, **options)
        return self._trackers[key]

    def locate(self, frame: Frame) -> FramePose:
        """The frame's pose, or why it has none.

        A picture is detected once, as :func:`fidlearn.locate` does (the whole dictionary when none
        of the map's markers is in view); a video's or camera's frame goes to the source's
        :class:`fidlearn.MarkerTracker`.

        Parameters
        ----------
        frame : fidlearn.images.Frame
            The frame (``kind`` ``"image"``, ``"video"`` or ``"camera"``).

        Returns
        -------
        FramePose
            The pose (None without one), the detections and the reason.

        Raises
        ------
        CameraError
            The frame has another aspect ratio than the camera.
        """
        cam = self.camera_for(frame)
        tracker = self._tracker(frame, cam) if frame.kind != "image" else None
        reason, detections = NO_MARKER, []
        try:
            if tracker is None:
                detections = _detect_map_markers(frame.image, self.marker_map, self.refine, None, True)
                pose = estimate_pose(detections, self.marker_map, cam)
            else:
                pose = tracker.locate(frame.image)
                detections = tracker.last_detections
        except NoMarkersError:
            pose = None
        except PoseError as exc:  # a degenerate view: report the frame, keep going
            pose, reason = None, f"no pose: {' '.join(str(exc).split())}"
        if pose is None and tracker is not None:  # what is in view, from the whole dictionary
            options = {"refine": self.refine} if self.refine is not None else {}
            names = self.marker_map.dictionaries
            detections = detect_markers(frame.image, names if len(names) > 1 else names[0], **options)
        return FramePose(frame, cam, pose, list(detections), "" if pose is not None else reason)


def check_picture_sizes(items: Sequence[tuple[str, Path]], camera: Camera, max_pixels: float) -> None:
    """Refuse, before any frame is read, pictures that the camera cannot fit (another aspect ratio).

    Each picture's size is read from its header; a folder that mixes sizes is refused as a
    whole, before the rescaling warning of its first pictures.

    Parameters
    ----------
    items : sequence of (str, Path)
        ``("image" | "video", path)`` as :func:`fidlearn.images.expand_inputs` gives them
        (videos are checked when read).
    camera : Camera
        The camera.
    max_pixels : float
        Larger pictures are left to :func:`fidlearn.images.load_image`, which refuses them as such.

    Raises
    ------
    CameraError
        The first picture whose size the camera cannot be rescaled to, named.
    """
    seen: set[tuple[int, int]] = set()
    for kind, path in items:
        if kind != "image":
            continue
        size = _header_size(path)
        if min(size) <= 0 or size[0] * size[1] > max_pixels or size in seen:
            continue
        seen.add(size)
        try:
            camera.for_image(size, warn=False)
        except CameraError as exc:
            raise CameraError(f"{path.name}: {exc}") from None


def _header_size(path: Path) -> tuple[int, int]:
    """A picture's (width, height) from its header; (-1, -1) when it cannot be read or says none."""
    try:
        with open(path, "rb") as f:
            data = f.read(4096)
            head = image_size_from_header(data)
            if head is not None and head[1] < 0:  # a JPEG whose EXIF block comes before its size
                head = image_size_from_header(data + f.read(_HEADER_BYTES))
    except OSError:
        return (-1, -1)  # reading the picture says what is wrong with it
    return head[1:] if head is not None else (-1, -1)


@dataclass
class TrackStep:
    """One frame of :func:`track`: its own pose and the track's.

    Attributes
    ----------
    located : FramePose
        The frame's own pose (as :meth:`FrameLocator.locate` gives it).
    t_s : float
        The frame's time, seconds (``index / fps``, or the time given for it).
    tracked : TrackedPose or None
        The tracked pose at ``t_s``; None before the first frame with a pose (nothing to track yet).
    """

    located: FramePose
    t_s: float
    tracked: TrackedPose | None


def track(
    frames: Iterable[Frame],
    marker_map: MarkerMap | str | os.PathLike,
    camera: Camera | str | os.PathLike,
    *,
    fps: float = 30.0,
    refine: str | None = None,
    T_camera_base: Any = None,
    odometry: Odometry | None = None,
    process_noise: tuple[float, float] | None = DEFAULT_PROCESS_NOISE,
    times: Iterable[float] | None = None,
) -> Iterator[TrackStep]:
    """Every frame's pose through one :class:`fidlearn.PoseTracker`: frames in, tracked poses out.

    The frames are one run, ``1 / fps`` seconds apart from t = 0 s, in the order given. Each frame's
    pose is :meth:`FrameLocator.locate`'s; the tracker takes the agreeing one of an ambiguous pair,
    rejects a pose beyond its gate and bridges frames without a pose (with the odometry when given).

    Parameters
    ----------
    frames : iterable of fidlearn.images.Frame
        The frames (e.g. :func:`fidlearn.images.read_frames`), read one at a time.
    marker_map : MarkerMap or path
        The world map.
    camera : Camera or path
        The camera (fitted to each frame's resolution).
    fps : float
        Frames per second of the run.
    refine : str, optional
        Corner refinement (see :func:`fidlearn.detect_markers`).
    T_camera_base : array_like, shape (4, 4), optional
        The camera's mount on the robot (mm; :func:`fidlearn.ros.read_mount_json` reads one): the
        tracked poses then also give the base's pose.
    odometry : fidlearn.ros.Odometry, optional
        The robot base's odometry on the frames' clock (:func:`fidlearn.ros.read_odometry_csv`): the
        motion between frames replaces the constant-velocity prediction.
    process_noise : (float, float) or None
        The tracker's motion noise (see :class:`fidlearn.PoseTracker`); None (the default) learns it
        from the frames.
    times : iterable of float, optional
        Each frame's time in seconds, increasing (e.g. a bag's header stamps, from 0 at the first
        frame), taken one per frame as the frames are read; instead of ``index / fps``.

    Returns
    -------
    iterator of TrackStep
        One step per frame, made as the frames are read. The arguments are checked at the call,
        before any frame is read.

    Raises
    ------
    TrackingError
        ``fps`` is not a positive number, ``frames`` is not iterable (an item that is not a Frame,
        or a time that is not after the previous one, raises when it is reached), ``odometry`` is
        not an Odometry, a bad ``process_noise``.
    FidlearnError
        A map, camera or mount that is not one (each its own error).
    """
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not (math.isfinite(fps) and fps > 0):
        raise TrackingError(f"fps must be a positive number of frames per second, got {fps!r}")
    if odometry is not None and not isinstance(odometry, Odometry):
        raise TrackingError(
            f"odometry must be a fidlearn.ros.Odometry (read a CSV with fidlearn.ros.read_odometry_csv), "
            f"got {type(odometry).__name__}"
        )
    try:
        frames = iter(frames)
    except TypeError:
        raise TrackingError(
            f"frames must be an iterable of fidlearn.images.Frame, got {type(frames).__name__}"
        ) from None
    locator = FrameLocator(marker_map, camera, refine=refine)
    options = {"refine": refine} if refine is not None else {}  # checked here, before any frame
    tracker = PoseTracker(
        locator.marker_map, locator.camera, process_noise=process_noise, T_camera_base=T_camera_base, **options
    )
    return _steps(frames, locator, tracker, float(fps), odometry, times)


def _timed(frames: Iterator, fps: float, times) -> Iterator[tuple[Any, float]]:
    """``(frame, t_s)``: the frame read first, then its time (a time may be known once its frame is read)."""
    if times is None:
        yield from ((frame, n / fps) for n, frame in enumerate(frames))
        return
    clock = iter(times)
    last = -math.inf
    for n, frame in enumerate(frames):
        t = next(clock, None)
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
            raise TrackingError(f"frame {n} has no time in seconds (times gave {t!r:.40}); give one per frame")
        if not t > last:
            raise TrackingError(
                f"frame {n}'s time {t:.9f} s is not after the previous frame's {last:.9f} s; "
                "the frames must be in time order, each at its own time"
            )
        last = float(t)
        yield frame, last


def _steps(frames, locator: FrameLocator, tracker: PoseTracker, fps: float, odometry, times) -> Iterator[TrackStep]:
    prev, first, used, n = 0.0, 0.0, 0, -1
    for n, (frame, t_s) in enumerate(_timed(frames, fps, times)):
        if not isinstance(frame, Frame):
            raise TrackingError(
                f"frame {n} is a {type(frame).__name__}, not a fidlearn.images.Frame (read files with "
                "fidlearn.images.read_frames, or wrap an image: Frame(name, image, source, kind))"
            )
        if n == 0:
            first = t_s
        located = locator.locate(frame)
        odo = None
        if odometry is not None and n > 0:
            with contextlib.suppress(OdometryRangeError):  # a frame beyond the odometry: the motion model alone
                odo = odometry.between(prev, t_s)
                used += 1
        out = None
        if located.pose is not None or tracker.started:  # before the first pose there is nothing to track
            out = tracker.update(located.pose, t_s, odometry=odo)
        prev = t_s
        yield TrackStep(located, t_s, out)
    if odometry is not None and n > 0 and not used:  # a clock of another origin (Unix time): nothing was used
        ts = odometry.times_s
        raise TrackingError(
            f"the odometry's samples run from {ts[0]:g} to {ts[-1]:g} s and the frames from {first:g} to {prev:g} s: "
            "no frame had odometry; record it over the video, or start the video's clock at the odometry's"
        )
