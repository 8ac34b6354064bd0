"""The error-state Kalman filter on the camera pose: state, prediction, measurement update, gating.

State (the mean): the camera's orientation ``R_world_camera`` (3, 3), its centre ``C`` (3,, mm,
world), its angular velocity ``w`` (3,, rad/s, world axes) and its velocity ``v`` (3,, mm/s,
world), and the odometry's scale error ``k`` (the base's true translation is ``(1 + k)`` times the
odometry's). The covariance ``P`` (13, 13) is that of the error state ``[dtheta, dC, dw, dv, dk]``, with
``dtheta`` a small rotation in world axes applied on the left (``R_true = exp([dtheta]x) R``): the
same coordinates as :attr:`fidlearn.Pose.covariance`, so a pose measurement is ``H = [I6, 0]``.
Rotations are never averaged as vectors: the filter corrects ``R`` by ``exp(dtheta) R``.

Motion model: constant velocity with white acceleration (spectral densities ``q_lin^2`` in
(mm/s^2)^2 / Hz and ``q_ang^2`` in (rad/s^2)^2 / Hz); or, when odometry is given for a step, the
odometry's relative motion of the base, its translation corrected by ``1 + k``, carried to the camera
through the mount. ``k`` starts at 0 with a standard deviation ``ODOMETRY_SCALE_STD`` and is learnt from
the poses: wheels a little larger than their nominal size, or a slipping floor, make every step of the
odometry too long or too short by the same fraction, an error that adds up along the drive and that the
odometry's own per-step covariance (independent from step to step) does not describe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._so3 import chi2_6_quantile, exp_so3, left_jacobian, log_so3, skew

#: A measurement whose squared Mahalanobis distance from the prediction (6 degrees of freedom)
#: is above the chi-square quantile of this probability is rejected.
GATE_PROBABILITY = 0.999
GATE_CHI2 = chi2_6_quantile(GATE_PROBABILITY)
#: The covariance of an ambiguous frame, or of a pose from one marker, is multiplied by this before it
#: enters the filter. Near the flip the error surface is far from quadratic and the reported covariance
#: too small in its tails, on either branch: on the rendered single-marker views of
#: ``benchmarks/bench_tracking.py`` (1 px corner noise) the squared Mahalanobis distance of the reported
#: pose from the truth averaged 10.2 instead of 6, and the 95 % ellipsoid of the single-marker poses
#: not flagged ambiguous held the truth in 55 % of the frames.
AMBIGUOUS_INFLATION = 2.0
#: After this many rejected frames in a row the track restarts from the next measurement.
MAX_REJECTIONS = 5
#: Prior standard deviation of the velocity (mm/s) and angular velocity (rad/s) when a track starts.
START_SPEED_STD_MM_S = 500.0
START_TURN_STD_RAD_S = 1.0
#: Prior standard deviation of the odometry's scale error ``k`` (a fraction of each step's translation)...
ODOMETRY_SCALE_STD = 0.05
#: ... and how fast it may wander (random walk, per sqrt(second)).
ODOMETRY_SCALE_DRIFT = 0.002
#: Size of the error state.
_N = 13

_I3 = np.eye(3)


@dataclass
class _State:
    """One estimate: the mean (R, C, w, v, k), its covariance P (13, 13) and its time (s)."""

    R: np.ndarray
    C: np.ndarray
    w: np.ndarray
    v: np.ndarray
    P: np.ndarray
    t: float
    k: float = 0.0

    def copy(self) -> _State:
        return _State(self.R.copy(), self.C.copy(), self.w.copy(), self.v.copy(), self.P.copy(), self.t, self.k)

    def T(self) -> np.ndarray:
        """T_world_camera (4, 4), mm."""
        T = np.eye(4)
        T[:3, :3] = self.R
        T[:3, 3] = self.C
        return T


def start_state(T_world_camera: np.ndarray, covariance: np.ndarray, t_s: float) -> _State:
    """A track starting at a measured pose, at rest with a broad prior on its velocity and the odometry's scale."""
    P = np.zeros((_N, _N))
    P[:6, :6] = covariance
    P[6:9, 6:9] = _I3 * START_TURN_STD_RAD_S**2
    P[9:12, 9:12] = _I3 * START_SPEED_STD_MM_S**2
    P[12, 12] = ODOMETRY_SCALE_STD**2
    T = np.asarray(T_world_camera, dtype=float)
    return _State(T[:3, :3].copy(), T[:3, 3].copy(), np.zeros(3), np.zeros(3), P, float(t_s))


