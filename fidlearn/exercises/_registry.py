"""The lessons a learner can open: the registry, :class:`Lesson`, :func:`lesson` and graded lessons."""

from __future__ import annotations

import functools
import json
import os
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import ExerciseError
from ._engine import Question, Result, _Questions
from ._graded import GradedLesson
from ._scenery import _SEED


@dataclass(frozen=True)
class _LessonInfo:
    number: str
    topic: str
    title: str
    intro: str
    build: Callable[[str], list]


_LESSONS: dict[str, _LessonInfo] = {}


def fold_learner(learner) -> str:
    """A learner id folded to the form every variant is seeded with: blanks trimmed and merged, lower case.

    Parameters
    ----------
    learner : object
        The id as given (``None`` counts as ``""``, the class's shared variant).

    Returns
    -------
    str
        ``"  Alice   Smith "`` -> ``"alice smith"``; ``""`` stays ``""``.

    Examples
    --------
    >>> fold_learner("Alice "), fold_learner(None)
    ('alice', '')
    """
    return " ".join(str(learner or "").split()).lower()


def _register(number: str, topic: str, title: str, intro: str, build: Callable[[str], list]) -> None:
    _LESSONS[number] = _LessonInfo(number, topic, title, textwrap.dedent(intro).strip(), build)


class Lesson(_Questions):
    """The questions of one lesson for one learner: ``ex.q1``, ``ex.q2``... and :meth:`summary`.

    Made by :func:`lesson`; every question is a fresh copy, so a learner may change its inputs.

    Parameters
    ----------
    info : _LessonInfo
        The registered lesson (number, topic, title, introduction, builder).
    learner : str
        The learner's id ("" for the class's shared variant).

    Attributes
    ----------
    number, topic, title, intro, learner : str
    questions : list of Question
        In notebook order; each is also an attribute (``ex.q1``).
    """

    def __init__(self, info: _LessonInfo, learner: str):
        self.number = info.number
        self.topic = info.topic
        self.title = info.title
        self.intro = info.intro
        self.learner = learner
        self.questions: list[Question] = [
            q._fresh(functools.partial(_judge, info.number, learner, q.name)) for q in _built(info.number, learner)
        ]
        for q in self.questions:
            setattr(self, q.name, q)

    def results(self) -> list[Result]:
        """The current result of every question (prints nothing).

        Returns
        -------
        list of Result
        """
        return [q.grade() for q in self.questions]

    def summary(self) -> None:
        """Print a score and one line per question."""
        res = self.results()
        n_ok = sum(r.correct for r in res)
        who = f" for learner {self.learner!r}" if self.learner else ""
        print(f"Lesson {self.number}{who}: {n_ok} of {len(res)} correct")
        self._print_rows(res)

    def __repr__(self) -> str:
        who = f", learner {self.learner!r}" if self.learner else ", the class's shared variant"
        return f"Lesson {self.number}: {self.title}{who}\n{self._listing()}"


@functools.lru_cache(maxsize=64)
def _built(number: str, learner: str) -> tuple:
    """The questions of a lesson for a learner, built once (rendering takes a moment); Lesson hands out copies."""
    return tuple(_LESSONS[number].build(learner))


def _judge(number: str, learner: str, name: str) -> Question:
    """Question ``name`` of a lesson with its answer key: what a learner's copy is checked with."""
    return next(q for q in _built(number, learner) if q.name == name)


def lessons() -> dict[str, str]:
    """The available lessons: ``{"01": "pinhole", ...}`` (number to topic).

    Returns
    -------
    dict of str to str
        Lesson number to topic, in lesson order.

    Examples
    --------
    >>> list(lessons().items())[:2]
    [('01', 'pinhole'), ('02', 'calibration')]
    """
    return {k: v.topic for k, v in sorted(_LESSONS.items())}


