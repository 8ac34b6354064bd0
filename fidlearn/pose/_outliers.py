"""Markers that disagree with the others (measured wrongly on the wall): a cheap screen, then leave-one-out."""

from __future__ import annotations

import math

import numpy as np

from ..camera import Camera
from ..errors import PoseError
from ._checks import _cheirality
from ._observations import _Candidate, _Obs
from ._refine import _residuals, pose_jacobian
from ._solvers import _solve

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