def _blocks(pos: int, vel: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """0/1 masks (13, 13) of one white acceleration's position block, its cross blocks and its velocity block."""
    position, cross, velocity = np.zeros((_N, _N)), np.zeros((_N, _N)), np.zeros((_N, _N))
    position[pos : pos + 3, pos : pos + 3] = _I3
    cross[pos : pos + 3, vel : vel + 3] = cross[vel : vel + 3, pos : pos + 3] = _I3
    velocity[vel : vel + 3, vel : vel + 3] = _I3
    return position, cross, velocity


_ROT_BLOCKS, _POS_BLOCKS = _blocks(0, 6), _blocks(3, 9)
_SCALE_BLOCK = np.zeros((_N, _N))
_SCALE_BLOCK[12, 12] = 1.0
_I13 = np.eye(_N)


def _white_acceleration(dt: float, q_lin: float, q_ang: float) -> np.ndarray:
    """Process noise (13, 13) of white acceleration over ``dt`` seconds (and the odometry scale's wander)."""
    Q = (ODOMETRY_SCALE_DRIFT**2 * dt) * _SCALE_BLOCK
    for (pp, pv, vv), q2 in ((_ROT_BLOCKS, q_ang**2), (_POS_BLOCKS, q_lin**2)):
        Q = Q + (q2 * dt**3 / 3.0) * pp + (q2 * dt**2 / 2.0) * pv + (q2 * dt) * vv
    return Q


def predict_constant_velocity(s: _State, t_s: float, q_lin: float, q_ang: float) -> tuple[_State, np.ndarray]:
    """The state at ``t_s`` under constant velocity, and the error-state transition F (13, 13)."""
    dt = float(t_s) - s.t
    phi = s.w * dt
    E = exp_so3(phi)
    F = _I13.copy()
    F[0:3, 0:3] = E
    F[0:3, 6:9] = left_jacobian(phi) * dt
    F[3:6, 9:12] = _I3 * dt
    P = F @ s.P @ F.T + _white_acceleration(dt, q_lin, q_ang)
    return _State(E @ s.R, s.C + s.v * dt, s.w.copy(), s.v.copy(), 0.5 * (P + P.T), float(t_s), s.k), F


def predict_odometry(
    s: _State,
    t_s: float,
    T_camprev_camcurr: np.ndarray,
    cov_cam: np.ndarray,
    dt_dk: np.ndarray,
    q_lin: float,
    q_ang: float,
) -> tuple[_State, np.ndarray]:
    """The state at ``t_s`` moved by a measured relative camera motion, and F (13, 13).

    ``T_camprev_camcurr`` (4, 4, mm) is the camera's motion with the scale ``1 + s.k`` applied
    (:func:`odometry_to_camera`), ``dt_dk`` (3,) the derivative of its translation with respect to
    ``k`` (mm, previous camera frame); ``cov_cam`` (6, 6) its covariance as a right perturbation
    ``[rotation (rad), translation (mm)]`` in the current camera frame. The velocities are re-read
    from the motion (they do not depend on the previous ones: F's velocity rows are zero), with the
    odometry's noise divided by the step.
    """
    dt = float(t_s) - s.t
    R_rel, t_rel = T_camprev_camcurr[:3, :3], T_camprev_camcurr[:3, 3]
    R_new = s.R @ R_rel
    C_new = s.C + s.R @ t_rel
    F = np.eye(_N)
    F[3:6, 0:3] = -skew(s.R @ t_rel)
    F[3:6, 12] = s.R @ dt_dk
    G = np.zeros((_N, 6))
    G[0:3, 0:3] = R_new
    G[3:6, 3:6] = R_new
    if dt > 0:
        F[6:12, 6:12] = 0.0
        F[9:12, :] = F[3:6, :] / dt  # v = (C_new - C) / dt
        F[9:12, 3:6] = 0.0
        G[6:9, 0:3] = R_new / dt
        G[9:12, 3:6] = R_new / dt
        w, v = log_so3(R_new @ s.R.T) / dt, (C_new - s.C) / dt
    else:
        w, v = s.w.copy(), s.v.copy()
    Q = _white_acceleration(dt, q_lin, q_ang)
    Q[0:6, :] = 0.0  # the pose follows the odometry; the white acceleration only blurs the velocities
    Q[:, 0:6] = 0.0
    P = F @ s.P @ F.T + G @ cov_cam @ G.T + Q
    return _State(R_new, C_new, w, v, 0.5 * (P + P.T), float(t_s), s.k), F


def innovation(s: _State, T_meas: np.ndarray, cov_meas: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Residual r (6,) ``[log(R_meas R^T), C_meas - C]``, its covariance S (6, 6) and ``r^T S^-1 r``."""
    r = np.concatenate([log_so3(T_meas[:3, :3] @ s.R.T), T_meas[:3, 3] - s.C])
    S = s.P[:6, :6] + cov_meas
    S = 0.5 * (S + S.T)
    try:
        d2 = float(r @ np.linalg.solve(S, r))
    except np.linalg.LinAlgError:
        d2 = math.inf
    return r, S, d2


def update(s: _State, r: np.ndarray, S: np.ndarray, cov_meas: np.ndarray) -> tuple[_State, np.ndarray]:
    """The state corrected by a pose measurement (residual ``r``, its covariance ``S``; Joseph form), and the
    gain K (13, 6)."""
    K = np.linalg.solve(S, s.P[:6, :]).T  # P H^T S^-1, (13, 6)
    dx = K @ r
    IKH = _I13.copy()
    IKH[:, :6] -= K
    P = IKH @ s.P @ IKH.T + K @ cov_meas @ K.T
    return boxplus(s, dx, 0.5 * (P + P.T)), K


def boxminus(a: _State, b: _State) -> np.ndarray:
    """The error state (13,) taking ``b`` to ``a``: ``[log(R_a R_b^T), C_a - C_b, w_a - w_b, v_a - v_b, k_a - k_b]``."""
    return np.concatenate([log_so3(a.R @ b.R.T), a.C - b.C, a.w - b.w, a.v - b.v, [a.k - b.k]])


def boxplus(s: _State, dx: np.ndarray, P: np.ndarray) -> _State:
    """``s`` moved by the error state ``dx`` (13,), with the covariance ``P``."""
    return _State(exp_so3(dx[0:3]) @ s.R, s.C + dx[3:6], s.w + dx[6:9], s.v + dx[9:12], P, s.t, s.k + float(dx[12]))


def mount_covariance(T_world_camera: np.ndarray, cov_camera: np.ndarray, T_camera_base: np.ndarray) -> np.ndarray:
    """Covariance (6, 6) of ``T_world_base = T_world_camera @ T_camera_base`` from the camera's, same coordinates.

    The rotation error is the same (left, world axes); the base's position moves with the camera's
    centre and with the rotation about it: ``dP_base = dC - [R_world_camera t_camera_base]x dtheta``.
    """
    J = np.eye(6)
    J[3:6, 0:3] = -skew(T_world_camera[:3, :3] @ T_camera_base[:3, 3])
    out = J @ cov_camera @ J.T
    return 0.5 * (out + out.T)


def odometry_to_camera(T_prev_curr: np.ndarray, cov_base: np.ndarray, T_camera_base: np.ndarray | None, k: float):
    """The camera's relative motion, its covariance (right perturbation, camera frame) and the derivative
    (3,) of its translation with respect to the odometry's scale error ``k``, from the base's motion.

    The base's translation is taken as ``(1 + k)`` times the odometry's. Then
    ``T_cam_prev_curr = T_camera_base @ T_prev_curr @ T_base_camera``; a right perturbation
    ``xi = [rotation, translation]`` of the base becomes ``Ad(T_camera_base) xi`` for the camera, and
    the camera's translation moves with ``k`` by ``R_camera_base`` times the base's translation.
    """
    T = np.array(T_prev_curr, dtype=float)
    t_odo = T[:3, 3].copy()
    T[:3, 3] = (1.0 + k) * t_odo
    if T_camera_base is None:
        return T, cov_base, t_odo
    R, t = T_camera_base[:3, :3], T_camera_base[:3, 3]
    T_base_camera = np.eye(4)
    T_base_camera[:3, :3] = R.T
    T_base_camera[:3, 3] = -R.T @ t
    Ad = np.zeros((6, 6))
    Ad[0:3, 0:3] = R
    Ad[3:6, 3:6] = R
    Ad[3:6, 0:3] = skew(t) @ R
    return T_camera_base @ T @ T_base_camera, Ad @ cov_base @ Ad.T, R @ t_odo
