"""The outlier screen fires at its stated rate on pure noise; the rejection names a moved marker; the quantiles.

Every trial is seeded: the counts are the same on every run (no flaky statistics), and the
tolerances are 4-5 binomial standard deviations around the stated rate, so a screen off by a
factor of two would fail.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import fidlearn
from fidlearn import pose as pose_mod
from fidlearn.detection import Detection
from fidlearn.markermap import MarkerMap, MarkerPlacement
from fidlearn.pose._stats import _beta_isf_int, _beta_sf_int, _chi2_isf_even, _chi2_sf_even
from fidlearn.synthetic import look_at

CAM = fidlearn.Camera([[600.0, 0, 320.0], [0, 600.0, 240.0], [0, 0, 1]], [-0.1, 0.05, 0, 0, 0], (640, 480))
WALL_YZ = [(0, 1500), (450, 1500), (900, 1500), (150, 1050), (600, 1050), (1050, 1100), (300, 600), (800, 650)]


def wall(n: int) -> MarkerMap:
    p = {k: MarkerPlacement(k, (0.0, float(y), float(z)), (0.0, 0.0, 0.0)) for k, (y, z) in enumerate(WALL_YZ[:n])}
    return MarkerMap(p, 150.0, "ARUCO_ORIGINAL", "mm")


def views(m: MarkerMap, count: int, rng) -> list[np.ndarray]:
    """Camera poses 1-2.5 m from the wall, up to 40 degrees off its normal, seeing every marker."""
    centre = np.mean([m.T_world_marker(i)[:3, 3] for i in m.ids], axis=0)
    out = []
    while len(out) < count:
        a, phi = math.radians(rng.uniform(0, 40)), rng.uniform(0, 2 * math.pi)
        v = np.array([math.cos(a), math.sin(a) * math.cos(phi), math.sin(a) * math.sin(phi)])
        T = look_at(centre + rng.uniform(1000, 2500) * v, centre, roll_deg=rng.uniform(-20, 20))
        px = np.concatenate([CAM.project(c, T) for c in m.corners().values()])
        if np.all(px > 5) and np.all(px < np.array(CAM.image_size) - 6):
            out.append(T)
    return out


def noisy(m: MarkerMap, T: np.ndarray, sigma: float, rng, moved: dict | None = None) -> list[Detection]:
    moved = moved or {}
    return [
        Detection(i, CAM.project(c + moved.get(i, 0.0), T) + rng.normal(0, sigma, (4, 2)))
        for i, c in m.corners().items()
    ]


def screen_fires(m: MarkerMap, dets, sigma_given) -> bool:
    world, faces = pose_mod._world(m)
    corners = {d.id: d.corners_px for d in dets}
    obs = pose_mod._make_obs(sorted(corners), corners, world, faces)
    cands, _, _ = pose_mod._solve(obs, m, CAM, "auto", True)
    return pose_mod._screen(obs, cands[0], CAM, sigma_given) is not None


@pytest.mark.parametrize(("n", "sigma", "given", "seed"), [(3, 1.0, False, 1), (4, 0.5, True, 2), (8, 0.3, False, 3)])
def test_the_screen_fires_on_pure_noise_at_its_stated_rate(n, sigma, given, seed):
    rng = np.random.default_rng(seed)
    m = wall(n)
    trials = 1500
    poses = views(m, 30, rng)
    fired = sum(screen_fires(m, noisy(m, poses[k % 30], sigma, rng), sigma if given else None) for k in range(trials))
    expected = pose_mod.SCREEN_P * trials  # 15: binomial standard deviation 3.9
    assert 0.25 * expected <= fired <= expected + 5 * math.sqrt(expected), fired


def test_pure_noise_rejects_nothing_and_a_marker_moved_30_mm_is_named():
    rng = np.random.default_rng(4)
    m = wall(6)
    poses = views(m, 40, rng)
    assert not any(fidlearn.estimate_pose(noisy(m, T, 0.5, rng), m, CAM).rejected_ids for T in poses)
    for k, T in enumerate(poses):
        bad = k % 6
        phi = rng.uniform(0, 2 * math.pi)
        off = {bad: 30.0 * np.array([0.0, math.cos(phi), math.sin(phi)])}
        pose = fidlearn.estimate_pose(noisy(m, T, 0.5, rng, off), m, CAM)
        assert pose.rejected_ids == (bad,), (k, pose.rejected_ids)


def test_the_screen_names_the_marker_whose_removal_explains_the_rest():
    # Q_k, computed from the one fit of all markers, is the drop of the sum of squares when marker k is left
    # out: compare with refitting without it (nearly linear here: a 40 mm move, six markers, no noise).
    m = wall(6)
    T = views(m, 1, np.random.default_rng(5))[0]
    dets = noisy(m, T, 0.0, np.random.default_rng(6), {2: np.array([0.0, 40.0, 0.0])})
    world, faces = pose_mod._world(m)
    corners = {d.id: d.corners_px for d in dets}
    obs = pose_mod._make_obs(sorted(corners), corners, world, faces)
    best = pose_mod._solve(obs, m, CAM, "auto", True)[0][0]
    q = pose_mod._deletion_q(obs, best, CAM)
    assert int(np.argmax(q)) == 2 and pose_mod._screen(obs, best, CAM, None) == 2
    rest = [d for d in dets if d.id != 2]
    sse_rest = fidlearn.estimate_pose(rest, m, CAM, reject_outliers=False).reprojection_rms_px ** 2 * 20
    assert best.sse - q[2] == pytest.approx(sse_rest, abs=0.02 * best.sse)


def test_the_quantiles_are_exact():
    for p in (0.5, 0.01, 1e-4):  # chi-square(2) has sf exp(-x/2); Beta(1, b) has sf (1 - x)^b
        assert _chi2_isf_even(p, 2) == pytest.approx(-2 * math.log(p), rel=1e-9)
        assert _beta_isf_int(p, 1, 7) == pytest.approx(1 - p ** (1 / 7), rel=1e-9)
    assert _chi2_sf_even(_chi2_isf_even(0.01, 58), 58) == pytest.approx(0.01, rel=1e-9)
    assert _beta_sf_int(_beta_isf_int(0.01 / 3, 4, 5), 4, 5) == pytest.approx(0.01 / 3, rel=1e-9)
    # 8 F(8, 10) at 1 - 1e-4 (the table of the left-out test) from Beta(4, 5): F = (x / 4) / ((1 - x) / 5)
    x = _beta_isf_int(1e-4, 4, 5)
    assert 8 * (x / 4) / ((1 - x) / 5) == pytest.approx(125.9, rel=2e-3)
