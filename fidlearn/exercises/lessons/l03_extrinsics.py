"""Lesson 03: Extrinsics and transforms.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("03", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ... import frames
from ...frames import look_at
from .._engine import Question, QuestionText
from .._parsers import (
    _EXTRINSIC_MSG,
    _T_HINTS,
    _array,
    _close,
    _cmp_array,
    _cmp_transform,
    _parts,
    _scalar,
    _T_is,
)
from .._scenery import (
    _rng,
    _wall_translation,
)

NUMBER = "03"
TOPIC = "extrinsics"
TITLE = "Extrinsics and transforms"
INTRO = """
    Poses as 4x4 homogeneous transforms: build one from roll, pitch and yaw, move points between
    frames, chain transforms so that their names match, and read solvePnP's rvec, tvec.
    """


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "A robot's pose from roll, pitch and yaw",
    "task": """
        A robot stands at `position_mm` (x, y, z in the world, mm) with orientation `rpy_deg` =
        (roll, pitch, yaw) in degrees, rotations about the FIXED world X, Y and Z axes applied in
        that order, so R = Rz(yaw) @ Ry(pitch) @ Rx(roll). Write code that builds its pose
        T_world_robot, a 4x4 homogeneous transform (you may use frames.rot_x / rot_y / rot_z,
        which take radians, or write the matrices yourself).
        """,
    "hint": [
        "The order of the three turns matters, and so does the unit the rotation functions expect.",
        (
            "R = Rz(yaw) Ry(pitch) Rx(roll): yaw is applied last (outermost). frames.rot_x/y/z take radians; the "
            "pose puts R and the position into one 4x4."
        ),
    ],
    "solution": """
        roll, pitch, yaw = np.radians(q1.inputs.rpy_deg)
        R = frames.rot_z(yaw) @ frames.rot_y(pitch) @ frames.rot_x(roll)
        T_world_robot = np.eye(4)
        T_world_robot[:3, :3] = R
        T_world_robot[:3, 3] = q1.inputs.position_mm
        q1.answer = T_world_robot
        """,
    "level": "easy",
}


def _q1(learner: str) -> Question:
    """q1: A robot's pose from roll, pitch and yaw."""
    rng = _rng("03", learner, "q1")
    rpy = np.round(rng.uniform([-20, -20, -180], [20, 20, 180]))
    pos = np.round(rng.uniform([500, -1500, 0], [3000, 1500, 400]))
    R = frames.rotation_from_rpy_deg(*rpy)
    T = frames.make_transform(R, pos)
    R_rad_as_deg = frames.rot_z(rpy[2]) @ frames.rot_y(rpy[1]) @ frames.rot_x(rpy[0])
    R_xyz = frames.rot_x(math.radians(rpy[0])) @ frames.rot_y(math.radians(rpy[1])) @ frames.rot_z(math.radians(rpy[2]))
    return Question(
        "q1",
        inputs={"rpy_deg": rpy, "position_mm": pos},
        expected=T,
        parse=_array((4, 4), "T_world_robot", _T_HINTS),
        compare=_cmp_transform(0.05, 0.5),
        wrong=[
            (
                _T_is(frames.invert_transform(T)),
                (
                    "you built the inverse, T_robot_world: the pose of the robot in the world has R in the top-left "
                    "block and the robot's position as the last column"
                ),
            ),
            (
                lambda a: frames.rotation_angle_deg(a[:3, :3], R_rad_as_deg) < 0.05,
                "the angles are in degrees but rot_x / rot_y / rot_z take radians: convert with np.radians",
            ),
            (
                lambda a: frames.rotation_angle_deg(a[:3, :3], R_xyz) < 0.05,
                (
                    "the order of the rotations is reversed: about fixed axes roll first, then pitch, then yaw, "
                    "so R = Rz(yaw) @ Ry(pitch) @ Rx(roll)"
                ),
            ),
            (
                lambda a: frames.rotation_angle_deg(a[:3, :3], R.T) < 0.05,
                "the rotation is transposed (inverted): R = Rz(yaw) @ Ry(pitch) @ Rx(roll) goes in as it is",
            ),
            (
                lambda a: frames.rotation_angle_deg(a[:3, :3], R) < 0.05 and not _close(a[:3, 3], pos, 0.5),
                "the rotation is right; the last column must be the robot's position in mm",
            ),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "World points in the camera frame",
    "task": """
        A camera's pose is `T_world_camera` (4x4, mm). `points_world_mm` are 4 points on the wall
        (N, 3) in world coordinates. Write code that expresses them in the camera frame (OpenCV's:
        x right, y down, z forward): an (N, 3) array in mm. Their z (depth) must come out positive:
        the camera sees them.
        """,
    "hint": [
        "You have the camera's pose in the world; the points must go the other way, from world to camera.",
        (
            "Turning a transform round (its inverse) swaps the names: T_camera_world from T_world_camera. Apply "
            "it to each point with a homogeneous 1 appended (frames.transform_points does rows of points)."
        ),
    ],
    "solution": """
        T_camera_world = frames.invert_transform(q2.inputs.T_world_camera)
        q2.answer = frames.transform_points(T_camera_world, q2.inputs.points_world_mm)
        """,
    "level": "medium",
}


def _q2(learner: str) -> Question:
    """q2: World points in the camera frame."""
    rng = _rng("03", learner, "q2")
    cpos = np.round(rng.uniform([1500, -800, 900], [3500, 800, 1600]))
    Twc = look_at(cpos, np.round(rng.uniform([0, -400, 700], [0, 400, 1300])))
    pts = np.round(np.column_stack([np.zeros(4), rng.uniform(-600, 600, 4), rng.uniform(300, 1800, 4)]))
    Tcw = frames.invert_transform(Twc)
    expected = frames.transform_points(Tcw, pts)
    return Question(
        "q2",
        inputs={"T_world_camera": Twc, "points_world_mm": pts},
        expected=expected,
        parse=_array(
            (4, 3),
            "the points",
            {(4, 4): "drop the homogeneous 1 (keep x, y, z)", (3, 4): "one ROW per point: transpose it"},
        ),
        compare=_cmp_array(0.05, " mm"),
        wrong=[
            (
                lambda a: _close(a, frames.transform_points(Twc, pts), 0.05),
                (
                    "T_world_camera maps camera coordinates INTO the world; you need the other direction, "
                    "T_camera_world "
                    "= frames.invert_transform(T_world_camera)"
                ),
            ),
            (
                lambda a: _close(a, pts @ Twc[:3, :3], 0.05),
                "you rotated but forgot the translation: p_camera = R^T (p_world - t)",
            ),
            (
                lambda a: _close(a, pts @ Twc[:3, :3] - Twc[:3, 3], 0.05),
                (
                    "subtract the camera position BEFORE rotating: p_camera = R^T (p_world - t), where t is "
                    "T_world_camera's "
                    "last column"
                ),
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Chain the map and a detection",
    "task": """
        The map says where a marker is: `T_world_marker`. A single-marker detection says where the
        marker is seen from the camera: `T_camera_marker`. Write code that computes the camera's
        pose in the world, T_world_camera (4x4, mm). Let the names chain:
        T_world_camera = T_world_marker @ T_marker_camera.
        """,
    "hint": (
        "Write the frames of each factor under it: T_world_marker @ T_marker_camera -> T_world_camera. "
        "The middle names must match."
    ),
    "solution": """
        T_marker_camera = frames.invert_transform(q3.inputs.T_camera_marker)
        q3.answer = q3.inputs.T_world_marker @ T_marker_camera
        """,
    "level": "medium",
}


def _q3(learner: str) -> Question:
    """q3: Chain the map and a detection."""
    rng = _rng("03", learner, "q3")
    yaw = float(rng.choice([0, 90, 180, -90]))
    wall = {0: "north", 90: "west", 180: "south", -90: "east"}[int(yaw)]  # the wall it faces away from
    Twm = frames.make_transform(
        frames.rotation_from_rpy_deg(0, 0, yaw) @ np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], dtype=float),
        _wall_translation(rng, wall, 1.0, (-1000, 1000), (800, 1500), per_ft=304.8),
    )
    normal = Twm[:3, 2]
    cpos = (
        Twm[:3, 3]
        + normal * rng.uniform(1200, 2500)
        + np.cross([0, 0, 1], normal) * rng.uniform(-500, 500)
        + [0, 0, rng.uniform(-300, 300)]
    )
    Twc3 = look_at(np.round(cpos), Twm[:3, 3])
    Tcm = frames.invert_transform(Twc3) @ Twm
    return Question(
        "q3",
        inputs={"T_world_marker": Twm, "T_camera_marker": Tcm},
        expected=Twc3,
        parse=_array((4, 4), "T_world_camera", _T_HINTS),
        compare=_cmp_transform(0.05, 0.5),
        wrong=[
            (_T_is(frames.invert_transform(Twc3)), _EXTRINSIC_MSG),
            (
                _T_is(Twm @ Tcm),
                (
                    "the names do not chain: T_world_marker @ T_camera_marker has 'marker' next to 'camera'; "
                    "you need T_marker_camera = frames.invert_transform(T_camera_marker)"
                ),
            ),
            (
                _T_is(frames.invert_transform(Tcm) @ Twm),
                (
                    "the order is reversed: matrix products do not commute; T_world_camera = T_world_marker @ "
                    "T_marker_camera"
                ),
            ),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "From rvec, tvec to a 4x4 matrix",
    "task": """
        cv2.solvePnP returned `rvec` and `tvec` (mm). Write code that turns them into the 4x4
        homogeneous transform they describe. Which transform is it, T_camera_world or
        T_world_camera? Give exactly that one.
        """,
    "hint": (
        "R, _ = cv2.Rodrigues(rvec) gives the rotation; solvePnP's pair maps world points into the "
        "camera frame: p_camera = R @ p_world + tvec."
    ),
    "solution": """
        R, _ = cv2.Rodrigues(np.asarray(q4.inputs.rvec, dtype=float))
        T_camera_world = np.eye(4)
        T_camera_world[:3, :3] = R
        T_camera_world[:3, 3] = np.ravel(q4.inputs.tvec)
        q4.answer = T_camera_world
        """,
    "level": "medium",
}


def _q4(learner: str) -> Question:
    """q4: From rvec, tvec to a 4x4 matrix."""
    rng = _rng("03", learner, "q4")
    Twc4 = look_at(
        np.round(rng.uniform([1500, -900, 900], [3500, 900, 1700])),
        np.round(rng.uniform([0, -300, 800], [0, 300, 1200])),
    )
    Tcw4 = frames.invert_transform(Twc4)
    rvec, tvec = frames.rvec_tvec_from_transform(Tcw4)
    rvec, tvec = np.round(rvec, 6), np.round(tvec, 3)
    Tcw4 = frames.transform_from_rvec_tvec(rvec, tvec)
    R_euler = frames.rot_z(rvec[2]) @ frames.rot_y(rvec[1]) @ frames.rot_x(rvec[0])
    return Question(
        "q4",
        inputs={"rvec": rvec, "tvec": tvec},
        expected=Tcw4,
        parse=_array((4, 4), "the transform", _T_HINTS),
        compare=_cmp_transform(0.05, 0.5),
        wrong=[
            (
                _T_is(Twc4),
                (
                    "solvePnP's rvec, tvec already ARE T_camera_world (they map world points into the camera "
                    "frame); you inverted them: give the transform itself"
                ),
            ),
            (
                lambda a: frames.rotation_angle_deg(a[:3, :3], R_euler) < 0.05,
                (
                    "rvec is not roll, pitch, yaw: it is a Rodrigues (axis-angle) vector, the axis times the "
                    "angle; cv2.Rodrigues(rvec) gives the 3x3 rotation matrix"
                ),
            ),
            (
                lambda a: frames.rotation_angle_deg(a[:3, :3], Tcw4[:3, :3].T) < 0.05,
                "the rotation is transposed: use the matrix cv2.Rodrigues returns as it is",
            ),
        ],
        **_Q4,
    )


#: q5's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q5: QuestionText = {
    "title": "What an rvec says",
    "task": """
        solvePnP answers rotations as a rotation vector `rvec` (3,). Without calling cv2.Rodrigues,
        write code that reads off the rotation it describes: the unit axis it turns about (3,) and
        the angle it turns by, in degrees (right-hand rule: thumb along the axis, fingers turning).
        Answer {"axis": (3,), "angle_deg": angle}.
        """,
    "hint": [
        "A rotation vector packs two things into three numbers: a direction and a length. Which is which?",
        "Its direction is the axis and its length the angle in radians; the zero vector is no rotation at all.",
    ],
    "solution": """
        rvec = np.asarray(q5.inputs.rvec, dtype=float)
        angle = np.linalg.norm(rvec)                       # radians
        q5.answer = {"axis": rvec / angle, "angle_deg": np.degrees(angle)}
        """,
    "level": "easy",
}


def _q5(learner: str) -> Question:
    """q5: What an rvec says."""
    rng = _rng("03", learner, "q5")
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = float(rng.uniform(20, 170))
    rvec = np.round(axis * math.radians(angle), 6)
    angle = math.degrees(float(np.linalg.norm(rvec)))
    axis = rvec / np.linalg.norm(rvec)

    def R_of(a):
        return cv2.Rodrigues(np.asarray(a["axis"]) / np.linalg.norm(a["axis"]) * math.radians(a["angle_deg"]))[0]

    def cmp5(a, _key):
        if abs(np.linalg.norm(a["axis"]) - 1) > 1e-3:
            return f"the axis has length {np.linalg.norm(a['axis']):.4g}: give a UNIT vector"
        err = frames.rotation_angle_deg(R_of(a), cv2.Rodrigues(rvec)[0])
        return None if err <= 0.05 else f"your axis and angle turn {err:.3g} deg away from the rvec's rotation"

    return Question(
        "q5",
        inputs={"rvec": rvec},
        expected={"axis": axis, "angle_deg": angle},
        parse=_parts(axis=_array((3,), "axis"), angle_deg=_scalar("angle_deg")),
        compare=cmp5,
        wrong=[
            (
                lambda a: abs(a["angle_deg"] - math.radians(angle)) < 1e-3,
                "that angle is in radians: the length of the rvec is radians, the answer is asked in degrees",
            ),
            (
                lambda a: _close(a["axis"], rvec, 1e-4),
                "the axis is the rvec's DIRECTION: divide it by its length (the length is the angle)",
            ),
            (
                lambda a: _close(a["axis"], -axis, 1e-3) and abs(a["angle_deg"] - angle) < 0.05,
                "the axis points the wrong way: turning by +angle about -axis is the opposite rotation",
            ),
        ],
        **_Q5,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 03 for one learner, in notebook order.

    Parameters
    ----------
    learner : str
        The learner's id; it seeds every question's numbers (``""``: the class's shared variant).

    Returns
    -------
    list of Question
        q1, q2, q3, q4, q5, with their answer keys.
    """
    return [_q1(learner), _q2(learner), _q3(learner), _q4(learner), _q5(learner)]
