"""Variants where a listed wrong method would pass are excluded by construction: the marker is never exactly upside
down (05 q3, where a flipped sign gives the same angle), the frames never keep the nominal rhythm (09 q4), and the
mean of three rotations is none of them nor the plain "backwards" the task names (10 q1)."""

from __future__ import annotations

import numpy as np
import pytest

from fidlearn import exercises, frames
from fidlearn.exercises import INCORRECT
from fidlearn.exercises.lessons import l09_robot


def incorrect(q, answer) -> bool:
    return q.grade(answer).status == INCORRECT


def check_09_q4(learner: str) -> None:
    q = l09_robot._q4(learner)  # q4 alone: the lesson would render q1's drive too (see the test below)
    p = np.asarray(q.inputs.positions_mm)
    ok = ~np.isnan(p).any(axis=1)
    distance = np.sum(np.linalg.norm(np.diff(p[ok, :2], axis=0), axis=1))
    nominal = distance / (0.1 * np.ptp(np.flatnonzero(ok)))
    r = q.grade(nominal)
    assert r.status == INCORRECT, (learner, r)
    assert "timestamps" in r.message


def check_10_q1(learner: str) -> None:
    q = exercises.lesson("10", learner=learner).q1
    for R in (*np.asarray(q.inputs.rotations), frames.rotation_from_rpy_deg(0, 0, 180)):
        assert incorrect(q, R), learner


def check_05_q3(learner: str) -> None:
    q = exercises.lesson("05", learner=learner).q3
    ns: dict = {}
    exec(exercises.SETUP_CODE, ns)
    ns["q3"] = q
    exec(q.solution_code, ns)
    r = q.grade(-q.answer)
    assert r.status == INCORRECT, (learner, q.answer, r)
    assert "sign" in r.message


@pytest.mark.parametrize("check", [check_09_q4, check_10_q1])
def test_cheap_variants_of_100_learners(check):
    for learner in range(100):
        check(str(learner))


def test_09_q4_alone_is_the_lessons_q4():
    for learner in ("0", "7", "123"):
        alone, in_lesson = l09_robot._q4(learner), exercises.lesson("09", learner=learner).q4
        np.testing.assert_array_equal(alone.inputs.positions_mm, in_lesson.inputs.positions_mm)
        np.testing.assert_array_equal(alone.inputs.timestamps_s, in_lesson.inputs.timestamps_s)


def test_turned_markers_of_10_learners():
    for learner in range(10):
        check_05_q3(str(learner))


@pytest.mark.slow
@pytest.mark.parametrize("check", [check_09_q4, check_10_q1])
def test_cheap_variants_of_the_first_thousand_learners(check):
    for learner in range(100, 1000):
        check(str(learner))


@pytest.mark.slow
def test_turned_markers_of_200_learners():
    for learner in range(10, 200):
        check_05_q3(str(learner))
