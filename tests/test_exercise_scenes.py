"""Every exercise variant is a scene that could exist: checked for 200 learners, question by question.

Markers hang on the room's walls (or lie on its floor) and face into the room; cameras stand in the
room, in front of the markers they see, and every marker or corner they see lies inside their
image. Each question says where its scene is in :data:`SCENES`; a question without a scene (a field
of view, a rotation, numbers for a formula) says so, and a new question must be listed.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn import exercises, frames
from fidlearn.exercises._scenery import _SIZES, ROOM_MM, _rng
from fidlearn.exercises.lessons import (
    _l11_two_view,
    l01_pinhole,
    l02_calibration,
    l03_extrinsics,
    l04_world_map,
    l05_detection,
    l06_pnp,
    l07_inversion,
    l08_accuracy,
    l09_robot,
    l10_tracking,
    l11_mapping,
)
from fidlearn.markermap import MarkerMap

LEARNERS = [f"learner{i:03d}" for i in range(200)] + [""]  # and the shared variant of the notebooks


class Scene:
    """What one variant puts in the room: markers, cameras, points seen, pixels in an image."""

    def __init__(
        self, marker_map=None, markers=(), cameras=(), camera=None, pixels=None, image_size=None, seen=None, inside=None
    ):
        self.markers = list(markers)  # (centre (3,), normal (3,), corners (4, 3) or None)
        if marker_map is not None:
            for i in marker_map.ids:
                c = marker_map.marker_corners(i)
                self.markers.append((c.mean(axis=0), marker_map.normal(i), c))
        self.cameras = [np.asarray(T, dtype=float) for T in cameras]  # T_world_camera
        self.camera = camera
        self.pixels = None if pixels is None else np.asarray(pixels, dtype=float).reshape(-1, 2)
        self.image_size = image_size or (camera.image_size if camera is not None else None)
        self.seen = None if seen is None else np.asarray(seen, dtype=float).reshape(-1, 3)  # world points, mm
        self.inside = np.zeros((0, 3)) if inside is None else np.asarray(inside, dtype=float).reshape(-1, 3)


def problems(scene: Scene) -> list[str]:
    """What is impossible about a scene, in words (empty when it could exist)."""
    lo, hi = ROOM_MM
    out = []
    corners = [c for _, _, c in scene.markers if c is not None]
    if corners:
        c = np.concatenate(corners)
        if np.any(c < lo - 0.5) or np.any(c > hi + 0.5):
            out.append(
                f"a marker corner is outside the room: {np.round(c[np.any((c < lo - 0.5) | (c > hi + 0.5), 1)][0])}"
            )
    for centre, normal, _ in scene.markers:
        ahead = centre + 10 * normal
        if np.any(ahead <= lo) or np.any(ahead >= hi):
            out.append(f"the marker at {np.round(centre)} faces {np.round(normal, 3)}: out of the room, into a wall")
    if np.any(scene.inside < lo - 1e-6) or np.any(scene.inside > hi + 1e-6):
        out.append(f"a point is outside the room: {np.round(scene.inside).tolist()}")
    for T in scene.cameras:
        eye = T[:3, 3]
        if np.any(eye <= lo + 50) or np.any(eye >= hi - 50):
            out.append(f"a camera stands at {np.round(eye)}, outside the room")
        out += _seen_from(scene, T)
    if scene.pixels is not None and scene.image_size is not None:
        w, h = scene.image_size
        p = scene.pixels
        if np.any(p < -0.5) or np.any(p[:, 0] > w - 0.5) or np.any(p[:, 1] > h - 0.5):
            out.append(
                f"a pixel lies outside the {w} x {h} image: x {p[:, 0].min():.0f}..{p[:, 0].max():.0f}, "
                f"y {p[:, 1].min():.0f}..{p[:, 1].max():.0f}"
            )
    return out


def _seen_from(scene: Scene, T_world_camera: np.ndarray) -> list[str]:
    """Problems of what the camera at T_world_camera sees: markers behind it, turned away or off the image."""
    out = []
    eye = T_world_camera[:3, 3]
    Tcw = frames.invert_transform(T_world_camera)
    for centre, normal, corners in scene.markers:
        if normal @ (eye - centre) <= 0:
            out.append(f"the camera at {np.round(eye)} sees the back of the marker at {np.round(centre)}")
        pts = corners if corners is not None else centre[None]
        if np.any(frames.transform_points(Tcw, pts)[:, 2] <= 0):
            out.append(f"the marker at {np.round(centre)} is behind the camera at {np.round(eye)}")
        elif scene.camera is not None:
            px = scene.camera.project(pts, T_world_camera)
            w, h = scene.camera.image_size
            if np.any(px < -0.5) or np.any(px[:, 0] > w - 0.5) or np.any(px[:, 1] > h - 0.5):
                out.append(f"the marker at {np.round(centre)} is (partly) outside the {w} x {h} image")
    if scene.seen is not None and np.any(frames.transform_points(Tcw, scene.seen)[:, 2] <= 0):
        out.append(f"a point the camera at {np.round(eye)} looks at is behind it")
    return out


def _T_world_camera_from(rvec, tvec) -> np.ndarray:
    return frames.invert_transform(frames.transform_from_rvec_tvec(np.ravel(rvec), np.ravel(tvec)))


def _pnp_pose(detections, marker_map, camera) -> np.ndarray:
    """The camera pose that the detections of mapped markers give (to check where that camera stands)."""
    known = [d for d in detections if d.id in marker_map]
    obj = np.concatenate([marker_map.marker_corners(d.id) for d in known])
    img = np.concatenate([d.corners_px for d in known])
    _, rvec, tvec = cv2.solvePnP(obj, img, camera.K, camera.dist)
    return _T_world_camera_from(rvec, tvec)


def _key(q):
    """The answer the question's own solution gives."""
    ns: dict = {}
    exec(exercises.SETUP_CODE, ns)
    ns[q.name] = q
    exec(q.solution_code, ns)
    return q.answer


