"""A robot's truth for a camera's poses: the two fixed transforms of a robot-world / hand-eye calibration.

A static camera watches a board that a robot holds on its tool flange. For every photo ``i`` the
robot reports ``T_base_tool(i)``; the board's pose in the camera is then

    T_camera_board(i) = inv(T_base_camera) @ T_base_tool(i) @ T_tool_board

with two unknown fixed transforms: the camera in the robot's base and the board on the flange.
:func:`fit` finds both from photos whose board pose some vision method measured
(a closed-form linear solution for a start, :func:`initial_guess`, then a least-squares refinement of both with
``scipy.optimize.least_squares``); :func:`predict` turns a robot pose into the board pose the
robot says the camera should see, independent of that photo's pixels; :func:`leave_one_out`
does so for every photo from a fit that leaves it out. All lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

#: The 95 % quantile of chi-square with 6 degrees of freedom (a 6-dof pose error).
CHI2_6_95 = 12.591587


def transform(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """A 4x4 rigid transform from a rotation matrix (3, 3) and a translation (3,).

    Parameters
    ----------
    rotation : ndarray, shape (3, 3)
    translation : array_like, shape (3,)

    Returns
    -------
    ndarray, shape (4, 4)
    """
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = np.ravel(translation)
    return T


def invert(T: np.ndarray) -> np.ndarray:
    """The inverse of a rigid transform (4, 4).

    Parameters
    ----------
    T : ndarray, shape (4, 4)

    Returns
    -------
    ndarray, shape (4, 4)
    """
    R = T[:3, :3]
    return transform(R.T, -R.T @ T[:3, 3])


def _to_params(T: np.ndarray) -> np.ndarray:
    return np.concatenate([Rotation.from_matrix(T[:3, :3]).as_rotvec(), T[:3, 3]])


def _from_params(p: np.ndarray) -> np.ndarray:
    return transform(Rotation.from_rotvec(p[:3]).as_matrix(), p[3:6])


@dataclass(frozen=True)
class RobotWorld:
    """The two fixed transforms (mm) and how well they explain the photos they were fitted to.

    Attributes
    ----------
    T_base_camera : ndarray, shape (4, 4)
        The camera in the robot's base frame.
    T_tool_board : ndarray, shape (4, 4)
        The board on the robot's tool flange.
    rms_mm : float
        RMS over the fitted photos and the board's points of the distance between where the
        robot puts a board point and where vision does (mm).
    n_photos : int
        Photos the fit used.
    """

    T_base_camera: np.ndarray
    T_tool_board: np.ndarray
    rms_mm: float
    n_photos: int


def predict(fit: RobotWorld, T_base_tool: np.ndarray) -> np.ndarray:
    """The board's pose in the camera (4, 4, mm) that the robot's pose implies.

    Parameters
    ----------
    fit : RobotWorld
    T_base_tool : ndarray, shape (4, 4)
        The robot's flange in its base (mm).

    Returns
    -------
    ndarray, shape (4, 4)
        ``inv(T_base_camera) @ T_base_tool @ T_tool_board``.
    """
    return invert(fit.T_base_camera) @ T_base_tool @ fit.T_tool_board


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def initial_guess(T_base_tool: list[np.ndarray], T_camera_board: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A closed-form robot-world / hand-eye solution: ``(T_base_camera, T_tool_board)``.

    With ``X = T_base_camera``, ``Y = T_tool_board``, ``B_i = T_base_tool(i)`` and ``C_i = T_camera_board(i)``,
    every photo says ``X C_i = B_i Y``. The rotations solve the linear system
    ``R_X R_Ci - R_Bi R_Y = 0`` (its null vector, as in Shah's method, which OpenCV's
    ``calibrateRobotWorldHandEye`` implements; OpenCV 5.0's Python module lacks that function),
    each projected onto the nearest rotation; the translations then solve
    ``t_X - R_Bi t_Y = t_Bi - R_X t_Ci`` by linear least squares.

    Parameters
    ----------
    T_base_tool, T_camera_board : list of ndarray (4, 4)
        Per photo, the robot's pose and the vision pose (mm); at least 3 photos with distinct rotations.

    Returns
    -------
    T_base_camera, T_tool_board : ndarray (4, 4)
    """
    eye = np.eye(3)
    M = np.concatenate(
        [np.hstack([np.kron(eye, C[:3, :3].T), -np.kron(B[:3, :3], eye)]) for B, C in zip(T_base_tool, T_camera_board)]
    )
    v = np.linalg.svd(M)[2][-1]
    if np.linalg.det(v[:9].reshape(3, 3)) < 0:
        v = -v
    R_X, R_Y = _nearest_rotation(v[:9].reshape(3, 3)), _nearest_rotation(v[9:].reshape(3, 3))
    A = np.concatenate([np.hstack([eye, -B[:3, :3]]) for B in T_base_tool])
    b = np.concatenate([B[:3, 3] - R_X @ C[:3, 3] for B, C in zip(T_base_tool, T_camera_board)])
    t = np.linalg.lstsq(A, b, rcond=None)[0]
    return transform(R_X, t[:3]), transform(R_Y, t[3:])


