"""The track: measurements (a frame's :class:`Pose`, or none) and odometry fed to the filter, step by step.

Shared by :class:`~fidlearn.filtering.PoseTracker` (live) and :func:`~fidlearn.filtering.smooth`
(offline, which keeps every step's prediction for the backward pass).

With the learnt noise (the default) the poses' covariance ``R`` is read as two parts
(:mod:`fidlearn.filtering._adapt`): ``share * R`` varies from frame to frame and ``(1 - share) * R`` is shared
with the frames around it. The filter runs on the poses' covariance as given (its gains are those of
``share * R`` with the process noise scaled alike); its covariance, read at that scale, is the error of the
varying part, and its NIS is ``d2 / share`` (``d2`` the distance with ``R`` as given, on which the gate and
the manoeuvre test still work). The shared part of frame ``k`` is ``B_k u_k``, ``B_k = sqrt(1 - share) chol(R_k)``
and ``u`` (6,) a first-order Gauss-Markov process of unit covariance (``u_k = a u_{k-1} + sqrt(1 - a^2) n_k``,
``a = exp(-dt / SHARED_ERROR_TIME_S)``: all shared errors taken as one, which an unchanging view makes exact).
It enters the track as a frame's error does, through the gain: the state's error from it follows
``e_k = (I - K_k H) F_k e_{k-1} + K_k B_k u_k``, and the track carries its covariance ``C`` (13, 13) and its
covariance with ``u`` ``X`` (13, 6) exactly (:func:`predict_shared`, ``_Track._enter_shared``); ``C``'s pose
block is added to the covariance the track reports, and the smoother carries the same error backwards
(:mod:`fidlearn.filtering._smoother`). On the tracking benchmark's drive the NIS with ``R`` as given averaged 4.0
(frames from several markers: 4.7) while the track held the truth in its 95 % ellipsoid in only 88 % of
the frames: the frames' errors persist from one to the next, which the innovations cannot see.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import frames
from ..errors import TrackingError
from ..pose import Pose
from . import _filter as kf
from ._adapt import MANOEUVRE_CHI2, PROCESS_NOISE_START, NoiseLearner, manoeuvre_inflation
from ._result import TrackedPose
from ._so3 import log_so3

#: Default process noise: None, learnt from the innovations (:mod:`fidlearn.filtering._adapt`). A fixed
#: one is white acceleration of the camera centre (mm/s^2 per sqrt(Hz)) and of its rotation (rad/s^2 per
#: sqrt(Hz)): the velocity's standard deviation grows by this much in one second.
DEFAULT_PROCESS_NOISE = None
#: Largest time (s, either sign) a frame may have: about 31,700 years, far beyond any clock (Unix
#: seconds are 1.8e9 now); a gap of 1e300 s overflowed the prediction's covariance.
MAX_TIME_S = 1e12
#: Largest variance a pose's covariance may hold (rad^2 or mm^2): beyond it the pose says nothing.
MAX_VARIANCE = 1e30
#: How long (s) the error the poses share from frame to frame lasts: the time constant of the Gauss-Markov process
#: it is taken as. Chosen on four more seeds of the tracking benchmark's drive (drive and noise seeds (5, 12),
#: (6, 13), (7, 14), (8, 15)): 0.07 s left the truth in the track's 95 % ellipsoid in 91-95 % of the frames, 0.1 s in
#: 93-96 % (the smoother's in 93-97 %), 0.15 s in 94-97 % (93-99 %), 0.2 s in 95-97 % (93-100 %) and 1 s in
#: 97-98 % (93-100 %); at 0.1 s the tracker's is 92-96 % since a frame without a shared error also corrects the one
#: the track holds (the smoother's as before). Errors that last longer than this make the track overconfident:
#: corner offsets that persist 0.7 s (``tests/test_track_consistency.py``) left the smoother's ellipsoid holding
#: the truth in 78-95 %.
SHARED_ERROR_TIME_S = 0.1
_I3, _I6 = np.eye(3), np.eye(6)


@dataclass
class _Step:
    """One step of a recorded track: the transition F into it (None when a segment starts here),
    the predicted and the filtered state, and what the output said."""

    F: np.ndarray | None
    predicted: kf._State
    filtered: kf._State
    out: TrackedPose
    #: the shared error after this step (the module's docstring), as the track carried it: its covariance ``C``
    #: (13, 13) in the state and the state's covariance with ``u`` ``X`` (13, 6) (None: a fixed noise, no shared
    #: error), and the fade ``a`` of ``u`` into this step (:func:`shared_fade`; 0 where a segment starts)
    shared_cov: np.ndarray | None = None
    shared_cross: np.ndarray | None = None
    fade: float = 0.0
    #: the gain's pose columns K (13, 6) of a measured step (None: no frame corrected it) and the square root
    #: (6, 6) of the frame's shared error, as it entered (None: none); with ``F`` and ``fade``, how the step
    #: moved the state's error and ``u`` (:meth:`shared_transition`), which the smoother carries backwards
    #: (:mod:`fidlearn.filtering._smoother`)
    gain: np.ndarray | None = None
    entry: np.ndarray | None = None

    @property
    def shared(self) -> np.ndarray | None:
        """The covariance (6, 6) of the shared error in the filtered pose (None: none is carried)."""
        return None if self.shared_cov is None else self.shared_cov[:6, :6]

    def shared_transition(self) -> tuple[np.ndarray, np.ndarray]:
        """``(A, KB)``: the step (not a segment's start) took the shared error's part of the state's error ``e``
        and ``u`` to ``A e + a KB u + sqrt(1 - a^2) KB n`` and ``a u + sqrt(1 - a^2) n`` (``a`` the step's
        ``fade``, ``n`` new), as the track carried them (:func:`predict_shared`, then ``_Track._enter_shared``
        for a measured step): ``A = (I - K H) F`` and ``KB = K B`` (0 for a frame without a shared error), or
        ``F`` and 0 for a step no frame corrected."""
        assert self.F is not None
        if self.gain is None:
            return self.F, np.zeros((kf._N, 6))
        KB = np.zeros((kf._N, 6)) if self.entry is None else self.gain @ self.entry
        return self.F - self.gain @ self.F[:6], KB


def shared_fade(dt: float) -> float:
    """How much of the shared error's process ``u`` lasts ``dt`` seconds: ``exp(-dt / SHARED_ERROR_TIME_S)``."""
    return math.exp(-max(dt, 0.0) / SHARED_ERROR_TIME_S)


def predict_shared(C: np.ndarray, X: np.ndarray, F: np.ndarray, fade: float) -> tuple[np.ndarray, np.ndarray]:
    """The shared error's covariance in the state ``C`` (13, 13) and the state's covariance with ``u`` ``X``
    (13, 6) carried by the transition ``F``: the state's error becomes ``F e`` and ``u`` becomes
    ``a u + sqrt(1 - a^2) n`` with ``a = fade`` (:func:`shared_fade` of the time step; ``n`` new, independent)."""
    FC = F @ C
    out = FC @ F.T
    return 0.5 * (out + out.T), fade * (F @ X)


def check_process_noise(process_noise) -> tuple[float, float] | None:
    """None (learn it), or ``(linear_mm_s2, angular_rad_s2)``, both finite and > 0; TrackingError otherwise."""
    if process_noise is None:
        return None
    try:
        q_lin, q_ang = (float(v) for v in process_noise)
    except (TypeError, ValueError):
        q_lin = q_ang = math.nan
    if not (0 < q_lin <= 1e7 and 0 < q_ang <= 1e4):  # NaN fails too
        raise TrackingError(
            f"process_noise must be None (learnt from the frames) or two numbers > 0 (at most 1e7 and 1e4), "
            f"(linear mm/s^2, angular rad/s^2) per sqrt(Hz), e.g. (50, 0.1), got {process_noise!r}"
        )
    return q_lin, q_ang


def check_mount(T_camera_base) -> np.ndarray | None:
    """The mount (4, 4, mm) as a checked rigid transform, or None."""
    if T_camera_base is None:
        return None
    return frames.check_transform(T_camera_base, "T_camera_base")


def check_odometry(odometry) -> tuple[np.ndarray, np.ndarray] | None:
    """``(T_prev_curr (4, 4) mm, covariance (6, 6))`` checked, or None."""
    if odometry is None:
        return None
    if not isinstance(odometry, (tuple, list)) or len(odometry) != 2:
        raise TrackingError(
            "odometry must be a pair (T_prev_curr, covariance): the base's motion since the last frame "
            "(4x4, mm) and its 6x6 covariance [rotation (rad), translation (mm)]"
        )
    T = frames.check_transform(odometry[0], "odometry T_prev_curr")
    cov = np.asarray(odometry[1], dtype=float) if _numeric(odometry[1]) else None
    if cov is None or cov.shape != (6, 6) or not np.isfinite(cov).all():
        raise TrackingError("odometry covariance must be a 6x6 array of finite numbers ([rad, mm] order)")
    scale = max(1.0, float(np.abs(cov).max()))
    lowest = np.linalg.eigvalsh(0.5 * (cov + cov.T)).min()
    if not np.allclose(cov, cov.T, rtol=1e-6, atol=1e-12) or lowest < -1e-9 * scale:
        raise TrackingError("odometry covariance must be symmetric positive semi-definite")
    return T, 0.5 * (cov + cov.T)


def _numeric(value) -> bool:
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return True


def check_time(t_s, last: float | None) -> float:
    """The time as a float, never before ``last``; TrackingError otherwise."""
    if (
        isinstance(t_s, bool)
        or not isinstance(t_s, (int, float, np.integer, np.floating))
        or not abs(float(t_s)) <= MAX_TIME_S  # NaN and huge integers fail too
    ):
        raise TrackingError(f"t_s must be a finite time in seconds (at most {MAX_TIME_S:g} either way), got {t_s!r}")
    if last is not None and float(t_s) < last:
        raise TrackingError(
            f"t_s={float(t_s):.6f} s is before the last frame's {last:.6f} s; give frames in time order"
        )
    return float(t_s)


def check_pose(pose, where: str = "pose") -> None:
    """A :class:`Pose` the filter can use: a 6x6 covariance (or None), its alternative likewise; TrackingError."""
    if not isinstance(pose, Pose):
        raise TrackingError(f"{where} must be a fidlearn.Pose or None, got {type(pose).__name__}")
    if not _plain_rigid(pose.T_world_camera):
        frames.check_transform(pose.T_world_camera, f"{where}.T_world_camera")
    cov = pose.covariance
    if cov is not None:
        arr = np.asarray(cov, dtype=float) if _numeric(cov) else None
        if arr is None or arr.shape != (6, 6) or not (np.abs(arr) <= MAX_VARIANCE).all():
            shape = "not numbers" if arr is None else f"shape {arr.shape}"
            raise TrackingError(
                f"{where}.covariance must be a 6x6 array of finite numbers (at most {MAX_VARIANCE:g}) "
                f"[dtheta (rad), position (mm)], or None; got {shape}"
            )
        if not _symmetric_psd(arr):
            raise TrackingError(f"{where}.covariance must be symmetric positive semi-definite")
    if not isinstance(pose.marker_ids, (tuple, list)):
        raise TrackingError(f"{where}.marker_ids must be a tuple of marker ids, got {type(pose.marker_ids).__name__}")
    alt = alternative(pose) if pose.ambiguous else None  # an unambiguous pose's alternative is never built
    if alt is not None:
        check_pose(alt, f"{where}.alternative")


def _plain_rigid(T) -> bool:
    """True for a (4, 4) float array that :func:`fidlearn.frames.check_transform` accepts (the same checks on
    plain floats, a few microseconds; the messages that name what is wrong are left to it)."""
    if not (isinstance(T, np.ndarray) and T.shape == (4, 4) and T.dtype == np.float64):
        return False
    rows = T.tolist()
    if not math.isfinite(sum(map(sum, rows))):  # NaN or infinity anywhere (a finite sum of finite floats)
        return False
    (a, b, c, _), (d, e, f, _), (g, h, i, _), (w, x, y, z) = rows
    if max(abs(w), abs(x), abs(y), abs(z - 1.0)) > 1e-6:
        return False
    gram = (
        a * a + d * d + g * g - 1.0,
        b * b + e * e + h * h - 1.0,
        c * c + f * f + i * i - 1.0,
        a * b + d * e + g * h,
        a * c + d * f + g * i,
        b * c + e * f + h * i,
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return max(map(abs, gram)) <= 1e-6 and det > 0


def _symmetric_psd(arr: np.ndarray) -> bool:
    """``arr`` (6, 6) symmetric (as ``np.allclose(arr, arr.T, rtol=1e-6, atol=1e-12)``) with no eigenvalue below
    ``-1e-9`` times its largest entry (at least 1): a Cholesky factor of ``arr`` plus that much, else the
    eigenvalues."""
    if not (np.abs(arr - arr.T) <= 1e-12 + 1e-6 * np.abs(arr.T)).all():
        return False
    tol = 1e-9 * max(1.0, float(np.abs(arr).max()))
    try:
        np.linalg.cholesky(arr + tol * _I6)
        return True
    except np.linalg.LinAlgError:
        return bool(np.linalg.eigvalsh(arr).min() >= -tol)


def alternative(pose: Pose) -> Pose | None:
    """The pose's other planar solution, or None (:attr:`fidlearn.Pose.alternative`, a property)."""
    alt: Pose | None = getattr(pose, "alternative")  # noqa: B009 (declared as an InitVar, read as a property)
    return alt


def _root(cov: np.ndarray) -> np.ndarray:
    """A square root ``L`` (6, 6) of a covariance, ``L L^T = cov``: its Cholesky factor, else from its eigenvalues."""
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (cov + cov.T))
        return V * np.sqrt(np.clip(w, 0.0, None))


def _step(pose: Pose, alt: Pose) -> np.ndarray:
    """The error-state step (6,) ``[rotation (rad), position (mm)]`` from ``pose`` to ``alt``."""
    return np.concatenate(
        [log_so3(alt.T_world_camera[:3, :3] @ pose.T_world_camera[:3, :3].T), alt.position_mm - pose.position_mm]
    )


def _well_determined(pose: Pose | None) -> bool:
    """A pose from several markers that is not ambiguous: one that may teach the motion noise."""
    return pose is not None and not pose.ambiguous and len(pose.marker_ids) > 1


class _Track:
    """The filter's state and its steps (see the module's docstring)."""

    def __init__(self, process_noise, T_camera_base, record: bool = False):
        self.fixed = check_process_noise(process_noise)
        self.learner = NoiseLearner() if self.fixed is None else None
        self.T_camera_base = check_mount(T_camera_base)
        self.state: kf._State | None = None
        self.rejections = 0
        self.steps: list[_Step] | None = [] if record else None
        self.nis_sum, self.nis_count = 0.0, 0
        # the error the frames share (the module's docstring): its covariance in the state (13, 13) and the
        # state's covariance with the unit Gauss-Markov process u that drives it (13, 6); cov(u) = I
        self.shared_cov, self.shared_cross = np.zeros((kf._N, kf._N)), np.zeros((kf._N, 6))
        self.fade = 0.0  # how much of u lasted into the latest step (shared_fade)

    @property
    def q(self) -> tuple[float, float]:
        """The process noise in force: ``(q_lin, q_ang)``, fixed or learnt so far."""
        return self.learner.q if self.learner is not None else self.fixed  # type: ignore[return-value]

    # -- one step ----------------------------------------------------------------------------
    def step(self, pose: Pose | None, t_s: float, odometry, why: str = "") -> TrackedPose:
        """Advance to ``t_s`` (odometry or the motion model), then correct with ``pose`` if it agrees."""
        t = check_time(t_s, None if self.state is None else self.state.t)
        odo = check_odometry(odometry)
        if pose is not None:
            check_pose(pose)
        if pose is not None and pose.covariance is None:
            pose, why = None, "the frame's pose is not determined (no covariance)"
        if self.state is None:
            if pose is None:
                raise TrackingError(
                    f"no pose yet at t_s={t:.3f}: the track starts at the first frame with a pose "
                    f"({why or 'none given'})"
                )
            return self._start(pose, t, "started", None)
        well_determined = _well_determined(pose)
        predicted, F = self._predict(t, odo, well_determined)
        if pose is None:
            status = "odometry" if odo is not None else "predicted"
            return self._keep(F, predicted, predicted, status, reason=why)
        T, cov, flipped = self._choose(pose, predicted)
        # only a well-determined pose teaches the noise or tells a manoeuvre: an ambiguous one, or one from a
        # single marker, has heavy tails and errors that persist from frame to frame (and a flip is no manoeuvre)
        learner = self.learner if well_determined else None
        r, S, d2 = kf.innovation(predicted, T, cov)
        learnt = (r, S)
        if learner is not None and odo is None and d2 > MANOEUVRE_CHI2:
            predicted, (r, S, d2) = self._manoeuvre(predicted, T, cov, r)
        if d2 > kf.GATE_CHI2:
            return self._reject(F, predicted, pose, t, d2)
        self.rejections = 0
        if learner is not None:
            learner.learn(*learnt)
        nis = d2 if self.learner is None else self.learner.nis(d2)
        self.nis_sum, self.nis_count = self.nis_sum + nis, self.nis_count + 1
        chosen = alternative(pose) if flipped else pose
        filtered, K = kf.update(predicted, r, S, cov)
        root = self._shared_root(cov)
        if self.learner is not None:  # the shared error enters the track as the frame's does, through the gain
            self._enter_shared(K, root)
        if self.learner is not None:
            self.learner.learn_share(d2)
        return self._keep(F, predicted, filtered, "measured", d2=nis, pose=chosen, flipped=flipped, gain=K, entry=root)

    def _reject(self, F, predicted: kf._State, pose: Pose, t: float, d2: float) -> TrackedPose:
        """A frame beyond the gate: the prediction is the output (or, after too many, the track restarts)."""
        self.rejections += 1
        if self.rejections > kf.MAX_REJECTIONS:
            return self._start(pose, t, "restarted", None)
        reason = (
            f"disagrees with the track: squared Mahalanobis distance {d2:.1f} > {kf.GATE_CHI2:.1f} "
            f"(chi-square, 6 degrees of freedom, {kf.GATE_PROBABILITY}; the frame's covariance as given)"
        )
        nis = d2 if self.learner is None else self.learner.nis(d2)
        return self._keep(F, predicted, predicted, "rejected", reason=reason, d2=nis)

    def _manoeuvre(self, predicted: kf._State, T: np.ndarray, cov: np.ndarray, r: np.ndarray):
        """The prediction with this step's process noise raised until the frame fits (a sudden manoeuvre), and
        the frame's innovation from it; at most up to the learner's ceiling."""
        assert self.learner is not None
        assert self.state is not None
        Q = kf._white_acceleration(predicted.t - self.state.t, *self.learner.q)
        lam = manoeuvre_inflation(predicted.P, Q, r, cov, self.learner.headroom())
        self.learner.manoeuvre(lam)
        wide = predicted.copy()
        wide.P = predicted.P + (lam - 1.0) * Q
        return wide, kf.innovation(wide, T, cov)

    def _predict(self, t: float, odo, well_determined: bool):
        """The prediction to ``t``. Before a frame that cannot teach the noise (no pose, an ambiguous one, one
        marker) the learnt noise is trusted no lower than ``PROCESS_NOISE_START``: what was learnt on
        well-determined frames need not hold while the frames cannot check it."""
        assert self.state is not None
        q_lin, q_ang = self.q
        if self.learner is not None and not well_determined:
            q_lin, q_ang = max(q_lin, PROCESS_NOISE_START[0]), max(q_ang, PROCESS_NOISE_START[1])
        if odo is None:
            predicted, F = kf.predict_constant_velocity(self.state, t, q_lin, q_ang)
        else:
            T_rel, cov_rel, dt_dk = kf.odometry_to_camera(odo[0], odo[1], self.T_camera_base, self.state.k)
            predicted, F = kf.predict_odometry(self.state, t, T_rel, cov_rel, dt_dk, q_lin, q_ang)
        if self.learner is not None:
            self.fade = shared_fade(t - self.state.t)
            self.shared_cov, self.shared_cross = predict_shared(self.shared_cov, self.shared_cross, F, self.fade)
        return predicted, F

    def _start(self, pose: Pose, t: float, status: str, F) -> TrackedPose:
        self.rejections = 0
        if self.learner is not None:
            self.learner.forget_lag()
        assert pose.covariance is not None
        cov = np.asarray(pose.covariance, dtype=float)
        root = self._shared_root(cov)
        self.shared_cov, self.shared_cross, self.fade = np.zeros((kf._N, kf._N)), np.zeros((kf._N, 6)), 0.0
        if root is not None:  # the start's error is the frame's own
            self.shared_cross[:6] = root
            self.shared_cov[:6, :6] = root @ root.T
        self.state = kf.start_state(pose.T_world_camera, cov, t)
        return self._keep(F, self.state, self.state, status, pose=pose, entry=root)

    def _keep(
        self, F, predicted, filtered, status, *, reason="", d2=None, pose=None, flipped=False, gain=None, entry=None
    ) -> TrackedPose:
        self.state = filtered
        shared = None if self.learner is None else self.shared_cov[:6, :6].copy()
        out = self.output(filtered, status, reason=reason, d2=d2, pose=pose, flipped=flipped, shared=shared)
        if self.steps is not None:  # C and X are replaced at every step, never changed in place: kept as they are
            C, X = (None, None) if self.learner is None else (self.shared_cov, self.shared_cross)
            self.steps.append(_Step(F, predicted, filtered, out, C, X, self.fade, gain, entry))
        return out

    def _enter_shared(self, K: np.ndarray, root: np.ndarray | None) -> None:
        """A frame whose shared error is ``root @ u`` (None: it has none, the share being 1 or more) corrected the
        state with the gain ``K`` (13, 6): the state's error ``e`` becomes ``(I - K H) e + K root u`` (see
        :func:`predict_shared`). The shared error the state already holds is corrected by the gain either way."""
        C, X = self.shared_cov, self.shared_cross
        AX = X - K @ X[:6]  # (I - K H) X
        AC = C - K @ C[:6]  # (I - K H) C
        out = AC - AC[:, :6] @ K.T  # (I - K H) C (I - K H)^T
        if root is not None:
            KB = K @ root
            cross = AX @ KB.T
            out = out + cross + cross.T + KB @ KB.T
            AX = AX + KB
        self.shared_cov, self.shared_cross = 0.5 * (out + out.T), AX

    @property
    def share(self) -> float:
        """The share of the poses' covariance that varies from frame to frame: learnt, or 1 (a fixed noise)."""
        return 1.0 if self.learner is None else self.learner.share

    def _shared_root(self, cov: np.ndarray) -> np.ndarray | None:
        """A square root of the rest of a pose's covariance ``cov``: the error it shares with the frames around
        it (None when there is none)."""
        share = self.share
        return None if share >= 1.0 else math.sqrt(1.0 - share) * _root(cov)

    # -- the measurement ---------------------------------------------------------------------
    def _choose(self, pose: Pose, predicted: kf._State) -> tuple[np.ndarray, np.ndarray, bool]:
        """The solution that agrees with the prediction: the pose, or (ambiguous frames) its alternative.

        Both are measured against the prediction with one covariance, the frame's own (for an
        ambiguous frame :func:`fidlearn.estimate_pose` reports the two-pose mixture, which reaches
        the alternative): the nearer one in that metric wins, a fair choice whatever the metric.
        The alternative then enters with that covariance plus ``d d^T`` (``d`` the step between
        the two solutions), an upper bound of the mixture's second moment about it: a solution
        IPPE ranked second is never trusted more than the frame's data allow. Either is widened by
        ``AMBIGUOUS_INFLATION`` (see :mod:`fidlearn.filtering._filter`), and so is a pose from a single
        marker that is not flagged: its error surface is as far from quadratic.
        """
        alt = alternative(pose) if pose.ambiguous else None
        assert pose.covariance is not None
        cov = np.asarray(pose.covariance, dtype=float)
        if alt is None:
            wide = pose.ambiguous or len(pose.marker_ids) == 1
            return pose.T_world_camera, cov * (kf.AMBIGUOUS_INFLATION if wide else 1.0), False
        d_pose = kf.innovation(predicted, pose.T_world_camera, cov)[2]
        d_alt = kf.innovation(predicted, alt.T_world_camera, cov)[2]
        if d_alt < d_pose:
            d = _step(pose, alt)
            return alt.T_world_camera, kf.AMBIGUOUS_INFLATION * (cov + np.outer(d, d)), True
        return pose.T_world_camera, kf.AMBIGUOUS_INFLATION * cov, False

    # -- the answer --------------------------------------------------------------------------
    def output(
        self, s: kf._State, status: str, *, reason="", d2=None, pose=None, flipped=False, shared=None
    ) -> TrackedPose:
        """The TrackedPose of state ``s``: its covariance read at the learnt share, plus ``shared`` (6, 6), the
        error shared with the frames."""
        T = s.T()
        cov = (0.5 * self.share) * (s.P[:6, :6] + s.P[:6, :6].T)
        if shared is not None:
            cov = cov + shared
        T_base = cov_base = None
        if self.T_camera_base is not None:
            T_base = T @ self.T_camera_base
            cov_base = kf.mount_covariance(T, cov, self.T_camera_base)
        return TrackedPose(
            t_s=s.t,
            T_world_camera=T,
            covariance=cov,
            status=status,
            flip_resolved=flipped,
            reason=reason,
            mahalanobis2=d2,
            pose=pose,
            T_world_base=T_base,
            base_covariance=cov_base,
            velocity_mm_s=s.v.copy(),
            angular_velocity_rad_s=s.w.copy(),
            odometry_scale=1.0 + s.k,
            odometry_scale_std=math.sqrt(max(float(s.P[12, 12]), 0.0)),
            process_noise=self.q,
        )
