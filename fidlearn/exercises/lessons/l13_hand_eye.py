"""Lesson 13: The robot's truth: hand-eye calibration.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("13", learner, "qN")``), so a learner's variant of one question
does not depend on the others. A static camera watches a board that a robot holds on its flange:
``T_camera_board(i) = inv(T_base_camera) @ T_base_tool(i) @ T_tool_board``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ... import frames
from ...frames import look_at
from .._engine import Question, QuestionText
from .._parsers import _T_HINTS, _array, _close, _cmp_array, _cmp_scalar, _cmp_transform, _scalar, _T_is
from .._scenery import _rng

NUMBER = "13"
TOPIC = "hand_eye"
TITLE = "The robot's truth: hand-eye calibration"
INTRO = """
    A robot holds a board in front of a camera that stands still. Chain the robot's pose into the
    board's pose in the camera, solve the two halves of the hand-eye problem AX = XB (the rotation,
    then the translation), and judge a measured pose by what the robot says.
    """


def _robot_scene(rng: np.random.Generator, n: int) -> tuple:
    """A static camera, a board on the flange and n robot poses: (T_base_camera, T_tool_board, [T_base_tool])."""
    T_base_camera = look_at(np.round(rng.uniform([-200, 1100, 200], [200, 1400, 500])), [0.0, 600.0, 500.0])
    R_tb = frames.rotation_from_rpy_deg(*np.round(rng.uniform(-20, 20, 3), 1))
    T_tool_board = frames.make_transform(R_tb, np.round(rng.uniform([-60, -60, 180], [60, 60, 260])))
    # the flange holds the board facing the camera, turned differently in every photo
    R_face = T_base_camera[:3, :3] @ frames.rotation_from_rpy_deg(180, 0, 0) @ R_tb.T
    poses = []
    for _ in range(n):
        turn = Rotation.from_rotvec(rng.uniform(-0.5, 0.5, 3)).as_matrix()
        R = turn @ R_face
        board_at = np.array([0.0, 600.0, 500.0]) + rng.uniform(-150, 150, 3)
        poses.append(frames.make_transform(R, board_at - R @ T_tool_board[:3, 3]))
    return T_base_camera, T_tool_board, poses


def _camera_board(T_base_camera, T_base_tool, T_tool_board) -> np.ndarray:
    return np.linalg.inv(T_base_camera) @ T_base_tool @ T_tool_board


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "The board in the camera, from the robot",
    "task": """
        The camera stands at `T_base_camera` in the robot's base frame; the board is clamped on the
        flange at `T_tool_board`; for one photo the robot reports its flange at `T_base_tool` (all
        4x4, mm). Write code that computes the board's pose in the camera, T_camera_board (4x4, mm),
        from the robot alone.
        """,
    "hint": [
        "Follow the names: each transform takes you from the frame on its right to the frame on its left.",
        (
            "From the camera to the base you need the camera seen from the base turned around; then base to "
            "flange, then flange to board. The inner names must match, as in notebook 03."
        ),
    ],
    "solution": """
        d = q1.inputs
        q1.answer = np.linalg.inv(d.T_base_camera) @ d.T_base_tool @ d.T_tool_board
        """,
    "level": "easy",
}


def _q1(learner: str) -> Question:
    """q1: The board in the camera, from the robot."""
    rng = _rng(NUMBER, learner, "q1")
    T_bc, T_tb, poses = _robot_scene(rng, 1)
    T_bt = poses[0]
    key = _camera_board(T_bc, T_bt, T_tb)
    return Question(
        "q1",
        inputs={"T_base_camera": T_bc, "T_base_tool": T_bt, "T_tool_board": T_tb},
        expected=key,
        parse=_array((4, 4), "T_camera_board", _T_HINTS),
        compare=_cmp_transform(0.05, 0.5),
        wrong=[
            (
                _T_is(T_bc @ T_bt @ T_tb),
                "T_base_camera goes from the camera to the base; the chain starts in the camera, so it needs "
                "the inverse: inv(T_base_camera) @ ...",
            ),
            (
                _T_is(np.linalg.inv(key)),
                "that is the camera in the board's frame (T_board_camera): invert it",
            ),
            (
                _T_is(np.linalg.inv(T_bc) @ np.linalg.inv(T_bt) @ T_tb),
                "the robot reports the flange in the base (T_base_tool), which the chain uses as it is",
            ),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "The hand-eye rotation",
    "task": """
        Pairs of photos give motions A (of the flange, in the base) and B (of the board, seen from
        the camera) with A X = X B, X = T_base_camera. Their rotation parts obey alpha = R_X beta,
        where `alpha` (k, 3) and `beta` (k, 3) are the rotation vectors (radians) of the pairs'
        rotations R_A and R_B, measured with a little noise. Write code that finds the rotation R_X
        (3x3) that best turns every beta into its alpha.
        """,
    "hint": [
        "It is the problem of aligning two sets of vectors by one rotation, as for two point clouds.",
        (
            "Sum the outer products of each alpha with its beta into one 3x3 matrix; the rotation nearest to it "
            "(its SVD, with the determinant made +1) is the answer. Mind which vector goes on the left."
        ),
    ],
    "solution": """
        d = q2.inputs
        M = sum(np.outer(a, b) for a, b in zip(d.alpha, d.beta))
        U, _, Vt = np.linalg.svd(M)
        q2.answer = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
        """,
    "level": "hard",
}


def _kabsch(M: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def _q2(learner: str) -> Question:
    """q2: The hand-eye rotation."""
    rng = _rng(NUMBER, learner, "q2")
    while True:  # R_X never near a half turn, where it and its transpose are alike
        T_bc, T_tb, poses = _robot_scene(rng, 6)
        yaw = frames.make_transform(frames.rotation_from_rpy_deg(0, 0, float(rng.uniform(-150, 150))))
        T_bc, poses = yaw @ T_bc, [yaw @ T for T in poses]  # the robot's base turned on the floor
        if frames.rotation_angle_deg(T_bc[:3, :3], T_bc[:3, :3].T) > 10:
            break
    T_cb = [_camera_board(T_bc, T, T_tb) for T in poses]
    pairs = [(i, j) for i in range(len(poses)) for j in range(i + 1, len(poses))]
    A = [poses[i] @ np.linalg.inv(poses[j]) for i, j in pairs]
    B = [T_cb[i] @ np.linalg.inv(T_cb[j]) for i, j in pairs]
    alpha = np.array([Rotation.from_matrix(a[:3, :3]).as_rotvec() for a in A]) + rng.normal(0, 2e-4, (len(A), 3))
    beta = np.array([Rotation.from_matrix(b[:3, :3]).as_rotvec() for b in B]) + rng.normal(0, 2e-4, (len(B), 3))
    alpha, beta = np.round(alpha, 6), np.round(beta, 6)
    key = _kabsch(np.sum([np.outer(a, b) for a, b in zip(alpha, beta)], axis=0))
    transposed = key.T
    return Question(
        "q2",
        inputs={"alpha": alpha, "beta": beta},
        expected=key,
        parse=_array((3, 3), "R_X"),
        compare=lambda a, b: (
            None
            if frames.rotation_angle_deg(_kabsch(a), b) <= 0.05 and np.abs(a.T @ a - np.eye(3)).max() < 1e-3
            else "that rotation does not turn the betas into the alphas"
        ),
        wrong=[
            (
                lambda a: np.abs(a - transposed).max() < 1e-3,
                "that turns the alphas into the betas: the outer products are the other way round (alpha on the "
                "left: it is the vector the rotation must produce)",
            ),
            (
                lambda a: np.abs(a.T @ a - np.eye(3)).max() >= 1e-3,
                "not a rotation matrix: take the rotation nearest to the summed matrix (its SVD)",
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Then the hand-eye translation",
    "task": """
        With the rotation R_X known, the translation part of A X = X B is linear in t_X:
        (R_A - I) t_X = R_X t_B - t_A for every pair. `R_A` (k, 3, 3), `t_A` (k, 3) and `t_B` (k, 3)
        are the pairs' flange rotations and the two motions' translations (mm); `R_X` is given. Write
        code that finds t_X (3,), mm, by least squares over all pairs.
        """,
    "hint": [
        "Each pair gives three linear equations in the three unknowns of t_X; stack them all.",
        (
            "Stack the (R_A - I) blocks into one tall matrix and the right-hand sides into one long vector, "
            "then solve the over-determined system in the least-squares sense (numpy has it)."
        ),
    ],
    "solution": """
        d = q3.inputs
        lhs = np.concatenate([np.asarray(R) - np.eye(3) for R in d.R_A])
        rhs = np.concatenate([np.asarray(d.R_X) @ b - a for a, b in zip(d.t_A, d.t_B)])
        q3.answer = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
        """,
    "level": "medium",
}


def _q3(learner: str) -> Question:
    """q3: Then the hand-eye translation."""
    rng = _rng(NUMBER, learner, "q3")
    T_bc, T_tb, poses = _robot_scene(rng, 5)
    T_cb = [_camera_board(T_bc, T, T_tb) for T in poses]
    pairs = [(i, j) for i in range(len(poses)) for j in range(i + 1, len(poses))]
    A = [poses[i] @ np.linalg.inv(poses[j]) for i, j in pairs]
    B = [T_cb[i] @ np.linalg.inv(T_cb[j]) for i, j in pairs]
    R_A = np.array([a[:3, :3] for a in A])
    t_A = np.round(np.array([a[:3, 3] for a in A]) + rng.normal(0, 0.05, (len(A), 3)), 3)
    t_B = np.round(np.array([b[:3, 3] for b in B]) + rng.normal(0, 0.05, (len(B), 3)), 3)
    R_X = T_bc[:3, :3]
    lhs = np.concatenate([R - np.eye(3) for R in R_A])
    rhs = np.concatenate([R_X @ b - a for a, b in zip(t_A, t_B)])
    key = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    one_pair = np.linalg.lstsq(lhs[:3], rhs[:3], rcond=None)[0]
    flipped = np.linalg.lstsq(lhs, -rhs, rcond=None)[0]
    return Question(
        "q3",
        inputs={"R_A": R_A, "t_A": t_A, "t_B": t_B, "R_X": R_X},
        expected=key,
        parse=_array((3,), "t_X"),
        compare=_cmp_array(0.5, " mm"),
        wrong=[
            (
                lambda a: _close(a, flipped, 0.5),
                "the sign of the right-hand side is flipped: it is R_X t_B - t_A",
            ),
            (
                lambda a: _close(a, one_pair, 0.5) and not _close(one_pair, key, 0.5),
                "one pair cannot fix t_X (a rotation leaves its axis free): stack every pair's equations",
            ),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Judge a photo by the robot",
    "task": """
        The chain was fitted without this photo: `T_base_camera`, `T_tool_board`, and the robot's
        `T_base_tool` for it (4x4, mm). A method measured the board's pose in the photo,
        `T_camera_board_measured`. How far (mm) is the board's centre, `centre_mm` (3,) in the
        board's frame, from where the robot says it is? Compare in the camera's frame.
        """,
    "hint": [
        "Two poses of the same board in the camera: one from the robot's chain, one measured. Put the same "
        "point of the board through both.",
        (
            "A pose carries a point from the board's frame into the camera's (homogeneous coordinates, a 1 "
            "appended). The distance between the two images of the centre is the error; the poses' own "
            "translations describe the board's corner, not its centre."
        ),
    ],
    "solution": """
        d = q4.inputs
        predicted = np.linalg.inv(d.T_base_camera) @ d.T_base_tool @ d.T_tool_board
        c = np.append(d.centre_mm, 1.0)
        q4.answer = np.linalg.norm((np.asarray(d.T_camera_board_measured) @ c - predicted @ c)[:3])
        """,
    "level": "easy",
}


def _q4(learner: str) -> Question:
    """q4: Judge a photo by the robot."""
    rng = _rng(NUMBER, learner, "q4")
    centre = np.array([90.4875, 126.6825, 0.0])
    while True:  # an error where the board's corner and its centre disagree clearly
        T_bc, T_tb, poses = _robot_scene(rng, 1)
        predicted = _camera_board(T_bc, poses[0], T_tb)
        error = frames.make_transform(Rotation.from_rotvec(rng.normal(0, 0.004, 3)).as_matrix(), rng.normal(0, 1.5, 3))
        measured = np.round(predicted @ error, 6)
        measured[:3, :3] = Rotation.from_matrix(measured[:3, :3]).as_matrix()
        c = np.append(centre, 1.0)
        key = float(np.linalg.norm((measured @ c - predicted @ c)[:3]))
        origin = float(np.linalg.norm(measured[:3, 3] - predicted[:3, 3]))
        if abs(origin - key) > 0.3 and key > 0.5:
            break
    return Question(
        "q4",
        inputs={
            "T_base_camera": T_bc,
            "T_tool_board": T_tb,
            "T_base_tool": poses[0],
            "T_camera_board_measured": measured,
            "centre_mm": centre,
        },
        expected=key,
        parse=_scalar("the error"),
        compare=_cmp_scalar(0.05, " mm"),
        wrong=[
            (
                lambda a: abs(a - origin) <= 0.05,
                "that compares the poses' translations: the board's corner (its origin), not its centre",
            ),
        ],
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 13 for one learner, in notebook order.

    Parameters
    ----------
    learner : str
        The learner's id; it seeds every question's numbers (``""``: the class's shared variant).

    Returns
    -------
    list of Question
        q1, q2, q3, q4, with their answer keys.
    """
    return [_q1(learner), _q2(learner), _q3(learner), _q4(learner)]
