"""Lesson 06: PnP: the pose from several markers.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("06", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ... import _cv, frames
from ...camera import Camera
from ...detection import Detection
from ...frames import look_at
from .._engine import Question, QuestionText, _AnswerError
from .._parsers import (
    _array,
    _close,
    _cmp_array,
    _cmp_scalar,
    _cmp_transform,
    _scalar,
    _T_is,
)
from .._scenery import (
    _noisy_detections,
    _pose_seeing_all,
    _rng,
    _wall_map,
)

NUMBER = "06"
TOPIC = "pnp"
TITLE = "PnP: the pose from several markers"
INTRO = """
    Solve for the camera's extrinsics with every marker at once: pair world corners with pixels,
    run cv2.solvePnP, and measure how well the pose explains the corners (reprojection error).
    """


def _same_rows(a: np.ndarray, b: np.ndarray, tol: float = 0.01) -> bool:
    """Whether the rows of a and b are the same set (any order, each within tol), float32 answers included."""
    if a.shape != b.shape:
        return False
    free = list(range(len(b)))
    for row in a:
        hit = next((k for k in free if np.abs(b[k] - row).max() <= tol), None)
        if hit is None:
            return False
        free.remove(hit)
    return True


def _lens(rng: np.random.Generator) -> list:
    """A webcam's barrel distortion (k1, k2, p1, p2, k3): strong enough that ignoring it shows."""
    return [float(np.round(rng.uniform(-0.25, -0.12), 3)), float(np.round(rng.uniform(0.0, 0.06), 3)), 0.0, 0.0, 0.0]


def _shifted_inside(corners_px: np.ndarray, shift_px: tuple, image_size: tuple) -> np.ndarray:
    """Corners moved by ``shift_px``, the shift turned back on an axis where it would leave the image."""
    shift = np.array(shift_px, dtype=float)
    for axis in (0, 1):
        moved = corners_px[:, axis] + shift[axis]
        if moved.min() < 10 or moved.max() > image_size[axis] - 11:
            shift[axis] = -shift[axis]
    return corners_px + shift


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "2D-3D correspondences",
    "task": """
        `detections` lists detected markers (fidlearn Detection: `.id`, `.corners_px` (4, 2) px,
        TL, TR, BR, BL); one of them is not in the map. `marker_map` gives world corners
        (marker_map.marker_corners(id), (4, 3) mm, same order). Write code that builds the
        arrays solvePnP needs: object_points (N, 3) mm and image_points (N, 2) px, row k of one
        matching row k of the other. Answer (object_points, image_points).
        """,
    "hint": (
        "Loop over the detections, skip an id that is not in marker_map (`d.id in marker_map`), and "
        "stack marker_map.marker_corners(d.id) and d.corners_px."
    ),
    "solution": """
        m = q1.inputs.marker_map
        known = [d for d in q1.inputs.detections if d.id in m]
        object_points = np.concatenate([m.marker_corners(d.id) for d in known])
        image_points = np.concatenate([d.corners_px for d in known])
        q1.answer = (object_points, image_points)
        """,
    "level": "easy",
}


