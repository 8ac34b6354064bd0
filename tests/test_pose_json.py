"""Pose.to_dict / Pose.from_dict: the record ``fidlearn locate --json`` writes, and back."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fidlearn
from fidlearn import Pose, PoseError, data_path
from fidlearn.cli import main
from fidlearn.detection import Detection, load_image

WORLD = fidlearn.MarkerMap.load(data_path("world_map.json"))
CAMERA = fidlearn.Camera.load(data_path("scenes", "camera.json"))
SCENE = data_path("scenes", "scene_00.png")


@pytest.fixture(scope="module")
def pose():
    return fidlearn.locate(load_image(SCENE), WORLD, CAMERA)


@pytest.fixture(scope="module")
def ambiguous():
    """One small marker seen face-on from afar: two planar poses explain it."""
    cam = fidlearn.Camera.from_fov(60, (640, 480))
    T = fidlearn.look_at([3000, 150, 250], [0, 150, 250])
    corners = WORLD.corners()
    rng = np.random.default_rng(3)
    dets = [Detection(0, cam.project(corners[0], T) + rng.normal(0, 0.3, (4, 2)))]
    out = fidlearn.estimate_pose(dets, WORLD, cam)
    assert out.alternative is not None
    return out


def test_a_hand_made_pose_gives_its_known_record():
    T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])
    cov = np.diag([1e-6, 1e-6, 1e-6, 4.0, 9.0, 16.0])
    d = Pose(T, (0, 2), {}, 0.5, cov, 0.2, rejected_ids=(1,), ignored_ids=(7,), method="ippe+lm").to_dict()
    assert list(d) == [
        "T_world_camera",
        "position_mm",
        "rpy_deg",
        "position_std_mm",
        "marker_ids",
        "reprojection_rms_px",
        "ambiguous",
        "rejected_ids",
        "ignored_ids",
        "method",
    ]
    assert d["position_mm"] == [1000.0, 150.0, 250.0]
    assert np.allclose(d["rpy_deg"], [-90.0, 0.0, 90.0])
    assert d["position_std_mm"] == [2.0, 3.0, 4.0]
    assert (d["marker_ids"], d["rejected_ids"], d["ignored_ids"], d["ambiguous"]) == ([0, 2], [1], [7], False)
    assert (d["reprojection_rms_px"], d["method"]) == (0.5, "ippe+lm")


def test_the_record_is_what_locate_writes(pose, tmp_path):
    out = tmp_path / "poses.jsonl"
    argv = ["locate", SCENE, "--camera", data_path("scenes", "camera.json"), "--map", data_path("world_map.json")]
    assert main([str(a) for a in argv] + ["--json", str(out)]) == 0
    line = json.loads(out.read_text().splitlines()[0])
    assert line == {"frame": "scene_00.png", "located": True, **json.loads(json.dumps(pose.to_dict()))}
    back = Pose.from_dict(line, source="poses.jsonl line 1")  # a locate line is read as it is
    np.testing.assert_allclose(back.T_world_camera, pose.T_world_camera, atol=1e-12)
    assert back.marker_ids == pose.marker_ids
    assert back.covariance is None
    assert np.isnan(back.corner_sigma_px)


def test_the_full_record_round_trips_through_json(pose, ambiguous):
    for p in (pose, ambiguous):
        d = json.loads(json.dumps(p.to_dict(full=True), allow_nan=False))
        back = Pose.from_dict(d)
        assert back.to_dict(full=True) == d
        np.testing.assert_allclose(back.covariance, p.covariance, rtol=1e-12)
        assert back.marker_rms_px == pytest.approx(p.marker_rms_px)
        assert back.corner_sigma_px == p.corner_sigma_px
        assert back.ambiguous == p.ambiguous
    back = Pose.from_dict(json.loads(json.dumps(ambiguous.to_dict(full=True))))
    np.testing.assert_allclose(back.alternative.T_world_camera, ambiguous.alternative.T_world_camera, atol=1e-9)
    assert "alternative_position_mm" in ambiguous.to_dict()


def test_the_short_record_round_trips_what_it_holds(pose):
    d = pose.to_dict()
    again = Pose.from_dict(d).to_dict()
    # neither the covariance nor the alternative pose is in the short record: only their read-outs
    assert again == {**{k: v for k, v in d.items() if k != "alternative_position_mm"}, "position_std_mm": None}


def test_markers_of_another_dictionary_keep_it_in_the_record():
    """A map's marker of a second dictionary is written as the map file writes its key, "4X4_50:0", not as its
    bare id (which reads as the map's own marker 0), and read back as that marker."""
    world = fidlearn.MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 120,
            "markers": {
                "0": {"translation": [0, 0, 1500]},
                "4X4_50:0": {"translation": [0, 400, 1500], "size_mm": 180},
                "1": {"translation": [0, -300, 1300]},
            },
        }
    )
    cam = fidlearn.Camera.from_fov(60, (1280, 720))
    T = fidlearn.look_at([2200, 100, 1500], [0, 100, 1400])
    dets = [Detection(int(k), cam.project(c, T), world.marker_dictionary(k)) for k, c in world.corners().items()]
    pose = fidlearn.estimate_pose(dets, world, cam)
    key = world.key(0, "4X4_50")
    d = json.loads(json.dumps(pose.to_dict(full=True)))
    assert d["marker_ids"] == [0, "4X4_50:0", 1]
    assert set(d["residuals_px"]) == {"0", "4X4_50:0", "1"}
    back = Pose.from_dict(d)
    assert back.marker_ids == (0, key, 1)
    assert set(back.residuals_px) == {0, key, 1}
    assert back.to_dict(full=True) == d


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda _d: [1, 2], r"expected a JSON object"),
        (lambda d: {k: v for k, v in d.items() if k != "marker_ids"}, r"missing field marker_ids"),
        (lambda d: {**d, "marker_id": [1]}, r"unknown field 'marker_id': did you mean 'marker_ids'\?"),
        (lambda d: {**d, "T_world_camera": np.eye(4)[:3].tolist()}, r"T_world_camera must be a 4x4 rigid"),
        (lambda d: {**d, "T_world_camera": (2 * np.eye(4)).tolist()}, r"T_world_camera must be a 4x4 rigid"),
        (lambda d: {**d, "marker_ids": [True]}, r"marker_ids must be a list of marker ids"),
        (lambda d: {**d, "marker_ids": [-1]}, r"marker_ids must be a list of marker ids"),
        (lambda d: {**d, "marker_ids": ["NO_SUCH_DICT:1"]}, r"marker_ids must be a list of marker ids"),
        (lambda d: {**d, "rejected_ids": "4X4_50:1"}, r"rejected_ids must be a list of marker ids"),
        (lambda d: {**d, "reprojection_rms_px": -1}, r"reprojection_rms_px must be a non-negative number"),
        (lambda d: {**d, "ambiguous": "no"}, r"ambiguous must be true or false"),
        (lambda d: {**d, "method": 3}, r"method must be text"),
        (lambda d: {**d, "covariance": [[1.0]]}, r"covariance must be a symmetric 6x6"),
        (lambda d: {**d, "residuals_px": {"a": [[0, 0]] * 4}}, r"residuals_px\['a'\] must be 4x2"),
        (lambda d: {**d, "located": False}, r"the frame was not located"),
    ],
)
def test_bad_records_are_refused_with_a_mending_message(pose, change, message):
    with pytest.raises(PoseError, match=r"^poses\.jsonl: " + message):
        Pose.from_dict(change(pose.to_dict()), source="poses.jsonl")
