"""The camera's pose in the world from detected markers: PnP over every known marker at once.

The pipeline: every detected marker that the map knows gives four 2D-3D
correspondences (its pixel corners and its world corners, TL, TR, BR, BL).
A PnP solver finds ``T_camera_world`` (OpenCV's rvec/tvec, the extrinsics);
Levenberg-Marquardt then minimises the reprojection error; the camera's pose
in the world is the closed-form inverse ``T_world_camera``.

``method="auto"`` picks the solver the data calls for:

* one marker: ``IPPE_SQUARE`` in the marker's own frame;
* several markers on one plane (the corners actually seen are coplanar within
  1 mm, or within 1 % of their extent, after which IPPE runs on the points
  flattened onto their best plane): ``IPPE`` over all corners;
* markers on several walls (IPPE fails outright on points off a plane): ``SQPNP``
  (when the corners are nearly on one plane, off by less than 10 % of their
  extent, IPPE's flattened solutions compete with it).

A planar target has two poses that explain the image almost equally well when
it is seen nearly face-on or from afar (the "flip" ambiguity). IPPE gives both;
both are refined (the second only when it starts close enough to rival the
first); the better one is returned, the other is kept as
:attr:`Pose.alternative`, and :attr:`Pose.ambiguous` says when the data cannot
tell them apart (see :func:`estimate_pose`).

A marker measured wrongly on the wall is found by leave-one-out (only when the
residuals look suspicious, so the usual cost is one IPPE and one short LM run)
and reported in :attr:`Pose.rejected_ids`. Answers no camera can give are refused
with a :class:`PoseError` that says what to check: a marker whose image corners are
not a convex quad running clockwise on screen (mirrored, shuffled or collinear
corners), a pose that would see a marker from behind or have corners behind the
camera (never chosen while another candidate is possible), and a best fit whose
reprojection error is above ``BAD_FIT_REL`` marker sides. The uncertainty comes as a 6x6
covariance of the camera pose from the Jacobian of the corners
(:func:`pose_jacobian`).

Conventions: millimetres, OpenCV camera frame (x right, y down, z forward),
pixel centres at integer coordinates, ``T_a_b`` maps frame b into frame a.

Examples
--------
>>> import numpy as np, fidlearn
>>> from fidlearn.detection import Detection
>>> m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
>>> cam = fidlearn.Camera.from_fov(60, (640, 480))
>>> T_world_camera = fidlearn.make_transform(
...     fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])   # facing the wall (-X)
>>> dets = [Detection(i, cam.project(c, T_world_camera)) for i, c in m.corners().items()]
>>> pose = estimate_pose(dets, m, cam)
>>> np.round(pose.position_mm, 3).tolist()
[1000.0, 150.0, 250.0]
"""

from __future__ import annotations

import math
import os
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from . import _cv, frames
from .camera import Camera
from .detection import Detection
from .errors import NoMarkersError, PoseError
from .markermap import MarkerMap

__all__ = ["Pose", "estimate_pose", "locate", "METHODS", "pose_jacobian", "refine_pose_lm"]

#: The solvers ``method=`` accepts besides ``"auto"``, with their OpenCV names.
METHODS = {
    "ippe": "IPPE",
    "ippe_square": "IPPE_SQUARE",
    "sqpnp": "SQPNP",
    "iterative": "ITERATIVE",
    "epnp": "EPNP",
}

#: Prior corner noise (px) and its weight in degrees of freedom, blended with the
#: residuals when ``corner_sigma_px`` is not given (see :func:`estimate_pose`).
PRIOR_SIGMA_PX = 0.25
PRIOR_DOF = 2.0
#: Smallest corner noise (px) ever assumed: below this a covariance would claim
#: more than any detector can deliver.
MIN_SIGMA_PX = 0.02
#: The alternative planar solution counts as "as good" when its extra sum of
#: squared residuals is below this many sigma^2 (a likelihood ratio above
#: exp(-9/2) ~ 1/90: the data cannot rule it out).
AMBIGUITY_CHI2 = 9.0
#: The other planar solutions are refined only when they start within this many sigma^2
#: of the best one's refined sum of squared residuals (else they are kept as IPPE gave them).
REFINE_GAP_CHI2 = 100.0
#: False-alarm probability of the test that rejects a marker (per marker tested): its 8
#: residuals, predicted from the pose of the others, must have a Mahalanobis chi-square
#: above the chi-square(8) quantile (sigma given) or above 8 F(8, nu) (sigma estimated from
#: the others' nu degrees of freedom: the nested-model F test)...
OUTLIER_P = 1e-4
#: chi-square(8) quantile at OUTLIER_P (used in the cheap screen and with a known sigma).
OUTLIER_CHI2 = 31.83
#: ... and its RMS residual must also be above this many pixels (sub-pixel disagreement
#: is detector bias or calibration, not a misplaced marker).
OUTLIER_MIN_RMS_PX = 0.75
#: Noise assumed when screening for outliers: never below this (px).
OUTLIER_SIGMA_FLOOR_PX = 0.3
#: A fit whose RMS reprojection error is above ``max(BAD_FIT_MIN_PX, BAD_FIT_REL * s)``,
#: ``s`` the median side of the markers in the image (px), is not returned as a pose: the
#: corners do not fit the map (:class:`PoseError`). Detectors place corners within a pixel or
#: two. Measured (six or three markers, 25-80 px wide): a marker moved by 8-14 cm on a map of
#: 150 mm markers drags the pose and leaves 0.15-0.32 side widths of RMS residual (still a pose,
#: its residuals telling, see ``Pose.marker_rms_px``); positions in the wrong units (mm, cm,
#: inch, foot, metre taken for another) leave 0.47-3.5, a corner order mixed up 0.67-5.
BAD_FIT_REL = 0.4
BAD_FIT_MIN_PX = 5.0
#: The ambiguity test never assumes a corner noise above this (px) when it estimates the noise
#: from the residuals: no detector is that far off on a marker it decoded, so larger residuals
#: are a wrong map or camera, and they must not make a poorer second pose look "as good".
AMBIGUITY_MAX_SIGMA_PX = 3.0
#: Below this area (px^2) for every triangle of three of a marker's image corners, they are on a
#: line or repeat a point. (Noisy corners of a marker seen exactly edge-on span more: in 60000
#: benchmark-like views with 0.3-2 px of noise the smallest was 0.26 px^2.)
_MIN_QUAD_AREA_PX2 = 0.01
#: A marker's corners are called mirrored or out of order only when a triangle of them (or the
#: quad) has the wrong orientation by more than this many times ``d`` px^2, ``d`` the RMS of its
#: diagonals (px): five standard deviations of that area for corners 1 px off. A marker seen
#: nearly edge-on, a few pixels wide, can fold over under corner noise; it is not judged.
_QUAD_MARGIN_PX = 5.0
#: A marker counts as seen from behind when the camera is more than this far (degrees) behind
#: its plane: a marker seen at a grazing angle may be estimated a little behind it.
_BEHIND_TOL_DEG = 10.0
_SIN_BEHIND_TOL = math.sin(math.radians(_BEHIND_TOL_DEG))

_PLANAR_TOL_MM = 1.0
_PLANAR_TOL_REL = 0.01
#: Off-plane thickness below this fraction of the extent: SQPnP's answer competes with IPPE's.
_NEAR_PLANAR_REL = 0.1
#: Levenberg-Marquardt stops when a step would lower the sum of squared residuals by less than
#: this (px^2): a change of the pose far below its own uncertainty for any realistic corner noise.
_LM_TOL_PX2 = 1e-8
#: ... or by less than this many sigma^2 (sigma^2 estimated as sse / (2N - 6)).
_LM_TOL_SIGMA2 = 1e-3