def _q1(learner: str) -> Question:
    """q1: 2D-3D correspondences."""
    rng = _rng("06", learner, "q1")
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720))
    m = _wall_map(rng, 4, float(rng.choice([100, 120, 150])))
    T = _pose_seeing_all(
        rng, cam, m, lambda r: look_at(np.round(r.uniform([1800, -500, 1000], [3000, 500, 1500])), [0, 0, 1200])
    )
    dets = _noisy_detections(rng, m, cam, T, 0.2)
    stray_id = int(max(m.ids) + 1 + rng.integers(0, 5))
    stray = Detection(stray_id, np.round(_shifted_inside(dets[0].corners_px, (-300, 150), cam.image_size), 3))
    detections = sorted(dets + [stray], key=lambda d: d.corners_px[0, 0])
    obj = np.concatenate([m.marker_corners(d.id) for d in detections if d.id in m])
    img = np.concatenate([d.corners_px for d in detections if d.id in m])
    key_pairs = np.column_stack([obj, img])

    def parse_pairs(answer):
        if not isinstance(answer, (tuple, list)) or len(answer) != 2:
            raise _AnswerError("give a pair (object_points (N, 3), image_points (N, 2))")
        o = _array((-1, 3), "object_points", {(len(obj), 2): "object points are 3D world corners (x, y, z), mm"})(
            answer[0]
        )
        i = _array((-1, 2), "image_points")(answer[1])
        if len(o) != len(i):
            raise _AnswerError(f"{len(o)} object points but {len(i)} image points: every world corner needs its pixel")
        return o, i

    def cmp_pairs(a, _):
        o, i = a
        if _same_rows(np.column_stack([o, i]), key_pairs):
            return None
        if len(o) == len(obj) + 4:
            return (
                f"you have {len(o) // 4} markers; marker {stray_id} was detected but is not in the map: skip "
                "ids the map does not know"
            )
        if len(o) != len(obj):
            return (
                f"you have {len(o)} correspondences; the {len(obj) // 4} mapped markers give {len(obj)} (4 "
                "corners each)"
            )
        if _same_rows(o, obj):
            return (
                "each world corner must sit next to ITS pixel: detection i's corners (TL, TR, BR, BL) go "
                "with marker_corners(detection i's id), in the same order"
            )
        return "these are not the map's corners of the detected markers"

    return Question(
        "q1",
        inputs={"detections": detections, "marker_map": m, "camera": cam},
        expected=(obj, img),
        parse=parse_pairs,
        compare=cmp_pairs,
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "solvePnP over every marker",
    "task": """
        The camera `camera` (K, dist) saw the 5 markers of `marker_map`; their detections are in
        `detections`. Write code that estimates the camera's extrinsics with cv2.solvePnP using
        the corners of ALL markers at once. Answer (rvec, tvec) as solvePnP returns them.
        """,
    "hint": [
        "One solve over every marker at once: pair every 3D corner of the map with its detected pixel (as in q1).",
        (
            "OpenCV's PnP solver takes those pairs with the camera matrix and the distortion, and answers with the "
            "world seen from the camera: a rotation vector and a translation. Keep the lens in: the corners were "
            "detected in the distorted picture."
        ),
    ],
    "solution": """
        m, cam = q2.inputs.marker_map, q2.inputs.camera
        known = [d for d in q2.inputs.detections if d.id in m]
        object_points = np.concatenate([m.marker_corners(d.id) for d in known])
        image_points = np.concatenate([d.corners_px for d in known])
        ok, rvec, tvec = cv2.solvePnP(object_points, image_points, cam.K, cam.dist)
        q2.answer = (rvec, tvec)
        """,
    "level": "medium",
}


def _q2_mistakes(Tcw_epnp, Tcw_key, Tcw_nodist) -> list:
    """The mistakes q2 names: (detector, message) pairs, in the order they are tried."""
    return [
        (
            _T_is(Tcw_nodist, 0.05, 1.0),
            (
                "the distortion was ignored: this camera's lens bends the picture (camera.dist is not zero), and "
                "solvePnP without it fits a pinhole to bent corners; pass camera.dist as distCoeffs"
            ),
        ),
        (
            _T_is(frames.invert_transform(Tcw_key), 0.5, 15),
            (
                "that is the camera's pose (T_world_camera); solvePnP's rvec, tvec are T_camera_world: give "
                "them as they are"
            ),
        ),
        (
            _T_is(Tcw_epnp, 0.05, 1.0),
            (
                "EPnP is unreliable when all the points lie on one plane (the markers are all on one wall): "
                "use the default SOLVEPNP_ITERATIVE, IPPE or SQPNP"
            ),
        ),
        (
            lambda a: (
                frames.rotation_angle_deg(a[:3, :3], Tcw_key[:3, :3]) < 3
                and np.linalg.norm(a[:3, 3] - Tcw_key[:3, 3]) < 150
            ),
            (
                "close, but not the least-squares pose: use all 5 markers (20 corners) and the camera's "
                "distortion, "
                "and if you chose SOLVEPNP_IPPE, refine with cv2.solvePnPRefineLM (the default SOLVEPNP_ITERATIVE "
                "does)"
            ),
        ),
    ]


