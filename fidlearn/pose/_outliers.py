"""Markers that disagree with the others (measured wrongly on the wall): a screen with a stated false-alarm rate,
then leave-one-out fits from the pose of all and the nested-model test of the marker that explains most."""

from __future__ import annotations

import math

import numpy as np

from ..camera import Camera
from ..errors import PoseError
from ._checks import _cheirality
from ._observations import _Candidate, _Obs
from ._refine import _lm, _residuals
from ._solvers import _solve
from ._stats import _beta_isf_int, _chi2_isf_even

#: False-alarm probability of the test that rejects a marker (per marker tested): its 8
#: residuals, predicted from the pose of the others, must have a Mahalanobis chi-square
#: above the chi-square(8) quantile (sigma given) or above 8 F(8, nu) (sigma estimated from
#: the others' nu degrees of freedom: the nested-model F test)...
OUTLIER_P = 1e-4
#: chi-square(8) quantile at OUTLIER_P (the test's limit with a known sigma).
OUTLIER_CHI2 = 31.83
#: ... and its RMS residual must also be above this many pixels (sub-pixel disagreement
#: is detector bias or calibration, not a misplaced marker).
OUTLIER_MIN_RMS_PX = 0.75
#: Noise assumed in the test of a left-out marker when it is estimated: never below this (px).
OUTLIER_SIGMA_FLOOR_PX = 0.3


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


#: False-alarm probability of the screen on pure noise: the chance that corners with only
#: Gaussian noise (of ``corner_sigma_px`` when given) start the rejection test. Measured in
#: ``benchmarks/bench_estimate.py`` and ``tests/test_pose_outliers.py``.
SCREEN_P = 0.01


def _deletion_q(obs: _Obs, best: _Candidate, camera: Camera) -> np.ndarray | None:
    """Per marker, ``Q_k = r_k^T (I - H_kk)^-1 r_k`` (px^2): how much the sum of squared residuals drops
    when marker k is left out, from the one fit of all (None when the pose is not determined).

    ``H_kk`` is marker k's (8, 8) block of the hat matrix ``J (J^T J)^-1 J^T``. For a model linear
    near the fit this is exact: ``Q_k / sigma^2`` is the chi-square (8 dof) of marker k's corners
    predicted by the pose of the others, ``sse - Q_k`` the others' own sum of squares. No fit of a
    subset is made, so no subset (two coplanar markers) can flip to its other planar solution.
    """
    loo = _leave_one_out(obs, best, camera)
    return None if loo is None else loo[0]