def fit(
    T_base_tool: list[np.ndarray],
    T_camera_board: list[np.ndarray],
    points_board: np.ndarray,
    *,
    loss: str = "soft_l1",
    f_scale_mm: float = 2.0,
) -> RobotWorld:
    """Fit the camera in the robot's base and the board on the flange to photos' robot and vision poses.

    Starts from :func:`initial_guess`, then minimises over both transforms (12 parameters) the
    distances, in the camera's frame, between the board's points placed by the robot and placed
    by vision, with a robust loss (``"soft_l1"`` at ``f_scale_mm``: one bad vision pose moves the
    fit little; ``loss="linear"`` for plain least squares).

    Parameters
    ----------
    T_base_tool, T_camera_board : list of ndarray (4, 4)
        Per photo, the robot's flange in its base and the board in the camera (mm); at least 3 photos.
    points_board : ndarray, shape (N, 3)
        Points on the board (its frame, mm) whose distances are minimised, e.g. its chess corners.
    loss : str
        ``scipy.optimize.least_squares``'s loss.
    f_scale_mm : float
        Where the robust loss starts to flatten (mm).

    Returns
    -------
    RobotWorld

    Raises
    ------
    ValueError
        Fewer than 3 photos, or lists of different lengths.
    """
    if len(T_base_tool) != len(T_camera_board) or len(T_base_tool) < 3:
        raise ValueError(
            f"need as many robot poses as vision poses and at least 3 of each, got {len(T_base_tool)} robot "
            f"and {len(T_camera_board)} vision poses"
        )
    P = np.c_[np.asarray(points_board, dtype=float), np.ones(len(points_board))].T
    tools = np.asarray(T_base_tool, dtype=float)
    seen = np.einsum("nij,jk->nik", np.asarray(T_camera_board, dtype=float), P)[:, :3]

    def residuals(p: np.ndarray) -> np.ndarray:
        camera_base = invert(_from_params(p[:6]))
        robot = np.einsum("ij,njk,kl->nil", camera_base, tools, _from_params(p[6:]) @ P)[:, :3]
        return (robot - seen).ravel()

    start = np.concatenate([_to_params(T) for T in initial_guess(T_base_tool, T_camera_board)])
    result = least_squares(residuals, start, loss=loss, f_scale=f_scale_mm, x_scale="jac")
    d = result.fun.reshape(len(tools), 3, -1)
    rms = float(np.sqrt(np.mean(np.sum(d**2, axis=1))))
    return RobotWorld(_from_params(result.x[:6]), _from_params(result.x[6:]), rms, len(tools))


def leave_one_out(
    T_base_tool: list[np.ndarray],
    T_camera_board: list[np.ndarray | None],
    points_board: np.ndarray,
    judged: list[int] | None = None,
    **kw,
) -> list[np.ndarray]:
    """For every photo, the board pose the robot implies, from a fit to the other photos alone.

    Parameters
    ----------
    T_base_tool : list of ndarray (4, 4)
        The robot's pose for every photo.
    T_camera_board : list of (ndarray (4, 4) or None)
        The vision pose for every photo, None where vision found none (such a photo is still
        predicted, from all the others).
    points_board : ndarray, shape (N, 3)
        As for :func:`fit`.
    judged : list of int, optional
        The photos to predict (default: every photo).
    **kw
        Passed to :func:`fit`.

    Returns
    -------
    list of ndarray (4, 4)
        The predicted ``T_camera_board`` of every judged photo, in the order of ``judged``.
    """
    out = []
    for k in range(len(T_base_tool)) if judged is None else judged:
        keep = [i for i, T in enumerate(T_camera_board) if T is not None and i != k]
        rw = fit([T_base_tool[i] for i in keep], [T_camera_board[i] for i in keep], points_board, **kw)
        out.append(predict(rw, T_base_tool[k]))
    return out


def pose_error(T_true: np.ndarray, T_measured: np.ndarray, point: np.ndarray) -> tuple[float, float]:
    """Position error (mm) of a board point and rotation error (degrees) between two board poses.

    Parameters
    ----------
    T_true, T_measured : ndarray, shape (4, 4)
        ``T_camera_board`` from the robot and from vision.
    point : array_like, shape (3,)
        The board point whose position is compared (e.g. the board's centre), board frame.

    Returns
    -------
    position_mm, rotation_deg : float
    """
    p = np.append(np.asarray(point, dtype=float), 1.0)
    position = float(np.linalg.norm((T_true @ p - T_measured @ p)[:3]))
    R = T_true[:3, :3].T @ T_measured[:3, :3]
    rotation = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))))
    return position, rotation


