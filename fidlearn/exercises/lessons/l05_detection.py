"""Lesson 05: Detecting markers.

The three questions share one rendered picture (:func:`_scene`, drawn once per learner); each
question builder takes that scene.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import cv2
import numpy as np

from ... import frames
from ...camera import Camera
from ...frames import look_at
from ...markermap import MarkerMap, MarkerPlacement
from .._engine import Question, QuestionText, _AnswerError
from .._parsers import _array, _close, _cmp_array, _cmp_scalar, _corner_order, _scalar, _winding_message
from .._scenery import _pose_seeing_all, _rng

NUMBER = "05"
TOPIC = "detection"
TITLE = "Detecting markers"
INTRO = """
    Find markers in a rendered picture: the right dictionary, the ids, the corners in the marker's
    own winding order TL, TR, BR, BL, and how a turned marker shows in the image.
    """


class _Scene(NamedTuple):
    """The lesson's picture and what is true about it."""

    camera: Camera
    marker_map: MarkerMap
    T_world_camera: np.ndarray
    image: np.ndarray
    truth: dict
    rotated_id: int | None
    dictionary: str


#: The lesson's scene: 5 markers, one of them turned, from one of these dictionaries.
_SCENE_ARGS = (5, True, ("ARUCO_ORIGINAL", "4X4_50", "6X6_250"))


def _layout(rng: np.random.Generator, n_markers: int, rotated: bool, dictionaries: Sequence[str]) -> tuple:
    """The scene before it is rendered: (camera, marker_map, T_world_camera, rotated_id, dictionary)."""
    dictionary = str(rng.choice(list(dictionaries)))
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 70))), (800, 600))
    size = 120.0
    ids = [int(i) for i in np.sort(rng.choice(40, size=n_markers, replace=False))]
    ys = np.linspace(-600, 600, n_markers) + rng.uniform(-60, 60, n_markers)
    placements = {}
    rotated_id = int(rng.choice(ids)) if rotated else None
    for k, (mid, y) in enumerate(zip(ids, ys)):
        z = 1150.0 + (180.0 if k % 2 else -120.0) + float(rng.uniform(-40, 40))
        # never exactly upside down: at 180 deg a sign error in the angle (q3) would give the same answer
        roll = float(rng.choice([90, 165, -165, -90])) if mid == rotated_id else 0.0
        # a marker rotated about its top-left corner: shift it so that it stays where it was meant to be
        tl = np.array([0.0, np.round(y), np.round(z)])
        R = frames.rotation_from_rpy_deg(roll, 0, 0)
        centre_offset = R @ np.array([0.0, size / 2, -size / 2]) - np.array([0.0, size / 2, -size / 2])
        tl = tl - centre_offset
        tx, ty, tz = (float(v) for v in tl)
        placements[mid] = MarkerPlacement(mid, (tx, ty, tz), (roll, 0.0, 0.0))
    m = MarkerMap(placements, size, dictionary=dictionary, units="mm")

    def draw(r):
        eye = np.round(r.uniform([1700, -300, 1000], [2300, 300, 1400]))
        return look_at(eye, [0.0, float(np.round(r.uniform(-100, 100))), 1150.0])

    return cam, m, _pose_seeing_all(rng, cam, m, draw), rotated_id, dictionary


def _scene(lesson_id: str, learner: str, question: str, n_markers: int, rotated: bool, dictionaries: Sequence[str]):
    """A seeded scene: (camera, marker_map, T_world_camera, image, truth, rotated_id, dictionary)."""
    from ... import synthetic

    rng = _rng(lesson_id, learner, question)
    cam, m, T, rotated_id, dictionary = _layout(rng, n_markers, rotated, dictionaries)
    rendered = synthetic.render_scene(
        m, cam, T, seed=int(rng.integers(1 << 30)), blur_px=0.6, noise_std_gray=2.0, gradient=0.15
    )
    image, truth = rendered.image, rendered.truth
    return cam, m, T, image, truth, rotated_id, dictionary


def _parse_ids(answer):
    if isinstance(answer, (str, bytes)) or not hasattr(answer, "__iter__"):
        raise _AnswerError("give a list of marker ids (integers)")
    items = [getattr(v, "id", v) for v in answer]  # Detection objects are fine too
    try:
        a = np.asarray(items)
    except ValueError:  # a ragged list
        a = np.asarray(items, dtype=object)
    if a.dtype != object and a.ndim > 1 and a.size not in a.shape:
        raise _AnswerError(f"give one list of marker ids; your answer has shape {a.shape}")
    out = []
    for v in a.ravel() if a.dtype != object else items:
        v = v.item() if isinstance(v, np.generic) else v  # shown as the learner wrote it
        try:
            f = complex(np.asarray(v).reshape(-1)[0])
        except (TypeError, ValueError, IndexError, OverflowError):
            raise _AnswerError(f"{v!r} is not a marker id") from None
        if f.imag != 0 or not math.isfinite(f.real) or f.real != round(f.real):
            raise _AnswerError(f"{v!r} is not a marker id: ids are whole numbers (0, 1, 2, ...)")
        out.append(int(f.real))
    return sorted(out)


