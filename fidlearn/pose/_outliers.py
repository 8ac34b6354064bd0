"""Markers that disagree with the others (measured wrongly on the wall): a screen with a stated false-alarm rate,
then leave-one-out fits, the others solved afresh each time (both planar solutions), and the marker whose
absence explains the others best: left out when it is the marker displaced in its plane (2 degrees of freedom,
the way a marker is misplaced), else when it fails the nested-model test (its 8 corner coordinates free: a
marker turned, a wrong corner)."""

from __future__ import annotations

import functools
import math
from typing import cast

import cv2
import numpy as np

from .. import _stats
from ..camera import Camera
from ..errors import PoseError
from ._checks import _cheirality
from ._noise import _SHIFT8, SPLIT_MIN_MARKERS
from ._noise_fast import _noise_parts_fast as _noise_parts  # the same numbers in closed forms
from ._noise_fast import _pose_covariance_fast as _pose_covariance
from ._observations import _UNCHECKED, _Candidate, _Obs
from ._refine import _residuals
from ._solvers import _solve
from ._stats import _solve_each

#: False-alarm probability of the test that rejects a marker (per marker tested): its 8
#: residuals, predicted from the pose of the others, must have a Mahalanobis chi-square
#: above the chi-square(8) quantile (sigma given) or above 8 F(8, nu) (sigma estimated from
#: the others' nu degrees of freedom: the nested-model F test)...
OUTLIER_P = 1e-4
#: chi-square(8) quantile at OUTLIER_P (the test's limit with a known sigma): 31.83.
OUTLIER_CHI2 = _stats.chi2_isf(OUTLIER_P, 8)
#: ... and its RMS residual must also be above this many pixels (sub-pixel disagreement
#: is detector bias or calibration, not a misplaced marker).
OUTLIER_MIN_RMS_PX = 0.75
#: A marker whose corners, predicted from the others' pose, are off by less than this fraction of its side (RMS,
#: px over px) is kept: a board bent by a fraction of a millimetre or a camera model a little off does that to
#: markers, a marker moved on its wall is off by a good part of its size (lesson 08: 80-140 mm moves of 150 mm
#: markers; the tests: 30 mm of 150 mm). Chosen on the robot's photos 0, 2, ..., 14 (a 5x7 ChArUco board whose
#: outer column is 0.3-0.8 mm off flat): each photo's worst marker is off by 2.7-6.7 % of its side, 11 % on
#: photo 2 (where the shared-noise test keeps it); held out, the odd photos' worst are 3.6-7.3 %.
MODEL_ERROR_REL = 0.1
#: Noise assumed in the test of a left-out marker when it is estimated: never below this (px).
OUTLIER_SIGMA_FLOOR_PX = 0.3


#: Below this many degrees of freedom of the others' fit the limit grows as 1 / nu^2 from its value here,
#: steeply more careful than F itself would be wary of so few.
_OUTLIER_MIN_NU = 10


def _outlier_threshold(nu: float, sigma_known: bool) -> float:
    """The chi-square a left-out marker must exceed: chi-square(8) at ``OUTLIER_P`` with sigma known, else
    8 F(8, nu; 1 - OUTLIER_P) (125.9 at nu = 10, 34.21 at 180, OUTLIER_CHI2 in the limit)."""
    if sigma_known:
        return OUTLIER_CHI2
    if nu <= _OUTLIER_MIN_NU:
        return _outlier_f8(_OUTLIER_MIN_NU) * (_OUTLIER_MIN_NU / max(nu, 1.0)) ** 2
    return _outlier_f8(float(nu))


@functools.lru_cache(maxsize=256)
def _outlier_f8(nu: float) -> float:
    return 8.0 * _stats.f_isf(OUTLIER_P, 8, nu)


# The screen's quantiles depend on the number of markers alone: each is computed once (the same numbers).
_f_isf = functools.lru_cache(maxsize=256)(_stats.f_isf)
_chi2_isf = functools.lru_cache(maxsize=256)(_stats.chi2_isf)
_beta_isf = functools.lru_cache(maxsize=256)(_stats.beta_isf)


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
    stats = _marker_stats(obs, best, camera)
    return None if stats is None else stats[0]


