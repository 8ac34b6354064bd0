"""One grade type: the class grader and the self-study check give the same :class:`fidlearn.grading.Grade`."""

from __future__ import annotations

from fidlearn import grading
from fidlearn.exercises import CORRECT, INCORRECT, NOT_ATTEMPTED, Result


def _grade(**kw) -> grading.Grade:
    results = [Result("q1", CORRECT, "well done"), Result("q2", INCORRECT, "off by 2"), Result("q3", NOT_ATTEMPTED, "")]
    return grading.Grade("sub/alice.ipynb", "alice", "03", results, **kw)


def test_the_graders_line_and_the_self_study_report_come_from_one_grade():
    g = _grade(problem="it took 200 s", cell_errors=["cell 4: ZeroDivisionError: division by zero"])
    assert g.score == 1
    assert g.line() == "sub/alice.ipynb: learner 'alice', lesson 03: 1 of 3 correct (it took 200 s)"
    assert g.errors == ["cell 4: ZeroDivisionError: division by zero", "it took 200 s"]
    assert str(g).splitlines() == [
        "sub/alice.ipynb: lesson 03, learner 'alice': 1 of 3 correct",
        "  Correct (q1): well done",
        "  Incorrect (q2): off by 2",
        "  Not attempted (q3)",
        "  problem: cell 4: ZeroDivisionError: division by zero",
        "  problem: it took 200 s",
    ]


def test_a_notebook_not_run_says_why_in_its_line():
    g = grading.Grade("", "bob", "03", problem="missing: no notebook was handed in", graded=False)
    assert g.line() == "(no notebook): learner 'bob', lesson 03: missing: no notebook was handed in"
    assert g.score == 0
    assert g.errors == ["missing: no notebook was handed in"]


def test_the_self_study_check_gives_the_grader_type(tmp_path):
    nb = tmp_path / "empty.ipynb"
    nb.write_text('{"cells": [], "metadata": {}, "nbformat": 4, "nbformat_minor": 5}', encoding="utf-8")
    g = grading.grade_notebook(nb)
    assert type(g) is grading.Grade
    assert not hasattr(grading, "NotebookGrade")
    assert str(g) == (
        f"{nb}: lesson None, learner None: 0 of 0 correct\n"
        "  problem: no exercises found: the notebook never ran ex = exercises.lesson(...)"
    )