# ---------------------------------------------------------------------------------------
# The result
# ---------------------------------------------------------------------------------------
@dataclass(eq=False, repr=False)
class Pose:
    """The camera's pose in the world, with its quality.

    Attributes
    ----------
    T_world_camera : ndarray, shape (4, 4)
        The camera's pose in the world (mm): ``p_world = T_world_camera @ p_camera``.
    marker_ids : tuple of int
        The markers the pose was computed from.
    residuals_px : dict of int to ndarray (4, 2)
        Per marker: observed minus reprojected corners (px), TL, TR, BR, BL.
        Rejected markers are listed too (their residual under this pose).
    reprojection_rms_px : float
        RMS over the used corners of the residual length (px), as
        ``cv2.solvePnPGeneric`` reports it.
    covariance : ndarray, shape (6, 6)
        Covariance of the camera's pose: ``[dtheta (rad, 3), position (mm, 3)]``
        where ``dtheta`` is a small rotation vector, in world axes, applied on
        the left of ``R_world_camera`` (``R = expm([dtheta]x) @ R_est``) and
        position is the camera centre in the world. ``sigma_px^2 (J^T J)^-1``
        with ``J`` the Jacobian of the corner pixels at the solution
        (:func:`pose_jacobian`): the Cramer-Rao bound when ``corner_sigma_px``
        is given. When sigma is estimated from the residuals it is multiplied
        by ``3 F(3, nu; 0.95) / chi2(3; 0.95)`` (Hotelling; ``nu = 2N - 6 +
        PRIOR_DOF``) so that the 95 % ellipsoid still holds the true position
        95 % of the time: 1.08 with six markers, 1.2 with three, 2.5 with one.
        When the pose is ``ambiguous`` it is instead the second moment, about
        this pose, of the mixture of both poses (weights from their likelihood
        ratio), so the ellipsoid reaches the alternative. The alternative's own
        covariance is the local one. None if the pose is not determined.

        What it promises: when the corner errors are independent, Gaussian,
        of the sigma used, the 95 % ellipsoid
        (:meth:`position_ellipsoid_contains`) holds the true position about
        95 % of the time. Measured in ``benchmarks/bench_pose.py`` (corners
        with Gaussian noise of 0.3 and 1 px, 400 views each): 91-96 % for
        three and six markers, sigma given or estimated; one marker 94 % and
        89 % with sigma given, 96 % (0.3 px) and only 68 % (1 px) with sigma
        estimated, because its 2 degrees of freedom leave the estimate to the
        prior below. It knows only the corner noise: an error of the map, the
        marker size or the calibration is not in it. An estimated sigma is
        blended with a prior of ``PRIOR_SIGMA_PX`` (0.25 px) worth
        ``PRIOR_DOF`` degrees of freedom, so with few markers the ellipsoid
        is too large (conservative) for a detector better than that (on the
        bundled rendered scenes fidlearn's corners are 0.02-0.1 px off: the
        truth was always inside, at a mean squared Mahalanobis distance of
        0.25 instead of 3) and too small for a worse one. Give
        ``corner_sigma_px`` when you know your detector's noise.
    sigma_px : float
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
        Markers left out because they disagree with the others (misplaced?).
    method : str
        The solver(s) used, e.g. ``"ippe+lm"``.
    """

    T_world_camera: np.ndarray
    marker_ids: tuple[int, ...]
    residuals_px: dict[int, np.ndarray]
    reprojection_rms_px: float
    covariance: np.ndarray | None
    sigma_px: float
    ambiguous: bool = False
    alternative: Pose | None = None
    ignored_ids: tuple[int, ...] = ()
    rejected_ids: tuple[int, ...] = ()
    method: str = ""
    _T_camera_world: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        self.T_world_camera = frames.check_transform(self.T_world_camera, "T_world_camera")

    def __getattribute__(self, name: str):
        value = object.__getattribute__(self, name)
        if name == "alternative" and callable(value):
            # built on first use: most poses never need their (unambiguous) alternative
            value = value()
            object.__setattr__(self, "alternative", value)
        return value

    # -- derived views -----------------------------------------------------------------
    @property
    def T_camera_world(self) -> np.ndarray:
        """The extrinsics (4, 4): world points into the camera frame (closed-form inverse)."""
        if self._T_camera_world is None:
            self._T_camera_world = frames.invert_transform(self.T_world_camera)
        return self._T_camera_world.copy()

    @property
    def position_mm(self) -> np.ndarray:
        """Camera centre (3,) in world coordinates, mm."""
        return self.T_world_camera[:3, 3].copy()

    @property
    def rpy_deg(self) -> np.ndarray:
        """Roll, pitch, yaw (3,) in degrees of the camera's orientation in the world (``R_world_camera``)."""
        return frames.rpy_deg_from_rotation(self.T_world_camera[:3, :3])

    @property
    def rvec(self) -> np.ndarray:
        """Rodrigues vector (3,) of ``T_camera_world``, as ``cv2.solvePnP`` returns it."""
        return frames.rvec_tvec_from_transform(self.T_camera_world)[0]

    @property
    def tvec(self) -> np.ndarray:
        """Translation (3,), mm, of ``T_camera_world``, as ``cv2.solvePnP`` returns it."""
        return self.T_camera_world[:3, 3].copy()

    @property
    def position_std_mm(self) -> np.ndarray:
        """Standard deviation (3,) of the camera position along world X, Y, Z, mm."""
        if self.covariance is None:
            return np.full(3, np.nan)
        return np.sqrt(np.maximum(np.diag(self.covariance)[3:], 0.0))

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

    def position_ellipsoid_contains(self, point_mm: np.ndarray, probability: float = 0.95) -> bool:
        """Whether a world point (3,), mm, lies inside the camera position's confidence ellipsoid."""
        if self.covariance is None:
            return False
        d = np.asarray(point_mm, dtype=float).reshape(3) - self.position_mm
        m2 = float(d @ np.linalg.solve(self.covariance[3:, 3:], d))
        return m2 <= _chi2_3_quantile(probability)

    def __repr__(self) -> str:
        x, y, z = self.position_mm
        r, p, yw = self.rpy_deg
        sx, sy, sz = self.position_std_mm
        parts = [
            f"position_mm=[{x:.1f}, {y:.1f}, {z:.1f}]",
            f"rpy_deg=[{r:.1f}, {p:.1f}, {yw:.1f}]",
            f"markers={list(self.marker_ids)}",
            f"rms={self.reprojection_rms_px:.2f} px",
            f"std_mm=[{sx:.1f}, {sy:.1f}, {sz:.1f}]",
            f"ambiguous={self.ambiguous}",
        ]
        if self.alternative is not None:
            a = self.alternative
            ax, ay, az = a.position_mm
            parts.append(f"alternative at [{ax:.1f}, {ay:.1f}, {az:.1f}] rms={a.reprojection_rms_px:.2f} px")
        if self.rejected_ids:
            parts.append(f"rejected={list(self.rejected_ids)}")
        if self.ignored_ids:
            parts.append(f"ignored={list(self.ignored_ids)}")
        parts.append(f"method={self.method!r}")
        return "Pose(" + ", ".join(parts) + ")"


def _chi2_3_quantile(p: float) -> float:
    """Quantile of the chi-square distribution with 3 degrees of freedom (7.815 for 0.95).

    Its CDF has a closed form, ``erf(sqrt(x/2)) - sqrt(2x/pi) exp(-x/2)``: bisect on it.
    """
    if not 0 < p < 1:
        raise PoseError(f"probability must be between 0 and 1 (exclusive), got {p}")
    lo, hi = 0.0, 200.0
    for _ in range(100):
        mid = (lo + hi) / 2
        cdf = math.erf(math.sqrt(mid / 2)) - math.sqrt(2 * mid / math.pi) * math.exp(-mid / 2)
        if cdf < p:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


