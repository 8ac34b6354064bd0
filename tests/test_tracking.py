"""MarkerTracker on a short rendered drive: the same markers and corners as detect_markers, poses against the truth."""

from __future__ import annotations

import numpy as np
import pytest

from fidlearn import Camera, MarkerMap, MarkerPlacement, MarkerTracker, detect_markers, locate
from fidlearn.errors import CameraError, FidlearnError, ImageError, NoMarkersError
from fidlearn.synthetic import render_trajectory

CAM = Camera([[500.0, 0, 320.4], [0, 500.0, 238.7], [0, 0, 1]], [-0.1, 0.05, 0.0004, -0.0003, 0.0], (640, 480))


def wall_map() -> MarkerMap:
    """Six 100 mm markers on the north wall (x = 0), facing +X; ids not consecutive."""
    p = {}
    for i, y, z in [(3, 0, 1500), (7, 400, 1500), (11, 800, 1500), (20, 100, 1100), (21, 500, 1100), (40, 900, 1150)]:
        p[i] = MarkerPlacement(i, (0.0, float(y), float(z)), (0.0, 0.0, 0.0))
    return MarkerMap(p, 100.0, dictionary="ARUCO_ORIGINAL", units="mm")


@pytest.fixture(scope="module")
def drive():
    """Eight consecutive frames (about 25 mm apart) of a robot driving toward the wall, 1.8 m to 0.8 m away."""
    return render_trajectory(
        wall_map(),
        CAM,
        n_frames=40,
        seed=3,
        start_distance_mm=1800.0,
        end_distance_mm=800.0,
        start_lateral_mm=-300.0,
        end_lateral_mm=200.0,
        frames_to_render=range(12, 20),
    )


def test_same_markers_and_corners_as_detect_markers(drive):
    tracker = MarkerTracker(drive.marker_map, CAM)
    for image, truth in zip(drive.images, drive.truth):
        tracker.locate(image)
        full = {d.id: d.corners_px for d in detect_markers(image, drive.marker_map.dictionary)}
        got = {d.id: d.corners_px for d in tracker.last_detections}
        assert sorted(got) == sorted(full)
        assert set(truth) <= set(got)
        for i in got:
            np.testing.assert_allclose(got[i], full[i], atol=1e-6)
    # the windows did the work: one full detection, on the first frame
    assert (tracker.frames, tracker.full_detections) == (len(drive), 1)


def test_pose_matches_truth_and_locate(drive):
    tracker = MarkerTracker(drive.marker_map, CAM)
    for image, T in zip(drive.images, drive.T_world_camera):
        pose = tracker.locate(image)
        assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 3.0
        np.testing.assert_allclose(pose.position_mm, locate(image, drive.marker_map, CAM).position_mm, atol=1e-6)


def test_recovers_after_a_frame_without_markers(drive):
    tracker = MarkerTracker(drive.marker_map, CAM)
    assert tracker.locate(drive.images[0]).marker_ids == (3, 7, 11, 20, 21, 40)
    blank = np.full_like(drive.images[0], 128)
    with pytest.raises(NoMarkersError, match=r"no marker was detected; the map .* has ids \[3, 7, 11, 20, 21, 40\]"):
        tracker.locate(blank)  # a frame without a pose raises, as fidlearn.locate does
    assert tracker.last_pose is None
    assert tracker.last_detections == []
    pose = tracker.locate(drive.images[2])
    assert tracker.last_full  # frame 0, the blank frame, then afresh
    assert tracker.full_detections == 3
    assert np.linalg.norm(pose.position_mm - drive.T_world_camera[2][:3, 3]) < 3.0


def cover(image, truth, ids):
    """A copy of ``image`` with the markers ``ids`` painted over in the wall's gray."""
    out = image.copy()
    for i in ids:
        x0, y0 = np.floor(truth[i].min(axis=0)).astype(int) - 2
        x1, y1 = np.ceil(truth[i].max(axis=0)).astype(int) + 3
        out[y0:y1, x0:x1] = 128
    return out


def test_a_covered_marker_costs_a_larger_window_not_a_full_detection(drive):
    tracker = MarkerTracker(drive.marker_map, CAM)
    tracker.locate(drive.images[0])
    pose = tracker.locate(cover(drive.images[1], drive.truth[1], [7]))
    assert not tracker.last_full
    assert tracker.full_detections == 1
    assert pose.marker_ids == (3, 11, 20, 21, 40)
    tracker.locate(drive.images[2])  # marker 7 is predicted from the map, so its window finds it again
    assert not tracker.last_full
    assert [d.id for d in tracker.last_detections] == [3, 7, 11, 20, 21, 40]


