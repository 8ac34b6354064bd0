"""The exercise notebooks: answer keys run clean and say Correct; student copies run clean and say Not attempted.

The answer keys run in a real Jupyter kernel (nbclient) in strict mode, so a
check that is not Correct fails the notebook. The student copies are run in
this process, cell by cell, in strict "blank" mode: every check must say Not
attempted, and nothing may raise. Both must match what
``tools/make_student_copies.py`` builds from the lessons in ``fidlearn/exercises/lessons/``.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys

import nbformat
import pytest

from fidlearn import exercises, grading
from fidlearn.data import repo_dir

EXERCISES_DIR = repo_dir() / "notebooks" / "exercises"
SOLUTIONS_DIR = EXERCISES_DIR / "solutions"
LESSONS = list(exercises.lessons())
CHECK_LINE = re.compile(r"^(Correct|Incorrect|Not attempted) \((q\d+)\)", re.M)


def sources(nb):
    return [(c.cell_type, c.source) for c in nb.cells]


def read(path):
    assert path.exists(), f"{path} is missing: run python tools/make_student_copies.py"
    return nbformat.read(path, as_version=4)


@pytest.mark.parametrize("number", LESSONS)
def test_notebooks_are_not_stale(number):
    name = exercises.notebook_name(number)
    key = exercises.answer_key_notebook(number)
    assert sources(read(SOLUTIONS_DIR / name)) == sources(key), (
        f"solutions/{name} is stale: run python tools/make_student_copies.py {number}"
    )
    student = exercises.student_copy(read(SOLUTIONS_DIR / name))
    assert sources(read(EXERCISES_DIR / name)) == sources(student), (
        f"{name} is stale: run python tools/make_student_copies.py {number}"
    )


@pytest.mark.parametrize("number", LESSONS)
def test_answer_key_blocks_are_the_code_solution_shows(number):
    blocks = exercises.solution_blocks(read(SOLUTIONS_DIR / exercises.notebook_name(number)))
    ex = exercises.lesson(number)
    assert blocks == {q.name: q.solution_code for q in ex}


def test_student_copy_keeps_no_solution():
    key = exercises.answer_key_notebook("01")
    student = exercises.student_copy(key)
    text = "\n".join(c.source for c in student.cells)
    assert exercises.BEGIN_SOLUTION not in text
    assert "np.radians(q1.inputs.dfov_deg)" not in text
    assert text.count(".answer = ...") == len(exercises.lesson("01"))
    bad = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("### BEGIN SOLUTION\nx = 1\n### END SOLUTION")])
    with pytest.raises(ValueError, match="assigns no answer"):
        exercises.student_copy(bad)


@pytest.mark.parametrize("number", LESSONS)
def test_answer_key_runs_clean_and_every_check_is_correct(number, monkeypatch):
    from nbclient import NotebookClient

    monkeypatch.setenv("FIDLEARN_STRICT", "1")
    monkeypatch.delenv("FIDLEARN_LEARNER", raising=False)
    nb = exercises.answer_key_notebook(number)
    NotebookClient(nb, timeout=60, kernel_name="python3").execute()  # raises CellExecutionError on any error
    text = "".join(
        o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "stream"
    )
    found = CHECK_LINE.findall(text)
    names = [q.name for q in exercises.lesson(number)]
    assert found == [("Correct", n) for n in names]


@pytest.mark.parametrize("number", LESSONS)
def test_student_copy_runs_clean_and_every_check_is_not_attempted(number):
    nb = read(EXERCISES_DIR / exercises.notebook_name(number))
    ns: dict = {"__name__": "__main__"}
    out = io.StringIO()
    with exercises.strict("blank"), contextlib.redirect_stdout(out):
        for cell in nb.cells:
            if cell.cell_type == "code":
                exec(compile(cell.source, f"<{number} cell {cell.get('id')}>", "exec"), ns)
    if "matplotlib.pyplot" in sys.modules:  # the cells that show pictures opened figures
        sys.modules["matplotlib.pyplot"].close("all")
    found = CHECK_LINE.findall(out.getvalue())
    names = [q.name for q in exercises.lesson(number)]
    assert found == [("Not attempted", n) for n in names]


@pytest.mark.parametrize("number", LESSONS)
def test_stored_outputs_are_real(number):
    """The stored outputs come from running the notebooks: keys say Correct, copies Not attempted."""
    name = exercises.notebook_name(number)
    for path, status in ((SOLUTIONS_DIR / name, "Correct"), (EXERCISES_DIR / name, "Not attempted")):
        nb = read(path)
        text = "".join(
            o.get("text", "")
            for c in nb.cells
            if c.cell_type == "code"
            for o in c.get("outputs", [])
            if o.output_type == "stream"
        )
        assert {s for s, _ in CHECK_LINE.findall(text)} == {status}, (
            f"{path.name}: run python tools/make_student_copies.py {number}"
        )


def test_grading_a_learners_notebook(tmp_path):
    """A learner's copy with one right answer, one common mistake and one broken cell."""
    nb = read(EXERCISES_DIR / exercises.notebook_name("07"))
    ex = exercises.lesson("07", learner="erin")
    stub = "{q}.answer = ..."
    for cell in nb.cells:
        if stub.format(q="q1") in cell.source:
            cell.source = cell.source.replace(stub.format(q="q1"), ex.q1.solution_code)
        elif stub.format(q="q2") in cell.source:  # the extrinsic matrix where the pose is asked
            cell.source = cell.source.replace(
                stub.format(q="q2"), "q2.answer = frames.transform_from_rvec_tvec(q2.inputs.rvec, q2.inputs.tvec)"
            )
        elif stub.format(q="q3") in cell.source:
            cell.source = cell.source.replace(stub.format(q="q3"), "q3.answer = 1 / 0")
    path = tmp_path / "07_erin.ipynb"
    nbformat.write(nb, path)
    grade = grading.grade_notebook(path, learner="erin")
    assert (grade.lesson, grade.learner) == ("07", "erin")
    assert [r.status for r in grade.results] == ["Correct", "Incorrect"] + ["Not attempted"] * (len(ex) - 2)
    assert "extrinsic matrix" in grade.results[1].message
    assert len(grade.errors) == 1
    assert "ZeroDivisionError" in grade.errors[0]
    assert str(grade).startswith(f"{path}: lesson 07, learner 'erin': 1 of {len(ex)} correct")
