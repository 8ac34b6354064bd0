"""Grading a class: the answer key never enters a learner's kernel.

Self-study (``q.check()``, ``q.hint()``, ``q.solution()``) checks answers in the learner's own
Python (the question object keeps no key; each check builds it afresh), which is what practice
needs and what a grade must not rely on: a notebook could rebuild the key from the open library,
patch the checker, print a fake result. Graded mode splits
the two sides:

* **release** (:func:`release`): the instructor's process builds each learner's questions from a
  class secret (HMAC-SHA256 of the secret, the lesson, the learner and the question seeds the
  numbers, so nobody without the secret can rebuild them from the open library) and writes only
  their *inputs*, as plain data, into ``fidlearn_inputs.json`` beside the learner's notebook.
  In a folder with that file, ``exercises.lesson(...)`` hands out a graded lesson built from the
  file alone: inputs, ``check()`` that records the answer, ``hint()``.
* **grade** (:func:`grade`): each submitted notebook runs in a process of its own, in a scratch
  copy of its folder, in a box of its own where bubblewrap works (no network, no other files,
  its own processes that die with it), with time, memory, process and file limits, an
  environment without the instructor's variables and, when the grader runs as root, as an
  unprivileged user. A cell
  appended to it writes the learner's answers as plain data (numbers, arrays, text); the
  grader reads them (strict JSON, bounded), rebuilds the questions with their answers in its
  own process and judges there. Nothing printed, patched or written in the notebook can
  change a grade: a notebook that crashes, hangs, is killed or writes nonsense gets 0 with
  the reason, and every other notebook of the batch is still graded; the CSV is written once
  the batch is done (never half of it). Each notebook is matched to its learner by the id
  that release wrote in its metadata (:mod:`fidlearn.grading._gradebook`).

In the learner's kernel a graded lesson is a :class:`~fidlearn.exercises.GradedLesson`, built
from the inputs file alone: inputs, ``check()`` that records, ``hint()``; no solution, no
checker, no key (:mod:`fidlearn.exercises._graded`).

Self-study checking of a learner's notebook (:func:`grade_notebook`, ``python -m
fidlearn.exercises grade``) runs it in the same sandbox and judges it against the self-study
variant. This package sits above :mod:`fidlearn.exercises`: it builds on the lessons, and
nothing in ``exercises`` imports it.
"""

from .._plain import from_plain, to_plain
from ..errors import GradingError
from ._grade import Grade
from ._gradebook import lms_path
from ._grader import (
    collect,
    grade,
    grade_one,
    graded_questions,
    inputs_record,
    release,
)
from ._learners import learner_from_filename, new_secret, normalize_learner, read_roster, read_secret, variant_seed
from ._sandbox import ANSWERS_FILE, COLLECT_CELL, INPUTS_FILE, read_answers, run_notebook, sandbox_plan
from ._selfstudy import grade_notebook

__all__ = [
    "ANSWERS_FILE",
    "COLLECT_CELL",
    "INPUTS_FILE",
    "Grade",
    "GradingError",
    "collect",
    "from_plain",
    "grade",
    "grade_notebook",
    "grade_one",
    "graded_questions",
    "inputs_record",
    "learner_from_filename",
    "lms_path",
    "new_secret",
    "normalize_learner",
    "read_answers",
    "read_roster",
    "read_secret",
    "release",
    "run_notebook",
    "sandbox_plan",
    "to_plain",
    "variant_seed",
]
