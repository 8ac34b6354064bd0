"""A ChArUco board entry's chess corners in the pose: fitted with the marker corners, each group's noise measured.

The marker corners give the pose first (every step of :func:`~fidlearn.estimate_pose`: the solvers, the outlier
screen, the ambiguity). The chess corners then join them in one weighted least-squares fit in which each marker's
corners may be shifted and scaled in the image as a whole: a marker's outline is where blur, ink and the corner
refinement put it, a little bigger or smaller and off its place (on the robot's photos the markers' apparent size
differs from the board's by up to 5 %), while a chess corner is a saddle point that neither moves. The size error
all markers share is a free parameter (the chess corners fix the scale); each marker's own shift (px per axis)
and size error (relative) are random, of variances measured from the fit (EM, from ``CHESS_START_SHIFT_PX`` and
``CHESS_START_SIZE_REL``): where the markers sit right (a sharp render) they keep their full weight, where they
do not, the chess corners carry the pose. Each group of corners is weighted by ``1 / sigma^2``, its noise
measured from its own residuals (variance components: the group's sum of squares over its redundancy ``2 N_g -
tr(N^-1 A_g) / sigma_g^2``, ``A_g = J_g^T J_g``, ``N`` the fit's normal matrix), starting from the pose's
``corner_sigma_px`` for the markers and ``1 / CHESS_START_RATIO`` of it for the chess corners, iterated to
convergence (at most ``CHESS_ROUNDS``). Chess corners the interpolation placed wrong (residual above
``CHESS_OUTLIER_SIGMA`` sigma_c after the first fit) are left out.

The covariance is the pose's block of ``N^-1 (sum_g k_g A_g / sigma_g^2 + P) N^-1``: each group's measured
noise, widened by ``k_g`` for its estimate (Hotelling, ``nu`` = the group's redundancy), and the markers' own
shifts and size errors (``P`` their precisions). It holds what the residuals show, not errors that every corner
shares (a calibration a little off).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..camera import Camera
from ._refine import _residuals
from ._result import Pose
from ._stats import MIN_SIGMA_PX, _estimated_sigma_inflation

#: The fewest chess corners that join a pose (fewer: the marker corners' pose is kept).
CHESS_MIN_CORNERS = 4
#: The chess corners' noise to start from, ``sigma_m / CHESS_START_RATIO`` (then measured): a saddle point refined
#: on the image is placed several times better than a marker's corner.
CHESS_START_RATIO = 3.0
#: The least chess-corner noise (px) the weights assume: a render's corners can fit to a hundredth of a pixel,
#: which no photo's do; the floor keeps the weights finite.
CHESS_MIN_SIGMA_PX = 0.02
#: Rounds of the fit and the measured noise components.
CHESS_ROUNDS = 30
#: The markers' shift (px per axis) and own size error (relative) to start from; then measured from the fit.
CHESS_START_SHIFT_PX = 0.5
CHESS_START_SIZE_REL = 0.01
#: A chess corner whose residual is above this many sigma_c (after the first fit) is left out.
CHESS_OUTLIER_SIGMA = 5.0


def _growth(img_m: np.ndarray) -> np.ndarray:
    """Each marker corner's image offset from its marker's centre (2N,): a marker's growth per unit of size."""
    q = img_m.reshape(-1, 4, 2)
    return (q - q.mean(axis=1, keepdims=True)).reshape(-1)


def _nuisance(img_m: np.ndarray) -> np.ndarray:
    """The marker corners' nuisance columns (2N, 2M + 1): each marker's shift (x, y), and their common size."""
    M = len(img_m) // 4
    E = np.zeros((2 * len(img_m), 3 * M + 1))
    g = _growth(img_m)
    for m in range(M):
        E[8 * m : 8 * m + 8 : 2, 3 * m] = 1.0
        E[8 * m + 1 : 8 * m + 8 : 2, 3 * m + 1] = 1.0
        E[8 * m : 8 * m + 8, 3 * m + 2] = g[8 * m : 8 * m + 8]
    E[:, -1] = g
    return E