# ---------------------------------------------------------------------------------------
# Maths on plain arrays (usable on their own, e.g. in notebooks and benchmarks)
# ---------------------------------------------------------------------------------------
def pose_jacobian(points_world: np.ndarray, T_world_camera: np.ndarray, camera: Camera) -> np.ndarray:
    """Jacobian (2N, 6) of the projected pixels with respect to the camera pose.

    Parameters
    ----------
    points_world : ndarray, shape (N, 3)
        World points, mm.
    T_world_camera : ndarray, shape (4, 4)
        Camera pose at which to differentiate.
    camera : Camera
        Intrinsics and distortion.

    Returns
    -------
    ndarray, shape (2N, 6)
        Rows ``u0, v0, u1, v1, ...``; columns ``[dtheta (3, rad), dC (3, mm)]``:
        ``dtheta`` a small rotation in world axes applied on the left of
        ``R_world_camera``, ``dC`` a shift of the camera centre in the world.
        ``sigma^2 (J^T J)^-1`` is then the covariance (Cramer-Rao bound at the
        true pose) of the camera pose in those coordinates.
    """
    P = np.asarray(points_world, dtype=float).reshape(-1, 3)
    R_wc = T_world_camera[:3, :3]
    C = T_world_camera[:3, 3]
    R_cw = R_wc.T
    d = P - C  # (N, 3) world vectors from the camera centre
    X_c = d @ R_cw.T
    # d(pixel)/d(point in camera frame): projectPoints' Jacobian w.r.t. tvec at rvec = tvec = 0
    _, jac = cv2.projectPoints(X_c.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, camera.dist)
    dpx_dXc = jac[:, 3:6].reshape(-1, 2, 3)
    # X_c = R_cw0 expm(-[dtheta]x) (P - C): dX_c/dtheta = R_cw0 [d]x ; dX_c/dC = -R_cw0
    skew = np.zeros((len(P), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2] = -d[:, 2], d[:, 1]
    skew[:, 1, 0], skew[:, 1, 2] = d[:, 2], -d[:, 0]
    skew[:, 2, 0], skew[:, 2, 1] = -d[:, 1], d[:, 0]
    A = dpx_dXc @ R_cw  # (N, 2, 3)
    J = np.concatenate([A @ skew, -A], axis=2)
    return J.reshape(-1, 6)


def refine_pose_lm(
    points_world: np.ndarray,
    points_px: np.ndarray,
    camera: Camera,
    rvec: np.ndarray,
    tvec: np.ndarray,
    max_iterations: int = 50,
):
    """Levenberg-Marquardt on the reprojection error from a starting pose.

    The steps are taken on the camera's pose (a small rotation in world axes and
    a shift of the camera centre) with Marquardt's diagonal scaling; the
    Jacobian is :func:`pose_jacobian`. From an IPPE start it usually converges
    in two or three iterations. It minimises the same error as
    ``cv2.solvePnPRefineLM``, which stopped short of the optimum on far,
    poorly conditioned views when this was written (OpenCV 5.0).

    Parameters
    ----------
    points_world : ndarray, shape (N, 3), mm
    points_px : ndarray, shape (N, 2), px
    camera : Camera
    rvec, tvec : ndarray, shape (3,)
        Starting ``T_camera_world`` (OpenCV's convention).
    max_iterations : int

    Returns
    -------
    rvec, tvec : ndarray, shape (3,)
        The refined ``T_camera_world``.
    """
    obj = np.ascontiguousarray(points_world, dtype=np.float64).reshape(-1, 3)
    img = np.ascontiguousarray(points_px, dtype=np.float64).reshape(-1, 2)
    R_cw, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
    R_wc = R_cw.T
    C = -R_wc @ np.asarray(tvec, dtype=np.float64).reshape(3)
    R_wc, C, _, _, _ = _lm(obj, img, camera.K, camera.dist, R_wc, C, max_iterations, tol_sigma2=0.0)
    R_cw = R_wc.T
    return _rotvec(R_cw), -R_cw @ C


def _rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,), rad, of a rotation matrix (3, 3): the log map, exact for tiny angles too.

    ``cv2.Rodrigues`` returns exactly zero below about 1e-5 rad (OpenCV 4.x and 5.x); there
    ``sin(angle) = angle`` to 1e-10, so the skew part of ``R`` is the rotation vector.
    """
    r = cv2.Rodrigues(np.ascontiguousarray(R, dtype=np.float64))[0].reshape(3)
    if not r.any():
        r = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return r


_ZERO3 = np.zeros(3)


def _residuals(obj, img, K, dist, R_wc, C, with_jacobian: bool):
    """Residuals (2N,) observed minus projected, and optionally the Jacobian (2N, 6) of the projection.

    The same Jacobian as :func:`pose_jacobian`, written for speed (this runs in every LM step).
    """
    d = obj - C
    X_c = d @ R_wc  # rows: R_cw @ d = R_wc^T d
    px, jac = cv2.projectPoints(X_c.reshape(-1, 1, 3), _ZERO3, _ZERO3, K, dist)
    r = img.reshape(-1) - px.reshape(-1)
    if not with_jacobian:
        return r, None
    A = jac[:, 3:6] @ R_wc.T  # (2N, 3): d(px)/d(world displacement of the point)
    dd = np.repeat(d, 2, axis=0)
    J = np.empty((len(A), 6))
    # row a of A times [d]x is a x d
    J[:, 0] = A[:, 1] * dd[:, 2] - A[:, 2] * dd[:, 1]
    J[:, 1] = A[:, 2] * dd[:, 0] - A[:, 0] * dd[:, 2]
    J[:, 2] = A[:, 0] * dd[:, 1] - A[:, 1] * dd[:, 0]
    np.negative(A, out=J[:, 3:])
    return r, J


def _lm(obj, img, K, dist, R_wc, C, max_iterations=50, tol_sigma2=None):
    """Levenberg-Marquardt (Marquardt's diagonal scaling) on the camera pose.

    Returns R_wc, C, the sum of squared residuals, the residuals (2N,) and J^T J (6, 6) there.
    """
    r, J = _residuals(obj, img, K, dist, R_wc, C, True)
    sse = float(r @ r)
    lam = 1e-4
    JtJ = J.T @ J
    g = J.T @ r
    dof = max(len(r) - 6, 1)
    for _ in range(max_iterations):
        # Stop when the next step would move the pose by less than about 0.03 sigma (its
        # squared length in sigma units below 1e-3, sigma estimated from the residuals).
        tol = max(_LM_TOL_PX2, (_LM_TOL_SIGMA2 if tol_sigma2 is None else tol_sigma2) * sse / dof)
        A = JtJ.copy()
        A.flat[::7] += lam * np.maximum(JtJ.flat[::7], 1e-12)  # Marquardt: damp the diagonal
        try:
            step = np.linalg.solve(A, g)
        except np.linalg.LinAlgError:
            break
        predicted = float(step @ g)  # about twice the decrease a linear model expects
        if not predicted > tol:
            break  # converged: no step left worth taking
        dR, _ = cv2.Rodrigues(step[:3].reshape(3, 1))
        R_new = dR @ R_wc
        C_new = C + step[3:]
        r_new, J_new = _residuals(obj, img, K, dist, R_new, C_new, True)
        sse_new = float(r_new @ r_new)
        if sse_new < sse:
            done = sse - sse_new <= tol
            R_wc, C, sse, r, J = R_new, C_new, sse_new, r_new, J_new
            JtJ = J.T @ J
            g = J.T @ r
            lam = max(lam / 10, 1e-12)
            if done:
                break
        else:
            lam *= 10
            if lam > 1e8:
                break
    return R_wc, C, sse, r, JtJ


def _plane_fit(points: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
    """Thickness (mm), extent (mm), centroid (3,) and rotation (3, 3) whose 3rd row is the plane normal."""
    c = points.mean(axis=0)
    q = points - c
    _, s, vt = np.linalg.svd(q, full_matrices=False)
    if vt.shape[0] < 3:
        vt = np.vstack([vt, np.cross(vt[0], vt[1])])
    if np.linalg.det(vt) < 0:
        vt[2] = -vt[2]
    thickness = float(np.abs(q @ vt[2]).max())
    extent = float(np.abs(q @ vt[0]).max()) * 2
    return thickness, extent, c, vt


_PLANE_CACHE: dict[bytes, tuple] = {}


def _plane_fit_cached(points: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
    """:func:`_plane_fit`, remembered for the last few point sets (a map seen again and again)."""
    key = points.tobytes()
    hit = _PLANE_CACHE.get(key)
    if hit is None:
        hit = _plane_fit(points)
        hit[2].flags.writeable = hit[3].flags.writeable = False
        if len(_PLANE_CACHE) >= 64:
            _PLANE_CACHE.pop(next(iter(_PLANE_CACHE)))
        _PLANE_CACHE[key] = hit
    return hit


# ---------------------------------------------------------------------------------------
# Solvers
# ---------------------------------------------------------------------------------------
@dataclass
class _Obs:
    ids: list[int]
    obj: np.ndarray  # (4n, 3) world corners, mm
    img: np.ndarray  # (4n, 2) pixel corners
    _faces: np.ndarray | None = field(default=None, init=False, repr=False)

    def faces(self) -> np.ndarray:
        """Rows (n, 7): centre (mm), unit normal and normal . centre of each marker's printed face (world)."""
        if self._faces is None:
            self._faces = _faces_of(self.obj)
        return self._faces


_UNCHECKED = "unchecked"
_YZX, _ZXY = np.array([1, 2, 0]), np.array([2, 0, 1])


@dataclass
class _Candidate:
    R_wc: np.ndarray  # (3, 3) camera orientation in the world
    C: np.ndarray  # (3,) camera centre in the world, mm
    sse: float  # sum of squared residuals, px^2
    r: np.ndarray | None  # (2N,) residuals, observed minus projected, px (None: not computed yet)
    refined: bool = False  # whether Levenberg-Marquardt ran from it
    JtJ: np.ndarray | None = None  # (6, 6) J^T J at this pose, when LM left it behind
    problem: str | None = _UNCHECKED  # why it cannot be the camera (None: it can); see _cheirality
    problem_short: str = ""  # the same in one sentence, to follow another message

    @property
    def T_world_camera(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = self.R_wc
        T[:3, 3] = self.C
        return T


def _from_R_t(obs: _Obs, camera: Camera, R_cw: np.ndarray, t: np.ndarray, sse: float | None = None) -> _Candidate:
    """A candidate from T_camera_world's rotation (3, 3) and translation (3,), not refined.

    With ``sse`` given (the solver's own reprojection error) the residuals are left for later.
    """
    R_wc = np.ascontiguousarray(R_cw.T)
    C = -R_wc @ np.asarray(t, dtype=np.float64).reshape(3)
    if sse is not None:
        return _Candidate(R_wc, C, float(sse), None)
    r, _ = _residuals(obs.obj, obs.img, camera.K, camera.dist, R_wc, C, False)
    return _Candidate(R_wc, C, float(r @ r), r)


def _lm_candidate(obs: _Obs, camera: Camera, start: _Candidate) -> _Candidate:
    R_wc, C, sse, r, JtJ = _lm(obs.obj, obs.img, camera.K, camera.dist, start.R_wc, start.C)
    return _Candidate(R_wc, C, sse, r, True, JtJ)


def _generic(flag_name: str, obj: np.ndarray, img: np.ndarray, camera: Camera):
    """``cv2.solvePnPGeneric``: a list of (R_cw (3, 3), t (3,), sse px^2); empty when the solver fails."""
    try:
        n, rvecs, tvecs, rms = cv2.solvePnPGeneric(
            np.ascontiguousarray(obj, dtype=np.float64).reshape(-1, 1, 3),
            np.ascontiguousarray(img, dtype=np.float64).reshape(-1, 1, 2),
            camera.K,
            camera.dist,
            flags=_cv.solvepnp_flag(flag_name),
        )
    except cv2.error:
        return []
    rms = np.asarray(rms, dtype=np.float64).reshape(-1) if rms is not None else np.full(n, np.nan)
    out = []
    for k, (r, t) in enumerate(list(zip(rvecs, tvecs))[:n]):
        r = np.asarray(r, dtype=np.float64).reshape(3, 1)
        t = np.asarray(t, dtype=np.float64).reshape(3)
        if np.all(np.isfinite(r)) and np.all(np.isfinite(t)):
            sse = float(rms[k]) ** 2 * len(obj) if k < len(rms) and np.isfinite(rms[k]) else None
            out.append((cv2.Rodrigues(r)[0], t, sse))
    return out


def _solve_ippe_square(obs: _Obs, marker_map: MarkerMap, camera: Camera):
    """IPPE_SQUARE in the marker's own frame (centre origin, x right, y up), moved to the world."""
    s = marker_map.marker_size_mm
    local = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0], [-s / 2, -s / 2, 0]])
    T_world_marker = marker_map.T_world_marker(obs.ids[0])
    R_wm, t_wm = T_world_marker[:3, :3], T_world_marker[:3, 3]
    # T_camera_world = T_camera_marker @ inv(T_world_marker)
    return [
        (R_cm @ R_wm.T, t_cm - R_cm @ R_wm.T @ t_wm, sse)
        for R_cm, t_cm, sse in _generic("IPPE_SQUARE", local, obs.img, camera)
    ]