def test_a_turn_that_stops_at_once_keeps_every_marker():
    """Still, a sudden 20 degree turn, still again: the motion model carries the markers on by another 20 degrees,
    out of the picture; they are found where they were last seen (two of four were lost)."""
    import fidlearn  # noqa: PLC0415

    m = MarkerMap.load(fidlearn.data_path("two_walls_map.json"))
    cam = Camera.from_fov(70, (640, 480))

    def T(yaw):
        return fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, yaw), [1800, 150, 250])

    run = render_trajectory(m, cam, poses=[T(90), T(90), T(110), T(110), T(110)], noise_std_gray=1.0)
    tracker = MarkerTracker(m, cam)
    for k, image in enumerate(run.images):
        pose = tracker.locate(image)
        assert sorted(pose.marker_ids) == sorted(run.truth[k]), k
    assert not tracker.last_full


def test_most_markers_missing_calls_for_a_full_detection(drive):
    tracker = MarkerTracker(drive.marker_map, CAM)
    tracker.locate(drive.images[0])
    pose = tracker.locate(cover(drive.images[1], drive.truth[1], [3, 7, 11, 20]))
    assert tracker.last_full
    assert tracker.full_detections == 2
    assert pose.marker_ids == (21, 40)
    assert np.linalg.norm(pose.position_mm - drive.T_world_camera[1][:3, 3]) < 10.0


def test_full_every_and_reset(drive):
    tracker = MarkerTracker(drive.marker_map, CAM, full_every=3)
    for image in drive.images[:7]:
        tracker.locate(image)
    assert tracker.full_detections == 3  # frames 0, 3, 6
    tracker.reset()
    tracker.locate(drive.images[7])
    assert (tracker.frames, tracker.full_detections, tracker.last_full) == (1, 1, True)
    assert "6 markers" in repr(tracker)


def test_bgr_frames_and_pose_options(drive):
    tracker = MarkerTracker(drive.marker_map, CAM, method="ippe", refine="subpix")
    bgr = np.repeat(drive.images[4][:, :, None], 3, axis=2)
    pose = tracker.locate(bgr)
    expected = locate(drive.images[4], drive.marker_map, CAM, method="ippe", refine="subpix")
    assert pose.method == expected.method == "ippe"
    np.testing.assert_allclose(pose.position_mm, expected.position_mm, atol=1e-6)
    assert np.linalg.norm(pose.position_mm - drive.T_world_camera[4][:3, 3]) < 50.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(marker_map="map.json"), "marker_map must be a fidlearn.MarkerMap"),
        (dict(camera=None), "camera must be a fidlearn.Camera"),
        (dict(full_every=0), "full_every must be a whole number of frames >= 1, got 0"),
        (dict(search_px=-1), "search_px must be a number of pixels >= 0"),
        (dict(refine="sharp"), "unknown corner refinement 'sharp'"),
        (dict(method="dlt"), "unknown method 'dlt'"),
        # checked once, as locate checks them, not found wrong on every frame
        (dict(corner_sigma_px=0), "corner_sigma_px must be a positive number of pixels, got 0"),
        (dict(reject_outliers="no"), "reject_outliers must be True or False, got 'no'"),
        (dict(reject_outlier=False), r"MarkerTracker\(\) got unknown option 'reject_outlier'; it takes refine, "),
        (dict(detector_params={"adaptiveThreshWinSize": 5}), "no field 'adaptiveThreshWinSize'"),
    ],
)
def test_bad_arguments(kwargs, match):
    args = dict(marker_map=wall_map(), camera=CAM) | kwargs
    with pytest.raises(FidlearnError, match=match):
        MarkerTracker(args.pop("marker_map"), args.pop("camera"), **args)


def test_bad_frames():
    tracker = MarkerTracker(wall_map(), CAM)
    with pytest.raises(ImageError, match="frame: expected a numpy array"):
        tracker.locate("frame_001.png")
    with pytest.raises(CameraError, match="aspect"):
        tracker.locate(np.zeros((480, 480), np.uint8))
