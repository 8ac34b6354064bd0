"""Lesson 08: Accuracy and pitfalls.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("08", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

import cv2
import numpy as np

from ... import _cv, frames
from ...camera import Camera
from ...frames import look_at
from ...markermap import MarkerMap, MarkerPlacement
from .._design import _WallTask
from .._engine import Question, QuestionText, _AnswerError
from .._parsers import (
    _array,
    _close,
    _cmp_array,
    _marker_map,
    _parts,
    _scalar,
)
from .._scenery import (
    _noisy_detections,
    _pose_seeing_all,
    _rng,
    _wall_map,
)

NUMBER = "08"
TOPIC = "accuracy"
TITLE = "Accuracy and pitfalls"
INTRO = """
    What limits a pose: depth error that grows with the square of the distance, a marker that
    moved after the map was measured, and the two-fold ambiguity of a small marker seen from afar.
    """


_AMBIGUITY_CHOICES = [
    (
        "flip",
        "A small flat marker seen nearly face-on from far away: two mirror-image tilts project its "
        "corners to almost the same pixels, and the corner noise cannot tell them apart.",
    ),
    ("id", "The marker's id was decoded wrongly, so the map gave the corners of another marker."),
    ("distortion", "The lens distortion was not calibrated, so the corners are in the wrong places."),
    ("too_few", "solvePnP needs at least 6 points; the 4 corners of one marker are too few for a pose."),
]


_AMBIGUITY_WRONG = {
    "id": "a wrong id would give one bad pose with a large reprojection error, not two poses that both fit the corners",
    "distortion": (
        "the corners here are projected with the camera's own model; both candidates fit them to a fraction of a pixel"
    ),
    "too_few": (
        "4 coplanar points are enough: IPPE (SOLVEPNP_IPPE_SQUARE) solves a square marker from its "
        "4 corners; the trouble is that it finds TWO solutions"
    ),
}


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "Error grows with distance",
    "task": """
        A marker of side `marker_size_mm` faces the camera squarely at each distance in
        `distances_mm`; the camera's focal length is `camera.fx` px. Distance from apparent size is
        Z = fx * s / w (w the side in pixels). If w is measured `side_error_px` pixels too large,
        how far off is Z? Write code that gives the size of the depth error (mm, positive) at
        each distance, an array like `distances_mm`, to first order (dZ = |dZ/dw| * side_error_px).
        How does it grow when the distance doubles?
        """,
    "hint": [
        (
            "The marker's width in pixels shrinks as it moves away: how fast does the depth change when that "
            "width is off by a little?"
        ),
        (
            "Differentiate Z = fx s / w with respect to w, then write the result with Z in place of w; the size "
            "of the error is that slope times side_error_px."
        ),
    ],
    "solution": """
        Z = np.asarray(q1.inputs.distances_mm, dtype=float)
        q1.answer = Z ** 2 / (q1.inputs.camera.fx * q1.inputs.marker_size_mm) * q1.inputs.side_error_px
        """,
    "level": "easy",
}


def _q1(learner: str) -> Question:
    """q1: Error grows with distance."""
    rng = _rng("08", learner, "q1")
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720))
    size = float(np.round(rng.uniform(60, 200), -1) + 5 * rng.integers(0, 2))
    dists = np.array([500.0, 1000.0, 2000.0, 4000.0, 8000.0])
    err_px = float(rng.choice([0.2, 0.25, 0.3, 0.4, 0.5, 0.75, 1.0]))
    dZ = dists**2 * err_px / (cam.fx * size)
    return Question(
        "q1",
        inputs={"camera": cam, "marker_size_mm": size, "distances_mm": dists, "side_error_px": err_px},
        expected=dZ,
        parse=_array((len(dists),), "the depth errors"),
        compare=_cmp_array(0.0, " mm", rtol=0.01),
        wrong=[
            (
                lambda a: _close(a, dists * err_px / cam.fx, 0, 0.01),
                (
                    "that is the SIDEWAYS error of one pixel (Z / fx per px); the depth error from the apparent "
                    "size grows with Z squared: |dZ/dw| = fx * s / w^2 = Z^2 / (fx * s)"
                ),
            ),
            (
                lambda a: _close(a, dists * err_px / size, 0, 0.01),
                (
                    "your error grows linearly with distance; differentiate Z = fx * s / w with respect to w: "
                    "|dZ/dw| = Z^2 / (fx * s)"
                ),
            ),
            (lambda a: _close(a * 1000, dZ, 0, 0.01), "that is in metres: the answer is asked in mm"),
            (lambda a: _close(-a, dZ, 0, 0.01), "give the size of the error (positive)"),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "Where did the misplaced marker go?",
    "task": """
        Someone moved one marker along its wall after the map was measured: `marker_map` still has
        the old position. fidlearn.pose.estimate_pose finds that marker for you (the others do not
        agree with it: it is in Pose.rejected_ids, and the pose is solved without it). What it does
        not tell you is where the marker went. Write code that detects the markers in `image` (the
        map's dictionary), finds the misplaced one and measures how it moved: its centre now minus
        its centre in the map, a (3,) vector in world mm. Answer {"misplaced_id": id,
        "moved_mm": (3,)}.
        """,
    "look": 'from fidlearn import plotting\nplotting.show_image(None, q2.inputs.image, title="q2.inputs.image");',
    "hint": [
        "The pose solved without the misplaced marker is trustworthy, and the marker still hangs on the same "
        "wall. What does a pixel tell you about the point it saw, once you know where the camera is?",
        "Each corner's pixel is a ray from the camera's centre (undistort it, turn it into the world frame with "
        "the camera's rotation). Where does that ray meet the plane of the wall the marker hangs on?",
    ],
    "solution": """
        from fidlearn.detection import detect_markers
        from fidlearn.pose import estimate_pose
        m, cam = q2.inputs.marker_map, q2.inputs.camera
        dets = [d for d in detect_markers(q2.inputs.image, m.dictionary) if d.id in m]
        pose = estimate_pose(dets, m, cam)                # solved without the marker that disagrees
        moved_id = pose.rejected_ids[0]
        px = next(d for d in dets if d.id == moved_id).corners_px
        xy = cv2.undistortPoints(px.reshape(-1, 1, 2), cam.K, cam.dist).reshape(-1, 2)  # z = 1 in the camera
        R, eye = pose.T_world_camera[:3, :3], pose.T_world_camera[:3, 3]
        rays = np.column_stack([xy, np.ones(len(xy))]) @ R.T   # world directions of the 4 corner rays
        old = m.marker_corners(moved_id)
        normal = m.normal(moved_id)                        # the wall's plane: through old[0], this normal
        depth = ((old[0] - eye) @ normal) / (rays @ normal)
        now = eye + depth[:, None] * rays                  # where the rays meet the wall
        q2.answer = {"misplaced_id": moved_id, "moved_mm": now.mean(axis=0) - old.mean(axis=0)}
        """,
    "level": "hard",
}


def _moved_on_wall(detection, marker_map, camera, T_world_camera) -> np.ndarray:
    """How the marker of ``detection`` moved on its wall: the rays of its corners meet the map's wall plane."""
    xy = cv2.undistortPoints(detection.corners_px.reshape(-1, 1, 2), camera.K, camera.dist).reshape(-1, 2)
    rays = np.column_stack([xy, np.ones(len(xy))]) @ T_world_camera[:3, :3].T
    old = marker_map.marker_corners(detection.id)
    normal = marker_map.normal(detection.id)
    eye = T_world_camera[:3, 3]
    depth = ((old[0] - eye) @ normal) / (rays @ normal)
    return (eye + depth[:, None] * rays).mean(axis=0) - old.mean(axis=0)


def _q2_mistakes(bad, tol, moved, biased, map_centre) -> list:
    """The mistakes q2 names: (detector, message) pairs, in the order they are tried."""

    def near(v):
        return lambda a: a["misplaced_id"] == bad and np.linalg.norm(a["moved_mm"] - v) <= tol

    return [
        (near(-moved), "that is the move the other way round: the centre NOW minus the centre in the map"),
        (
            lambda a: a["misplaced_id"] == bad and np.linalg.norm(a["moved_mm"]) < 5,
            (
                "your marker did not move: the map's corners give the map's centre back. Find where the marker "
                "is now from its pixels: the rays through them, from the camera, meet the wall"
            ),
        ),
        (
            near(map_centre + moved),
            "that is where the marker is now; the question asks how it MOVED: subtract its centre in the map",
        ),
        (
            lambda a: (
                a["misplaced_id"] == bad
                and np.linalg.norm(a["moved_mm"] - biased) <= tol
                and np.linalg.norm(biased - moved) > tol
            ),
            (
                "the pose you cast the rays from still uses the misplaced marker, and it pulls the pose: solve it "
                "without that marker (estimate_pose rejects it; use that pose)"
            ),
        ),
        (
            lambda a: a["misplaced_id"] == bad and np.linalg.norm(a["moved_mm"] * 10 - moved) <= tol,
            "that looks like cm: give mm",
        ),
    ]


def _q2_layout(rng: np.random.Generator) -> tuple:
    """q2's scene before it is rendered: (camera, marker_map, T_world_camera), every marker in the picture."""
    cam2 = Camera.from_fov(float(np.round(rng.uniform(55, 65))), (960, 720))
    true_map = _wall_map(rng, 5, 150.0, spread_mm=700.0)

    def draw(r):
        return look_at(np.round(r.uniform([1800, -400, 1000], [2600, 400, 1400])), [0.0, 0.0, 1250.0])

    return cam2, true_map, _pose_seeing_all(rng, cam2, true_map, draw)


def _q2(learner: str) -> Question:
    """q2: Where did the misplaced marker go?"""
    from ... import pose as _pose
    from ... import synthetic
    from ...detection import detect_markers

    rng = _rng("08", learner, "q2")
    cam2, true_map, T2 = _q2_layout(rng)
    scene = synthetic.render_scene(true_map, cam2, T2, seed=int(rng.integers(1 << 30)), blur_px=0.5, noise_std_gray=1.5)
    image, truth = scene.image, scene.truth
    seen = sorted(set(truth) & {d.id for d in detect_markers(image, true_map.dictionary)})
    bad = int(rng.choice(seen))  # a marker the learner's detection finds too
    shift = rng.choice([-1, 1]) * float(rng.uniform(80, 140))
    placements = dict(true_map.placements)
    p = placements[bad]
    placements[bad] = MarkerPlacement(
        bad, (p.translation_mm[0], p.translation_mm[1] + round(shift), p.translation_mm[2]), p.rotation_deg
    )
    wrong_map = MarkerMap(placements, true_map.marker_size_mm, dictionary=true_map.dictionary, units="mm")
    dets = [d for d in detect_markers(image, true_map.dictionary) if d.id in seen]
    moved = np.array([0.0, -float(round(shift)), 0.0])  # the map was shifted; the marker is where it was
    bad_det = next(d for d in dets if d.id == bad)
    good = _pose.estimate_pose([d for d in dets if d.id != bad], wrong_map, cam2, reject_outliers=False)
    all_in = _pose.estimate_pose(dets, wrong_map, cam2, reject_outliers=False)
    est = _moved_on_wall(bad_det, wrong_map, cam2, good.T_world_camera)
    biased = _moved_on_wall(bad_det, wrong_map, cam2, all_in.T_world_camera)
    tol = max(15.0, 3 * float(np.linalg.norm(est - moved)))

    def cmp2(a, _):
        if a["misplaced_id"] != bad:
            return (
                f"marker {a['misplaced_id']} agrees with the others; leave each marker out in turn (or read "
                "Pose.rejected_ids) and see which one the others do not explain"
            )
        err = float(np.linalg.norm(a["moved_mm"] - moved))
        if err > tol:
            return f"the right marker, but your move is {err:.0f} mm from the truth (tolerance {tol:.0f} mm)"
        return None

    return Question(
        "q2",
        inputs={"image": image.copy(), "marker_map": wrong_map, "camera": cam2},
        expected={"misplaced_id": bad, "moved_mm": moved},
        parse=_parts(misplaced_id=lambda v: int(_scalar("misplaced_id")(v)), moved_mm=_array((3,), "moved_mm")),
        compare=cmp2,
        wrong=_q2_mistakes(bad, tol, moved, biased, wrong_map.marker_corners(bad).mean(axis=0)),
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Two poses that both fit",
    "task": """
        One marker, seen from about 3 m, was detected (`detections`); `marker_map` and `camera`
        are as usual. fidlearn.pose.estimate_pose reports the pose as ambiguous, and the camera
        position jumps from frame to frame. Write code that computes both candidate camera poses
        (estimate_pose returns the second one as Pose.alternative; cv2.solvePnPGeneric with
        SOLVEPNP_IPPE_SQUARE gives both too) and the distance in mm between the two candidate
        camera positions. Then choose the explanation from `choices`. Answer
        {"choice": letter, "separation_mm": distance}.
        """,
    "hint": [
        "A flat target seen from afar has two poses that fit its corners almost equally well (notebook 08).",
        (
            "fidlearn's pose keeps the runner-up solution of a planar target beside the one it ranked first; "
            "measure how far apart the two camera positions are. Both fit the corners to a fraction of a pixel: "
            "which explanation allows that?"
        ),
    ],
    "solution": """
        from fidlearn.pose import estimate_pose
        pose = estimate_pose(q3.inputs.detections, q3.inputs.marker_map, q3.inputs.camera)
        separation = np.linalg.norm(pose.position_mm - pose.alternative.position_mm)
        flip = next(k for k, text in q3.inputs.choices.items() if "face-on" in text)
        q3.answer = {"choice": flip, "separation_mm": separation}
        """,
    "level": "hard",
}


def _q3_mistakes(right, sep) -> list:
    """The mistakes q3 names: (detector, message) pairs, in the order they are tried."""
    return [
        (
            lambda a: a["choice"] == right and abs(a["separation_mm"] * 1000 - sep) <= 0.15 * sep + 5,
            "that separation is in metres: give mm",
        ),
        (
            lambda a: a["choice"] == right and a["separation_mm"] < 1,
            (
                "the two candidates are far apart (the camera seems to swing to the other side): compare "
                "pose.position_mm with pose.alternative.position_mm"
            ),
        ),
    ]


def _ambiguous_view(rng: np.random.Generator) -> tuple:
    """q3's scene: one small marker seen from about 3 m, redrawn until its two candidate poses are far apart.

    Returns ``(camera, marker_map, detections, separation_mm, separations_mm)``: the separation of
    estimate_pose's two candidates, and the separations a learner may fairly give (raw IPPE too).
    """
    from ... import pose as _pose

    cam3 = Camera.from_fov(float(np.round(rng.uniform(55, 70))), (1280, 720))
    mid = int(rng.integers(0, 40))
    m3 = MarkerMap(
        {
            mid: MarkerPlacement(
                mid,
                (0.0, float(np.round(rng.uniform(-300, 300))), float(np.round(rng.uniform(1000, 1400)))),
                (0.0, 0.0, 0.0),
            )
        },
        float(rng.choice([80, 100])),
        dictionary="ARUCO_ORIGINAL",
        units="mm",
    )
    centre = m3.marker_corners(mid).mean(axis=0)
    for _ in range(50):
        T3 = look_at(
            centre + [float(rng.uniform(2800, 3600)), float(rng.uniform(-150, 150)), float(rng.uniform(-100, 100))],
            centre,
        )
        det3 = _noisy_detections(rng, m3, cam3, T3, 0.3)
        p3 = _pose.estimate_pose(det3, m3, cam3)
        # Pose.alternative is a property set after the class; mypy sees only the dataclass's InitVar
        alt3 = p3.alternative  # type: ignore[attr-defined]
        if p3.ambiguous and alt3 is not None and np.linalg.norm(p3.position_mm - alt3.position_mm) > 250:
            break
    sep = float(np.linalg.norm(p3.position_mm - alt3.position_mm))
    # the two raw IPPE solutions (no refinement) are a fair answer too
    s3 = m3.marker_size_mm / 2
    local = np.array([[-s3, s3, 0], [s3, s3, 0], [s3, -s3, 0], [-s3, -s3, 0]])
    _, rvs, tvs, _ = cv2.solvePnPGeneric(
        local, det3[0].corners_px, cam3.K, cam3.dist, flags=_cv.solvepnp_flag("IPPE_SQUARE")
    )
    raw = [
        frames.invert_transform(frames.transform_from_rvec_tvec(np.ravel(r), np.ravel(t)))[:3, 3]
        for r, t in zip(rvs, tvs)
    ]
    seps = [sep] + ([float(np.linalg.norm(raw[0] - raw[1]))] if len(raw) == 2 else [])
    return cam3, m3, det3, sep, seps


def _q3(learner: str) -> Question:
    """q3: Two poses that both fit."""
    rng = _rng("08", learner, "q3")
    cam3, m3, det3, sep, seps = _ambiguous_view(rng)
    order = list(rng.permutation(len(_AMBIGUITY_CHOICES)))
    letters = "ABCD"
    choices = {letters[k]: _AMBIGUITY_CHOICES[i][1] for k, i in enumerate(order)}
    right = letters[order.index(0)]
    wrong_letters = {letters[k]: _AMBIGUITY_CHOICES[i][0] for k, i in enumerate(order) if i != 0}

    def parse3(answer):
        d = _parts(choice=lambda v: str(v).strip().upper()[:1], separation_mm=_scalar("separation_mm"))(answer)
        if d["choice"] not in choices:
            raise _AnswerError(f"choice must be one of {', '.join(choices)}, got {d['choice']!r}")
        return d

    def cmp3(a, _):
        if a["choice"] != right:
            return f"choice {a['choice']} does not explain it: {_AMBIGUITY_WRONG[wrong_letters[a['choice']]]}"
        if all(abs(a["separation_mm"] - x) > 0.15 * x + 5 for x in seps):
            return (
                f"the explanation is right; the separation {a['separation_mm']:.0f} mm is not what the two "
                "candidate poses give (within 15 %)"
            )
        return None

    return Question(
        "q3",
        inputs={"detections": det3, "marker_map": m3, "camera": cam3, "choices": choices},
        expected={"choice": right, "separation_mm": sep},
        parse=parse3,
        compare=cmp3,
        wrong=_q3_mistakes(right, sep),
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Design: three markers, the whole area within the target",
    "task": """
        A robot's `camera` (with its lens distortion) rides `height_mm` above the floor in the floor area
        `area_mm` = (x0, y0, x1, y1), mm, in front of the wall X = 0. You may print three markers of side
        `marker_size_mm` and hang them on that wall, facing into the room (+X, rotation [0, 0, 0]), every
        corner within `wall_span_mm` (Y, mm) and `height_range_mm` (Z, mm). Where? Answer a MarkerMap (or a
        dict in the full map-file layout) with exactly three markers. The check predicts the camera's position
        error looking toward the markers, `fidlearn.plan_room(your_map, camera, height_mm=height_mm,
        area=area_mm, step_mm=250, headings=0)`, and wants `fraction_within(target_mm)` of at least
        `fraction`. `fidlearn.planning.suggest_markers` may help; knowing why helps more.
        """,
    "hint": (
        "From afar, markers close together act as one small marker: its corners hardly tell a small tilt of the "
        "wall from a sideways shift of the camera, so spread the three along the wall AND in height (a wide "
        "triangle). The far places are the hardest: the error grows with the square of the distance and shrinks "
        "with the marker's size in pixels. But the camera looks at the middle of the markers: from the nearest "
        "places at least one must still be whole in the picture. Try a few widths with plan_room and keep the best."
    ),
    "solution": """
        i = q4.inputs
        s, (y_lo, y_hi), (z_lo, z_hi) = i.marker_size_mm, i.wall_span_mm, i.height_range_mm
        y_mid, z_low = (y_lo + y_hi - s) / 2, z_lo + s   # top-left corners, mm
        w = 0.6 * (y_hi - y_lo - s) / 2                  # wide, but the nearest places must still see one marker
        spots = [(y_mid - w, z_low), (y_mid, z_low + w / 2), (y_mid + w, z_low)]  # two low, one higher between
        places = {k: fidlearn.MarkerPlacement(k, (0, y, z), (0, 0, 0)) for k, (y, z) in enumerate(spots)}
        q4.answer = fidlearn.MarkerMap(places, s)
        """,
    "level": "hard",
}


def _q4(learner: str) -> Question:
    """q4: Design: three markers, the whole area within the target."""
    rng = _rng("08", learner, "q4")
    size = [(1280, 720), (1024, 768), (1280, 960)][int(rng.integers(3))]
    k1, k2 = float(np.round(rng.uniform(-0.06, -0.02), 3)), float(np.round(rng.uniform(0, 0.02), 3))
    cam = Camera.from_fov(float(np.round(rng.uniform(60, 75))), size, dist=[k1, k2, 0, 0, 0])
    height = float(np.round(rng.uniform(200, 500), -1))
    x0, x1 = float(np.round(rng.uniform(800, 1200), -1)), float(np.round(rng.uniform(3000, 3600), -2))
    marker = float(np.round(rng.uniform(26, 32) * x1 / cam.fx, -1))  # 26 to 32 px wide at the far end
    width, yc = float(np.round(rng.uniform(2000, 3000), -2)), float(np.round(rng.uniform(-500, 500), -1))
    area = (x0, yc - width / 2, x1, yc + width / 2)
    span = (area[1] - 500, area[3] + 500)
    heights = (float(np.round(rng.uniform(250, 400), -1)), float(np.round(rng.uniform(1500, 1900), -2)))
    task = _WallTask(cam, height, area, marker, 10.0, 0.9, span, heights)
    return Question(
        "q4",
        inputs={
            "camera": cam,
            "height_mm": height,
            "area_mm": area,
            "marker_size_mm": marker,
            "wall_span_mm": span,
            "height_range_mm": heights,
            "target_mm": 10.0,
            "fraction": 0.9,
        },
        expected=task,
        parse=_marker_map,
        compare=task.verdict,
        notes=[(lambda _m: True, task.praise)],
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 08 for one learner, in notebook order.

    Parameters
    ----------
    learner : str
        The learner's id; it seeds every question's numbers (``""``: the class's shared variant).

    Returns
    -------
    list of Question
        q1 to q4, with their answer keys.
    """
    return [_q1(learner), _q2(learner), _q3(learner), _q4(learner)]