def _solve_ippe(obs: _Obs, camera: Camera, plane) -> list:
    """IPPE on the points flattened onto their best plane (IPPE refuses points even 1 mm off it)."""
    _, _, c, vt = plane
    local = (obs.obj - c) @ vt.T
    local[:, 2] = 0.0
    # T_camera_world = T_camera_plane @ T_plane_world, T_plane_world = [vt, -vt c]
    return [(R_cp @ vt, t_cp - R_cp @ vt @ c, sse) for R_cp, t_cp, sse in _generic("IPPE", local, obs.img, camera)]


def _solve(obs: _Obs, marker_map: MarkerMap, camera: Camera, method: str, refine_lm: bool):
    """Candidates sorted by reprojection error, and the method's name."""
    n_pts = len(obs.obj)
    thickness, extent, c, vt = _plane_fit_cached(obs.obj)
    planar = thickness <= max(_PLANAR_TOL_MM, _PLANAR_TOL_REL * extent)
    if method == "auto":
        if len(obs.ids) == 1:
            method_used, raw = "ippe_square", _solve_ippe_square(obs, marker_map, camera)
        elif planar:
            method_used, raw = "ippe", _solve_ippe(obs, camera, (thickness, extent, c, vt))
        else:
            method_used, raw = "sqpnp", _generic("SQPNP", obs.obj, obs.img, camera)
            if thickness < _NEAR_PLANAR_REL * extent:
                # a wall measured a little unevenly: IPPE's two flattened solutions compete too
                raw = raw + _solve_ippe(obs, camera, (thickness, extent, c, vt))
        if not raw:  # degenerate data: fall back on the general solvers
            for name in ("SQPNP", "ITERATIVE"):
                raw = _generic(name, obs.obj, obs.img, camera)
                if raw:
                    method_used = name.lower()
                    break
    else:
        method_used = method
        if method == "ippe_square":
            if len(obs.ids) != 1:
                raise PoseError(
                    f"method='ippe_square' solves one marker, but {len(obs.ids)} markers {obs.ids} are in view; "
                    "use method='ippe' (coplanar markers) or 'auto'"
                )
            raw = _solve_ippe_square(obs, marker_map, camera)
        elif method == "ippe":
            if not planar:
                raise PoseError(
                    f"method='ippe' needs coplanar points, but the corners of markers {obs.ids} are up to "
                    f"{thickness:.1f} mm off their best plane (markers on several walls); use method='sqpnp', "
                    "'epnp', 'iterative' or 'auto'"
                )
            raw = _solve_ippe(obs, camera, (thickness, extent, c, vt))
        else:
            if (method == "sqpnp" and n_pts < 3) or (method in ("epnp", "iterative") and n_pts < 4):
                raise PoseError(f"method={method!r} needs more points than the {n_pts} corners in view")
            raw = _generic(METHODS[method], obs.obj, obs.img, camera)
    if not raw:
        raise PoseError(
            f"the PnP solver ({method_used}) found no pose from markers {obs.ids}; are the map's corners "
            "in TL, TR, BR, BL order and the marker size right?"
        )
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


