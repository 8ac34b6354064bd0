"""Is the board flat? A test of each calibration view for a bent board, at a stated false-alarm rate and size.

A board that bows (a print on thin card, a sheet that lifts at one edge) still gives a small RMS,
but every view pulls the intrinsics its own way. Each view's residuals are tested for a bow of its
board (three quadratic lifts of the board's points) on the whole linearised calibration: the
intrinsics and every view's pose refitted, so a bent view's pull on the shared intrinsics does not
make another view look bent. The statistic is an F-ratio with 3 and ``2N - 9`` degrees of freedom,
compared with its quantile at :data:`BENT_FALSE_ALARM` shared among the views (Bonferroni).

Significance alone calls a flat board bent whenever the residuals have any smooth structure that
white noise does not explain (a lens the model describes a little wrong, a corner finder's bias):
with enough corners a bow of a tenth of a millimetre is significant. A view is therefore called
bent only when its fitted bow is also physically large: a sag of at least :data:`BENT_MIN_SAG_MM`
from the best plane through the board's points. A board shown on a flat screen or printed on glass
is flat to far less; a sheet lifting off its backing is not (OpenCV's ``right02.jpg``, 1.5 mm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _stats
from ..camera import Camera
from . import _checks
from ._lens_jacobians import view_jacobians

__all__ = ["BENT_FALSE_ALARM", "BENT_MIN_SAG_MM", "Bend", "bend_flag", "board_bends", "bent_views"]

#: False-alarm rate of the bent-board test per calibration set: with a flat board and Gaussian
#: corner noise, at most this fraction of sets has a view called bent (each of V views is tested
#: at ``BENT_FALSE_ALARM / V``, Bonferroni).
BENT_FALSE_ALARM = 1e-3
#: Smallest bow called a bent board (mm): the fitted sag of the board's points from their best plane.
#: A sag under it moves a corner less than the corner noise of a typical photo at arm's length.
BENT_MIN_SAG_MM = 1.0


@dataclass(frozen=True)
class Bend:
    """One view's fitted bow of its board.

    Attributes
    ----------
    name : str
        The view.
    sag_mm : float
        How far the bowed board's points stand off their best plane, highest minus lowest (mm).
    sag_std_mm : float
        The standard deviation of ``sag_mm`` from the corner noise (mm).
    F : float
        The F-ratio of the bend against the corner noise.
    limit : float
        The F-ratio's quantile at the view's share of :data:`BENT_FALSE_ALARM`.
    """

    name: str
    sag_mm: float
    sag_std_mm: float
    F: float
    limit: float


def _bend_rows(camera: Camera, points_mm: np.ndarray, image_px: np.ndarray, T: np.ndarray):
    """One view's residuals (2N,), Jacobians on its pose (2N, 6), the intrinsics (2N, n) and a bend (2N, 3).

    The bend lifts each board point off the board's plane by ``c1 x^2 + c2 x y + c3 y^2`` (mm; x, y
    the point's board coordinates from the board's centre over its largest extent): the three
    smooth ways to bow a sheet that no move of the board undoes.
    """
    P = np.asarray(points_mm, dtype=float).reshape(-1, 3)
    proj, J_pose, J_intrinsics = view_jacobians(camera, P, T)  # either lens model: cv2's or cv2.fisheye's Jacobian
    r = (np.asarray(image_px, dtype=float).reshape(-1, 2) - proj).ravel()
    lift = (J_pose[:, 3:6] @ T[:3, 2]).reshape(-1, 2)  # d pixel / d (mm along the board's normal)
    x, y = (P[:, :2] - P[:, :2].mean(axis=0)).T / max(float(np.ptp(P[:, :2], axis=0).max()), 1e-9)
    bend = np.column_stack([(lift * f[:, None]).ravel() for f in (x * x, x * y, y * y)])
    return r, J_pose, J_intrinsics, bend  # fx, fy, cx, cy and the distortion


def bent_views(camera: Camera, board_points_mm: dict, image_points_px: dict, T_camera_board: dict) -> list[str]:
    """Views whose board was not flat: a bend explains their residuals beyond the noise, and is large.

    The names of :func:`board_bends`, which says how each is tested.

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
    return [b.name for b in board_bends(camera, board_points_mm, image_points_px, T_camera_board)]


