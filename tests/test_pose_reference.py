"""estimate_pose gives the answers stored in tests/data/pose_reference.json (tools/make_pose_reference.py).

The reference holds the bundled scenes' corners (true corners of data/scenes/poses.json with seeded
noise; one marker moved 40 mm in some) and the poses, flags, alternatives and covariances that
estimate_pose computed when it was written (its ``provenance`` names the commit). Faster code must
give the same numbers: positions to 1e-6 mm, rotations to 1e-9, covariances to 1e-6 relative.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fidlearn import Camera, MarkerMap, estimate_pose
from fidlearn.data import data_path
from fidlearn.detection import Detection

REFERENCE = Path(__file__).parent / "data" / "pose_reference.json"
CASES = json.loads(REFERENCE.read_text())["cases"]
CAMERA = Camera.load(data_path("scenes", "camera.json"))
MAPS = {name: MarkerMap.load(data_path(name)) for name in {c["map"] for c in CASES}}

POSITION_TOL_MM = 1e-6
ROTATION_TOL = 1e-9
COV_REL_TOL = 1e-6


def _same_pose(T, T_ref, what):
    T, T_ref = np.asarray(T), np.asarray(T_ref)
    dp = float(np.abs(T[:3, 3] - T_ref[:3, 3]).max())
    dr = float(np.abs(T[:3, :3] - T_ref[:3, :3]).max())
    assert dp <= POSITION_TOL_MM and dr <= ROTATION_TOL, f"{what}: position off by {dp:.2e} mm, rotation by {dr:.2e}"


def _same_cov(cov, cov_ref, what):
    if cov_ref is None:
        assert cov is None, what
        return
    cov, cov_ref = np.asarray(cov), np.asarray(cov_ref)
    scale = np.sqrt(np.outer(np.diag(cov_ref), np.diag(cov_ref)))  # relative to the standard deviations
    err = float(np.abs((cov - cov_ref) / scale).max())
    assert err <= COV_REL_TOL, f"{what}: covariance off by {err:.2e} (relative)"


def test_the_reference_covers_flips_rejections_and_both_noise_options():
    kinds = {(c["expected"]["ambiguous"], bool(c["expected"]["rejected_ids"])) for c in CASES}
    assert {(True, False), (False, False), (True, True), (False, True)} <= kinds
    assert {c["corner_sigma_px"] for c in CASES} == {None, 0.5}
    assert any(len(c["corners_px"]) == 1 for c in CASES) and any(len(c["corners_px"]) >= 5 for c in CASES)


@pytest.mark.parametrize("case", CASES, ids=[f"{c['scene'][:-4]}-{c['variant']}-{c['corner_sigma_px']}" for c in CASES])
def test_estimate_pose_gives_the_reference_answer(case):
    dets = [Detection(int(i), np.asarray(c)) for i, c in case["corners_px"].items()]
    pose = estimate_pose(dets, MAPS[case["map"]], CAMERA, corner_sigma_px=case["corner_sigma_px"])
    ref = case["expected"]
    assert list(pose.marker_ids) == ref["marker_ids"] and list(pose.rejected_ids) == ref["rejected_ids"]
    assert pose.ambiguous == ref["ambiguous"] and pose.method == ref["method"]
    _same_pose(pose.T_world_camera, ref["T_world_camera"], "pose")
    assert pose.sigma_px == pytest.approx(ref["sigma_px"], rel=1e-6)
    assert pose.reprojection_rms_px == pytest.approx(ref["reprojection_rms_px"], rel=1e-6, abs=1e-9)
    _same_cov(pose.covariance, ref["covariance"], "covariance")
    alt, alt_ref = pose.alternative, ref["alternative"]
    assert (alt is None) == (alt_ref is None)
    if alt is not None:
        _same_pose(alt.T_world_camera, alt_ref["T_world_camera"], "alternative")
        _same_cov(alt.covariance, alt_ref["covariance"], "alternative's covariance")
        assert alt.method == alt_ref["method"]
