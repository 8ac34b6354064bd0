"""The answer of the tracker for one instant: :class:`TrackedPose`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import TrackingError
from ..pose import Pose
from ..pose._result import _PoseReadouts

#: What a TrackedPose can be: its ``status``.
STATUSES = ("started", "measured", "rejected", "predicted", "odometry", "restarted", "smoothed")


@dataclass(eq=False, repr=False)
class TrackedPose(_PoseReadouts):
    """The camera's (and the robot's) pose at one instant, as the tracker or the smoother gives it.

    Attributes
    ----------
    t_s : float
        The time, s (the caller's clock).
    T_world_camera : ndarray, shape (4, 4)
        The camera's pose in the world, mm (OpenCV camera frame: x right, y down, z forward).
    covariance : ndarray, shape (6, 6)
        Covariance of the camera pose, in :attr:`fidlearn.Pose.covariance`'s coordinates:
        ``[dtheta (rad, world axes, left of R_world_camera), camera centre (mm, world)]``.
    status : str
        ``"measured"`` (a frame's pose corrected the track), ``"started"`` (the first pose),
        ``"restarted"`` (the track started afresh after ``MAX_REJECTIONS`` rejected frames in a row),
        ``"rejected"`` (the frame's pose disagreed with the track beyond the gate: the output is the
        prediction), ``"predicted"`` (no pose in the frame: the motion model), ``"odometry"`` (no pose:
        the odometry carried the track), ``"smoothed"`` (from :func:`smooth`).
    flip_resolved : bool
        The frame was ambiguous and its ``alternative`` (the other planar solution) agreed with the
        track, not the pose :func:`fidlearn.estimate_pose` ranked first: the flip was undone.
    reason : str
        Why the frame's pose was not used (rejected, no marker, no pose), else ``""``.
    mahalanobis2 : float or None
        Squared Mahalanobis distance (6 degrees of freedom) of the chosen measurement from the
        prediction, the NIS, None when there was none. With the learnt noise it is read with the share of
        the poses' covariance that varies from frame to frame (:class:`PoseTracker`); the gate compares
        the distance with the covariance as given.
    pose : Pose or None
        The frame's measurement (the chosen solution), None when there was none.
    T_world_base : ndarray, shape (4, 4) or None
        The robot base's pose (mm, world) when the tracker knows the mount (``T_camera_base``).
    base_covariance : ndarray, shape (6, 6) or None
        Its covariance, ``[dtheta (rad, world axes), base origin (mm, world)]``.
    velocity_mm_s : ndarray, shape (3,)
        The camera centre's velocity, mm/s, world axes.
    angular_velocity_rad_s : ndarray, shape (3,)
        The camera's angular velocity, rad/s, world axes.
    odometry_scale : float
        What the odometry's translations are multiplied by to give the base's true motion, as learnt
        from the poses so far (1.0 before any odometry: e.g. 0.97 when the wheels report 3 % too far).
    odometry_scale_std : float
        Its standard deviation (``ODOMETRY_SCALE_STD`` = 0.05 until odometry and poses have met).
    process_noise : (float, float) or None
        The process noise in force after this step, ``(q_lin mm/s^2, q_ang rad/s^2)`` per sqrt(Hz): the
        tracker's fixed one, or what it has learnt from the frames so far (``process_noise=None``).
    """

    t_s: float
    T_world_camera: np.ndarray
    covariance: np.ndarray
    status: str
    flip_resolved: bool = False
    reason: str = ""
    mahalanobis2: float | None = None
    pose: Pose | None = None
    T_world_base: np.ndarray | None = None
    base_covariance: np.ndarray | None = None
    velocity_mm_s: np.ndarray | None = None
    angular_velocity_rad_s: np.ndarray | None = None
    odometry_scale: float = 1.0
    odometry_scale_std: float | None = None
    process_noise: tuple[float, float] | None = None

    _error = TrackingError

    @property
    def rejected(self) -> bool:
        """True when the frame's pose was rejected (see :attr:`reason`)."""
        return self.status == "rejected"

    @property
    def measured(self) -> bool:
        """True when a frame's pose corrected (or started) the track at this instant."""
        return self.status in ("measured", "started", "restarted")

    def __repr__(self) -> str:
        parts = [f"t_s={self.t_s:.3f}", self.status, *self._readout_parts()]
        if self.flip_resolved:
            parts.append("flip resolved")
        if self.reason:
            parts.append(f"reason={self.reason!r}")
        if self.T_world_base is not None:
            bx, by, bz = self.T_world_base[:3, 3]
            parts.append(f"base_mm=[{bx:.1f}, {by:.1f}, {bz:.1f}]")
        return "TrackedPose(" + ", ".join(parts) + ")"


__all__ = ["TrackedPose", "STATUSES"]
