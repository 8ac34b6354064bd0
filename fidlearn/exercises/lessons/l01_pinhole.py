"""Lesson 01: The pinhole camera and K.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("01", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ...camera import Camera
from .._engine import Detector, Question, QuestionText
from .._parsers import (
    _array,
    _close,
    _cmp_array,
    _cmp_scalar,
    _scalar,
)
from .._scenery import (
    _SIZES,
    _rng,
)

NUMBER = "01"
TOPIC = "pinhole"
TITLE = "The pinhole camera and K"
INTRO = """
    The pinhole model in code: build the intrinsic matrix K from a field of view, project points
    with it, and use similar triangles to measure distance from a marker's apparent size.
    """


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "K from a diagonal field of view",
    "task": """
        A phone's data sheet gives its camera's field of view the way phone makers do: DIAGONALLY,
        `dfov_deg` degrees from one corner of the picture to the opposite one. Its pictures are
        `image_size` = (width, height) pixels, its pixels are square and its principal point is in
        the middle. Write code that computes its intrinsic matrix K, a (3, 3) array
        `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]` in pixels. fidlearn puts pixel centres at integer
        coordinates, so the centre of the image is at ((width - 1) / 2, (height - 1) / 2).
        (`Camera.from_fov` takes the horizontal field of view: it does not answer this one.)
        """,
    "hint": [
        "Draw the right triangle from the pinhole to the image's corner: the angle at the pinhole is half the field "
        "of view, and the side opposite it lies in the image plane.",
        "The side opposite half the diagonal field of view is half the image's diagonal, in pixels; the side next "
        "to it is the focal length in pixels. Angles go to np.tan in radians.",
    ],
    "solution": """
        w, h = q1.inputs.image_size
        half_diagonal = np.hypot(w, h) / 2                  # pixels, in the image plane
        f = half_diagonal / np.tan(np.radians(q1.inputs.dfov_deg) / 2)
        K = np.array([[f, 0, (w - 1) / 2],
                      [0, f, (h - 1) / 2],
                      [0, 0, 1]])
        q1.answer = K
        """,
    "level": "medium",
}


def _fx_is(value: float) -> Detector:
    """A detector: the answer's fx is ``value``."""
    return lambda a: abs(a[0, 0] - value) <= 1e-3 * abs(value) + 0.01


def _compare_K(a: np.ndarray, b: np.ndarray) -> str | None:
    """q1's comparison: fx, fy within 0.1 %, cx, cy within half a pixel, the zeros and the 1 exact."""
    return (
        None
        if (
            abs(a[0, 0] - b[0, 0]) <= 1e-3 * b[0, 0]
            and abs(a[1, 1] - b[1, 1]) <= 1e-3 * b[1, 1]
            and abs(a[0, 2] - b[0, 2]) <= 0.51
            and abs(a[1, 2] - b[1, 2]) <= 0.51
            and np.abs(a[[0, 1, 2, 2, 2], [1, 0, 0, 1, 2]] - [0, 0, 0, 0, 1]).max() < 1e-9
        )
        else _cmp_array(0.01, " px")(a, b)
    )


def _q1_mistakes(w: int, h: int, dfov: float, f: float, K: np.ndarray) -> list:
    """The mistakes q1 names: (detector, message) pairs, in the order they are tried."""
    d = math.hypot(w, h)
    half = math.radians(dfov) / 2
    return [
        (
            lambda a: _close(a, K.T, 0.51),
            (
                "your K is transposed: cx and cy belong in the last COLUMN, [[fx, 0, cx], [0, fy, cy], [0, "
                "0, 1]], and the bottom row is [0, 0, 1]"
            ),
        ),
        (
            _fx_is((w / 2) / math.tan(half)),
            (
                "that takes the diagonal field of view for the horizontal one (as Camera.from_fov(dfov_deg, ...) "
                "would): the angle spans the image's DIAGONAL, sqrt(w^2 + h^2), so tan(dfov/2) = (diagonal/2) / f"
            ),
        ),
        (
            _fx_is((d / 2) / math.tan(dfov / 2)),
            (
                "np.tan and math.tan take radians, and dfov_deg is in degrees: convert with np.radians (or "
                "math.radians) first"
            ),
        ),
        (
            _fx_is((d / 2) / math.tan(2 * half)),
            (
                "use HALF the field of view: the right triangle has half the diagonal opposite the angle "
                "dfov/2, so tan(dfov/2) = (diagonal/2) / f"
            ),
        ),
        (_fx_is(d / math.tan(half)), "use HALF the image's diagonal: tan(dfov/2) = (diagonal/2) / f"),
        (
            _fx_is((h / 2) / math.tan(half)),
            "the diagonal field of view goes with the image's DIAGONAL, sqrt(w^2 + h^2), not its height",
        ),
        (
            _fx_is(((w + h) / 2) / math.tan(half)),
            "the diagonal is sqrt(w^2 + h^2) (Pythagoras), not w + h: half of it is opposite dfov/2",
        ),
        (lambda a: abs(a[0, 0] - f) < 1e-3 * f and abs(a[1, 1] - f) > 1e-3 * f, "square pixels: fy equals fx"),
        (
            lambda a: abs(a[0, 0] - f) < 1e-3 * f and (abs(a[0, 2] - (h - 1) / 2) < 0.51 or abs(a[0, 2]) < 1e-9),
            "fx is right; now put cx = (width - 1) / 2 and cy = (height - 1) / 2 (image_size is (width, height))",
        ),
    ]