def _cheirality(obs: _Obs, c: _Candidate) -> str | None:
    """None when a candidate sees every marker from its printed side and every corner in front of it.

    Otherwise a message saying which markers break it and what is likely wrong. A mirror image
    of the markers (camera behind them, or behind the camera) can fit the corners perfectly:
    a pose is only one that a camera can have when both hold.
    """
    if c.problem is not _UNCHECKED:
        return c.problem
    f = obs.faces()
    height = f[:, 3:6] @ c.C - f[:, 6]  # the camera's height above each marker's plane: > 0 on the printed side
    z = c.R_wc[:, 2]  # the camera's optical axis in the world
    depth = obs.obj @ z - c.C @ z  # > 0: in front of the camera
    if min(height.tolist()) > 0 and min(depth.tolist()) > 0:  # (builtin min: cheaper on a few values)
        c.problem = None
        return None
    # a grazing view may come out a little behind: allowed up to _BEHIND_TOL_DEG of elevation
    to_camera = c.C - f[:, :3]
    seen = (height > 0) | (height * height < _SIN_BEHIND_TOL**2 * (to_camera * to_camera).sum(axis=1))
    if seen.all() and depth.min() > 0:
        c.problem = None
        return None
    rms = math.sqrt(c.sse / len(obs.obj))
    backs = [i for i, ok in zip(obs.ids, seen) if not ok]
    if backs:
        one = len(backs) == 1
        which = f"marker{'' if one else 's'} {backs[0] if one else backs}"
        c.problem = (
            f"{which} would be seen from behind (from the back of {'its' if one else 'their'} printed face) by the "
            f"pose that fits the corners best (reprojection error {rms:.1f} px): {'is its rotation' if one else 'are their rotations'} "
            "in the map wrong (yaw 180, facing into the wall instead of out of it; a marker on a wall facing +X has "
            "rotation [0, 0, 0]), or the corners mirrored (TL, BL, BR, TR instead of TL, TR, BR, BL)?"
            + (
                f" With markers {obs.ids} in view, the wrong rotation may be another one's."
                if len(backs) < len(obs.ids)
                else ""
            )
        )
        c.problem_short = f"Even that best fit would see {which} from behind."
        return c.problem
    behind = [i for i, d in zip(obs.ids, depth.reshape(-1, 4).min(axis=1)) if not d > 0]
    if behind:
        one = len(behind) == 1
        which = f"marker{'' if one else 's'} {behind[0] if one else behind}"
        c.problem = (
            f"{which} would be behind the camera in the pose that fits the corners best (reprojection error "
            f"{rms:.1f} px): the corners do not fit the map; check the map's positions and rotations, the marker "
            "size and the corner order (TL, TR, BR, BL)"
        )
        c.problem_short = f"Even that best fit would have {which} behind the camera."
        return c.problem
    c.problem = None
    return None


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


_NEXT = np.array([1, 2, 3, 0])


def _side_px(img: np.ndarray) -> np.ndarray:
    """Mean side length (n,), px, of each marker's four image corners (4n, 2)."""
    q = img.reshape(-1, 4, 2)
    e = q[:, _NEXT] - q
    return np.sqrt((e * e).sum(axis=2)).mean(axis=1)


def _check_quads(ids: Sequence[int], img: np.ndarray) -> None:
    """Raise PoseError when a marker's image corners cannot be a marker seen from its printed side.

    TL, TR, BR, BL of a marker seen from its printed side run clockwise in the image (y points
    down), as every detector reports them: a convex quad whose four corner triangles (and
    shoelace area) are positive. Refused: corners on a line or repeated (no area), corners
    anticlockwise (mirrored), and corners that fold or cross (out of order), each only when
    clearly so (``_QUAD_MARGIN_PX``), so that noisy corners of a marker seen edge-on pass.
    """
    q = img.reshape(-1, 4, 2)  # the markers' corners, TL, TR, BR, BL
    nxt = q[:, _NEXT]
    e = nxt - q  # edges c[k+1] - c[k]
    e_next = e[:, _NEXT]
    tri = e[..., 0] * e_next[..., 1] - e[..., 1] * e_next[..., 0]  # (n, 4) twice the signed triangle areas
    if min(tri.ravel().tolist()) > 0:
        return  # the usual case: convex and clockwise
    tri = 0.5 * tri
    area = 0.5 * np.sum(q[..., 0] * nxt[..., 1] - nxt[..., 0] * q[..., 1], axis=1)
    d = np.sqrt(0.5 * (np.sum((q[:, 2] - q[:, 0]) ** 2, axis=1) + np.sum((q[:, 3] - q[:, 1]) ** 2, axis=1)))
    margin = _QUAD_MARGIN_PX * d
    flat = np.abs(tri).max(axis=1) < _MIN_QUAD_AREA_PX2
    mirrored = (area < -margin) & (tri.max(axis=1) < margin)
    folded = tri.min(axis=1) < -margin
    bad = flat | mirrored | folded
    if not bad.any():
        return
    k = int(np.flatnonzero(bad)[0])
    i, c = ids[k], np.round(q[k], 1).tolist()
    if flat[k]:
        raise PoseError(
            f"marker {i}: its image corners {c} enclose no area (they lie on a line or repeat a point): no "
            "detector reports such a marker and no pose follows from it; check how the corners were made"
        )
    if mirrored[k]:
        raise PoseError(
            f"marker {i}: its image corners {c} run anticlockwise on the screen, the mirror image of a marker "
            "seen from its printed side (detection reports TL, TR, BR, BL clockwise, y pointing down): are "
            "they listed TL, BL, BR, TR? corners[[0, 3, 2, 1]] puts them right. (A camera behind the marker, "
            "or a mirrored picture, gives this too.)"
        )
    raise PoseError(
        f"marker {i}: its image corners {c} do not form a convex quadrilateral (the outline crosses itself or "
        "folds in): they are not in the order TL, TR, BR, BL around the marker"
    )


def _mahalanobis2(a: _Candidate, b: _Candidate, JtJ: np.ndarray, sigma: float) -> float:
    """Squared distance between two poses in units of the pose's uncertainty at ``a``."""
    dtheta = _rotvec(b.R_wc @ a.R_wc.T)
    d = np.concatenate([dtheta, b.C - a.C])
    return float(d @ JtJ @ d) / sigma**2


#: 95 % quantiles of the F distribution with (3, nu) degrees of freedom (standard tables),
#: for the inflation of a covariance whose sigma was estimated with nu degrees of freedom.
_F3_95 = (
    (1, 215.7),
    (2, 19.16),
    (3, 9.28),
    (4, 6.59),
    (5, 5.41),
    (6, 4.76),
    (7, 4.35),
    (8, 4.07),
    (9, 3.86),
    (10, 3.71),
    (12, 3.49),
    (15, 3.29),
    (20, 3.10),
    (24, 3.01),
    (30, 2.92),
    (40, 2.84),
    (60, 2.76),
    (120, 2.68),
    (math.inf, 2.605),
)
_CHI2_3_95 = 7.8147


def _estimated_sigma_inflation(nu: float) -> float:
    """``3 F(3, nu; 0.95) / chi2(3; 0.95)``: how much wider the 95 % region is when sigma is estimated.

    Hotelling: with sigma estimated from ``nu`` degrees of freedom, ``d^T (s^2 A)^-1 d / 3``
    follows F(3, nu), not chi-square(3) / 3. Interpolated in 1/nu in the table above.
    """
    nu = max(float(nu), 1.0)
    for (n0, f0), (n1, f1) in zip(_F3_95, _F3_95[1:]):
        if nu <= n1:
            x0, x1, x = 1.0 / n0, (0.0 if math.isinf(n1) else 1.0 / n1), 1.0 / nu
            f = f1 + (f0 - f1) * (x - x1) / (x0 - x1)
            return 3.0 * f / _CHI2_3_95
    return 3.0 * _F3_95[-1][1] / _CHI2_3_95


