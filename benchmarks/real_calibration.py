"""The calibration's own error in the real benchmark's judging of fidlearn's covariance.

A camera that carries its calibration's covariance (``fidlearn.calibration.camera_with_uncertainty``) adds
the pose's response to an error of the intrinsics to the pose's covariance. The truths the real benchmark
judges by are made with the same camera, so the same error moves them too:

* the robot's truth is a hand-eye fit to the other photos' vision poses, all made with the camera: an error
  of the intrinsics moves the fit, and the truth it predicts, much as it moves the judged pose;
* the course's reference is the photo's chessboard-corner pose with the same camera.

What is judged is the difference, vision minus truth, and its covariance from the calibration is
``D Sigma_k D^T`` with ``D`` the difference of the two responses, not the pose's own ``A Sigma_k A^T``. The
judge therefore uses the pose's covariance without the calibration's term (the same pose with a camera
that does not carry it), the truth's own covariance, and ``D Sigma_k D^T``. For the robot ``D`` is measured
by central differences, one standard deviation along each of the covariance's principal axes (every pose
and every leave-one-out prediction made again); for the course's reference, a least-squares pose like
fidlearn's, both responses are ``(J^T J)^-1 J^T J_k``.
"""

from __future__ import annotations

import cv2
import numpy as np

from benchmarks import handeye as he
from benchmarks import robot_charuco as rc
from fidlearn import Camera, frames
from fidlearn.pose import pose_jacobian


def plain(camera: Camera) -> Camera:
    """The camera without its calibration's covariance."""
    return Camera(camera.K, camera.dist, camera.image_size, camera.source, model=camera.model)


def moved(camera: Camera, d: np.ndarray) -> Camera:
    """The camera with ``fx, fy, cx, cy, *dist`` moved by ``d`` (no covariance)."""
    v = np.r_[camera.fx, camera.fy, camera.cx, camera.cy, camera.dist] + d
    return Camera([[v[0], 0, v[2]], [0, v[1], v[3]], [0, 0, 1]], v[4:], camera.image_size, model=camera.model)


def axes(camera: Camera) -> np.ndarray:
    """The covariance's principal axes scaled by their standard deviations (columns; ``L L^T = Sigma_k``)."""
    w, V = np.linalg.eigh(camera.intrinsics_covariance)
    keep = w > 1e-12 * w.max()
    return V[:, keep] * np.sqrt(w[keep])


def _robot_run(camera: Camera, robots: list) -> tuple[list, list]:
    """Every photo's camera pose and the leave-one-out truth fitted to the others (T_world_camera, board frame)."""
    measured = [rc.fidlearn_pose(i, camera) for i in range(rc.N_PHOTOS)]
    boards = [m.T_camera_board for m in measured]
    vision = [None if m.pose is None else m.pose.T_world_camera for m in measured]
    truth = [he.invert(he.predict_with_covariance(robots, boards, rc.chess_corners_mm(), i)[0]) for i in range(16)]
    return vision, truth


def robot_effect(camera: Camera, robots: list) -> list[np.ndarray | None]:
    """Per photo ``D`` (6, q): how one standard deviation along each principal axis of the calibration's
    covariance moves the truth minus the pose (``handeye.camera_error``), None without a pose."""
    L = axes(camera)
    v0, t0 = _robot_run(plain(camera), robots)
    cols: list[list] = [[] for _ in range(rc.N_PHOTOS)]
    for j in range(L.shape[1]):
        (vp, tp), (vm, tm) = (_robot_run(moved(camera, s * L[:, j]), robots) for s in (1.0, -1.0))
        for i in range(rc.N_PHOTOS):
            if v0[i] is None or vp[i] is None or vm[i] is None:
                cols[i].append(None)
                continue
            dv = he.camera_error(vp[i], v0[i]) - he.camera_error(vm[i], v0[i])
            dt = he.camera_error(tp[i], t0[i]) - he.camera_error(tm[i], t0[i])
            cols[i].append((dt - dv) / 2)
    return [None if any(c is None for c in col) else np.column_stack(col) for col in cols]


def response(points_world: np.ndarray, T_world_camera: np.ndarray, camera: Camera) -> np.ndarray:
    """``(J^T J)^-1 J^T J_k`` (6, p): a least-squares pose's response to the intrinsics."""
    J = pose_jacobian(points_world, T_world_camera, camera)
    X_c = frames.transform_points(frames.invert_transform(T_world_camera), points_world)
    zero = np.zeros(3)
    _, jac = cv2.projectPoints(X_c.reshape(-1, 1, 3), zero, zero, camera.K, camera.dist)
    return np.linalg.solve(J.T @ J, J.T @ jac[:, 6 : 10 + len(camera.dist)])
