"""Lesson 14 (ChArUco boards): every variant solvable by the taught method and every listed wrong method named, for
learner ids 0-49 here and 0-999 in the slow run."""

from __future__ import annotations

import cv2
import helpers
import numpy as np
import pytest

from fidlearn.exercises import CORRECT, INCORRECT


def solved(name: str, learner: str):
    return helpers.solved("14", name, learner)


named = helpers.named


def check_learner(learner: str) -> None:
    q, key = solved("q1", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    H = cv2.getPerspectiveTransform(d.marker_mm.astype(np.float32), d.marker_px.astype(np.float32))
    named(q, (H @ np.append(d.corner_mm, 1.0))[:2], "divided")
    A = cv2.getAffineTransform(d.marker_mm[:3].astype(np.float32), d.marker_px[:3].astype(np.float32))
    named(q, A @ np.append(d.corner_mm, 1.0), "affine")
    assert q.grade(d.marker_px.mean(axis=0)).status == INCORRECT  # the marker's centre is not the corner

    q, key = solved("q2", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    wrong = [i for i in range(len(d.candidates)) if i != key]
    assert len(wrong) == 5
    assert all(q.grade(i).status == INCORRECT for i in wrong)
    assert sum("the other one missed" in q.grade(i).message for i in wrong) == 1

    q, key = solved("q3", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    counts = np.asarray(d.corners_per_view)
    used = counts[counts >= d.min_corners]
    named(q, 2 * counts.sum() - (4 + d.n_dist + 6 * len(counts)), "left out")
    named(q, used.sum() - (4 + d.n_dist + 6 * len(used)), "two residuals")
    named(q, 2 * used.sum() - (4 + d.n_dist), "own pose")


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
