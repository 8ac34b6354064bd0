"""The noise a pose's residuals hold (``fidlearn.pose._noise``): its moment equations against a dense hand
computation, its estimates against known variance components, and the coverage of the 95 % ellipsoid it gives."""

from __future__ import annotations

import numpy as np
import pytest
from test_pose import CAM, look_at, observe, two_wall_map, wall_map

from fidlearn import estimate_pose
from fidlearn.pose import _noise, pose_jacobian


def _scene(n_cols=4, n_rows=3):
    """Corners (M, 4, 2) of a wall of markers seen from 1.7 m, their Jacobian (8M, 6) and the growth (M, 8)."""
    m = wall_map(n_cols=n_cols, n_rows=n_rows, size=120.0, spacing=300.0)
    T = look_at([1700.0, 500.0, 1100.0], [0.0, 450.0, 1150.0])
    P = np.concatenate(list(m.corners().values()))
    q = CAM.project(P, T).reshape(-1, 4, 2)
    return q, pose_jacobian(P, T, CAM), (q - q.mean(axis=1, keepdims=True)).reshape(len(q), 8)


def _dense(blocks):
    """The block-diagonal (8M, 8M) matrix of per-marker blocks (M, 8, 8)."""
    M = len(blocks)
    out = np.zeros((8 * M, 8 * M))
    for k, b in enumerate(blocks):
        out[8 * k : 8 * k + 8, 8 * k : 8 * k + 8] = b
    return out


def test_the_expected_statistics_are_the_dense_traces():
    """``E[r^T S r] = tr((I - H) S (I - H) C)`` for ``r = (I - H) e``, ``e ~ N(0, C)``, written out with dense
    matrices; for unit corner noise and ``S = I`` it is ``8M - 7`` (the pose's 6 columns and the common size)."""
    q, J, grow = _scene()
    M = len(q)
    X = np.column_stack([J, grow.reshape(-1)])
    G = np.linalg.inv(X.T @ X)
    Xb = X.reshape(M, 8, 7)
    IH = np.eye(8 * M) - X @ G @ X.T
    size = np.einsum("mi,mj->mij", grow, grow) / np.einsum("mi,mi->m", grow, grow)[:, None, None]
    stats = {"mean": np.broadcast_to(_noise._MEAN8, (M, 8, 8)), "size": size}
    stats["rest"] = np.eye(8) - stats["mean"] - size
    parts = _noise._parts_cov(grow)
    for name, S in stats.items():
        S_arg = _noise._MEAN8 if name == "mean" else S  # the function takes a shared block as (8, 8)
        XSX = _noise._blocks(Xb, S_arg)
        for k, C in enumerate(parts):
            C_dense = _dense(np.broadcast_to(C, (M, 8, 8)))
            want = float(np.trace(IH @ _dense(S) @ IH @ C_dense))
            got = _noise._expected(S_arg, C, Xb, G, XSX)
            assert got == pytest.approx(want, rel=1e-9, abs=1e-9), (name, k)
    XSX = _noise._blocks(Xb, _noise._EYE8)
    assert _noise._expected(_noise._EYE8, _noise._EYE8, Xb, G, XSX) == pytest.approx(8 * M - 7, rel=1e-12)


def test_the_components_are_measured_without_bias():
    """Residuals of corners with known corner noise ``a``, marker shift ``b`` and marker size ``c``: the mean of the
    estimates over many draws is within a few of its standard errors of the truth."""
    q, J, grow = _scene()
    M = len(q)
    a, b, c = 0.09, 0.04, 0.006**2  # px^2, px^2, relative^2
    cov = _dense(a * np.eye(8) + b * _noise._SHIFT8 + c * np.einsum("mi,mj->mij", grow, grow))
    L = np.linalg.cholesky(cov)
    X = np.column_stack([J, grow.reshape(-1)])
    IH = np.eye(8 * M) - X @ np.linalg.solve(X.T @ X, X.T)
    rng = np.random.default_rng(11)
    est = np.array([_noise._measure(IH @ (L @ rng.standard_normal(8 * M)), J, q, None)[0] for _ in range(400)])
    mean, se = est.mean(axis=0), est.std(axis=0) / np.sqrt(len(est))
    # non-negative least squares truncates at 0: a small bias upward where an estimate is often 0 (none here)
    assert np.all(np.abs(mean - [a, b, c]) < 4 * se + 0.03 * np.array([a, b, c])), (mean, se)
    assert np.all(se < 0.2 * np.array([a, b, c])), se  # and the draws do measure them


def test_one_scale_of_the_prior_mix_with_few_markers_by_hand():
    """Fewer than four markers, noise estimated: the prior mix scaled by ``(PRIOR_DOF + s dof) / (PRIOR_DOF + dof)``,
    ``s`` the sum of squares over its expectation under the mix, ``dof = 8M - 6``."""
    m = wall_map(n_cols=2, n_rows=1, size=150.0, spacing=400.0)
    T = look_at([1500.0, 300.0, 1300.0], [0.0, 300.0, 1400.0])
    P = np.concatenate(list(m.corners().values()))
    q = CAM.project(P, T).reshape(-1, 4, 2)
    J = pose_jacobian(P, T, CAM)
    r = np.random.default_rng(3).normal(0.0, 0.4, len(P) * 2)
    M = len(q)
    grow = (q - q.mean(axis=1, keepdims=True)).reshape(M, 8)
    prior = np.array([_noise.PRIOR_SIGMA_PX**2, _noise.PRIOR_SHIFT_PX**2, _noise.PRIOR_SIZE_REL**2])
    H = J @ np.linalg.solve(J.T @ J, J.T)
    IH = np.eye(8 * M) - H
    blocks = [np.eye(8), _noise._SHIFT8, None]
    expected = 0.0
    for p, C in zip(prior, blocks):
        C_dense = _dense(np.einsum("mi,mj->mij", grow, grow)) if C is None else _dense(np.broadcast_to(C, (M, 8, 8)))
        expected += p * float(np.trace(IH @ C_dense))
    dof = 8 * M - 6
    scale = (_noise.PRIOR_DOF + float(r @ r) / expected * dof) / (_noise.PRIOR_DOF + dof)
    parts = _noise._noise_parts(r, J, q, None)
    np.testing.assert_allclose([parts.a, parts.b, parts.c], scale * prior, rtol=1e-9)
    assert parts.nu == dof + _noise.PRIOR_DOF


@pytest.mark.parametrize(
    ("scene", "sigma", "seed"),
    [("two walls", 0.3, 21), ("one wall of 12", 1.0, 22)],
)
def test_the_95_percent_ellipsoid_holds_the_truth_90_to_98_percent(scene, sigma, seed):
    """Gaussian corner noise, the noise estimated from the residuals (the default): 200 draws of a fixed seed;
    the band 90-98 % is about three binomial standard deviations (1.5 %) either side of 95 %."""
    if scene == "two walls":
        m, T = two_wall_map(), look_at([2300.0, 2100.0, 1300.0], [300.0, 300.0, 1100.0])
    else:
        m = wall_map(n_cols=4, n_rows=3, size=120.0, spacing=300.0)
        T = look_at([1700.0, 500.0, 1100.0], [0.0, 450.0, 1150.0])
    rng = np.random.default_rng(seed)
    n = 200
    inside = sum(
        estimate_pose(observe(m, T, sigma, rng), m, CAM, reject_outliers=False).position_ellipsoid_contains(T[:3, 3])
        for _ in range(n)
    )
    assert 0.90 <= inside / n <= 0.98, inside / n
