"""Lesson 15: Wide lenses: the fisheye model.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("15", learner, "qN")``), so a learner's variant of one question
does not depend on the others. The lens is OpenCV's fisheye model (Kannala-Brandt):
``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)``, ``r = f theta_d``.
"""

from __future__ import annotations

import numpy as np

from .._engine import Question, QuestionText
from .._parsers import _array, _close, _cmp_array, _cmp_scalar, _scalar
from .._scenery import _rng

NUMBER = "15"
TOPIC = "wide_lenses"
TITLE = "Wide lenses: the fisheye model"
INTRO = """
    A fisheye lens sees too wide for the pinhole model. Project a ray through the Kannala-Brandt
    model, choose the camera an undistorted picture should have, and read whether two calibrations
    differ by more than their noise.
    """


def _kb_pixel(point: np.ndarray, K: np.ndarray, D: np.ndarray) -> np.ndarray:
    """The pixel (2,) of a camera-frame point (3,) through the fisheye model."""
    x, y, z = point
    rho = np.hypot(x, y)
    th = np.arctan2(rho, z)
    th_d = th * (1 + D[0] * th**2 + D[1] * th**4 + D[2] * th**6 + D[3] * th**8)
    return np.array([K[0, 0] * th_d * x / rho + K[0, 2], K[1, 1] * th_d * y / rho + K[1, 2]])


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "A ray through the fisheye model",
    "task": """
        A fisheye camera has the intrinsics `K` (3x3, px) and the four coefficients `dist` (k1..k4)
        of OpenCV's fisheye model; `point` (3,) is a point in the camera's frame (mm), far from the
        optical axis. Write code that computes its pixel (u, v) with the Kannala-Brandt model, as in
        notebook 15 (not with the pinhole model).
        """,
    "hint": [
        "The fisheye model works with the angle between the ray and the optical axis, not with x/z and y/z.",
        (
            "Find that angle, bend it with the odd polynomial of the four coefficients, scale it by the focal "
            "lengths in the direction of (x, y) from the axis, and add the principal point."
        ),
    ],
    "solution": """
        d = q1.inputs
        x, y, z = d.point
        rho = np.hypot(x, y)
        th = np.arctan2(rho, z)
        k1, k2, k3, k4 = d.dist
        th_d = th * (1 + k1 * th**2 + k2 * th**4 + k3 * th**6 + k4 * th**8)
        q1.answer = [d.K[0, 0] * th_d * x / rho + d.K[0, 2], d.K[1, 1] * th_d * y / rho + d.K[1, 2]]
        """,
    "level": "medium",
}


