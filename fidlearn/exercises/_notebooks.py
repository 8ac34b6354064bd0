"""The exercise notebooks: answer keys built from the lessons, student copies built from the keys."""

from __future__ import annotations

import copy
import re

from ._engine import BEGIN_SOLUTION, END_SOLUTION, SETUP_CODE
from ._registry import _LESSONS, Lesson, lesson_number

_HOW_TO = """\
**How to work.** Each question gives its data in `qN.inputs`. Write code that computes the
answer from them, assign it to `qN.answer` and run `qN.check()`: it says `Correct`,
`Incorrect` (with what looks wrong) or `Not attempted`. Stuck? `qN.hint()`. Given up?
`qN.solution()` shows one way to do it. Put your name (or the id your teacher gave you) in
`LEARNER` to get your own numbers; the checks know the answers for everyone."""


def answer_key_notebook(number: str):
    """The answer-key notebook of a lesson (an ``nbformat`` notebook, not executed).

    Each question has a markdown cell (the task), a cell showing its inputs,
    and a cell whose solution sits between ``### BEGIN SOLUTION`` and
    ``### END SOLUTION``, followed by ``qN.check()``.

    Parameters
    ----------
    number : str or int
        The lesson.

    Returns
    -------
    nbformat.NotebookNode
        The notebook, cells with stable ids (``ex03-00``...).

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    """
    import nbformat

    info = _LESSONS[lesson_number(number)]
    ex = Lesson(info, "")
    v4 = nbformat.v4
    cells = [
        v4.new_markdown_cell(f"# Exercises {info.number}: {info.title}\n\n{info.intro}\n\n{_HOW_TO}"),
        v4.new_code_cell(
            f'{SETUP_CODE}\n\nLEARNER = ""  # your name or id, e.g. "alice": it gives you your own numbers\nex '
            f'= exercises.lesson("{info.number}", learner=LEARNER)\nex'
        ),
    ]
    for q in ex:
        level = f" ({q.level})" if q.level else ""
        cells.append(v4.new_markdown_cell(f"## {q.name}. {q.title}{level}\n\n{q.task}"))
        look = f"{q.look_code}\n" if q.look_code else ""
        cells.append(v4.new_code_cell(f"{q.name} = ex.{q.name}\n{look}{q.name}.inputs"))
        cells.append(v4.new_code_cell(f"{BEGIN_SOLUTION}\n{q.solution_code}\n{END_SOLUTION}\n{q.name}.check()"))
    cells.append(v4.new_markdown_cell("## Your score"))
    cells.append(v4.new_code_cell("ex.summary()"))
    for i, c in enumerate(cells):
        c["id"] = f"ex{info.number}-{i:02d}"
    nb = v4.new_notebook(cells=cells)
    nb.metadata = {
        "kernelspec": {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"},
        "language_info": {"name": "python"},
    }
    return nb


_BLOCK_RE = re.compile(re.escape(BEGIN_SOLUTION) + r"\n(.*?)\n?" + re.escape(END_SOLUTION) + r"\n?", re.S)


_ANSWER_RE = re.compile(r"^(\w+)\.answer\s*=", re.M)


def solution_blocks(nb) -> dict[str, str]:
    """The solution code of each question in an answer-key notebook.

    Parameters
    ----------
    nb : nbformat.NotebookNode
        An answer-key notebook (:func:`answer_key_notebook`).

    Returns
    -------
    dict of str to str
        ``{"q1": code, ...}``: the code between the solution markers, by the question it answers.

    Raises
    ------
    ValueError
        For a solution block that assigns no ``qN.answer``.
    """
    out = {}
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        for m in _BLOCK_RE.finditer(cell.source):
            names = _ANSWER_RE.findall(m.group(1))
            if not names:
                raise ValueError(
                    f"a solution block assigns no answer (expected a line 'qN.answer = ...'):\n{m.group(1)}"
                )
            out[names[-1]] = m.group(1).strip()
    return out


def student_copy(nb):
    """The student copy of an answer-key notebook: solutions replaced by stubs, outputs cleared.

    A block between ``### BEGIN SOLUTION`` and ``### END SOLUTION`` that
    assigns ``qN.answer`` becomes ``# your code here ...`` and
    ``qN.answer = ...``, so the check that follows says ``Not attempted``.

    Parameters
    ----------
    nb : nbformat.NotebookNode
        An answer-key notebook; it is not changed.

    Returns
    -------
    nbformat.NotebookNode
        The copy.

    Raises
    ------
    ValueError
        For a solution block that assigns no ``qN.answer``.
    """
    nb = copy.deepcopy(nb)

    def stub(m: re.Match) -> str:
        names = _ANSWER_RE.findall(m.group(1))
        if not names:
            raise ValueError(f"a solution block assigns no answer (expected a line 'qN.answer = ...'):\n{m.group(1)}")
        q = names[-1]
        return f"# Your code here: compute the answer from {q}.inputs. Stuck? {q}.hint()\n{q}.answer = ...\n"

    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.source = _BLOCK_RE.sub(stub, cell.source)
            cell.outputs = []
            cell.execution_count = None
        cell.get("metadata", {}).pop("execution", None)
    return nb
