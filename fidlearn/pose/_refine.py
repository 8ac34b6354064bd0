"""Levenberg-Marquardt on the reprojection error, and the Jacobian of the corners with respect to the camera pose."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..camera import Camera
from ..frames import transform_from_rvec_tvec
from ..frames._rotations import _rotvec

__all__ = ["pose_jacobian", "refine_pose_lm", "PoseRefinement"]

#: Levenberg-Marquardt stops when a step would lower the sum of squared residuals by less than
#: this (px^2): a change of the pose far below its own uncertainty for any realistic corner noise.
_LM_TOL_PX2 = 1e-8
#: ... or by less than this many sigma^2 (sigma^2 estimated as sse / (2N - 6)).
_LM_TOL_SIGMA2 = 1e-3


def pose_jacobian(points_world: np.ndarray, T_world_camera: np.ndarray, camera: Camera) -> np.ndarray:
    """Jacobian (2N, 6) of the projected pixels with respect to the camera pose.

    Parameters
    ----------
    points_world : ndarray, shape (N, 3)
        World points, mm.
    T_world_camera : ndarray, shape (4, 4)
        Camera pose at which to differentiate.
    camera : Camera
        Intrinsics and distortion: OpenCV's pinhole lens, or a fisheye (the chain rule through
        ``cv2.fisheye``'s Kannala-Brandt projection: rows in the fisheye picture's own pixels).

    Returns
    -------
    ndarray, shape (2N, 6)
        Rows ``u0, v0, u1, v1, ...``; columns ``[dtheta (3, rad), dC (3, mm)]``:
        ``dtheta`` a small rotation in world axes applied on the left of
        ``R_world_camera``, ``dC`` a shift of the camera centre in the world.
        ``sigma^2 (J^T J)^-1`` is then the covariance (Cramer-Rao bound at the
        true pose) of the camera pose in those coordinates.

    Examples
    --------
    A point 1 m straight ahead: moving the camera 1 mm to its right (world x here) moves the
    point ``fx / 1000`` px to the left.

    >>> import numpy as np, fidlearn
    >>> cam = fidlearn.Camera.from_fov(60, (640, 480))
    >>> J = pose_jacobian([[0.0, 0.0, 1000.0]], np.eye(4), cam)
    >>> J.shape, bool(np.isclose(J[0, 3], -cam.fx / 1000))
    ((2, 6), True)
    """
    P = np.asarray(points_world, dtype=float).reshape(-1, 3)
    R_wc = T_world_camera[:3, :3]
    C = T_world_camera[:3, 3]
    R_cw = R_wc.T
    d = P - C  # (N, 3) world vectors from the camera centre
    X_c = d @ R_cw.T
    dpx_dXc = _pixels_against_point(X_c, camera)
    # X_c = R_cw0 expm(-[dtheta]x) (P - C): dX_c/dtheta = R_cw0 [d]x ; dX_c/dC = -R_cw0
    skew = np.zeros((len(P), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2] = -d[:, 2], d[:, 1]
    skew[:, 1, 0], skew[:, 1, 2] = d[:, 2], -d[:, 0]
    skew[:, 2, 0], skew[:, 2, 1] = -d[:, 1], d[:, 0]
    A = dpx_dXc @ R_cw  # (N, 2, 3)
    J = np.concatenate([A @ skew, -A], axis=2)
    return J.reshape(-1, 6)


def _pixels_against_point(X_c: np.ndarray, camera: Camera) -> np.ndarray:
    """d(pixel) / d(point in the camera frame) (N, 2, 3) of points ``X_c`` (N, 3): the Jacobian of
    ``cv2.projectPoints`` (``cv2.fisheye.projectPoints`` for a fisheye) with respect to ``tvec`` at
    ``rvec = tvec = 0``."""
    pts = X_c.reshape(-1, 1, 3)
    if camera.model == "fisheye":  # columns: f (2), c (2), k (4), rvec (3), tvec (3), skew (1)
        _, jac = cv2.fisheye.projectPoints(pts, np.zeros((3, 1)), np.zeros((3, 1)), camera.K, camera.dist)
        return jac[:, 11:14].reshape(-1, 2, 3)
    _, jac = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), camera.K, camera.dist)
    return jac[:, 3:6].reshape(-1, 2, 3)


@dataclass(frozen=True, eq=False)
class PoseRefinement:
    """The pose :func:`refine_pose_lm` reached, in OpenCV's convention, and how well it fits.

    Attributes
    ----------
    rvec : ndarray, shape (3,)
        Rotation vector of the refined ``T_camera_world``, rad.
    tvec : ndarray, shape (3,)
        Its translation, mm.
    reprojection_rms_px : float
        RMS over the points of the residual length there (px), ``sqrt(sum |r|^2 / N)``, as
        :attr:`fidlearn.Pose.reprojection_rms_px`.
    """

    rvec: np.ndarray
    tvec: np.ndarray
    reprojection_rms_px: float

    @property
    def T_camera_world(self) -> np.ndarray:
        """The refined extrinsics (4, 4, mm): world points into the camera frame."""
        return transform_from_rvec_tvec(self.rvec, self.tvec)


def refine_pose_lm(
    points_world: np.ndarray,
    points_px: np.ndarray,
    camera: Camera,
    rvec: np.ndarray,
    tvec: np.ndarray,
    *,
    max_iterations: int = 50,
) -> PoseRefinement:
    """Levenberg-Marquardt on the reprojection error from a starting pose.

    The steps are taken on the camera's pose (a small rotation in world axes and
    a shift of the camera centre) with Marquardt's diagonal scaling; the
    Jacobian is :func:`pose_jacobian`. From an IPPE start it usually converges
    in two or three iterations. It minimises the same error as
    ``cv2.solvePnPRefineLM``, which stopped short of the optimum on far,
    poorly conditioned views when this was written (OpenCV 5.0).

    Parameters
    ----------
    points_world : array-like, shape (N, 3)
        Points in the world frame, mm (N >= 3).
    points_px : array-like, shape (N, 2)
        Their observed pixels, px (OpenCV's convention: pixel centres at integers).
    camera : Camera
        Intrinsics and distortion: OpenCV's pinhole lens, or a fisheye (the residuals and their Jacobian
        through ``cv2.fisheye``'s projection, in the fisheye picture's own pixels).
    rvec, tvec : array-like, shape (3,)
        Starting ``T_camera_world`` (OpenCV's convention): rotation vector (rad) and translation (mm).
    max_iterations : int
        At most this many steps.

    Returns
    -------
    PoseRefinement
        ``rvec`` and ``tvec`` of the refined ``T_camera_world`` (rad, mm) and the
        ``reprojection_rms_px`` there.

    Examples
    --------
    Four corners of a 100 mm square 1 m ahead, and a start 1 degree and 10 mm off:

    >>> import numpy as np, fidlearn
    >>> cam = fidlearn.Camera.from_fov(60, (640, 480))
    >>> P = np.array([[-50.0, -50, 1000], [50, -50, 1000], [50, 50, 1000], [-50, 50, 1000]])
    >>> px = cam.project(P, np.eye(4))     # the camera at the world origin
    >>> refined = refine_pose_lm(P, px, cam, np.radians([1.0, 0, 0]), [10.0, 0, 0])
    >>> bool(np.degrees(np.abs(refined.rvec)).max() < 1e-4), bool(np.abs(refined.tvec).max() < 1e-3)  # the truth
    (True, True)
    >>> bool(refined.reprojection_rms_px < 1e-6)
    True
    """
    obj = np.ascontiguousarray(points_world, dtype=np.float64).reshape(-1, 3)
    img = np.ascontiguousarray(points_px, dtype=np.float64).reshape(-1, 2)
    R_cw, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
    R_wc = R_cw.T
    C = -R_wc @ np.asarray(tvec, dtype=np.float64).reshape(3)
    R_wc, C, sse, _, _ = _lm(obj, img, camera.K, camera.dist, R_wc, C, max_iterations, 0.0, camera.model)
    R_cw = R_wc.T
    return PoseRefinement(_rotvec(R_cw), -R_cw @ C, math.sqrt(sse / len(obj)))


_ZERO3 = np.zeros(3)
_ZERO31 = np.zeros((3, 1))
_EYE6 = np.eye(6)
_FLOOR6 = 1e-12 * _EYE6


def _residuals(obj, img, K, dist, R_wc, C, with_jacobian: bool, model: str = "pinhole"):
    """Residuals (2N,) observed minus projected, and optionally the Jacobian (2N, 6) of the projection.

    The same Jacobian as :func:`pose_jacobian`, written for speed (this runs in every LM step); ``model``
    ``"fisheye"`` projects through ``cv2.fisheye`` (residuals in the fisheye picture's pixels).
    """
    r, J, _ = _residuals_and_jacobians(obj, img, K, dist, R_wc, C, with_jacobian, model)
    return r, J


def _residuals_and_jacobians(obj, img, K, dist, R_wc, C, with_jacobian: bool = True, model: str = "pinhole"):
    """:func:`_residuals`, and the Jacobian (2N, 4 + len(dist)) on ``fx, fy, cx, cy`` and the distortion from
    the same projection (None without ``with_jacobian``)."""
    r, J, jac = _projection(obj, img.reshape(-1), K, dist, R_wc, C, with_jacobian, model)
    if jac is None:
        return r, None, None
    return r, J, jac[:, :8] if model == "fisheye" else jac[:, 6 : 10 + len(dist)]


def _projection(obj, img_flat, K, dist, R_wc, C, with_jacobian: bool, model: str):
    """:func:`_residuals` of the observed pixels ``img_flat`` (2N,) and the projection's whole Jacobian (OpenCV's
    columns, the lens's among them; None without ``with_jacobian``): what a Levenberg-Marquardt step needs, the
    lens's columns not cut out."""
    X_c = (obj - C) @ R_wc  # rows: R_cw @ (P - C) = R_wc^T (P - C)
    if model == "fisheye":  # cv2.fisheye's columns: f (2), c (2), k (4), rvec (3), tvec (3), skew (1)
        px, jac = cv2.fisheye.projectPoints(X_c.reshape(-1, 1, 3), _ZERO31, _ZERO31, K, dist)
        pose_columns = jac[:, 8:14]
    else:  # cv2.projectPoints' columns: rvec (3), tvec (3), f (2), c (2), dist
        px, jac = cv2.projectPoints(X_c, _ZERO3, _ZERO3, K, dist)  # (N, 3): N points, as (N, 1, 3) would be
        pose_columns = jac[:, :6]
    r = img_flat - px.reshape(-1)
    if not with_jacobian:
        return r, None, None
    # projectPoints' Jacobian at rvec = tvec = 0 is d(px)/d[w, t] for X_c -> X_c + w x X_c + t. Turning the
    # camera by dtheta (world axes, on the left of R_wc) moves X_c by X_c x (R_cw dtheta), i.e. w = -R_cw dtheta;
    # moving its centre by dC moves X_c by -R_cw dC. So J = jac[:, :6] @ diag(-R_cw, -R_cw): each row's two
    # triples times -R_cw, as one product.
    J = (pose_columns.reshape(-1, 3) @ -R_wc.T).reshape(-1, 6)
    return r, J, jac


def _lm(obj, img, K, dist, R_wc, C, max_iterations=50, tol_sigma2=None, model="pinhole"):
    """Levenberg-Marquardt (Marquardt's diagonal scaling) on the camera pose.

    Returns R_wc, C, the sum of squared residuals, the residuals (2N,) and J^T J (6, 6) there.
    """
    R_wc, C, sse, r, _, JtJ = _lm_full(obj, img, K, dist, R_wc, C, max_iterations, tol_sigma2, model)
    return R_wc, C, sse, r, JtJ


def _lm_full(obj, img, K, dist, R_wc, C, max_iterations=50, tol_sigma2=None, model="pinhole"):
    """:func:`_lm`, returning also the Jacobian (2N, 6) at the end: R_wc, C, sse, r, J, J^T J."""
    img = img.reshape(-1)
    r, J, _ = _projection(obj, img, K, dist, R_wc, C, True, model)
    sse = float(r @ r)
    lam = 1e-4
    JtJ = J.T @ J
    g = J.T @ r
    # Marquardt's scale of the damping, per parameter, max(JtJ_ii, 1e-12) on the diagonal (zeros elsewhere): the
    # same sums as adding lam times it to JtJ's diagonal in place, in two numpy calls per step instead of five
    D = np.maximum(JtJ * _EYE6, _FLOOR6)
    dof = max(len(r) - 6, 1)
    rel = _LM_TOL_SIGMA2 if tol_sigma2 is None else tol_sigma2
    for _ in range(max_iterations):
        # Stop when the next step would move the pose by less than about 0.03 sigma (its
        # squared length in sigma units below 1e-3, sigma estimated from the residuals).
        tol = max(_LM_TOL_PX2, rel * sse / dof)
        A = JtJ + lam * D  # Marquardt: damp the diagonal
        ok, step = cv2.solve(A, g.reshape(6, 1))  # (OpenCV's LU: a fifth of numpy's overhead on 6 x 6)
        if not ok:
            break  # singular: no step
        predicted = float(np.vdot(step, g))  # about twice the decrease a linear model expects
        if not predicted > tol:
            break  # converged: no step left worth taking
        dR, _ = cv2.Rodrigues(step[:3])
        R_new = dR @ R_wc
        C_new = C + step[3:, 0]
        r_new, J_new, _ = _projection(obj, img, K, dist, R_new, C_new, True, model)
        sse_new = float(r_new @ r_new)
        if sse_new < sse:
            done = sse - sse_new <= tol
            R_wc, C, sse, r, J = R_new, C_new, sse_new, r_new, J_new
            JtJ = J.T @ J
            g = J.T @ r
            D = np.maximum(JtJ * _EYE6, _FLOOR6)
            lam = max(lam / 10, 1e-12)
            if done:
                break
        else:
            lam *= 10
            if lam > 1e8:
                break
    return R_wc, C, sse, r, J, JtJ
