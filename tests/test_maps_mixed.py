"""Maps as people build them: markers of their own size and dictionary in one map, found, used and printed."""

import json
import operator
import pickle

import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, MarkerKey, MarkerMap, MarkerPlacement, MarkerTracker, detect_markers, locate
from fidlearn.detection import Detection
from fidlearn.errors import MapError, NoMarkersError
from fidlearn.frames import look_at
from fidlearn.printables import layout_map_markers
from fidlearn.synthetic import MIXED_WALL, render_scene

#: Four 80 mm ARUCO_ORIGINAL markers and two 200 mm 4X4_50 markers whose ids (0, 1) the small ones use too.
MIXED = MIXED_WALL
CAM = Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.05, 0.02, 0, 0, 0], (640, 480))


def mixed():
    return MarkerMap.from_dict(MIXED, source="mixed.json")


def test_each_marker_has_its_size_and_dictionary_and_the_map_keeps_its_defaults():
    m = mixed()
    big0, big1 = MarkerKey(0, "4X4_50"), MarkerKey(1, "4X4_50")
    assert m.ids == [0, big0, 1, big1, 2, 3]
    assert (m.marker_size_mm, m.dictionary, m.dictionaries) == (80.0, "ARUCO_ORIGINAL", ["ARUCO_ORIGINAL", "4X4_50"])
    assert [m.marker_size(k) for k in m.ids] == [80, 200, 80, 200, 80, 80]
    assert [m.marker_dictionary(k) for k in m.ids] == ["ARUCO_ORIGINAL", "4X4_50"] * 2 + ["ARUCO_ORIGINAL"] * 2
    assert m.corners()[big0].tolist() == [[0, 800, 1500], [0, 1000, 1500], [0, 1000, 1300], [0, 800, 1300]]
    assert m.corners()[0].tolist() == [[0, 0, 1400], [0, 80, 1400], [0, 80, 1320], [0, 0, 1320]]
    assert np.allclose(m.T_world_marker(big1)[:3, 3], [0, 900, 1000])
    assert np.allclose(m.T_world_marker(big1)[:3, :3], m.T_world_marker(1)[:3, :3])
    assert (m.key(1), m.key(1, "DICT_4X4_50"), m.ids_in("4X4_50")) == (1, big1, [0, 1])
    assert "80 and 200 mm, ARUCO_ORIGINAL and 4X4_50" in repr(m)


def test_a_marker_is_its_dictionary_and_id():
    k = MarkerKey(3, "4X4_50")
    assert k != 3
    assert operator.ne(3, k)  # a plain id on the left too
    assert k == MarkerKey(3, "4X4_50")
    assert k != MarkerKey(3, "6X6_250")
    assert len({k, 3, MarkerKey(3, "4X4_50")}) == 2
    assert (str(k), f"{k:d}", k.id, json.dumps([k])) == ("4X4_50:3", "3", 3, "[3]")
    assert pickle.loads(pickle.dumps(k)) == k


def test_the_full_layout_round_trips_with_sizes_and_dictionaries(tmp_path):
    m = mixed()
    d = m.to_dict()
    assert d["markers"]["4X4_50:1"] == {
        "translation": [0.0, 800.0, 1100.0],
        "rotation": [0.0, 0.0, 0.0],
        "size_mm": 200.0,
        "dictionary": "4X4_50",
    }
    assert d["markers"]["2"] == {"translation": [0.0, 0.0, 1100.0], "rotation": [0.0, 0.0, 0.0]}
    back = MarkerMap.load(m.save(tmp_path / "m.json"))
    assert back.ids == m.ids
    for k in m.ids:
        assert np.array_equal(back.corners()[k], m.corners()[k])
    assert json.loads((tmp_path / "m.json").read_text())["markers"].keys() == d["markers"].keys()