def _q1(learner: str) -> Question:
    """q1: K from a diagonal field of view."""
    rng = _rng("01", learner, "q1")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    dfov = float(np.round(rng.uniform(60, 100) * 2) / 2)
    f = (math.hypot(w, h) / 2) / math.tan(math.radians(dfov) / 2)
    K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
    return Question(
        "q1",
        inputs={"dfov_deg": dfov, "image_size": (w, h)},
        expected=K,
        parse=_array(
            (3, 3), "K", {(3,): "that is a vector; K is a 3x3 matrix", (4, 4): "K is 3x3, not a 4x4 transform"}
        ),
        compare=_compare_K,
        wrong=_q1_mistakes(w, h, dfov, f, K),
        notes=[
            (
                lambda a: abs(a[0, 2] - K[0, 2]) > 0.25 or abs(a[1, 2] - K[1, 2]) > 0.25,
                (
                    "K is right; note that with pixel centres at integer coordinates fidlearn puts cx at (width "
                    "- 1) / 2, half a pixel left of width / 2"
                ),
            )
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "Project points with K",
    "task": """
        `points_camera_mm` holds 5 points (N, 3) in the camera frame (OpenCV's: x right, y down,
        z forward), in mm. Write code that projects them with the pinhole model and the intrinsic
        matrix `K` (no distortion) and gives their pixel coordinates, an (N, 2) array of (u, v).
        """,
    "hint": [
        "A point twice as far away lands twice as close to the image centre: the depth divides.",
        (
            "Each coordinate is scaled by the focal length after dividing by the depth, then moved by the "
            "principal point; in matrix form that is K times the point, followed by the division by its third "
            "entry."
        ),
    ],
    "solution": """
        P = q2.inputs.points_camera_mm                      # (N, 3) mm, camera frame
        ph = P @ q2.inputs.K.T                              # rows of K @ p
        q2.answer = ph[:, :2] / ph[:, 2:3]                  # divide by the depth
        """,
    "level": "easy",
}


def _q2(learner: str) -> Question:
    """q2: Project points with K."""
    rng = _rng("01", learner, "q2")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 85))), (w, h))
    K2 = cam.K.copy()
    K2[0, 2] += float(np.round(rng.uniform(-15, 15), 1))
    K2[1, 2] += float(np.round(rng.uniform(-10, 10), 1))
    n = 5
    z = rng.uniform(800, 3000, n)
    u = rng.uniform(0.1 * w, 0.9 * w, n)
    v = rng.uniform(0.1 * h, 0.9 * h, n)
    P = np.column_stack([(u - K2[0, 2]) / K2[0, 0] * z, (v - K2[1, 2]) / K2[1, 1] * z, z])
    P = np.round(P, 1)
    uv = (P @ K2.T)[:, :2] / P[:, 2:]
    no_div = (P @ K2.T)[:, :2]
    kt = (P @ K2)[:, :2] / (P @ K2)[:, 2:]
    no_c = P[:, :2] * [K2[0, 0], K2[1, 1]] / P[:, 2:]
    return Question(
        "q2",
        inputs={"K": K2, "points_camera_mm": P},
        expected=uv,
        parse=_array(
            (n, 2),
            "the pixels",
            {
                (n, 3): "drop the third (homogeneous) coordinate after dividing by it",
                (2, n): "one ROW per point, please: transpose it",
            },
        ),
        compare=_cmp_array(0.05, " px"),
        wrong=[
            (
                lambda a: _close(a, no_div, 0.05),
                "divide by the depth: after K @ p, divide u and v by the third coordinate (it is Z)",
            ),
            (
                lambda a: _close(a, uv[:, ::-1], 0.05),
                "the columns are swapped: u (the x pixel, to the right) comes first, then v (down)",
            ),
            (
                lambda a: _close(a, kt, 0.05),
                "K is used transposed: the pixel is K @ p (with p as a column), i.e. p @ K.T for rows of points",
            ),
            (lambda a: _close(a, no_c, 0.05), "add the principal point: u = fx * X / Z + cx, v = fy * Y / Z + cy"),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "How far is the marker?",
    "task": """
        A square marker `marker_size_in` inches wide faces the camera squarely, in the middle of the
        image, and appears `side_px` pixels wide. The camera's intrinsics are in `camera`
        (a fidlearn Camera: `camera.fx`, `camera.K`). Write code that computes the distance from
        the camera to the marker along the optical axis, in millimetres.
        """,
    "hint": [
        (
            "Similar triangles: the marker's real size and its size on the image stand in the same ratio as two "
            "distances from the pinhole. Which two?"
        ),
        (
            "On the image side the distance is the focal length in pixels; on the world side it is the depth you "
            "want. Convert inches to mm (25.4 mm per inch) first."
        ),
    ],
    "solution": """
        size_mm = q3.inputs.marker_size_in * 25.4
        q3.answer = q3.inputs.camera.fx * size_mm / q3.inputs.side_px
        """,
    "level": "easy",
}


def _q3(learner: str) -> Question:
    """q3: How far is the marker?."""
    rng = _rng("01", learner, "q3")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    cam3 = Camera.from_fov(float(np.round(rng.uniform(55, 85))), (w, h))
    size_in = float(rng.choice([4, 5, 6, 8]))
    dist_mm = float(rng.uniform(700, 4000))
    side_px = float(np.round(cam3.fx * size_in * 25.4 / dist_mm, 1))
    d = cam3.fx * size_in * 25.4 / side_px
    return Question(
        "q3",
        inputs={"camera": cam3, "marker_size_in": size_in, "side_px": side_px},
        expected=d,
        parse=_scalar("the distance"),
        compare=_cmp_scalar(0, " mm", rtol=2e-3),
        wrong=[
            (
                lambda a: abs(a * 25.4 - d) <= 3e-3 * d,
                (
                    "that is the distance in inches: the answer is asked in mm (1 in = 25.4 mm); convert the "
                    "marker size first"
                ),
            ),
            (
                lambda a: abs(a * 304.8 - d) <= 3e-3 * d,
                "that is the distance in feet (304.8x too small): the answer is asked in mm",
            ),
            (lambda a: abs(a * 1000 - d) <= 3e-3 * d, "that is in metres: the answer is asked in mm"),
            (lambda a: abs(a * 10 - d) <= 3e-3 * d, "that is in cm: the answer is asked in mm"),
            (
                lambda a: abs(a - cam3.fx * size_in / side_px) <= 3e-3 * d,
                "the marker size is in inches: convert it to mm (x 25.4) before using it",
            ),
            (
                lambda a: a < 1 or abs(a - side_px / (cam3.fx * size_in * 25.4)) < 1e-6,
                "the ratio is upside down: similar triangles give Z / size = fx / side_px",
            ),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Field of view from K",
    "task": """
        Given the intrinsic matrix `K` of a camera and its `image_size` (width, height), write code
        that computes its horizontal and vertical fields of view in degrees, as a pair
        (hfov_deg, vfov_deg).
        """,
    "hint": [
        "Run q1 backwards: the same right triangle, now solved for the angle.",
        (
            "Half the image's width is opposite half the horizontal field of view and fx is next to it; the "
            "vertical one uses the height and fy. The answer is asked in degrees."
        ),
    ],
    "solution": """
        K = q4.inputs.K
        w, h = q4.inputs.image_size
        hfov = np.degrees(2 * np.arctan((w / 2) / K[0, 0]))
        vfov = np.degrees(2 * np.arctan((h / 2) / K[1, 1]))
        q4.answer = (hfov, vfov)
        """,
    "level": "easy",
}


def _q4(learner: str) -> Question:
    """q4: Field of view from K."""
    rng = _rng("01", learner, "q4")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    fx = float(np.round(rng.uniform(0.5, 1.2) * w, 1))
    K4 = np.array([[fx, 0, (w - 1) / 2], [0, fx, (h - 1) / 2], [0, 0, 1]])
    fov = np.degrees([2 * math.atan(w / (2 * fx)), 2 * math.atan(h / (2 * fx))])
    return Question(
        "q4",
        inputs={"K": K4, "image_size": (w, h)},
        expected=fov,
        parse=_array((2,), "(hfov_deg, vfov_deg)"),
        compare=_cmp_array(0.05, " deg"),
        wrong=[
            (
                lambda a: _close(np.degrees(a), fov, 0.05),
                "those are radians: the answer is asked in degrees (np.degrees)",
            ),
            (
                lambda a: _close(a, fov[::-1], 0.05),
                "the order is (horizontal, vertical): the width goes with the horizontal field of view",
            ),
            (
                lambda a: _close(a, fov / 2, 0.05),
                "that is the HALF angle: the field of view is 2 * atan((w/2) / fx)",
            ),
            (
                lambda a: _close(a, np.degrees([2 * math.atan(w / fx), 2 * math.atan(h / fx)]), 0.05),
                "use half the image size: fov = 2 * atan((w / 2) / fx)",
            ),
        ],
        **_Q4,
    )


#: q5's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q5: QuestionText = {
    "title": "Where a lens bends a point",
    "task": """
        A webcam's lens bends straight lines: its distortion `dist` = (k1, k2, p1, p2, k3) has
        only the radial terms k1 and k2. `points_camera_mm` holds 5 points (N, 3) in the camera
        frame, in mm. Write code that gives their pixels (N, 2) with the lens: divide by the depth
        (x = X / Z, y = Y / Z), bend radially, x_d = x * (1 + k1 r^2 + k2 r^4) with r^2 = x^2 + y^2
        (and y_d the same way), then u = fx x_d + cx, v = fy y_d + cy with `K`. Write the model
        out; check it against cv2.projectPoints afterwards if you like.
        """,
    "hint": [
        "Three steps in order: onto the plane at depth 1, bend there, then into pixels with K.",
        "The bend factor 1 + k1 r^2 + k2 r^4 is the same for x and y of one point, and r is measured on the "
        "plane at depth 1 (no pixels yet).",
    ],
    "solution": """
        P = q5.inputs.points_camera_mm
        K = q5.inputs.K
        k1, k2 = q5.inputs.dist[0], q5.inputs.dist[1]
        xy = P[:, :2] / P[:, 2:3]                          # the plane at depth 1
        r2 = np.sum(xy ** 2, axis=1, keepdims=True)
        xy_d = xy * (1 + k1 * r2 + k2 * r2 ** 2)            # the radial bend
        q5.answer = xy_d * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
        """,
    "level": "medium",
}


def _bent(P: np.ndarray, K: np.ndarray, k1: float, k2: float, r_of=lambda xy: xy) -> np.ndarray:
    """Pixels of camera-frame points through a radial lens; ``r_of`` says where r is measured (a mistake)."""
    xy = P[:, :2] / P[:, 2:3]
    r2 = np.sum(r_of(xy) ** 2, axis=1, keepdims=True)
    return xy * (1 + k1 * r2 + k2 * r2**2) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]


