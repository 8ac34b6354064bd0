"""Lesson 02: Calibration.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("02", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ... import frames
from ...boards import Board
from ...camera import Camera
from ...frames import look_at
from .._engine import Question, QuestionText, _AnswerError
from .._parsers import (
    _array,
    _close,
    _cmp_array,
    _scalar,
)
from .._scenery import (
    _SIZES,
    _rng,
)

NUMBER = "02"
TOPIC = "calibration"
TITLE = "Calibration"
INTRO = """
    From checkerboard corners to K: build the board's object points, run cv2.calibrateCamera, find
    the picture that does not belong, and carry K to another resolution.
    """


def _calibration_views(
    rng: np.random.Generator, camera: Camera, obj: np.ndarray, n_views: int, noise_px: float
) -> list:
    """Pixel corners (N, 2) of a board seen from n_views varied poses, with Gaussian noise."""
    centre = obj.mean(axis=0)
    extent = float(np.ptp(obj[:, 0]))
    views: list[np.ndarray] = []
    while len(views) < n_views:
        dist = extent * rng.uniform(1.6, 3.0)
        direction = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), -1.0])
        eye = centre + dist * direction / np.linalg.norm(direction)
        T = look_at(eye, centre + [rng.uniform(-0.3, 0.3) * extent, rng.uniform(-0.2, 0.2) * extent, 0], up=(0, -1, 0))
        T = T @ frames.make_transform(frames.rot_z(math.radians(rng.uniform(-20, 20))))
        px = camera.project(obj, T)
        if np.all(camera.points_in_front(obj, T)) and np.all((px > 5) & (px < np.array(camera.image_size) - 6)):
            views.append(np.round(px + rng.normal(0, noise_px, px.shape), 3))
    return views


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "The board's object points",
    "task": """
        Your checkerboard has `pattern_size` = (columns, rows) INNER corners and squares of
        `square_size_in` inches. Write code that builds its object points for cv2.calibrateCamera:
        an (N, 3) float array in mm, z = 0, the first corner at the origin, in the order
        cv2.findChessboardCorners reports corners: along a row first (x grows fastest), then the
        next row (y grows).
        """,
    "hint": (
        "np.mgrid[0:rows, 0:cols] gives row and column indices; x = column * square_mm, y = row * square_mm, z = 0."
    ),
    "solution": """
        cols, rows = q1.inputs.pattern_size
        square_mm = q1.inputs.square_size_in * 25.4
        obj = np.zeros((cols * rows, 3))
        obj[:, 0] = np.tile(np.arange(cols), rows) * square_mm     # x: along a row
        obj[:, 1] = np.repeat(np.arange(rows), cols) * square_mm   # y: row after row
        q1.answer = obj
        """,
    "level": "easy",
}


def _q1(learner: str) -> Question:
    """q1: The board's object points."""
    rng = _rng("02", learner, "q1")
    pattern = (int(rng.integers(6, 10)), int(rng.integers(4, 7)))
    square_in = float(rng.choice([0.75, 1.0, 1.25, 1.5]))
    obj = Board.checkerboard(pattern, square_in * 25.4).object_points()
    cols, rows = pattern
    col_major = np.array([[i, j, 0] for i in range(cols) for j in range(rows)], dtype=float) * square_in * 25.4
    return Question(
        "q1",
        inputs={"pattern_size": pattern, "square_size_in": square_in},
        expected=obj,
        parse=_array(
            (cols * rows, 3),
            "the object points",
            {
                (
                    (cols + 1) * (rows + 1),
                    3,
                ): "that counts the squares' corners on the outer border too: pattern_size counts the INNER corners",
                (cols * rows, 2): "add z = 0: object points are 3D",
            },
        ),
        compare=_cmp_array(0.01, " mm"),
        wrong=[
            (
                lambda a: _close(a * 25.4, obj, 0.01),
                "the square size is in inches: multiply by 25.4 to get mm (your values are 25.4x too small)",
            ),
            (
                lambda a: _close(a, col_major, 0.01),
                (
                    "the order is column by column; findChessboardCorners goes along a row first: point k is "
                    "at (k % columns, k // columns) * square"
                ),
            ),
            (
                lambda a: _close(np.sort(a, axis=0), np.sort(obj, axis=0), 0.01),
                "the points are right but in another order: along a row first (x fastest), then the next row",
            ),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "Calibrate from corner detections",
    "task": """
        A 9 x 6 checkerboard with 25 mm squares (its object points are in `object_points`, (54, 3)
        mm) was detected in 10 pictures whose arrays have `image_shape` = picture.shape, numpy's
        (rows, columns); `image_points` holds the 10 arrays of (54, 2) pixel corners. Write code
        that calibrates the camera with cv2.calibrateCamera and gives it as a fidlearn Camera:
        `fidlearn.Camera(K, dist, image_size)`, with its distortion and its image size in
        OpenCV's order, (width, height).
        """,
    "hint": (
        "cv2.calibrateCamera wants a list of object-point arrays (one per view, float32), a list of "
        "image-point arrays and the image size, and returns rms, K, dist, rvecs, tvecs. Mind the order: "
        "numpy's shape counts rows first, OpenCV's sizes count columns first."
    ),
    "solution": """
        obj = q2.inputs.object_points.astype(np.float32)
        imgs = [p.astype(np.float32) for p in q2.inputs.image_points]
        rows, cols = q2.inputs.image_shape
        size = (cols, rows)                                 # OpenCV: (width, height)
        rms, K, dist, rvecs, tvecs = cv2.calibrateCamera([obj] * len(imgs), imgs, size, None, None)
        q2.answer = fidlearn.Camera(K, dist, size)
        """,
    "level": "medium",
}


def _parse_camera(answer) -> tuple:
    """q2's parser: a fidlearn Camera, read as (K, dist (5,), image_size (w, h))."""
    if isinstance(answer, Camera):
        return answer.K, np.resize(np.asarray(answer.dist, dtype=float).ravel(), 5), tuple(answer.image_size)
    shape = answer.shape if isinstance(answer, np.ndarray) else None  # a list may be ragged: no shape
    hints: dict[tuple[int, ...] | None, str] = {(3, 3): "that is K alone", (5,): "that is the distortion vector alone"}
    what = hints.get((5,) if shape == (1, 5) else shape, f"got {type(answer).__name__}")
    raise _AnswerError(
        f"give the whole camera, fidlearn.Camera(K, dist, image_size): {what}; a camera is K, its "
        "distortion and the image size they hold for"
    )


def _camera_comparer(size: tuple, f_tol: float, c_tol: float, k1_true: float, k1_tol: float):
    """q2's comparison of a camera (K, dist, image_size) with the true one, within what calibration reaches."""

    def cmp_camera(a, b):
        K, dist, image_size = a
        if image_size != size:
            return f"the camera's image_size is {image_size}, the pictures are {size[0]} x {size[1]} (width x height)"
        if abs(dist[0] - k1_true) > k1_tol:
            return f"the distortion k1 = {dist[0]:.3f} is not what these corners show (within {k1_tol:.3f})"
        if (
            abs(K[0, 0] - b[0, 0]) <= f_tol
            and abs(K[1, 1] - b[1, 1]) <= f_tol
            and np.abs(K[:2, 2] - b[:2, 2]).max() <= c_tol
            and abs(K[2, 2] - 1) < 1e-6
        ):
            return None
        return (
            f"your fx = {K[0, 0]:.1f}, cx = {K[0, 2]:.1f}, cy = {K[1, 2]:.1f} px are farther from the true camera "
            f"than calibration on these corners gets (fx within {f_tol:.1f} px, cx, cy within {c_tol:.1f} px)"
        )

    return cmp_camera


def _q2(learner: str) -> Question:
    """q2: Calibrate from corner detections."""
    rng = _rng("02", learner, "q2")
    size = _SIZES[int(rng.integers(1, 3))]
    true_cam = Camera.from_fov(
        float(np.round(rng.uniform(55, 75))), size, dist=[float(np.round(rng.uniform(-0.2, -0.06), 3)), 0, 0, 0, 0]
    )
    K_true = true_cam.K.copy()
    K_true[0, 2] += float(np.round(rng.uniform(-12, 12), 1))
    K_true[1, 2] += float(np.round(rng.uniform(-8, 8), 1))
    true_cam = Camera(K_true, true_cam.dist, size)
    obj2 = Board.checkerboard((9, 6), 25.0).object_points()
    views = _calibration_views(rng, true_cam, obj2, 10, 0.15)
    _, K_key, d_key, _, _ = cv2.calibrateCamera(
        [obj2.astype(np.float32)] * len(views), [v.astype(np.float32) for v in views], size, None, None
    )
    # judged against the true camera, with what calibration on these corners can reach
    f_tol2 = max(0.01 * K_true[0, 0], 3 * abs(K_key[0, 0] - K_true[0, 0]))
    c_tol2 = max(3.0, 3 * float(np.abs(K_key[:2, 2] - K_true[:2, 2]).max()))
    k1_true = float(np.asarray(true_cam.dist).ravel()[0])
    k1_tol = max(0.02, 3 * abs(float(d_key.ravel()[0]) - k1_true))
    cmp_camera = _camera_comparer(size, f_tol2, c_tol2, k1_true, k1_tol)
    return Question(
        "q2",
        inputs={"object_points": obj2, "image_points": views, "image_shape": (size[1], size[0])},
        expected=K_true,
        parse=_parse_camera,
        compare=cmp_camera,
        wrong=[
            (
                lambda a: a[2] == (size[1], size[0]),
                (
                    f"the image size is swapped: you gave (height, width) = {(size[1], size[0])}, numpy's shape "
                    f"order; OpenCV and fidlearn want (width, height) = {size}. calibrateCamera hardly notices "
                    "(it only starts from the centre), but every later use of the camera does"
                ),
            ),
            (
                lambda a: not np.any(a[1]),
                (
                    "the distortion was ignored: your camera has dist = 0, but these corners bend (k1 about "
                    f"{k1_true:.2f}); keep the dist that calibrateCamera returns"
                ),
            ),
        ],
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Find the picture that does not belong",
    "task": """
        Your class pooled its checkerboard pictures; one of the 9 views in
        `image_points` was taken at another resolution (the phone's video mode), so its corners do
        not fit the same K. Write code that calibrates on all views and finds the bad one from
        the per-view reprojection RMS (the view whose reprojected corners are farthest from its
        detected corners). Answer the view's index in the list (0-based).
        """,
    "hint": (
        "cv2.calibrateCamera returns rvecs and tvecs per view; cv2.projectPoints(object_points, rvecs[i], "
        "tvecs[i], K, dist) reprojects view i; compare with image_points[i] (RMS of the distances). "
        "cv2.calibrateCameraExtended also returns perViewErrors."
    ),
    "solution": """
        obj = q3.inputs.object_points.astype(np.float32)
        imgs = [p.astype(np.float32) for p in q3.inputs.image_points]
        rms, K, dist, rvecs, tvecs = cv2.calibrateCamera([obj] * len(imgs), imgs, q3.inputs.image_size, None, None)
        per_view = []
        for img, rvec, tvec in zip(imgs, rvecs, tvecs):
            proj, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
            per_view.append(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))
        q3.answer = int(np.argmax(per_view))
        """,
    "level": "medium",
}


def _q3(learner: str) -> Question:
    """q3: Find the picture that does not belong."""
    rng = _rng("02", learner, "q3")
    size3 = (1280, 720)
    cam3 = Camera.from_fov(float(np.round(rng.uniform(60, 75))), size3)
    obj3 = Board.checkerboard((9, 6), 25.0).object_points()
    views3 = _calibration_views(rng, cam3, obj3, 9, 0.15)
    small = cam3.scaled((640, 360))
    odd = int(rng.integers(1, 9))
    objs3 = [obj3.astype(np.float32)] * len(views3)
    for _ in range(30):
        # a board seen squarely at half resolution looks like one twice as far away: draw the odd
        # view again until the per-view errors single it out clearly (3x the next worst view)
        views3[odd] = np.round(_calibration_views(rng, small, obj3, 1, 0.1)[0], 3)
        _, K3, d3, rv3, tv3 = cv2.calibrateCamera(objs3, [v.astype(np.float32) for v in views3], size3, None, None)
        per_view = [
            float(
                np.sqrt(np.mean(np.sum((cv2.projectPoints(objs3[0], r, t, K3, d3)[0].reshape(-1, 2) - v) ** 2, axis=1)))
            )
            for v, r, t in zip(views3, rv3, tv3)
        ]
        if int(np.argmax(per_view)) == odd and per_view[odd] >= 3 * sorted(per_view)[-2]:
            break
    return Question(
        "q3",
        inputs={"object_points": obj3, "image_points": views3, "image_size": size3},
        expected=odd,
        parse=lambda a: int(_scalar("the index")(a)),
        compare=lambda a, b: None if a == b else f"view {a} is not the one that stands out",
        wrong=[
            (lambda a: a == odd + 1, "Python counts from 0: the first view has index 0"),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "K at another resolution",
    "task": """
        The camera was calibrated at `calibrated_size` (width, height) with intrinsic matrix `K`;
        you now run it at `new_size` (same aspect ratio, the whole sensor resized). Write code that
        computes K at the new size. With pixel centres at integer coordinates a position scales as
        c' = (c + 0.5) * s - 0.5.
        """,
    "hint": (
        "Every entry measured in pixels scales by s = new_width / old_width: fx, fy, cx, cy (cx, "
        "cy with the half-pixel shift)."
    ),
    "solution": """
        sx = q4.inputs.new_size[0] / q4.inputs.calibrated_size[0]
        sy = q4.inputs.new_size[1] / q4.inputs.calibrated_size[1]
        K = np.array(q4.inputs.K, dtype=float)
        K_new = K.copy()
        K_new[0, 0] = K[0, 0] * sx
        K_new[1, 1] = K[1, 1] * sy
        K_new[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
        K_new[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
        q4.answer = K_new
        """,
    "level": "easy",
}


def _q4_mistakes(K4new, K4, s) -> list:
    """The mistakes q4 names: (detector, message) pairs, in the order they are tried."""
    return [
        (
            lambda a: abs(a[0, 0] - K4[0, 0]) < 0.01,
            "the focal length is in pixels, so it scales with the image: fx' = fx * new_width / old_width",
        ),
        (
            lambda a: abs(a[0, 0] - K4[0, 0] / s) < 0.01,
            "the scale is upside down: s = new_width / old_width (a smaller image has a smaller fx, in pixels)",
        ),
        (
            lambda a: abs(a[0, 0] - K4new[0, 0]) < 0.01 and abs(a[0, 2] - K4[0, 2]) < 0.01,
            "the principal point moves too: cx and cy scale like fx (in pixels)",
        ),
        (lambda a: _close(a, K4new.T, 0.51), "your K is transposed: cx and cy belong in the last column"),
    ]


def _q4(learner: str) -> Question:
    """q4: K at another resolution."""
    rng = _rng("02", learner, "q4")
    big = _SIZES[int(rng.integers(2, 4))]
    sizes = [
        (w, h)
        for w, h in (
            (big[0] // 2, big[1] // 2),
            (big[0] // 4, big[1] // 4),
            (1280, 720),
            (640, 360),
            (big[0] * 2, big[1] * 2),
        )
        if (w, h) != big
    ]
    new = sizes[int(rng.integers(len(sizes)))]
    cam4 = Camera.from_fov(float(np.round(rng.uniform(55, 80))), big)
    K4 = cam4.K.copy()
    K4[0, 2] += float(np.round(rng.uniform(-20, 20), 1))
    K4[1, 2] += float(np.round(rng.uniform(-15, 15), 1))
    K4new = Camera(K4, None, big).scaled(new).K
    s = new[0] / big[0]
    return Question(
        "q4",
        inputs={"K": K4, "calibrated_size": big, "new_size": new},
        expected=K4new,
        parse=_array((3, 3), "K"),
        compare=lambda a, b: (
            None
            if (
                np.abs(a[[0, 1], [0, 1]] - b[[0, 1], [0, 1]]).max() <= 0.01
                and np.abs(a[:2, 2] - b[:2, 2]).max() <= 0.51
                and np.abs(a[2] - [0, 0, 1]).max() < 1e-9
            )
            else _cmp_array(0.01, " px")(a, b)
        ),
        wrong=_q4_mistakes(K4new, K4, s),
        notes=[
            (
                lambda a: np.abs(a[:2, 2] - K4new[:2, 2]).max() > 0.1,
                (
                    "K is right to within half a pixel; with pixel centres at integer coordinates c' = (c + 0.5) "
                    "* s - 0.5 is exact"
                ),
            )
        ],
        **_Q4,
    )


#: q5's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q5: QuestionText = {
    "title": "Calibrate from pictures",
    "task": """
        `images` are 6 gray photos (320 x 240) of a printed checkerboard with `pattern_size` =
        (columns, rows) INNER corners and squares of `square_size_mm`. Write code that calibrates the
        camera from the pictures (fidlearn.calibration.calibrate_checkerboard, or
        cv2.findChessboardCorners + cv2.calibrateCamera) and gives K (3, 3).
        """,
    "hint": [
        "The task names the function: read what its result holds (the calibrated camera, and the camera's K).",
        "pattern_size counts INNER corners: a board of 8 x 6 squares has 7 x 5.",
    ],
    "solution": """
        from fidlearn.calibration import calibrate_checkerboard
        calibration = calibrate_checkerboard(q5.inputs.images, q5.inputs.pattern_size, q5.inputs.square_size_mm)
        print(f"RMS {calibration.rms_px:.3f} px over {len(calibration.used)} views")
        q5.answer = calibration.camera.K
        """,
    "level": "medium",
}


def _q5(learner: str) -> Question:
    """q5: Calibrate from pictures."""
    from ... import synthetic
    from ...calibration import calibrate_checkerboard

    rng = _rng("02", learner, "q5")
    f5 = float(np.round(rng.uniform(260, 340)))
    cam5 = Camera(
        np.array(
            [
                [f5, 0, 159.5 + float(np.round(rng.uniform(-4, 4), 1))],
                [0, f5, 119.5 + float(np.round(rng.uniform(-3, 3), 1))],
                [0, 0, 1],
            ]
        ),
        np.array([float(np.round(rng.uniform(-0.15, 0.0), 3)), 0, 0, 0, 0]),
        (320, 240),
    )
    square5 = float(rng.choice([20, 25, 30]))
    views5 = synthetic.render_calibration_views(
        cam5, n_views=6, board=Board.checkerboard((7, 5), square5), seed=int(rng.integers(1 << 20)), supersample=2
    )
    key5 = calibrate_checkerboard(views5.images, (7, 5), square5).camera.K
    f_tol = max(0.015 * f5, 3 * abs(key5[0, 0] - f5))
    c_tol = max(4.0, 3 * float(np.abs(key5[:2, 2] - cam5.K[:2, 2]).max()))

    def cmp5(a, b):
        if (
            abs(a[0, 0] - b[0, 0]) <= f_tol
            and abs(a[1, 1] - b[1, 1]) <= f_tol
            and np.abs(a[:2, 2] - b[:2, 2]).max() <= c_tol
            and abs(a[2, 2] - 1) < 1e-6
        ):
            return None
        return (
            f"your fx = {a[0, 0]:.1f} px, cx = {a[0, 2]:.1f}, cy = {a[1, 2]:.1f} are farther from the true "
            f"camera than calibration on these pictures gets (fx within {f_tol:.1f} px, cx, cy within {c_tol:.1f} "
            "px)"
        )

    return Question(
        "q5",
        inputs={"images": [im.copy() for im in views5.images], "pattern_size": (7, 5), "square_size_mm": square5},
        expected=cam5.K,
        parse=_array(
            (3, 3),
            "K",
            {(5,): "that is the distortion vector; give K", (1, 5): "that is the distortion vector; give K"},
        ),
        compare=cmp5,
        wrong=[
            (lambda a: cmp5(a.T, cam5.K) is None, "your K is transposed: cx and cy belong in the last column"),
        ],
        **_Q5,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 02 for one learner, in notebook order.

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
