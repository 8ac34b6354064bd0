"""Lesson 14: ChArUco boards.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("14", learner, "qN")``), so a learner's variant of one question
does not depend on the others. The boards are OpenCV's ``CharucoBoard`` layout (board frame: origin
at the top-left outer corner, x along the first row of squares, y down the board, mm), seen by a
pinhole camera of 1280 x 720 pixels.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from ..._cv_charuco import charuco_board
from .._engine import Question, QuestionText
from .._parsers import _array, _close, _cmp_array, _cmp_scalar, _scalar
from .._scenery import _rng

NUMBER = "14"
TOPIC = "charuco"
TITLE = "ChArUco boards"
INTRO = """
    A ChArUco board hides ArUco markers in the white squares of a chessboard. Predict a chess
    corner from one marker, find the marker the detector missed among the rejected quads (what
    refineDetectedMarkers does), and count what a ChArUco calibration has to work with.
    """

_IMAGE_SIZE = (1280, 720)


def _board(rng: np.random.Generator) -> tuple:
    """A board: squares (x, y), square and marker sides (mm), markers' corners (M, 4, 2), chess corners (C, 2), mm."""
    squares = (int(rng.integers(5, 8)), int(rng.integers(5, 9)))
    square = float(rng.choice([30.0, 35.0, 40.0, 50.0]))
    marker = float(np.round(square * rng.uniform(0.55, 0.75)))
    board = charuco_board(squares, square, marker, "6X6_250")
    markers = np.asarray(board.getObjPoints(), dtype=float).reshape(-1, 4, 3)[:, :, :2]
    chess = np.asarray(board.getChessboardCorners(), dtype=float).reshape(-1, 3)[:, :2]
    return squares, square, marker, markers, chess


def _view(rng: np.random.Generator, squares: tuple, square: float) -> tuple:
    """A pinhole K and a tilted pose of the board in front of it: (K, rvec, tvec), mm."""
    f = float(np.round(rng.uniform(800, 1100)))
    K = np.array([[f, 0.0, 640.0], [0.0, f, 360.0], [0.0, 0.0, 1.0]])
    tilt = np.deg2rad(rng.uniform(20, 40, 2) * rng.choice([-1, 1], 2))
    R = Rotation.from_euler("xyz", [tilt[0], tilt[1], rng.uniform(-0.5, 0.5)]).as_matrix()
    centre = np.array([squares[0] * square / 2, squares[1] * square / 2, 0.0])
    size = max(squares) * square
    t = np.array([rng.uniform(-0.1, 0.1) * size, rng.uniform(-0.1, 0.1) * size, rng.uniform(2.2, 3.0) * size])
    return K, cv2.Rodrigues(R)[0].ravel(), t - R @ centre


