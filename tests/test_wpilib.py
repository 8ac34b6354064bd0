"""WPILib AprilTag field layouts: read and written with the tag frame and corner order checked on known geometry."""

import json

import numpy as np
import pytest

from fidlearn import Camera, MarkerMap, MarkerTracker, detect_markers, estimate_pose, frames, locate
from fidlearn.data import data_path
from fidlearn.detection import Detection
from fidlearn.errors import MapError, PoseError
from fidlearn.frames import look_at
from fidlearn.synthetic import render_scene

CRESCENDO = data_path("wpilib", "2024-crescendo.json")
FRC = {"dictionary": "apriltag_36h11", "marker_size_mm": 165.1}  # FRC's 6.5 in tags
H = 165.1 / 2


def crescendo():
    return MarkerMap.load(CRESCENDO, **FRC)


def test_the_2024_layout_loads_with_each_tags_centre_and_facing():
    m = crescendo()
    assert m.ids == list(range(1, 17))
    assert (m.units, m.dictionary, m.marker_size_mm, m.field_m) == ("m", "APRILTAG_36h11", 165.1, (16.541, 8.211))
    # tag 7: on the blue alliance wall (x = -0.0381 m), rotation identity: facing +X, into the field,
    # TL -> TR along +Y (to the right of someone on the field looking at it)
    c7 = np.array([-38.1, 5547.868, 1451.102])
    expected7 = c7 + [[0, -H, H], [0, H, H], [0, H, -H], [0, -H, -H]]
    assert np.allclose(m.corners()[7], expected7, atol=1e-9)
    assert np.allclose(m.normal(7), [1, 0, 0])
    # tag 3: on the red wall (x = 16.579 m), yaw 180: facing -X, TL -> TR along -Y
    c3 = np.array([16579.342, 4982.718, 1451.102])
    assert np.allclose(m.corners()[3], c3 + [[0, H, H], [0, -H, H], [0, -H, -H], [0, H, -H]], atol=1e-9)
    assert np.allclose(m.normal(3), [-1, 0, 0])
    # every tag's centre is the file's translation
    for tag in json.loads(CRESCENDO.read_text())["tags"]:
        t = tag["pose"]["translation"]
        assert np.allclose(m.T_world_marker(tag["ID"])[:3, 3], [1000 * t[a] for a in "xyz"], atol=1e-9)


def test_saving_as_wpilib_writes_the_file_back(tmp_path):
    m = crescendo()
    out = m.save(tmp_path / "layout.json", format="wpilib")
    a, b = json.loads(CRESCENDO.read_text()), json.loads(out.read_text())
    assert b["field"] == a["field"]
    assert [t["ID"] for t in b["tags"]] == [t["ID"] for t in a["tags"]]
    for ta, tb in zip(a["tags"], b["tags"]):
        assert np.allclose([tb["pose"]["translation"][k] for k in "xyz"], [ta["pose"]["translation"][k] for k in "xyz"])
        qa = np.array([ta["pose"]["rotation"]["quaternion"][k] for k in "WXYZ"])
        qb = np.array([tb["pose"]["rotation"]["quaternion"][k] for k in "WXYZ"])
        assert min(np.abs(qa - qb).max(), np.abs(qa + qb).max()) < 1e-9  # q and -q are one rotation
    back = MarkerMap.load(out, **FRC)
    for k in m.ids:
        assert np.allclose(back.corners()[k], m.corners()[k], atol=1e-9)


def test_a_fidlearn_map_saves_as_a_layout_of_its_tags_centres(tmp_path):
    m = MarkerMap.from_dict(
        {"units": "mm", "marker_size_mm": 100, "markers": {"4": {"translation": [0, 200, 1000], "rotation": [0, 0, 0]}}}
    )
    with pytest.raises(MapError, match="field's length and width .m., which this map does not hold"):
        m.save(tmp_path / "w.json", format="wpilib")
    for bad in ((0, 2), (3,), "3x2", (3, float("nan"))):
        with pytest.raises(MapError, match="field_m"):
            m.save(tmp_path / "w.json", format="wpilib", field_m=bad)
    with pytest.raises(MapError, match="the full layout holds none"):
        m.save(tmp_path / "w.json", field_m=(3, 2))
    assert not list(tmp_path.iterdir())
    d = json.loads(m.save(tmp_path / "w.json", format="wpilib", field_m=(3, 2)).read_text())
    assert d["field"] == {"length": 3.0, "width": 2.0}
    assert d["tags"][0]["pose"]["translation"] == {"x": 0.0, "y": 0.25, "z": 0.95}
    assert d["tags"][0]["pose"]["rotation"]["quaternion"] == {"W": 1.0, "X": 0.0, "Y": 0.0, "Z": 0.0}
    back = MarkerMap.load(tmp_path / "w.json", dictionary="ARUCO_ORIGINAL", marker_size_mm=100)
    assert np.allclose(back.corners()[4], m.corners()[4])


