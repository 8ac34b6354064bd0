"""Lesson 09: Localizing a robot.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("09", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

import math

import numpy as np

from ... import frames
from ...camera import Camera
from ...markermap import MarkerMap
from .._engine import Question, QuestionText
from .._parsers import (
    _array,
    _close,
    _cmp_scalar,
    _scalar,
)
from .._scenery import (
    _rng,
)

NUMBER = "09"
TOPIC = "robot"
TITLE = "Localizing a robot"
INTRO = """
    Put it together on a moving robot: localize every frame of a drive, carry the camera's pose to
    the robot's through the mounting transform, and measure the path it drove.
    """


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "Localize every frame of a drive",
    "task": """
        A camera on a robot drove toward the seed wall (`marker_map`, the course's world_map.json)
        and took the frames in `images` (a list of gray pictures); `camera` is calibrated. Write
        code that localizes every frame: detect, estimate the pose, and collect the camera's
        position in the world. Answer an (N, 3) array, mm, one row per frame in order.
        """,
    "hint": [
        "Each frame is a lesson-07 problem on its own: detect, then localize.",
        (
            "fidlearn.detection.detect_markers and fidlearn.pose.estimate_pose do each step; keep the camera "
            "position of each frame, in order."
        ),
    ],
    "look": (
        "from fidlearn import plotting\nfirst_middle_last = [0, len(q1.inputs.images) // 2, len(q1.inputs.images) "
        '- 1]\nplotting.show_images([q1.inputs.images[i] for i in first_middle_last], titles=[f"frame '
        '{i}" for i in first_middle_last], ncols=3);'
    ),
    "solution": """
        from fidlearn.detection import detect_markers
        from fidlearn.pose import estimate_pose
        m, cam = q1.inputs.marker_map, q1.inputs.camera
        positions = []
        for image in q1.inputs.images:
            pose = estimate_pose(detect_markers(image, m.dictionary), m, cam)
            positions.append(pose.position_mm)
        q1.answer = np.array(positions)
        """,
    "level": "medium",
}


def _q1_mistakes(tvecs, tol, truth_pos) -> list:
    """The mistakes q1 names: (detector, message) pairs, in the order they are tried."""
    return [
        (
            lambda a: _close(a, tvecs, 1.0),
            (
                "those are the tvecs, the world's origin seen from the camera (T_camera_world); the camera's "
                "position is Pose.position_mm (= -R^T t)"
            ),
        ),
        (lambda a: np.all(np.linalg.norm(a * 1000 - truth_pos, axis=1) <= tol), "those are metres: give mm"),
        (
            lambda a: np.all(np.linalg.norm(a * 304.8 - truth_pos, axis=1) <= tol),
            "those are feet (304.8x too small): give mm",
        ),
    ]


def _localize(images: list, marker_map: MarkerMap, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """fidlearn's own answer for q1: the camera positions (N, 3) mm and the tvecs (N, 3) mm, per frame."""
    from ... import pose as _pose
    from ...detection import detect_markers

    m, cam = marker_map, camera
    est, tvecs = [], []
    for image in images:
        p = _pose.estimate_pose(detect_markers(image, m.dictionary), m, cam)
        est.append(p.position_mm)
        tvecs.append(p.tvec)
    return np.array(est), np.array(tvecs)


def _q1(learner: str) -> Question:
    """q1: Localize every frame of a drive."""
    from ... import synthetic
    from ...data import data_path

    rng = _rng("09", learner, "q1")
    m = MarkerMap.load(data_path("world_map.json"))
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 65))), (960, 720))
    n = 6
    drive = synthetic.render_trajectory(
        m,
        cam,
        n_frames=n,
        seed=int(rng.integers(1 << 20)),
        start_lateral_mm=float(rng.uniform(-700, -300)),
        end_lateral_mm=float(rng.uniform(200, 600)),
    )
    truth_pos = drive.positions_mm
    est, tvecs = _localize(drive.images, m, cam)
    centre = np.mean([m.marker_corners(i).mean(axis=0) for i in m.ids], axis=0)
    distance = np.linalg.norm(truth_pos - centre, axis=1)
    # what corner noise allows: 6 % of the distance, or 3x what fidlearn's own pipeline misses by
    tol = np.maximum.reduce([np.full(n, 50.0), 0.06 * distance, 3.0 * np.linalg.norm(est - truth_pos, axis=1)])

    def cmp1(a, b):
        err = np.linalg.norm(a - b, axis=1)
        bad = np.flatnonzero(err > tol)
        if bad.size == 0:
            return None
        k = int(bad[0])
        return (
            f"frame {k} is {err[k]:.0f} mm from the truth (tolerance {tol[k]:.0f} mm at {distance[k] / 1000:.1f} "
            f"m); {bad.size} of {len(a)} "
            "frames are off. Far away the markers are small and a corner error of half a pixel moves the camera "
            "by centimetres: "
            "refine the corners (fidlearn.detection.detect_markers does by default; OpenCV's detector does not) "
            "and use every marker"
        )

    return Question(
        "q1",
        inputs={"images": [im.copy() for im in drive.images], "marker_map": m, "camera": cam},
        expected=truth_pos,
        parse=_array(
            (n, 3),
            "the positions",
            {
                (3, n): "one ROW per frame: transpose it",
                (n, 4, 4): "give the positions (the last column of each T_world_camera), not the 4x4 poses",
            },
        ),
        compare=cmp1,
        wrong=_q1_mistakes(tvecs, tol, truth_pos),
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "From the camera's pose to the robot's",
    "task": """
        The camera is bolted to the robot, turned a little to one side: `T_robot_camera` (4x4, mm)
        is its pose in the robot's frame (x forward, y left, z up, origin on the floor between the
        wheels). Localization gave `T_world_camera`. Write code that computes where the ROBOT is:
        (x_mm, y_mm, heading_deg), its origin's world x and y and the direction of its x axis in
        the world, atan2(dy, dx) in degrees.
        """,
    "hint": [
        "Chain the frames by their names: you have T_world_camera and T_robot_camera and you want a transform "
        "with 'world' on the left and 'robot' on the right. What must stand between them?",
        "Names cancel when the inner ones match, T_a_c = T_a_b @ T_b_c, and turning a transform round swaps its "
        "names (its inverse). The heading is where the robot's own x axis points once it is in the world frame.",
    ],
    "solution": """
        T_world_robot = q2.inputs.T_world_camera @ frames.invert_transform(q2.inputs.T_robot_camera)
        heading = np.degrees(np.arctan2(T_world_robot[1, 0], T_world_robot[0, 0]))
        q2.answer = (T_world_robot[0, 3], T_world_robot[1, 3], heading)
        """,
    "level": "medium",
}


