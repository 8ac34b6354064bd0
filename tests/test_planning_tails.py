"""The tail of the predicted pose error: the sampled solutions against the solver, the 90th percentile, the RMS."""

import math

import cv2
import numpy as np
import pytest

from fidlearn import Camera, Detection, MarkerMap, estimate_pose, frames, look_at, predict_accuracy
from fidlearn.planning import noise, sampling
from fidlearn.planning.sampling import _error_stats

CAM = Camera(np.array([[800.0, 0, 639.5], [0, 800.0, 359.5], [0, 0, 1]]), np.zeros(5), (1280, 720))


def one_marker(size_mm: float) -> MarkerMap:
    return MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": size_mm,
            "markers": {"0": {"translation": [0, -size_mm / 2, 1000 + size_mm / 2], "rotation": [0, 0, 0]}},
        }
    )


def test_each_sampled_solution_is_the_least_squares_pose_of_its_noisy_corners():
    camera = Camera(np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]), [-0.2, 0.05, 0.001, 0, 0], (640, 480))
    world = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 80,
            "markers": {
                "0": {"translation": [0, -40, 1040], "rotation": [0, 0, 0]},
                "1": {"translation": [0, 200, 900], "rotation": [0, 0, 0]},
            },
        }
    )
    T = look_at([1500, 300, 1100], [0, 0, 1000])
    P = np.concatenate([world.marker_corners(i) for i in world.ids])
    px = camera.project(P, T)
    blocks = [noise.corner_covariance(px[4 * k : 4 * k + 4], 0.3) for k in range(2)]
    errors = sampling.sampled_position_errors(P, T, camera, blocks, draws=20)
    draws = sampling._noise_draws(blocks, 20)
    rvec, tvec = (
        np.asarray(v, float).reshape(3, 1) for v in frames.rvec_tvec_from_transform(frames.invert_transform(T))
    )
    for k in range(3):  # OpenCV's Levenberg-Marquardt on the same noisy corners, from the truth
        r, t = cv2.solvePnPRefineLM(
            P, px + draws[k].reshape(-1, 2), camera.K, camera.dist, rvec.copy(), tvec.copy(), criteria=(3, 100, 1e-12)
        )
        C = -cv2.Rodrigues(r)[0].T @ t.ravel()
        assert np.linalg.norm(errors[k] - (C - T[:3, 3])) < 0.01 * np.linalg.norm(errors[k]) + 0.05


@pytest.mark.parametrize("distance", [1500.0, 4500.0])
def test_a_small_marker_seen_face_on_gets_the_tail_of_estimate_pose(distance):
    # Face-on, a marker's tilt moves its corners only to second order: the linearized tilt is known to
    # 8 deg at 1.5 m and 70 deg at 4.5 m, and a Gaussian of that size overstates the error 1.2 to 5 times.
    world, sigma = one_marker(160), 0.5
    T = look_at([distance, 0, 1000], [0, 0, 1000])
    p = predict_accuracy(world, CAM, T, corner_sigma_px=sigma)
    px = CAM.project(world.marker_corners(0), T)
    L = np.linalg.cholesky(noise.corner_covariance(px, sigma))
    rng = np.random.default_rng(3)
    errs = np.array(
        [
            np.linalg.norm(
                estimate_pose([Detection(0, px + (L @ rng.normal(size=8)).reshape(4, 2))], world, CAM).position_mm
                - T[:3, 3]
            )
            for _ in range(150)
        ]
    )
    assert p.position_error_mm == pytest.approx(np.median(errs), rel=0.15)
    assert p.position_p90_mm == pytest.approx(np.quantile(errs, 0.9), rel=0.15)
    assert p.position_rms_mm == pytest.approx(np.sqrt(np.mean(errs**2)), rel=0.15)
    assert p.position_error_mm < p.position_p90_mm


def test_the_90th_percentile_of_an_error_along_one_axis_is_1_645_sigma():
    z = np.random.default_rng(0).standard_normal(20000)
    errors = np.column_stack([3.0 * z, np.zeros_like(z), np.zeros_like(z)])
    median, p90, rms = _error_stats([(1.0, errors, 0.0, np.full(3, np.nan))])
    assert median == pytest.approx(3.0 * 0.6745, rel=0.03)
    assert p90 == pytest.approx(3.0 * 1.6449, rel=0.03)
    assert rms == pytest.approx(3.0, rel=0.03)


def test_a_likely_flip_puts_the_other_solution_in_the_tail():
    z = np.random.default_rng(0).standard_normal((20000, 3))
    median, p90, rms = _error_stats([(1.0, z, 0.2, np.array([1000.0, 0.0, 0.0]))])  # one pose in five 1 m off
    assert median < 3.0
    assert p90 == pytest.approx(1000.0, rel=0.01)
    assert rms == pytest.approx(math.sqrt(0.2) * 1000.0, rel=0.01)


def test_no_pose_no_percentile():
    p = predict_accuracy(one_marker(160), CAM, look_at([1000, 0, 1000], [2000, 0, 1000]))  # looking away
    assert not p.possible
    assert p.position_p90_mm == math.inf
    assert p.position_rms_mm == math.inf


def test_many_markers_keep_the_linearized_gaussian():
    world = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 150,
            "markers": {str(i): {"translation": [0, -600 + 300 * i, 800], "rotation": [0, 0, 0]} for i in range(5)},
        }
    )
    p = predict_accuracy(world, CAM, look_at([1500, 200, 900], [0, 0, 850]), corner_sigma_px=0.1)
    s = p.position_std_mm
    assert p.position_rms_mm == pytest.approx(math.sqrt(float(s @ s)), rel=0.05)


def test_the_plan_command_prints_the_90th_percentile(tmp_path):
    import subprocess
    import sys

    import fidlearn

    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "fidlearn",
            "plan",
            str(fidlearn.data_path("world_map.json")),
            "--camera",
            str(fidlearn.data_path("scenes/camera.json")),
            "--step-mm",
            "1000",
            "--headings",
            "0",
            "-o",
            str(tmp_path / "plan.png"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    line = next(x for x in out.stdout.splitlines() if "predicted error looking at the markers" in x)
    median, p90 = (float(line.split(what)[1].split()[0]) for what in ("markers: median", "within it): median"))
    assert p90 > median > 0