def _sigma(sse: float, dof: int, corner_sigma_px: float | None) -> float:
    if corner_sigma_px is not None:
        return float(corner_sigma_px)
    s2 = (PRIOR_DOF * PRIOR_SIGMA_PX**2 + sse) / (PRIOR_DOF + max(dof, 0))
    return max(math.sqrt(s2), MIN_SIGMA_PX)


def _covariance_from(JtJ: np.ndarray, sigma: float) -> np.ndarray | None:
    """``sigma^2 (J^T J)^-1``, symmetric; None when the pose is not determined (singular J^T J)."""
    try:
        cov = sigma**2 * np.linalg.inv(JtJ)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(cov)):
        return None
    return (cov + cov.T) / 2


_WORLD_CACHE: weakref.WeakKeyDictionary[MarkerMap, tuple] = weakref.WeakKeyDictionary()


def _faces_of(points: np.ndarray) -> np.ndarray:
    """Rows (n, 7) ``[centre (3), unit normal (3), normal . centre]`` of markers' faces from their corners (4n, 3)."""
    q = points.reshape(-1, 4, 3)
    # x from TL to TR, y from BL to TL, z = x cross y out of the printed face (MarkerMap.normal)
    a, b = q[:, 1] - q[:, 0], q[:, 0] - q[:, 3]
    n = a[:, _YZX] * b[:, _ZXY] - a[:, _ZXY] * b[:, _YZX]
    n /= np.sqrt((n * n).sum(axis=1))[:, None]
    centres = q.mean(axis=1)
    return np.column_stack([centres, n, (n * centres).sum(axis=1)])


def _world(marker_map: MarkerMap) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """``marker_map.corners()`` and each marker's face row (:func:`_faces_of`), cached per map.

    The cache holds while the map's placements and marker size stay the same.
    """
    key = (marker_map.marker_size_mm, tuple(marker_map.placements.values()))
    try:
        hit = _WORLD_CACHE.get(marker_map)
    except TypeError:  # an unhashable map: no cache
        hit, key = None, None
    if hit is not None and hit[0] == key:
        return hit[1], hit[2]
    corners = marker_map.corners()
    for c in corners.values():
        c.flags.writeable = False
    ids = list(corners)
    rows = _faces_of(np.concatenate([corners[i] for i in ids])) if ids else np.zeros((0, 7))
    faces = dict(zip(ids, rows))
    if key is not None:
        _WORLD_CACHE[marker_map] = (key, corners, faces)
    return corners, faces


def _make_obs(
    ids: Sequence[int],
    corners_px: dict[int, np.ndarray],
    world: dict[int, np.ndarray],
    faces: dict[int, np.ndarray] | None = None,
) -> _Obs:
    ids = list(ids)
    obs = _Obs(ids, np.concatenate([world[i] for i in ids]), np.concatenate([corners_px[i] for i in ids]))
    if faces is not None:
        obs._faces = np.array([faces[i] for i in ids])
    return obs


# ---------------------------------------------------------------------------------------
# Outliers
# ---------------------------------------------------------------------------------------
def _marker_chi2(
    obs_rest: _Obs, cand: _Candidate, obj_out: np.ndarray, img_out: np.ndarray, camera: Camera, sigma: float
) -> tuple[float, float]:
    """Mahalanobis chi-square (8 dof) and RMS (px) of a left-out marker under the others' pose.

    The prediction's covariance is ``sigma^2 (I + J_out (J_rest^T J_rest)^-1 J_out^T)``: the
    corner noise plus the uncertainty of the pose fitted without it.
    """
    T = cand.T_world_camera
    r, _ = _residuals(obj_out, img_out, camera.K, camera.dist, cand.R_wc, cand.C, False)
    J_rest = pose_jacobian(obs_rest.obj, T, camera)
    J_out = pose_jacobian(obj_out, T, camera)
    try:
        S = np.eye(len(r)) + J_out @ np.linalg.solve(J_rest.T @ J_rest, J_out.T)
        chi2 = float(r @ np.linalg.solve(S, r)) / sigma**2
    except np.linalg.LinAlgError:
        chi2 = float(r @ r) / sigma**2
    rms = float(np.sqrt(np.mean(np.sum(r.reshape(-1, 2) ** 2, axis=1))))
    return chi2, rms


#: 8 F(8, nu; 1 - OUTLIER_P) for nu degrees of freedom of the others' fit (computed by numerical
#: integration of the F distribution; the limit is the chi-square(8) quantile).
_OUTLIER_F8 = (
    (10, 125.9),
    (14, 83.66),
    (18, 67.01),
    (26, 53.0),
    (34, 46.9),
    (42, 43.51),
    (58, 39.87),
    (90, 36.78),
    (180, 34.21),
    (math.inf, OUTLIER_CHI2),
)


def _outlier_threshold(nu: float, sigma_known: bool) -> float:
    """The chi-square a left-out marker must exceed: chi-square(8) or 8 F(8, nu), interpolated in 1/nu."""
    if sigma_known:
        return OUTLIER_CHI2
    if nu <= _OUTLIER_F8[0][0]:
        return _OUTLIER_F8[0][1] * (_OUTLIER_F8[0][0] / max(nu, 1.0)) ** 2  # steeply more careful below
    for (n0, t0), (n1, t1) in zip(_OUTLIER_F8, _OUTLIER_F8[1:]):
        if nu <= n1:
            x0, x1, x = 1.0 / n0, (0.0 if math.isinf(n1) else 1.0 / n1), 1.0 / nu
            return math.exp(math.log(t1) + (math.log(t0) - math.log(t1)) * (x - x1) / (x0 - x1))
    return OUTLIER_CHI2


def _screen(obs: _Obs, best: _Candidate, camera: Camera, corner_sigma_px: float | None) -> bool:
    """Cheap test: could one marker be an outlier? (per-marker residuals against a robust noise level)."""
    r = best.r
    if r is None:  # a solver's pose not refined (its residuals were left for later): compute them now
        r, _ = _residuals(obs.obj, obs.img, camera.K, camera.dist, best.R_wc, best.C, False)
    per = np.sum(r.reshape(-1, 8) ** 2, axis=1)  # sigma^2 * chi-square of each marker (8 values)
    # A misplaced marker drags the pose and spreads its error over the others, at worst
    # evenly: be generous here (this only decides whether the leave-one-out test runs), and
    # look also at the overall fit, against the noise when it is given.
    overall_rms = math.sqrt(float(np.sum(per)) / (4 * len(per)))
    if overall_rms > max(OUTLIER_MIN_RMS_PX, 3.0 * (corner_sigma_px or 0.0)):
        return True
    if float(per.max()) <= (OUTLIER_CHI2 / 3) * OUTLIER_SIGMA_FLOOR_PX**2:
        return False  # every marker fits within the noise floor: nothing to look for
    robust = float(np.median(per)) / 8.0
    sigma2 = max((corner_sigma_px or 0.0) ** 2, robust, OUTLIER_SIGMA_FLOOR_PX**2)
    rms = np.sqrt(per / 4.0)
    return bool(np.any((per / sigma2 > OUTLIER_CHI2 / 3) & (rms > OUTLIER_MIN_RMS_PX / 2)))


