"""Lesson 12 (your own camera): every variant solvable by the taught method and every listed wrong method named,
for learner ids 0-99 here and 0-999 in the slow run."""

from __future__ import annotations

import helpers
import numpy as np
import pytest

from fidlearn.exercises import CORRECT


def solved(name: str, learner: str):
    return helpers.solved("12", name, learner)


named = helpers.named


def check_learner(learner: str) -> None:
    q, key = solved("q1", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    named(q, d.located_distance_mm * d.map_size_mm / d.printed_mm, "upside down")
    named(q, d.located_distance_mm, "scales with the marker's size")
    named(q, d.located_distance_mm + d.printed_mm - d.map_size_mm, "a ratio, not a difference")

    q, key = solved("q2", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    cols, rows = d.cells
    transposed = np.zeros((cols, rows), bool)
    for c in d.corners_px:
        col = np.clip((c[:, 0] / d.width * rows).astype(int), 0, rows - 1)
        row = np.clip((c[:, 1] / d.height * cols).astype(int), 0, cols - 1)
        transposed[row, col] = True
    named(q, transposed.mean(), "transposed")
    named(q, 100 * key, "percentage")

    q, key = solved("q3", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    ignoring_flags = key["fraction"] >= d.good_fraction
    if d.flags:
        assert ignoring_flags  # a warning comes with a small uncertainty: the warning alone decides
        named(q, {"fraction": key["fraction"], "good": True}, "warning")
    else:
        named(q, {"fraction": key["fraction"], "good": not key["good"]}, "compare it with good_fraction")
    assert abs(key["fraction"] - d.good_fraction) > 0.02  # never a coin toss at the threshold

    q, key = solved("q4", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    T_last = np.asarray(d.T_world_camera_last)
    p = np.linalg.inv(T_last) @ np.append(d.point_mm, 1.0)
    uvw = np.asarray(d.K) @ p[:3]
    named(q, uvw[:2] / uvw[2], "LAST frame")


@pytest.mark.parametrize("start", range(0, 100, 25))
def test_every_variant_is_solvable_and_its_wrong_methods_named(start):
    for learner in range(start, start + 25):
        check_learner(str(learner))


@pytest.mark.slow
@pytest.mark.parametrize("start", range(100, 1000, 100))
def test_every_variant_of_the_first_thousand_learners(start):
    for learner in range(start, start + 100):
        check_learner(str(learner))
