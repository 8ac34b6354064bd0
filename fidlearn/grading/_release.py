"""``release``: every learner's notebook and inputs, built in a temporary sibling folder and renamed into place.

A learner's folder is named by their id (:func:`fidlearn.grading._learners.normalize_learner`), which is
also the seed of their numbers and what ``grade`` matches their notebook by (the notebook's
metadata carries it). Nothing is ever written outside the output folder, no learner's files
overwrite another's, and a release that fails (a full disk, Ctrl-C) leaves nothing behind.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

from .._plain import to_plain
from ..errors import GradingError
from ._learners import read_roster, read_secret, release_tag

#: Where a released notebook says whose it is: ``metadata["fidlearn"] = {"lesson", "learner", "tag"}``.
METADATA_KEY = "fidlearn"

_GRADED_NOTE = (
    "**Graded lesson.** Your numbers are your own, seeded by your instructor. `qN.check()` records your "
    "answer and says whether it can be handed in, never whether it is right; `qN.hint()` still helps; "
    "there is no `qN.solution()`. Your instructor grades the answers after you hand in this notebook."
)


def inputs_record(number: str, learner: str, questions: list) -> dict:
    """What ``fidlearn_inputs.json`` holds: the lesson, the id, each question's inputs, title, task, hints.

    Parameters
    ----------
    number : str
        The lesson (``"03"``).
    learner : str
        The normalized learner id.
    questions : list of Question
        The learner's questions (built with their keys in the instructor's process).

    Returns
    -------
    dict
        Plain data: no answer, no solution, no checker.
    """
    return {
        "fidlearn_graded": 1,
        "lesson": number,
        "learner": learner,
        "questions": {q.name: {k: to_plain(q.inputs[k]) for k in q.inputs} for q in questions},
        "about": {
            q.name: {"title": q.title, "task": q.task, "level": q.level, "hints": list(q._hints)} for q in questions
        },
    }


def released_notebook(source: Path, number: str, learner: str, tag: str) -> str:
    """The student notebook as a learner receives it: outputs cleared, a graded note, their id in its metadata.

    Parameters
    ----------
    source : pathlib.Path
        The lesson's student notebook.
    number, learner : str
        The lesson and the learner's id.
    tag : str
        :func:`fidlearn.grading._learners.release_tag` of the lesson and the id.

    Returns
    -------
    str
        The notebook's JSON text.
    """
    import nbformat

    nb = nbformat.read(source, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    note = nbformat.v4.new_markdown_cell(_GRADED_NOTE)
    note["id"] = f"ex{number}-graded"
    nb.cells.insert(1, note)
    nb.metadata[METADATA_KEY] = {"lesson": number, "learner": learner, "tag": tag}
    return nbformat.writes(nb)


def release(number: str, learners: Sequence[str], secret_path, out_dir, *, build, notebook: Path | None) -> list[Path]:
    """Write ``OUT/<id>/`` for each learner: all built in a sibling folder, renamed into place at the end.

    Parameters
    ----------
    number : str
        The lesson, canonical (``"03"``).
    learners : sequence of str
        The roster's lines (ids as written; normalized and checked here).
    secret_path : path
        The class secret's file.
    out_dir : path
        The folder to create (or an empty one to fill).
    build : callable
        ``build(number, learner, secret) -> list of Question``.
    notebook : pathlib.Path or None
        The student notebook (None: inputs only).

    Returns
    -------
    list of pathlib.Path
        The learners' folders.

    Raises
    ------
    GradingError
        For a missing secret or parent folder, an existing non-empty output folder, an unusable
        learner id (with its line), two lines that are one learner, or a disk that refuses.
    """
    secret = read_secret(secret_path)
    ids = read_roster(list(learners), "the roster")
    out = Path(out_dir)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise GradingError(f"{out}: the folder {parent} does not exist; create it first")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise GradingError(f"{out}: exists and is not an empty folder; release each lesson into a new folder")
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    except OSError as exc:
        raise GradingError(f"{out}: cannot write in {parent} ({exc.strerror}); nothing was written") from None
    try:
        for learner in ids:
            folder = tmp / learner
            folder.mkdir()
            record = inputs_record(number, learner, build(number, learner, secret))
            _write(folder / "fidlearn_inputs.json", json.dumps(record))
            if notebook is not None:
                text = released_notebook(notebook, number, learner, release_tag(secret, number, learner))
                _write(folder / notebook.name, text)
        os.chmod(tmp, 0o777 & ~_umask())
        os.replace(tmp, out)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise GradingError(
            f"{out}: cannot write the learners' folders ({exc.strerror or exc}); check the free disk space; "
            "nothing was written"
        ) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return [out / learner for learner in ids]


def _write(path: Path, text: str) -> None:
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