def _fit(obj: np.ndarray, img: np.ndarray, camera: Camera, w: np.ndarray, E: np.ndarray, P: np.ndarray, start: tuple):
    """Gauss-Newton on ``sum w_i |r_i - (E k)_i|^2`` over the pose and the nuisances ``k``, from ``start``.

    ``w`` per point, ``E`` (2N, p) the nuisance columns, ``start`` ``(R_wc, C, k)``. Returns R_wc, C, k, the
    residuals (2N,) with ``E k`` taken out and the Jacobian (2N, 6 + p) there.
    """
    sw = np.repeat(np.sqrt(w), 2)
    R_wc, C, k = start
    prior = np.r_[np.zeros(6), P]

    def at(R, c, k):
        r, J = _residuals(obj, img, camera.K, camera.dist, R, c, True)
        r = r - E @ k
        return r, np.column_stack([J, E]), float(np.sum((sw * r) ** 2) + P @ (k * k))

    r, J, sse = at(R_wc, C, k)
    for _ in range(20):
        Jw = J * sw[:, None]
        g = Jw.T @ (sw * r) - prior * np.r_[np.zeros(6), k]
        try:
            step = np.linalg.solve(Jw.T @ Jw + np.diag(prior), g)
        except np.linalg.LinAlgError:
            break
        dR, _ = cv2.Rodrigues(step[:3].reshape(3, 1))
        R_new, C_new, k_new = dR @ R_wc, C + step[3:6], k + step[6:]
        r_new, J_new, sse_new = at(R_new, C_new, k_new)
        if not sse_new < sse:
            break
        done = sse - sse_new < 1e-10 * sse + 1e-12
        R_wc, C, k, r, J, sse = R_new, C_new, k_new, r_new, J_new, sse_new
        if done:
            break
    return R_wc, C, k, r, J


def _components(r: np.ndarray, J: np.ndarray, n_m: int, s: np.ndarray, P: np.ndarray):
    """The corner noise (px) of the markers and of the chess corners measured from their residuals in the fit
    weighted by ``s``: ``(s, redundancies, A_m, A_c, N^-1)``."""
    groups = (slice(0, 2 * n_m), slice(2 * n_m, None))
    A = [J[g].T @ J[g] for g in groups]
    Ninv = np.linalg.inv(A[0] / s[0] ** 2 + A[1] / s[1] ** 2 + np.diag(np.r_[np.zeros(6), P]))
    red = np.array([max(len(r[g]) - float(np.trace(Ninv @ a)) / sg**2, 1.0) for g, a, sg in zip(groups, A, s)])
    floors = (MIN_SIGMA_PX, CHESS_MIN_SIGMA_PX)
    new = np.array([max(math.sqrt(float(r[g] @ r[g]) / d), f) for g, d, f in zip(groups, red, floors)])
    return new, red, A[0], A[1], Ninv


