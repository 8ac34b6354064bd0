"""The answer of the tracker for one instant: :class:`TrackedPose`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import frames
from ..pose import Pose
from ..pose._stats import _chi2_3_quantile

#: What a TrackedPose can be: its ``status``.
STATUSES = ("started", "measured", "rejected", "predicted", "odometry", "restarted", "smoothed")


@dataclass(eq=False, repr=False)
class TrackedPose:
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
        prediction, None when there was none.
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

    @property
    def rejected(self) -> bool:
        """True when the frame's pose was rejected (see :attr:`reason`)."""
        return self.status == "rejected"

    @property
    def measured(self) -> bool:
        """True when a frame's pose corrected (or started) the track at this instant."""
        return self.status in ("measured", "started", "restarted")

    @property
    def position_mm(self) -> np.ndarray:
        """Camera centre (3,), mm, world."""
        return self.T_world_camera[:3, 3].copy()

    @property
    def rpy_deg(self) -> np.ndarray:
        """Roll, pitch, yaw (3,), degrees, of ``R_world_camera`` (fixed world axes, as :attr:`Pose.rpy_deg`)."""
        return frames.rpy_deg_from_rotation(self.T_world_camera[:3, :3])

    @property
    def position_std_mm(self) -> np.ndarray:
        """Standard deviation (3,) of the camera centre along world X, Y, Z, mm."""
        return np.sqrt(np.maximum(np.diag(self.covariance)[3:], 0.0))

    def position_ellipsoid_contains(self, point_mm, probability: float = 0.95) -> bool:
        """Whether a world point lies inside the camera centre's confidence ellipsoid.

        Parameters
        ----------
        point_mm : array-like, shape (3,)
            A point in the world frame, mm (e.g. the true camera position).
        probability : float
            The ellipsoid's confidence level, between 0 and 1 (exclusive).

        Returns
        -------
        bool
            True when the squared Mahalanobis distance of the point from :attr:`position_mm`
            (under ``covariance[3:, 3:]``) is at most the chi-square(3) quantile of ``probability``.

        Raises
        ------
        TrackingError
            ``probability`` is not between 0 and 1.

        Examples
        --------
        >>> import numpy as np
        >>> p = TrackedPose(0.0, np.eye(4), np.diag([1e-6] * 3 + [4.0] * 3), "measured")
        >>> p.position_ellipsoid_contains([0, 0, 5.0]), p.position_ellipsoid_contains([0, 0, 6.0])
        (True, False)
        """
        from ..errors import TrackingError

        if not (isinstance(probability, (int, float)) and 0.0 < probability < 1.0):
            raise TrackingError(f"probability must be between 0 and 1 (exclusive), got {probability!r}")
        d = np.asarray(point_mm, dtype=float).reshape(3) - self.position_mm
        return float(d @ np.linalg.solve(self.covariance[3:, 3:], d)) <= _chi2_3_quantile(probability)

    def __repr__(self) -> str:
        x, y, z = self.position_mm
        r, p, yw = self.rpy_deg
        sx, sy, sz = self.position_std_mm
        parts = [
            f"t_s={self.t_s:.3f}",
            self.status,
            f"position_mm=[{x:.1f}, {y:.1f}, {z:.1f}]",
            f"rpy_deg=[{r:.1f}, {p:.1f}, {yw:.1f}]",
            f"std_mm=[{sx:.1f}, {sy:.1f}, {sz:.1f}]",
        ]
        if self.flip_resolved:
            parts.append("flip resolved")
        if self.reason:
            parts.append(f"reason={self.reason!r}")
        if self.T_world_base is not None:
            bx, by, bz = self.T_world_base[:3, 3]
            parts.append(f"base_mm=[{bx:.1f}, {by:.1f}, {bz:.1f}]")
        return "TrackedPose(" + ", ".join(parts) + ")"


__all__ = ["TrackedPose", "STATUSES"]