def _cmp_ids(a, b):
    if sorted(set(a)) == b:
        return None if len(a) == len(b) else "each id once, please"
    if not a:
        return None if not b else "no ids"
    missing = sorted(set(b) - set(a))
    extra = sorted(set(a) - set(b))
    if extra:
        return f"ids {extra} are not in the picture"
    return (
        f"you found {len(b) - len(missing)} of the {len(b)} markers; look again (the whole image, the right dictionary)"
    )


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "Which markers are in the picture?",
    "task": """
        `image` is a gray picture (H, W) of a wall with markers from the dictionary `dictionary`.
        Write code that detects them (fidlearn.detection.detect_markers, or OpenCV's
        cv2.aruco.ArucoDetector) and gives the sorted list of their ids.
        """,
    "hint": [
        "The detector must be told which dictionary the markers were printed from; with the wrong one it finds "
        "nothing, or the wrong ids.",
        (
            "fidlearn's detection (notebook 05) takes the picture and the dictionary and returns one detection per "
            "marker, each with its id. The question wants the ids, in increasing order."
        ),
    ],
    "look": 'from fidlearn import plotting\nplotting.show_image(None, q1.inputs.image, title="q1.inputs.image");',
    "solution": """
        from fidlearn.detection import detect_markers
        detections = detect_markers(q1.inputs.image, dictionary=q1.inputs.dictionary)
        q1.answer = sorted(d.id for d in detections)
        """,
    "level": "easy",
}


