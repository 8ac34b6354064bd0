"""The fast paths of ``estimate_pose`` give the numbers of the straightforward computation.

The noise of a pose's corners and its covariance in closed forms for 6 x 6 (``fidlearn.pose._noise_fast``)
against ``fidlearn.pose._noise`` and against dense (8M, 8M) matrices written out by hand; the pose of rendered
markers against its truth, computed with and without the fast paths.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_pose import CAM, look_at, wall_map

from fidlearn import estimate_pose
from fidlearn.detection import Detection
from fidlearn.pose import _estimate, _noise, _noise_fast, pose_jacobian


def _scene(n_markers: int, seed: int):
    """Corners (M, 4, 2) of ``n_markers`` of a wall seen from an oblique seeded viewpoint, with 0.3 px of noise,
    their Jacobian (8M, 6) at the true pose and residual-like noise (8M,)."""
    rng = np.random.default_rng(seed)
    m = wall_map(n_cols=max(1, n_markers), n_rows=1, size=120.0, spacing=260.0)
    ids = m.ids[:n_markers]
    centre = np.mean([m.corners()[i].mean(axis=0) for i in ids], axis=0)
    eye = centre + np.array([1500.0 + 300 * rng.random(), 400 * rng.normal(), 300 * rng.normal()])
    T = look_at(eye, centre)
    P = np.concatenate([m.corners()[i] for i in ids])
    q = CAM.project(P, T).reshape(-1, 4, 2) + rng.normal(0, 0.3, (n_markers, 4, 2))
    return q, pose_jacobian(P, T, CAM), rng.normal(0, 0.3, 8 * n_markers)


def _dense_cov(J, q, parts):
    """``(J^T J)^-1 J^T Sigma J (J^T J)^-1`` with Sigma the (8M, 8M) block-diagonal covariance written out, plus
    the common size error's effect, widened by the Hotelling factor: the module's docstring, by hand."""
    M = len(q)
    grow = (q - q.mean(axis=1, keepdims=True)).reshape(M, 8)
    Sigma = np.zeros((8 * M, 8 * M))
    shift = np.kron(np.ones((4, 4)), np.eye(2))
    for k in range(M):
        Sigma[8 * k : 8 * k + 8, 8 * k : 8 * k + 8] = (
            parts.a * np.eye(8) + parts.b * shift + parts.c * np.outer(grow[k], grow[k])
        )
    G = np.linalg.inv(J.T @ J)
    d = G @ J.T @ grow.reshape(-1)
    cov = G @ J.T @ Sigma @ J @ G + parts.size**2 * np.outer(d, d)
    return cov * (1.0 if parts.nu is None else _noise._inflation(round(parts.nu, 1)))


@pytest.mark.parametrize("n_markers", [1, 2, 3, 5])
@pytest.mark.parametrize("sigma", [None, 0.4])
def test_the_closed_forms_give_the_straightforward_noise_and_covariance(n_markers, sigma):
    for seed in range(3):
        q, J, r = _scene(n_markers, seed)
        want = _noise._noise_parts(r, J, q, sigma)
        got = _noise_fast._noise_parts_fast(r, J, q, sigma)
        for name in ("a", "b", "c", "size", "nu"):
            if getattr(want, name) is None:
                assert getattr(got, name) is None, name
            else:
                assert getattr(got, name) == pytest.approx(getattr(want, name), rel=1e-9, abs=1e-15), name
        cov_ref = _noise._pose_covariance(J, q, want)
        cov = _noise_fast._pose_covariance_fast(J, q, want)
        # round-off of (J^T J)^-1, cond(J^T J) up to 1e8 for one marker
        np.testing.assert_allclose(cov, cov_ref, rtol=1e-7, atol=1e-10 * np.abs(cov_ref).max())
        np.testing.assert_allclose(cov, _dense_cov(J, q, want), rtol=1e-7, atol=1e-10 * np.abs(cov_ref).max())


@pytest.mark.parametrize("sigma", [None, 0.3])
def test_measured_shifts_and_size_errors_are_the_straightforward_ones(sigma):
    """Residuals with a shift and a size error of each marker and a common size error (8 markers): the three parts
    are all measured (not zero), as the straightforward moment equations measure them."""
    q, J, _ = _scene(8, 3)
    rng = np.random.default_rng(11)
    grow = (q - q.mean(axis=1, keepdims=True)).reshape(8, 8)
    r = (
        rng.normal(0, 0.3, (8, 8))
        + np.tile(rng.normal(0, 0.8, (8, 1, 2)), (1, 4, 1)).reshape(8, 8)
        + grow * (rng.normal(0.004, 0.01, (8, 1)))
    ).reshape(-1)
    want = _noise._noise_parts(r, J, q, sigma)
    got = _noise_fast._noise_parts_fast(r, J, q, sigma)
    assert min(want.a, want.b, want.c, abs(want.size)) > 0
    for name in ("a", "b", "c", "size", "nu"):
        assert getattr(got, name) == pytest.approx(getattr(want, name), rel=1e-8), name


def test_a_size_error_and_a_shift_enter_the_closed_form_as_written_out():
    """Parts with every term non-zero (a measured common size error too), which the estimates above need not have."""
    q, J, _ = _scene(3, 7)
    parts = _noise._NoiseParts(0.09, 0.2, 3e-5, size=0.004, nu=11.0)
    want = _dense_cov(J, q, parts)
    np.testing.assert_allclose(_noise_fast._pose_covariance_fast(J, q, parts), want, rtol=1e-8)
    np.testing.assert_allclose(_noise._pose_covariance(J, q, parts), want, rtol=1e-8)
    # a wrong weight would show: the shift alone is a large part of the whole
    wrong = _noise._NoiseParts(0.09, 0.0, 3e-5, size=0.004, nu=11.0)
    assert np.abs(_noise_fast._pose_covariance_fast(J, q, wrong) - want).max() > 0.05 * np.abs(want).max()


def test_a_singular_jacobian_gives_no_covariance():
    q, J, r = _scene(1, 0)
    J = J.copy()
    J[:, 5] = J[:, 4]  # two columns alike: the pose is not determined
    assert _noise_fast._pose_covariance_fast(J, q, _noise._NoiseParts(0.1, 0.0, 0.0)) is None


@pytest.mark.parametrize("n_markers", [1, 2, 3, 6])
def test_estimate_pose_gives_the_same_pose_with_and_without_the_fast_paths(n_markers, monkeypatch):
    """Rendered corners of a known pose (0.3 px of noise): the pose is near the truth, and the straightforward
    computation gives the same pose, flags, covariance and alternative to round-off."""
    rng = np.random.default_rng(40 + n_markers)
    m = wall_map(n_cols=n_markers, n_rows=1, size=150.0, spacing=300.0)
    centre = np.mean([c.mean(axis=0) for c in m.corners().values()], axis=0)
    T = look_at(centre + [2000.0, 350.0, -200.0], centre)
    dets = [Detection(i, CAM.project(c, T) + rng.normal(0, 0.3, (4, 2))) for i, c in m.corners().items()]
    fast = estimate_pose(dets, m, CAM)
    with monkeypatch.context() as mp:
        mp.setattr(_estimate, "_noise_parts", lambda r, J, q, sigma, _JtJ=None: _noise._noise_parts(r, J, q, sigma))
        mp.setattr(
            _estimate,
            "_pose_covariance_fast",
            lambda J, q, parts, _JtJ=None, _sums=None: _noise._pose_covariance(J, q, parts),
        )
        plain = estimate_pose(dets, m, CAM)
    d = fast.position_mm - T[:3, 3]  # the truth, within 4 of its sigmas (one marker is 150 mm wide at 2 m)
    assert float(d @ np.linalg.solve(fast.covariance[3:, 3:], d)) < 16.0
    for a, b in ((fast, plain), (fast.alternative, plain.alternative)):
        if a is None or b is None:
            assert (a, b) == (None, None)
            continue
        np.testing.assert_allclose(a.T_world_camera, b.T_world_camera, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.covariance, b.covariance, rtol=1e-7, atol=1e-10 * np.abs(b.covariance).max())
        assert (a.ambiguous, a.method, a.marker_ids) == (b.ambiguous, b.method, b.marker_ids)
        assert a.corner_sigma_px == pytest.approx(b.corner_sigma_px, rel=1e-12)


@pytest.mark.parametrize("n_markers", [2, 5])
def test_the_noise_hands_its_part_sums_to_the_covariance_at_the_same_jacobian(n_markers):
    """The noise returns the 6 x 6 sums of its Jacobian (measured with the 7th column when split, written alone
    with fewer markers); the covariance at that Jacobian given them is the one it computes itself, and the one
    written out by hand. Another Jacobian or other corners (the alternative pose, another frame) get their own."""
    q, J, r = _scene(n_markers, 2)
    q2, J2, _ = _scene(n_markers, 4)
    parts = _noise_fast._noise_parts_fast(r, J, q, None)
    assert parts.sums is not None
    own = _noise_fast._part_matrices(J, q)._replace(G=np.linalg.inv(J.T @ J))
    for got, want in zip(parts.sums, own):
        # G by OpenCV's LU against numpy's inverse: apart by the condition number's rounding (1e-12 of the
        # largest element on the reference numpy, 1.3e-12 on the oldest)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-10 * np.abs(want).max())
    shared = _noise_fast._pose_covariance_fast(J, q, parts, sums=parts.sums)
    np.testing.assert_allclose(shared, _noise_fast._pose_covariance_fast(J, q, parts), rtol=1e-12)
    np.testing.assert_allclose(shared, _dense_cov(J, q, parts), rtol=1e-7)
    for Jx, qx in ((J2, q2), (J, q2), (J2.copy(), q2)):
        got = _noise_fast._pose_covariance_fast(Jx, qx, parts)
        np.testing.assert_allclose(got, _dense_cov(Jx, qx, parts), rtol=1e-7)
        assert np.abs(got - shared).max() > 1e-3 * np.abs(shared).max()  # not the first pose's sums
    assert not hasattr(_noise_fast, "_LAST_PARTS")  # nothing kept between calls


def test_the_prior_blends_the_estimated_corner_noise_alone():
    """8 markers: 39 degrees of freedom of the corner noise, 10 of the shift, 7 of the size; estimated, the corner
    noise 0.04 px^2 meets the prior 0.25^2 worth PRIOR_DOF = 2: (2 * 0.0625 + 39 * 0.04) / 41; given, nothing moves."""
    theta = np.array([0.04, 0.2, 1e-5])
    nus = _noise._blend_prior(theta, 8, None)
    np.testing.assert_array_equal(nus, [41.0, 10.0, 7.0])
    assert theta[0] == pytest.approx((2 * 0.25**2 + 39 * 0.04) / 41, rel=1e-15)
    assert list(theta[1:]) == [0.2, 1e-5]
    theta = np.array([0.09, 0.2, 1e-5])
    np.testing.assert_array_equal(_noise._blend_prior(theta, 8, 0.3), [np.inf, 10.0, 7.0])
    assert list(theta) == [0.09, 0.2, 1e-5]


@pytest.mark.parametrize("n_markers", [3, 4, 8, 20])
def test_the_screens_remembered_quantiles_are_scipys(n_markers):
    """The screen's three quantiles, computed once per number of markers, are the ones ``fidlearn._stats`` gives
    (and a wrong argument shows: the chi-square of 2N - 6 degrees of freedom is not that of 2N - 5)."""
    from fidlearn import _stats
    from fidlearn.pose import _outliers

    dof = 8 * n_markers - 6
    p_any = _outliers.SCREEN_P - _outliers.DISPLACEMENT_P
    for _ in range(2):  # computed, then remembered
        assert _outliers._chi2_isf(p_any, dof) == _stats.chi2_isf(p_any, dof)
        assert _outliers._beta_isf(p_any / n_markers, 4, (dof - 8) // 2) == _stats.beta_isf(
            p_any / n_markers, 4, (dof - 8) // 2
        )
        p = _outliers.DISPLACEMENT_P / n_markers
        assert _outliers._f_isf(p, 2, dof - 2) == _stats.f_isf(p, 2, dof - 2)
    assert _outliers._chi2_isf(p_any, dof) != _stats.chi2_isf(p_any, dof + 1)


def test_the_solvers_solutions_are_read_as_before(monkeypatch):
    """``_generic`` reads OpenCV's solutions with Python's isfinite: the same rotations, translations and sums of
    squares as numpy's checks give, and a solution with a NaN or an infinite entry, or a NaN RMS, left out or
    without its sum of squares as before."""
    import cv2

    from fidlearn.pose import _solvers

    q, _, _ = _scene(1, 5)
    obj = np.array([[-75.0, 75, 0], [75, 75, 0], [75, -75, 0], [-75, -75, 0]])
    n, rvecs, tvecs, rms = cv2.solvePnPGeneric(obj, q[0], CAM.K, CAM.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    assert n == 2
    got = _solvers._generic("IPPE_SQUARE", obj, q[0], CAM)
    for (R, t, sse), rv, tv, e in zip(got, rvecs, tvecs, rms.reshape(-1)):
        np.testing.assert_array_equal(R, cv2.Rodrigues(rv)[0])
        np.testing.assert_array_equal(t, tv.reshape(3))
        assert sse == float(e) ** 2 * 2 * 4
    bad = (
        3,
        (rvecs[0], np.array([[np.nan], [0.0], [0.0]]), rvecs[1]),
        (tvecs[0], tvecs[1], np.array([[0.0], [np.inf], [900.0]])),
        np.array([[rms[0, 0]], [rms[1, 0]], [np.nan]]),
    )
    monkeypatch.setattr(_solvers.cv2, "solvePnPGeneric", lambda *_args, **_kwargs: bad)
    got = _solvers._generic("IPPE_SQUARE", obj, q[0], CAM)
    assert len(got) == 1  # the NaN rotation and the infinite translation are left out
    np.testing.assert_array_equal(got[0][1], tvecs[0].reshape(3))
    monkeypatch.setattr(_solvers.cv2, "solvePnPGeneric", lambda *_args, **_kwargs: (1, bad[1][:1], bad[2][:1], None))
    assert _solvers._generic("IPPE_SQUARE", obj, q[0], CAM)[0][2] is None  # no RMS: the sum of squares left for later
    nan_rms = (1, bad[1][:1], bad[2][:1], np.array([[np.nan]]))
    monkeypatch.setattr(_solvers.cv2, "solvePnPGeneric", lambda *_args, **_kwargs: nan_rms)
    assert _solvers._generic("IPPE_SQUARE", obj, q[0], CAM)[0][2] is None