def _q1(learner: str) -> Question:
    """q1: A ray through the fisheye model."""
    rng = _rng(NUMBER, learner, "q1")
    size = (800, 600)
    while True:  # a ray 50 to 85 degrees off the axis whose pixel is inside the picture
        f = float(np.round(rng.uniform(240, 300), 1))
        K = np.array([[f, 0.0, np.round(rng.uniform(390, 410), 1)], [0.0, f, np.round(rng.uniform(290, 310), 1)]])
        K = np.vstack([K, [0.0, 0.0, 1.0]])
        D = np.round(np.array([rng.uniform(-0.06, -0.02), rng.uniform(-0.03, 0.01), rng.uniform(-0.01, 0.01), 0.0]), 4)
        D[3] = np.round(rng.uniform(-0.003, 0.003), 4)
        theta, phi = np.radians(rng.uniform(50, 85)), rng.uniform(-np.pi, np.pi)
        distance = rng.uniform(500, 3000)
        point = np.round(distance * np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]))
        key = _kb_pixel(point, K, D)
        c = K[:2, 2]
        pinhole = K[:2, :2] @ (point[:2] / point[2]) + c
        equidistant = _kb_pixel(point, K, np.zeros(4))
        ts = np.linspace(0.0, theta, 50)  # a real lens: the bent angle rises all the way out to the ray
        rising = np.all(np.diff(ts * (1 + D[0] * ts**2 + D[1] * ts**4 + D[2] * ts**6 + D[3] * ts**8)) > 0)
        inside = np.all((key > 5) & (key < np.array(size) - 5))
        if inside and rising and np.linalg.norm(key - equidistant) > 1.0 and np.linalg.norm(key - pinhole) > 5.0:
            break
    no_centre = key - c
    return Question(
        "q1",
        inputs={"K": K, "dist": D, "point": point, "image_size": size},
        expected=key,
        parse=_array((2,), "the pixel (u, v)"),
        compare=_cmp_array(0.05, " px"),
        wrong=[
            (
                lambda a: _close(a, pinhole, 1.0),
                "that is the pinhole's f x/z: the fisheye model bends the angle from the axis, not x/z",
            ),
            (
                lambda a: _close(a, equidistant, 0.05),
                "that is the plain equidistant lens (r = f theta): bend the angle with the four coefficients first",
            ),
            (
                lambda a: _close(a, no_centre, 0.05),
                "measured from the principal point: add (cx, cy) to get the pixel",
            ),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "The camera of an undistorted picture",
    "task": """
        A fisheye picture is to be undistorted (remapped) into a pinhole picture `width` pixels wide
        (pixel centres at 0 .. width - 1), with its principal point in the middle, that keeps
        `fov_deg` degrees across its width. Write code that computes the focal length fx (px) that
        new camera must have.
        """,
    "hint": [
        "The new picture is a pinhole picture: a ray at angle theta lands f tan(theta) from its principal point.",
        (
            "The outermost pixel centre of each side is half of (width - 1) from the middle and must hold the ray "
            "at half the field of view; mind the angle's unit."
        ),
    ],
    "solution": """
        d = q2.inputs
        q2.answer = (d.width - 1) / 2 / np.tan(np.radians(d.fov_deg / 2))
        """,
    "level": "easy",
}


def _q2(learner: str) -> Question:
    """q2: The camera of an undistorted picture."""
    rng = _rng(NUMBER, learner, "q2")
    while True:  # every listed mistake far from the key and from the others (tan(70 rad) is close to 70 degrees')
        width = int(rng.choice([640, 800, 1024, 1280]))
        fov = float(np.round(rng.uniform(100, 160)))
        half = np.radians(fov / 2)
        key = (width - 1) / 2 / np.tan(half)
        equidistant = (width - 1) / 2 / half
        whole_angle = (width - 1) / 2 / np.tan(2 * half)
        values = [key, equidistant, whole_angle, (width - 1) / 2 / np.tan(fov / 2), (width - 1) / np.tan(half)]
        if min(abs(a - b) for i, a in enumerate(values) for b in values[i + 1 :]) > 2.0:
            break
    return Question(
        "q2",
        inputs={"width": width, "fov_deg": fov},
        expected=float(key),
        parse=_scalar("fx"),
        compare=_cmp_scalar(0.5, " px"),
        wrong=[
            (
                lambda a: abs(a - equidistant) <= 0.5,
                "that is the fisheye's own r = f theta; the undistorted picture is a pinhole picture: r = f tan(theta)",
            ),
            (
                lambda a: abs(a - whole_angle) <= 0.5 or abs(a - (width - 1) / np.tan(2 * half)) <= 0.5,
                "the whole field of view spans the whole width: half the width holds half the angle",
            ),
            (
                lambda a: abs(a - (width - 1) / 2 / np.tan(fov / 2)) <= 0.5,
                "np.tan takes radians",
            ),
            (
                lambda a: abs(a - (width - 1) / np.tan(half)) <= 0.5,
                "from the middle to the edge is half the width",
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Beyond the noise?",
    "task": """
        Two calibrations of one lens were compared at N pixels across the picture: `difference_px`
        (N, 2) is where the second puts what the first sees there, minus the pixel, and `sigma_px`
        (N,) is the standard deviation of that difference along each axis expected from both
        calibrations' noise (the same along x and y, independent). Write code that computes the
        comparison's ratio, as compare_calibrations does: the RMS over the pixels of each difference
        measured in its own standard deviations, per axis (about 1 when the two agree).
        """,
    "hint": [
        "Measure each pixel's difference in its own standard deviations before averaging anything.",
        (
            "Each pixel gives a squared length in units of its sigma; average those over the pixels, and "
            "remember each one holds two axes before taking the root."
        ),
    ],
    "solution": """
        d = q3.inputs
        m2 = np.sum(np.asarray(d.difference_px) ** 2, axis=1) / np.asarray(d.sigma_px) ** 2
        q3.answer = np.sqrt(np.mean(m2) / 2)
        """,
    "level": "medium",
}


def _q3(learner: str) -> Question:
    """q3: Beyond the noise?"""
    rng = _rng(NUMBER, learner, "q3")
    n = 12
    while True:  # sigmas that differ across the picture, so that dividing the averages is wrong
        sigma = np.round(rng.uniform(0.2, 2.5, n), 2)
        scale = float(rng.choice([0.7, 1.0, 1.5, 2.5, 4.0]))
        diff = np.round(rng.normal(0.0, 1.0, (n, 2)) * sigma[:, None] * scale, 3)
        m2 = np.sum(diff**2, axis=1) / sigma**2
        key = float(np.sqrt(np.mean(m2) / 2))
        others = [
            float(np.sqrt(np.mean(m2))),  # both axes as one
            float(np.sqrt(np.mean(np.sum(diff**2, axis=1)) / 2) / np.sqrt(np.mean(sigma**2))),  # averages divided
            float(np.mean(np.sqrt(m2 / 2))),  # a mean of lengths, not an RMS
        ]
        values = [key, *others]
        gaps = [abs(a - b) for i, a in enumerate(values) for b in values[i + 1 :]]
        if min(gaps) > 0.05 * key + 0.02:  # each mistake is told apart from the key and from the others
            break
    return Question(
        "q3",
        inputs={"difference_px": diff, "sigma_px": sigma},
        expected=key,
        parse=_scalar("the ratio"),
        compare=_cmp_scalar(0.01),
        wrong=[
            (
                lambda a: abs(a - others[0]) <= 0.01,
                "each pixel's squared length holds two axes: per axis, divide its mean by 2 before the root",
            ),
            (
                lambda a: abs(a - others[1]) <= 0.01,
                "that divides the RMS difference by the RMS sigma: measure each pixel in its own sigma first",
            ),
            (
                lambda a: abs(a - others[2]) <= 0.01,
                "that averages the lengths; the ratio is a root of the mean of the squares",
            ),
        ],
        **_Q3,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 15 for one learner, in notebook order.

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