def test_the_seeds_bare_layout_loads_as_before():
    m = MarkerMap.from_dict({"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}}, units="ft", marker_size_mm=80)
    assert [type(k) for k in m.corners()] == [int]
    assert m.corners()[0].tolist() == [[0, 0, 304.8], [0, 80, 304.8], [0, 80, 224.8], [0, 0, 224.8]]
    assert (m.dictionaries, m.marker_size(0), m.placements[0].size_mm, m.placements[0].dictionary) == (
        ["ARUCO_ORIGINAL"],
        80.0,
        None,
        None,
    )


def test_a_marker_of_the_maps_own_dictionary_named_again_is_the_same_marker():
    d = {"units": "mm", "marker_size_mm": 80, "markers": {"ARUCO_ORIGINAL:4": {"translation": [0, 0, 0]}}}
    m = MarkerMap.from_dict(d)
    assert m.ids == [4]
    assert m.to_dict()["markers"] == {"4": {"translation": [0.0, 0.0, 0.0], "rotation": [0.0, 0.0, 0.0]}}


@pytest.mark.parametrize(
    ("markers", "match"),
    [
        ({"0": {"translation": [0, 0, 0], "size_mm": 0}}, "marker 0: size_mm is 0; it must be positive"),
        ({"0": {"translation": [0, 0, 0], "size_mm": 0.2}}, "size_mm is 0.2, under 1 mm; if that is metres"),
        ({"0": {"translation": [0, 0, 0], "size_mm": "80"}}, "size_mm must be a number"),
        ({"0": {"translation": [0, 0, 0], "dictionary": "4X4_5"}}, "unknown ArUco dictionary '4X4_5'"),
        ({"4X4_50:0": {"translation": [0, 0, 0], "dictionary": "5X5_50"}}, "names dictionary 4X4_50 in its key but"),
        ({"0": {"translation": [0, 0, 0], "size": 200}}, "unknown field 'size': did you mean 'size_mm'"),
        ({"0": {"translation": [0, 0, 0]}, "ARUCO_ORIGINAL:0": {"translation": [0, 1, 0]}}, "marker 0 appears twice"),
        (
            {"4X4_50:0": {"translation": [0, 0, 0]}, "0": {"translation": [0, 1, 0], "dictionary": "4X4_50"}},
            "marker 4X4_50:0 appears twice",
        ),
        ({"4X4_50:60": {"translation": [0, 0, 0]}}, "marker id 60 does not exist in dictionary 4X4_50"),
        (  # 4X4_50's markers are 4X4_250's first 50: one printed marker
            {"4X4_50:3": {"translation": [0, 0, 0]}, "4X4_250:3": {"translation": [0, 600, 0]}},
            "markers 4X4_50:3 and 4X4_250:3 are one printed pattern",
        ),
    ],
)
def test_per_marker_mistakes_name_the_marker_and_the_fix(markers, match):
    with pytest.raises(MapError, match=match):
        MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80, "markers": markers}, source="m.json")


def test_a_key_is_asked_for_by_a_whole_id_and_a_known_dictionary():
    m = mixed()
    assert m.key(1, "4X4_50") == MarkerKey(1, "4X4_50")
    assert m.key(MarkerKey(1, "4X4_50")) == MarkerKey(1, "4X4_50")  # a key keeps its dictionary
    assert m.key(np.int64(1)) == 1
    for bad in ("abc", None, 3.7, -1, True):
        with pytest.raises(MapError, match="a marker id is a whole number >= 0"):
            m.key(bad)
    with pytest.raises(fidlearn.FidlearnError, match="unknown ArUco dictionary"):
        m.key(1, "4X4_5")


def test_nested_dictionaries_hold_different_markers_apart():
    """4X4_250's marker 60 is not among 4X4_50's 50: both in one map are two markers."""
    m = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 80,
            "dictionary": "4X4_50",
            "markers": {"3": {"translation": [0, 0, 0]}, "4X4_250:60": {"translation": [0, 600, 0]}},
        }
    )
    assert m.ids == [3, MarkerKey(60, "4X4_250")]


def test_placements_given_in_python_are_keyed_by_dictionary_and_id():
    p = {
        0: MarkerPlacement(0, (0, 0, 0), (0, 0, 0)),
        1: MarkerPlacement(0, (0, 500, 0), (0, 0, 0), size_mm=150, dictionary="DICT_6X6_250"),
    }
    m = MarkerMap(p, 80, units="mm")
    assert m.ids == [0, MarkerKey(0, "6X6_250")]
    assert m.corners()[MarkerKey(0, "6X6_250")][2].tolist() == [0, 650, -150]


