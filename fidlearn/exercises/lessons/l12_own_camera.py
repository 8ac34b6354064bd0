"""Lesson 12: Your own camera.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("12", learner, "qN")``), so a learner's variant of one question
does not depend on the others. Every question runs on numbers or bundled pictures: no camera.
"""

from __future__ import annotations

import json

import numpy as np

from ... import frames
from ...data import data_path
from ...frames import look_at
from .._engine import Question, QuestionText
from .._parsers import _array, _close, _cmp_array, _cmp_scalar, _parts, _scalar

NUMBER = "12"
TOPIC = "own_camera"
TITLE = "Your own camera"
INTRO = """
    Bring a camera of your own: markers that printed at the wrong size, how much of the picture a set
    of calibration views covers, the coach's verdict in numbers, and where MarkerTracker looks for a
    marker in the next frame. Everything runs on numbers and the bundled pictures: no camera needed.
    """

#: The notebook's verdict: the coach's uncertainty under this many pixels ...
GOOD_UNCERTAINTY_PX = 0.3
#: ... over at least this share of the picture, and no warning.
GOOD_FRACTION = 0.9

#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "Markers printed at the wrong size",
    "task": """
        The map says the markers' black squares are `map_size_mm` wide. Your printer scaled the page:
        with a ruler a black square measures `printed_mm`. `fidlearn.locate` with the map put the
        camera `located_distance_mm` from the markers. How far is the camera really (mm)?
        """,
    "hint": [
        "A picture cannot tell a small marker near from a big marker far: only the ratio of size to distance.",
        (
            "Everything the pose says about lengths is in the map's units, scaled by what the map believes the "
            "marker's size to be. Correct the distance by the ratio of the true size to the believed one."
        ),
    ],
    "solution": """
        d = q1.inputs
        q1.answer = d.located_distance_mm * d.printed_mm / d.map_size_mm
        """,
    "level": "easy",
}


def _q1(learner: str) -> Question:
    """q1: Markers printed at the wrong size."""
    rng = _rng_for(learner, "q1")
    size = float(rng.choice([80.0, 100.0, 120.0, 150.0]))
    scale = float(rng.choice([rng.uniform(0.93, 0.985), rng.uniform(1.02, 1.06)]))
    printed = round(size * scale, 1)
    located = round(float(rng.uniform(900, 4000)), 1)
    key = located * printed / size
    return Question(
        "q1",
        inputs={"map_size_mm": size, "printed_mm": printed, "located_distance_mm": located},
        expected=key,
        parse=_scalar("the distance"),
        compare=_cmp_scalar(0.5, " mm"),
        wrong=[
            (
                lambda a: abs(a - located * size / printed) <= 0.5,
                "the ratio is upside down: a marker smaller than the map says looks farther away than it is, "
                "so the camera is nearer than located",
            ),
            (
                lambda a: abs(a - located) <= 0.5,
                "that is the distance located with the map's size: the pose scales with the marker's size",
            ),
            (
                lambda a: abs(a - (located + printed - size)) <= 0.5 or abs(a - (located - printed + size)) <= 0.5,
                "the size error is not added to the distance: it scales it (a ratio, not a difference)",
            ),
        ],
        **_Q1,
    )


def _rng_for(learner: str, question: str) -> np.random.Generator:
    """The learner's generator for one of this lesson's questions."""
    from .._scenery import _rng

    return _rng(NUMBER, learner, question)


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "How much of the picture do the views cover?",
    "task": """
        `corners_px` holds the inner corners (pixels, (54, 2) each) of some bundled calibration views
        of a `width` x `height` picture. Cut the picture into `cells` = (columns, rows) equal cells
        and count a cell as covered when a board corner of some view lies in it. What fraction of
        the cells is covered (a number from 0 to 1)?
        """,
    "hint": [
        "For each corner, find the column and the row of the cell it falls in; then count the distinct cells.",
        (
            "A corner at x lies in column floor(x / width * columns), and likewise for rows with y and height. "
            "Mind which of the two numbers in `cells` goes with x."
        ),
    ],
    "solution": """
        d = q2.inputs
        cols, rows = d.cells
        covered = np.zeros((rows, cols), bool)
        for c in d.corners_px:
            c = np.asarray(c)
            col = np.clip((c[:, 0] / d.width * cols).astype(int), 0, cols - 1)
            row = np.clip((c[:, 1] / d.height * rows).astype(int), 0, rows - 1)
            covered[row, col] = True
        q2.answer = covered.mean()
        """,
    "level": "medium",
}


def _coverage(corner_sets: list, size: tuple, cells: tuple) -> float:
    """Fraction of the (cols, rows) cells holding a corner of some view."""
    (w, h), (cols, rows) = size, cells
    covered = np.zeros((rows, cols), bool)
    for c in corner_sets:
        col = np.clip((c[:, 0] / w * cols).astype(int), 0, cols - 1)
        row = np.clip((c[:, 1] / h * rows).astype(int), 0, rows - 1)
        covered[row, col] = True
    return float(covered.mean())


