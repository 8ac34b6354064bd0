"""The shortcuts of the fisheye path give what the longer computations they replace give: the profiles' levels by
one reduction over their samples, the weighted fit's last residuals and Jacobian, the ideal corners' detections, the
side fit's sampling map and side normals, its planes' normals without eigh and its cross products without np.cross,
the ray angles' Newton steps, the lens Jacobians in closed form, the weighted fit's converged stop, the second
look's projection."""

from __future__ import annotations

import cv2
import numpy as np

from fidlearn import Camera, MarkerMap, frames
from fidlearn._detector import _detector_fields
from fidlearn._fisheye_edges import (
    _NEXT,
    _PREV,
    _cross,
    _fit_planes,
    _least_eigenvector,
    _rays,
    _sample_map,
    _side_curves,
)
from fidlearn._lens import _fisheye_theta_d, fisheye_angles, pixels_from_normalized, project_points
from fidlearn.detection import Detection
from fidlearn.pose._inputs import _as_pinhole, _lens_jacobians, _lens_refine
from fidlearn.pose._refine import _residuals
from fidlearn.pose._second_look import _border_bits, missed_in_view, read_again
from fidlearn.refinement import _least, _most

K_FE = np.array([[290.050152, 0.0, 399.938345], [0.0, 289.392837, 273.885669], [0.0, 0.0, 1.0]])
D_FE = np.array([-0.030464, -0.019695, 0.002098, 0.001030])


def test_the_levels_reduction_gives_numpys_min_and_max():
    rng = np.random.default_rng(3)
    prof = (rng.uniform(0, 255, size=(5, 4, 16, 13))).astype(np.float32)
    prof[2, 1, 7, 4] = np.nan  # numpy's min and max carry a NaN through; so must these
    for part in (prof[..., :7], prof[..., 6:], prof[:0, ..., :7]):
        assert np.array_equal(_least(part), part.min(-1), equal_nan=True)
        assert np.array_equal(_most(part), part.max(-1), equal_nan=True)
    assert np.isnan(_least(prof[..., :7])[2, 1, 7])


def test_the_weighted_fit_returns_the_residuals_and_jacobian_of_its_pose():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    pinhole = Camera(K_FE, None, (800, 503))
    s = 60.0
    square = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]])
    obj = np.concatenate([square + [x, y, 0] for x, y in ((-150, 0), (150, 40), (0, -160))])
    T = frames.look_at([100.0, -80.0, -600.0], [0.0, 0.0, 0.0])
    rng = np.random.default_rng(7)
    ideal = pinhole.project(obj, T) + rng.normal(0, 0.2, (len(obj), 2))
    D = _lens_jacobians(fisheye, ideal)
    start_R = cv2.Rodrigues(np.array([0.01, -0.02, 0.015]))[0] @ T[:3, :3]
    R, C, weighted_J, r, J = _lens_refine(obj, ideal, pinhole, D, start_R, T[:3, 3] + [3.0, -2.0, 4.0])
    r_again, J_again = _residuals(obj, ideal, pinhole.K, pinhole.dist, R, C, True)
    assert np.array_equal(r, r_again)
    assert np.array_equal(J, J_again)
    assert np.allclose(weighted_J, (D @ J.reshape(-1, 2, 6)).reshape(-1, 6))
    r_start, _ = _residuals(obj, ideal, pinhole.K, pinhole.dist, start_R, T[:3, 3] + [3.0, -2.0, 4.0], False)

    def picture_sse(res):
        w = (D @ res.reshape(-1, 2, 1)).ravel()
        return float(w @ w)

    assert picture_sse(r) < 0.01 * picture_sse(r_start)  # it moved from the start (5.4 mm off) to the fit
    assert np.linalg.norm(C - T[:3, 3]) < 3.0  # within the noise of 0.2 px on 12 corners at 0.6 m


def test_the_ideal_corners_keep_id_and_dictionary_and_drop_markers_past_90_degrees():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    near = Detection(4, [[390, 260], [420, 262], [418, 290], [388, 288]], "ARUCO_ORIGINAL")
    # a corner beyond 90 degrees off the axis: no pinhole picture of it
    far = Detection(9, [[0, 10], [30, 10], [30, 40], [-400, 40]], "ARUCO_ORIGINAL")
    out, pinhole, beyond = _as_pinhole([near, far], fisheye)
    assert [d.id for d in out] == [4]
    assert beyond == [far]
    assert out[0].dictionary == "ARUCO_ORIGINAL"
    assert np.array_equal(out[0].corners_px, fisheye.undistort_points(near.corners_px))
    assert out[0].corners_px.shape == (4, 2)
    assert out[0].corners_px.dtype == np.float64
    assert pinhole.model == "pinhole"
    assert np.array_equal(pinhole.K, fisheye.K)