def _marker_stats(obs: _Obs, best: _Candidate, camera: Camera) -> tuple[np.ndarray, tuple] | None:
    """:func:`_deletion_q` (n,) and what :func:`_move_drop` needs too: the per-marker blocks ``J_k^T J_k``
    (n, 6, 6) and ``J_k^T r_k`` (n, 6), ``J^T J``, ``J`` and ``r``; and, for :func:`_suspects`, each marker's
    corners' residuals (n, 8) predicted by the pose of the others, ``(I - H_kk)^-1 r_k`` (px).
    None when the pose is not determined. Computed once per candidate pose (the screen, the test of a move
    and the choice of suspects all read it)."""
    if best.marker_stats is _UNCHECKED:
        best.marker_stats = _marker_stats_of(obs, best, camera)
    return cast("tuple[np.ndarray, tuple] | None", best.marker_stats)


def _marker_stats_of(obs: _Obs, best: _Candidate, camera: Camera) -> tuple[np.ndarray, tuple] | None:
    r, J = _fit_residuals(obs, best, camera)
    n = len(obs.ids)
    # Woodbury: (I - J_k (J^T J)^-1 J_k^T)^-1 = I + J_k (J^T J - J_k^T J_k)^-1 J_k^T, the others' J^T J (6 x 6)
    Jb = J.reshape(n, 8, 6)
    Jt = Jb.transpose(0, 2, 1)
    rb = r.reshape(n, 8)
    Jtr = Jt @ rb[..., None]  # (n, 6, 1): J_k^T r_k
    g = Jtr[..., 0]
    JtJ = best.JtJ if best.JtJ is not None and J is best.J else J.T @ J  # LM's own, of this very J
    B = Jt @ Jb  # (n, 6, 6): J_k^T J_k
    x = _solve_each(JtJ - B, Jtr)  # (n, 6, 1): (the others' J^T J)^-1 J_k^T r_k
    if x is None:
        return None
    predicted = rb + (Jb @ x)[..., 0]  # (I - H_kk)^-1 r_k: marker k's residuals from the others
    # Q_k = r_k^T (I - H_kk)^-1 r_k = r_k . predicted_k (= |r_k|^2 + g_k . x_k)
    return (rb * predicted).sum(axis=1), (B, g, JtJ, J, r, predicted)


def _move_drop(obs: _Obs, blocks: tuple, M: np.ndarray, Jtr: np.ndarray, k: int) -> float | None:
    """:func:`_displacement_drop` of marker k from :func:`_marker_stats`' blocks, ``M = (J^T J)^-1`` and
    ``J^T r``; None when the pose absorbs its moves entirely.

    A corner's pixels move with its world point as minus with the camera centre: the marker's moves ``E``
    (3, 2) give ``D_k = -J_k[:, 3:] E``, so ``D_k^T D_k``, ``D_k^T J_k`` and ``D_k^T r_k`` are ``E^T`` times
    blocks of ``J_k^T J_k`` and ``J_k^T r_k``: no pixel-sized array is formed.
    """
    B, g = blocks[:2]
    P = obs.obj[4 * k : 4 * k + 4]
    Et = P[1::-1] - P[::3]  # (2, 3): corners 1 - 0 and 0 - 3, the marker's x and y axes (any basis will do)
    W = Et @ B[k, 3:]  # (2, 6): -D_k^T J_k
    WM = W @ M
    (a, b), (_, c) = (W[:, 3:] @ Et.T - WM @ W.T).tolist()  # D_k^T (I - H) D_k, H = J M J^T
    h0, h1 = (Et @ g[k, 3:] - WM @ Jtr).tolist()  # -D_k^T (I - H) r
    det = a * c - b * b
    if not det > 1e-12 * a * c:
        return None
    return max((c * h0 * h0 - 2 * b * h0 * h1 + a * h1 * h1) / det, 0.0)


