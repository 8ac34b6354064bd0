"""Lesson 10 (tracking): the named wrong answers of every question, for several learners."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.stats import chi2

from fidlearn import exercises, frames
from fidlearn.exercises import CORRECT, INCORRECT
from fidlearn.exercises.lessons import l10_tracking

LEARNERS = ["", "carol", "dave", "learner007"]


def key_of(name: str, learner: str):
    q = exercises.lesson("10", learner=learner)[name]
    ns: dict = {}
    exec(exercises.SETUP_CODE, ns)
    ns[name] = q
    exec(q.solution_code, ns)
    return q, q.answer


def _exp(w):
    return cv2.Rodrigues(np.asarray(w, dtype=float).reshape(3, 1))[0]


def _log(R):
    return cv2.Rodrigues(R)[0].ravel()


@pytest.mark.parametrize("learner", LEARNERS)
def test_q1_averaging_rotation_vectors_or_euler_angles_is_named(learner):
    q, key = key_of("q1", learner)
    Rs = np.asarray(q.inputs.rotations)
    rvec_mean = _exp(np.mean([_log(R) for R in Rs], axis=0))
    euler_mean = frames.rotation_from_rpy_deg(*np.mean([frames.rpy_deg_from_rotation(R) for R in Rs], axis=0))
    assert frames.rotation_angle_deg(rvec_mean, key) > 90
    assert frames.rotation_angle_deg(euler_mean, key) > 90
    r = q.grade(rvec_mean)
    assert r.status == INCORRECT
    assert "rotation vectors" in r.message
    r = q.grade(euler_mean)
    assert r.status == INCORRECT
    assert "Euler angles" in r.message
    r = q.grade(Rs.mean(axis=0))
    assert r.status == INCORRECT
    assert "element-wise mean" in r.message
    # the chordal mean (the element-wise mean projected back onto the rotations) is as good here
    U, _, Vt = np.linalg.svd(Rs.mean(axis=0))
    assert q.grade(U @ Vt).status == CORRECT
    assert q.grade(Rs[0]).status == INCORRECT  # one of the three is not their mean


@pytest.mark.parametrize("learner", LEARNERS)
def test_q2_too_little_and_too_much_process_noise_are_named(learner):
    q, best = key_of("q2", learner)
    candidates = q.inputs.candidates
    i = candidates.index(best)
    assert 0 < i < len(candidates) - 1
    r = q.grade(candidates[i - 1])
    assert r.status == INCORRECT
    assert "lags" in r.message
    r = q.grade(candidates[i + 1])
    assert r.status == INCORRECT
    assert "smaller q" in r.message
    assert q.grade(123.0).status == INCORRECT


def test_q2_key_is_the_first_candidate_meeting_the_lag_goal_by_a_margin():
    for learner in LEARNERS:
        q = l10_tracking._q2(learner)
        d = q.inputs
        lags = []
        for c in d.candidates:
            e = l10_tracking._kalman_1d(d.measured_mm, d.times_s, c, d.sigma_mm) - d.true_mm
            lags.append(-(e @ d.true_velocity_mm_s) / (d.true_velocity_mm_s @ d.true_velocity_mm_s) * 30)
        i = next(k for k, lag in enumerate(lags) if lag <= 1.0)
        assert lags[i] <= 0.9
        assert lags[i - 1] >= 1.15
        assert q.grade(d.candidates[i]).status == CORRECT


@pytest.mark.parametrize("learner", LEARNERS)
def test_q3_the_inverse_mount_and_the_camera_pose_are_named(learner):
    q, key = key_of("q3", learner)
    Twc, Tcb = q.inputs.T_world_camera, q.inputs.T_camera_base
    r = q.grade(Twc @ frames.invert_transform(Tcb))
    assert r.status == INCORRECT
    assert "inverse mount" in r.message
    r = q.grade(Tcb @ Twc)
    assert r.status == INCORRECT
    assert "order" in r.message
    r = q.grade(Twc)
    assert r.status == INCORRECT
    assert "camera's pose" in r.message
    assert abs(key[2, 3]) < 1e-6  # the base stands on the floor, upright
    assert abs(key[2, 2] - 1) < 1e-9


@pytest.mark.parametrize("learner", LEARNERS)
def test_q4_the_wrong_order_of_composition_is_named(learner):
    q, key = key_of("q4", learner)
    start, steps = q.inputs.T_world_base_start, q.inputs.odometry
    backwards, on_the_left = start.copy(), start.copy()
    for s in steps[::-1]:
        backwards = backwards @ s
    for s in steps:
        on_the_left = s @ on_the_left
    r = q.grade(backwards)
    assert r.status == INCORRECT
    assert "wrong order" in r.message
    r = q.grade(on_the_left)
    assert r.status == INCORRECT
    assert "on the left" in r.message
    added = start.copy()
    added[:3, 3] += steps[:, :3, 3].sum(axis=0)
    r = q.grade(added)
    assert r.status == INCORRECT
    assert "translations" in r.message
    # the right answer by hand: the robot turned by the sum of its turns, about z
    yaw = np.degrees(np.arctan2(key[1, 0], key[0, 0]) - np.arctan2(start[1, 0], start[0, 0]))
    turns = np.degrees([np.arctan2(s[1, 0], s[0, 0]) for s in steps]).sum()
    assert abs((yaw - turns + 180) % 360 - 180) < 1e-6


def _nis_and_bands(q):
    r, S = np.asarray(q.inputs.innovations), np.asarray(q.inputs.S)
    k = len(r)
    mean = float(np.mean([ri @ np.linalg.solve(Si, ri) for ri, Si in zip(r, S)]))
    return mean, k, chi2.ppf([0.025, 0.975], 6 * k) / k


@pytest.mark.parametrize("learner", LEARNERS)
def test_q5_the_identity_the_sum_and_wrong_bands_are_named(learner):
    q, key = key_of("q5", learner)
    mean, k, (lo, hi) = _nis_and_bands(q)
    assert key["mean_nis"] == pytest.approx(mean, rel=1e-9)
    assert key["consistent"] == (lo <= mean <= hi)
    r = np.asarray(q.inputs.innovations)
    res = q.grade({"mean_nis": float(np.mean(np.sum(r**2, axis=1))), "consistent": key["consistent"]})
    assert res.status == INCORRECT
    assert "identity" in res.message
    res = q.grade({"mean_nis": k * mean, "consistent": key["consistent"]})
    assert res.status == INCORRECT
    assert "sum" in res.message
    flipped = {"mean_nis": mean, "consistent": not key["consistent"]}
    res = q.grade(flipped)
    assert res.status == INCORRECT
    one_lo, one_hi = chi2.ppf([0.025, 0.975], 6)
    three_lo, three_hi = chi2.ppf([0.025, 0.975], 3 * k) / k
    if (one_lo <= mean <= one_hi) == flipped["consistent"]:
        assert "ONE chi-square(6)" in res.message
    elif (three_lo <= mean <= three_hi) == flipped["consistent"]:
        assert "3 degrees of freedom" in res.message
    else:
        assert "the verdict is not" in res.message
    assert q.grade({"mean_nis": mean * 1.01, "consistent": key["consistent"]}).status == INCORRECT
    assert q.grade((mean, key["consistent"])).status == CORRECT


def test_q5_the_wrong_bands_are_named_for_the_learners_they_fool():
    seen = set()
    for learner in ("0", "1", "2", "3", "4", "5", "6", "7", "8", "9", "10", "11"):
        q = l10_tracking._q5(learner)
        mean, k, (lo, hi) = _nis_and_bands(q)
        message = q.grade({"mean_nis": mean, "consistent": not (lo <= mean <= hi)}).message
        seen |= {name for name in ("ONE chi-square(6)", "3 degrees of freedom") if name in message}
    assert seen == {"ONE chi-square(6)", "3 degrees of freedom"}


def test_q5_every_variant_of_100_learners_is_solvable_clear_of_the_band_and_of_every_kind():
    kinds = set()
    for i in range(100):
        q, key = key_of("q5", str(i))
        assert q.grade(key).status == CORRECT
        mean, k, (lo, hi) = _nis_and_bands(q)
        assert 40 <= k <= 80
        margin = 0.25 * (hi - lo)
        assert not lo - margin < mean < lo + margin  # never near an edge
        assert not hi - margin < mean < hi + margin
        kinds.add("consistent" if lo <= mean <= hi else "overconfident" if mean > hi else "cautious")
    assert kinds == {"consistent", "overconfident", "cautious"}


@pytest.mark.parametrize("learner", LEARNERS)
def test_q6_camera_axes_sign_subtraction_and_degrees_are_named(learner):
    q, key = key_of("q6", learner)
    R_pred, R_meas = np.asarray(q.inputs.R_pred), np.asarray(q.inputs.R_meas)
    # the key turns the prediction into the measurement, on the left, in radians
    assert np.abs(_exp(key) @ R_pred - R_meas).max() < 1e-6
    assert 2 <= np.degrees(np.linalg.norm(key)) <= 8
    assert q.grade(key + 5e-5).status == CORRECT
    for answer, words in (
        (_log(R_pred.T @ R_meas), "camera's own axes"),
        (-key, "sign"),
        (_log(R_meas) - _log(R_pred), "subtracts the two rotation vectors"),
        (np.degrees(key), "degrees"),
    ):
        r = q.grade(answer)
        assert r.status == INCORRECT, (learner, words)
        assert words in r.message
    assert q.grade(key + 1e-3).status == INCORRECT
    assert q.grade(np.zeros(3)).status == INCORRECT


def test_q6_no_variant_of_the_first_thousand_learners_lets_a_named_mistake_pass():
    seen_near_180 = 0
    for i in range(1000):
        q = l10_tracking._q6(str(i))
        R_pred, R_meas = np.asarray(q.inputs.R_pred), np.asarray(q.inputs.R_meas)
        key = _log(R_meas @ R_pred.T)
        assert q.grade(key).status == CORRECT
        assert 2 <= np.degrees(np.linalg.norm(key)) <= 8
        for mistake in (_log(R_pred.T @ R_meas), -key, _log(R_meas) - _log(R_pred), np.degrees(key)):
            assert q.grade(mistake).status == INCORRECT, i
            assert np.abs(mistake - key).max() > 5e-3
        seen_near_180 += frames.rotation_angle_deg(R_pred, np.eye(3)) > 150
    assert seen_near_180 > 100  # many predictions are turned far round, where rotation vectors wrap