def _with_chess(
    pose: Pose, obj_m: np.ndarray, img_m: np.ndarray, camera: Camera, obj_c: np.ndarray, img_c: np.ndarray
) -> Pose:
    """``pose`` (from the marker corners ``obj_m``/``img_m``) refitted with the chess corners joined (see the module).

    Returns ``pose`` itself with fewer than :data:`CHESS_MIN_CORNERS` chess corners.
    """
    if len(obj_c) < CHESS_MIN_CORNERS:
        return pose
    n_m = len(obj_m)
    s = np.array([pose.corner_sigma_px, max(pose.corner_sigma_px / CHESS_START_RATIO, CHESS_MIN_SIGMA_PX)])
    keep = _plausible(camera.project(obj_c, pose.T_world_camera) - img_c)
    if keep.sum() < CHESS_MIN_CORNERS:
        return pose
    v = np.array([CHESS_START_SHIFT_PX**2, CHESS_START_SIZE_REL**2])
    E_m = _nuisance(img_m)
    start = (pose.T_world_camera[:3, :3], pose.T_world_camera[:3, 3], np.zeros(E_m.shape[1]))
    for it in range(CHESS_ROUNDS):
        w = np.r_[np.full(n_m, 1.0 / s[0] ** 2), np.full(int(keep.sum()), 1.0 / s[1] ** 2)]
        obj, img = np.concatenate([obj_m, obj_c[keep]]), np.concatenate([img_m, img_c[keep]])
        E = np.zeros((2 * len(obj), E_m.shape[1]))
        E[: 2 * n_m] = E_m
        P = np.r_[np.tile([1.0 / v[0], 1.0 / v[0], 1.0 / v[1]], n_m // 4), 0.0]
        R_wc, C, k, r, J = _fit(obj, img, camera, w, E, P, start)
        start = (R_wc, C, k)
        weights = 1.0 / s**2
        try:
            s, red, A_m, A_c, Ninv = _components(r, J, n_m, s, P)
        except np.linalg.LinAlgError:  # the corners do not determine the pose and the markers' nuisances
            return pose
        second = (k * k + np.diag(Ninv)[6:])[:-1]  # EM: each marker's shift and size, mean and variance
        old, v = (
            v,
            np.array(
                [max(float(np.mean(np.r_[second[0::3], second[1::3]])), 1e-8), max(float(np.mean(second[2::3])), 1e-10)]
            ),
        )
        if it > 0 and np.all(np.abs(v / old - 1) < 1e-3) and np.all(np.abs(s * s * weights - 1) < 1e-3):
            break
        if it == 0:  # a corner the interpolation placed wrong
            far = ~_plausible(r[2 * n_m :].reshape(-1, 2))
            if far.any() and keep.sum() - far.sum() >= CHESS_MIN_CORNERS:
                keep[np.flatnonzero(keep)[far]] = False
    infl = [_estimated_sigma_inflation(d) for d in red]
    meat = weights[0] ** 2 * s[0] ** 2 * infl[0] * A_m + weights[1] ** 2 * s[1] ** 2 * infl[1] * A_c
    cov = (Ninv @ (meat + np.diag(np.r_[np.zeros(6), P])) @ Ninv)[:6, :6]  # the markers' shifts and sizes too
    return _refitted(pose, R_wc, C, r[: 2 * n_m] + E_m @ k, (cov + cov.T) / 2)


def _plausible(residuals: np.ndarray) -> np.ndarray:
    """Which chess corners (residuals (N, 2), px) lie within ``CHESS_OUTLIER_SIGMA`` robust spreads: the spread
    from the median distance (a Rayleigh's is 1.1774 sigma), at least ``CHESS_MIN_SIGMA_PX``, so that one corner
    placed wrong widens neither its own yardstick nor the fit it is judged by."""
    d = np.linalg.norm(residuals, axis=1)
    spread = max(float(np.median(d)) / 1.1774, CHESS_MIN_SIGMA_PX)
    return d <= CHESS_OUTLIER_SIGMA * spread


def _refitted(pose: Pose, R_wc: np.ndarray, C: np.ndarray, r_m: np.ndarray, cov: np.ndarray) -> Pose:
    """``pose`` at the pose the chess corners joined, its marker residuals and covariance there."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R_wc, C
    q = r_m.reshape(-1, 4, 2)
    residuals = dict(zip(pose.marker_ids, q))
    for i, old in pose.residuals_px.items():
        residuals.setdefault(i, old)
    return Pose._trusted(
        T_world_camera=T,
        marker_ids=pose.marker_ids,
        residuals_px=dict(sorted(residuals.items())),
        reprojection_rms_px=math.sqrt(float(r_m @ r_m) / (len(r_m) / 2)),
        covariance=cov if np.all(np.isfinite(cov)) else None,
        corner_sigma_px=pose.corner_sigma_px,
        ambiguous=pose.ambiguous,
        alternative=pose._alternative,
        ignored_ids=pose.ignored_ids,
        rejected_ids=pose.rejected_ids,
        method=pose.method + "+chess",
    )
