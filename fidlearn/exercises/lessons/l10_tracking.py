"""Lesson 10: Tracking over time.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("10", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ... import frames
from .._engine import Question, QuestionText
from .._parsers import _T_HINTS, _array, _cmp_transform, _scalar, _T_is
from .._scenery import _rng
from ._l10_consistency import _Q5, _Q6, _q5, _q6  # noqa: F401 (q5 and q6, kept apart for the module's length)

NUMBER = "10"
TOPIC = "tracking"
TITLE = "Tracking over time"
INTRO = """
    Filter the pose over time: the mean of rotations done right, the process noise chosen for a
    stated lag, the robot's pose from the camera's through the mount, a gap without markers
    bridged with odometry, whether a filter is consistent (its mean NIS against its band), and the
    rotation innovation of an update.
    """


def _exp(w: np.ndarray) -> np.ndarray:
    """A rotation vector (3,), rad, to its matrix."""
    return cv2.Rodrigues(np.asarray(w, dtype=float).reshape(3, 1))[0]


def _log(R: np.ndarray) -> np.ndarray:
    """A rotation matrix to its rotation vector (3,), rad."""
    return cv2.Rodrigues(np.asarray(R, dtype=float))[0].ravel()


def _manifold_mean(rotations: np.ndarray) -> np.ndarray:
    """The rotation whose logs to all the others sum to zero (Karcher mean), from the first one."""
    R = rotations[0]
    for _ in range(20):
        step = np.mean([_log(R.T @ Ri) for Ri in rotations], axis=0)
        R = R @ _exp(step)
        if np.linalg.norm(step) < 1e-13:
            break
    return R


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "The mean of three rotations",
    "task": """
        A robot was put three times at the same spot, facing the same way (backwards, about 180 deg
        from the world's x axis), and the tracker reported its orientation each time: `rotations`
        (3, 3, 3), three `R_world_base` matrices a few degrees apart. Write code that computes their
        mean rotation, a 3x3 rotation matrix as near as possible to all three.
        """,
    "hint": [
        "Near 180 deg the numbers that describe a rotation (angles, rotation vectors) jump from +180 to -180: "
        "averaging them averages the jump.",
        "Work in small steps from one of the rotations: express the others relative to it as rotation vectors "
        "(log), average those small vectors, and turn the average back into a rotation (exp). Repeat from the "
        "new mean until it stops moving.",
    ],
    "solution": """
        Rs = np.asarray(q1.inputs.rotations, dtype=float)
        R = Rs[0]
        for _ in range(10):
            step = np.mean([cv2.Rodrigues(R.T @ Ri)[0].ravel() for Ri in Rs], axis=0)
            R = R @ cv2.Rodrigues(step)[0]
        q1.answer = R
        """,
    "level": "medium",
}


def _cmp_rotation(tol_deg: float):
    def compare(a: np.ndarray, b: np.ndarray) -> str | None:
        if np.abs(a.T @ a - np.eye(3)).max() > 1e-3 or np.linalg.det(a) < 0:
            return "that is not a rotation matrix (its columns must be orthonormal, determinant +1)"
        ang = frames.rotation_angle_deg(a, b)
        return None if ang <= tol_deg else f"your rotation is {ang:.3g} deg from the mean"

    return compare


def _q1(learner: str) -> Question:
    """q1: The mean of three rotations."""
    rng = _rng("10", learner, "q1")
    backwards = frames.rotation_from_rpy_deg(0, 0, 180)
    while True:  # the mean must be none of the three, nor the plain "backwards" the task mentions
        yaws = [180 - rng.uniform(5, 15), 180 + rng.uniform(5, 15), 180 + rng.uniform(-3, 3)]
        Rs = np.array([frames.rotation_from_rpy_deg(*np.append(rng.uniform(-3, 3, 2), yaw)) for yaw in yaws])
        Rs = np.array([frames.rotation_from_rpy_deg(*np.round(frames.rpy_deg_from_rotation(R), 3)) for R in Rs])
        key = _manifold_mean(Rs)
        if min(frames.rotation_angle_deg(key, R) for R in (*Rs, backwards)) > 2.0:
            break
    rvec_mean = _exp(np.mean([_log(R) for R in Rs], axis=0))
    euler_mean = frames.rotation_from_rpy_deg(*np.mean([frames.rpy_deg_from_rotation(R) for R in Rs], axis=0))
    elementwise = Rs.mean(axis=0)

    def near(R):
        return lambda a: np.abs(a.T @ a - np.eye(3)).max() <= 1e-3 and frames.rotation_angle_deg(a, R) <= 0.5

    return Question(
        "q1",
        inputs={"rotations": Rs},
        expected=key,
        parse=_array((3, 3), "the mean rotation"),
        compare=_cmp_rotation(0.5),
        wrong=[
            (
                near(rvec_mean),
                (
                    "that averages the rotation vectors: near 180 deg they point to opposite sides (+pi and -pi "
                    "about nearly the same axis), and their mean is a rotation facing the other way. Average the "
                    "small rotations relative to one of them, then go back (exp)"
                ),
            ),
            (
                near(euler_mean),
                (
                    "that averages the Euler angles (roll, pitch, yaw): a yaw of +170 and one of -170 average to "
                    "0, facing forwards, while both face backwards. Average on the manifold (log, mean, exp)"
                ),
            ),
            (
                lambda a: np.abs(a - elementwise).max() <= 1e-6,
                (
                    "that is the element-wise mean of the matrices: not a rotation (its columns are shorter than "
                    "1). Average the small rotations relative to one of them, then go back (exp)"
                ),
            ),
        ],
        **_Q1,
    )


#: The process noises q2 offers, mm/s^2 per sqrt(Hz).
_Q2_CANDIDATES = (10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0, 10000.0)


def _kalman_1d(z: np.ndarray, t: np.ndarray, q: float, sigma: float) -> np.ndarray:
    """q2's filter: constant velocity, white acceleration q, positions z with noise sigma."""
    x = np.array([z[0], 0.0])
    P = np.diag([sigma**2, 500.0**2])
    out = [x[0]]
    for k in range(1, len(z)):
        dt = t[k] - t[k - 1]
        F = np.array([[1.0, dt], [0.0, 1.0]])
        x, P = F @ x, F @ P @ F.T + q**2 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        K = P[:, 0] / (P[0, 0] + sigma**2)
        x, P = x + K * (z[k] - x[0]), P - np.outer(K, P[0, :])
        out.append(x[0])
    return np.array(out)


def _q2_drive(rng: np.random.Generator) -> tuple:
    """A robot's drive along a line (truth, velocity, times, measurements, noise) whose lags are clear."""
    n, fps = 150, 30.0
    t = np.round(np.arange(n) / fps, 6)
    while True:
        acc = np.zeros(n)
        for _ in range(3):
            c, w = int(rng.integers(10, n - 20)), int(rng.integers(8, 20))
            acc[c : c + w] += float(rng.choice([-1, 1]) * rng.uniform(300, 800))
        v = np.cumsum(acc) / fps
        x = np.cumsum(v) / fps + float(np.round(rng.uniform(500, 2500)))
        sigma = float(np.round(rng.uniform(5, 15), 1))
        z = np.round(x + rng.normal(0, sigma, n), 2)
        lags = np.array([_lag_frames(_kalman_1d(z, t, q, sigma) - x, v, fps) for q in _Q2_CANDIDATES])
        ok = np.flatnonzero(lags <= 1.0)
        if ok.size and ok[0] > 0 and lags[ok[0]] <= 0.9 and lags[ok[0] - 1] >= 1.15 and np.all(np.diff(lags) < 0.05):
            return x, v, t, z, sigma, lags, int(ok[0])


def _lag_frames(error: np.ndarray, velocity: np.ndarray, fps: float) -> float:
    """The least-squares tau in ``error = -tau * velocity``, in frames."""
    return float(-(error @ velocity) / (velocity @ velocity) * fps)


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "Choosing the process noise",
    "task": """
        A robot drove along a line for 5 s; `measured_mm` (N,) are its positions as the camera gave
        them at `times_s` (N,), each with Gaussian noise of `sigma_mm`; `true_mm` and
        `true_velocity_mm_s` are the truth. Filter the positions with the notebook's Kalman filter
        in one dimension: state [position, velocity], starting at the first measurement at rest with
        covariance diag(sigma_mm^2, 500^2); predict with F = [[1, dt], [0, 1]] and
        Q = q^2 [[dt^3/3, dt^2/2], [dt^2/2, dt]]; update with H = [1, 0] and R = sigma_mm^2. Run it
        with each process noise q of `candidates` (mm/s^2 per sqrt(Hz)) and measure its lag in
        frames, tau = -(e . v) / (v . v) * 30, with e the filtered minus the true positions and v the
        true velocity. The goal: the least jitter (the smallest q) whose lag is at most one frame.
        Answer that q.
        """,
    "hint": [
        "A small q trusts the motion model: smooth, but late when the robot speeds up or brakes. A large q "
        "follows every measurement, noise included.",
        "Write the filter once as a function of q (notebook 10, section 2, with one coordinate), run it for "
        "every candidate, compute each lag, and keep the first candidate, in increasing order, that meets the goal.",
    ],
    "solution": """
        d = q2.inputs
        z, t, s = np.asarray(d.measured_mm), np.asarray(d.times_s), d.sigma_mm
        v = np.asarray(d.true_velocity_mm_s)

        def kalman(q):
            x, P, out = np.array([z[0], 0.0]), np.diag([s**2, 500.0**2]), [z[0]]
            for k in range(1, len(z)):
                dt = t[k] - t[k - 1]
                F = np.array([[1.0, dt], [0.0, 1.0]])
                x, P = F @ x, F @ P @ F.T + q**2 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
                K = P[:, 0] / (P[0, 0] + s**2)
                x, P = x + K * (z[k] - x[0]), P - np.outer(K, P[0, :])
                out.append(x[0])
            return np.array(out)

        def lag_frames(q):
            e = kalman(q) - np.asarray(d.true_mm)
            return -(e @ v) / (v @ v) * 30

        q2.answer = next(q for q in sorted(d.candidates) if lag_frames(q) <= 1.0)
        """,
    "level": "hard",
}


