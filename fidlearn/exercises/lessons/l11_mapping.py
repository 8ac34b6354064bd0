"""Lesson 11: From localization to mapping.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("11", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from ... import frames
from ...camera import Camera
from ...frames import look_at
from ...markermap import MarkerMap, MarkerPlacement
from ...synthetic import visible_markers
from .._engine import Detector, Question, QuestionText
from .._parsers import (
    _array,
    _close,
    _cmp_array,
    _cmp_scalar,
    _scalar,
)
from .._scenery import (
    _pose_seeing_all,
    _rng,
    _wall_map,
)
from ._l11_print import _Q5, _q5  # noqa: F401 (q5, kept apart for the module's length)
from ._l11_two_view import _Q6, _q6  # noqa: F401 (q6, likewise)

NUMBER = "11"
TOPIC = "mapping"
TITLE = "From localization to mapping"
INTRO = """
    Let photos measure the map: count a survey's unknowns, build one of its residuals by hand,
    find the marker the tape put in the wrong place, choose the photo that helps the map most,
    write in the map the sizes your printer really made, and give a map made from two photos its scale.
    """

_CORNERS = ("top-left", "top-right", "bottom-right", "bottom-left")


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "Count the unknowns of a survey",
    "task": """
        A survey adjusts every photo's camera pose and every marker's placement at once.
        `markers_seen` lists, for each photo, the ids of the markers it shows (every marker of the
        map is in at least two photos); `fixed_ids` are markers whose placement is taken as exact.
        Write code that computes how many unknowns the least-squares problem has.
        """,
    "hint": [
        "An unknown is a number the solver may change. Which things does it move, and how many numbers is each?",
        (
            "A pose (a camera's, or a marker's placement) is 6 numbers: 3 of rotation, 3 of translation. The "
            "detected corners are measurements (residuals), not unknowns; a fixed marker is not moved at all."
        ),
    ],
    "solution": """
        photos = len(q1.inputs.markers_seen)
        markers = {i for seen in q1.inputs.markers_seen for i in seen}
        q1.answer = 6 * photos + 6 * len(markers - set(q1.inputs.fixed_ids))
        """,
    "level": "easy",
}


def _q1_mistakes(n_photos: int, n_markers: int, n_fixed: int, n_seen: int) -> list:
    """The mistakes q1 names: (detector, message) pairs, in the order they are tried."""
    free = n_markers - n_fixed
    return [
        (
            lambda a: a == 6 * (n_photos + n_markers),
            "that counts the fixed marker(s) too: a fixed marker is held, not adjusted, so it has no unknowns",
        ),
        (
            lambda a: n_fixed > 1 and a == 6 * (n_photos + n_markers - 1),
            "every fixed marker removes its 6 unknowns, not only the first",
        ),
        (
            lambda a: a in (4 * n_seen, 8 * n_seen, 12 * n_seen, 8 * n_seen + 6 * free),
            (
                "that counts corners (or their coordinates): those are the measurements, the residuals; the "
                "unknowns are the poses, 6 per photo and 6 per free marker"
            ),
        ),
        (
            lambda a: a in (3 * (n_photos + free), 3 * (n_photos + n_markers)),
            "a pose is 6 numbers, not 3: the rotation is unknown as well as the position",
        ),
        (lambda a: a == 6 * free, "the photos' camera poses are unknowns too: 6 per photo"),
        (lambda a: a == 6 * n_photos, "the markers' placements are unknowns too: 6 per marker that is not fixed"),
    ]


def _q1(learner: str) -> Question:
    """q1: Count the unknowns of a survey."""
    rng = _rng("11", learner, "q1")
    n_markers = int(rng.integers(6, 13))
    ids = sorted(int(i) for i in rng.choice(50, size=n_markers, replace=False))
    n_photos = int(rng.integers(8, 25))
    while True:
        seen = [
            sorted(int(i) for i in rng.choice(ids, size=int(rng.integers(2, 6)), replace=False))
            for _ in range(n_photos)
        ]
        counts = {i: sum(i in s for s in seen) for i in ids}
        if min(counts.values()) >= 2:
            break
    fixed = sorted(int(i) for i in rng.choice(ids, size=int(rng.integers(1, 3)), replace=False))
    n_seen = sum(len(s) for s in seen)
    key = 6 * n_photos + 6 * (n_markers - len(fixed))
    return Question(
        "q1",
        inputs={"markers_seen": seen, "fixed_ids": fixed},
        expected=float(key),
        parse=_scalar("the number of unknowns"),
        compare=_cmp_scalar(0.5),
        wrong=_q1_mistakes(n_photos, n_markers, len(fixed), n_seen),
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "One residual by hand",
    "task": """
        One residual of a survey: where the current estimates put one corner in one photo, minus
        where the detector found it. `marker_map` holds the marker's current placement, `corner`
        which of its corners (0 top-left, 1 top-right, 2 bottom-right, 3 bottom-left), `T_camera_world`
        the photo's current camera pose as the survey keeps it (world points into the camera frame,
        mm), `camera` the calibrated camera (with its distortion) and `detected_px` the detected
        corner (u, v). Write code that computes the residual (u, v), px: projected minus detected.
        """,
    "hint": [
        "Three steps: the corner in the world, the corner in the photo (with everything the camera does to it), "
        "then the difference in the survey's order.",
        (
            "MarkerMap.marker_corners gives the corners in the world, in winding order; Camera.project wants "
            "T_world_camera (the inverse of the pose you are given) and applies the distortion; the residual is "
            "projected minus detected."
        ),
    ],
    "solution": """
        m = q2.inputs.marker_map
        X = m.marker_corners(m.ids[0])[q2.inputs.corner]
        T_world_camera = frames.invert_transform(q2.inputs.T_camera_world)
        projected = q2.inputs.camera.project(X, T_world_camera)
        q2.answer = projected - q2.inputs.detected_px
        """,
    "level": "medium",
}


def _q2_layout(rng: np.random.Generator):
    """The camera, the one-marker map, T_world_camera of q2 (a camera seeing the marker whole) and how far (px)
    the lens moves each corner."""
    size = float(rng.choice([100.0, 150.0, 200.0]))
    m = _wall_map(rng, 1, size, first_id=int(rng.integers(0, 20)), spread_mm=600.0)
    dist = [float(np.round(rng.uniform(-0.2, -0.08), 3)), float(np.round(rng.uniform(0.02, 0.08), 3)), 0.0, 0.0, 0.0]
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720), dist=dist if rng.random() < 0.6 else None)
    centre = m.marker_corners(m.ids[0]).mean(axis=0)

    def draw(r):
        eye = [r.uniform(900, 2500), r.uniform(-900, 900), r.uniform(900, 1800)]
        # aim away from the marker so it sits off the image's centre, where the lens bends most
        return look_at(eye, centre + [0.0, r.uniform(-500, 500), r.uniform(-300, 300)], roll_deg=r.uniform(-8, 8))

    pinhole, corners = Camera(cam.K, None, cam.image_size), m.marker_corners(m.ids[0])
    for _ in range(_Q2_DRAWS):  # a lens must move some corner clearly, or leaving it out goes unnoticed
        T_wc = _pose_seeing_all(rng, cam, m, draw)
        bent = np.linalg.norm(cam.project(corners, T_wc) - pinhole.project(corners, T_wc), axis=1)
        if cam.dist is None or not np.any(cam.dist) or bent.max() >= _Q2_LENS_PX:
            break
    return cam, m, T_wc, bent


#: Draws of q2's layout before one whose lens moves a corner by at least _Q2_LENS_PX (px); the corner asked is
#: one it moves that much (at 0.003 px, 8 learners in 300 had "the lens left out" marked right).
_Q2_DRAWS, _Q2_LENS_PX = 20, 0.5


def _q2(learner: str) -> Question:
    """q2: One residual by hand."""
    rng = _rng("11", learner, "q2")
    cam, m, T_wc, bent = _q2_layout(rng)
    corners = m.marker_corners(m.ids[0])
    k = int(rng.integers(0, 4))
    if cam.dist is not None and np.any(cam.dist) and bent[k] < _Q2_LENS_PX:
        k = int(np.argmax(bent))  # the corner the lens moves most
    true_px = cam.project(corners, T_wc)
    detected = np.round(true_px[k] + rng.normal(0, 0.6, 2), 3)
    T_cw = frames.invert_transform(T_wc)
    key = true_px[k] - detected
    pinhole = Camera(cam.K, np.zeros(5), cam.image_size)
    wrong: list[tuple[Detector, str]] = [
        (
            lambda a: _close(a, -key, 1e-3),
            "that is detected minus projected: the survey's residual is projected minus detected",
        ),
        (
            lambda a: _close(a, cam.project(corners[k], T_cw) - detected, 1e-2),
            (
                "Camera.project wants T_world_camera, and you gave it T_camera_world: invert the pose first "
                "(frames.invert_transform)"
            ),
        ),
        (
            lambda a: (
                cam.dist is not None
                and np.any(np.asarray(cam.dist) != 0)
                and _close(a, pinhole.project(corners[k], T_wc) - detected, 1e-2)
            ),
            "that projection leaves out the lens distortion; the survey projects with it (Camera.project does)",
        ),
        (lambda a: _close(a, true_px[k], 1e-2), "that is the projected corner; subtract the detected one"),
    ]
    for j in range(4):
        if j != k:
            wrong.append(
                (
                    partial(_close, b=true_px[j] - detected, atol=1e-2),
                    f"that is the {_CORNERS[j]} corner; corner {k} is the {_CORNERS[k]} (TL, TR, BR, BL)",
                )
            )
    return Question(
        "q2",
        inputs={"marker_map": m, "corner": k, "T_camera_world": T_cw, "camera": cam, "detected_px": detected},
        expected=key,
        parse=_array((2,), "the residual (u, v)"),
        compare=_cmp_array(0.01, " px"),
        wrong=wrong,
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "Which marker did the tape put in the wrong place?",
    "task": """
        A survey compared each marker's tape position with where the photos alone put it.
        `ids` (n,) are the markers, `differences_mm` (n, 3) the photos' position minus the tape's
        (world, mm), and `covariances_mm2` (n, 3, 3) the covariance of each difference (the photos'
        uncertainty plus the tape's, mm^2). Exactly one marker was moved after it was measured.
        Write code that finds it: answer its id.
        """,
    "hint": [
        "A difference means something only next to how large it could be by chance, and that depends on the "
        "direction: some markers are pinned down much better in one direction than in another.",
        (
            "Measure each difference in sigmas with its own covariance: the Mahalanobis distance "
            "sqrt(d^T C^-1 d) (np.linalg.solve). The moved marker has the largest."
        ),
    ],
    "solution": """
        d = np.asarray(q3.inputs.differences_mm, dtype=float)
        C = np.asarray(q3.inputs.covariances_mm2, dtype=float)
        sigmas = [np.sqrt(d[i] @ np.linalg.solve(C[i], d[i])) for i in range(len(d))]
        q3.answer = q3.inputs.ids[int(np.argmax(sigmas))]
        """,
    "level": "medium",
}


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    return frames.rotation_from_rpy_deg(*rng.uniform(-180, 180, 3))


def _tilted_frame(rng: np.random.Generator) -> np.ndarray:
    """A rotation whose first column is near a cube diagonal (1, +-1, +-1) / sqrt(3): an ellipsoid long along it
    tilts across every world axis, so its diagonal variances say little of it."""
    u = np.array([1.0, *rng.choice([-1.0, 1.0], 2)]) / np.sqrt(3) + rng.normal(0, 0.08, 3)
    u /= np.linalg.norm(u)
    v = np.cross(u, rng.normal(0, 1, 3))
    v /= np.linalg.norm(v)
    return np.column_stack([u, v, np.cross(u, v)])


def _q3_draw(rng: np.random.Generator, n: int):
    """One draw of q3's differences and covariances: the moved marker (row 0), pinned well across its view and
    moved that way, a weakly held one (row 1, the farthest in mm), a tilted one (row 2, first by the diagonal
    variances alone), the others by chance."""
    d, C = np.zeros((n, 3)), np.zeros((n, 3, 3))
    for i in range(n):
        if i == 0:  # long along a diagonal, moved along a short axis: the diagonal variances hide the move
            R, s = _tilted_frame(rng), np.array([rng.uniform(60, 80), *rng.uniform(15, 22, 2)])
            d[i] = R[:, int(rng.integers(1, 3))] * rng.uniform(85, 110) * rng.choice([-1, 1])
        elif i == 1:  # seen only from far along one world axis: its depth weakly held
            R, s = np.eye(3)[:, rng.permutation(3)], rng.uniform(18, 30, 3)
            s[0] = rng.uniform(60, 90)
            d[i] = R[:, 0] * s[0] * rng.uniform(2.0, 2.6) * rng.choice([-1, 1])
        elif i == 2:  # tilted and off along its long axis, well within chance
            R, s = _tilted_frame(rng), np.array([rng.uniform(45, 60), *rng.uniform(12, 18, 2)])
            d[i] = R[:, 0] * s[0] * rng.uniform(1.8, 2.0) * rng.choice([-1, 1])
        else:
            R, s = _random_rotation(rng), rng.uniform(18, 30, 3)
            z = rng.normal(0, 1, 3)
            d[i] = R @ (s * z * min(1.0, 2.2 / np.linalg.norm(z)))
        C[i] = np.round(R @ np.diag(s**2) @ R.T, 1)
    return np.round(d, 1), C


def _q3_scores(d: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each row's difference in sigmas (Mahalanobis), by the diagonal variances alone, and in mm."""
    sig = np.array([np.sqrt(d[i] @ np.linalg.solve(C[i], d[i])) for i in range(len(d))])
    diag = np.array([np.sqrt(np.sum(d[i] ** 2 / np.diag(C[i]))) for i in range(len(d))])
    return sig, diag, np.linalg.norm(d, axis=1)


def _q3_data(rng: np.random.Generator):
    """ids, differences (n, 3), covariances (n, 3, 3), the moved marker's row and a weakly held one's: drawn until
    each way of judging names its own marker (sigmas the moved one, the diagonal variances a tilted one, mm the
    weakly held one), so that each mistake is told apart; the rows shuffled."""
    n = int(rng.integers(6, 10))
    ids = np.sort(rng.choice(40, size=n, replace=False)).astype(int)
    for _ in range(_Q3_DRAWS):
        d, C = _q3_draw(rng, n)
        sig, diag, mm = _q3_scores(d, C)
        others = np.delete(sig, 0)
        if np.argmax(diag) == 2 and np.argmax(mm) == 1 and sig[0] > 3.37 and others.max() < 2.7:
            break
    order = rng.permutation(n)
    return ids, d[order], C[order], int(np.argsort(order)[0]), int(np.argsort(order)[1])


#: Draws of q3's data before one where each way of judging names its own marker (about 1 in 3 does).
_Q3_DRAWS = 200


def _q3(learner: str) -> Question:
    """q3: Which marker did the tape put in the wrong place?"""
    rng = _rng("11", learner, "q3")
    ids, d, C, moved, _ = _q3_data(rng)
    sig, diag, mm = _q3_scores(d, C)
    key = int(ids[int(np.argmax(sig))])
    far, far_d, diag_pick = int(ids[int(np.argmax(mm))]), float(mm.max()), int(ids[int(np.argmax(diag))])
    wrong = [
        (
            lambda a: int(round(a)) == far != key,
            (
                f"marker {far} is the farthest in mm ({far_d:.0f} mm), but its covariance is large in that "
                "direction: in sigmas (Mahalanobis, sqrt(d^T C^-1 d)) it is within what chance allows"
            ),
        ),
        (
            lambda a: int(round(a)) == diag_pick != key,
            (
                "that weighs each axis by its variance alone; the covariance's off-diagonal terms tilt the "
                "ellipsoid: solve with the whole 3x3 matrix"
            ),
        ),
        (lambda a: int(round(a)) not in ids, f"answer one of the ids {ids.tolist()}, not a row number"),
    ]
    return Question(
        "q3",
        inputs={"ids": ids, "differences_mm": d, "covariances_mm2": C},
        expected=float(key),
        parse=_scalar("the marker's id"),
        compare=lambda a, b: None if abs(a - b) < 0.5 else "that marker's difference is within what chance allows",
        wrong=wrong,
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Which photo to take next?",
    "task": """
        A survey of the markers in `marker_map` reports each marker's position uncertainty
        `position_std_mm` (n,), one per id of `marker_map.ids`, in that order. You can take one
        more photo, from one of the camera poses `candidates` (k, 4, 4) (`T_world_camera`, mm) with
        `camera`. Write code that picks the photo that helps the map most: the one that shows,
        whole, the marker that is worst determined. Answer its index in `candidates` (from 0).
        """,
    "hint": [
        "A photo improves only the markers it shows. Which marker needs it, and which candidate shows it?",
        (
            "The worst marker has the largest std; fidlearn.synthetic.visible_markers(marker_map, camera, T) "
            "tells which markers a camera at T sees whole."
        ),
    ],
    "solution": """
        from fidlearn.synthetic import visible_markers
        m = q4.inputs.marker_map
        worst = m.ids[int(np.argmax(q4.inputs.position_std_mm))]
        sees = [worst in visible_markers(m, q4.inputs.camera, T) for T in q4.inputs.candidates]
        q4.answer = sees.index(True)
        """,
    "level": "medium",
}


def _q4_map(rng: np.random.Generator) -> MarkerMap:
    """Five or six markers of 150 mm spread along the north wall, about 600 mm apart."""
    n = int(rng.integers(5, 7))
    ids = np.sort(rng.choice(40, size=n, replace=False)).astype(int)
    ys = np.round(np.linspace(-1500, 1350, n) + rng.uniform(-60, 60, n), -1)
    zs = np.round(rng.uniform(800, 1700, n), -1)
    pl = {int(i): MarkerPlacement(int(i), (0.0, float(y), float(z)), (0.0, 0.0, 0.0)) for i, y, z in zip(ids, ys, zs)}
    return MarkerMap(pl, 150.0, dictionary="ARUCO_ORIGINAL", units="mm")


#: Candidate photos offered in q4.
_Q4_N = 10


def _q4_layout(rng: np.random.Generator):
    """The map, camera, stds, candidates and the index of the candidate that sees the worst marker."""
    m = _q4_map(rng)
    cam = Camera.from_fov(float(np.round(rng.uniform(40, 50))), (1280, 720))
    ids = m.ids
    std = np.round(rng.uniform(1.0, 4.0, len(ids)), 1)
    worst = int(rng.integers(len(ids)))
    std[worst] = np.round(rng.uniform(9, 20), 1)
    centres = {i: m.marker_corners(i).mean(axis=0) for i in ids}
    others = [int(i) for i in ids if i != ids[worst]]

    def candidate(target: int, must_see_worst: bool):
        """A pose aimed at one marker that shows it whole, and shows the worst marker only when it must."""
        while True:
            T = look_at(
                [rng.uniform(1200, 2200), centres[target][1] + rng.uniform(-300, 300), rng.uniform(1000, 1600)],
                centres[target],
            )
            seen = visible_markers(m, cam, T)
            if target in seen and (ids[worst] in seen) == must_see_worst:
                return T, seen

    # Enough candidates that guessing the index is no way to answer: one shows the worst marker, the rest not.
    picks = [candidate(ids[worst], True)] + [candidate(int(t), False) for t in rng.choice(others, size=_Q4_N - 1)]
    order = rng.permutation(_Q4_N)
    cands = [picks[i][0] for i in order]
    seen = [picks[i][1] for i in order]
    return m, cam, std, np.array(cands), seen, int(np.flatnonzero(order == 0)[0])


def _q4(learner: str) -> Question:
    """q4: Which photo to take next?"""
    rng = _rng("11", learner, "q4")
    m, cam, std, cands, seen, key = _q4_layout(rng)
    most = max(range(_Q4_N), key=lambda c: len(seen[c]))
    best_id = m.ids[int(np.argmin(std))]
    best = [c for c in range(_Q4_N) if best_id in seen[c] and c != key]
    worst_id = m.ids[int(np.argmax(std))]
    wrong = [
        (
            lambda a: int(round(a)) == most != key,
            f"that photo shows the most markers, but not marker {worst_id}, the worst determined: a photo helps "
            "only the markers it shows",
        ),
        (
            lambda a: int(round(a)) in best,
            f"that photo shows marker {best_id}, the best determined already; look for the one with the largest std",
        ),
        (
            lambda a: int(round(a)) == key + 1,
            "the indices start at 0: candidates[0] is the first",
        ),
    ]
    return Question(
        "q4",
        inputs={"marker_map": m, "camera": cam, "position_std_mm": std, "candidates": cands},
        expected=float(key),
        parse=_scalar("the candidate's index"),
        compare=lambda a, b: None if abs(a - b) < 0.5 else "that photo does not show the worst-determined marker",
        wrong=wrong,
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 11 for one learner, in notebook order.

    Parameters
    ----------
    learner : str
        The learner's id; it seeds every question's numbers (``""``: the class's shared variant).

    Returns
    -------
    list of Question
        q1, q2, q3, q4, q5, q6, with their answer keys.
    """
    return [_q1(learner), _q2(learner), _q3(learner), _q4(learner), _q5(learner), _q6(learner)]