def scene(m, eye, target, seed=0):
    return render_scene(m, CAM, look_at(eye, target), seed=seed, noise_std_gray=2.0, blur_px=0.6)


def test_detection_finds_every_dictionary_and_keeps_equal_ids_apart():
    m = mixed()
    sc = scene(m, [2200, 500, 1300], [0, 500, 1250])
    assert len(sc.truth) == 6
    dets = detect_markers(sc.image, m.dictionaries)
    assert [(d.id, d.dictionary) for d in dets] == [
        (0, "ARUCO_ORIGINAL"),
        (0, "4X4_50"),
        (1, "ARUCO_ORIGINAL"),
        (1, "4X4_50"),
        (2, "ARUCO_ORIGINAL"),
        (3, "ARUCO_ORIGINAL"),
    ]
    for d in dets:
        assert np.abs(d.corners_px - sc.truth[m.key(d.id, d.dictionary)]).max() < 0.5
    only = detect_markers(sc.image, ["4X4_50", "ARUCO_ORIGINAL"], ids={"4X4_50": [1]})
    assert [(d.id, d.dictionary) for d in only] == [(1, "4X4_50")]
    assert [d.id for d in detect_markers(sc.image, "4X4_50")] == [0, 1]


def test_a_detection_meets_its_own_dictionarys_marker_only():
    m = mixed()
    T = look_at([2000, 500, 1300], [0, 500, 1250])
    big = MarkerKey(0, "4X4_50")
    as_big = [Detection(0, CAM.project(m.marker_corners(big), T), "4X4_50")]
    as_big.append(Detection(1, CAM.project(m.marker_corners(MarkerKey(1, "4X4_50")), T), "4X4_50"))
    pose = fidlearn.estimate_pose(as_big, m, CAM)
    assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 1e-3
    assert pose.marker_ids == (big, MarkerKey(1, "4X4_50"))
    with pytest.raises(NoMarkersError, match="ARUCO_ORIGINAL and 4X4_50"):
        fidlearn.estimate_pose([Detection(0, as_big[0].corners_px, "6X6_250")], m, CAM)


def viewpoints(n, seed=3):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        d = rng.uniform(1000, 3500)
        target = np.array([0, rng.uniform(0, 900), rng.uniform(900, 1400)])
        v = np.array([1, rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3)])
        yield look_at(target + d * v / np.linalg.norm(v), target, roll_deg=rng.uniform(-15, 15))


def test_locate_on_renders_with_80_and_200_mm_markers():
    m = mixed()
    errors, frames = [], 0
    for k, T in enumerate(viewpoints(12)):
        sc = render_scene(m, CAM, T, seed=k, noise_std_gray=2.0, blur_px=0.6)
        if not sc.truth:
            continue
        frames += 1
        pose = locate(sc.image, m, CAM)  # no frame without a pose: this raises
        errors.append(np.linalg.norm(pose.position_mm - T[:3, 3]))
        big = [i for i in sc.truth if m.marker_size(i) == 200]
        assert set(big) <= set(pose.marker_ids), (k, big, pose.marker_ids)
    assert frames >= 10
    assert np.median(errors) <= 3.0, errors
    # the same pictures with the map's one size for every marker: the big markers' corners no longer fit
    one_size = MarkerMap.from_dict({**MIXED, "markers": {k: {**v, "size_mm": 80} for k, v in MIXED["markers"].items()}})
    T = look_at([2200, 500, 1300], [0, 500, 1250])
    with pytest.raises(fidlearn.PoseError, match="do not fit the map"):
        locate(render_scene(m, CAM, T).image, one_size, CAM, reject_outliers=False)


def test_the_tracker_uses_every_dictionary_and_size():
    m = mixed()
    drive = fidlearn.render_trajectory(m, CAM, n_frames=40, frames_to_render=range(0, 8))
    tracker = MarkerTracker(m, CAM)
    for image, T in zip(drive.images, drive.T_world_camera):
        pose = tracker.locate(image)
        assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 5.0
        assert MarkerKey(0, "4X4_50") in pose.marker_ids
    assert (tracker.frames, tracker.full_detections) == (8, 1)
    assert {d.dictionary for d in tracker.last_detections} == {"ARUCO_ORIGINAL", "4X4_50"}


