"""How uncertain a calibration's intrinsics really are: the corner noise plus what the model cannot explain.

OpenCV's standard deviations (``Calibration.std_intrinsics``) assume every corner's error is
independent white noise of the RMS's size. Real views break that: a board that is not quite
flat, a lens the model describes a little wrong, a corner finder's bias that follows the
squares' shape all leave residuals that are alike within a view. Such a view pulls the
intrinsics its own way, as a whole, and two independent sets of photos of one camera then
differ by several times their stated standard deviations (measured in docs/benchmarks.md).

:func:`intrinsics_uncertainty` measures that pull from the data. Linearised at the solution,
view ``v``'s share of the gradient on the intrinsics is ``s_v = Jv^T r_v`` (``Jv`` its
Jacobian on the intrinsics with its own pose's columns projected out, ``r_v`` its residuals).
With white corner noise of variance ``sigma^2``,
``E[sum_v s_v^T S^-1 s_v] = sigma^2 (p - sum_v tr((S^-1 S_v)^2))`` exactly (``S_v = Jv^T Jv``,
``S = sum_v S_v``, ``p`` free intrinsics). The ratio of what is observed to that expectation,
``k^2``, is how much more each view pulls than white noise would (a per-view random error term
estimated from the data, the scalar form of the view-clustered sandwich covariance): the stated
covariance is OpenCV's times ``max(1, k^2)``. Pooled over every view and parameter, ``k^2``
stays steady with a handful of views, where a full clustered covariance would not.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .. import frames
from ..errors import CalibrationError
from ._models import FISHEYE_NAMES
from .run import INTRINSIC_NAMES

__all__ = ["IntrinsicsUncertainty", "camera_with_uncertainty", "intrinsics_uncertainty"]


@dataclass(frozen=True)
class IntrinsicsUncertainty:
    """The covariance of a calibration's free intrinsics, with and without the views' own error.

    Attributes
    ----------
    names : tuple of str
        The free intrinsics, in order (``fx, fy, cx, cy, k1, ...``; those held fixed left out).
    covariance : ndarray, shape (p, p)
        Their covariance, inflated by ``inflation`` (px and the coefficients' own units).
    white_covariance : ndarray, shape (p, p)
        The covariance white corner noise alone would give (OpenCV's ``stdDeviationsIntrinsics``
        are the square roots of its diagonal).
    inflation : float
        ``max(1, k^2)``: how much the views pull the intrinsics beyond white noise, in variance.
    k2 : float
        The measured ratio itself (about 1 with white noise; below 1 by chance).
    """

    names: tuple
    covariance: np.ndarray
    white_covariance: np.ndarray
    inflation: float
    k2: float

    @property
    def std(self) -> dict:
        """The inflated standard deviations, by name (a dict like ``Calibration.std_intrinsics``)."""
        return dict(zip(self.names, np.sqrt(np.diag(self.covariance)).tolist()))

    @property
    def white_std(self) -> dict:
        """The white-noise standard deviations (OpenCV's), by name."""
        return dict(zip(self.names, np.sqrt(np.diag(self.white_covariance)).tolist()))


def _view_terms(camera, obj: np.ndarray, img: np.ndarray, T: np.ndarray, free: np.ndarray):
    """One view's pose-projected intrinsics Jacobian ``Jv`` (2N, p) and residuals (2N,). With fx held and fy free
    (``CALIB_FIX_ASPECT_RATIO``: fx = a fy), fy's column moves fx with it, as OpenCV's ``aspectRatio`` does."""
    rvec, tvec = frames.rvec_tvec_from_transform(T)
    if camera.model == "fisheye":  # columns: f (2), c (2), k (4), rvec (3), tvec (3), skew
        D = camera.dist.reshape(1, 4)
        proj, J = cv2.fisheye.projectPoints(obj.reshape(-1, 1, 3), rvec.reshape(3, 1), tvec.reshape(3, 1), camera.K, D)
        J_pose, J_int = J[:, 8:14], J[:, :8][:, free]
    else:
        aspect = camera.fx / camera.fy if _tied_aspect(free) else 0.0
        proj, J = cv2.projectPoints(obj.reshape(-1, 1, 3), rvec, tvec, camera.K, camera.dist, aspectRatio=aspect)
        J_pose, J_int = J[:, :6], J[:, 6 : 10 + len(camera.dist)][:, free]
    r = (img.reshape(-1, 2) - proj.reshape(-1, 2)).ravel()
    Jv = J_int - J_pose @ np.linalg.lstsq(J_pose, J_int, rcond=None)[0]
    return Jv, r - J_pose @ np.linalg.lstsq(J_pose, r, rcond=None)[0]


def _tied_aspect(free: np.ndarray) -> bool:
    """Whether fx follows fy (``CALIB_FIX_ASPECT_RATIO``): fx held while fy is free, which no other flag does."""
    return bool(not free[0] and free[1])


def _names(camera) -> tuple:
    """The intrinsics' names in ``[fx, fy, cx, cy, *dist]`` order, for the camera's lens model."""
    return FISHEYE_NAMES if camera.model == "fisheye" else INTRINSIC_NAMES[: 4 + len(camera.dist)]


def _free(cal) -> np.ndarray:
    std = cal.std_intrinsics or {}
    return np.array([std.get(k, 1.0) > 0 for k in _names(cal.camera)], dtype=bool)


def intrinsics_uncertainty(cal) -> IntrinsicsUncertainty:
    """The covariance of a calibration's intrinsics that covers what its views share beyond white noise.

    See the module's docstring for the estimate; in short, OpenCV's covariance times
    ``max(1, k^2)``, ``k^2`` the views' measured pull on the intrinsics over what white corner
    noise of the calibration's RMS would give.

    Parameters
    ----------
    cal : Calibration
        A calibration (``calibrate_checkerboard`` or ``calibrate_charuco``) of the pinhole or the
        fisheye model (``fx, fy, cx, cy, k1..k4``), with its views' points and poses.

    Returns
    -------
    IntrinsicsUncertainty

    Raises
    ------
    CalibrationError
        If ``cal`` is not a calibration with its views (a camera file has none), or holds fewer
        points than parameters.

    Examples
    --------
    >>> from fidlearn import Board, calibrate_checkerboard
    >>> from fidlearn.data import data_path
    >>> cal = calibrate_checkerboard(data_path("calibration"), board=Board.checkerboard((9, 6), 25))
    >>> u = intrinsics_uncertainty(cal)
    >>> bool(u.std["fx"] >= cal.std_intrinsics["fx"])
    True
    """
    views = getattr(cal, "T_camera_board", None)
    if not isinstance(views, dict) or not views:
        raise CalibrationError(
            "the uncertainty needs a calibration with its views (calibrate_checkerboard or "
            "calibrate_charuco), not a camera file: calibrate from the photos"
        )
    free = _free(cal)
    terms = [
        _view_terms(
            cal.camera,
            np.asarray(cal.board_points_mm[n], dtype=float),
            np.asarray(cal.image_points_px[n], dtype=float),
            views[n],
            free,
        )
        for n in views
    ]
    p = int(free.sum())
    dof = sum(len(r) for _, r in terms) - p - 6 * len(terms)
    if dof < 1:
        raise CalibrationError(f"{len(terms)} views give too few points for {p} intrinsics: add views")
    sigma2 = sum(float(r @ r) for _, r in terms) / dof
    S_v = [Jv.T @ Jv for Jv, _ in terms]
    S_inv = _inverse(sum(S_v))
    s = [Jv.T @ r for Jv, r in terms]
    observed = sum(float(g @ S_inv @ g) for g in s)
    expected = sigma2 * (p - sum(float(np.trace(S_inv @ Sv @ S_inv @ Sv)) for Sv in S_v))
    k2 = observed / expected if expected > 0 else 1.0
    white = sigma2 * S_inv
    inflation = max(1.0, k2)
    names = tuple(k for k, f in zip(_names(cal.camera), free) if f)
    return IntrinsicsUncertainty(names, white * inflation, white, inflation, float(k2))


def _inverse(S: np.ndarray) -> np.ndarray:
    """``S``'s inverse, its rows and columns scaled to a unit diagonal first (the distortion coefficients' columns
    are thousands of times the focal length's): a weakly observed coefficient keeps its large variance, as in
    ``Calibration.std_intrinsics``, instead of losing it to the pseudo-inverse's cut-off."""
    d = np.sqrt(np.clip(np.diag(S), 0.0, None))
    d[~(d > 0)] = 1.0
    scale = np.outer(1.0 / d, 1.0 / d)
    try:
        return np.linalg.inv(S * scale) * scale
    except np.linalg.LinAlgError:  # singular: the pseudo-inverse, as for the standard deviations
        return np.linalg.pinv(S * scale) * scale


def camera_with_uncertainty(cal):
    """The calibration's camera carrying the covariance of its intrinsics (:func:`intrinsics_uncertainty`).

    A pose estimated with it (:func:`fidlearn.estimate_pose`, :func:`fidlearn.locate`) adds the effect of
    the calibration's error to its covariance: with many markers the corner noise's share of a pose's error
    is small and the intrinsics' error, the same in every pose and shown by no residual, is most of it.

    Parameters
    ----------
    cal : Calibration
        As for :func:`intrinsics_uncertainty`.

    Returns
    -------
    Camera
        ``cal.camera`` with ``intrinsics_covariance`` over ``fx, fy, cx, cy`` and every distortion
        coefficient (zero for one held fixed).

    Raises
    ------
    CalibrationError
        As :func:`intrinsics_uncertainty`.

    Examples
    --------
    >>> from fidlearn import Board, calibrate_checkerboard
    >>> from fidlearn.data import data_path
    >>> cal = calibrate_checkerboard(data_path("calibration"), board=Board.checkerboard((9, 6), 25))
    >>> cam = camera_with_uncertainty(cal)
    >>> bool(cam.intrinsics_covariance[0, 0] ** 0.5 >= cal.std_intrinsics["fx"])
    True
    """
    from ..camera import Camera

    u = intrinsics_uncertainty(cal)
    cam = cal.camera
    names = _names(cam)
    at = [names.index(n) for n in u.names]
    full = np.zeros((len(names), len(names)))
    full[np.ix_(at, at)] = u.covariance
    if _tied_aspect(_free(cal)):  # fx = a fy: fx's row and column are fy's times a
        full[0], full[:, 0] = cam.fx / cam.fy * full[1], cam.fx / cam.fy * full[:, 1]
        full[0, 0] = (cam.fx / cam.fy) ** 2 * full[1, 1]
    return Camera(cam.K, cam.dist, cam.image_size, cam.source, model=cam.model, intrinsics_covariance=full)