def _project(points_mm: np.ndarray, K: np.ndarray, rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """Board-plane points (..., 2), mm, to pixels (..., 2) through a pinhole camera."""
    flat = np.asarray(points_mm, dtype=float).reshape(-1, 2)
    obj = np.column_stack([flat, np.zeros(len(flat))])
    px = cv2.projectPoints(obj, rvec, tvec, K, None)[0].reshape(-1, 2)
    return px.reshape(np.shape(points_mm))


def _inside(px: np.ndarray) -> bool:
    p = np.asarray(px).reshape(-1, 2)
    return bool(np.all((p > 5) & (p < np.array(_IMAGE_SIZE) - 5)))


def _apply(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    q = H @ np.append(p, 1.0)
    return q[:2] / q[2]


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "A chess corner from one marker",
    "task": """
        One marker of a ChArUco board was detected: its four corners on the board, `marker_mm`
        (4, 2: x, y in the board's plane, mm, in the order TL, TR, BR, BL) and in the picture,
        `marker_px` (4, 2, the same order). The chess corner `corner_mm` (2,) is a corner of that
        marker's square. Write code that predicts where the chess corner is in the picture (2,),
        px, as OpenCV does before it refines a ChArUco corner (the camera's K is not known).
        """,
    "hint": [
        "The board is flat: a pinhole camera maps its plane to the picture by one 3x3 matrix, and four points "
        "fix that matrix.",
        (
            "Fit the plane-to-picture map from the four marker corners (OpenCV has a function for exactly four "
            "pairs), then carry the chess corner through it in homogeneous coordinates: a 1 appended, and the "
            "result divided by its last entry."
        ),
    ],
    "solution": """
        d = q1.inputs
        H = cv2.getPerspectiveTransform(d.marker_mm.astype(np.float32), d.marker_px.astype(np.float32))
        p = H @ np.append(d.corner_mm, 1.0)
        q1.answer = p[:2] / p[2]
        """,
    "level": "easy",
}


def _q1_scene(rng: np.random.Generator) -> tuple:
    while True:
        squares, square, _, markers, chess = _board(rng)
        K, rvec, tvec = _view(rng, squares, square)
        k = int(rng.integers(len(markers)))
        centre = markers[k].mean(axis=0)
        near = chess[np.linalg.norm(chess - centre, axis=1) < square * 0.75]
        if len(near) == 0:
            continue
        corner = near[int(rng.integers(len(near)))]
        marker_px = np.round(_project(markers[k], K, rvec, tvec), 3)
        H = cv2.getPerspectiveTransform(markers[k].astype(np.float32), marker_px.astype(np.float32))
        key = _apply(H, corner)
        plain = (H @ np.append(corner, 1.0))[:2]
        affine = cv2.getAffineTransform(markers[k][:3].astype(np.float32), marker_px[:3].astype(np.float32))
        three = affine @ np.append(corner, 1.0)
        far = all(np.linalg.norm(w - key) > 1.0 for w in (plain, three))
        if far and _inside(np.vstack([marker_px, key])):
            return markers[k], marker_px, corner, key, plain, three


def _q1(learner: str) -> Question:
    """q1: A chess corner from one marker."""
    rng = _rng(NUMBER, learner, "q1")
    marker_mm, marker_px, corner, key, plain, three = _q1_scene(rng)
    return Question(
        "q1",
        inputs={"marker_mm": marker_mm, "marker_px": marker_px, "corner_mm": corner},
        expected=key,
        parse=_array((2,), "the chess corner (u, v)"),
        compare=_cmp_array(0.05, " px"),
        wrong=[
            (
                lambda a: _close(a, plain, 0.05),
                "the homogeneous result was not divided by its last entry",
            ),
            (
                lambda a: _close(a, three, 0.05),
                "three corners fit an affine map, which cannot follow the board's tilt: use all four",
            ),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "The marker the detector missed",
    "task": """
        The detector read most markers of a ChArUco board: their corners on the board, `found_mm`
        (k, 4, 2, mm in the board's plane) and in the picture, `found_px` (k, 4, 2). It missed
        marker `missing_id`, whose corners on the board are `missing_mm` (4, 2), and rejected six
        quads, `candidates` (6, 4, 2, px; a quad's corners may start at any of its corners). Which
        candidate is marker `missing_id`? Answer its index in `candidates` (from 0). No K is given.
        """,
    "hint": [
        "The markers found tie the board's plane to the picture; that tie says where every other marker of the "
        "board must be.",
        (
            "Fit the plane-to-picture map from all the found corners at once (least squares over every pair), "
            "carry the missing marker's corners through it, and take the candidate whose corners land closest. "
            "Other quads on a ChArUco board are its black squares, a square's width away."
        ),
    ],
    "solution": """
        d = q2.inputs
        H, _ = cv2.findHomography(d.found_mm.reshape(-1, 2), d.found_px.reshape(-1, 2))
        where = cv2.perspectiveTransform(d.missing_mm.reshape(-1, 1, 2), H).reshape(4, 2)
        q2.answer = int(np.argmin([np.linalg.norm(c.mean(axis=0) - where.mean(axis=0)) for c in d.candidates]))
        """,
    "level": "medium",
}

#: Candidate quads offered in q2.
_Q2_N = 6


def _black_squares(squares: tuple, square: float) -> list[np.ndarray]:
    """Every black square's corners (4, 2), mm; OpenCV's layout puts a black square at the top-left."""
    out = []
    for row in range(squares[1]):
        for col in range(squares[0]):
            if (row + col) % 2 == 0:
                x, y = col * square, row * square
                out.append(np.array([[x, y], [x + square, y], [x + square, y + square], [x, y + square]]))
    return out


def _q2_scene(rng: np.random.Generator) -> tuple:
    while True:
        squares, square, _, markers, _ = _board(rng)
        K, rvec, tvec = _view(rng, squares, square)
        outline = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) * np.array(squares) * square
        if _inside(_project(outline, K, rvec, tvec)):
            return squares, square, markers, K, rvec, tvec


def _q2(learner: str) -> Question:
    """q2: The marker the detector missed."""
    rng = _rng(NUMBER, learner, "q2")
    squares, square, markers, K, rvec, tvec = _q2_scene(rng)
    missing, other = (int(i) for i in rng.choice(len(markers), size=2, replace=False))
    found = [i for i in range(len(markers)) if i not in (missing, other)]
    blacks = _black_squares(squares, square)
    picks = [markers[missing], markers[other]] + [blacks[int(i)] for i in rng.choice(len(blacks), _Q2_N - 2, False)]
    quads = []
    for quad_mm in picks:
        px = _project(quad_mm, K, rvec, tvec) + rng.normal(0, 0.2, (4, 2))
        quads.append(np.roll(px, int(rng.integers(4)), axis=0))
    order = rng.permutation(_Q2_N)
    candidates = np.round(np.array([quads[i] for i in order]), 2)
    key = int(np.flatnonzero(order == 0)[0])
    other_at = int(np.flatnonzero(order == 1)[0])
    return Question(
        "q2",
        inputs={
            "found_mm": markers[found],
            "found_px": np.round(_project(markers[found], K, rvec, tvec), 2),
            "missing_id": missing,
            "missing_mm": markers[missing],
            "candidates": candidates,
        },
        expected=float(key),
        parse=_scalar("the candidate's index"),
        compare=lambda a, b: None if abs(a - b) < 0.5 else f"that quad is not where the board puts marker {missing}",
        wrong=[
            (
                lambda a: int(round(a)) == other_at,
                f"that quad is where the board puts marker {other}, the other one missed: carry the corners of "
                f"marker {missing} (missing_mm) through the map",
            ),
            (
                lambda a: int(round(a)) == key + 1,
                "the indices start at 0: candidates[0] is the first",
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "What a ChArUco calibration has to work with",
    "task": """
        A ChArUco calibration found `corners_per_view` (n,) chess corners in n photos; views with
        fewer than `min_corners` corners are left out. The camera is fitted with fx, fy, cx, cy and
        `n_dist` distortion coefficients, and every view used has its own pose. How many more
        equations than unknowns does the fit have (its redundancy: the number of residuals minus
        the number of unknowns)?
        """,
    "hint": [
        "Count the two sides separately: what every detected corner contributes, and what every view used and "
        "the camera itself add to the unknowns.",
        (
            "A corner is a point in the picture: two coordinates, two residuals. A pose is a rotation and a "
            "translation. The views under the minimum bring neither residuals nor a pose."
        ),
    ],
    "solution": """
        d = q3.inputs
        used = [n for n in d.corners_per_view if n >= d.min_corners]
        q3.answer = 2 * sum(used) - (4 + d.n_dist + 6 * len(used))
        """,
    "level": "easy",
}


def _q3(learner: str) -> Question:
    """q3: What a ChArUco calibration has to work with."""
    rng = _rng(NUMBER, learner, "q3")
    min_corners = int(rng.choice([6, 8]))
    n_dist = int(rng.choice([4, 5]))
    while True:
        n = int(rng.integers(5, 10))
        counts = rng.integers(min_corners, 25, n)
        short = rng.choice(n, size=int(rng.integers(1, 3)), replace=False)
        counts[short] = rng.integers(4, min_corners, len(short))
        used = counts[counts >= min_corners]
        key = 2 * int(used.sum()) - (4 + n_dist + 6 * len(used))
        every = 2 * int(counts.sum()) - (4 + n_dist + 6 * n)
        single = int(used.sum()) - (4 + n_dist + 6 * len(used))
        no_pose = 2 * int(used.sum()) - (4 + n_dist)
        if len({key, every, single, no_pose}) == 4 and key > 0:
            break
    return Question(
        "q3",
        inputs={"corners_per_view": counts.astype(int), "min_corners": min_corners, "n_dist": n_dist},
        expected=float(key),
        parse=_scalar("the redundancy"),
        compare=_cmp_scalar(0.5),
        wrong=[
            (lambda a: abs(a - every) < 0.5, "the views with fewer than min_corners corners are left out of the fit"),
            (lambda a: abs(a - single) < 0.5, "each corner gives two residuals, one in u and one in v"),
            (lambda a: abs(a - no_pose) < 0.5, "every view used adds its own pose: six unknowns"),
        ],
        **_Q3,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 14 for one learner, in notebook order.

    Parameters
    ----------
    learner : str
        The learner's id; it seeds every question's numbers (``""``: the class's shared variant).

    Returns
    -------
    list of Question
        q1, q2, q3, with their answer keys.
    """
    return [_q1(learner), _q2(learner), _q3(learner)]