def _marker(T_world_marker) -> tuple:
    return T_world_marker[:3, 3], T_world_marker[:3, 2], None


def _s01_q2(learner):
    q = l01_pinhole._q2(learner)
    K, P = q.inputs.K, q.inputs.points_camera_mm
    size = min(_SIZES, key=lambda s: abs(s[0] - 2 * K[0, 2]))
    ph = P @ K.T
    assert np.all(P[:, 2] > 0), "a point behind the camera"
    return Scene(pixels=ph[:, :2] / ph[:, 2:], image_size=size)


def _s01_q3(learner):
    q = l01_pinhole._q3(learner)
    side = q.inputs.side_px
    # a marker seen squarely in the middle of the image: its square fits in the picture
    return Scene(
        pixels=[[(q.inputs.camera.width - side) / 2, (q.inputs.camera.height - side) / 2]] * 2
        + [[(q.inputs.camera.width + side) / 2, (q.inputs.camera.height + side) / 2]],
        image_size=q.inputs.camera.image_size,
    )


def _s01_q5(learner):
    q = l01_pinhole._q5(learner)
    K, P = q.inputs.K, q.inputs.points_camera_mm
    size = min(_SIZES, key=lambda s: abs(s[0] - 2 * K[0, 2]))
    assert np.all(P[:, 2] > 0), "a point behind the camera"
    px = cv2.projectPoints(P, np.zeros(3), np.zeros(3), K, q.inputs.dist)[0]
    return Scene(pixels=px, image_size=size)


def _s02_q2(learner):
    q = l02_calibration._q2(learner)
    return Scene(pixels=np.concatenate(q.inputs.image_points), image_size=q.inputs.image_shape[::-1])


def _s03_q1(learner):
    q = l03_extrinsics._q1(learner)
    return Scene(inside=[q.inputs.position_mm])  # the robot stands in the room