def _q2_mistakes(cmp2, pose_xyh, Twc, T_robot_camera, key2, cam_heading) -> list:
    """The mistakes q2 names: (detector, message) pairs, in the order they are tried."""
    return [
        (
            lambda a: np.linalg.norm(a[:2] - Twc[:2, 3]) <= 1.0,
            (
                "that is where the CAMERA is; the robot's origin is elsewhere: T_world_robot = T_world_camera "
                "@ T_camera_robot, with T_camera_robot = invert(T_robot_camera)"
            ),
        ),
        (
            lambda a: cmp2(a, pose_xyh(Twc @ T_robot_camera)) is None,
            "the names do not chain: T_world_camera @ T_robot_camera; invert T_robot_camera first (T_camera_robot)",
        ),
        (
            lambda a: np.linalg.norm(a[:2] - key2[:2]) <= 1.0 and abs((a[2] - cam_heading + 180) % 360 - 180) <= 0.1,
            (
                "the position is right, but that heading is the CAMERA's optical axis; the camera is turned "
                "on the robot: take the robot's x axis from T_world_robot"
            ),
        ),
        (
            lambda a: (
                np.linalg.norm(a[:2] - key2[:2]) <= 1.0 and abs((math.degrees(a[2]) - key2[2] + 180) % 360 - 180) <= 0.1
            ),
            "the heading is in radians: give degrees",
        ),
        (
            lambda a: np.linalg.norm(a[:2] - key2[:2]) <= 1.0,
            (
                "the position is right; the heading is the direction of the robot's x axis, the first column "
                "of T_world_robot's rotation: atan2(R[1, 0], R[0, 0]) in degrees"
            ),
        ),
    ]


