"""locate reads again, where the pose puts them, the map's markers the detector missed."""

import numpy as np

from fidlearn import Camera, detect_markers, locate
from fidlearn.frames import look_at
from fidlearn.pose._second_look import missed_in_view, read_again
from fidlearn.synthetic import mixed_wall, render_scene

CAM = Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.05, 0.02, 0, 0, 0], (640, 480))
#: The benchmark's scene 21: 4X4_50 marker 0 is whole (18 px from the right edge), about 60 px wide, and
#: its white margin's outline pushes its own out of OpenCV's candidates.
T_SCENE = look_at([1815.7, -72.6, 1507.1], [0.0, 117.6, 1057.6], roll_deg=-11.53)


def scene():
    m = mixed_wall()
    return m, render_scene(m, CAM, T_SCENE, seed=21, noise_std_gray=2.0, blur_px=0.6)


def test_a_big_marker_the_detector_misses_is_read_where_the_pose_puts_it():
    m, sc = scene()
    big = m.key(0, "4X4_50")
    assert big in sc.truth  # whole in the picture
    pose = locate(sc.image, m, CAM)
    assert set(pose.marker_ids) == set(sc.truth)
    assert np.linalg.norm(pose.position_mm - T_SCENE[:3, 3]) < 3.0
    # the marker read again sits at its rendered corners
    missed = missed_in_view(m, CAM, pose.T_world_camera, set(pose.marker_ids) - {big}, None)
    assert [k for k, _, _ in missed] == [big]
    (det,) = read_again(sc.image, missed, None, None)
    assert (det.id, det.dictionary) == (0, "4X4_50")
    assert np.abs(det.corners_px - sc.truth[big]).max() < 0.5


def test_a_marker_that_is_not_in_the_picture_is_not_invented():
    m, _ = scene()
    # the same wall printed without 4X4_50 marker 0: the pose predicts it whole, the second look finds nothing
    printed = mixed_wall(without=["4X4_50:0"])
    sc = render_scene(printed, CAM, T_SCENE, seed=21, noise_std_gray=2.0, blur_px=0.6)
    pose = locate(sc.image, m, CAM)
    assert set(pose.marker_ids) == set(sc.truth)
    assert m.key(0, "4X4_50") not in pose.marker_ids
    missed = missed_in_view(m, CAM, pose.T_world_camera, set(pose.marker_ids), None)
    assert [k for k, _, _ in missed] == [m.key(0, "4X4_50")]
    assert read_again(sc.image, missed, None, None) == []


def test_markers_cut_by_the_edge_or_behind_the_camera_get_no_second_look():
    m, sc = scene()
    pose = locate(sc.image, m, CAM)
    # turned away: the camera behind the wall sees every marker's back
    behind = T_SCENE.copy()
    behind[0, 3] = -behind[0, 3]
    behind = look_at(behind[:3, 3], [0.0, 117.6, 1057.6])
    assert missed_in_view(m, CAM, behind, set(), None) == []
    # every marker of the map found: nothing to read again
    assert missed_in_view(m, CAM, pose.T_world_camera, set(m), None) == []
    # a small camera picture cut through the big marker: not whole, no second look
    narrow = Camera(CAM.K, CAM.dist, (600, 480))
    assert m.key(0, "4X4_50") not in [k for k, _, _ in missed_in_view(m, narrow, pose.T_world_camera, set(), None)]


def test_plain_detection_and_locate_agree_on_the_markers_both_find():
    m, sc = scene()
    pose = locate(sc.image, m, CAM)
    plain = {m.key(d.id, d.dictionary) for d in detect_markers(sc.image, ["ARUCO_ORIGINAL", "4X4_50"])}
    assert plain <= set(pose.marker_ids)