def _q2(learner: str) -> Question:
    """q2: Choosing the process noise."""
    rng = _rng("10", learner, "q2")
    x, v, t, z, sigma, lags, best = _q2_drive(rng)
    key = _Q2_CANDIDATES[best]

    def cmp2(a, b):
        if a == b:
            return None
        if a not in _Q2_CANDIDATES:
            return f"{a:g} is not one of the candidates {list(_Q2_CANDIDATES)}"
        return f"q = {a:g} is not the one the goal picks"

    def lag_of(a):
        return float(lags[_Q2_CANDIDATES.index(a)])

    return Question(
        "q2",
        inputs={
            "measured_mm": z,
            "times_s": t,
            "sigma_mm": sigma,
            "true_mm": np.round(x, 3),
            "true_velocity_mm_s": np.round(v, 3),
            "candidates": list(_Q2_CANDIDATES),
        },
        expected=key,
        parse=_scalar("the process noise"),
        compare=cmp2,
        wrong=[
            (
                lambda a: a in _Q2_CANDIDATES and a < key,
                lambda a: (
                    f"with q = {a:g} the filter lags {lag_of(a):.2f} frames behind the robot: it trusts its "
                    "constant-velocity model too much. The goal allows one frame"
                ),
            ),
            (
                lambda a: a in _Q2_CANDIDATES and a > key,
                lambda a: (
                    f"q = {a:g} meets the lag goal ({lag_of(a):.2f} frames), but so does a smaller q, which "
                    "follows less of the measurement noise: the goal asks for the least jitter"
                ),
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "The robot's pose from the camera's",
    "task": """
        The camera is mounted on a robot; the mount is `T_camera_base` (4x4, mm), the robot base's
        frame in the camera's frame (a point of the base: p_camera = T_camera_base @ p_base), as
        `PoseTracker(..., T_camera_base=...)` takes it. The tracker gave the camera's pose
        `T_world_camera`. Write code that computes the robot base's pose `T_world_base` (4x4, mm).
        """,
    "hint": [
        "Chain the frames by their names: world on the left, base on the right.",
        "Names cancel when the inner ones match: T_a_c = T_a_b @ T_b_c. Is the mount you have already the one "
        "that fits, or must it be turned round?",
    ],
    "solution": """
        q3.answer = q3.inputs.T_world_camera @ q3.inputs.T_camera_base
        """,
    "level": "easy",
}


def _q3_scene(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A camera on a robot standing in the room: (T_world_camera, T_camera_base), mm."""
    cam_yaw = float(np.round(rng.uniform(10, 35)) * rng.choice([-1, 1]))
    R_base_camera = frames.rot_z(math.radians(cam_yaw)) @ np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    offset = np.round(rng.uniform([80, -60, 250], [250, 60, 450]))
    T_base_camera = frames.make_transform(R_base_camera, offset)
    robot_xy = np.round(rng.uniform([800, -800], [2500, 800]))
    yaw = float(np.round(rng.uniform(-180, 180)))
    T_world_base = frames.make_transform(frames.rot_z(math.radians(yaw)), [robot_xy[0], robot_xy[1], 0.0])
    return np.round(T_world_base @ T_base_camera, 9), np.round(frames.invert_transform(T_base_camera), 9)


def _q3(learner: str) -> Question:
    """q3: The robot's pose from the camera's."""
    rng = _rng("10", learner, "q3")
    Twc, Tcb = _q3_scene(rng)
    key = Twc @ Tcb
    return Question(
        "q3",
        inputs={"T_world_camera": Twc, "T_camera_base": Tcb},
        expected=key,
        parse=_array((4, 4), "T_world_base", _T_HINTS),
        compare=_cmp_transform(0.05, 0.5),
        wrong=[
            (
                _T_is(Twc @ frames.invert_transform(Tcb)),
                (
                    "that uses the inverse mount, T_base_camera: T_world_camera @ T_base_camera does not chain "
                    "(camera next to base). The mount given, T_camera_base, already fits: world-camera, camera-base"
                ),
            ),
            (
                _T_is(Tcb @ Twc),
                "the order is turned round: T_camera_base @ T_world_camera does not chain; put the world on the left",
            ),
            (_T_is(Twc), "that is the camera's pose; the robot's base sits elsewhere on the robot"),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Bridging a gap with odometry",
    "task": """
        The camera was covered for a second. The last pose before the gap is `T_world_base_start`
        (4x4, mm); the wheel odometry gives the base's motion between consecutive frames,
        `odometry` (K, 4, 4): step k is `T_prev_curr`, the current base frame in the previous one.
        Write code that computes the base's pose `T_world_base` (4x4, mm) at the last frame of the
        gap from the odometry alone.
        """,
    "hint": [
        "Each step is measured in the robot's own frame at that moment, not in the world's.",
        "T_world_b1 = T_world_b0 @ T_b0_b1, then T_world_b2 = T_world_b1 @ T_b1_b2, and so on: in which order do "
        "the steps stand?",
    ],
    "solution": """
        T = np.asarray(q4.inputs.T_world_base_start, dtype=float)
        for step in q4.inputs.odometry:
            T = T @ step
        q4.answer = T
        """,
    "level": "medium",
}


def _q4(learner: str) -> Question:
    """q4: Bridging a gap with odometry."""
    rng = _rng("10", learner, "q4")
    k = int(rng.integers(8, 13))
    start_xy = np.round(rng.uniform([1500, -500], [3000, 500]))
    yaw = float(np.round(rng.uniform(-180, 180)))
    start = np.round(frames.make_transform(frames.rot_z(math.radians(yaw)), [start_xy[0], start_xy[1], 0.0]), 9)
    turn = float(rng.uniform(4, 8) * rng.choice([-1, 1]))
    steps = np.array(
        [
            np.round(
                frames.make_transform(
                    frames.rot_z(math.radians(turn + rng.uniform(-1, 1))), [rng.uniform(25, 40), rng.uniform(-2, 2), 0]
                ),
                9,
            )
            for _ in range(k)
        ]
    )
    key = start.copy()
    reversed_order, world_frame = start.copy(), start.copy()
    for s in steps:
        key = key @ s
        world_frame = s @ world_frame
    for s in steps[::-1]:
        reversed_order = reversed_order @ s
    added = start.copy()
    added[:3, 3] += steps[:, :3, 3].sum(axis=0)
    return Question(
        "q4",
        inputs={"T_world_base_start": start, "odometry": steps},
        expected=key,
        parse=_array((4, 4), "T_world_base", _T_HINTS),
        compare=_cmp_transform(0.05, 0.5),
        wrong=[
            (
                _T_is(reversed_order),
                (
                    "the steps are composed in the wrong order (last step first): each step is measured from the "
                    "pose the previous steps reached, T_world_start @ T_0_1 @ T_1_2 @ ..."
                ),
            ),
            (
                _T_is(world_frame),
                (
                    "the steps are applied on the left, as if measured in the world frame; odometry measures in "
                    "the robot's own frame: multiply on the right, T = T @ step"
                ),
            ),
            (
                lambda a: a.shape == (4, 4) and np.linalg.norm(a[:3, 3] - added[:3, 3]) <= 0.5,
                (
                    "that adds up the steps' translations as if they were in the world frame; each is in the robot's "
                    "frame of the moment, turned as the robot turned: compose the 4x4 steps"
                ),
            ),
        ],
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 10 for one learner, in notebook order.

    Parameters
    ----------
    learner : str
        The learner's id; it seeds every question's numbers (``""``: the class's shared variant).

    Returns
    -------
    list of Question
        q1 to q6, with their answer keys.
    """
    return [_q1(learner), _q2(learner), _q3(learner), _q4(learner), _q5(learner), _q6(learner)]