def _q2(learner: str) -> Question:
    """q2: From the camera's pose to the robot's."""
    rng = _rng("09", learner, "q2")
    cam_yaw = float(np.round(rng.uniform(10, 35)) * rng.choice([-1, 1]))
    R_robot_camera = frames.rot_z(math.radians(cam_yaw)) @ np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    T_robot_camera = frames.make_transform(
        R_robot_camera,
        [
            float(np.round(rng.uniform(80, 250))),
            float(np.round(rng.uniform(-60, 60))),
            float(np.round(rng.uniform(250, 450))),
        ],
    )
    robot_xy = np.round(rng.uniform([800, -800], [2500, 800]))
    robot_yaw = float(np.round(rng.uniform(120, 240)))
    T_world_robot = frames.make_transform(frames.rot_z(math.radians(robot_yaw)), [robot_xy[0], robot_xy[1], 0.0])
    Twc = T_world_robot @ T_robot_camera
    Twc = np.round(Twc, 9)
    T_wr = Twc @ frames.invert_transform(T_robot_camera)
    key2 = np.array([T_wr[0, 3], T_wr[1, 3], math.degrees(math.atan2(T_wr[1, 0], T_wr[0, 0]))])

    def cmp2(a, b):
        d = (a[2] - b[2] + 180) % 360 - 180
        if np.linalg.norm(a[:2] - b[:2]) <= 1.0 and abs(d) <= 0.1:
            return None
        return f"your (x, y) is {np.linalg.norm(a[:2] - b[:2]):.0f} mm and your heading {d:+.3g} deg from the key's"

    def pose_xyh(T):
        return np.array([T[0, 3], T[1, 3], math.degrees(math.atan2(T[1, 0], T[0, 0]))])

    cam_axis = Twc[:3, 2]
    cam_heading = math.degrees(math.atan2(cam_axis[1], cam_axis[0]))
    return Question(
        "q2",
        inputs={"T_world_camera": Twc, "T_robot_camera": T_robot_camera},
        expected=key2,
        parse=_array((3,), "(x_mm, y_mm, heading_deg)"),
        compare=cmp2,
        wrong=_q2_mistakes(cmp2, pose_xyh, Twc, T_robot_camera, key2, cam_heading),
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "How far did the robot drive?",
    "task": """
        `positions_mm` (N, 3) are the camera positions of a drive, one per frame; in the frames
        where no marker was seen the row is NaN. Write code that computes the distance driven on
        the floor: the length of the path through the valid positions in order, using x and y
        only, in mm.
        """,
    "hint": [
        "A path's length is the sum of its steps; a lost frame is not a step.",
        (
            "Keep only the valid rows, take the differences of consecutive ones on the floor (x and y), and add "
            "up their lengths."
        ),
    ],
    "solution": """
        p = np.asarray(q3.inputs.positions_mm, dtype=float)
        valid = p[~np.isnan(p).any(axis=1)]
        steps = np.diff(valid[:, :2], axis=0)
        q3.answer = np.sum(np.linalg.norm(steps, axis=1))
        """,
    "level": "easy",
}