def _q2(learner: str) -> Question:
    """q2: solvePnP over every marker."""
    rng = _rng("06", learner, "q2")
    cam2 = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720), dist=_lens(rng))
    m2 = _wall_map(rng, 5, 150.0)
    T2 = _pose_seeing_all(
        rng,
        cam2,
        m2,
        lambda r: look_at(
            np.round(r.uniform([1500, -700, 900], [3000, 700, 1600])), [0, float(np.round(r.uniform(-200, 200))), 1200]
        ),
    )
    dets2 = _noisy_detections(rng, m2, cam2, T2, 0.3)
    obj2 = np.concatenate([m2.marker_corners(d.id) for d in dets2])
    img2 = np.concatenate([d.corners_px for d in dets2])
    ok, rv, tv = cv2.solvePnP(obj2, img2, cam2.K, cam2.dist, flags=_cv.solvepnp_flag("ITERATIVE"))
    Tcw_key = frames.transform_from_rvec_tvec(rv.ravel(), tv.ravel())
    ok, rv_e, tv_e = cv2.solvePnP(obj2, img2, cam2.K, cam2.dist, flags=_cv.solvepnp_flag("EPNP"))
    Tcw_epnp = frames.transform_from_rvec_tvec(rv_e.ravel(), tv_e.ravel())
    ok, rv_n, tv_n = cv2.solvePnP(obj2, img2, cam2.K, None, flags=_cv.solvepnp_flag("ITERATIVE"))
    Tcw_nodist = frames.transform_from_rvec_tvec(rv_n.ravel(), tv_n.ravel())

    def parse_rt(answer):
        if isinstance(answer, np.ndarray) and answer.shape == (4, 4):
            raise _AnswerError("give (rvec, tvec) as solvePnP returns them, not a 4x4 matrix")
        if not isinstance(answer, (tuple, list)) or len(answer) not in (2, 3):
            raise _AnswerError("give the pair (rvec, tvec) that cv2.solvePnP returns")
        if len(answer) == 3:
            answer = answer[1:]  # (ok, rvec, tvec) straight from solvePnP
        r = _array(
            (3,), "rvec", {(3, 3): "that is a rotation matrix: give the Rodrigues vector (cv2.Rodrigues(R)[0])"}
        )(answer[0])
        t = _array((3,), "tvec")(answer[1])
        return frames.transform_from_rvec_tvec(r, t)

    return Question(
        "q2",
        inputs={"detections": dets2, "marker_map": m2, "camera": cam2},
        expected=Tcw_key,
        parse=parse_rt,
        compare=_cmp_transform(0.5, 15.0),
        wrong=_q2_mistakes(Tcw_epnp, Tcw_key, Tcw_nodist),
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Reprojection error",
    "task": """
        solvePnP on `object_points` (N, 3) mm and `image_points` (N, 2) px gave `rvec`, `tvec`.
        Write code that reprojects the object points with that pose and the camera (K, dist) and
        computes the RMS reprojection error in pixels: the square root of the mean of the SQUARED
        distances between reprojected and detected corners.
        """,
    "hint": [
        "Put the corners back through the camera with the pose and compare them with the detected ones.",
        (
            "cv2.projectPoints reprojects (with K and dist); the error of one corner is the length of its (dx, "
            "dy); RMS is the root of the mean of those lengths squared."
        ),
    ],
    "solution": """
        cam = q3.inputs.camera
        proj, _ = cv2.projectPoints(q3.inputs.object_points, q3.inputs.rvec, q3.inputs.tvec, cam.K, cam.dist)
        residuals = proj.reshape(-1, 2) - q3.inputs.image_points
        q3.answer = np.sqrt(np.mean(np.sum(residuals ** 2, axis=1)))
        """,
    "level": "easy",
}


def _q3(learner: str) -> Question:
    """q3: Reprojection error."""
    rng = _rng("06", learner, "q3")
    cam3 = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720), dist=_lens(rng))
    m3 = _wall_map(rng, 4, 120.0)
    T3 = _pose_seeing_all(
        rng, cam3, m3, lambda r: look_at(np.round(r.uniform([1500, -700, 900], [3000, 700, 1600])), [0, 0, 1200])
    )
    dets3 = _noisy_detections(rng, m3, cam3, T3, float(np.round(rng.uniform(0.3, 1.0), 2)))
    obj3 = np.concatenate([m3.marker_corners(d.id) for d in dets3])
    img3 = np.concatenate([d.corners_px for d in dets3])
    ok, rv3, tv3 = cv2.solvePnP(obj3, img3, cam3.K, cam3.dist)
    rv3, tv3 = np.round(rv3.ravel(), 6), np.round(tv3.ravel(), 3)
    proj = cv2.projectPoints(obj3, rv3, tv3, cam3.K, cam3.dist)[0].reshape(-1, 2)
    d = np.linalg.norm(proj - img3, axis=1)
    rms = float(np.sqrt(np.mean(d**2)))
    proj_nodist = cv2.projectPoints(obj3, rv3, tv3, cam3.K, None)[0].reshape(-1, 2)
    rms_nodist = float(np.sqrt(np.mean(np.sum((proj_nodist - img3) ** 2, axis=1))))
    return Question(
        "q3",
        inputs={"object_points": obj3, "image_points": img3, "rvec": rv3, "tvec": tv3, "camera": cam3},
        expected=rms,
        parse=_scalar("the RMS error"),
        compare=_cmp_scalar(1e-3, " px", rtol=1e-3),
        wrong=[
            (
                lambda a: abs(a - rms_nodist) < 1e-3 * rms_nodist,
                (
                    "the distortion was ignored: the corners were detected through a lens that bends them "
                    "(camera.dist is not zero), so reproject with cv2.projectPoints(..., K, dist), not with K alone"
                ),
            ),
            (
                lambda a: abs(a - d.mean()) < 1e-3,
                "that is the mean distance; RMS is the square ROOT of the MEAN of the SQUARED distances",
            ),
            (
                lambda a: abs(a - rms / math.sqrt(2)) < 1e-3,
                (
                    "that averages over the 2N coordinates; average the squared DISTANCES over the N points (dx^2 "
                    "+ dy^2 per point)"
                ),
            ),
            (lambda a: abs(a - rms**2) < 1e-3, "that is the mean squared error; take its square root"),
            (
                lambda a: abs(a - float(np.sqrt(np.sum(d**2)))) < 1e-3,
                "divide by the number of points before the square root (the MEAN of the squares)",
            ),
            (
                lambda a: a > 20,
                (
                    "that is far too large: did you project with the right pose (rvec, tvec are T_camera_world, "
                    "as cv2.projectPoints wants) and the camera's K and dist?"
                ),
            ),
        ],
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Straighten the corners",
    "task": """
        `corners_px` (4, 2) are a marker's corners detected near the edge of a picture taken through
        the lens of `camera` (K and its distortion `dist`). Before drawing straight lines through
        them (or solving a pose by hand) they must be where an ideal pinhole camera with the same K
        would have seen them. Write code that gives those corners, (4, 2) pixels.
        """,
    "hint": [
        "Undoing the lens has no closed form, but OpenCV undoes it for you. Read what its undistortion returns.",
        "cv2.undistortPoints returns points on the plane at depth 1 unless you tell it which camera matrix to "
        "put them back into pixels with (its P argument).",
    ],
    "solution": """
        cam = q4.inputs.camera
        px = np.asarray(q4.inputs.corners_px, dtype=np.float64).reshape(-1, 1, 2)
        q4.answer = cv2.undistortPoints(px, cam.K, cam.dist, P=cam.K).reshape(-1, 2)
        """,
    "level": "medium",
}