def _reject_outliers(obs: _Obs, marker_map, camera, method, refine_lm, corner_sigma_px, cands, unrefined):
    """Leave-one-out: drop the marker whose removal explains the others best, while it is inconsistent."""
    rejected: list[int] = []
    while len(obs.ids) >= 3 and _screen(obs, cands[0], camera, corner_sigma_px):
        best = None
        for k, mid in enumerate(obs.ids):
            keep = [i for j, i in enumerate(obs.ids) if j != k]
            sel = np.r_[0 : 4 * k, 4 * k + 4 : len(obs.obj)]
            rest = _Obs(keep, obs.obj[sel], obs.img[sel])
            try:
                rc, ru, _ = _solve(rest, marker_map, camera, method, refine_lm)
            except PoseError:
                continue
            if _cheirality(rest, rc[0]) is not None:
                continue  # no pose a camera can have
            if best is None or rc[0].sse < best[0]:
                best = (rc[0].sse, k, mid, rest, rc, ru)
        if best is None:
            break
        score, k, mid, rest, rc, ru = best
        dof = 2 * len(rest.obj) - 6
        if corner_sigma_px is None:
            sigma = max(math.sqrt(score / dof), OUTLIER_SIGMA_FLOOR_PX)
        else:
            sigma = float(corner_sigma_px)
        chi2, rms = _marker_chi2(rest, rc[0], obs.obj[4 * k : 4 * k + 4], obs.img[4 * k : 4 * k + 4], camera, sigma)
        if chi2 <= _outlier_threshold(dof, corner_sigma_px is not None) or rms <= OUTLIER_MIN_RMS_PX:
            break
        rejected.append(mid)
        obs, cands, unrefined = rest, rc, ru
    return obs, cands, unrefined, rejected


# ---------------------------------------------------------------------------------------
# Public entry points
# ---------------------------------------------------------------------------------------
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
        if not (ok and np.isfinite(corner_sigma_px) and corner_sigma_px > 0):
            raise PoseError(f"corner_sigma_px must be a positive number of pixels, got {corner_sigma_px!r}")
    return method


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
    if dets and not np.isfinite(np.stack([d.corners for d in dets])).all():
        k, d = next((k, d) for k, d in enumerate(dets) if not np.isfinite(d.corners).all())
        raise PoseError(f"detections[{k}] (marker {d.id}) has NaN or infinite corners: {d.corners.tolist()}")
    return dets, marker_map, camera


