"""Is the board flat? A test of each calibration view for a bent board, at a stated false-alarm rate.

A board that bows (a print on thin card, a sheet that lifts at one edge) still gives a small RMS,
but every view pulls the intrinsics its own way. Each view's residuals are tested for a bow of its
board (three quadratic lifts of the board's points) on the whole linearised calibration: the
intrinsics and every view's pose refitted, so a bent view's pull on the shared intrinsics does not
make another view look bent. The statistic is an F-ratio with 3 and ``2N - 9`` degrees of freedom,
compared with its quantile at :data:`BENT_FALSE_ALARM` shared among the views (Bonferroni).
"""

from __future__ import annotations

import cv2
import numpy as np

from .. import _stats, frames
from ..camera import Camera
from . import _checks

__all__ = ["BENT_FALSE_ALARM", "bent_views"]

#: False-alarm rate of the bent-board test per calibration set: with a flat board and Gaussian
#: corner noise, at most this fraction of sets has a view called bent (each of V views is tested
#: at ``BENT_FALSE_ALARM / V``, Bonferroni).
BENT_FALSE_ALARM = 1e-3


def _bend_rows(camera: Camera, points_mm: np.ndarray, image_px: np.ndarray, T: np.ndarray):
    """One view's residuals (2N,), Jacobians on its pose (2N, 6), the intrinsics (2N, n) and a bend (2N, 3).

    The bend lifts each board point off the board's plane by ``c1 x^2 + c2 x y + c3 y^2`` (mm; x, y
    the point's board coordinates from the board's centre over its largest extent): the three
    smooth ways to bow a sheet that no move of the board undoes.
    """
    P = np.asarray(points_mm, dtype=float).reshape(-1, 3)
    rvec, tvec = frames.rvec_tvec_from_transform(T)
    proj, jac = cv2.projectPoints(P.reshape(-1, 1, 3), rvec, tvec, camera.K, camera.dist)
    r = (np.asarray(image_px, dtype=float).reshape(-1, 2) - proj.reshape(-1, 2)).ravel()
    lift = (jac[:, 3:6] @ T[:3, 2]).reshape(-1, 2)  # d pixel / d (mm along the board's normal)
    x, y = (P[:, :2] - P[:, :2].mean(axis=0)).T / max(float(np.ptp(P[:, :2], axis=0).max()), 1e-9)
    bend = np.column_stack([(lift * f[:, None]).ravel() for f in (x * x, x * y, y * y)])
    return r, jac[:, :6], jac[:, 6 : 6 + 4 + len(camera.dist)], bend  # fx, fy, cx, cy and the distortion


def bent_views(camera: Camera, board_points_mm: dict, image_points_px: dict, T_camera_board: dict) -> list[str]:
    """Views whose board was not flat: a bend explains their residuals beyond the corner noise.

    The whole calibration (the intrinsics, every view's board pose) is linearised at its
    solution. For each view, ``t`` is how much a bend of its board (three coefficients, below)
    would shrink the squared residuals once the intrinsics and every pose are refitted with it,
    and ``F = (t / 3) / s^2``, ``s^2`` the corner noise: the larger of the set's typical noise (the
    median over the views of their squared residuals per degree of freedom, ``2N - 6``: a bent
    view does not inflate it) and the view's own (what its residuals leave beside the bend, over
    ``2N - 9``: a blurred or badly detected photo is noisy, not bent). With a flat board and
    Gaussian corner noise ``F`` is at most an F(3, 2N - 9) variable: a view is called bent when
    it exceeds that distribution's quantile at ``BENT_FALSE_ALARM / V`` (``V`` views; 8.4 for 20
    views of 54 points), so at most one flat set in 1000 gets a view called bent. Views are
    tested worst first, each found bend then being fitted too, so that a bent view's pull on the
    intrinsics does not make others look bent.

    The bend lifts each board point off its plane by ``c1 x^2 + c2 x y + c3 y^2`` (x, y its board
    coordinates from the centre): no tilt or shift of the board undoes it.

    Parameters
    ----------
    camera : Camera
        The calibrated camera.
    board_points_mm : dict of str to ndarray, shape (N, 3)
        Each view's board points (mm, board frame).
    image_points_px : dict of str to ndarray, shape (N, 2)
        Where each view found them (px).
    T_camera_board : dict of str to ndarray, shape (4, 4)
        Each view's board pose in the camera frame (mm), as the calibration found it.

    Returns
    -------
    list of str
        The names of the bent views, the most bent first; empty when none is.

    Raises
    ------
    CalibrationError
        If the camera is not a Camera, or a view is missing or malformed (the message names it).
    """
    board_points_mm, image_points_px, T_camera_board = _checks.check_views(
        camera, board_points_mm, image_points_px, T_camera_board
    )
    names = list(T_camera_board)
    rows = [_bend_rows(camera, board_points_mm[n], image_points_px[n], T_camera_board[n]) for n in names]
    dof = {k: len(r) - 9 for k, (r, *_) in enumerate(rows)}  # beside the pose and the bend
    testable = {k for k, d in dof.items() if d >= 2}
    if not testable:
        return []
    G, r, start = _linearised_calibration(rows)
    typical = float(np.median([float(rows[k][0] @ rows[k][0]) / (dof[k] + 3) for k in testable]))
    bent: list[int] = []
    while testable - set(bent):
        stats = _bend_statistics(G, r, start, rows, testable - set(bent))
        F = {k: (t / 3) / max(typical, left / dof[k], 1e-300) for k, (t, left) in stats.items()}
        worst = max(F, key=F.get, default=None)
        if worst is None or F[worst] <= _stats.f_isf(BENT_FALSE_ALARM / len(names), 3, dof[worst]):
            break
        bent.append(worst)
        G = np.column_stack([G, _bend_columns(start, rows, worst)])  # its bend is fitted from now on
    return [names[k] for k in bent]


def _linearised_calibration(rows: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Jacobian of every view's residuals (shared intrinsics, then 6 pose columns per view), the
    residuals, and where each view's rows start (and the last ends)."""
    start = np.cumsum([0] + [len(r) for r, *_ in rows])
    n = rows[0][2].shape[1]
    G = np.zeros((start[-1], n + 6 * len(rows)))
    for k, (_, Je, Ji, _) in enumerate(rows):
        G[start[k] : start[k + 1], :n] = Ji
        G[start[k] : start[k + 1], n + 6 * k : n + 6 * k + 6] = Je
    return G, np.concatenate([r for r, *_ in rows]), start


def _bend_columns(start: np.ndarray, rows: list, k: int) -> np.ndarray:
    B = np.zeros((start[-1], 3))
    B[start[k] : start[k + 1]] = rows[k][3]
    return B


def _bend_statistics(G: np.ndarray, r: np.ndarray, start: np.ndarray, rows: list, views) -> dict:
    """Per view ``(t, q)`` (px^2): how much a bend of its board would shrink the squared residuals
    once the model ``G`` is refitted too, and the view's own squared residuals left beside it."""
    Q = np.linalg.qr(G)[0]
    rest = r - Q @ (Q.T @ r)
    out = {}
    for k in views:
        B = _bend_columns(start, rows, k)
        B -= Q @ (Q.T @ B)
        Qb, Rb = np.linalg.qr(B)
        if np.min(np.abs(np.diag(Rb))) > 1e-9 * max(float(np.abs(Rb).max()), 1e-300):
            c = Qb.T @ rest
            left = (rest - Qb @ c)[start[k] : start[k + 1]]  # the view's residuals beside its bend
            out[k] = (float(c @ c), float(left @ left))
    return out
