"""Classroom exercises with automatic feedback: ``q1.check()``, ``q1.hint()``, ``q1.solution()``.

Each lesson (``"01"`` to ``"10"``) holds questions built from seeded synthetic
data. A question shows its inputs in ``q.inputs``; the learner writes code that
computes the answer from them, assigns ``q.answer = ...`` (or calls
``q.check(value)``) and runs ``q.check()``, which prints one line:

* ``Correct (q1): ...``
* ``Incorrect (q1): what is wrong, and a nudge`` (common mistakes such as a
  transposed K, degrees for radians, the wrong winding order, the extrinsic
  matrix where the camera pose is asked, or feet for mm are recognised and
  named);
* ``Not attempted (q1): ...`` while the answer is still ``...`` or ``None``.

``check()`` never raises in a learner's notebook. Tests and graders switch on
strict mode (``FIDLEARN_STRICT=1`` or ``with exercises.strict():``), in which
every check that is not ``Correct`` raises :class:`AssertionError`;
``strict("blank")`` (``FIDLEARN_STRICT=blank``) instead demands ``Not
attempted`` everywhere, which is how the student copies are tested.

A learner's id seeds a personal variant: ``exercises.lesson("03",
learner="alice")`` gives Alice her own numbers, and the answer key checks
them. The id is hashed with SHA-256, so the variant is the same on every
machine and every Python run. Without an id (``learner=""``) the id comes from
the environment variable ``FIDLEARN_LEARNER``, else the whole class shares one
variant.

Grading: :func:`fidlearn.grading.grade_notebook` (or ``python -m fidlearn.exercises grade
NOTEBOOK... --learner ID --csv FILE``) runs a learner's notebook in a fresh
kernel and checks the answers its lesson holds. The answer-key notebooks are
built from the lesson definitions here (:func:`answer_key_notebook`) and the
student copies from the keys (:func:`student_copy`), by
``tools/make_student_copies.py``; see ``docs/teaching.md``.

Examples
--------
>>> import math
>>> ex = lesson("01", learner="alice")
>>> q1 = ex.q1
>>> q1.check()  # doctest: +ELLIPSIS
Not attempted (q1): ...
>>> w, h = q1.inputs.image_size
>>> f = (math.hypot(w, h) / 2) / math.tan(math.radians(q1.inputs.dfov_deg) / 2)
>>> q1.check([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])  # doctest: +ELLIPSIS
Correct (q1): ...
"""

from __future__ import annotations

from ..errors import ExerciseError

# The lesson modules register themselves first: the subpackage ``lessons`` would otherwise be
# the attribute ``fidlearn.exercises.lessons``, which is the function :func:`lessons` below.
from . import lessons as _lesson_modules  # registers the lessons
from ._engine import (
    BEGIN_SOLUTION,
    CORRECT,
    END_SOLUTION,
    INCORRECT,
    NOT_ATTEMPTED,
    RECORDED,
    SETUP_CODE,
    Inputs,
    Question,
    Result,
)
from ._graded import GradedLesson, GradedQuestion
from ._notebooks import answer_key_notebook, solution_blocks, student_copy
from ._registry import (
    INPUTS_FILE,
    Lesson,
    build_questions,
    lesson,
    lesson_number,
    lessons,
    notebook_name,
)
from ._strict import STRICT_STACK, strict, strict_mode

__all__ = [
    "CORRECT",
    "INCORRECT",
    "NOT_ATTEMPTED",
    "RECORDED",
    "SETUP_CODE",
    "BEGIN_SOLUTION",
    "END_SOLUTION",
    "INPUTS_FILE",
    "STRICT_STACK",
    "ExerciseError",
    "Inputs",
    "Lesson",
    "GradedLesson",
    "GradedQuestion",
    "Question",
    "Result",
    "lesson",
    "lessons",
    "lesson_number",
    "build_questions",
    "notebook_name",
    "strict",
    "strict_mode",
    "answer_key_notebook",
    "student_copy",
    "solution_blocks",
]

del _lesson_modules