def test_no_missed_marker_means_no_second_look():
    assert read_again(np.full((60, 80), 255, np.uint8), [], None, None) == []


def _sides(camera: Camera, n: int = 16):
    """Points and unit normals on the bent sides of three markers seen through ``camera``, at ``n`` positions each."""
    C = np.array(
        [
            [[390, 260], [420, 262], [418, 290], [388, 288]],
            [[40, 60], [75, 50], [82, 85], [48, 95]],
            [[700, 420], [760, 430], [752, 470], [695, 462]],
        ],
        dtype=np.float64,
    )
    t = np.broadcast_to(0.1 + 0.8 * np.linspace(0.0, 1.0, n), (3, 4, n))
    return C, *_side_curves(C, _rays(C, camera), camera, t)


def test_the_side_normals_are_numpys_gradient_turned_outward():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    C, P, nz = _sides(fisheye)
    tangent = np.gradient(P, axis=2)  # what the central differences replace
    Z = C[..., 0] + 1j * C[..., 1]
    Dz = Z[:, _NEXT] - Z
    turn = np.where((Dz[:, 0].conj() * Dz[:, 1]).imag >= 0, -1j, 1j)
    np.testing.assert_allclose(nz, tangent / np.abs(tangent) * turn[:, None, None], rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.abs(nz), 1.0, rtol=0, atol=1e-12)  # unit normals, across the side
    np.testing.assert_allclose((tangent.conj() * nz).real / np.abs(tangent), 0.0, rtol=0, atol=1e-12)
    # the middle marker's sides turn clockwise on screen: outward is -i times the direction
    np.testing.assert_allclose(nz[0] / (tangent[0] / np.abs(tangent[0])), -1j, rtol=0, atol=1e-12)


def test_the_sampling_map_is_the_complex_sum_in_single_precision():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    _, P, nz = _sides(fisheye)
    h = np.array([1.5, 2.2, 5.0])
    v = np.linspace(-1.0, 1.0, 13)
    ok = np.ones(3, bool)
    pts = (P[..., None] + (h[:, None, None, None] * v) * nz[..., None]).astype(np.complex64)  # what it replaces
    got = _sample_map(P, nz, h, v, ok)
    assert got.shape == (12, 16 * 13, 2)
    assert got.dtype == np.float32
    assert np.array_equal(got, pts.view(np.float32).reshape(12, -1, 2))
    # a marker whose side has no normal: read far outside the picture, the others as they were
    nz_bad = nz.copy()
    nz_bad[1, 2, 5] = np.nan
    ok = np.isfinite(nz_bad).all(axis=(1, 2))
    bad = _sample_map(P, nz_bad, h, v, ok).reshape(3, 4, -1, 2)
    assert (bad[1] == -10.0).all()
    assert np.array_equal(bad[[0, 2]], got.reshape(3, 4, -1, 2)[[0, 2]])


def test_the_second_look_predicts_the_corners_camera_project_gives():
    wall = MarkerMap.from_dict(
        {str(k): {"translation": [0, 200 * k - 500, 0], "rotation": [0, 0, 0]} for k in range(6)},
        marker_size_mm=120,
        units="mm",
    )
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    T = frames.look_at([600.0, 80.0, -60.0], [0.0, -100.0, 0.0], roll_deg=12.0)
    missed = missed_in_view(wall, fisheye, T, {2}, None)
    assert [k for k, _, _ in missed] == [0, 1, 3, 4, 5]
    for k, name, q in missed:
        assert name == "ARUCO_ORIGINAL"
        np.testing.assert_allclose(q, fisheye.project(wall.marker_corners(k), T), rtol=0, atol=1e-9)


def test_the_border_bits_read_once_are_the_detectors():
    assert _border_bits(None) == int(_detector_fields(None)["markerBorderBits"]) == 1
    assert _border_bits({"markerBorderBits": 2}) == 2


def test_the_cross_products_are_numpys():
    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(2, 7, 4, 3))
    assert np.array_equal(_cross(a, b), np.cross(a, b))