def test_printables_print_each_marker_at_its_size():
    sizes = {"4X4_50:0": 140, "4X4_50:1": 120}
    markers = {k: {**v, "size_mm": sizes[k]} if k in sizes else v for k, v in MIXED["markers"].items()}
    sheets = layout_map_markers(MarkerMap.from_dict({**MIXED, "markers": markers}))
    assert [(s.dictionary, s.marker_size_mm, [i for p in s.pages for i, _, _ in p]) for s in sheets] == [
        ("ARUCO_ORIGINAL", 80.0, [0, 1, 2, 3]),
        ("4X4_50", 120.0, [1]),
        ("4X4_50", 140.0, [0]),
    ]
    assert sheets[2].cell_mm == pytest.approx(140 / 6)
    with pytest.raises(fidlearn.errors.PrintError, match=r"markers 4X4_50:0, 4X4_50:1 are 200 mm, too large"):
        layout_map_markers(mixed())


def test_fidlearn_markers_prints_a_map_at_each_markers_size(tmp_path, capsys):
    from fidlearn.cli import main

    sizes = {"4X4_50:0": 140, "4X4_50:1": 120}
    markers = {k: {**v, "size_mm": sizes[k]} if k in sizes else v for k, v in MIXED["markers"].items()}
    (tmp_path / "m.json").write_text(json.dumps({**MIXED, "markers": markers}))
    assert main(["markers", "--map", str(tmp_path / "m.json"), "-o", str(tmp_path / "m.pdf")]) == 0
    out = capsys.readouterr().out
    assert "4 markers of 80 mm (ARUCO_ORIGINAL) and 1 marker of 120 mm (4X4_50) and 1 marker of 140 mm" in out
    assert "(4X4_50) on 4 a4 pages" in out  # two of 80 mm a page, one page for each larger size
    assert (tmp_path / "m.pdf").read_bytes().startswith(b"%PDF")
    (tmp_path / "big.json").write_text(json.dumps(MIXED))
    assert main(["markers", "--map", str(tmp_path / "big.json"), "-o", str(tmp_path / "big.pdf")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("error: ")
    assert "are 200 mm, too large for one a4 page" in err[0]
    assert not (tmp_path / "big.pdf").exists()


def test_a_maps_boards_are_printed_whole_not_as_loose_markers(tmp_path, capsys):
    """fidlearn markers --map printed a ChArUco entry's 17 markers as cut-out markers, with no squares: the board
    the map describes could not be rebuilt from them. A bundle's markers are loose markers on an object."""
    from fidlearn.cli import main

    board = {"type": "charuco", "translation": [0, 0, 500], "squares": [5, 7], "square_mm": 40, "marker_mm": 28,
             "dictionary": "6X6_250"}  # fmt: skip
    dock = {"translation": [0, 900, 0], "markers": {"40": {"translation": [0, 0, 0]}}}
    single = {"30": {"translation": [0, 500, 500]}}
    d = {"units": "mm", "marker_size_mm": 50, "dictionary": "6X6_250", "markers": single, "boards": {"wall": board},
         "bundles": {"dock": dock}}  # fmt: skip
    sheets = layout_map_markers(MarkerMap.from_dict(d))
    assert sorted(i for s in sheets for page in s.pages for i, _, _ in page) == [30, 40]
    (tmp_path / "m.json").write_text(json.dumps(d))
    assert main(["markers", "--map", str(tmp_path / "m.json"), "-o", str(tmp_path / "m.pdf")]) == 0
    out = capsys.readouterr().out
    assert (
        "board 'wall' is not on these pages: fidlearn board --squares 5x7 --square-mm 40 --charuco --marker-mm 28 "
        "--dictionary 6X6_250 -o wall.pdf" in out
    )
    only = {**d, "markers": {}, "bundles": {}}
    with pytest.raises(fidlearn.errors.PrintError, match="every marker of the map is on a board"):
        layout_map_markers(MarkerMap.from_dict(only))
