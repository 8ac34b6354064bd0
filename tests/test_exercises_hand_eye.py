"""Lesson 13 (hand-eye): every variant solvable by the taught method and every listed wrong method named, for
learner ids 0-49 here and 0-999 in the slow run."""

from __future__ import annotations

import helpers
import numpy as np
import pytest

from fidlearn.exercises import CORRECT


def solved(name: str, learner: str):
    return helpers.solved("13", name, learner)


named = helpers.named


def check_learner(learner: str) -> None:
    q, key = solved("q1", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    named(q, d.T_base_camera @ d.T_base_tool @ d.T_tool_board, "inverse")
    named(q, np.linalg.inv(key), "T_board_camera")

    q, key = solved("q2", learner)
    assert q.grade(key).status == CORRECT
    named(q, key.T, "other way round")
    named(q, sum(np.outer(a, b) for a, b in zip(q.inputs.alpha, q.inputs.beta)), "not a rotation")

    q, key = solved("q3", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    lhs = np.concatenate([np.asarray(R) - np.eye(3) for R in d.R_A])
    rhs = np.concatenate([np.asarray(d.R_X) @ b - a for a, b in zip(d.t_A, d.t_B)])
    named(q, np.linalg.lstsq(lhs, -rhs, rcond=None)[0], "sign")

    q, key = solved("q4", learner)
    d = q.inputs
    assert q.grade(key).status == CORRECT
    predicted = np.linalg.inv(d.T_base_camera) @ d.T_base_tool @ d.T_tool_board
    named(q, np.linalg.norm(d.T_camera_board_measured[:3, 3] - predicted[:3, 3]), "translations")


def test_every_variant_of_50_learners():
    for learner in range(50):
        check_learner(str(learner))


@pytest.mark.slow
@pytest.mark.parametrize("start", range(50, 1000, 190))
def test_every_variant_of_the_first_thousand_learners(start):
    for learner in range(start, min(start + 190, 1000)):
        check_learner(str(learner))
