"""Lesson 15 (wide lenses): every variant solvable by the taught method, its key checked against OpenCV, and every
listed wrong method named, for learner ids 0-49 here and 0-999 in the slow run."""

from __future__ import annotations

import cv2
import helpers
import numpy as np
import pytest

from fidlearn.exercises import CORRECT


def solved(name: str, learner: str):
    return helpers.solved("15", name, learner)


named = helpers.named


def check_learner(learner: str) -> None:
    q, key = solved("q1", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    K, D, point = np.asarray(d.K), np.asarray(d.dist), np.asarray(d.point, float)
    opencv = cv2.fisheye.projectPoints(point.reshape(1, 1, 3), np.zeros(3), np.zeros(3), K, D)[0].ravel()
    np.testing.assert_allclose(key, opencv, atol=1e-6)  # the same model as OpenCV's
    assert np.all((opencv > 0) & (opencv < np.array(d.image_size) - 1))
    named(q, K[:2, :2] @ (point[:2] / point[2]) + K[:2, 2], "pinhole")
    equidistant = cv2.fisheye.projectPoints(point.reshape(1, 1, 3), np.zeros(3), np.zeros(3), K, np.zeros(4))[0]
    named(q, equidistant.ravel(), "equidistant")
    named(q, np.asarray(key) - K[:2, 2], "principal point")

    q, key = solved("q2", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    K = np.array([[key, 0, (d.width - 1) / 2], [0, key, 100.0], [0, 0, 1]])
    edge = np.array([[d.width - 1.0, 100.0]])  # the edge's ray is at half the field of view
    ray = cv2.undistortPoints(edge.reshape(1, 1, 2), K, None).ravel()
    assert np.degrees(np.arctan(ray[0])) == pytest.approx(d.fov_deg / 2, abs=1e-9)
    named(q, (d.width - 1) / 2 / np.radians(d.fov_deg / 2), "r = f theta")
    named(q, (d.width - 1) / 2 / np.tan(d.fov_deg / 2), "radians")
    named(q, (d.width - 1) / np.tan(np.radians(d.fov_deg / 2)), "half the width")

    q, key = solved("q3", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    diff, sigma = np.asarray(d.difference_px), np.asarray(d.sigma_px)
    # compare_calibrations' own formula, with each pixel's covariance sigma^2 I
    C = sigma[:, None, None] ** 2 * np.eye(2)
    m2 = np.einsum("ni,nij,nj->n", diff, np.linalg.inv(C), diff)
    assert key == pytest.approx(np.sqrt(np.mean(m2) / 2), rel=1e-9)
    named(q, np.sqrt(np.mean(m2)), "two axes")
    named(q, np.sqrt(np.mean(np.sum(diff**2, axis=1)) / 2) / np.sqrt(np.mean(sigma**2)), "own sigma")
    named(q, np.mean(np.sqrt(m2 / 2)), "averages the lengths")


def test_every_variant_of_50_learners():
    for learner in range(50):
        check_learner(str(learner))


def test_the_shared_variant():
    check_learner("")


@pytest.mark.slow
@pytest.mark.parametrize("start", range(50, 1000, 190))
def test_every_variant_of_the_first_thousand_learners(start):
    for learner in range(start, min(start + 190, 1000)):
        check_learner(str(learner))