@pytest.mark.parametrize(
    ("edit", "kwargs", "match"),
    [
        (None, {"dictionary": "apriltag_36h11"}, "does not say its tags' marker_size_mm; give them"),
        (None, {"marker_size_mm": 165.1}, "does not say its tags' dictionary"),
        (None, {**FRC, "units": "ft"}, "is in metres, but units='ft' was given"),
        (lambda d: d["tags"][0].pop("ID"), FRC, 'tags\\[0\\]: no "ID"'),
        (lambda d: d["tags"][1].update(ID=1), FRC, "tag ID 1 appears twice"),
        (lambda d: d["tags"][0]["pose"]["rotation"]["quaternion"].update(W=2.0), FRC, "quaternion has length"),
        (lambda d: d["tags"][0]["pose"]["translation"].update(x="1"), FRC, "translation x must be a finite number"),
        (lambda d: d["tags"][0]["pose"]["translation"].update(x=10**400), FRC, "translation x must be a finite"),
        (lambda d: d["tags"][0]["pose"]["translation"].update(x=1e10), FRC, "at most 1e"),
        (lambda d: d["field"].update(length=0), FRC, "field: length 0 and width 8.211 must both be above 0"),
        (lambda d: d["field"].update(width=-1), FRC, "must both be above 0"),
        (lambda d: d["tags"][0]["pose"].pop("rotation"), FRC, 'tag 1: no "rotation"'),
        (lambda d: d.update(tags=[]), FRC, '"tags" must be a non-empty list'),
        (lambda d: d["tags"][0].update(ID=600), FRC, "marker id 600 does not exist in dictionary APRILTAG_36h11"),
    ],
)
def test_layout_mistakes_say_what_to_mend(edit, kwargs, match):
    d = json.loads(CRESCENDO.read_text())
    if edit is not None:
        edit(d)
    with pytest.raises(MapError, match=match):
        MarkerMap.from_dict(d, source="layout.json", **kwargs)


def test_a_map_of_two_sizes_or_an_unknown_format_is_not_saved(tmp_path):
    two = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 80,
            "markers": {"0": {"translation": [0, 0, 0]}, "1": {"translation": [0, 200, 0], "size_mm": 120}},
        }
    )
    with pytest.raises(MapError, match="holds tags of one family and one size"):
        two.save(tmp_path / "w.json", format="wpilib")
    with pytest.raises(MapError, match="unknown map format 'ros'"):
        two.save(tmp_path / "w.json", format="ros")
    assert not list(tmp_path.iterdir())


CAM = Camera([[1500, 0, 639.5], [0, 1500, 359.5], [0, 0, 1]], [0, 0, 0, 0, 0], (1280, 720))
#: a camera on the field 1 m in front of tag 7, seeing it alone
T_ONE = look_at([1000, 5650, 1300], [0, 5548, 1450])


def mirrored_layout() -> dict:
    """The 2024 layout with every tag turned a half turn about its vertical axis: TL and TR (and BL and BR) change
    places, as a tag frame with y to the viewer's left (or z into the tag) makes them."""
    d = json.loads(CRESCENDO.read_text())
    for t in d["tags"]:
        q = t["pose"]["rotation"]["quaternion"]
        R = frames.matrix_from_quaternion(np.array([q["X"], q["Y"], q["Z"], q["W"]]))
        x, y, z, w = frames.quaternion_from_matrix(R @ frames.rotation_from_rpy_deg(0, 0, 180))
        t["pose"]["rotation"]["quaternion"] = {"W": w, "X": x, "Y": y, "Z": z}
    return d