def estimate_pose(
    detections: Sequence[Detection],
    marker_map: MarkerMap,
    camera: Camera,
    method: str = "auto",
    *,
    refine_lm: bool | None = None,
    reject_outliers: bool = True,
    corner_sigma_px: float | None = None,
) -> Pose:
    """The camera's pose in the world from detected markers, using every marker the map knows.

    Parameters
    ----------
    detections : list of Detection
        Detected markers (pixel corners TL, TR, BR, BL). Ids not in the map are
        ignored and listed in ``Pose.ignored_ids``. An id detected twice keeps
        its largest detection.
    marker_map : MarkerMap or path
        Where the markers are (world corners, mm). A path (str or
        ``pathlib.Path``) is read with :meth:`MarkerMap.load`.
    camera : Camera or path
        Intrinsics and distortion at the resolution the corners were detected
        at. A path is read with :meth:`Camera.load`.
    method : {"auto", "ippe", "ippe_square", "sqpnp", "iterative", "epnp"}
        ``"auto"`` (default) chooses by the data: ``ippe_square`` for one marker,
        ``ippe`` for coplanar corners (both solutions kept), ``sqpnp`` for
        markers on several planes, always followed by Levenberg-Marquardt on the
        reprojection error. A named method runs that OpenCV solver alone (no
        LM unless ``refine_lm=True``) so solvers can be compared; ``"iterative"``
        is OpenCV's own LM from a DLT/homography start.
    refine_lm : bool, optional
        Refine with Levenberg-Marquardt on the reprojection error (fidlearn's
        own, :func:`refine_pose_lm`: it minimises what ``cv2.solvePnPRefineLM``
        does but runs to the optimum on far, poorly conditioned views).
        Default: True for ``"auto"``, False for a named method.
    reject_outliers : bool
        With 3 or more markers, leave out a marker that disagrees with the
        others (a marker measured wrongly on the wall) and list it in
        ``Pose.rejected_ids``. The check is cheap: leave-one-out solves run only
        when a marker's residual stands out from the others'. A marker is
        rejected when its residual, predicted from the pose of the others, fails
        the nested-model test at ``OUTLIER_P`` (chi-square with 8 degrees of
        freedom when ``corner_sigma_px`` is given, else F(8, nu) with the noise
        estimated from the others) and its RMS is above ``OUTLIER_MIN_RMS_PX``. With 2 markers nobody can tell which is wrong:
        nothing is rejected, but ``Pose.marker_rms_px`` shows the disagreement.
    corner_sigma_px : float, optional
        Standard deviation (px, per coordinate) of the corner noise. If None it
        is estimated from the residuals with ``2N - 6`` degrees of freedom,
        blended with a prior of ``PRIOR_SIGMA_PX`` worth ``PRIOR_DOF`` degrees of
        freedom (so one marker's 2 degrees of freedom do not claim a perfect
        fit), and never below ``MIN_SIGMA_PX``; the covariance is then widened
        for the uncertainty of that estimate (see :attr:`Pose.covariance`).

    Returns
    -------
    Pose
        ``Pose.ambiguous`` is True when the second planar solution's extra sum
        of squared residuals is below ``AMBIGUITY_CHI2 * sigma^2``: the
        likelihood ratio of the two poses is then above ``exp(-9/2)`` and the
        corners cannot rule out the alternative. Only when the fit is good: a
        sigma estimated from the residuals counts at most
        ``AMBIGUITY_MAX_SIGMA_PX`` here (larger residuals are a wrong map or
        camera, not noise, and make no second pose "as good").

    Raises
    ------
    NoMarkersError
        No detected marker is in the map.
    PoseError
        Bad inputs; a marker whose image corners are not a convex
        quadrilateral running clockwise on screen (TL, TR, BR, BL as detection
        reports them: collinear, repeated, mirrored or shuffled corners); no
        pose that sees every used marker from its printed side with every
        corner in front of the camera (a marker turned the wrong way in the
        map); a best fit whose RMS reprojection error is above
        ``max(BAD_FIT_MIN_PX, BAD_FIT_REL * median marker side in px)`` (the
        corners do not fit the map: wrong positions, rotations, units, marker
        size or camera); or a named method that cannot solve this data.
    """
    dets, marker_map, camera = _check_inputs(detections, marker_map, camera)
    method = _check_options(method, refine_lm, reject_outliers, corner_sigma_px)
    if refine_lm is None:
        refine_lm = method == "auto"
    refine_lm = bool(refine_lm)

    corners_px: dict[int, np.ndarray] = {}
    ignored: list[int] = []
    for d in dets:
        if d.id not in marker_map:
            if d.id not in ignored:
                ignored.append(d.id)
            continue
        if d.id in corners_px and corners_px[d.id] is not None:
            prev = Detection(d.id, corners_px[d.id])
            if prev.side_px >= d.side_px:
                continue
        corners_px[d.id] = d.corners
    if not corners_px:
        seen = sorted({d.id for d in dets})
        if seen:
            what = f"the image shows markers {seen}, none of which is in the map"
        else:
            what = "no marker was detected"
        raise NoMarkersError(
            f"{what}; the map ({marker_map.source}) has ids {marker_map.ids} in dictionary "
            f"{marker_map.dictionary}. Check that the printed markers come from {marker_map.dictionary} "
            "(detect with the map's dictionary), that the map lists the ids on the wall, and that the "
            "markers are in view, in focus and large enough"
        )

    ids = sorted(corners_px)
    world, faces = _world(marker_map)
    obs = _make_obs(ids, corners_px, world, faces)
    _check_quads(obs.ids, obs.img)
    cands, unrefined, method_used = _solve(obs, marker_map, camera, method, refine_lm)
    rejected: list[int] = []
    if reject_outliers and len(ids) >= 3:
        obs, cands, unrefined, rejected = _reject_outliers(
            obs, marker_map, camera, method, refine_lm, corner_sigma_px, cands, unrefined
        )

    problem = _cheirality(obs, cands[0])  # not None: every candidate breaks it (_solve puts the others first)
    rms = math.sqrt(cands[0].sse / len(obs.obj))
    side = float(np.median(_side_px(obs.img))) if rms > BAD_FIT_MIN_PX else 0.0  # the limit is at least the floor
    if rms > max(BAD_FIT_MIN_PX, BAD_FIT_REL * side):
        what = (
            f"reprojection error {rms:.1f} px for markers {obs.ids}, which are about {side:.0f} px wide in the "
            "image (a pose that fits leaves a pixel or two); check the map's positions and rotations, the marker "
            "size, the units, the corner order (TL, TR, BR, BL) and the camera file"
        )
        note = f" ({cands[0].problem_short})" if problem is not None else ""
        raise PoseError(f"the corners do not fit the map: {what}{note}")
    if problem is not None:
        raise PoseError(problem)

    dof = 2 * len(obs.obj) - 6
    sigma = _sigma(cands[0].sse, dof, corner_sigma_px)
    # The ambiguity test's noise: residuals far above any detector's noise are a wrong map or
    # camera, not noise, and must not make a poorer second pose look "as good" (nor hide the
    # first pose's misfit behind it).
    sigma_amb = sigma if corner_sigma_px is not None else min(sigma, AMBIGUITY_MAX_SIGMA_PX)
    JtJ = cands[0].JtJ
    if JtJ is None:
        J = pose_jacobian(obs.obj, cands[0].T_world_camera, camera)
        JtJ = J.T @ J
    # The other planar solution (the "flip"). Refined, when LM keeps it apart as a second
    # minimum; else as IPPE gave it, when LM ran from it into the first one along a flat valley.
    # It counts as another answer when it lies outside the 3-sigma ellipsoid of the best pose
    # (squared Mahalanobis distance above AMBIGUITY_CHI2); it is "as good" (ambiguous) when its
    # extra sum of squared residuals is below AMBIGUITY_CHI2 sigma^2. Near a single quadratic
    # minimum the two numbers are equal, so a merely nearby pose is never called ambiguous;
    # both hold only when the error surface is far from quadratic, which is the flip.
    # Only a pose a camera can have counts (:func:`_cheirality`).
    alt = next(
        (
            c
            for c in cands[1:]
            if _mahalanobis2(cands[0], c, JtJ, sigma_amb) > AMBIGUITY_CHI2 and _cheirality(obs, c) is None
        ),
        None,
    )
    if alt is None and unrefined is not cands:
        far = [
            c
            for c in unrefined
            if c.sse > cands[0].sse
            and _mahalanobis2(cands[0], c, JtJ, sigma_amb) > AMBIGUITY_CHI2
            and _cheirality(obs, c) is None
        ]
        alt = min(far, key=lambda c: c.sse) if far else None
    ambiguous = alt is not None and (alt.sse - cands[0].sse) < AMBIGUITY_CHI2 * sigma_amb**2

    def build(c: _Candidate, alternative: Pose | None, how: str, JtJ_c: np.ndarray | None = None) -> Pose:
        T_world_camera = c.T_world_camera
        if c.r is None:
            c.r, _ = _residuals(obs.obj, obs.img, camera.K, camera.dist, c.R_wc, c.C, False)
            c.sse = float(c.r @ c.r)
        r = c.r.reshape(-1, 4, 2)
        residuals = {i: r[k] for k, i in enumerate(obs.ids)}
        for i in rejected:
            ri, _ = _residuals(world[i], corners_px[i], camera.K, camera.dist, c.R_wc, c.C, False)
            residuals[i] = ri.reshape(4, 2)
        if JtJ_c is None:
            Jc = pose_jacobian(obs.obj, T_world_camera, camera)
            JtJ_c = Jc.T @ Jc
        cov = _covariance_from(JtJ_c, sigma)  # one noise level for the data, whichever pose
        if cov is not None and corner_sigma_px is None:
            cov = cov * _estimated_sigma_inflation(dof + PRIOR_DOF)
        if ambiguous and alternative is not None and cov is not None and alternative.covariance is not None:
            # Two poses explain the corners: report the second moment about this pose of the
            # two-pose mixture, weighted by likelihood, so its ellipsoid reaches the other one.
            w_alt = 1.0 / (1.0 + math.exp(min((alt.sse - c.sse) / (2 * sigma_amb**2), 700.0)))
            d = np.r_[_rotvec(alt.R_wc @ c.R_wc.T), alt.C - c.C]
            cov = (1 - w_alt) * cov + w_alt * (alternative.covariance + np.outer(d, d))
        return Pose(
            T_world_camera=T_world_camera,
            marker_ids=tuple(obs.ids),
            residuals_px=dict(sorted(residuals.items())),
            reprojection_rms_px=math.sqrt(c.sse / len(obs.obj)),
            covariance=cov,
            sigma_px=sigma,
            ambiguous=ambiguous,
            alternative=alternative,
            ignored_ids=tuple(ignored),
            rejected_ids=tuple(rejected),
            method=how,
        )

    alt_how = method_used if alt is not None and alt.refined else method_used.replace("+lm", "") + " (not refined)"
    if alt is None:
        return build(cands[0], None, method_used, JtJ)
    if ambiguous:  # its covariance enters this pose's
        return build(cands[0], build(alt, None, alt_how), method_used, JtJ)
    return build(cands[0], lambda: build(alt, None, alt_how), method_used, JtJ)


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
        OpenCV detector parameters, passed to ``detect_markers(params=...)``.
    only_map_markers : bool
        Look only for the map's ids (the default, faster); False to detect the
        whole dictionary and list the other ids in ``Pose.ignored_ids``.
    **kw
        Passed to :func:`estimate_pose` (``method``, ``refine_lm``,
        ``reject_outliers``, ``corner_sigma_px``).

    Returns
    -------
    Pose

    Raises
    ------
    ImageError
        ``image`` is not an image array.
    NoMarkersError
        No marker of the map is detected.
    PoseError
        Bad arguments, or the corners do not give a pose (see :func:`estimate_pose`).
    """
    from .detection import detect_markers  # noqa: PLC0415 (keeps pose importable on its own)

    # every argument is checked before the (costly) detection
    if not isinstance(image, np.ndarray):
        from .errors import ImageError

        raise ImageError(
            f"image must be a numpy array (use fidlearn.detection.load_image for a file), got {type(image).__name__}"
        )
    unknown = sorted(set(kw) - _ESTIMATE_OPTIONS)
    if unknown:
        raise PoseError(
            f"locate() got unknown option{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}; it takes "
            f"refine, detector_params and estimate_pose's {', '.join(sorted(_ESTIMATE_OPTIONS))}"
        )
    _check_options(
        kw.get("method", "auto"), kw.get("refine_lm"), kw.get("reject_outliers", True), kw.get("corner_sigma_px")
    )
    marker_map = _as_map(marker_map)
    camera = _as_camera(camera).for_image(image)
    det_kw = {} if refine is None else {"refine": refine}
    if detector_params is not None:
        det_kw["params"] = detector_params
    if not isinstance(only_map_markers, (bool, np.bool_)):
        raise PoseError(f"only_map_markers must be True or False, got {only_map_markers!r}")
    ids = marker_map.ids if only_map_markers else None
    detections = detect_markers(image, dictionary=marker_map.dictionary, ids=ids, **det_kw)
    if not detections and only_map_markers:
        # nothing of the map: detect the whole dictionary once, so the error lists what is in view
        detections = detect_markers(image, dictionary=marker_map.dictionary, **{**det_kw, "refine": "none"})
    return estimate_pose(detections, marker_map, camera, **kw)


_ESTIMATE_OPTIONS = frozenset({"method", "refine_lm", "reject_outliers", "corner_sigma_px"})
