"""Property tests: frames and the world map hold their promises for *every* valid input.

Each property is checked on a few hundred random inputs (hypothesis), not on the
handful of hand-picked cases the other test files use. The known answers here are
identities: a square of side s, the winding TL -> TR -> BR -> BL, inverse and
composition laws, and round trips through rvec/tvec, roll-pitch-yaw and the map file.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from fidlearn import frames
from fidlearn.errors import TransformError
from fidlearn.markermap import UNITS_TO_MM, MarkerMap, MarkerPlacement

FAST = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# A room: 20 m each way around the origin, in mm.
coord_mm = st.floats(-10_000, 10_000, allow_nan=False, allow_infinity=False)
translation_mm = st.tuples(coord_mm, coord_mm, coord_mm)
# Any orientation, including gimbal lock and angles beyond +-180 degrees.
angle_deg = st.floats(-360, 360, allow_nan=False, allow_infinity=False)
rpy_any_deg = st.tuples(angle_deg, angle_deg, angle_deg)
right_angle_deg = st.sampled_from([-270, -180, -90, 0, 90, 180, 270])
rpy_walls_deg = st.tuples(right_angle_deg, right_angle_deg, right_angle_deg)
marker_size_mm = st.floats(1, 1000, allow_nan=False, allow_infinity=False)


@st.composite
def rigid_transforms(draw) -> np.ndarray:
    R = frames.rotation_from_rpy_deg(*draw(st.one_of(rpy_any_deg, rpy_walls_deg)))
    return frames.make_transform(R, draw(translation_mm))


def wrap_deg(a: np.ndarray) -> np.ndarray:
    """Angle difference folded into [-180, 180)."""
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


# -- the world map: every placement gives a square of the stated size ------------------
@FAST
@given(t=translation_mm, rpy=st.one_of(rpy_any_deg, rpy_walls_deg), s=marker_size_mm)
def test_any_placement_gives_a_square_of_the_stated_size(t, rpy, s):
    m = MarkerMap({7: MarkerPlacement(7, t, rpy)}, marker_size_mm=s)
    c = m.marker_corners(7)
    assert c.shape == (4, 3)
    tol = 1e-6 * (1 + np.abs(t).max())
    # TL is where the map put it.
    np.testing.assert_allclose(c[0], t, atol=tol)
    # Four sides of length s, two diagonals of length s * sqrt(2): a square, not a rhombus.
    sides = np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1)
    np.testing.assert_allclose(sides, s, atol=tol)
    np.testing.assert_allclose(np.linalg.norm(c[2] - c[0]), s * math.sqrt(2), atol=tol)
    np.testing.assert_allclose(np.linalg.norm(c[3] - c[1]), s * math.sqrt(2), atol=tol)
    # Flat: the fourth corner lies in the plane of the other three.
    n = np.cross(c[1] - c[0], c[3] - c[0])
    assert abs(np.dot(c[2] - c[0], n)) <= tol * s * s


@FAST
@given(t=translation_mm, rpy=st.one_of(rpy_any_deg, rpy_walls_deg), s=marker_size_mm)
def test_winding_is_tl_tr_br_bl_around_the_rotated_x_axis(t, rpy, s):
    """With rotation [0, 0, 0], TR - TL = s*Y and BL - TL = -s*Z, so (TR - TL) x (BL - TL) = -s^2 X.

    The placement rotates the whole marker, so the same cross product is -s^2 R X for every
    placement, and the printed face (the marker's normal) is +R X: the marker is seen from
    where its rotated +X axis points, and its corners run TL -> TR -> BR -> BL clockwise
    as seen from there (ArUco's order).
    """
    m = MarkerMap({3: MarkerPlacement(3, t, rpy)}, marker_size_mm=s)
    c = m.marker_corners(3)
    x_rotated = frames.rotation_from_rpy_deg(*rpy)[:, 0]
    cross = np.cross(c[1] - c[0], c[3] - c[0]) / s**2
    np.testing.assert_allclose(cross, -x_rotated, atol=1e-9 * (1 + np.abs(t).max() / s))
    # The same orientation around every corner: consecutive edges turn the same way.
    for i in range(4):
        a, b, d = c[i], c[(i + 1) % 4], c[(i + 3) % 4]
        turn = np.cross(b - a, d - a) / s**2
        np.testing.assert_allclose(turn, -x_rotated, atol=1e-6)
    # the normal comes from the corners, which hold t's round-off: the same scale as the cross product's above
    np.testing.assert_allclose(m.normal(3), x_rotated, atol=1e-9 * (1 + np.abs(t).max() / s))
    # The marker frame: origin at the centre, x along TL->TR, y along BL->TL, z out of the face.
    T = m.T_world_marker(3)
    frames.check_transform(T)
    np.testing.assert_allclose(T[:3, 3], c.mean(axis=0), atol=1e-6 * (1 + np.abs(t).max()))
    np.testing.assert_allclose(T[:3, 0], (c[1] - c[0]) / s, atol=1e-6)
    np.testing.assert_allclose(T[:3, 1], (c[0] - c[3]) / s, atol=1e-6)


@FAST
@given(rpy=rpy_walls_deg, t=st.tuples(*[st.integers(-10_000, 10_000)] * 3), s=st.integers(1, 1000))
def test_right_angle_placements_give_exact_corners(rpy, t, s):
    """Markers on walls, floors and ceilings (multiples of 90 degrees) have exact integer corners."""
    c = MarkerMap({0: MarkerPlacement(0, tuple(float(v) for v in t), rpy)}, marker_size_mm=s).marker_corners(0)
    np.testing.assert_array_equal(c, np.round(c))


@FAST
@given(
    placements=st.dictionaries(
        st.integers(0, 1023), st.tuples(translation_mm, st.one_of(rpy_any_deg, rpy_walls_deg)), min_size=1, max_size=6
    ),
    units=st.sampled_from(sorted(UNITS_TO_MM)),
    s=marker_size_mm,
)
def test_map_survives_the_file_round_trip(placements, units, s, tmp_path_factory):
    scale = UNITS_TO_MM[units]
    d = {
        "units": units,
        "marker_size_mm": s,
        "dictionary": "ARUCO_ORIGINAL",
        "markers": {
            str(i): {"translation": [v / scale for v in t], "rotation": list(r)} for i, (t, r) in placements.items()
        },
    }
    m = MarkerMap.from_dict(d)
    path = tmp_path_factory.mktemp("map") / "map.json"
    m.save(path)
    again = MarkerMap.load(path)
    assert again.ids == sorted(placements) == m.ids
    assert again.units == units
    assert again.marker_size_mm == s
    assert again.dictionary == "ARUCO_ORIGINAL"
    for i in m.ids:
        np.testing.assert_allclose(again.marker_corners(i), m.marker_corners(i), atol=1e-6)
        np.testing.assert_allclose(m.marker_corners(i)[0], placements[i][0], atol=1e-6 * (1 + scale))


# -- frames: inverse, composition, rvec/tvec, roll-pitch-yaw --------------------------
@FAST
@given(T=rigid_transforms())
def test_inverse_undoes_the_transform(T):
    T_inv = frames.invert_transform(T)
    np.testing.assert_allclose(T_inv @ T, np.eye(4), atol=1e-9)
    np.testing.assert_allclose(T @ T_inv, np.eye(4), atol=1e-9)
    np.testing.assert_allclose(T_inv, np.linalg.inv(T), atol=1e-8)
    np.testing.assert_allclose(frames.invert_transform(T_inv), T, atol=1e-9)
    frames.check_transform(T_inv)


@FAST
@given(A=rigid_transforms(), B=rigid_transforms(), C=rigid_transforms())
def test_compose_is_associative_and_chains_names(A, B, C):
    left = frames.compose(frames.compose(A, B), C)
    right = frames.compose(A, frames.compose(B, C))
    np.testing.assert_allclose(left, right, atol=1e-6)
    np.testing.assert_allclose(frames.compose(A, B, C), left, atol=1e-6)
    # T_a_c = T_a_b @ T_b_c maps points of c straight to a.
    p_c = np.array([[1.0, 2.0, 3.0], [-500.0, 250.0, 1000.0]])
    np.testing.assert_allclose(
        frames.transform_points(frames.compose(A, B), p_c),
        frames.transform_points(A, frames.transform_points(B, p_c)),
        atol=1e-6,
    )
    # (A B)^-1 = B^-1 A^-1
    np.testing.assert_allclose(
        frames.invert_transform(frames.compose(A, B)),
        frames.compose(frames.invert_transform(B), frames.invert_transform(A)),
        atol=1e-6,
    )
    np.testing.assert_allclose(frames.compose(A), A)
    np.testing.assert_array_equal(frames.compose(), np.eye(4))


@FAST
@given(T=rigid_transforms(), points=st.lists(translation_mm, min_size=1, max_size=8))
def test_transform_points_and_back(T, points):
    p_b = np.array(points)
    p_a = frames.transform_points(T, p_b)
    np.testing.assert_allclose(p_a, (T @ np.c_[p_b, np.ones(len(p_b))].T).T[:, :3], atol=1e-6)
    np.testing.assert_allclose(frames.transform_points(frames.invert_transform(T), p_a), p_b, atol=1e-6)
    # Distances are kept: a rigid transform.
    np.testing.assert_allclose(np.linalg.norm(p_a - p_a[0], axis=1), np.linalg.norm(p_b - p_b[0], axis=1), atol=1e-6)


# cv2.Rodrigues (4.x and 5.x alike) returns a zero vector for rotations whose sine is below 1e-5
# (frames takes the skew part there instead) and loses about 1e-6 rad within 1e-5 rad of 180 degrees.
RODRIGUES_ATOL = 2e-6


@FAST
@given(T=rigid_transforms())
def test_rvec_tvec_round_trip_from_a_transform(T):
    rvec, tvec = frames.rvec_tvec_from_transform(T)
    assert rvec.shape == (3,)
    assert tvec.shape == (3,)
    assert np.linalg.norm(rvec) <= math.pi + 1e-9
    back = frames.transform_from_rvec_tvec(rvec, tvec)
    np.testing.assert_allclose(back[:3, :3], T[:3, :3], atol=RODRIGUES_ATOL)
    np.testing.assert_array_equal(back[:3, 3], T[:3, 3])


@FAST
@given(
    axis=st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 3),
    angle=st.one_of(st.floats(0, math.pi - 1e-3), st.floats(0, 1e-4)),
    t=translation_mm,
)
def test_rvec_tvec_round_trip_from_a_vector(axis, angle, t):
    a = np.array(axis)
    assume(np.linalg.norm(a) > 1e-3)
    rvec = a / np.linalg.norm(a) * angle
    T = frames.transform_from_rvec_tvec(rvec, t)
    frames.check_transform(T)
    assert frames.rotation_angle_deg(T) == pytest.approx(math.degrees(angle), abs=1e-5)
    rvec2, tvec2 = frames.rvec_tvec_from_transform(T)
    np.testing.assert_allclose(rvec2, rvec, atol=1e-8)  # tiny angles included, 180 degrees excluded
    np.testing.assert_allclose(tvec2, t, atol=1e-9)


@FAST
@given(
    roll=st.floats(-179.9, 179.9),
    pitch=st.floats(-89.5, 89.5),
    yaw=st.floats(-179.9, 179.9),
)
def test_rpy_round_trip_away_from_gimbal_lock(roll, pitch, yaw):
    rpy = frames.rpy_deg_from_rotation(frames.rotation_from_rpy_deg(roll, pitch, yaw))
    np.testing.assert_allclose(wrap_deg(rpy - [roll, pitch, yaw]), 0, atol=1e-6)


@FAST
@given(rpy=st.one_of(rpy_any_deg, rpy_walls_deg))
def test_rpy_of_any_rotation_rebuilds_it(rpy):
    """Even at gimbal lock, where roll and yaw are not unique, the angles give back the same rotation."""
    R = frames.rotation_from_rpy_deg(*rpy)
    roll, pitch, yaw = frames.rpy_deg_from_rotation(R)
    assert -90 - 1e-9 <= pitch <= 90 + 1e-9
    assert -180 - 1e-9 <= roll <= 180 + 1e-9
    assert -180 - 1e-9 <= yaw <= 180 + 1e-9
    np.testing.assert_allclose(frames.rotation_from_rpy_deg(roll, pitch, yaw), R, atol=1e-6)


@FAST
@given(rpy=st.one_of(rpy_any_deg, rpy_walls_deg))
def test_rotation_from_rpy_is_a_rotation_about_fixed_axes(rpy):
    roll, pitch, yaw = (math.radians(v) for v in rpy)
    R = frames.rotation_from_rpy_deg(*rpy)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(R, frames.rot_z(yaw) @ frames.rot_y(pitch) @ frames.rot_x(roll), atol=1e-12)


@FAST
@given(
    T=rigid_transforms(),
    scale=st.floats(1.01, 10),
    axis=st.integers(0, 2),
)
def test_check_transform_refuses_what_is_not_rigid(T, scale, axis):
    stretched = T.copy()
    stretched[:3, axis] *= scale
    with pytest.raises(TransformError, match="not orthonormal"):
        frames.check_transform(stretched)
    mirrored = T.copy()
    mirrored[:3, axis] *= -1
    with pytest.raises(TransformError, match="reflection"):
        frames.invert_transform(mirrored)
    bottom = T.copy()
    bottom[3, axis] = scale
    with pytest.raises(TransformError, match="bottom row"):
        frames.compose(T, bottom)


# -- the camera: scaling follows the pixel-centre convention ---------------------------------
from fidlearn.camera import Camera  # noqa: E402


@FAST
@given(
    hfov=st.floats(20, 120),
    size=st.sampled_from([(640, 480), (1280, 720), (1920, 1080), (800, 600)]),
    factor=st.sampled_from([0.25, 0.5, 2.0, 3.0]),
    k1=st.floats(-0.3, 0.3),
    point=st.tuples(st.floats(-300, 300), st.floats(-300, 300), st.floats(500, 5000)),
)
def test_a_scaled_camera_sees_the_same_picture_scaled(hfov, size, factor, k1, point):
    """Binning or resizing scales pixel *edges*: a pixel centre u maps to (u + 0.5) * s - 0.5."""
    cam = Camera.from_fov(hfov, size, dist=[k1, 0, 0, 0, 0])
    new_size = (round(size[0] * factor), round(size[1] * factor))
    scaled = cam.scaled(new_size)
    px = cam.project(np.array([point]), np.eye(4))
    px_scaled = scaled.project(np.array([point]), np.eye(4))
    np.testing.assert_allclose(px_scaled, (px + 0.5) * factor - 0.5, atol=1e-6 * max(size))
    np.testing.assert_allclose(scaled.fov_deg, cam.fov_deg, atol=0.2)  # the scene fills the same share


@FAST
@given(
    hfov=st.floats(30, 100),
    k=st.tuples(st.floats(-0.2, 0.2), st.floats(-0.05, 0.05)),
    p=st.tuples(st.floats(-1e-3, 1e-3), st.floats(-1e-3, 1e-3)),
    xy=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.2, 0.2)),
)
def test_undistort_undoes_distortion_in_the_middle_of_the_picture(hfov, k, p, xy):
    """Distorting a point with project() and undistorting it lands on the ideal pinhole pixel."""
    lens = Camera.from_fov(hfov, (640, 480), dist=[k[0], k[1], p[0], p[1], 0])
    pinhole = Camera(lens.K, None, lens.image_size)
    point = np.array([[xy[0] * 1000, xy[1] * 1000, 1000.0]])
    ideal = pinhole.project(point, np.eye(4))
    np.testing.assert_allclose(lens.undistort_points(lens.project(point, np.eye(4))), ideal, atol=0.01)
