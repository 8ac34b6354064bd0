"""The course's pictures: each drawing puts its geometry where the maths says."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mpl_toolkits.mplot3d import proj3d  # noqa: E402

from fidlearn import (  # noqa: E402
    Camera,
    FidlearnError,
    MarkerMap,
    PlotError,
    frames,
    look_at,
    plotting,  # noqa: E402
)

SEED = {
    "0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]},
    "1": {"translation": [0, 1, 1], "rotation": [0, 0, 0]},
    "2": {"translation": [0, 0.5, 0.75], "rotation": [0, 0, 0]},
}


@pytest.fixture
def seed_map():
    return MarkerMap.from_dict(SEED, units="ft", marker_size_mm=80)


@pytest.fixture
def camera():
    return Camera([[500.0, 0, 319.5], [0, 500.0, 239.5], [0, 0, 1]], None, (640, 480))


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def line_xyz(line) -> np.ndarray:
    return np.column_stack(line.get_data_3d())


def test_frustum_apex_is_the_camera_centre_and_base_lies_at_depth(camera):
    T = frames.make_transform(frames.rotation_from_rpy_deg(0, 0, 30), [1200, -300, 450])
    f = plotting.camera_frustum(camera, T, depth_mm=250)
    assert f.shape == (5, 3)
    assert np.allclose(f[0], [1200, -300, 450])
    pts_cam = frames.transform_points(frames.invert_transform(T), f[1:])
    assert np.allclose(pts_cam[:, 2], 250)
    # the base corners project back onto the image's outer corners
    px = camera.project(f[1:], T)
    assert np.allclose(px, [[-0.5, -0.5], [639.5, -0.5], [639.5, 479.5], [-0.5, 479.5]], atol=1e-6)


def test_draw_camera_lines_start_at_the_camera_position(camera):
    ax = plotting.new_axes_3d()
    T = look_at([1500, 200, 250], [0, 120, 230])
    lines = plotting.draw_camera(ax, camera, T, scale_mm=300)
    assert len(lines) == 5
    f = plotting.camera_frustum(camera, T, 300)
    for k, line in enumerate(lines[:4], start=1):
        xyz = line_xyz(line)
        assert np.allclose(xyz[0], [1500, 200, 250])
        assert np.allclose(xyz[1], f[k])
    base = line_xyz(lines[4])
    assert np.allclose(base, f[[1, 2, 3, 4, 1]])


def test_draw_frame_axes_have_the_rotation_columns_and_length():
    ax = plotting.new_axes_3d()
    T = frames.make_transform(frames.rotation_from_rpy_deg(0, 0, 90), [10, 20, 30])
    lines = plotting.draw_frame(ax, T, length_mm=50)
    tips = [line_xyz(line)[1] for line in lines]
    assert np.allclose(tips[0], [10, 70, 30])  # x of the frame = world +Y after yaw 90
    assert np.allclose(tips[1], [-40, 20, 30])  # y = world -X
    assert np.allclose(tips[2], [10, 20, 80])
    assert [line.get_color() for line in lines] == list(plotting.AXIS_COLORS)


def test_draw_markers_puts_one_square_per_marker_at_its_corners(seed_map):
    ax = plotting.new_axes_3d()
    coll = plotting.draw_markers(ax, seed_map)
    ax.figure.canvas.draw()
    # the drawn polygons (projected to 2D, in depth order) are the map's corners projected
    M = ax.get_proj()
    drawn = [p.vertices[:4] for p in coll.get_paths()]
    assert len(drawn) == 3
    for mid, c in seed_map.corners().items():
        x, y, _ = proj3d.proj_transform(c[:, 0], c[:, 1], c[:, 2], M)
        want = np.column_stack([x, y])
        assert any(np.allclose(d, want) for d in drawn), mid
    texts = sorted(t.get_text() for t in ax.texts)
    assert texts == ["0", "1", "2"]


def test_draw_markers_labels_a_board_once_above_it_with_its_ids():
    from fidlearn.synthetic import board_survey_room

    room = board_survey_room()
    ax = plotting.new_axes_3d()
    plotting.draw_markers(ax, room)
    texts = {t.get_text(): t for t in ax.texts}
    singles = [str(k) for k in room.placements if k not in room.owner]
    assert sorted(texts) == sorted([*singles, "dock (40-41)", "wall board (20-36)"])
    board = np.concatenate([c for k, c in room.corners().items() if room.owner.get(k) == "wall board"])
    x, y, z = texts["wall board (20-36)"].get_position_3d()  # written above the board's top markers, over its middle
    assert z > board[:, 2].max()
    assert board[:, 1].min() < y < board[:, 1].max()


def test_draw_markers_draws_the_marker_of_the_dictionary_asked_and_refuses_an_unknown_one():
    from fidlearn.errors import PlotError

    m = MarkerMap.from_dict(
        {
            "marker_size_mm": 100,
            "dictionary": "ARUCO_ORIGINAL",
            "markers": {
                "3": {"translation": [0, 0, 1000], "rotation": [0, 0, 0]},
                "4X4_50:3": {"translation": [0, 500, 1000], "rotation": [0, 0, 0]},
            },
        },
        units="mm",
    )
    other = next(k for k in m.corners() if str(k) == "4X4_50:3")
    ax = plotting.new_axes_3d()
    plotting.draw_markers(ax, m, ids=[other])
    (label,) = ax.texts
    assert label.get_text() == "4X4_50:3"
    assert label.get_position_3d()[1] > 300  # above the marker at y = 500 mm, not the map's own marker 3 at y = 0
    with pytest.raises(PlotError, match=r"markers \[99\] are not in the map"):
        plotting.draw_markers(ax, m, ids=[99])


def test_a_flat_bundle_of_another_dictionary_is_labelled_with_it_above_its_markers():
    m = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 80,
            "dictionary": "ARUCO_ORIGINAL",
            "markers": {"3": {"translation": [0, 0, 1000]}},
            "bundles": {
                "dock": {
                    "translation": [1000, 0, 0],
                    "dictionary": "4X4_50",
                    "markers": {
                        "5": {"translation": [0, 0, 0], "rotation": [0, -90, 0]},
                        "6": {"translation": [0, 200, 0], "rotation": [0, -90, 0]},
                    },
                }
            },
        }
    )
    ax = plotting.new_axes_3d()
    plotting.draw_markers(ax, m)
    texts = {t.get_text(): t.get_position_3d() for t in ax.texts}
    assert set(texts) == {"3", "dock (4X4_50:5-6)"}
    dock = np.concatenate([c for k, c in m.corners().items() if m.owner.get(k) == "dock"])
    assert texts["dock (4X4_50:5-6)"][2] > dock[:, 2].max() + 10  # above the markers lying on the floor


def test_draw_box_draws_the_twelve_edges_of_the_room():
    ax = plotting.new_axes_3d()
    lines = plotting.draw_box(ax, [0, 0, 0], [4000, 3000, 2500])
    assert len(lines) == 12
    lengths = sorted(round(float(np.linalg.norm(np.diff(line_xyz(line), axis=0)))) for line in lines)
    assert lengths == [2500] * 4 + [3000] * 4 + [4000] * 4


def test_set_axes_equal_gives_every_axis_the_same_range():
    ax = plotting.new_axes_3d()
    cube = plotting.set_axes_equal(ax, np.array([[0, 0, 0], [1000, 200, 50]]), margin=0)
    assert np.allclose(cube.centre, [500, 100, 25])
    assert cube.half_range == pytest.approx(500)
    ranges = [np.diff(lim)[0] for lim in (ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d())]
    assert np.allclose(ranges, 1000)


def test_plot_scene_includes_markers_cameras_and_world_axes(seed_map, camera):
    poses = [look_at([1500, 200, 250], [0, 120, 230]), look_at([1200, -400, 600], [0, 120, 230])]
    fig = plotting.plot_scene(seed_map, poses=poses, camera=camera, labels=["a", "b"])
    (ax,) = fig.axes
    assert ax.name == "3d"
    labels = {t.get_text().strip() for t in ax.texts}
    assert {"a", "b", "world", "X", "Y", "Z", "0", "1", "2"} <= labels
    # every camera centre and every corner lies inside the (cubic) view
    lims = np.array([ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d()])
    pts = np.vstack([T[:3, 3] for T in poses] + list(seed_map.corners().values()))
    assert np.all(pts >= lims[:, 0])
    assert np.all(pts <= lims[:, 1])
    assert np.allclose(np.diff(lims, axis=1), np.diff(lims, axis=1)[0])


def test_plot_scene_accepts_pose_objects_and_checks_labels(seed_map):
    class P:
        T_world_camera = look_at([1500, 200, 250], [0, 120, 230])

    fig = plotting.plot_scene(seed_map, poses=[P()])
    assert "camera" in {t.get_text().strip() for t in fig.axes[0].texts}
    with pytest.raises(ValueError, match="2 labels for 1 poses"):
        plotting.plot_scene(seed_map, poses=[P()], labels=["a", "b"])


def test_draw_trajectory_joins_the_positions_in_order(camera):
    ax = plotting.new_axes_3d()
    poses = [look_at([2000 - 300 * k, 100 * k, 300], [0, 120, 230]) for k in range(5)]
    line = plotting.draw_trajectory(ax, poses, camera=camera, every=2, scale_mm=100)
    assert np.allclose(line_xyz(line), [T[:3, 3] for T in poses])
    with pytest.raises(ValueError, match="no poses"):
        plotting.draw_trajectory(ax, [])


def test_top_view_puts_cameras_at_their_xy_with_headings(seed_map):
    poses = [look_at([1500, 0, 250], [0, 0, 250]), look_at([1000, 500, 250], [0, 500, 250])]
    truth = [look_at([1510, 0, 250], [0, 0, 250]), look_at([1000, 490, 250], [0, 500, 250])]
    ax = plotting.plot_top_view(seed_map, poses, truth=truth)
    path = np.column_stack(ax.lines[-1].get_data())
    assert np.allclose(path, [[1500, 0], [1000, 500]])
    (quiver,) = [c for c in ax.collections if c.__class__.__name__ == "Quiver"]
    assert np.allclose(quiver.U, [-150, -150])  # looking at -X
    assert np.allclose(quiver.V, [0, 0], atol=1e-9)
    # the seed's markers on the north wall (x = 0), seen from above: segments along Y at x = 0
    walls = [np.column_stack(line.get_data()) for line in ax.lines[:3]]
    assert all(np.allclose(w[:, 0], 0) for w in walls)
    assert np.allclose(walls[0][:, 1], [0, 80])
    with pytest.raises(ValueError, match="1 true poses for 2 poses"):
        plotting.plot_top_view(seed_map, poses, truth=truth[:1])


def test_show_image_converts_bgr_to_rgb_and_marks_points():
    img = np.zeros((20, 30, 3), np.uint8)
    img[..., 0] = 255  # pure blue in OpenCV's BGR
    ax = plotting.show_image(None, img, points=[[3, 4], [10, 12]], labels=["a", "b"])
    shown = ax.images[0].get_array()
    assert tuple(shown[0, 0]) == (0, 0, 255)  # blue in RGB
    assert np.allclose(ax.collections[0].get_offsets(), [[3, 4], [10, 12]])
    assert [t.get_text() for t in ax.texts] == ["a", "b"]
    # pixel centres at integer coordinates: the image spans -0.5 .. w - 0.5
    assert ax.images[0].get_extent() == [-0.5, 29.5, 19.5, -0.5]


def test_show_image_gray_uses_a_fixed_0_255_scale():
    ax = plotting.show_image(None, np.full((10, 10), 100, np.uint8))
    assert ax.images[0].get_clim() == (0, 255)
    with pytest.raises(ValueError, match="not an image"):
        plotting.show_image(None, np.zeros((4, 4, 2)))


def test_corner_labels_sit_beside_their_corners_in_order():
    _, ax = plt.subplots()
    quad = np.array([[10, 10], [50, 12], [48, 52], [8, 50]], float)
    texts = plotting.draw_corner_labels(ax, quad)
    assert [t.get_text() for t in texts] == ["TL", "TR", "BR", "BL"]
    assert np.allclose([t.xy for t in texts], quad)
    # TL's label is pushed up-left (away from the centre): offset x < 0, and y > 0 in points (up)
    dx, dy = texts[0].xyann
    assert dx < 0
    assert dy > 0


def test_projected_markers_match_camera_project(seed_map, camera):
    _, ax = plt.subplots()
    T = look_at([1500, 200, 250], [0, 120, 230])
    out = plotting.draw_projected_markers(ax, seed_map, camera, T)
    assert sorted(out) == [0, 1, 2]
    for mid, px in out.items():
        assert np.allclose(px, camera.project(seed_map.corners()[mid], T))
    # seen from inside the room the wall's +Y runs to the right: TR right of TL
    assert out[0][1, 0] > out[0][0, 0]
    assert ax.get_xlim() == (-0.5, 639.5)
    assert ax.get_ylim() == (479.5, -0.5)
    # a camera behind the wall sees nothing
    _, ax2 = plt.subplots()
    assert plotting.draw_projected_markers(ax2, seed_map, camera, look_at([-1500, 0, 250], [-3000, 0, 250])) == {}


def test_projected_markers_want_the_map_first(seed_map, camera):
    _, ax = plt.subplots()
    T = look_at([1500, 200, 250], [0, 120, 230])
    with pytest.raises(FidlearnError, match="the map comes first, then the camera; the arguments are swapped"):
        plotting.draw_projected_markers(ax, camera, seed_map, T)


def test_plot_errors_are_fidlearn_errors_and_value_errors():
    with pytest.raises(PlotError, match="no poses") as info:
        plotting.draw_trajectory(plotting.new_axes_3d(), [])
    assert isinstance(info.value, ValueError)


def test_draw_reprojection_returns_the_errors():
    _, ax = plt.subplots()
    err = plotting.draw_reprojection(ax, [[0, 0], [10, 10]], [[3, 4], [10, 10]])
    assert np.allclose(err, [5, 0])


def test_plot_detections_outlines_each_quad_closed():
    from fidlearn.detection import Detection

    _, ax = plt.subplots()
    d = Detection(7, [[10, 10], [50, 10], [50, 50], [10, 50]])
    (line,) = plotting.plot_detections(ax, [d])
    xy = np.column_stack(line.get_data())
    assert np.allclose(xy, [[10, 10], [50, 10], [50, 50], [10, 50], [10, 10]])
    assert "7" in [t.get_text() for t in ax.texts]


def test_show_images_grid_has_one_axes_per_slot():
    fig = plotting.show_images([np.zeros((10, 20), np.uint8)] * 5, titles=list("abcde"), ncols=3)
    assert len(fig.axes) == 6
    assert [ax.get_title() for ax in fig.axes[:5]] == list("abcde")


def test_importing_fidlearn_does_not_import_matplotlib():
    import subprocess
    import sys

    code = "import sys, fidlearn; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_mismatched_and_empty_inputs_are_plot_errors_and_a_folded_marker_is_not_drawn():
    """They raised IndexError or ValueError; a marker 60 degrees off the axis of a 70 degree barrel lens was
    drawn mirrored beside the one in view (the distortion polynomial folds back there)."""
    image = np.zeros((10, 20), np.uint8)
    with pytest.raises(PlotError, match="3 images and 1 titles"):
        plotting.show_images([image] * 3, titles=["a"])
    _, ax = plt.subplots()
    with pytest.raises(PlotError, match="2 quads and 1 ids"):
        plotting.draw_quads(ax, [np.zeros((4, 2))] * 2, ids=[1])
    with pytest.raises(PlotError, match=r"an image is an array \(H, W\)"):
        plotting.show_image(None, np.zeros(5))
    ax3 = plt.figure().add_subplot(projection="3d")
    with pytest.raises(PlotError, match="points must be finite"):
        plotting.set_axes_equal(ax3, np.zeros((0, 3)))
    cam = Camera.from_fov(70, (640, 480), dist=[-0.3, 0, 0, 0, 0])
    m = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 100,
            "markers": {"0": {"translation": [0, -50, 550]}, "1": {"translation": [0, -1800, 550]}},
        }
    )
    drawn = plotting.draw_projected_markers(ax, m, cam, look_at([1000, 0, 500], [0, 0, 500]))
    assert sorted(drawn) == [0]
    plt.close("all")