def _s03_q2(learner):
    q = l03_extrinsics._q2(learner)
    return Scene(cameras=[q.inputs.T_world_camera], seen=q.inputs.points_world_mm)


def _s03_q3(learner):
    q = l03_extrinsics._q3(learner)
    Twm = q.inputs.T_world_marker
    return Scene(markers=[_marker(Twm)], cameras=[Twm @ frames.invert_transform(q.inputs.T_camera_marker)])


def _s03_q4(learner):
    q = l03_extrinsics._q4(learner)
    return Scene(cameras=[_T_world_camera_from(q.inputs.rvec, q.inputs.tvec)])


def _s04_q1(learner):
    q = l04_world_map._q1(learner)
    m = MarkerMap.from_dict(
        {str(q.inputs.marker_id): q.inputs.placement}, units="ft", marker_size_mm=q.inputs.marker_size_mm
    )
    return Scene(marker_map=m)


def _s04_q2(learner):
    return Scene(marker_map=MarkerMap.from_dict(_key(l04_world_map._q2(learner))))


def _s04_q4(learner):
    return Scene(marker_map=l04_world_map._q4(learner).inputs.marker_map)


def _s05(learner):
    cam, m, T, _, _ = l05_detection._layout(_rng("05", learner, "scene"), *l05_detection._SCENE_ARGS)
    return Scene(marker_map=m, cameras=[T], camera=cam)


def _s06_detections(builder):
    def scene(learner):
        q = builder(learner)
        cam, m = q.inputs.camera, q.inputs.marker_map
        px = np.concatenate([d.corners_px for d in q.inputs.detections])
        return Scene(marker_map=m, cameras=[_pnp_pose(q.inputs.detections, m, cam)], camera=cam, pixels=px)

    return scene


def _s06_q3(learner):
    q = l06_pnp._q3(learner)
    return Scene(
        cameras=[_T_world_camera_from(q.inputs.rvec, q.inputs.tvec)],
        camera=q.inputs.camera,
        pixels=q.inputs.image_points,
        seen=q.inputs.object_points,
    )


def _s07_rt(builder):
    return lambda learner: Scene(
        cameras=[_T_world_camera_from(builder(learner).inputs.rvec, builder(learner).inputs.tvec)]
    )


def _s06_q4(learner):
    q = l06_pnp._q4(learner)
    ideal = cv2.undistortPoints(
        q.inputs.corners_px.reshape(-1, 1, 2), q.inputs.camera.K, q.inputs.camera.dist, P=q.inputs.camera.K
    )
    return Scene(pixels=np.concatenate([q.inputs.corners_px, ideal.reshape(-1, 2)]), camera=q.inputs.camera)


def _s07_q5(learner):
    q = l07_inversion._q5(learner)
    T = _T_world_camera_from(q.inputs.rvec, q.inputs.tvec)
    hit = T[:3, 3] - T[0, 3] / T[0, 2] * T[:3, 2]
    return Scene(cameras=[T], seen=[hit], inside=[hit])


def _s07_q4(learner):
    q = l07_inversion._q4(learner)
    Twm = q.inputs.T_world_marker
    Tcm = frames.transform_from_rvec_tvec(q.inputs.rvec, q.inputs.tvec)
    return Scene(markers=[_marker(Twm)], cameras=[Twm @ frames.invert_transform(Tcm)])


def _s08_q2(learner):
    cam, m, T = l08_accuracy._q2_layout(_rng("08", learner, "q2"))
    return Scene(marker_map=m, cameras=[T], camera=cam)


def _s08_q3(learner):
    cam, m, dets, _, _ = l08_accuracy._ambiguous_view(_rng("08", learner, "q3"))
    return Scene(
        marker_map=m, cameras=[_pnp_pose(dets, m, cam)], camera=cam, pixels=np.concatenate([d.corners_px for d in dets])
    )


def _s09_q2(learner):
    return Scene(cameras=[l09_robot._q2(learner).inputs.T_world_camera])


