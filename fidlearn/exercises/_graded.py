"""A graded lesson in the learner's kernel: inputs, ``check()`` that records, ``hint()``; nothing of the key.

These classes are built from the inputs file that ``fidlearn release`` writes (plain data: the
lesson, the learner's id, every question's inputs, title, task and hints). They never receive a
question with its answer key, its parser, its comparison, its list of mistakes or its solution:
no attribute, closure or frame of theirs can lead to them, because the kernel never builds them.
The instructor's grader rebuilds the key from the class secret and judges the recorded answers.
"""

from __future__ import annotations

import textwrap
from typing import Any

from ._engine import INCORRECT, NOT_ATTEMPTED, RECORDED, Inputs, Result, _Asked, _Questions, _say

_MISSING = object()


class GradedQuestion(_Asked):
    """One question of a graded lesson: its inputs, :meth:`check` (records the answer) and :meth:`hint`.

    Parameters
    ----------
    name, title, task, level : str
        ``"q1"``, the heading, what to compute, ``"easy"``/``"medium"``/``"hard"``.
    inputs : dict
        The learner's own data (seeded by the class secret).
    hints : sequence of str
        The tiered hints.

    Attributes
    ----------
    inputs : Inputs
        The data to compute from; also ``data``.
    answer : object
        The learner's answer; ``...`` or ``None`` means not attempted.
    """

    def __init__(self, name: str, title: str, task: str, level: str, inputs: dict, hints):
        self.name = name
        self.title = title
        self.task = textwrap.dedent(task).strip()
        self.level = level
        self.inputs = Inputs(**inputs)
        self.data = self.inputs
        self._hints = [str(h) for h in hints] or ["no hint for this question"]
        self._hints_shown = 0
        self.answer: Any = ...

    _LAST_HINT = " [that was the last hint]"

    def result(self) -> Result:
        """``Recorded`` when the answer can be handed in, ``Not attempted`` or ``Incorrect`` (why not).

        Returns
        -------
        Result
            Never ``Correct``: only the instructor's grader judges.
        """
        from .._plain import to_plain

        if self.answer is None or self.answer is Ellipsis:
            return Result(self.name, NOT_ATTEMPTED, f"replace the ... in {self.name}.answer = ... with your answer")
        try:
            kind = _unsupported(to_plain(self.answer))
        except Exception:  # noqa: BLE001 - any value that cannot be handed in
            kind = type(self.answer).__name__
        if kind:
            return Result(
                self.name, INCORRECT, f"an answer of type {kind} cannot be handed in; give numbers, arrays or text"
            )
        return Result(self.name, RECORDED, "your answer is kept for your instructor, who grades it")

    def check(self, answer: Any = _MISSING) -> None:
        """Record the answer (``check(value)`` first sets ``answer = value``) and print one line.

        The line says ``Recorded``, ``Not attempted`` or why the answer cannot be handed in; it
        never says whether it is right.

        Parameters
        ----------
        answer : object, optional
            When given, it becomes ``self.answer`` first.

        Raises
        ------
        AssertionError
            Only in strict mode, for a status the mode does not expect.
        """
        if answer is not _MISSING:
            self.answer = answer
        _say(self.result(), (RECORDED,))

    def __getattr__(self, name: str):
        if name in ("solution", "solution_code", "grade"):
            raise AttributeError(
                f"{self.name}.{name}: not in a graded lesson; your instructor's grader judges the answers "
                f"({self.name}.hint() still helps)"
            )
        raise AttributeError(name)

    def __repr__(self) -> str:
        return self._describe(self.result().status)


def _unsupported(plain) -> str:
    """The type name of the first part of an answer that cannot be handed in ("" when all can)."""
    if isinstance(plain, dict):
        if "__unsupported__" in plain:
            return str(plain["__unsupported__"])
        plain = list(plain.values())
    if isinstance(plain, list):
        return next((kind for kind in map(_unsupported, plain) if kind), "")
    return ""


class GradedLesson(_Questions):
    """A graded lesson's questions for one learner: ``ex.q1``... and :meth:`summary`.

    Parameters
    ----------
    record : dict
        The inputs file's content (``fidlearn_inputs.json``).
    topic, title, intro : str
        The lesson's topic, title and introduction.

    Attributes
    ----------
    number, topic, title, intro, learner : str
    questions : list of GradedQuestion
    """

    graded = True

    def __init__(self, record: dict, topic: str, title: str, intro: str):
        self.number = str(record["lesson"])
        self.learner = str(record["learner"])
        self.topic, self.title, self.intro = topic, title, intro
        about = record.get("about", {})
        self.questions = []
        for name, values in record["questions"].items():
            meta = about.get(name, {})
            q = GradedQuestion(
                str(name),
                str(meta.get("title", name)),
                str(meta.get("task", "")),
                str(meta.get("level", "")),
                values,
                list(meta.get("hints", [])),
            )
            self.questions.append(q)
            setattr(self, q.name, q)

    def results(self) -> list[Result]:
        """Each question's state: ``Recorded``, ``Not attempted`` or why it cannot be handed in.

        Returns
        -------
        list of Result
        """
        return [q.result() for q in self.questions]

    def summary(self) -> None:
        """Print how many answers are recorded for the instructor, and one line per question."""
        res = self.results()
        n = sum(r.status == RECORDED for r in res)
        print(
            f"Lesson {self.number} for learner {self.learner!r} (graded): {n} of {len(res)} answers recorded; "
            "your instructor grades them after you hand in this notebook"
        )
        self._print_rows(res)

    def __repr__(self) -> str:
        return f"Lesson {self.number}: {self.title}, learner {self.learner!r} (graded)\n{self._listing()}"