def lesson(number: str | int, learner: str | None = None) -> Lesson | GradedLesson:
    """The exercises of lesson ``number`` (``"01"`` ... ``"11"``) for a learner.

    In a folder holding a graded lesson's inputs file (``fidlearn_inputs.json``, written by
    ``fidlearn release``), it is a :class:`GradedLesson` built from that file alone: inputs,
    ``check()`` that records the answer and ``hint()``; no solution, no checker, no key.

    Parameters
    ----------
    number : str or int
        The lesson, ``"03"`` or ``3``.
    learner : str, optional
        Any id (a name, an e-mail, a student number): it seeds the learner's
        own numbers. It is folded once, here: trimmed, inner blanks merged, lower case, so
        ``"Alice "`` and ``"alice"`` are one learner. ``None`` or ``""`` takes
        ``$FIDLEARN_LEARNER``, else the variant the whole class shares.

    Returns
    -------
    Lesson or GradedLesson
        Its questions, fresh (no answers yet).

    Raises
    ------
    ExerciseError
        For an unknown lesson, or an inputs file that is damaged or belongs to another lesson.

    Examples
    --------
    >>> ex = lesson("01", learner="alice")
    >>> [q.name for q in ex]
    ['q1', 'q2', 'q3', 'q4', 'q5']
    >>> ex.q1.title
    'K from a diagonal field of view'
    """
    key = lesson_number(number)
    graded = Path(INPUTS_FILE)
    if graded.is_file():
        return _graded_lesson(key, graded)
    if not learner:
        learner = os.environ.get("FIDLEARN_LEARNER", "")
    return Lesson(_LESSONS[key], fold_learner(learner))


#: The file a graded lesson's inputs come in (written by ``fidlearn release``).
INPUTS_FILE = "fidlearn_inputs.json"


def lesson_number(number: str | int) -> str:
    """A lesson's number in its canonical form: ``3``, ``"3"`` or ``"03"`` -> ``"03"``.

    Parameters
    ----------
    number : str or int
        The lesson.

    Returns
    -------
    str
        Two digits.

    Raises
    ------
    ExerciseError
        For anything that is not a lesson; the message lists the lessons.

    Examples
    --------
    >>> lesson_number(3)
    '03'
    """
    text = str(number).strip()
    key = f"{int(text):02d}" if text.isascii() and text.isdigit() and len(text) < 4 else str(number)
    if key not in _LESSONS:
        raise ExerciseError(f"no exercises for lesson {number!r}; available: {', '.join(sorted(_LESSONS))}")
    return key


def build_questions(number: str, learner: str, seed: Callable[[str], int] | None = None) -> list:
    """The questions of a lesson built afresh, with their answer keys.

    Parameters
    ----------
    number : str or int
        The lesson.
    learner : str
        The learner's id (folded as in :func:`lesson`: ``"Alice "`` is ``"alice"``).
    seed : callable, optional
        ``seed(question_name) -> int``: seeds every question's generator instead of the learner's id
        (graded mode: :func:`fidlearn.grading.variant_seed` of the class secret). It holds only while
        the questions are built (a context variable), so other threads are not affected.

    Returns
    -------
    list of Question

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    """
    token = _SEED.set(seed)
    try:
        return list(_LESSONS[lesson_number(number)].build(fold_learner(learner)))
    finally:
        _SEED.reset(token)


def _graded_lesson(key: str, path: Path) -> GradedLesson:
    """A lesson whose inputs come from the grader's file: no question with a key is ever built here."""
    from .._plain import from_plain

    try:
        record = json.loads(path.read_text(encoding="utf-8"))
        given = record["questions"].items()
        record["questions"] = {str(name): {str(k): from_plain(v) for k, v in inputs.items()} for name, inputs in given}
        lesson_of_file = str(record["lesson"])
        info = _LESSONS[key]
        shell = GradedLesson(record, info.topic, info.title, info.intro)
    except Exception as exc:  # noqa: BLE001 - a damaged inputs file: say so in one line
        raise ExerciseError(
            f"{path} is damaged ({type(exc).__name__}); ask your instructor for your lesson's files again"
        ) from None
    if lesson_of_file != key:
        raise ExerciseError(
            f"this folder holds the inputs of lesson {lesson_of_file}, not {key}: "
            f"use exercises.lesson({lesson_of_file!r})"
        )
    return shell


def notebook_name(number: str) -> str:
    """The file name of a lesson's exercise notebook.

    Parameters
    ----------
    number : str or int
        The lesson.

    Returns
    -------
    str
        ``"<number>_<topic>.ipynb"``.

    Raises
    ------
    ExerciseError
        For an unknown lesson.

    Examples
    --------
    >>> notebook_name("03")
    '03_extrinsics.ipynb'
    """
    info = _LESSONS[lesson_number(number)]
    return f"{info.number}_{info.topic}.ipynb"