def _s09_path(builder):
    def scene(learner):
        p = builder(learner).inputs.positions_mm
        return Scene(cameras=[frames.make_transform(np.eye(3), x) for x in p[~np.isnan(p).any(axis=1)]])

    return scene


def _s10_q3(learner):
    q = l10_tracking._q3(learner)
    T_world_base = q.inputs.T_world_camera @ q.inputs.T_camera_base
    return Scene(cameras=[q.inputs.T_world_camera], inside=[T_world_base[:3, 3]])  # the robot stands in the room


def _s10_q4(learner):
    q = l10_tracking._q4(learner)
    T, path = q.inputs.T_world_base_start, [q.inputs.T_world_base_start[:3, 3]]
    for step in q.inputs.odometry:
        T = T @ step
        path.append(T[:3, 3])
    return Scene(inside=path)  # the robot drives on the room's floor


def _s11_q2(learner):
    cam, m, T, _ = l11_mapping._q2_layout(_rng("11", learner, "q2"))
    q = l11_mapping._q2(learner)
    return Scene(marker_map=m, cameras=[T], camera=cam, pixels=q.inputs.detected_px)


def _s11_q4(learner):
    q = l11_mapping._q4(learner)
    return Scene(marker_map=q.inputs.marker_map, cameras=list(q.inputs.candidates))


def _s11_q6(learner):
    *_, (m, cam, T_1, T_2) = _l11_two_view._q6_data(_rng("11", learner, "q6"))
    return Scene(marker_map=m, cameras=[T_1, T_2], camera=cam)


#: Where each question's scene is, or why it has none (a str). Slow questions (rendered pictures,
#: repeated calibrations) are in :data:`SLOW`, checked for fewer learners.
SCENES = {
    ("01", "q1"): "a field of view and an image size",
    ("01", "q2"): _s01_q2,
    ("01", "q3"): _s01_q3,
    ("01", "q4"): "K and an image size",
    ("01", "q5"): _s01_q5,
    ("02", "q1"): "a board's size",
    ("02", "q2"): _s02_q2,
    ("02", "q4"): "K at two sizes",
    ("03", "q1"): _s03_q1,
    ("03", "q2"): _s03_q2,
    ("03", "q3"): _s03_q3,
    ("03", "q4"): _s03_q4,
    ("03", "q5"): "a rotation vector",
    ("04", "q1"): _s04_q1,
    ("04", "q2"): _s04_q2,
    ("04", "q3"): "a rotation on the floor",
    ("04", "q4"): _s04_q4,
    ("05", "q1"): _s05,
    ("05", "q2"): _s05,
    ("05", "q3"): _s05,
    ("05", "q4"): "a camera and a marker size for the detector's rule",
    ("06", "q1"): _s06_detections(l06_pnp._q1),
    ("06", "q2"): _s06_detections(l06_pnp._q2),
    ("06", "q3"): _s06_q3,
    ("06", "q4"): _s06_q4,
    ("07", "q1"): _s07_rt(l07_inversion._q1),
    ("07", "q2"): _s07_rt(l07_inversion._q2),
    ("07", "q3"): _s07_rt(l07_inversion._q3),
    ("07", "q4"): _s07_q4,
    ("07", "q5"): _s07_q5,
    ("08", "q1"): "distances for a formula",
    ("08", "q2"): _s08_q2,
    ("08", "q3"): _s08_q3,
    ("08", "q4"): "a floor area to design for (plan_room checks every wall rule)",
    ("09", "q2"): _s09_q2,
    ("09", "q3"): _s09_path(l09_robot._q3),
    ("09", "q4"): _s09_path(l09_robot._q4),
    ("10", "q1"): "three orientations of a robot on the floor",
    ("10", "q2"): "positions along a line, one coordinate",
    ("10", "q3"): _s10_q3,
    ("10", "q4"): _s10_q4,
    ("10", "q5"): "innovations and their covariances for a consistency test",
    ("10", "q6"): "two orientations of a camera for a rotation innovation",
    ("11", "q1"): "numbers of photos and markers for a count",
    ("11", "q2"): _s11_q2,
    ("11", "q3"): "differences and covariances for a test",
    ("11", "q4"): _s11_q4,
    ("11", "q5"): "printed and measured marker sides for a scale",
    ("11", "q6"): _s11_q6,
    ("12", "q1"): "a marker size, a printed size and a distance for a ratio",
    ("12", "q2"): "the bundled calibration views' corners for a count of cells",
    ("12", "q3"): "an uncertainty map and warnings for a verdict",
    ("12", "q4"): "two camera poses and a point for a prediction (every pixel checked inside the picture)",
    ("13", "q1"): "a robot, a static camera and a board for a chain of transforms",
    ("13", "q2"): "rotation vectors of motion pairs for an alignment",
    ("13", "q3"): "motion pairs for a linear least-squares solve",
    ("13", "q4"): "a chain and a measured pose for a comparison",
    ("14", "q1"): "one marker of a board in front of a pinhole camera (its builder keeps every pixel inside)",
    ("14", "q2"): "a board's markers and quads in front of a pinhole camera (its builder keeps the board inside)",
    ("14", "q3"): "numbers of corners per view for a count",
    ("15", "q1"): "a camera-frame point for the fisheye formula (its pixel drawn inside the picture)",
    ("15", "q2"): "a width and a field of view for a formula",
    ("15", "q3"): "differences and their noise for a ratio",
}