def _q1(scene: _Scene) -> Question:
    """q1: Which markers are in the picture?"""
    image, dictionary = scene.image, scene.dictionary
    ids = sorted(scene.truth)
    return Question(
        "q1",
        inputs={"image": image.copy(), "dictionary": dictionary},
        expected=ids,
        parse=_parse_ids,
        compare=_cmp_ids,
        wrong=[
            (
                lambda a: len(a) == 0,
                (
                    "nothing was found: a detector only sees markers of its own dictionary; this picture uses "
                    f"{dictionary!r} "
                    "(pass dictionary=q1.inputs.dictionary)"
                ),
            ),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "The corners of a turned marker, in order",
    "task": """
        Marker `marker_id` hangs turned on the wall, so its own top-left corner is not the
        top-left of the picture. Write code that finds its four corners in `image` (dictionary
        `dictionary`) and gives them as a (4, 2) array of (x, y) pixels in the marker's own order
        TL, TR, BR, BL: the order the map uses and detection reports.
        """,
    "hint": (
        "Keep the corners exactly as the detector returns them for that id: d.corners_px for the Detection "
        "with d.id == marker_id."
    ),
    "solution": """
        from fidlearn.detection import detect_markers
        detections = detect_markers(q2.inputs.image, dictionary=q2.inputs.dictionary)
        q2.answer = next(d.corners_px for d in detections if d.id == q2.inputs.marker_id)
        """,
    "level": "medium",
}


def _q2(scene: _Scene) -> Question:
    """q2: The corners of a turned marker, in order."""
    image, dictionary, rot_id = scene.image, scene.dictionary, scene.rotated_id
    C = scene.truth[rot_id]

    def winding(a):
        order = _corner_order(a, C, 1.5)
        return order is not None and order != ("TL", "TR", "BR", "BL")

    image_sorted = C[np.lexsort((C[:, 0], C[:, 1]))]
    return Question(
        "q2",
        inputs={"image": image.copy(), "dictionary": dictionary, "marker_id": rot_id},
        expected=C,
        parse=_array((4, 2), "the corners", {(2, 4): "one ROW per corner: transpose it", (1, 4, 2): ""}),
        compare=_cmp_array(1.5, " px"),
        wrong=[
            (winding, lambda a: _winding_message(_corner_order(a, C, 1.5))),
            (lambda a: _close(a[:, ::-1], C, 1.0), "x and y are swapped: a pixel is (x, y) = (column, row)"),
            (
                lambda a: _close(a, image_sorted, 1.0),
                (
                    "you sorted the corners by their place in the picture; keep the order detection gives: the "
                    "marker's own TL, TR, BR, BL"
                ),
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "How is the marker turned?",
    "task": """
        From the detected corners of marker `marker_id`, write code that computes the direction of
        its top edge (from its TL to its TR) in the picture, in degrees, as atan2(dy, dx) with the
        image's axes (x right, y DOWN): 0 means upright, 90 means turned a quarter turn clockwise
        as you look at the picture.
        """,
    "hint": [
        (
            "The marker's top edge runs from its TL corner to its TR corner; its angle in the image is the angle "
            "of that edge."
        ),
        (
            "The angle of a vector (dx, dy) is atan2(dy, dx); in the image y points DOWN, so a positive angle "
            "turns clockwise on the screen. Give degrees."
        ),
    ],
    "solution": """
        from fidlearn.detection import detect_markers
        detections = detect_markers(q3.inputs.image, dictionary=q3.inputs.dictionary)
        c = next(d.corners_px for d in detections if d.id == q3.inputs.marker_id)
        dx, dy = c[1] - c[0]
        q3.answer = np.degrees(np.arctan2(dy, dx))
        """,
    "level": "medium",
}


def _q3(scene: _Scene) -> Question:
    """q3: How is the marker turned?"""
    image, dictionary, rot_id = scene.image, scene.dictionary, scene.rotated_id
    C = scene.truth[rot_id]
    angle = math.degrees(math.atan2(C[1, 1] - C[0, 1], C[1, 0] - C[0, 0]))

    def ang_diff(a, b):
        d = (a - b + 180) % 360 - 180
        return None if abs(d) <= 3 else f"your angle is {d:+.3g} deg from the key's"

    return Question(
        "q3",
        inputs={"image": image.copy(), "dictionary": dictionary, "marker_id": rot_id},
        expected=angle,
        parse=_scalar("the angle"),
        compare=ang_diff,
        wrong=[
            (lambda a: ang_diff(math.degrees(a), angle) is None, "that is in radians: give degrees (np.degrees)"),
            (
                lambda a: ang_diff(-a, angle) is None,
                "the sign is flipped: image y grows DOWNward, so use atan2(y_TR - y_TL, x_TR - x_TL) as it is",
            ),
            (
                lambda a: ang_diff(a, math.degrees(math.atan2(C[1, 0] - C[0, 0], C[1, 1] - C[0, 1]))) is None,
                "atan2 takes (dy, dx): y first",
            ),
            (
                lambda a: (
                    ang_diff(a + 90, angle) is None
                    or ang_diff(a - 90, angle) is None
                    or ang_diff(a + 180, angle) is None
                ),
                "that is the direction of another edge: use the TOP edge, TL (corner 0) to TR (corner 1)",
            ),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "How far can the detector see?",
    "task": """
        OpenCV's ArUco detector throws away every outline whose perimeter is shorter than
        `min_perimeter_rate` (its `minMarkerPerimeterRate`) times the LARGER side of the image, in
        pixels. A square marker of `marker_size_mm` faces `camera` squarely in the middle of the
        picture. Write code that computes the farthest distance (mm, along the optical axis) at which
        the detector still keeps it, by this rule alone (blur and noise can lose it sooner).
        """,
    "hint": [
        "Two lengths must meet: the smallest perimeter the detector keeps, in pixels, and the marker's "
        "perimeter in pixels at distance Z.",
        "A marker of side s at depth Z is fx * s / Z pixels wide (similar triangles); its outline has four such sides.",
    ],
    "solution": """
        cam = q4.inputs.camera
        min_perimeter_px = q4.inputs.min_perimeter_rate * max(cam.image_size)
        # the outline at depth Z is 4 sides of fx * s / Z pixels: solve 4 fx s / Z = min_perimeter_px
        q4.answer = 4 * cam.fx * q4.inputs.marker_size_mm / min_perimeter_px
        """,
    "level": "medium",
}


def _q4(learner: str) -> Question:
    """q4: How far can the detector see?"""
    rng = _rng("05", learner, "q4")
    size = [(640, 480), (1280, 720), (1920, 1080), (800, 600)][int(rng.integers(4))]
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 80))), size)
    marker = float(rng.choice([50, 80, 100, 120, 150, 200]))
    rate = float(cv2.aruco.DetectorParameters().minMarkerPerimeterRate)
    z = 4 * cam.fx * marker / (rate * max(size))
    return Question(
        "q4",
        inputs={"camera": cam, "marker_size_mm": marker, "min_perimeter_rate": rate},
        expected=z,
        parse=_scalar("the distance"),
        compare=_cmp_scalar(0, " mm", rtol=2e-3),
        wrong=[
            (
                lambda a: abs(a * 4 - z) <= 3e-3 * z,
                "the detector's limit is on the PERIMETER, four sides of the marker, not on one side",
            ),
            (
                lambda a: abs(a - z * max(size) / min(size)) <= 3e-3 * z,
                "the rate multiplies the LARGER side of the image (max(width, height)), not the smaller",
            ),
            (lambda a: abs(a * 1000 - z) <= 3e-3 * z, "that is in metres: the answer is asked in mm"),
            (
                lambda a: abs(a - 4 * cam.fx * marker / rate) <= 3e-3 * z * max(size),
                "the rate is a fraction of the image's larger side: multiply it by max(width, height) to get pixels",
            ),
        ],
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 05 for one learner, in notebook order.

    Parameters
    ----------
    learner : str
        The learner's id; it seeds the scene (``""``: the class's shared variant).

    Returns
    -------
    list of Question
        q1, q2, q3, all about one rendered picture, and q4, the detector's reach.
    """
    scene = _Scene(*_scene("05", learner, "scene", *_SCENE_ARGS))
    return [_q1(scene), _q2(scene), _q3(scene), _q4(learner)]