def _leave_one_out(obs: _Obs, best: _Candidate, camera: Camera) -> tuple[np.ndarray, np.ndarray] | None:
    """``(Q, s)`` per marker from the one fit of all, linearised: ``Q`` as in :func:`_deletion_q` and ``s``
    the sum of squares (px^2) of marker k's corners predicted by the pose of the others,
    ``|(I - H_kk)^-1 r_k|^2``. None when the pose is not determined."""
    r, J = best.r, best.J
    if r is None or J is None:
        r, J = _residuals(obs.obj, obs.img, camera.K, camera.dist, best.R_wc, best.C, True)
        best.r, best.sse = r, float(r @ r)
    n = len(obs.ids)
    # Woodbury: (I - J_k (J^T J)^-1 J_k^T)^-1 = I + J_k (J^T J - J_k^T J_k)^-1 J_k^T, the others' J^T J (6 x 6)
    Jb = J.reshape(n, 8, 6)
    Jt = Jb.transpose(0, 2, 1)
    rb = r.reshape(n, 8)
    g = (Jt @ rb[..., None])[..., 0]  # (n, 6): J_k^T r_k
    try:
        x = np.linalg.solve((J.T @ J) - Jt @ Jb, g[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return None
    predicted = rb + (Jb @ x[..., None])[..., 0]  # (I - H_kk)^-1 r_k: marker k's residuals from the others
    return (rb * rb).sum(axis=1) + (g * x).sum(axis=1), (predicted * predicted).sum(axis=1)


def _screen(obs: _Obs, best: _Candidate, camera: Camera, corner_sigma_px: float | None) -> int | None:
    """The marker that might be misplaced, or None: a test with false-alarm rate ``SCREEN_P`` on pure noise.

    With ``corner_sigma_px`` given: the chi-square of the whole fit, ``sse / sigma^2`` against the
    chi-square(2N - 6) quantile at ``1 - SCREEN_P``; when it fires, the marker with the largest
    :func:`_deletion_q`. Without: the noise is unknown, so the test is on ratios, free of it: marker
    k's ``Q_k / sse`` follows Beta(4, (2N - 14) / 2) on pure noise (the nested-model F test of
    leaving it out, with the noise estimated from the others), tested at ``SCREEN_P / n`` for each
    of the n markers (Bonferroni: at most ``SCREEN_P`` for the frame).
    """
    dof = 2 * len(obs.obj) - 6
    if corner_sigma_px is not None:
        if best.r is None:  # a solver's pose not refined (its residuals were left for later)
            r, _ = _residuals(obs.obj, obs.img, camera.K, camera.dist, best.R_wc, best.C, False)
            best.r, best.sse = r, float(r @ r)
        if best.sse / corner_sigma_px**2 <= _chi2_isf_even(SCREEN_P, dof):
            return None
    q = _deletion_q(obs, best, camera)
    if q is None:
        return None
    k = int(np.argmax(q))
    if corner_sigma_px is None and not q[k] > _beta_isf_int(SCREEN_P / len(q), 4, (dof - 8) // 2) * best.sse:
        return None
    return k


def _without(obs: _Obs, k: int) -> _Obs:
    sel = np.r_[0 : 4 * k, 4 * k + 4 : len(obs.obj)]
    return _Obs([i for j, i in enumerate(obs.ids) if j != k], obs.obj[sel], obs.img[sel])


def _rest_fit(obs: _Obs, best: _Candidate, k: int, camera: Camera) -> tuple:
    """The pose of every marker but k, refined by LM from the pose of all: ``(R_wc, C, sse, JtJ)``.

    A local step: it stays on the planar solution of all the markers, however few the others (two
    coplanar markers left alone could flip to their other solution; here they cannot).
    """
    rest = _without(obs, k)
    R_wc, C, sse, _, JtJ = _lm(rest.obj, rest.img, camera.K, camera.dist, best.R_wc, best.C)
    return R_wc, C, sse, JtJ


def _left_out_test(obs: _Obs, k: int, fit: tuple, camera: Camera, corner_sigma_px: float | None) -> bool:
    """Whether marker k disagrees with the others (their pose ``fit``, :func:`_rest_fit`): the nested-model
    test at ``OUTLIER_P``.

    Marker k's corners predicted from the others' pose must fail chi-square(8) (sigma given) or
    8 F(8, nu) (sigma from the others' nu degrees of freedom), with an RMS above ``OUTLIER_MIN_RMS_PX``.
    """
    R_wc, C, sse, JtJ = fit
    dof = 2 * (len(obs.obj) - 4) - 6
    sigma = float(corner_sigma_px) if corner_sigma_px is not None else max(math.sqrt(sse / dof), OUTLIER_SIGMA_FLOOR_PX)
    r_out, J_out = _residuals(
        obs.obj[4 * k : 4 * k + 4], obs.img[4 * k : 4 * k + 4], camera.K, camera.dist, R_wc, C, True
    )
    try:
        S = np.eye(8) + J_out @ np.linalg.solve(JtJ, J_out.T)
        chi2 = float(r_out @ np.linalg.solve(S, r_out)) / sigma**2
    except np.linalg.LinAlgError:
        chi2 = float(r_out @ r_out) / sigma**2
    rms = math.sqrt(float(r_out @ r_out) / 4)
    return chi2 > _outlier_threshold(dof, corner_sigma_px is not None) and rms > OUTLIER_MIN_RMS_PX


#: How many markers, those whose absence lowers the linearised sum of squares most, are refit by LM
#: when the screen fires: the refits agree with the linearised ranking to second order, and a
#: frame of 50 markers then costs 3 refits, not 50.
_SUSPECTS = 3


def _suspects(obs: _Obs, best: _Candidate, camera: Camera) -> list[int]:
    """The markers worth a leave-one-out refit: the ``_SUSPECTS`` largest :func:`_deletion_q` (all when it
    cannot be computed); none when no marker's corners, predicted by the pose of the others, are off by
    even half of ``OUTLIER_MIN_RMS_PX`` (a frame of sharp corners whose small errors are not alike: the
    screen's ratio test fires there, and no marker could be rejected)."""
    n = len(obs.ids)
    loo = _leave_one_out(obs, best, camera)
    if loo is None:
        return list(range(n))
    q, predicted_sq = loo
    if not np.sqrt(predicted_sq.max() / 4) > 0.5 * OUTLIER_MIN_RMS_PX:
        return []
    if n <= _SUSPECTS:
        return list(range(n))
    return [int(j) for j in np.argsort(-q, kind="stable")[:_SUSPECTS]]


def _reject_outliers(obs: _Obs, marker_map, camera, method, refine_lm, corner_sigma_px, cands, unrefined):
    """While :func:`_screen` fires: leave out the marker whose absence explains the others best (the
    :func:`_suspects` left out in turn, :func:`_rest_fit`), if :func:`_left_out_test` says it disagrees with them.

    The poses then come from the solver on the remaining markers, as if only they had been seen.
    """
    rejected: list[int] = []
    while len(obs.ids) >= 3:
        if _screen(obs, cands[0], camera, corner_sigma_px) is None:
            break
        fits = {j: _rest_fit(obs, cands[0], j, camera) for j in _suspects(obs, cands[0], camera)}
        if not fits:
            break
        k = min(fits, key=lambda j: fits[j][2])
        if not _left_out_test(obs, k, fits[k], camera, corner_sigma_px):
            break
        rest = _without(obs, k)
        try:
            rc, ru, _ = _solve(rest, marker_map, camera, method, refine_lm)
        except PoseError:
            break
        if _cheirality(rest, rc[0]) is not None:
            break  # no pose a camera can have without it
        rejected.append(obs.ids[k])
        obs, cands, unrefined = rest, rc, ru
    return obs, cands, unrefined, rejected
