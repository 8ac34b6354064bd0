"""The survey of a field from its official WPILib layout: the corrected layout, and which tag moved.

The red end of the 2024 field (tags 1-5 on the walls, 11 and 12 on the stage, 165.1 mm AprilTags) is built
with every tag within 3 mm of the official layout and tag 3 knocked 150 mm along the wall; photos are
rendered from that field and surveyed with the official layout as the starting map.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from helpers import run_cli

import fidlearn
from fidlearn import Camera, MarkerMap, MarkerPlacement
from fidlearn._wpilib import layout_format
from fidlearn.data import data_path
from fidlearn.errors import SurveyError
from fidlearn.frames import look_at
from fidlearn.survey import TagChange
from fidlearn.synthetic import render_scene, visible_markers

FRC = {"dictionary": "apriltag_36h11", "marker_size_mm": 165.1}
TAGS = (1, 2, 3, 4, 5, 11, 12)
MOVE_MM = np.array([0.0, 150.0, 0.0])
CAM = Camera([[700, 0, 639.5], [0, 700, 359.5], [0, 0, 1]], [-0.05, 0.02, 0, 0, 0], (1280, 720))


def red_end() -> dict:
    d = json.loads(data_path("wpilib", "2024-crescendo.json").read_text())
    return {**d, "tags": [t for t in d["tags"] if t["ID"] in TAGS]}


def built(official: MarkerMap, rng) -> MarkerMap:
    """The field as built: each tag within a few mm of the official placement, tag 3 moved 150 mm."""
    pl = {}
    for i, p in official.placements.items():
        t = np.add(p.translation_mm, rng.normal(0, 3.0, 3) + (MOVE_MM if i == 3 else 0))
        pl[i] = MarkerPlacement(i, tuple(t), p.rotation_deg)
    return MarkerMap(pl, official.marker_size_mm, dictionary=official.dictionary, units="m", source="built field")


def photo_poses(field: MarkerMap, rng, n: int = 20) -> list[np.ndarray]:
    """Standing 0.9-1.6 m high between the stage and the red wall, aiming near the tag seen least so far."""
    centres = {i: field.T_world_marker(i)[:3, 3] for i in field.ids}
    seen = dict.fromkeys(field.ids, 0)
    poses: list[np.ndarray] = []
    while len(poses) < n:
        eye = [rng.uniform(12500, 15500), rng.uniform(1000, 7500), rng.uniform(900, 1600)]
        aim = min(seen, key=lambda i: seen[i] + rng.uniform(0, 0.5))
        T = look_at(
            eye, centres[aim] + [rng.uniform(-800, 800), rng.uniform(-800, 800), 0], roll_deg=rng.uniform(-8, 8)
        )
        vis = visible_markers(field, CAM, T, margin_px=10)
        if len(vis) >= 2 and aim in vis:
            poses.append(T)
            for i in vis:
                seen[i] += 1
    return poses


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    folder = tmp_path_factory.mktemp("field")
    (folder / "layout.json").write_text(json.dumps(red_end()))
    official = MarkerMap.load(folder / "layout.json", **FRC)
    rng = np.random.default_rng(5)
    truth = built(official, rng)
    images = [
        render_scene(truth, CAM, T, seed=k, noise_std_gray=1.5, blur_px=0.6).image
        for k, T in enumerate(photo_poses(truth, rng))
    ]
    for k, img in enumerate(images):
        cv2.imwrite(str(folder / f"photo_{k:02d}.png"), img)
    CAM.save(folder / "camera.json")
    return folder, official, truth, fidlearn.survey(images, official, CAM)


def test_the_moved_tag_is_named_and_no_other(field):
    _, official, truth, s = field
    changes = s.tag_changes()
    assert [c.id for c in changes] == list(TAGS)
    assert all(isinstance(c, TagChange) for c in changes)
    assert [c.id for c in changes if c.moved] == [3]
    three = changes[TAGS.index(3)]
    # the surveyed centre is where tag 3 really is: 150 mm along +y, within the survey's noise
    true_offset = truth.T_world_marker(3)[:3, 3] - official.T_world_marker(3)[:3, 3]
    assert np.linalg.norm(three.offset_mm - true_offset) < 3 * three.distance_std_mm
    assert three.distance_mm == pytest.approx(150.0, abs=15.0)
    assert three.sigmas > 10
    for c in changes:
        if c.id != 3:
            # the others: within a few of the survey's standard deviations of the official placement
            assert c.distance_mm < 3 * c.distance_std_mm + 3.0
            assert c.angle_deg < 3 * c.angle_std_deg + 0.5
            assert c.sigmas < three.sigmas / 3
        assert c.photos >= 2
        assert 0 < c.distance_std_mm < 10
        assert 0 < c.angle_std_deg < 2


def test_the_centres_standard_deviation_comes_from_the_corners_and_the_rotation(field):
    _, _, _, s = field
    c = s.tag_changes()[0]
    cov = s.marker_covariance[c.id]
    # never smaller than the top-left corner's alone minus the rotation's lever (both are parts of it)
    corner = float(np.sqrt(np.trace(cov[3:, 3:])))
    lever = 165.1 / np.sqrt(2)  # mm from the corner to the centre
    rotation = float(np.sqrt(np.trace(cov[:3, :3])))
    assert abs(c.distance_std_mm - corner) <= lever * rotation + 1e-9


def test_the_corrected_layout_is_written_as_a_wpilib_layout(field, tmp_path):
    _, official, truth, s = field
    assert s.layout_format == "wpilib"
    assert official.to_dict()["units"] == "m"
    out = s.save(tmp_path / "surveyed.json")
    d = json.loads(out.read_text())
    assert set(d) == {"tags", "field"}
    assert d["field"] == red_end()["field"]
    back = MarkerMap.load(out, **FRC)
    assert back.ids == list(TAGS)
    for i in TAGS:
        assert np.allclose(back.corners()[i], s.marker_map.corners()[i], atol=1e-6)
    moved = back.T_world_marker(3)[:3, 3] - official.T_world_marker(3)[:3, 3]
    assert moved[1] == pytest.approx(150.0, abs=15.0)
    # the full layout, with the survey's note, when asked
    full = json.loads(s.save(tmp_path / "full.json", format="fidlearn").read_text())
    assert full["units"] == "m"
    assert "surveyed" in full
    with pytest.raises(SurveyError, match="unknown map format"):
        s.save(tmp_path / "x.json", format="yaml")
    # the same map read from the full layout is saved as the full layout
    again = MarkerMap.load(tmp_path / "full.json")
    assert again.to_dict()["markers"] == s.marker_map.to_dict()["markers"]
    assert layout_format(again) == "fidlearn"
    assert layout_format(official) == "wpilib"
    assert s.tag_report()[-1] == "tags moved from the official layout: 3"


def test_fidlearn_survey_reports_each_tag_against_the_official_layout(field, tmp_path, capsys):
    folder, official, _, _ = field
    out = tmp_path / "surveyed.json"
    code, stdout, stderr = run_cli(
        capsys, "survey", folder, "--camera", folder / "camera.json", "--map", folder / "layout.json",
        "--dictionary", "apriltag_36h11", "--marker-size-mm", "165.1", "-o", out,
    )  # fmt: skip
    assert code == 0, stderr
    assert "written as a WPILib field layout" in stdout
    assert "tags moved from the official layout layout.json: 3\n" in stdout
    verdicts = {int(ln.split()[0]): ln for ln in stdout.splitlines() if "+/-" in ln and ln.split()[0].isdigit()}
    assert sorted(verdicts) == list(TAGS)
    assert [i for i, ln in verdicts.items() if ln.endswith("MOVED: put the tag back, or use the surveyed layout")] == [
        3
    ]
    assert all(ln.endswith("within the noise") for i, ln in verdicts.items() if i != 3)
    assert set(json.loads(out.read_text())) == {"tags", "field"}
