"""The result: :class:`Pose`, the camera's pose in the world with its uncertainty, and its ``repr``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import KW_ONLY, InitVar, dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .. import frames
from ..errors import PoseError
from ._stats import _chi2_3_quantile

__all__ = ["Pose"]


class _PoseReadouts:
    """What :class:`Pose` and :class:`fidlearn.filtering.TrackedPose` read off ``T_world_camera`` (4, 4, mm)
    and ``covariance`` (6, 6, ``[dtheta (rad), camera centre (mm)]`` in world axes, or None)."""

    __slots__ = ()

    if TYPE_CHECKING:  # the fields of the classes that read them off
        T_world_camera: np.ndarray
        covariance: np.ndarray | None

    #: The error a bad argument raises (the owning package's own).
    _error: type = PoseError

    @property
    def position_mm(self) -> np.ndarray:
        """Camera centre (3,) in world coordinates, mm."""
        return self.T_world_camera[:3, 3].copy()

    @property
    def rpy_deg(self) -> np.ndarray:
        """Roll, pitch, yaw (3,) in degrees of the camera's orientation in the world (``R_world_camera``,
        fixed world axes)."""
        return frames.rpy_deg_from_rotation(self.T_world_camera[:3, :3])

    @property
    def position_std_mm(self) -> np.ndarray:
        """Standard deviation (3,) of the camera position along world X, Y, Z, mm (NaN without a covariance)."""
        if self.covariance is None:
            return np.full(3, np.nan)
        return np.sqrt(np.maximum(np.diag(self.covariance)[3:], 0.0))

    def _readout_parts(self) -> list[str]:
        """The position, roll-pitch-yaw and position standard deviation as ``repr`` shows them."""
        x, y, z = self.position_mm
        r, p, yw = self.rpy_deg
        sx, sy, sz = self.position_std_mm
        return [
            f"position_mm=[{x:.1f}, {y:.1f}, {z:.1f}]",
            f"rpy_deg=[{r:.1f}, {p:.1f}, {yw:.1f}]",
            f"std_mm=[{sx:.1f}, {sy:.1f}, {sz:.1f}]",
        ]

    def position_ellipsoid_contains(self, point_mm: np.ndarray, probability: float = 0.95) -> bool:
        """Whether a world point lies inside the camera position's confidence ellipsoid.

        Parameters
        ----------
        point_mm : array-like, shape (3,)
            A point in the world frame, mm (e.g. the true camera position).
        probability : float
            The ellipsoid's confidence level, between 0 and 1 (exclusive).

        Returns
        -------
        bool
            True when the squared Mahalanobis distance of the point from
            :attr:`position_mm` (under ``covariance[3:, 3:]``) is at most the
            chi-square(3) quantile of ``probability``; False when the covariance is None.

        Raises
        ------
        PoseError
            ``probability`` is not between 0 and 1 (:class:`TrackingError` for a ``TrackedPose``).

        Examples
        --------
        >>> import numpy as np
        >>> pose = Pose(np.eye(4), (0,), {}, 0.1, np.diag([1e-6, 1e-6, 1e-6, 4.0, 4.0, 4.0]), 0.1)
        >>> pose.position_ellipsoid_contains([0.0, 0.0, 5.0]), pose.position_ellipsoid_contains([0.0, 0.0, 6.0])
        (True, False)
        """
        if not (isinstance(probability, (int, float)) and 0.0 < probability < 1.0):
            raise self._error(f"probability must be between 0 and 1 (exclusive), got {probability!r}")
        try:
            point = np.asarray(point_mm, dtype=float).reshape(3)
        except (TypeError, ValueError, OverflowError):
            point = np.full(3, np.nan)
        if not np.isfinite(point).all():
            raise self._error(f"point_mm must be 3 finite numbers (x, y, z in mm), got {point_mm!r:.60}")
        if self.covariance is None:
            return False
        d = point - self.position_mm
        return float(d @ np.linalg.solve(self.covariance[3:, 3:], d)) <= _chi2_3_quantile(probability)


@dataclass(slots=True, eq=False, repr=False)
class Pose(_PoseReadouts):
    """The camera's pose in the world, with its quality.

    Attributes
    ----------
    T_world_camera : ndarray, shape (4, 4)
        The camera's pose in the world (mm): ``p_world = T_world_camera @ p_camera``.
    marker_ids : tuple of int
        The markers the pose was computed from.
    residuals_px : dict of int to ndarray (4, 2)
        Per marker: observed minus reprojected corners (px), TL, TR, BR, BL.
        Rejected markers are listed too (their residual under this pose), but for a fisheye's markers past 90
        degrees off its axis, which have no undistorted corners.
    reprojection_rms_px : float
        RMS over the used corners of the residual length (px; on a fisheye camera in the picture's
        own pixels, while ``residuals_px`` are in the undistorted ones),
        ``sqrt(sum |r|^2 / N)`` for N corners (``cv2.solvePnPGeneric``
        reports the RMS per coordinate, ``sqrt(sum |r|^2 / 2N)``: this over
        ``sqrt(2)``).
    covariance : ndarray, shape (6, 6)
        Covariance of the camera's pose: ``[dtheta (rad, 3), position (mm, 3)]``
        where ``dtheta`` is a small rotation vector, in world axes, applied on
        the left of ``R_world_camera`` (``R = expm([dtheta]x) @ R_est``) and
        position is the camera centre in the world. The noise of each marker's 8 corner coordinates is
        ``a I + b S + c g g^T``: corner noise ``a``, a shift ``b`` of its four corners together (a marker
        printed or stuck a little off, a board not quite flat, blur pulling its outline one way) and its own
        relative size error ``c`` (``g`` its corners about their centre), all measured from this pose's
        residuals with the degrees of freedom the fit used (the pose and the apparent size error common to
        all markers fitted first); the covariance is ``(J^T J)^-1 J^T Sigma J (J^T J)^-1``, ``J`` the
        Jacobian of the corner pixels at the solution (:func:`pose_jacobian`), plus the effect of that
        common size error (the pose takes it for distance). With fewer than 4 markers the three cannot be
        told apart: the residuals scale a prior mix (``PRIOR_SIGMA_PX``, ``PRIOR_SHIFT_PX``,
        ``PRIOR_SIZE_REL`` in ``fidlearn.pose._noise``, worth ``PRIOR_DOF`` degrees of freedom). With
        ``corner_sigma_px`` given, ``a`` is its square (and with fewer than 4 markers the covariance is
        the Cramer-Rao bound ``corner_sigma_px^2 (J^T J)^-1``). The estimate's own uncertainty widens it
        by ``3 F(3, nu; 0.95) / chi2(3; 0.95)`` (Hotelling; ``nu`` Satterthwaite's over the parts). A pinhole
        camera that carries its calibration's covariance (``Camera.intrinsics_covariance``,
        :func:`fidlearn.calibration.camera_with_uncertainty`) adds ``A Sigma_k A^T``, ``A = (J^T J)^-1 J^T
        J_k`` the pose's response to an error of the intrinsics (``J_k`` the corners' Jacobian on them): the
        calibration's error, the same in every pose and shown by no residual. When
        the pose is ``ambiguous`` it is instead the second moment, about this pose, of the mixture of
        both poses (weights from their likelihood ratio; with the noise estimated, the noise integrated out, whose
        tail is Student's), so the ellipsoid reaches the alternative. The
        alternative's own covariance is the local one, with the same noise. None if the pose is not
        determined.

        What it promises: the 95 % ellipsoid (:meth:`position_ellipsoid_contains`) holds the true
        position about 95 % of the time when the errors are of those kinds. Measured: on renders with
        Gaussian corner noise of 0.5 px, four markers (``tests/test_pose.py``), 97 % with sigma given or
        estimated, 95-96.5 % on six and twelve markers (``tests/test_pose_noise.py``); with fewer than 4
        markers and the noise estimated, 99 % (the prior mix holds a marker shift these renders lack); on
        real photos (``python -m benchmarks real``, docs/benchmarks.md): the robot's photos of a slightly
        bent ChArUco board, the truth's own covariance added, 14 of 16 camera positions inside, 16 of 16
        (position NEES median 2.6) with the calibration's covariance on the camera; the course's ChArUco
        photos against their chessboard pose, with it, 93-99.5 % with 1 to 3 markers but 82.5 % with 4-6 and
        65.5 % with 7-17 markers: an error all markers share (there a scale along the line of sight between the
        default edge fit's corners on markers 23-26 px across and the chessboard corners; 82-87 % with
        OpenCV's corner refinements) leaves no trace in the residuals and is not in it. With intrinsics drawn
        wrong from the camera's covariance on renders, 98 % (11 % without it; ``tests/test_pose_calibration.py``).
        An error of the
        map larger than a marker's shift (a marker moved on the wall) is for the outlier screen, not the
        covariance.
    corner_sigma_px : float
        The corner noise (px, per coordinate) the covariance assumes: given, or
        estimated from the residuals (see :func:`estimate_pose`).
    ambiguous : bool
        True when a second, distinct pose explains the corners nearly as well
        (planar targets seen face-on or from afar): see ``alternative``.
    alternative : Pose or None
        The other planar (IPPE) solution when it is distinct from this one (more
        than 3 sigma away): refined when LM keeps it as a second minimum, else
        as IPPE gave it (its ``method`` then says "not refined"). Draw both to
        see the flip.
    ignored_ids : tuple of int
        Detected ids that are not in the map.
    rejected_ids : tuple of int
        Markers left out because they disagree with the others (misplaced?), and a fisheye's markers with a
        corner 90 degrees or more off the axis, or so near it that its ideal pinhole pixels cannot be read by the
        pose's pinhole stage (``fidlearn.pose._inputs.RIM_PICTURE_PX``).
    method : str
        The solver(s) used, e.g. ``"ippe+lm"``.
    """

    T_world_camera: np.ndarray
    marker_ids: tuple[int, ...]
    residuals_px: dict[int, np.ndarray]
    reprojection_rms_px: float
    covariance: np.ndarray | None
    corner_sigma_px: float
    _: KW_ONLY
    ambiguous: bool = False
    alternative: InitVar[Pose | None] = None  # read through the property set below the class
    ignored_ids: tuple[int, ...] = ()
    rejected_ids: tuple[int, ...] = ()
    method: str = ""
    #: The alternative as given: a Pose, None, or a function that builds it (see :attr:`alternative`).
    _alternative: Pose | Callable[[], Pose] | None = field(default=None, init=False, repr=False)
    _T_camera_world: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self, alternative: Pose | None) -> None:
        self.T_world_camera = frames.check_transform(self.T_world_camera, "T_world_camera")
        self._alternative = alternative

    @classmethod
    def _trusted(cls, **fields) -> Pose:
        """A Pose from estimate_pose's own numbers (a rotation by construction): every field given, no check.

        ``alternative`` may be a function that builds it on first use (see :attr:`alternative`).
        """
        pose = object.__new__(cls)
        pose._alternative = fields.pop("alternative")
        for name, value in fields.items():
            setattr(pose, name, value)
        pose._T_camera_world = None
        return pose

    def _built_alternative(self) -> Pose | None:
        """The other planar (IPPE) solution, or None (see the class's Attributes).

        Built on first read and kept: most poses never need their (unambiguous) alternative.
        """
        value = self._alternative
        if callable(value):
            value = self._alternative = value()
        return value

    def __getstate__(self) -> dict:
        """The fields to pickle or copy, the alternative built (a function that builds it does not pickle)."""
        self._built_alternative()
        return {name: getattr(self, name) for name in self.__slots__}

    def __setstate__(self, state: dict) -> None:
        """Restore the fields :meth:`__getstate__` gave."""
        for name, value in state.items():
            setattr(self, name, value)

    # -- derived views -----------------------------------------------------------------
    @property
    def T_camera_world(self) -> np.ndarray:
        """The extrinsics (4, 4): world points into the camera frame (closed-form inverse)."""
        if self._T_camera_world is None:
            self._T_camera_world = frames.invert_transform(self.T_world_camera)
        return self._T_camera_world.copy()

    @property
    def rvec(self) -> np.ndarray:
        """Rodrigues vector (3,) of ``T_camera_world``, as ``cv2.solvePnP`` returns it."""
        return frames.rvec_tvec_from_transform(self.T_camera_world)[0]

    @property
    def tvec(self) -> np.ndarray:
        """Translation (3,), mm, of ``T_camera_world``, as ``cv2.solvePnP`` returns it."""
        return self.T_camera_world[:3, 3].copy()

    @property
    def rotation_std_deg(self) -> np.ndarray:
        """Standard deviation (3,) of the orientation about world X, Y, Z, degrees."""
        if self.covariance is None:
            return np.full(3, np.nan)
        return np.degrees(np.sqrt(np.maximum(np.diag(self.covariance)[:3], 0.0)))

    @property
    def marker_rms_px(self) -> dict[int, float]:
        """Per-marker RMS corner residual (px): a misplaced marker stands out here."""
        return {i: float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) for i, r in self.residuals_px.items()}

    def __repr__(self) -> str:
        position, rpy, std = self._readout_parts()
        parts = [
            position,
            rpy,
            f"markers={list(self.marker_ids)}",
            f"rms={self.reprojection_rms_px:.2f} px",
            std,
            f"ambiguous={self.ambiguous}",
        ]
        a = self._built_alternative()
        if a is not None:
            ax, ay, az = a.position_mm
            parts.append(f"alternative at [{ax:.1f}, {ay:.1f}, {az:.1f}] rms={a.reprojection_rms_px:.2f} px")
        if self.rejected_ids:
            parts.append(f"rejected={list(self.rejected_ids)}")
        if self.ignored_ids:
            parts.append(f"ignored={list(self.ignored_ids)}")
        parts.append(f"method={self.method!r}")
        return "Pose(" + ", ".join(parts) + ")"

    # -- JSON: the record ``fidlearn locate --json`` writes (bodies in _json.py) ---------------
    def to_dict(self, *, full: bool = False) -> dict:
        """The pose as JSON data: the record ``fidlearn locate --json`` writes for a located frame.

        Parameters
        ----------
        full : bool
            Also write what the record leaves out (``covariance``, ``corner_sigma_px``, ``residuals_px``
            and the ``alternative`` pose, each null when there is none), so that
            :meth:`from_dict` gives this pose back whole.

        Returns
        -------
        dict
            ``T_world_camera`` (4x4, mm), ``position_mm``, ``rpy_deg``, ``position_std_mm`` (null when
            the pose is not determined), ``marker_ids``, ``reprojection_rms_px``, ``ambiguous``,
            ``rejected_ids``, ``ignored_ids``, ``method`` and, for a pose with an alternative,
            ``alternative_position_mm``. Every value is JSON (lists, numbers, no NaN).

        Examples
        --------
        >>> import numpy as np
        >>> pose = Pose(np.eye(4), (3,), {}, 0.25, None, 0.1, method="ippe+lm")
        >>> d = pose.to_dict()
        >>> d["position_mm"], d["marker_ids"], d["position_std_mm"]
        ([0.0, 0.0, 0.0], [3], None)
        >>> Pose.from_dict(d).to_dict() == d
        True
        """
        from ._json import pose_to_dict

        return pose_to_dict(self, full)

    @classmethod
    def from_dict(cls, d: dict, *, source: str = "pose") -> Pose:
        """A pose from its JSON data (:meth:`to_dict`, or one line of ``fidlearn locate --json``).

        Parameters
        ----------
        d : dict
            ``T_world_camera``, ``marker_ids`` and ``reprojection_rms_px``, and optionally the other
            fields :meth:`to_dict` writes. ``position_mm``, ``rpy_deg``, ``position_std_mm`` and
            ``alternative_position_mm`` are read off the others and passed over, as are a
            ``fidlearn locate --json`` line's ``frame`` and ``located``. Without ``full=True``'s
            fields the pose has no covariance, no residuals, no alternative and a NaN ``corner_sigma_px``.
        source : str
            Where ``d`` came from, named in error messages.

        Returns
        -------
        Pose

        Raises
        ------
        PoseError
            ``d`` is not an object, misses a field, has an unknown field (with a guess at the meant
            one), a value of the wrong kind, a ``T_world_camera`` that is not a rigid transform, or
            is a frame that was not located.
        """
        from ._json import pose_from_dict

        return pose_from_dict(cls, d, source)


# A read-only property over the private slot, set after the class: a dataclass field (the ``alternative``
# the constructor and dataclasses.replace take) and a property cannot share a name in the class body.
Pose.alternative = property(Pose._built_alternative)  # type: ignore[assignment, method-assign, attr-defined]