def board_bends(camera: Camera, board_points_mm: dict, image_points_px: dict, T_camera_board: dict) -> list[Bend]:
    """The bent views with their fitted bow: significant against the corner noise and at least ``BENT_MIN_SAG_MM``.

    The whole calibration (the intrinsics, every view's board pose) is linearised at its
    solution. For each view, ``t`` is how much a bend of its board (three coefficients, below)
    would shrink the squared residuals once the intrinsics and every pose are refitted with it,
    and ``F = (t / 3) / s^2``, ``s^2`` the corner noise: the larger of the set's typical noise (the
    median over the views of their squared residuals per degree of freedom, ``2N - 6``: a bent
    view does not inflate it) and the view's own (what its residuals leave beside the bend, over
    ``2N - 9``: a blurred or badly detected photo is noisy, not bent). With a flat board and
    Gaussian corner noise ``F`` is at most an F(3, 2N - 9) variable: a view is significant when
    it exceeds that distribution's quantile at ``BENT_FALSE_ALARM / V`` (``V`` views; 8.4 for 20
    views of 54 points), so at most one flat set in 1000 gets a view called bent. It is called
    bent when, besides, the fitted bow's sag (its points' highest minus lowest off their best
    plane) is at least :data:`BENT_MIN_SAG_MM`: residual structure that no bend of a size a
    board can have explains (a lens the model describes a little wrong, a corner finder's bias) is not a
    bent board. Views are taken worst first, each found bend then being fitted too, so that a
    bent view's pull on the intrinsics does not make others look bent.

    The bend lifts each board point off its plane by ``c1 x^2 + c2 x y + c3 y^2`` (x, y its board
    coordinates from the centre over the board's largest extent; c in mm): no tilt or shift of
    the board undoes it. A fisheye camera (``model="fisheye"``) is linearised through
    ``cv2.fisheye.projectPoints``, its intrinsics ``fx, fy, cx, cy, k1..k4``.

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
    list of Bend
        The bent views, the most significant first; empty when none is.

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
    start = np.cumsum([0] + [len(r) for r, *_ in rows])
    typical = float(np.median([float(rows[k][0] @ rows[k][0]) / (dof[k] + 3) for k in testable]))
    bent: list[Bend] = []
    done: set[int] = set()
    while testable - done:
        found = []
        for k, (t, left, c, R_inv) in _bend_statistics(rows, start, done, testable - done).items():
            s2 = max(typical, left / dof[k], 1e-300)
            limit = _stats.f_isf(BENT_FALSE_ALARM / len(names), 3, dof[k])
            sag, grad = _sag(board_points_mm[names[k]], c)
            sag_std = float(np.sqrt(s2 * np.sum((grad @ R_inv) ** 2)))
            if (t / 3) / s2 > limit and sag >= BENT_MIN_SAG_MM:
                found.append((k, Bend(names[k], sag, sag_std, (t / 3) / s2, limit)))
        if not found:
            break
        k, worst = max(found, key=lambda kb: kb[1].F)
        bent.append(worst)
        done.add(k)  # its bend is fitted from now on
    return bent


def _sag(points_mm: np.ndarray, c: np.ndarray) -> tuple[float, np.ndarray]:
    """The bow's sag (mm: its points' highest minus lowest off their best plane) and its gradient on ``c``."""
    P = np.asarray(points_mm, dtype=float).reshape(-1, 3)
    x, y = (P[:, :2] - P[:, :2].mean(axis=0)).T / max(float(np.ptp(P[:, :2], axis=0).max()), 1e-9)
    F = np.column_stack([x * x, x * y, y * y])
    A = np.column_stack([np.ones_like(x), x, y])
    F = F - A @ np.linalg.lstsq(A, F, rcond=None)[0]  # what a tilt or shift of the board cannot undo
    z = F @ c
    hi, lo = int(np.argmax(z)), int(np.argmin(z))
    return float(z[hi] - z[lo]), F[hi] - F[lo]


def _projector(rows: list, fitted: set) -> tuple[list, np.ndarray, np.ndarray]:
    """The calibration's column space, by blocks: per view an orthonormal basis of its own columns (its
    pose, and its bend once fitted), then one of the shared intrinsics' columns beside those; and the
    residuals left outside the whole space."""
    local, shared, r_out = [], [], []
    for k, (r, Je, Ji, B) in enumerate(rows):
        Qe = np.linalg.qr(np.column_stack([Je, B]) if k in fitted else Je)[0]
        local.append(Qe)
        shared.append(Ji - Qe @ (Qe.T @ Ji))
        r_out.append(r - Qe @ (Qe.T @ r))
    Qi = np.linalg.qr(np.vstack(shared))[0]
    r_perp = np.concatenate(r_out)
    return local, Qi, r_perp - Qi @ (Qi.T @ r_perp)


def _bend_statistics(rows: list, start: np.ndarray, fitted: set, views) -> dict:
    """Per view ``(t, q, c, R^-1)``: how much a bend of its board would shrink the squared residuals
    once the intrinsics, every pose and the bends in ``fitted`` are refitted too (px^2), the view's own
    squared residuals left beside it, the bend's coefficients (mm) and the factor of their covariance
    (``s^2 R^-1 R^-T``). The calibration's columns are taken by blocks (each view's pose, then the shared
    intrinsics beside them): the same projection as one QR of the whole Jacobian, at a fraction of its cost."""
    local, Qi, rest = _projector(rows, fitted)
    out = {}
    for k in views:
        a, b = start[k], start[k + 1]
        Bk = rows[k][3] - local[k] @ (local[k].T @ rows[k][3])
        B = -Qi @ (Qi[a:b].T @ Bk)
        B[a:b] += Bk
        Qb, Rb = np.linalg.qr(B)
        if np.min(np.abs(np.diag(Rb))) > 1e-9 * max(float(np.abs(Rb).max()), 1e-300):
            c = Qb.T @ rest
            left = (rest - Qb @ c)[a:b]  # the view's residuals beside its bend
            out[k] = (float(c @ c), float(left @ left), np.linalg.solve(Rb, c), np.linalg.inv(Rb))
    return out


def bend_flag(bent: list, n_views: int, model: str = "pinhole") -> str:
    """The coach's sentence for bent views: a bent print, or (in many views at once) a lens the model cannot describe.

    Parameters
    ----------
    bent : list of Bend
        The bent views (:func:`board_bends`), not empty.
    n_views : int
        How many views the calibration used.
    model : {"pinhole", "fisheye"}
        The camera's lens model: a fisheye is not told to try the fisheye model.

    Returns
    -------
    str
        One sentence naming each view with its sag and what to do.
    """
    said = ", ".join(f"{b.name} ({b.sag_mm:.1f} ± {b.sag_std_mm:.1f} mm)" for b in bent)
    if 3 * len(bent) >= n_views and len(bent) >= 3 and model == "fisheye":
        return (
            f"{len(bent)} of {n_views} views do not look flat, bowed by {said}: so many bent boards are "
            "unlikely; the board itself may be bowed (then alike in every photo: mount the print on glass or "
            "a rigid panel), or the lens beyond what the fisheye model's 4 coefficients describe"
        )
    if 3 * len(bent) >= n_views and len(bent) >= 3:
        return (
            f"{len(bent)} of {n_views} views do not look flat, bowed by {said}: so many bent boards are "
            "unlikely; the lens model more likely cannot describe this lens (a wide or fisheye lens: try "
            "the rational model or a fisheye model), or the print is loose on its backing"
        )
    return (
        f"the board does not look flat in {said}: its residuals follow a smooth bend larger than "
        f"{BENT_MIN_SAG_MM:g} mm; glue the print to something rigid and retake those views"
    )