def _q3(learner: str) -> Question:
    """q3: How far did the robot drive?."""
    rng = _rng("09", learner, "q3")
    k = 12
    s = np.linspace(0, 1, k)
    start = np.round(rng.uniform([2000, -900], [2600, -400]))
    end = np.round(rng.uniform([700, 200], [1100, 800]))
    bend = float(rng.uniform(150, 400))
    xy = start + np.outer(s, end - start) + np.outer(np.sin(np.pi * s) * bend, [0.6, 0.8])
    xy = xy + rng.normal(0, 4, xy.shape)
    z = 300 + rng.normal(0, 15, k)  # the camera's height as the poses give it: noise of the estimate
    pts = np.round(np.column_stack([xy, z]), 1)
    lost = sorted(int(i) for i in rng.choice(np.arange(2, k - 2), size=2, replace=False))
    pts[lost] = np.nan
    ok = ~np.isnan(pts[:, 0])
    good = pts[ok]
    length = float(np.sum(np.linalg.norm(np.diff(good[:, :2], axis=0), axis=1)))
    length3 = float(np.sum(np.linalg.norm(np.diff(good, axis=0), axis=1)))
    straight = float(np.linalg.norm(good[-1, :2] - good[0, :2]))
    return Question(
        "q3",
        inputs={"positions_mm": pts},
        expected=length,
        parse=_scalar("the distance"),
        compare=_cmp_scalar(0.05, " mm"),
        wrong=[
            (
                lambda a: abs(a - straight) < 0.5,
                "that is the straight line from start to finish; add up the steps between consecutive valid frames",
            ),
            (
                lambda a: abs(a - length3) < 0.05,
                (
                    f"that is the 3D length of the camera's path, {length3 - length:.1f} mm more than the floor "
                    "path: the robot drives on the flat floor and the camera's z only wobbles with the pose's "
                    "noise, so each step up and down adds length that was never driven. Use x and y only"
                ),
            ),
            (lambda a: abs(a * 1000 - length) < 0.5, "that is in metres: give mm"),
            (
                lambda a: a < length * 0.9,
                (
                    "too short: did you drop more than the NaN rows, or skip the steps around a lost frame? Join "
                    "each valid position to the next valid one"
                ),
            ),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "How fast did the robot go?",
    "task": """
        `positions_mm` (N, 3) are the camera positions of a drive and `timestamps_s` (N,) the
        times the frames were taken (the camera does not keep a perfect rhythm); where no marker was
        seen the row is NaN, the first and last frames included. Write code that computes the
        robot's average speed on the floor over the part of the drive that was localized, in mm/s:
        the floor distance (x, y) through the valid positions divided by the time it took.
        """,
    "hint": [
        "An average speed is one distance over one duration; both must cover the same stretch of the drive.",
        "The stretch runs from the first localized frame to the last one: its time is the difference of THEIR "
        "timestamps, whatever happened before or after.",
    ],
    "solution": """
        p = np.asarray(q4.inputs.positions_mm, dtype=float)
        t = np.asarray(q4.inputs.timestamps_s, dtype=float)
        ok = ~np.isnan(p).any(axis=1)
        distance = np.sum(np.linalg.norm(np.diff(p[ok, :2], axis=0), axis=1))
        q4.answer = distance / (t[ok][-1] - t[ok][0])
        """,
    "level": "medium",
}


def _q4(learner: str) -> Question:
    """q4: How fast did the robot go?"""
    rng = _rng("09", learner, "q4")
    k = 15
    speed = float(rng.uniform(150, 400))  # mm/s
    while True:  # an uneven rhythm that a nominal 0.1 s per frame cannot pass for
        dt = rng.uniform(0.09, 0.11, k - 1)
        t = np.round(np.concatenate([[0.0], np.cumsum(dt)]) + float(np.round(rng.uniform(10, 50), 2)), 3)
        heading = float(rng.uniform(-np.pi, np.pi))
        start = np.round(rng.uniform([1500, -600], [3000, 600]))
        travelled = speed * (t - t[0])
        xy = start + np.outer(travelled, [math.cos(heading), math.sin(heading)])
        xy = xy + rng.normal(0, 3, xy.shape)
        pts = np.round(np.column_stack([xy, 300 + rng.normal(0, 15, k)]), 1)
        lost = [0, int(rng.integers(4, k - 4)), k - 1] + ([1] if rng.random() < 0.5 else [])
        pts[lost] = np.nan
        ok = ~np.isnan(pts[:, 0])
        d2 = float(np.sum(np.linalg.norm(np.diff(pts[ok, :2], axis=0), axis=1)))
        d3 = float(np.sum(np.linalg.norm(np.diff(pts[ok], axis=0), axis=1)))
        span = float(t[ok][-1] - t[ok][0])
        key = d2 / span
        if abs(d2 / (0.1 * np.ptp(np.flatnonzero(ok))) - key) > 1.0:
            break
    return Question(
        "q4",
        inputs={"positions_mm": pts, "timestamps_s": t},
        expected=key,
        parse=_scalar("the speed"),
        compare=_cmp_scalar(0.01, " mm/s"),
        wrong=[
            (
                lambda a: abs(a - d2 / (t[-1] - t[0])) < 0.01,
                (
                    "that divides by the whole recording, lost frames at the ends included; the distance only "
                    "covers the first to the last LOCALIZED frame, so the time must too"
                ),
            ),
            (
                lambda a: abs(a - d2 / (0.1 * np.ptp(np.flatnonzero(ok)))) < 0.01,
                "the frames are not exactly 0.1 s apart: use the timestamps, not a nominal frame rate",
            ),
            (
                lambda a: abs(a - d3 / span) < 0.01,
                "that is the 3D path of the camera: its z wobbles with the pose's noise; the floor speed uses x, y",
            ),
            (lambda a: abs(a * 1000 - key) < 0.01 * 1000, "that is in m/s: give mm/s"),
        ],
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 09 for one learner, in notebook order.

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