#: q4's tolerance (px) at least; its key is the exact undistortion (Camera.undistort_points).
_Q4_TOL_PX = 0.05


def _q4(learner: str) -> Question:
    """q4: Straighten the corners."""
    rng = _rng("06", learner, "q4")
    cam = Camera.from_fov(float(np.round(rng.uniform(60, 80))), (1280, 720), dist=_lens(rng))
    centre = np.array([rng.choice([1, -1]) * rng.uniform(380, 520), rng.choice([1, -1]) * rng.uniform(180, 260)])
    side = float(rng.uniform(50, 90))
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * side / 2 + centre + cam.K[:2, 2]
    ideal = np.round(square, 3)
    rays = np.column_stack([(ideal - cam.K[:2, 2]) / [cam.fx, cam.fy], np.ones(4)])
    corners = np.round(cv2.projectPoints(rays, np.zeros(3), np.zeros(3), cam.K, cam.dist)[0].reshape(-1, 2), 3)
    px = corners.reshape(-1, 1, 2)
    key = cam.undistort_points(corners)  # exact on every OpenCV (4's undistortPoints takes no criteria)
    # OpenCV's default 5 iterations stop short near the edge of a strong lens (0.1 px here at worst, 0.56 px
    # farther out): both the exact answer and the usual call are right
    usual = cv2.undistortPoints(px, cam.K, cam.dist, P=cam.K).reshape(-1, 2)
    tol = max(_Q4_TOL_PX, 2.0 * float(np.abs(usual - key).max()))
    normalized = cv2.undistortPoints(corners.reshape(-1, 1, 2), cam.K, cam.dist).reshape(-1, 2)
    bent_twice = cv2.projectPoints(
        np.column_stack([(corners - cam.K[:2, 2]) / [cam.fx, cam.fy], np.ones(4)]),
        np.zeros(3),
        np.zeros(3),
        cam.K,
        cam.dist,
    )[0].reshape(-1, 2)
    return Question(
        "q4",
        inputs={"camera": cam, "corners_px": corners},
        expected=key,
        parse=_array((4, 2), "the corners", {(4, 1, 2): "", (2, 4): "one ROW per corner: transpose it"}),
        compare=_cmp_array(tol, " px"),
        wrong=[
            (
                lambda a: _close(a, corners, 0.05),
                (
                    "the distortion was ignored: those are the detected corners as they are. Near the edge this "
                    "lens moves them by pixels; undo it with cv2.undistortPoints"
                ),
            ),
            (
                lambda a: _close(a, normalized, 1e-4),
                (
                    "those are on the plane at depth 1 (x = X / Z), not pixels: give cv2.undistortPoints P=K to "
                    "put them back into pixels"
                ),
            ),
            (
                lambda a: _close(a, bent_twice, 0.05),
                "that bends the corners a second time (cv2.projectPoints adds the lens): undistortion removes it",
            ),
        ],
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 06 for one learner, in notebook order.

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
