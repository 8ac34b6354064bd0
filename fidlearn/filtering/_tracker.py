""":class:`PoseTracker`: the camera's (or the robot's) pose over time, from frames, detections or poses."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..camera import Camera
from ..detection import Detection
from ..errors import NoMarkersError, PoseError, TrackingError
from ..markermap import MarkerMap
from ..pose import Pose, estimate_pose
from ..tracking import MarkerTracker
from . import _filter as kf
from ._adapt import nis_band
from ._result import TrackedPose
from ._track import DEFAULT_PROCESS_NOISE, _Track, check_time, predict_shared, shared_fade


class PoseTracker:
    """A Kalman filter on the camera's pose over time: no flips, less jitter, gaps bridged.

    Each frame's pose (:func:`fidlearn.estimate_pose`, with its 6x6 covariance) corrects a
    constant-velocity prediction of the camera's pose, an error-state (manifold) Kalman filter:
    the rotation is corrected as ``exp(dtheta) R``, never by averaging rotation vectors. When a
    frame is ambiguous (a planar target far away or face-on), both planar solutions are compared
    with the prediction (squared Mahalanobis distance) and the one that agrees is used, so a flip
    never reaches the output (with the frame's covariance, which reaches the other solution, widened
    by ``AMBIGUOUS_INFLATION`` = 2: near the flip the linearised covariance is too small; a pose from
    one marker is widened alike, flagged or not).
    A pose further from the prediction than the chi-square gate
    (``GATE_PROBABILITY`` = 0.999, 6 degrees of freedom: 22.46) is rejected and the output says
    so; after ``MAX_REJECTIONS`` (5) rejections in a row the track restarts from the frame's
    pose. A frame without a pose is bridged by the motion model, or by the odometry when given. The
    odometry's scale (wheels a few percent larger or smaller than their nominal size) is learnt from
    the poses as part of the state (:attr:`TrackedPose.odometry_scale`), so a gap is bridged with
    the corrected odometry and its ellipsoid grows as the scale's uncertainty says.

    The motion noise is learnt from the frames by default (:mod:`fidlearn.filtering._adapt`): the
    innovations of consecutive frames, whitened, are uncorrelated when the process noise is right,
    point the same way when it is too small (the track lags) and opposite ways when it is too large
    (the track follows each frame's noise); the process noise is raised or lowered accordingly, frame
    by frame, between a floor (a parked robot stays smooth) and a ceiling; only poses from several
    markers that are not ambiguous teach it, and before any other frame it is taken no lower than
    ``PROCESS_NOISE_START`` (what was learnt need not hold where the frames cannot check it). A frame
    that only a sudden manoeuvre explains (beyond the 0.99 quantile) raises that step's process noise
    until it fits, so a sudden turn is followed at once. The poses' covariance is read as a part that varies
    from frame to frame, whose share the NIS tells (learnt as the track runs), and a part shared with the
    frames around it (a marker's shift, the calibration, a bias that changes only as the view does), which
    the track cannot average away and keeps in its covariance: :meth:`consistency` says how the track's NIS
    compares with its 95 % band. With a fixed ``process_noise`` the poses' covariances are taken as given.

    Parameters
    ----------
    marker_map : MarkerMap
        The world map (mm).
    camera : Camera
        The camera (fitted to each frame's size as :class:`fidlearn.MarkerTracker` does).
    process_noise : (float, float) or None
        None (the default): learnt from the frames, as above (:attr:`TrackedPose.process_noise` says
        what it is at each frame). Two numbers: a fixed white acceleration of the motion model,
        linear (mm/s^2 per sqrt(Hz)) and angular (rad/s^2 per sqrt(Hz)); the velocity's standard
        deviation grows by this much in one second. Larger follows faster motion with less smoothing;
        the poses' covariances are then taken as they are.
    T_camera_base : array_like, shape (4, 4), optional
        The mount: the robot base's frame in the camera frame (mm; ``p_camera = T_camera_base @
        p_base``). With it every :class:`TrackedPose` also gives ``T_world_base`` and its
        covariance, and odometry is read as the base's motion.
    **pose_options
        Passed to :func:`fidlearn.estimate_pose` (``method``, ``corner_sigma_px``, ...) and, for
        images, the :class:`fidlearn.MarkerTracker` options (``refine``, ``detector_params``, ...).

    Raises
    ------
    FidlearnError
        A map or camera that is not one, a bad option (:class:`TrackingError` for
        ``process_noise``, :class:`TransformError` for a mount that is not a rigid transform).

    Examples
    --------
    A camera standing still 0.7 m in front of the seed's wall, its corners with 0.3 px of noise
    (one frame alone is about 8 mm off):

    >>> import numpy as np, fidlearn
    >>> from fidlearn.detection import Detection
    >>> m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
    >>> cam = fidlearn.Camera.from_fov(60, (640, 480))
    >>> T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [700, 150, 250])
    >>> rng = np.random.default_rng(0)
    >>> tracker = PoseTracker(m, cam, process_noise=(1, 0.001), corner_sigma_px=0.3)
    >>> for k in range(90):
    ...     dets = [Detection(i, cam.project(c, T) + rng.normal(0, 0.3, (4, 2))) for i, c in m.corners().items()]
    ...     out = tracker.update(dets, k / 30)
    >>> out.status, bool(np.linalg.norm(out.position_mm - [700, 150, 250]) < 3.0)
    ('measured', True)
    """

    def __init__(
        self,
        marker_map: MarkerMap,
        camera: Camera,
        *,
        process_noise: tuple[float, float] | None = DEFAULT_PROCESS_NOISE,
        T_camera_base: Any = None,
        **pose_options: Any,
    ) -> None:
        self._detector = MarkerTracker(marker_map, camera, **pose_options)  # checks the map, camera and options
        self.marker_map = marker_map
        self.camera = camera
        self.pose_options = {k: v for k, v in pose_options.items() if k in self._detector.pose_options}
        self._track = _Track(process_noise, T_camera_base)
        self.process_noise = self._track.fixed
        self.T_camera_base = self._track.T_camera_base
        self.last: TrackedPose | None = None

    def __repr__(self) -> str:
        state = "not started" if self.last is None else f"last {self.last.status} at t_s={self.last.t_s:.3f}"
        mount = ", with a mount" if self.T_camera_base is not None else ""
        return f"PoseTracker({len(self.marker_map)} markers, process_noise={self.process_noise}{mount}; {state})"

    @property
    def started(self) -> bool:
        """True once a frame gave a pose (before that, :meth:`predict` has nothing to predict)."""
        return self._track.state is not None

    def reset(self) -> None:
        """Forget the track: the next frame with a pose starts it afresh."""
        self._track = _Track(self.process_noise, self.T_camera_base)
        self._detector.reset()
        self.last = None

    def update(self, image_or_detections, t_s: float, odometry=None) -> TrackedPose:
        """Take one frame: predict to ``t_s``, correct with the frame's pose when it agrees.

        Parameters
        ----------
        image_or_detections : ndarray, list of Detection, Pose or None
            A frame (gray or BGR, pixels), its detections, its pose (already estimated, e.g. by
            :func:`fidlearn.locate`), or None for a frame that gave nothing (dropped).
        t_s : float
            The frame's time, seconds, never before the last frame's.
        odometry : (ndarray (4, 4), ndarray (6, 6)), optional
            The base's motion since the last frame ``T_prev_curr`` (mm; the camera's own motion
            without a mount) and its covariance as a right perturbation ``[rotation (rad),
            translation (mm)]`` in the current base frame. With it, the motion replaces the
            constant-velocity prediction for this step.

        Returns
        -------
        TrackedPose
            The pose at ``t_s`` with its covariance and what happened (``status``,
            ``flip_resolved``, ``rejected``, ``reason``).

        Raises
        ------
        TrackingError
            ``t_s`` before the last frame's or not a number, malformed odometry, an input that is not
            a frame, detections or a pose, or no pose yet (the first frames had no marker).
        ImageError
            The frame is not an image.
        """
        pose, why = self._measure(image_or_detections)
        self.last = self._track.step(pose, t_s, odometry, why)
        return self.last

    def consistency(self) -> dict[str, Any]:
        """How well the track's predictions agree with the frames so far: the mean NIS and its 95 % band.

        The NIS of a frame is its :attr:`TrackedPose.mahalanobis2` (chi-square with 6 degrees of freedom
        when the track's noise is right); over ``n`` frames its mean lies in the band 95 % of the time.
        Below the band the track is more cautious than it needs to be, above it overconfident (or the
        frames' covariances are too small).

        Returns
        -------
        dict
            ``frames`` (measured frames, the start and rejected frames not counted), ``mean_nis``
            (NaN for none), ``band`` (low, high) and ``consistent`` (the mean inside the band), with
            and the ``process_noise`` in force now.

        Examples
        --------
        >>> import fidlearn
        >>> m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
        >>> PoseTracker(m, fidlearn.Camera.from_fov(60, (640, 480))).consistency()["frames"]
        0

        Over 100 frames the band is 5.34 to 6.70.
        """
        n = self._track.nis_count
        mean = self._track.nis_sum / n if n else float("nan")
        lo, hi = nis_band(n)
        return {
            "frames": n,
            "mean_nis": mean,
            "band": (lo, hi),
            "consistent": bool(lo <= mean <= hi),
            "process_noise": self._track.q,
        }

    def predict(self, t_s: float) -> TrackedPose:
        """The pose expected at ``t_s`` from the motion model; the track itself does not change.

        Parameters
        ----------
        t_s : float
            A time, seconds, not before the last frame's.

        Returns
        -------
        TrackedPose
            Status ``"predicted"``, with the grown covariance.

        Raises
        ------
        TrackingError
            No frame has given a pose yet, or ``t_s`` is before the last frame's.
        """
        if self._track.state is None:
            raise TrackingError("nothing to predict: no frame has given a pose yet; call update() with frames first")
        t = check_time(t_s, self._track.state.t)
        state, F = kf.predict_constant_velocity(self._track.state, t, *self._track.q)
        if self._track.learner is None:
            return self._track.output(state, "predicted")
        fade = shared_fade(t - self._track.state.t)
        shared, _ = predict_shared(self._track.shared_cov, self._track.shared_cross, F, fade)
        return self._track.output(state, "predicted", shared=shared[:6, :6])

    def _measure(self, item) -> tuple[Pose | None, str]:
        """The frame's pose (None when it has none) and why not."""
        if item is None:
            return None, "no frame"
        if isinstance(item, Pose):
            return item, ""
        try:
            if isinstance(item, np.ndarray):
                return self._detector.locate(item), ""
            if isinstance(item, (list, tuple)) and all(isinstance(d, Detection) for d in item):
                return estimate_pose(list(item), self.marker_map, self.camera, **self.pose_options), ""
        except NoMarkersError:
            return None, "no marker of the map in the frame"
        except PoseError as exc:
            return None, f"no pose: {' '.join(str(exc).split())}"
        raise TrackingError(
            f"update() takes a frame (ndarray), a list of Detection, a Pose or None, got {type(item).__name__}"
        )