#: False-naming probability (per frame) of the test of a marker displaced in its wall's plane (the way a
#: marker is misplaced: its 2 coordinates on the wall measured wrongly): the sum of squares that such a
#: move of marker k would remove (:func:`_displacement_drop`), over sigma^2, against the chi-square(2)
#: quantile at ``1 - DISPLACEMENT_P / n`` for n markers (sigma given), else 2 F(2, 2N - 8) (sigma
#: estimated from the residuals of that model, never below ``OUTLIER_SIGMA_FLOOR_PX``). Part of the
#: screen's ``SCREEN_P``: on pure noise a good marker is named in at most this share of the frames. Each
#: such frame loses a good marker, and with 3 markers in a row at 1 px half of them then have a gross
#: error (the pose of 2 markers is that much less precise), so the level trades the power against the
#: gross errors it adds. Measured on ``benchmarks/bench_estimate.py``'s scenes (3 markers, 1 px; 2000 with a
#: marker moved 30 mm, 5000 of pure noise), noise estimated: at 0.1, 0.2, 0.3, 0.4 % named 93.0, 94.3, 94.8,
#: 95.3 %, gross error +0.08, +0.12, +0.18, +0.28 points; noise given: at 0.1, 0.2, 0.4 % named 96.5, 96.7,
#: 96.8 %, +0.04, +0.10, +0.16 points. Rejection must not add gross error (0.3 points at most): 0.2 %.
DISPLACEMENT_P = 0.002
#: ... and its move must explain more than this RMS (px) over its 4 corners, ``sqrt(drop / 4)``: a marker
#: that seems off by a pixel or less is the detector's bias or the calibration, not the map.
DISPLACEMENT_MIN_RMS_PX = 1.0
_DISPLACEMENT_DOF = 2