def test_tags_are_located_on_the_field():
    m = crescendo()
    T = look_at([2500, 5000, 1000], [0, 5265, 1450])
    sc = render_scene(m, Camera.from_fov(70, (1280, 720)), T, seed=1, noise_std_gray=2)
    assert sorted(sc.truth) == [7, 8]
    pose = locate(sc.image, m, Camera.from_fov(70, (1280, 720)))
    assert pose.marker_ids == (7, 8)
    assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 15.0
    one = locate(render_scene(m, CAM, T_ONE, seed=2, noise_std_gray=2).image, m, CAM)
    assert one.marker_ids == (7,)
    assert np.linalg.norm(one.position_mm - T_ONE[:3, 3]) < 15.0


def test_mirrored_corners_give_a_pose_behind_the_wall_that_is_refused():
    m = crescendo()
    mirrored = MarkerMap.from_dict(mirrored_layout(), source="mirrored.json", **FRC)
    assert np.allclose(mirrored.corners()[7], m.corners()[7][[1, 0, 3, 2]])
    sc = render_scene(m, CAM, T_ONE, seed=2, noise_std_gray=2)
    dets = detect_markers(sc.image, m.dictionary)
    # the trap: one tag, mirrored, fits from behind the wall with a residual as small as the truth's
    behind = estimate_pose(dets, mirrored, CAM)
    assert behind.reprojection_rms_px < 0.1
    assert behind.position_mm[0] < -900  # about 1 m behind the blue alliance wall
    with pytest.raises(PoseError, match=r"outside the 16.541 x 8.211 m field of mirrored.json: a pose behind"):
        locate(sc.image, mirrored, CAM)
    tracker = MarkerTracker(mirrored, CAM)
    with pytest.raises(PoseError, match="pose behind the tags' wall"):
        tracker.locate(sc.image)
    assert tracker.last_pose is None


def test_image_corners_listed_mirrored_are_refused_with_the_fix():
    m = crescendo()
    sc = render_scene(m, CAM, T_ONE, seed=2, noise_std_gray=2)
    d = detect_markers(sc.image, m.dictionary)[0]
    with pytest.raises(PoseError, match=r"run anticlockwise on the screen.*corners\[\[0, 3, 2, 1\]\] puts them right"):
        estimate_pose([Detection(d.id, d.corners_px[[1, 0, 3, 2]], d.dictionary)], m, CAM)


def test_a_map_without_a_field_is_not_bounded():
    m = crescendo()
    m.field_m = None
    mirrored = MarkerMap.from_dict(mirrored_layout(), **FRC)
    mirrored.field_m = None
    sc = render_scene(m, CAM, T_ONE, seed=2, noise_std_gray=2)
    assert locate(sc.image, mirrored, CAM).position_mm[0] < -900


def test_fidlearn_locate_takes_a_field_layout_with_its_family_and_size(tmp_path, capsys):
    from fidlearn.cli import main
    from fidlearn.images import write_image

    m = crescendo()
    write_image(tmp_path / "frame.png", render_scene(m, CAM, T_ONE, seed=2, noise_std_gray=2).image)
    CAM.save(tmp_path / "camera.json")
    argv = ["locate", str(tmp_path / "frame.png"), "--camera", str(tmp_path / "camera.json"), "--map", str(CRESCENDO)]
    assert main([*argv, "--dictionary", "apriltag_36h11", "--marker-size-mm", "165.1"]) == 0
    assert "frame.png" in capsys.readouterr().out
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "does not say its tags' dictionary or marker_size_mm" in err[0]


def test_a_wall_of_tags_saved_with_its_field_locates_the_camera_in_front_of_it(tmp_path):
    """Tags on the wall x = 0 facing +x, a camera 2 m in front: the layout saved with a field that holds the
    camera reads back to the same pose (a field made up from the tags' extent, 0 m long, refused it)."""
    m = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 165.1,
            "dictionary": "apriltag_36h11",
            "markers": {
                str(i): {"translation": [0, y, z]} for i, y, z in ((1, 0, 1500), (2, 600, 1500), (3, 300, 1000))
            },
        }
    )
    T = look_at([2000, 300, 1400], [0, 300, 1300])
    cam = Camera.from_fov(60, (1280, 720))
    image = render_scene(m, cam, T, seed=1).image
    back = MarkerMap.load(m.save(tmp_path / "w.json", format="wpilib", field_m=(4, 2)), **FRC)
    assert back.field_m == (4.0, 2.0)
    pose = locate(image, back, cam)
    assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 10