def test_the_planes_normals_are_eighs_smallest_eigenvector():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    C, P, nz = _sides(fisheye)
    rng = np.random.default_rng(11)
    E = P + rng.normal(0, 0.05, P.shape) * nz  # edge crossings with 0.05 px of noise about the bent sides
    rays = _rays(np.ascontiguousarray(E)[..., None].view(np.float64), fisheye)
    w = (rng.uniform(size=P.shape) > 0.2).astype(float)  # some profiles without a crossing
    A = (rays * w[..., None]).swapaxes(-1, -2) @ rays
    r = _rays(C, fisheye)
    got = _least_eigenvector(A, _cross(r, r[:, _NEXT]))
    want = np.linalg.eigh(A)[1][..., 0]  # what it replaces
    sign = np.sign(np.sum(got * want, axis=-1, keepdims=True))
    np.testing.assert_allclose(got * sign, want, rtol=0, atol=1e-12)
    # the corners the planes give: eigh's to 1e-9 px
    new, fitted = _fit_planes(E, w, fisheye, r)
    X = np.cross(want[:, _PREV], want)
    X = X * np.sign(np.einsum("mki,mki->mk", X, r))[..., None]
    want_px = project_points(X.reshape(-1, 3), K_FE, D_FE, "fisheye").reshape(new.shape)
    np.testing.assert_allclose(new, want_px, rtol=0, atol=1e-9)
    assert np.array_equal(fitted, (X[..., 2] > 0).all(1))
    assert fitted[0]  # the marker near the centre
    # a side with no weight has no plane: NaN, and the marker is not fitted
    w[0, 2] = 0.0
    new, fitted = _fit_planes(E, w, fisheye, r)
    assert not fitted[0]
    assert np.isnan(new[0, 2:]).all()


def test_the_ray_angles_are_the_plain_newton_steps():
    rng = np.random.default_rng(2)
    px = np.concatenate([rng.uniform(-1500, 2300, (4000, 2)), K_FE[:2, 2][None]])  # beyond the fold too
    for dist in (D_FE, np.zeros(4), np.array([0.1, -0.2, 0.05, -0.01])):
        # what it replaces: theta_d and its slope each on its own, np.clip
        yd = (px[:, 1] - K_FE[1, 2]) / K_FE[1, 1]
        xd = (px[:, 0] - K_FE[0, 2] - K_FE[0, 1] * yd) / K_FE[0, 0]
        theta_d = np.hypot(xd, yd)
        k1, k2, k3, k4 = dist

        def slope(t, k1=k1, k2=k2, k3=k3, k4=k4):
            t2 = t * t
            return 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))

        theta = np.minimum(theta_d, np.pi)
        for _ in range(50):
            s = slope(theta)
            step = (_fisheye_theta_d(theta, dist) - theta_d) / np.where(s > 0, s, 1.0)
            theta = np.clip(theta - step, 0.0, np.pi)
            if np.all(np.abs(step) < 1e-15):
                break
        reached = np.abs(_fisheye_theta_d(theta, dist) - theta_d) <= 1e-12 * np.maximum(1.0, theta_d)
        theta = np.where(reached & (slope(theta) > 0), theta, np.nan)
        got = fisheye_angles(px, K_FE, dist)
        assert np.array_equal(got[0], theta, equal_nan=True)
        assert np.array_equal(got[1], np.stack([xd, yd], axis=1))
        assert np.array_equal(got[2], theta_d)
    assert np.isnan(fisheye_angles(px, K_FE, np.array([0.1, -0.2, 0.05, -0.01]))[0]).any()  # a fold


def test_the_lens_jacobians_are_the_models_central_differences():
    rng = np.random.default_rng(4)
    ideal = np.concatenate([rng.uniform(-2500, 3300, (2000, 2)), K_FE[:2, 2] + rng.normal(0, 1e-7, (5, 2))])
    for dist in (D_FE, np.zeros(4)):
        fisheye = Camera(K_FE, dist, (800, 503), model="fisheye")
        h = 1e-2  # what it replaces: Camera.project's model 0.01 ideal px either side
        steps = np.array([[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]])
        pts = (ideal[:, None, :] + steps[None]).reshape(-1, 2)
        xy = np.stack([(pts[:, 0] - K_FE[0, 2]) / K_FE[0, 0], (pts[:, 1] - K_FE[1, 2]) / K_FE[1, 1]], axis=1)
        px = pixels_from_normalized(xy, K_FE, dist, "fisheye").reshape(-1, 4, 2)
        want = np.stack([(px[:, 0] - px[:, 1]) / (2 * h), (px[:, 2] - px[:, 3]) / (2 * h)], axis=2)
        got = _lens_jacobians(fisheye, ideal)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-7 * np.abs(want).max())
        # the equidistant lens at the axis: the picture's pixels are the ideal ones
        if not dist.any():
            np.testing.assert_allclose(got[-5:], np.broadcast_to(np.eye(2), (5, 2, 2)), atol=1e-9)


