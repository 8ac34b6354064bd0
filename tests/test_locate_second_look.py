"""locate reads again, where the pose puts them, the map's markers the detector missed."""

import numpy as np
import pytest

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


def _one_crop_at_a_time(image, missed):
    """The second look as it read each crop on its own (one detect_markers call per crop), as a reference."""
    return [d for one in missed for d in read_again(image, [one], None, None)]


def test_the_crops_read_side_by_side_are_the_crops_read_one_at_a_time():
    """Every map marker of two dictionaries not yet found, read again: the same markers in the same order, each at
    the corners its own crop gives (the edge fit samples at larger coordinates in the shared picture: single
    precision's last bits move a corner by thousandths of a pixel at most)."""
    m = mixed_wall()
    read = 0
    for k, T in enumerate(
        [
            T_SCENE,
            look_at([2600.0, 300.0, 1300.0], [0.0, 450.0, 1150.0], roll_deg=8.0),
            look_at([1500, 700, 900], [0, 300, 1200]),
        ]
    ):
        sc = render_scene(m, CAM, T, seed=k, noise_std_gray=2.0, blur_px=0.6)
        missed = missed_in_view(m, CAM, T, set(), None)
        assert len({name for _, name, _ in missed}) == 2
        assert len(missed) >= 4
        together, alone = read_again(sc.image, missed, None, None), _one_crop_at_a_time(sc.image, missed)
        assert [(d.id, d.dictionary) for d in together] == [(d.id, d.dictionary) for d in alone]
        for a, b in zip(together, alone):
            assert np.abs(a.corners_px - b.corners_px).max() < 0.01
        read += len(together)
    assert read >= 12


def test_a_marker_is_kept_only_in_its_own_crop():
    """Two crops of one dictionary: a marker predicted where another of the map sits is not reported as found
    (the other marker, read in that crop, has another id)."""
    m, sc = scene()
    small = [k for k in m if m.marker_dictionary(k) == "ARUCO_ORIGINAL"]
    missed = [x for x in missed_in_view(m, CAM, T_SCENE, set(), None) if x[0] in small[:2]]
    assert len(missed) == 2
    (a, name, qa), (b, _, qb) = missed
    swapped = [(a, name, qb), (b, name, qa)]  # each id predicted at the other's place
    assert read_again(sc.image, swapped, None, None) == []
    assert [d.id for d in read_again(sc.image, missed, None, None)] == [int(a), int(b)]


def test_the_shared_picture_keeps_the_pictures_marker_size_limits():
    from fidlearn._detector import _detector_fields, _limits_scaled

    limits = _limits_scaled(_detector_fields({"minMarkerPerimeterRate": 0.05}), 640, 1280)
    assert limits["minMarkerPerimeterRate"] * 1280 == 0.05 * 640  # 32 px either way
    assert limits["maxMarkerPerimeterRate"] * 1280 == 4.0 * 640
    # a limit the user set above the marker's perimeter in the picture: not found in the second look either
    m, sc = scene()
    missed = missed_in_view(m, CAM, T_SCENE, set(m) - {m.key(0, "4X4_50")}, None)
    assert len(read_again(sc.image, missed, None, None)) == 1
    assert read_again(sc.image, missed, None, {"minMarkerPerimeterRate": 300 / 640}) == []


@pytest.mark.parametrize("refine", ["subpix", "contour"])
def test_with_opencvs_refinements_each_crop_is_read_alone(refine):
    """OpenCV's own refinements place corners up to a pixel apart in a shared picture: their crops are read one by
    one, the corners those of the crop alone to the bit."""
    m = mixed_wall()
    T = look_at([2600.0, 300.0, 1300.0], [0.0, 450.0, 1150.0], roll_deg=8.0)
    sc = render_scene(m, CAM, T, seed=1, noise_std_gray=2.0, blur_px=0.6)
    missed = missed_in_view(m, CAM, T, set(), None)
    together = read_again(sc.image, missed, refine, None)
    alone = [d for one in missed for d in read_again(sc.image, [one], refine, None)]
    assert len(together) >= 4
    assert [(d.id, d.dictionary) for d in together] == [(d.id, d.dictionary) for d in alone]
    for a, b in zip(together, alone):
        assert np.array_equal(a.corners_px, b.corners_px)


def test_a_users_wider_threshold_windows_widen_the_gap_between_crops(monkeypatch):
    """With adaptive threshold windows up to 101 px, the crops sit 66 px apart: each window sees its own crop and
    white only, and the markers come out as their crops read alone do."""
    from fidlearn.pose import _second_look as S

    m = mixed_wall()
    T = look_at([2600.0, 300.0, 1300.0], [0.0, 450.0, 1150.0], roll_deg=8.0)
    sc = render_scene(m, CAM, T, seed=1, noise_std_gray=2.0, blur_px=0.6)
    missed = missed_in_view(m, CAM, T, set(), None)
    params = {"adaptiveThreshWinSizeMax": 101}
    gaps = []
    real = S._side_by_side
    monkeypatch.setattr(S, "_side_by_side", lambda crops, gap=S.GAP_PX: gaps.append(gap) or real(crops, gap))
    together = read_again(sc.image, missed, None, params)
    assert set(gaps) == {101 // 2 + 16}
    alone = [d for one in missed for d in read_again(sc.image, [one], None, params)]
    assert len(together) >= 4
    assert [(d.id, d.dictionary) for d in together] == [(d.id, d.dictionary) for d in alone]
    for a, b in zip(together, alone):
        assert np.abs(a.corners_px - b.corners_px).max() < 0.01
