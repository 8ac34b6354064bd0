"""Lesson 07: Inverting the extrinsics: where is the camera?.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("07", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ... import frames
from ...frames import look_at
from ...markermap import MarkerMap, MarkerPlacement
from .._engine import Question, QuestionText
from .._parsers import (
    _EXTRINSIC_MSG,
    _T_HINTS,
    _array,
    _close,
    _cmp_array,
    _cmp_transform,
    _T_is,
)
from .._scenery import (
    _WALL_YAW,
    _rng,
    _wall_translation,
)

NUMBER = "07"
TOPIC = "inversion"
TITLE = "Inverting the extrinsics: where is the camera?"
INTRO = """
    solvePnP answers with the world seen from the camera (T_camera_world). Turn it around: the
    camera's position -R^T t, its pose T_world_camera, the direction it looks, and a pose from a
    single marker chained through the map.
    """


def _room_pose(rng: np.random.Generator) -> np.ndarray:
    """A camera somewhere in the room looking at the north wall (x = 0)."""
    pos = np.round(rng.uniform([1200, -1200, 800], [4000, 1200, 1800]))
    target = np.round(rng.uniform([0, -500, 700], [0, 500, 1400]))
    return look_at(pos, target)


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "Where is the camera?",
    "task": """
        cv2.solvePnP gave `rvec` and `tvec` (mm) for a camera looking at the north wall. Write code
        that computes the camera's position in the world, (3,) in mm.
        """,
    "hint": "p_camera = R @ p_world + t. The camera's own centre has p_camera = 0; solve for p_world.",
    "solution": """
        R, _ = cv2.Rodrigues(np.asarray(q1.inputs.rvec, dtype=float))
        q1.answer = -R.T @ np.ravel(q1.inputs.tvec)
        """,
    "level": "easy",
}


def _q1(learner: str) -> Question:
    """q1: Where is the camera?."""
    rng = _rng("07", learner, "q1")
    Twc = _room_pose(rng)
    rvec, tvec = frames.rvec_tvec_from_transform(frames.invert_transform(Twc))
    rvec, tvec = np.round(rvec, 6), np.round(tvec, 2)
    R, _ = cv2.Rodrigues(rvec)
    pos = -R.T @ tvec
    return Question(
        "q1",
        inputs={"rvec": rvec, "tvec": tvec},
        expected=pos,
        parse=_array(
            (3,),
            "the position",
            {(4, 4): "give only the position (3,), the last column of T_world_camera", (3, 1): ""},
        ),
        compare=_cmp_array(0.5, " mm"),
        wrong=[
            (
                lambda a: _close(a, tvec, 0.5),
                (
                    "tvec is where the world's origin is in the CAMERA frame, not where the camera is: the camera's "
                    "position is -R^T @ tvec"
                ),
            ),
            (
                lambda a: _close(a, -tvec, 0.5),
                "-tvec is not enough: tvec is in camera coordinates; rotate it back into the world: -R^T @ tvec",
            ),
            (
                lambda a: _close(a, -R @ tvec, 0.5),
                "use the transpose: the inverse of a rotation is R^T, so the position is -R.T @ tvec",
            ),
            (lambda a: _close(a, R.T @ tvec, 0.5), "mind the sign: the position is -R^T @ tvec"),
            (lambda a: _close(a * 304.8, pos, 1), "that is in feet (304.8x too small): the answer is asked in mm"),
            (lambda a: _close(a * 1000, pos, 1), "that is in metres: the answer is asked in mm"),
            (
                lambda a: _close(a, rvec, 1e-3),
                "rvec is a rotation (axis times angle), not a position; R, _ = cv2.Rodrigues(rvec), then -R^T @ tvec",
            ),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "The camera's pose",
    "task": """
        From solvePnP's `rvec`, `tvec` (mm), write code that builds the camera's pose in the world,
        T_world_camera (4x4, mm): the transform that maps camera coordinates into world
        coordinates. Its last column holds the camera's position.
        """,
    "hint": [
        "solvePnP's pair is T_camera_world; the camera's pose is the same transform read the other way.",
        (
            "Inverting a rigid transform needs no general matrix inverse: the rotation's inverse is its "
            "transpose, and the translation must be carried through that rotation too."
        ),
    ],
    "solution": """
        R, _ = cv2.Rodrigues(np.asarray(q2.inputs.rvec, dtype=float))
        t = np.ravel(q2.inputs.tvec)
        T_world_camera = np.eye(4)
        T_world_camera[:3, :3] = R.T
        T_world_camera[:3, 3] = -R.T @ t
        q2.answer = T_world_camera
        """,
    "level": "easy",
}


def _q2(learner: str) -> Question:
    """q2: The camera's pose."""
    rng = _rng("07", learner, "q2")
    Twc2 = _room_pose(rng)
    rvec2, tvec2 = frames.rvec_tvec_from_transform(frames.invert_transform(Twc2))
    rvec2, tvec2 = np.round(rvec2, 6), np.round(tvec2, 2)
    Tcw2 = frames.transform_from_rvec_tvec(rvec2, tvec2)
    Twc2 = frames.invert_transform(Tcw2)
    R2 = Tcw2[:3, :3]
    bad_t = frames.make_transform(R2.T, -tvec2)
    return Question(
        "q2",
        inputs={"rvec": rvec2, "tvec": tvec2},
        expected=Twc2,
        parse=_array((4, 4), "T_world_camera", _T_HINTS),
        compare=_cmp_transform(0.05, 0.5),
        wrong=[
            (_T_is(Tcw2), _EXTRINSIC_MSG),
            (_T_is(bad_t), "the rotation is right (R^T) but the translation is not -tvec: it is -R^T @ tvec"),
            (
                _T_is(frames.make_transform(R2, -R2.T @ tvec2)),
                "the translation is right; the rotation of the inverse is R^T, not R",
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Which way does the camera look?",
    "task": """
        From solvePnP's `rvec`, `tvec`, write code that finds where the camera's optical axis
        (its +z) points in the world: its heading in degrees (the angle in the XY plane from +X
        towards +Y, atan2(dy, dx)) and its tilt in degrees below the horizon (positive when
        looking down). Answer (heading_deg, tilt_down_deg).
        """,
    "hint": [
        "First find which way the camera looks in the WORLD frame; then turn that direction into two angles.",
        (
            "The optical axis is the camera's own z axis: a column of the camera's rotation in the world (the "
            "inverse of solvePnP's). Heading is its direction on the floor, tilt how far it dips below the "
            "horizon."
        ),
    ],
    "solution": """
        R, _ = cv2.Rodrigues(np.asarray(q3.inputs.rvec, dtype=float))
        d = R.T[:, 2]                                    # camera +z in world coordinates
        heading = np.degrees(np.arctan2(d[1], d[0]))
        tilt_down = np.degrees(np.arcsin(-d[2]))
        q3.answer = (heading, tilt_down)
        """,
    "level": "medium",
}


def _q3(learner: str) -> Question:
    """q3: Which way does the camera look?."""
    rng = _rng("07", learner, "q3")
    pos3 = np.round(rng.uniform([1200, -1500, 1000], [4000, 1500, 2200]))
    target3 = np.round(rng.uniform([0, -900, 200], [0, 900, 1200]))
    Twc3 = look_at(pos3, target3)
    rvec3, tvec3 = frames.rvec_tvec_from_transform(frames.invert_transform(Twc3))
    rvec3, tvec3 = np.round(rvec3, 6), np.round(tvec3, 2)
    Twc3 = frames.invert_transform(frames.transform_from_rvec_tvec(rvec3, tvec3))
    axis = Twc3[:3, 2]
    heading = math.degrees(math.atan2(axis[1], axis[0]))
    tilt = math.degrees(math.asin(-axis[2]))
    expected3 = np.array([heading, tilt])
    row = Twc3[:3, :3][2, :]  # solvePnP's R[:, 2], the mistaken 'optical axis'
    wrong_heading = np.array(
        [math.degrees(math.atan2(row[1], row[0])), math.degrees(math.asin(float(np.clip(-row[2], -1, 1))))]
    )

    def heading_diff(a, b):
        d = (a[0] - b[0] + 180) % 360 - 180
        if abs(d) <= 0.2 and abs(a[1] - b[1]) <= 0.2:
            return None
        return f"your heading is {d:+.3g} deg and your tilt {a[1] - b[1]:+.3g} deg away from the key's"

    return Question(
        "q3",
        inputs={"rvec": rvec3, "tvec": tvec3},
        expected=expected3,
        parse=_array((2,), "(heading_deg, tilt_down_deg)"),
        compare=heading_diff,
        wrong=[
            (
                lambda a: heading_diff(np.degrees(a), expected3) is None,
                "those are radians: the answer is asked in degrees",
            ),
            (
                lambda a: heading_diff(a, wrong_heading) is None,
                (
                    "R[:, 2] of solvePnP's R is the world's Z axis seen from the camera; the camera's z axis "
                    "in the world is the third column of R^T (the third ROW of R)"
                ),
            ),
            (
                lambda a: heading_diff(a, np.array([heading + 180, -tilt])) is None,
                "that is the direction behind the camera: the optical axis is +z of the camera frame",
            ),
            (
                lambda a: abs(a[0] - heading) <= 0.2 and abs(a[1] + tilt) <= 0.2,
                (
                    "the heading is right; the tilt has the wrong sign: looking down means the axis has a negative "
                    "world z, tilt = asin(-z)"
                ),
            ),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Camera position from a single marker",
    "task": """
        solvePnP on the 4 corners of one marker, with the corners given in the MARKER's own frame
        (centre origin, x to the right, y up, z out of the face), gave `rvec`, `tvec` (mm): they
        describe T_camera_marker. The marker's pose in the world is `T_world_marker`. Write code that
        computes the camera's position in the WORLD, (3,) mm.
        """,
    "hint": [
        "One marker is enough: the detection gives the marker in the camera, the map gives the marker in the world.",
        (
            "Write the frames under each factor and chain them so the inner names cancel: you need the "
            "marker-to-camera transform the other way round."
        ),
    ],
    "solution": """
        T_camera_marker = frames.transform_from_rvec_tvec(q4.inputs.rvec, q4.inputs.tvec)
        T_world_camera = q4.inputs.T_world_marker @ frames.invert_transform(T_camera_marker)
        q4.answer = T_world_camera[:3, 3]
        """,
    "level": "hard",
}


def _q4(learner: str) -> Question:
    """q4: Camera position from a single marker."""
    rng = _rng("07", learner, "q4")
    wall = str(rng.choice(["north", "west", "east"]))
    yaw = _WALL_YAW[wall]
    t = _wall_translation(rng, wall, 10.0, (-1000, 1000), (700, 1600), per_ft=304.8)
    mmap = MarkerMap(
        {5: MarkerPlacement(5, tuple(t), (0.0, 0.0, float(yaw)))}, 150.0, dictionary="ARUCO_ORIGINAL", units="mm"
    )
    Twm = mmap.T_world_marker(5)
    n = Twm[:3, 2]
    cpos = (
        Twm[:3, 3]
        + n * rng.uniform(1000, 2500)
        + np.cross([0, 0, 1], n) * rng.uniform(-600, 600)
        + [0, 0, rng.uniform(-200, 400)]
    )
    Twc4 = look_at(np.round(cpos), Twm[:3, 3])
    Tcm = frames.invert_transform(Twc4) @ Twm
    rvec4, tvec4 = frames.rvec_tvec_from_transform(Tcm)
    rvec4, tvec4 = np.round(rvec4, 6), np.round(tvec4, 2)
    Tcm = frames.transform_from_rvec_tvec(rvec4, tvec4)
    pos4 = (Twm @ frames.invert_transform(Tcm))[:3, 3]
    pos_in_marker = frames.invert_transform(Tcm)[:3, 3]
    return Question(
        "q4",
        inputs={"rvec": rvec4, "tvec": tvec4, "T_world_marker": Twm},
        expected=pos4,
        parse=_array((3,), "the position"),
        compare=_cmp_array(0.5, " mm"),
        wrong=[
            (
                lambda a: _close(a, pos_in_marker, 0.5),
                (
                    "that is the camera's position in the MARKER's frame; chain it into the world: T_world_camera "
                    "= T_world_marker @ T_marker_camera"
                ),
            ),
            (
                lambda a: _close(a, (Twm @ Tcm)[:3, 3], 0.5),
                "T_camera_marker must be inverted before chaining: T_marker_camera = invert(T_camera_marker)",
            ),
            (
                lambda a: _close(a, Twm[:3, :3] @ tvec4 + Twm[:3, 3], 0.5) or _close(a, tvec4, 0.5),
                (
                    "tvec is the marker's position seen from the camera, not the camera's position; invert "
                    "T_camera_marker "
                    "first"
                ),
            ),
            (lambda a: _close(a * 304.8, pos4, 1), "that is in feet: the answer is asked in mm"),
        ],
        **_Q4,
    )


#: q5's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q5: QuestionText = {
    "title": "What is in the middle of the picture?",
    "task": """
        cv2.solvePnP gave `rvec` and `tvec` (mm) for a camera in the room looking at the north wall,
        the plane x = 0. Write code that finds the point of the wall seen at the centre of the
        picture (on the camera's optical axis): its world position, (3,) in mm.
        """,
    "hint": [
        "Two things are needed in the world frame: where the camera is, and which way its optical axis points.",
        "The axis leaves the camera's centre along the camera's own z; follow it until x reaches 0 "
        "(a line meeting a plane: solve for how far along the line).",
    ],
    "solution": """
        T_world_camera = frames.invert_transform(frames.transform_from_rvec_tvec(q5.inputs.rvec, q5.inputs.tvec))
        eye, axis = T_world_camera[:3, 3], T_world_camera[:3, 2]  # the camera's centre, its z axis in the world
        s = -eye[0] / axis[0]                                     # how far along the axis until x = 0
        q5.answer = eye + s * axis
        """,
    "level": "medium",
}


def _q5(learner: str) -> Question:
    """q5: What is in the middle of the picture?"""
    rng = _rng("07", learner, "q5")
    Twc = _room_pose(rng)
    rvec, tvec = frames.rvec_tvec_from_transform(frames.invert_transform(Twc))
    rvec, tvec = np.round(rvec, 6), np.round(tvec, 2)
    Twc = frames.invert_transform(frames.transform_from_rvec_tvec(rvec, tvec))

    def hit(eye, axis):
        return eye - eye[0] / axis[0] * axis

    key = hit(Twc[:3, 3], Twc[:3, 2])
    return Question(
        "q5",
        inputs={"rvec": rvec, "tvec": tvec},
        expected=key,
        parse=_array((3,), "the point", {(4,): "give x, y, z (3,), without the homogeneous 1"}),
        compare=_cmp_array(1.0, " mm"),
        wrong=[
            (
                lambda a: abs(a[0]) > 1.0,
                "the point must lie on the north wall, x = 0: follow the optical axis until its x is 0",
            ),
            (
                lambda a: np.linalg.norm(a) > 20000,
                (
                    "that point is far outside the room: the line you followed runs almost along the wall, so it "
                    "is not the optical axis. The camera's axis in the world is the third COLUMN of "
                    "T_world_camera's rotation, which is solvePnP's R[2, :], a ROW of R (not R[:, 2])"
                ),
            ),
            (
                lambda a: abs(tvec[0]) > 1e-6 and _close(a, hit(tvec, Twc[:3, 2]), 1.0),
                "tvec is not where the camera is: its centre is -R.T @ tvec (lesson 07's q1)",
            ),
        ],
        **_Q5,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 07 for one learner, in notebook order.

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