def test_the_weighted_fit_stops_where_the_longer_fit_does():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    pinhole = Camera(K_FE, None, (800, 503))
    s = 60.0
    square = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]])
    obj = np.concatenate([square + [x, y, 0] for x, y in ((-250, 0), (150, 40), (0, -160), (260, 150))])
    T = frames.look_at([250.0, -80.0, -450.0], [0.0, 0.0, 0.0])
    rng = np.random.default_rng(9)
    ideal = pinhole.project(obj, T) + rng.normal(0, 0.3, (len(obj), 2))
    D = _lens_jacobians(fisheye, ideal)
    start_R, start_C = cv2.Rodrigues(np.array([0.01, -0.02, 0.015]))[0] @ T[:3, :3], T[:3, 3] + [3.0, -2.0, 4.0]
    R, C, _, r, _ = _lens_refine(obj, ideal, pinhole, D, start_R, start_C)

    def picture(R_wc, c):
        res, J = _residuals(obj, ideal, pinhole.K, pinhole.dist, R_wc, c, True)
        return (D @ res.reshape(-1, 2, 1)).ravel(), (D @ J.reshape(-1, 2, 6)).reshape(-1, 6)

    # what it replaces: Gauss-Newton steps until a step no longer lowers the sum by 1e-10 of it
    R0, C0 = start_R, start_C
    res, J = picture(R0, C0)
    for _ in range(10):
        step = cv2.solve(J.T @ J, (J.T @ res).reshape(6, 1))[1].ravel()
        R1, C1 = cv2.Rodrigues(step[:3])[0] @ R0, C0 + step[3:]
        res1, J1 = picture(R1, C1)
        if not res1 @ res1 < res @ res:
            break
        done = res @ res - res1 @ res1 < 1e-10 * (res @ res) + 1e-12
        R0, C0, res, J = R1, C1, res1, J1
        if done:
            break
    cov = np.linalg.inv(J.T @ J) * (res @ res) / (len(res) - 6)
    assert np.linalg.norm(C - C0) < 1e-4 * np.sqrt(np.trace(cov[3:, 3:]))  # 1e-4 of its standard deviation
    assert np.abs(R - R0).max() < 1e-4 * np.sqrt(np.trace(cov[:3, :3]))
    assert np.linalg.norm(C - T[:3, 3]) < 5.0  # and the fit itself: within the noise of the truth
    np.testing.assert_array_equal(r, _residuals(obj, ideal, pinhole.K, pinhole.dist, R, C, False)[0])


def test_the_rim_test_leaves_out_a_corner_where_a_pixel_bends_its_ideal_pixel_as_much_as_it_moves_it():
    from fidlearn.pose._inputs import _rim_markers

    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    f = np.sqrt(K_FE[0, 0] * K_FE[1, 1])

    def excess(theta):  # r - f theta_d'(theta): positive past the rim angle
        k1, k2, k3, k4 = D_FE
        slope = 1 + 3 * k1 * theta**2 + 5 * k2 * theta**4 + 7 * k3 * theta**6 + 9 * k4 * theta**8
        return np.tan(theta) - f * slope

    lo, hi = np.radians(80), np.radians(89.999)
    for _ in range(60):  # bisection: the rim angle of this lens
        lo, hi = (lo, (lo + hi) / 2) if excess((lo + hi) / 2) > 0 else ((lo + hi) / 2, hi)
    assert 89.7 < np.degrees(lo) < 89.9  # close to an equidistant lens's 89.8 degrees at 290 px per radian
    direction = np.array([0.6, -0.8])

    def marker(theta):  # a small square with one corner theta off the axis, in ideal pixels
        tip = np.tan(theta) * direction
        pts = np.array([tip, tip * 0.99, tip * 0.99 + [0.01, 0.0], tip + [0.01, 0.0]])
        return np.column_stack([K_FE[0, 0] * pts[:, 0] + K_FE[0, 2], K_FE[1, 1] * pts[:, 1] + K_FE[1, 2]])

    corners = {1: marker(lo - 1e-4), 2: marker(hi + 1e-4), 3: marker(np.radians(45))}
    assert _rim_markers(corners, fisheye) == [2]
    assert _rim_markers({2: corners[2]}, fisheye) == []  # the only marker is kept


def test_the_weighted_fit_from_a_fits_own_residuals_is_the_fit_that_computes_them():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    pinhole = Camera(K_FE, None, (800, 503))
    s = 60.0
    square = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]])
    obj = np.concatenate([square + [x, y, 0] for x, y in ((-250, 0), (150, 40), (0, -160))])
    T = frames.look_at([150.0, -60.0, -500.0], [0.0, 0.0, 0.0])
    ideal = pinhole.project(obj, T) + np.random.default_rng(4).normal(0, 0.3, (len(obj), 2))
    D = _lens_jacobians(fisheye, ideal)
    R0, C0 = cv2.Rodrigues(np.array([0.01, -0.02, 0.015]))[0] @ T[:3, :3], T[:3, 3] + [3.0, -2.0, 4.0]
    given = _lens_refine(obj, ideal, pinhole, D, R0, C0, _residuals(obj, ideal, pinhole.K, pinhole.dist, R0, C0, True))
    for a, b in zip(given, _lens_refine(obj, ideal, pinhole, D, R0, C0)):
        assert np.array_equal(a, b)