def _s02_q3(learner):
    q = l02_calibration._q3(learner)
    return Scene(pixels=np.concatenate(q.inputs.image_points), image_size=q.inputs.image_size)


#: Questions whose variants take a tenth of a second or more to build: checked for 20 learners.
SLOW = {
    ("02", "q3"): _s02_q3,
    ("02", "q5"): "pictures the library renders of a board in front of the camera",
    ("09", "q1"): "pictures the library renders along a drive through the course's room",
}


def test_every_question_says_where_its_scene_is():
    questions = {(n, q.name) for n in exercises.lessons() for q in exercises.lesson(n)}
    assert questions == set(SCENES) | set(SLOW)


@pytest.mark.slow
def test_every_variant_is_physically_possible_for_200_learners():
    bad = []
    for (number, name), scene_of in SCENES.items():
        if isinstance(scene_of, str):
            continue
        for learner in LEARNERS:
            bad += [f"{number} {name} {learner}: {p}" for p in problems(scene_of(learner))]
    by_question = sorted({b[:6] for b in bad})
    assert not bad, f"{len(bad)} impossible variants in {by_question}, first: " + "\n".join(bad[:10])


@pytest.mark.parametrize("key", [k for k, v in SLOW.items() if not isinstance(v, str)])
def test_slow_variants_are_physically_possible(key):
    bad = [f"{learner}: {p}" for learner in LEARNERS[:20] for p in problems(SLOW[key](learner))]
    assert not bad, "\n".join(bad[:10])


def test_the_checks_catch_what_the_course_once_did():
    """A wall marker behind the north wall, a marker off the image and a camera behind the wall are refused."""
    behind = MarkerMap.from_dict(
        {"3": {"translation": [-1000, -1828.8, 1000], "rotation": [0, 0, 90]}}, units="mm", marker_size_mm=100
    )
    assert any("outside the room" in p for p in problems(Scene(marker_map=behind)))
    q = l06_pnp._q2("")
    off = Scene(pixels=[[600, 840]], image_size=(1280, 720))
    assert any("outside the 1280 x 720 image" in p for p in problems(off))
    T = _pnp_pose(q.inputs.detections, q.inputs.marker_map, q.inputs.camera)
    flipped = T.copy()
    flipped[0, 3] = -flipped[0, 3]
    assert problems(Scene(marker_map=q.inputs.marker_map, cameras=[flipped]))
    assert not problems(Scene(marker_map=q.inputs.marker_map, cameras=[T], camera=q.inputs.camera))
