"""MarkerTracker and PoseTracker on a rendered fisheye drive (160 degrees): the windows follow the markers out to
the edge of the picture, as the fisheye projects them, and the poses match the truth and locate's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fidlearn import Camera, MarkerMap, MarkerTracker, PoseTracker, detect_markers, frames, locate
from fidlearn._fisheye_edges import refine_edges_fisheye
from fidlearn.images import as_gray
from fidlearn.synthetic import render_trajectory

W, H = 640, 480
F = (W / 2) / math.radians(80)  # 160 degrees across the width
CAM = Camera([[F, 0, 319.5], [0, F, 239.5], [0, 0, 1]], [0.02, -0.01, 0.0, 0.0], (W, H), model="fisheye")
WALL = MarkerMap.from_dict(
    {
        str(k): {"translation": [0, y, z], "rotation": [0, 0, 0]}
        for k, (y, z) in enumerate((y, z) for y in range(-1500, 1501, 500) for z in (-400, 400))
    },
    marker_size_mm=120,
    units="mm",
)


def _off_axis_deg(T_world_camera: np.ndarray, marker_id: int) -> float:
    T_cw = np.linalg.inv(T_world_camera)
    x = T_cw[:3, :3] @ WALL.marker_corners(marker_id).mean(axis=0) + T_cw[:3, 3]
    return math.degrees(math.atan2(math.hypot(x[0], x[1]), x[2]))


@pytest.fixture(scope="module")
def drive():
    """Ten frames of a camera sliding 20 mm a frame along the wall, 50 cm from it, turning slowly."""
    poses = [
        frames.look_at([500.0 - 3 * k, -200.0 + 20 * k, 30.0], [0.0, -150.0 + 30 * k, 0.0], roll_deg=0.5 * k)
        for k in range(10)
    ]
    return render_trajectory(WALL, CAM, poses=poses, seed=5, supersample=2)


def test_marker_tracker_follows_markers_to_the_fisheye_edge(drive):
    tracker = MarkerTracker(WALL, CAM)
    edge_seen = 0
    for image, T in zip(drive.images, drive.T_world_camera):
        pose = tracker.locate(image)
        found = detect_markers(image, WALL.dictionary)  # the sides fitted as the lens bends them, as locate does
        straight = refine_edges_fisheye(as_gray(image), np.stack([d.corners_px for d in found]), CAM, 7)
        full = {d.id: c for d, c in zip(found, straight)}
        got = {d.id: d.corners_px for d in tracker.last_detections}
        assert sorted(got) == sorted(full)  # the windows found every marker a full detection finds
        for i in got:
            np.testing.assert_allclose(got[i], full[i], atol=1e-6)
        edge_seen += sum(_off_axis_deg(T, i) > 65 for i in got)
        assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 3.0
        np.testing.assert_allclose(pose.position_mm, locate(image, WALL, CAM).position_mm, atol=1e-6)
    assert edge_seen >= len(drive)  # markers 65 to 80 degrees off the axis, in the windows
    assert (tracker.frames, tracker.full_detections) == (len(drive), 1)


def test_pose_tracker_on_a_fisheye_drive(drive):
    tracker = PoseTracker(WALL, CAM)
    for k, (image, T) in enumerate(zip(drive.images, drive.T_world_camera)):
        tracked = tracker.update(image, t_s=0.1 * k)
        assert np.linalg.norm(tracked.position_mm - T[:3, 3]) < 3.0
    assert tracker._detector.full_detections == 1
