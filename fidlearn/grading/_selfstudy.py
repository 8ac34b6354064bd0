"""Checking a learner's self-study notebook: :func:`grade_notebook`, which gives a :class:`Grade`."""

from __future__ import annotations

import os
import re
from dataclasses import replace

from ._grade import Grade

_NO_LESSON = "no exercises found: the notebook never ran ex = exercises.lesson(...)"
_LESSON_CALL = re.compile(r"exercises\.lesson\(\s*[\"']?(\d{1,2})[\"']?")


def grade_notebook(path: str | os.PathLike, learner: str | None = None, timeout_s: int = 300) -> Grade:
    """Check a learner's self-study notebook: run it in a sandbox, judge its answers outside it.

    The notebook runs in a process of its own (see :mod:`fidlearn.grading`); its answers are
    collected as plain data and judged here against the self-study variant of ``learner``.
    This is a practice check: a self-study kernel holds its own answer key. For marks, release
    the lesson with a class secret and grade with ``fidlearn grade``. Nothing in this process
    changes: the learner id reaches the notebook through the sandbox's own environment.

    Parameters
    ----------
    path : str or os.PathLike
        The notebook (``.ipynb``).
    learner : str, optional
        The id the learner was told to use (a notebook whose ``LEARNER`` is empty runs with it).
    timeout_s : int
        Seconds the notebook may run.

    Returns
    -------
    Grade
        A Result per question; a notebook that never opened a lesson gets none, with the reason
        in ``problem`` (and ``errors``).

    Raises
    ------
    FidlearnError
        When ``path`` is a folder, missing, or not a Jupyter notebook.
    """
    import nbformat

    from ..errors import FidlearnError
    from ..exercises import lesson_number
    from . import _grader

    path = os.fspath(path)
    if not os.path.isfile(path):
        what = (
            "is a folder; give the notebooks in it (folder/*.ipynb)"
            if os.path.isdir(path)
            else "no such notebook; check the path"
        )
        raise FidlearnError(f"{path}: {what}")
    try:
        nb = nbformat.read(path, as_version=4)
    except Exception as exc:  # nbformat raises NotJSONError, UnicodeDecodeError, KeyError, validation errors...
        raise FidlearnError(
            f"{path}: not a Jupyter notebook ({type(exc).__name__}); give the learner's .ipynb file"
        ) from None
    found = {m.group(1) for c in nb.cells if c.cell_type == "code" for m in _LESSON_CALL.finditer(c.source)}
    if len(found) != 1:
        return Grade(path, learner, None, problem=_NO_LESSON)
    number = lesson_number(found.pop())
    g = _grader.grade_one(path, number, learner or "", None, timeout_s=timeout_s)
    return replace(g, notebook=path, learner=learner or "")
