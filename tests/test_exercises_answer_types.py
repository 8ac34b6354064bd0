"""Answers of an unexpected Python or numpy type get Incorrect with a sentence that names the type."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fidlearn import exercises
from fidlearn.exercises import CORRECT, INCORRECT

QUESTIONS = [(n, q.name) for n in exercises.lessons() for q in exercises.lesson(n, learner="")]


def solved(number: str, name: str):
    """The question and the answer its shown solution computes."""
    q = exercises.lesson(number, learner="")[name]
    ns: dict = {}
    exec(exercises.SETUP_CODE, ns)
    ns[name] = q
    exec(q.solution_code, ns)
    return q, q.answer


def odd_answers():
    return {
        "a set": {1, 2},
        "a generator": (i for i in range(3)),
        "a ragged list": [[1.0, 2.0], [3.0]],
        "a dict": {"x": 1.0},
        "a huge whole number": 10**400,
        "an object": object(),
        "a complex number": 1 + 2j,
        "a complex array": np.array([[1 + 1j, 2], [3, 4]]),
    }


@pytest.mark.parametrize(("number", "name"), QUESTIONS)
def test_odd_answers_are_incorrect_with_a_reason(number, name):
    q = exercises.lesson(number, learner="")[name]
    for what, answer in odd_answers().items():
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # numpy's ComplexWarning would drop the imaginary part
            result = q.grade(answer)  # never raises
        assert result.status == INCORRECT, (what, result)
        assert "could not be checked" not in result.message, (what, result)


def test_complex_answer_counts_only_without_an_imaginary_part():
    q, distance = solved("01", "q3")
    assert q.grade(complex(distance, 0.0)).status == CORRECT
    result = q.grade(complex(distance, 3.0))
    assert result.status == INCORRECT
    assert "complex" in result.message
    q, K = solved("01", "q1")
    assert q.grade(np.asarray(K, dtype=complex)).status == CORRECT
    result = q.grade(np.asarray(K) + 1j)
    assert result.status == INCORRECT
    assert "imaginary part" in result.message


def test_none_in_an_answer_is_named():
    q, _ = solved("01", "q4")
    result = q.grade([None, None])
    assert result.status == INCORRECT
    assert "None" in result.message


@pytest.mark.parametrize(
    ("number", "name", "dtype"), [("06", "q1", np.int64), ("01", "q2", np.uint8), ("01", "q5", np.int32)]
)
def test_whole_number_arrays_name_their_type(number, name, dtype):
    q, answer = solved(number, name)
    if isinstance(answer, tuple):
        answer = tuple(np.asarray(a).astype(dtype) for a in answer)
    else:
        answer = np.asarray(answer).astype(dtype)
    result = q.grade(answer)
    assert result.status == INCORRECT
    assert np.dtype(dtype).name in result.message
    assert "float" in result.message
    assert "ITS pixel" not in result.message  # the pairs are in order: only the type is wrong


def test_whole_numbers_are_fine_where_the_key_is_whole():
    q, index = solved("02", "q3")
    assert q.grade(np.int64(index)).status == CORRECT
    wrong = q.grade(np.int64(index + 1))
    assert wrong.status == INCORRECT
    assert "int64" not in wrong.message


def test_marker_ids_as_opencv_gives_them():
    q, ids = solved("05", "q1")
    column = np.asarray(ids, dtype=np.int32).reshape(-1, 1)  # cv2.aruco's ids: (N, 1)
    assert q.grade(column).status == CORRECT
    assert q.grade(column.T).status == CORRECT  # (1, N)
    square = q.grade(np.zeros((2, 2), dtype=int))
    assert square.status == INCORRECT
    assert "shape (2, 2)" in square.message
    fraction = q.grade([*ids[:-1], ids[-1] + 0.5])
    assert fraction.status == INCORRECT
    assert "whole numbers" in fraction.message