def _corner_share(corner_sets: list, size: tuple, cells: tuple) -> float:
    """The wrong count: the share of corners (not of cells) in distinct cells."""
    return _coverage(corner_sets, size, cells) * cells[0] * cells[1] / sum(len(c) for c in corner_sets)


def _q2(learner: str) -> Question:
    """q2: How much of the picture do the views cover?"""
    rng = _rng_for(learner, "q2")
    record = json.loads(data_path("calibration", "views.json").read_text())
    views = [np.asarray(v["corners_px"], dtype=float) for v in record["views"]]
    size = (640, 480)
    while True:  # a set the transposed grid and the corner count cannot pass by chance
        cells = tuple(int(v) for v in rng.choice([(8, 6), (10, 6), (6, 4), (12, 8)]))
        picked = sorted(int(i) for i in rng.choice(len(views), size=int(rng.integers(2, 6)), replace=False))
        sets = [views[i] for i in picked]
        key = _coverage(sets, size, cells)
        transposed = _coverage(sets, size, cells[::-1])
        if 0.1 < key < 0.95 and abs(transposed - key) > 0.02 and abs(_corner_share(sets, size, cells) - key) > 0.02:
            break
    return Question(
        "q2",
        inputs={
            "corners_px": [np.round(s, 3) for s in sets],
            "views": [f"view_{i:02d}.png" for i in picked],
            "width": size[0],
            "height": size[1],
            "cells": cells,
        },
        expected=key,
        parse=_scalar("the covered fraction"),
        compare=_cmp_scalar(1e-6),
        wrong=[
            (
                lambda a: abs(a - 100 * key) < 1e-4,
                "that is a percentage: the fraction is a number from 0 to 1",
            ),
            (
                lambda a: abs(a - transposed) < 1e-6,
                "the grid is transposed: `cells` is (columns, rows); columns go with x and the width",
            ),
            (
                lambda a: abs(a - _corner_share(sets, size, cells)) < 1e-6,
                "that is per corner: the question counts cells, each covered cell once",
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Good enough? The coach's verdict",
    "task": """
        The coach judged a calibration: `uncertainty_px` is its reprojection uncertainty over the
        picture (a grid of cells, px) and `flags` its warnings. The notebook's verdict: good enough
        when there is no warning and the uncertainty is under `good_px` over at least `good_fraction`
        of the cells. Answer a dict: `{"fraction": ..., "good": ...}`, the share of cells under
        `good_px` (0 to 1) and the verdict (True or False).
        """,
    "hint": [
        "Two conditions, both needed: look at every cell of the map, and at the warnings.",
        "The share of cells under the threshold is a mean of a comparison; a median or a mean of the map is not.",
    ],
    "solution": """
        d = q3.inputs
        fraction = float(np.mean(np.asarray(d.uncertainty_px) < d.good_px))
        q3.answer = {"fraction": fraction, "good": not d.flags and fraction >= d.good_fraction}
        """,
    "level": "easy",
}


def _q3_map(rng: np.random.Generator) -> np.ndarray:
    """A coach-like uncertainty map: smallest near where the views were, growing towards the picture's edges."""
    rows, cols = 12, 16
    y, x = np.mgrid[0:rows, 0:cols]
    cx, cy = rng.uniform(4, 12), rng.uniform(3, 9)
    base, grow = rng.uniform(0.05, 0.15), rng.uniform(0.0008, 0.004)
    return np.round(base + grow * ((x - cx) ** 2 + (y - cy) ** 2), 3)


def _q3(learner: str) -> Question:
    """q3: Good enough? The coach's verdict."""
    rng = _rng_for(learner, "q3")
    flagged = bool(rng.random() < 0.4)
    # A warning comes with a small enough uncertainty (the warning alone decides); otherwise either verdict.
    want_small = flagged or bool(rng.random() < 0.5)
    while True:  # never near the threshold, never the whole picture
        u = _q3_map(rng)
        fraction = float(np.mean(u < GOOD_UNCERTAINTY_PX))
        if 0.4 < fraction < 1 and abs(fraction - GOOD_FRACTION) > 0.02 and (fraction >= GOOD_FRACTION) == want_small:
            break
    flags = ["only 8 views were used; take at least 10 (15 to 25 is usual)"] if flagged else []
    good = not flags and fraction >= GOOD_FRACTION
    key = {"fraction": fraction, "good": good}

    def parse_bool(a):
        if isinstance(a, (bool, np.bool_)):
            return bool(a)
        from .._engine import _AnswerError

        raise _AnswerError(f"the verdict should be True or False, got {a!r:.40}")

    def compare(a, b):
        if abs(a["fraction"] - b["fraction"]) > 1e-6:
            return f"the fraction {a['fraction']:.4g} is not the share of cells under {GOOD_UNCERTAINTY_PX} px"
        if a["good"] != b["good"]:
            return "the fraction is right, the verdict is not"
        return None

    median_share = float(np.mean(u < np.median(u)))
    return Question(
        "q3",
        inputs={
            "uncertainty_px": u,
            "flags": flags,
            "good_px": GOOD_UNCERTAINTY_PX,
            "good_fraction": GOOD_FRACTION,
        },
        expected=key,
        parse=_parts(fraction=_scalar("the fraction"), good=parse_bool),
        compare=compare,
        wrong=[
            (
                lambda a: abs(a["fraction"] - fraction) <= 1e-6 and bool(flags) and bool(a["good"]),
                "the uncertainty is small enough, but the coach has a warning: fix it first",
            ),
            (
                lambda a: abs(a["fraction"] - fraction) <= 1e-6 and a["good"] != good,
                "the fraction is right; compare it with good_fraction (and look at the warnings) for the verdict",
            ),
            (
                lambda a: abs(a["fraction"] - 100 * fraction) <= 1e-4,
                "that is a percentage: the fraction is a number from 0 to 1",
            ),
            (
                lambda a: abs(a["fraction"] - median_share) <= 1e-6 and abs(median_share - fraction) > 1e-6,
                "that compares the cells with the map's median, not with good_px",
            ),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Where will the marker be in the next frame?",
    "task": """
        MarkerTracker looks for each marker near where it expects it. The camera's poses in the last
        two frames are `T_world_camera_prev` and `T_world_camera_last` (4x4, mm). Assume it keeps
        moving as it did between them (the same relative motion once more, in the camera's own frame)
        and predict where the world point `point_mm` (3,) appears in the next frame: its pixel (2,),
        with the camera matrix `K` (no distortion).
        """,
    "hint": [
        "First the motion between the two frames, as a transform from the last camera frame's point of view.",
        (
            "The motion is the relative transform from the previous pose to the last; apply it once more after "
            "the last pose. Then project as in notebook 01, from the world into the PREDICTED camera frame."
        ),
    ],
    "solution": """
        d = q4.inputs
        T_prev, T_last = np.asarray(d.T_world_camera_prev), np.asarray(d.T_world_camera_last)
        step = np.linalg.inv(T_prev) @ T_last          # the last frame's motion, in the camera's frame
        T_next = T_last @ step                          # once more
        p = np.linalg.inv(T_next) @ np.append(d.point_mm, 1.0)
        uvw = np.asarray(d.K) @ p[:3]
        q4.answer = uvw[:2] / uvw[2]
        """,
    "level": "medium",
}


def _project(K: np.ndarray, T_world_camera: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Pixel of a world point seen from a camera pose (pinhole, no distortion)."""
    p = np.linalg.inv(T_world_camera) @ np.append(point, 1.0)
    uvw = K @ p[:3]
    return uvw[:2] / uvw[2]


def _q4(learner: str) -> Question:
    """q4: Where will the marker be in the next frame?"""
    rng = _rng_for(learner, "q4")
    w, h = 640, 480
    f = float(np.round(rng.uniform(450, 700)))
    K = np.array([[f, 0, w / 2 - 0.5], [0, f, h / 2 - 0.5], [0, 0, 1.0]])
    while True:
        eye = rng.uniform([1500, -800, 600], [3500, 800, 1500])
        target = rng.uniform([0, -300, 800], [0, 300, 1400])
        T_last = look_at(np.round(eye), np.round(target))
        step = frames.make_transform(
            frames.rotation_from_rpy_deg(*rng.uniform(-4, 4, size=3)), rng.uniform(-60, 60, size=3)
        )
        T_prev = T_last @ frames.invert_transform(step)
        point = np.round(target + rng.uniform([0, -400, -300], [0, 400, 300]))
        T_next = T_last @ np.linalg.inv(T_prev) @ T_last
        key = _project(K, T_next, point)
        stay = _project(K, T_last, point)
        back = _project(K, T_prev, point)
        slide = _project(K, frames.make_transform(T_last[:3, :3], 2 * T_last[:3, 3] - T_prev[:3, 3]), point)
        inside = all(0 < v[0] < w and 0 < v[1] < h for v in (key, stay, back))
        apart = min(np.linalg.norm(key - v) for v in (stay, back, slide)) > 5
        if inside and apart:
            break
    return Question(
        "q4",
        inputs={"T_world_camera_prev": T_prev, "T_world_camera_last": T_last, "point_mm": point, "K": K},
        expected=key,
        parse=_array((2,), "the pixel", {(3,): "give the pixel (u, v): divide by the third coordinate"}),
        compare=_cmp_array(0.5, " px"),
        wrong=[
            (
                lambda a: _close(a, stay, 0.5),
                "that is where the point is in the LAST frame: the camera keeps moving, apply its motion once more",
            ),
            (
                lambda a: _close(a, back, 0.5),
                "that is the previous frame's pixel: the motion was applied backwards (prev to last, not last to prev)",
            ),
            (
                lambda a: _close(a, slide, 0.5),
                "only the position moved on: the camera also turned between the frames, and keeps turning",
            ),
        ],
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 12 for one learner, in notebook order.

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