def _fit_residuals(obs: _Obs, best: _Candidate, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Residuals (2N,) and Jacobian (2N, 6) at ``best`` (computed and its residuals kept when not yet there)."""
    r, J = best.r, best.J
    if r is None or J is None:
        r, J = _residuals(obs.obj, obs.img, camera.K, camera.dist, best.R_wc, best.C, True)
        best.r, best.sse = r, float(r @ r)
    return r, J


def _displacement_drop(obs: _Obs, best: _Candidate, camera: Camera) -> np.ndarray | None:
    """Per marker, how much the sum of squared residuals (px^2) drops when that marker alone may move in
    its plane (2 translations, along its x and y axes), the pose refitted with it.

    The generalised likelihood-ratio statistic of that model against none moved, linearised at the fit
    of all: with ``D_k`` (2N, 2) the derivative of the corners' pixels with respect to marker k's move
    (zero off its 8 rows) and ``P = I - J (J^T J)^-1 J^T`` the projection out of the pose, the drop is
    ``(D_k^T P r)^T (D_k^T P D_k)^-1 (D_k^T P r)``: chi-square(2) sigma^2 on pure noise. A corner's
    pixel derivative with respect to its world point is minus that with respect to the camera centre,
    so ``D_k`` comes from the Jacobian already there (:func:`_marker_stats`). At most :func:`_deletion_q`'s
    ``Q_k`` (freeing the 8 coordinates includes this move). None when the pose or a move is not determined.
    """
    stats = _marker_stats(obs, best, camera)
    if stats is None:
        return None
    _, blocks = stats
    ok, M = cv2.invert(blocks[2])
    Jtr = blocks[3].T @ blocks[4]
    drops = [_move_drop(obs, blocks, M, Jtr, k) for k in range(len(obs.ids))] if ok else [None]
    return None if None in drops else np.array(drops)


def _displacement_limit(sse: float, n: int, corner_sigma_px: float | None) -> float:
    """The drop (px^2) above which a marker fails the test of a move at ``DISPLACEMENT_P / n`` (n markers).

    chi-square(2) with sigma given; else 2 F(2, 2N - 8) with the noise estimated from the residuals left when
    the marker moves, ``s^2 = max((sse - drop) / (2N - 8), OUTLIER_SIGMA_FLOOR_PX^2)``: ``drop / s^2``
    increases with the drop, so the limit is where it equals 2 F.
    """
    p = DISPLACEMENT_P / n
    if corner_sigma_px is not None:
        return float(corner_sigma_px) ** 2 * -2.0 * math.log(p)  # chi-square(2): sf exp(-x / 2)
    nu = 8 * n - 6 - _DISPLACEMENT_DOF
    t = _DISPLACEMENT_DOF * _f_isf(p, 2, nu)
    limit = t * sse / (nu + t)  # drop nu / (sse - drop) = t
    return limit if sse - limit >= nu * OUTLIER_SIGMA_FLOOR_PX**2 else t * OUTLIER_SIGMA_FLOOR_PX**2


def _most_displaced(obs: _Obs, q: np.ndarray, blocks: tuple, limit: float) -> tuple[int, float] | None:
    """The marker whose move explains most, ``(k, drop_k)``, if its drop is above ``limit``; else None.

    A move of marker k is a special case of freeing its 8 coordinates, so its drop is at most ``Q_k``:
    the markers are taken by decreasing ``Q_k`` while that is above the limit and the best drop so far.
    """
    if not q.max() > limit:
        return None
    ok, M = cv2.invert(blocks[2])
    if not ok:
        return None
    Jtr = blocks[3].T @ blocks[4]
    best, top = None, limit
    qs = q.tolist()
    for k in sorted(range(len(qs)), key=qs.__getitem__, reverse=True):
        if not qs[k] > top:
            break
        drop = _move_drop(obs, blocks, M, Jtr, k)
        if drop is not None and drop > top:
            best, top = (k, drop), drop
    return best


def _screen(obs: _Obs, best: _Candidate, camera: Camera, corner_sigma_px: float | None) -> int | None:
    """The marker that might be misplaced, or None: a test with false-alarm rate ``SCREEN_P`` on pure noise.

    Two tests (Bonferroni: at most ``SCREEN_P`` for the frame). A marker displaced in its plane, at
    ``DISPLACEMENT_P``: :func:`_displacement_limit`, the marker named the one whose move explains most
    (:func:`_most_displaced`). Any misfit, at ``SCREEN_P - DISPLACEMENT_P``: with ``corner_sigma_px`` given,
    the chi-square of the whole fit, ``sse / sigma^2`` against the chi-square(2N - 6) quantile; without it
    the noise is unknown, so the test is on ratios, free of it: marker k's ``Q_k / sse`` (:func:`_deletion_q`)
    follows Beta(4, (2N - 14) / 2) on pure noise (the nested-model F test of leaving it out, with the noise
    estimated from the others), tested at ``(SCREEN_P - DISPLACEMENT_P) / n`` per marker; the marker named
    the one with the largest ``Q_k``.
    """
    n, dof = len(obs.ids), 2 * len(obs.obj) - 6
    p_any = SCREEN_P - DISPLACEMENT_P
    whole = False
    if corner_sigma_px is not None:
        if best.r is None:  # a solver's pose not refined (its residuals were left for later)
            r, _ = _residuals(obs.obj, obs.img, camera.K, camera.dist, best.R_wc, best.C, False)
            best.r, best.sse = r, float(r @ r)
        whole = best.sse / corner_sigma_px**2 > _chi2_isf(p_any, dof)
        if not whole and best.sse <= _displacement_limit(best.sse, n, corner_sigma_px):
            return None  # no drop (at most sse) can pass either
    stats = _marker_stats(obs, best, camera)
    if stats is None:
        return None
    q, blocks = stats
    hit = _most_displaced(obs, q, blocks, _displacement_limit(best.sse, n, corner_sigma_px))
    if hit is not None:
        return hit[0]
    k = int(q.argmax())
    if corner_sigma_px is not None:
        return k if whole else None
    return k if q[k] > _beta_isf(p_any / n, 4, (dof - 8) // 2) * best.sse else None


def _named_displaced(obs: _Obs, best: _Candidate, camera: Camera, corner_sigma_px: float | None) -> int | None:
    """The marker displaced in its plane (:func:`_most_displaced` above :func:`_displacement_limit`) if its
    move explains more than ``DISPLACEMENT_MIN_RMS_PX`` RMS over its 4 corners; else None."""
    stats = _marker_stats(obs, best, camera)
    if stats is None:
        return None
    hit = _most_displaced(obs, stats[0], stats[1], _displacement_limit(best.sse, len(obs.ids), corner_sigma_px))
    return hit[0] if hit is not None and math.sqrt(hit[1] / 4) > DISPLACEMENT_MIN_RMS_PX else None


def _without(obs: _Obs, k: int) -> _Obs:
    sel = np.r_[0 : 4 * k, 4 * k + 4 : len(obs.obj)]
    rest = _Obs([i for j, i in enumerate(obs.ids) if j != k], obs.obj[sel], obs.img[sel])
    if obs._faces is not None:
        rest._faces = np.delete(obs._faces, k, axis=0)
    return rest


def _rest_fit(obs: _Obs, marker_map, k: int, camera: Camera) -> tuple | None:
    """The pose of every marker but k, solved afresh: ``(R_wc, C, sse, JtJ, solved)``, ``solved`` what
    :func:`_solve` returned (method ``"auto"``, refined), or None when no pose is found.

    The others are solved as if only they had been seen (coplanar: IPPE's two solutions, each refined by
    LM, the better kept), not refined from the pose of all: a misplaced marker can drag that pose onto
    the other planar solution, from which a local step never reaches the others' own pose.
    """
    rest = _without(obs, k)
    try:
        solved = _solve(rest, marker_map, camera, "auto", True)
    except PoseError:
        return None
    best = solved[0][0]
    if best.problem is not None:
        return None  # no pose a camera can have
    JtJ = best.JtJ
    if JtJ is None:
        _, J = _residuals(rest.obj, rest.img, camera.K, camera.dist, best.R_wc, best.C, True)
        JtJ = J.T @ J
    return best.R_wc, best.C, best.sse, JtJ, solved


def _rest_noise(obs: _Obs, sse: float, corner_sigma_px: float | None) -> tuple[int, float]:
    """The degrees of freedom of a fit of all markers but one, and the noise (px) of the test of the one:
    ``corner_sigma_px`` when given, else estimated from that fit's ``sse``, never below ``OUTLIER_SIGMA_FLOOR_PX``."""
    dof = 2 * (len(obs.obj) - 4) - 6
    if corner_sigma_px is not None:
        return dof, float(corner_sigma_px)
    return dof, max(math.sqrt(sse / dof), OUTLIER_SIGMA_FLOOR_PX)


def _left_out_test(obs: _Obs, k: int, fit: tuple, camera: Camera, corner_sigma_px: float | None) -> bool:
    """Whether marker k disagrees with the others (their pose ``fit``, :func:`_rest_fit`): the nested-model
    test at ``OUTLIER_P``.

    Marker k's corners predicted from the others' pose must fail chi-square(8) (sigma given) or
    8 F(8, nu) (sigma from the others' nu degrees of freedom), with an RMS above ``OUTLIER_MIN_RMS_PX``.
    """
    R_wc, C, sse, JtJ = fit[:4]
    dof, sigma = _rest_noise(obs, sse, corner_sigma_px)
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


#: With up to this many markers every one is left out in turn (a fresh solve of the others each) when the
#: test runs: few markers are where one misplaced marker drags the pose of all furthest, and then the
#: sums of squares linearised at that pose (:func:`_deletion_q`) can rank the markers wrongly.
_LEAVE_EACH_OUT = 8
#: Above ``_LEAVE_EACH_OUT`` markers, how many, those whose absence lowers the linearised sum of squares
#: most, are solved afresh without them: the fits agree with the linearised ranking to second order
#: there, and a frame of 50 markers then costs 3 solves, not 50.
_SUSPECTS = 3

#: A fit of all the markers leaving more than this RMS reprojection error (px per corner) is tested by
#: leaving each marker out even when :func:`_screen` does not fire: far above any detector's noise, the
#: pose of all may sit on the other planar solution, where the screen's statistics, linearised there,
#: miss the misplaced marker. Pure noise of a detector (a pixel or less) never comes near it, so the
#: screen's rate ``SCREEN_P`` on pure noise holds.
OUTLIER_POOR_FIT_PX = 2.0


def _poor_fit(obs: _Obs, best: _Candidate) -> bool:
    """Whether the fit of all leaves more than ``OUTLIER_POOR_FIT_PX`` RMS per corner."""
    return best.sse > OUTLIER_POOR_FIT_PX**2 * len(obs.obj)


def _suspects(obs: _Obs, best: _Candidate, camera: Camera) -> list[int]:
    """The markers worth a leave-one-out fit: all of them up to ``_LEAVE_EACH_OUT`` markers, else the
    ``_SUSPECTS`` largest :func:`_deletion_q` (all when it cannot be computed); none when no marker's
    corners, predicted by the pose of the others, are off by even half of ``OUTLIER_MIN_RMS_PX`` (a frame of
    sharp corners whose small errors are not alike: the screen's ratio test fires there, and no marker
    could be rejected)."""
    n = len(obs.ids)
    stats = _marker_stats(obs, best, camera)
    if stats is None:
        return list(range(n))
    q, predicted = stats[0], stats[1][5]
    if not np.sqrt((predicted * predicted).sum(axis=1).max() / 4) > 0.5 * OUTLIER_MIN_RMS_PX:
        return []
    if n <= _LEAVE_EACH_OUT:
        return list(range(n))
    return [int(j) for j in np.argsort(-q, kind="stable")[:_SUSPECTS]]


def _to_leave_out(obs: _Obs, marker_map, best: _Candidate, camera: Camera, corner_sigma_px: float | None):
    """The marker to leave out and the solve of the others (:func:`_rest_fit`), or None.

    The marker displaced on its wall (:func:`_named_displaced`) is left out at once when the others, solved
    without it, agree (:func:`_agree`). Otherwise each of the :func:`_suspects` is left out in turn, the
    others solved afresh, and the marker whose absence explains them best is left out when it is the one
    displaced or else when :func:`_left_out_test` says it disagrees with them. The displaced marker is kept
    unless leaving out another explains the others better by more than the left-out test's limit (sigma^2
    times chi-square(8) or 8 F(8, nu)): among markers in a row a move is explained almost as well by leaving
    out a neighbour, and the move's own test (2 degrees of freedom) is the sharper judge; but a move
    linearised at a pose the misplaced marker dragged (onto the other planar solution) can name a good one.
    """
    named = _named_displaced(obs, best, camera, corner_sigma_px)
    tried: dict[int, tuple | None] = {}
    if named is not None:
        first = tried[named] = _rest_fit(obs, marker_map, named, camera)
        if first is not None and _agree(_without(obs, named), first[4][0][0], camera, corner_sigma_px):
            return named, first[4]
    for j in _suspects(obs, best, camera):
        if j not in tried:
            tried[j] = _rest_fit(obs, marker_map, j, camera)
    fits = {j: fit for j, fit in tried.items() if fit is not None}
    if not fits:
        return None
    k = min(fits, key=lambda j: fits[j][2])
    if named is not None and named in fits:
        dof, sigma = _rest_noise(obs, fits[k][2], corner_sigma_px)
        if fits[named][2] - fits[k][2] <= _outlier_threshold(dof, corner_sigma_px is not None) * sigma**2:
            return named, fits[named][4]
    return (k, fits[k][4]) if _left_out_test(obs, k, fits[k], camera, corner_sigma_px) else None


def _agree(obs: _Obs, best: _Candidate, camera: Camera, corner_sigma_px: float | None) -> bool:
    """Whether the markers of ``obs`` agree with each other at their fit ``best``: neither a fit leaving more
    than ``OUTLIER_POOR_FIT_PX`` nor (with 3 markers or more) the screen fires."""
    if _poor_fit(obs, best):
        return False
    return len(obs.ids) < 3 or _screen(obs, best, camera, corner_sigma_px) is None


def _model_error_explains(obs: _Obs, k: int, rest_best: _Candidate, camera: Camera, corner_sigma_px) -> bool:
    """Whether marker k's misfit is what a bent board or a model error does, not a moved marker.

    Marker k's corners are predicted from the others' pose ``rest_best``. Small: their RMS misfit is below
    ``MODEL_ERROR_REL`` of the marker's side in the image (a board bent by a fraction of a millimetre, a camera
    model a little off: a marker moved on its wall is off by a good part of its size). Shared: with at least
    ``SPLIT_MIN_MARKERS`` others, the noise of the others' fit is measured from its residuals (corner noise,
    each marker's shift and size error, :func:`._noise._noise_parts`) and the misfit's chi-square under it
    (plus the others' pose's covariance) is below the left-out test's limit (8 F(8, nu) at ``OUTLIER_P``):
    the others are off by as much, so the marker is kept.
    """
    sl = slice(4 * k, 4 * k + 4)
    r_k, J_k = _residuals(obs.obj[sl], obs.img[sl], camera.K, camera.dist, rest_best.R_wc, rest_best.C, True)
    side = float(np.mean(_side_lengths(obs.img[sl])))
    if math.sqrt(float(r_k @ r_k) / 4) < MODEL_ERROR_REL * side:
        return True
    rest = _without(obs, k)
    if len(rest.ids) < SPLIT_MIN_MARKERS:
        return False
    r, J = _residuals(rest.obj, rest.img, camera.K, camera.dist, rest_best.R_wc, rest_best.C, True)
    q = rest.img.reshape(-1, 4, 2)
    parts = _noise_parts(r, J, q, corner_sigma_px)
    cov = _pose_covariance(J, q, parts, sums=parts.sums)
    if cov is None:
        return False
    g = (obs.img[sl] - obs.img[sl].mean(axis=0)).reshape(8)
    S = parts.a * np.eye(8) + parts.b * _SHIFT8 + parts.c * np.outer(g, g) + J_k @ cov @ J_k.T
    try:
        chi2 = float(r_k @ np.linalg.solve(S, r_k))
    except np.linalg.LinAlgError:
        return False
    return chi2 <= _outlier_threshold(8 * len(rest.ids) - 7, False)


def _side_lengths(quad: np.ndarray) -> np.ndarray:
    """The four sides (px) of a marker's corners (4, 2)."""
    return np.linalg.norm(np.roll(quad, -1, axis=0) - quad, axis=1)


def _reject_outliers(obs: _Obs, marker_map, camera, method, refine_lm, corner_sigma_px, cands, unrefined):
    """While :func:`_screen` fires, or the fit of all leaves more than ``OUTLIER_POOR_FIT_PX``: leave out
    the marker :func:`_to_leave_out` names.

    The poses then come from the solver on the remaining markers, as if only they had been seen.
    """
    rejected: list[int] = []
    while len(obs.ids) >= 3:
        if not _poor_fit(obs, cands[0]) and _screen(obs, cands[0], camera, corner_sigma_px) is None:
            break
        hit = _to_leave_out(obs, marker_map, cands[0], camera, corner_sigma_px)
        if hit is None:
            break
        k, solved = hit
        if _model_error_explains(obs, k, solved[0][0], camera, corner_sigma_px):
            break  # a bent board or a model error: small, shared by the others, not a moved marker
        rest = _without(obs, k)
        try:  # the leave-one-out solve is the solver's own when it is the one asked for
            reuse = method == "auto" and refine_lm
            rc, ru, _ = solved if reuse else _solve(rest, marker_map, camera, method, refine_lm)
        except PoseError:
            break
        if _cheirality(rest, rc[0]) is not None:
            break  # no pose a camera can have without it
        rejected.append(obs.ids[k])
        obs, cands, unrefined = rest, rc, ru
    return obs, cands, unrefined, rejected
