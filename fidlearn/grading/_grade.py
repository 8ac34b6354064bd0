"""One learner's grade for one notebook: :class:`Grade`, made of a question :class:`~fidlearn.exercises.Result` each."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Grade:
    """One notebook's grade: a :class:`~fidlearn.exercises.Result` per question, its score and why not more.

    ``fidlearn grade`` (:func:`~fidlearn.grading.grade`, :func:`~fidlearn.grading.grade_one`) and
    the self-study check (:func:`~fidlearn.grading.grade_notebook`) both give one.

    Parameters
    ----------
    notebook : str
        The notebook's path ("" for a roster's learner who handed in nothing).
    learner : str or None
        The learner's id (None for a self-study notebook checked without one that never opened a lesson).
    lesson : str or None
        The lesson, ``"03"`` (None when the notebook never opened one).
    results : list of Result
        One :class:`~fidlearn.exercises.Result` per question (the type self-study checks give).
    problem : str
        Why it got 0 or took too long ("" when all went well).
    cell_errors : list of str
        The cells that raised (information only).
    graded : bool
        False for a notebook that was not run (unknown learner, handed in twice, another
        learner's notebook) and for a roster's learner who handed in nothing.

    Examples
    --------
    >>> from fidlearn.exercises import CORRECT, INCORRECT, Result
    >>> g = Grade("alice.ipynb", "alice", "03", [Result("q1", CORRECT, ""), Result("q2", INCORRECT, "")])
    >>> g.score, g.line()
    (1, "alice.ipynb: learner 'alice', lesson 03: 1 of 2 correct")
    """

    notebook: str
    learner: str | None
    lesson: str | None
    results: list = field(default_factory=list)
    problem: str = ""
    cell_errors: list = field(default_factory=list)
    graded: bool = True

    @property
    def score(self) -> int:
        """How many questions are Correct.

        Returns
        -------
        int
        """
        return sum(r.correct for r in self.results)

    @property
    def errors(self) -> list[str]:
        """What went wrong running the notebook: the cells that raised, then the problem, if any.

        Returns
        -------
        list of str
        """
        return list(self.cell_errors) + ([self.problem] if self.problem else [])

    def line(self) -> str:
        """One line for the grader's log: notebook, learner, lesson, score and any problem.

        Returns
        -------
        str
        """
        if not self.graded:
            return f"{self.notebook or '(no notebook)'}: learner {self.learner!r}, lesson {self.lesson}: {self.problem}"
        total = len(self.results)
        head = f"{self.notebook}: learner {self.learner!r}, lesson {self.lesson}: {self.score} of {total} correct"
        return head + (f" ({self.problem})" if self.problem else "")

    def __str__(self) -> str:
        """The report a self-study check prints: the score, a line per question, a line per problem."""
        head = (
            f"{self.notebook}: lesson {self.lesson}, learner {self.learner!r}: {self.score} of {len(self.results)} "
            "correct"
        )
        lines = [head] + [f"  {r.line}" for r in self.results] + [f"  problem: {e}" for e in self.errors]
        return "\n".join(lines)