def _q5(learner: str) -> Question:
    """q5: Where a lens bends a point."""
    rng = _rng("01", learner, "q5")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    K = Camera.from_fov(float(np.round(rng.uniform(60, 80))), (w, h)).K
    k1, k2 = float(np.round(rng.uniform(-0.3, -0.12), 3)), float(np.round(rng.uniform(0.02, 0.08), 3))
    n = 5
    z = rng.uniform(800, 3000, n)
    u = np.concatenate([rng.uniform(0.05, 0.2, 2), rng.uniform(0.8, 0.95, 2), rng.uniform(0.4, 0.6, 1)]) * w
    v = rng.uniform(0.1 * h, 0.9 * h, n)
    P = np.round(np.column_stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z]), 1)
    dist = np.array([k1, k2, 0.0, 0.0, 0.0])
    key = cv2.projectPoints(P, np.zeros(3), np.zeros(3), K, dist)[0].reshape(-1, 2)
    pinhole = (P @ K.T)[:, :2] / P[:, 2:]
    return Question(
        "q5",
        inputs={"K": K, "dist": dist, "points_camera_mm": P},
        expected=key,
        parse=_array((n, 2), "the pixels", {(2, n): "one ROW per point, please: transpose it"}),
        compare=_cmp_array(0.05, " px"),
        wrong=[
            (
                lambda a: _close(a, pinhole, 0.05),
                (
                    "the distortion was ignored: those are the pinhole pixels. This lens bends the points at the "
                    "edges of the picture by several pixels: apply 1 + k1 r^2 + k2 r^4 on the plane at depth 1"
                ),
            ),
            (
                lambda a: _close(a, _bent(P, K, k1, k2, lambda xy: xy * [K[0, 0], K[1, 1]]), 0.05),
                "r is measured on the plane at depth 1 (x = X / Z), not in pixels: bend before K, not after",
            ),
            (
                lambda a: _close(a, _bent(P, K, k1, 0.0), 0.05),
                "k2 is missing: the bend is 1 + k1 r^2 + k2 r^4",
            ),
            (
                lambda a: _close(a, pinhole + (pinhole - key), 0.5),
                "that bends the points the other way: barrel distortion (k1 < 0) pulls them TOWARDS the centre",
            ),
        ],
        **_Q5,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 01 for one learner, in notebook order.

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