def nees(T_world_camera_true: np.ndarray, T_world_camera: np.ndarray, covariance: np.ndarray) -> float:
    """Normalised estimation error squared of a camera pose against the truth under fidlearn's covariance.

    The error is ``[dtheta, C_true - C]`` with ``R_true = expm([dtheta]x) @ R`` (world axes, rad) and
    ``C`` the camera centre (mm), the parametrisation of :attr:`fidlearn.Pose.covariance`. Under a
    right covariance it follows chi-square with 6 degrees of freedom (95 % below :data:`CHI2_6_95`).

    Parameters
    ----------
    T_world_camera_true, T_world_camera : ndarray, shape (4, 4)
    covariance : ndarray, shape (6, 6)

    Returns
    -------
    float
    """
    dtheta = Rotation.from_matrix(T_world_camera_true[:3, :3] @ T_world_camera[:3, :3].T).as_rotvec()
    e = np.concatenate([dtheta, T_world_camera_true[:3, 3] - T_world_camera[:3, 3]])
    return float(e @ np.linalg.solve(covariance, e))


def camera_error(T_true: np.ndarray, T_world_camera: np.ndarray) -> np.ndarray:
    """``[dtheta, C_true - C]`` (rad, mm) of :func:`nees`: the parametrisation of ``fidlearn.Pose.covariance``.

    Parameters
    ----------
    T_true, T_world_camera : ndarray, shape (4, 4)
        The camera's true and measured pose.

    Returns
    -------
    ndarray, shape (6,)
    """
    dtheta = Rotation.from_matrix(T_true[:3, :3] @ T_world_camera[:3, :3].T).as_rotvec()
    return np.concatenate([dtheta, T_true[:3, 3] - T_world_camera[:3, 3]])


def predict_with_covariance(
    T_base_tool: list[np.ndarray],
    T_camera_board: list[np.ndarray | None],
    points_board: np.ndarray,
    k: int,
    **kw,
) -> tuple[np.ndarray, np.ndarray]:
    """Photo ``k``'s board pose from a fit to the other photos, and the covariance of that prediction.

    The covariance is the fit's own: the 12 fitted parameters' covariance, cluster-robust over the
    photos (``B^-1 (sum_p J_p^T r_p r_p^T J_p) B^-1``, ``B = J^T J``, each photo's residuals one cluster,
    times ``n / (n - 2)`` for the two photos' worth of parameters), carried to the camera's pose in the
    board's frame (6, 6; ``[dtheta (rad), camera centre (mm)]``, as ``fidlearn.Pose.covariance`` and
    :func:`nees`). It holds the scatter of the other photos (the robot's repeatability and their
    vision errors, averaged over the fit), not the robot's own error at photo ``k``.

    Parameters
    ----------
    T_base_tool, T_camera_board, points_board
        As for :func:`leave_one_out`.
    k : int
        The photo predicted.
    **kw
        Passed to :func:`fit`.

    Returns
    -------
    T_camera_board : ndarray (4, 4)
        The predicted board pose (mm).
    covariance : ndarray (6, 6)
        Of the camera's pose in the board's frame.
    """
    keep = [i for i, T in enumerate(T_camera_board) if T is not None and i != k]
    tools = [T_base_tool[i] for i in keep]
    seen = [T_camera_board[i] for i in keep]
    rw = fit(tools, seen, points_board, **kw)
    P = np.c_[np.asarray(points_board, dtype=float), np.ones(len(points_board))].T
    seen_pts = np.einsum("nij,jk->nik", np.asarray(seen, dtype=float), P)[:, :3]
    p0 = np.concatenate([_to_params(rw.T_base_camera), _to_params(rw.T_tool_board)])

    def residuals(p: np.ndarray) -> np.ndarray:
        robot = np.einsum("ij,njk,kl->nil", invert(_from_params(p[:6])), np.asarray(tools), _from_params(p[6:]) @ P)
        return (robot[:, :3] - seen_pts).reshape(len(tools), -1)

    def camera_in_board(p: np.ndarray) -> np.ndarray:
        return invert(invert(_from_params(p[:6])) @ T_base_tool[k] @ _from_params(p[6:]))

    h = np.r_[np.full(3, 1e-6), np.full(3, 1e-3), np.full(3, 1e-6), np.full(3, 1e-3)]
    r0 = residuals(p0)
    T0 = camera_in_board(p0)
    J = np.empty((*r0.shape, 12))
    D = np.empty((6, 12))
    for j in range(12):
        step = np.zeros(12)
        step[j] = h[j]
        J[..., j] = (residuals(p0 + step) - residuals(p0 - step)) / (2 * h[j])
        D[:, j] = (camera_error(camera_in_board(p0 + step), T0) - camera_error(camera_in_board(p0 - step), T0)) / (
            2 * h[j]
        )
    Binv = np.linalg.inv(np.einsum("nai,naj->ij", J, J))
    g = np.einsum("nai,na->ni", J, r0)  # each photo's J_p^T r_p
    n = len(tools)
    cov_p = Binv @ (g.T @ g) @ Binv * n / (n - 2)
    return predict(rw, T_base_tool[k]), D @ cov_p @ D.T
