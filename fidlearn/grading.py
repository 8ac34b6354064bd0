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
  In a folder with that file, ``exercises.lesson(...)`` hands out questions without answers:
  ``check()`` only says whether an answer has the right form.
* **grade** (:func:`grade`): each submitted notebook runs in a process of its own, in a scratch
  copy of its folder, in a box of its own where bubblewrap works (no network, no other files,
  its own processes that die with it), with time, memory, process and file limits, an
  environment without the instructor's variables and, when the grader runs as root, as an
  unprivileged user. A cell
  appended to it writes the learner's answers as plain data (numbers, arrays, text); the
  grader reads them (strict JSON, bounded), rebuilds the questions with their answers in its
  own process and judges there. Nothing printed, patched or written in the notebook can
  change a grade: a notebook that crashes, hangs, is killed or writes nonsense gets 0 with
  the reason, and every other notebook of the batch is still graded; the CSV is always written.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import shutil
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ._io import write_text_atomic

# the class secret, plain data and the sandbox live in modules of their own; their names stay
# importable from here
from ._learners import learner_from_filename as learner_from_filename
from ._learners import new_secret as new_secret
from ._learners import normalize_learner as normalize_learner
from ._learners import read_secret as read_secret
from ._learners import variant_seed as variant_seed
from ._plain import _ARRAY_KINDS as _ARRAY_KINDS
from ._plain import MAX_DEPTH as MAX_DEPTH
from ._plain import _bad as _bad
from ._plain import _Unsupported as _Unsupported
from ._plain import from_plain as from_plain
from ._plain import to_plain as to_plain
from ._sandbox import ANSWERS_FILE as ANSWERS_FILE
from ._sandbox import COLLECT_CELL as COLLECT_CELL
from ._sandbox import INPUTS_FILE as INPUTS_FILE
from ._sandbox import MAX_ANSWERS_BYTES as MAX_ANSWERS_BYTES
from ._sandbox import _Zero as _Zero
from ._sandbox import read_answers as read_answers
from ._sandbox import run_notebook as run_notebook
from ._sandbox import sandbox_plan as sandbox_plan
from .errors import FidlearnError
from .errors import GradingError as GradingError


# ------------------------------------------------------------------------------------------------
# release: the learner's inputs, without answers
# ------------------------------------------------------------------------------------------------
def graded_questions(lesson: str, learner: str, secret: bytes) -> list:
    """The questions of ``lesson`` for ``learner`` built from the class secret (with their answers).

    Parameters
    ----------
    lesson : str or int
        The lesson.
    learner : str
        The learner's id (normalized here).
    secret : bytes
        The class secret.

    Returns
    -------
    list of Question

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    GradingError
        For a learner id that cannot be used.
    """
    from . import exercises

    number = exercises.lesson_number(lesson)
    return list(
        exercises.build_questions(
            number,
            normalize_learner(learner),
            seed=lambda q: variant_seed(secret, number, normalize_learner(learner), q),
        )
    )


def inputs_record(lesson: str, learner: str, secret: bytes) -> dict:
    """What ``fidlearn_inputs.json`` holds for one learner: the lesson, the id and every question's inputs.

    Parameters
    ----------
    lesson : str or int
        The lesson.
    learner : str
        The learner's id.
    secret : bytes
        The class secret.

    Returns
    -------
    dict
        ``{"fidlearn_graded": 1, "lesson", "learner", "questions": {name: {input: plain data}}}``;
        no answers.

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    GradingError
        For a learner id that cannot be used.
    """
    from . import exercises

    number = exercises.lesson_number(lesson)
    questions = graded_questions(number, learner, secret)
    return {
        "fidlearn_graded": 1,
        "lesson": number,
        "learner": normalize_learner(learner),
        "questions": {q.name: {k: to_plain(q.inputs[k]) for k in q.inputs} for q in questions},
    }


def release(
    lesson: str, learners: Sequence[str], secret_path: str | os.PathLike, out_dir: str | os.PathLike
) -> list[Path]:
    """Write ``OUT/<learner>/`` for each learner: the lesson's student notebook and its inputs file.

    Parameters
    ----------
    lesson : str or int
        The lesson.
    learners : sequence of str
        The learners' ids.
    secret_path : str or os.PathLike
        The class secret's file.
    out_dir : str or os.PathLike
        The folder to write into (its parent must exist).

    Returns
    -------
    list of pathlib.Path
        One folder per learner.

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    GradingError
        For a missing secret or parent folder, an unusable learner id, or a learner listed twice.
    """
    from . import exercises

    secret = read_secret(secret_path)
    number = exercises.lesson_number(lesson)
    out = Path(out_dir)
    if not out.parent.is_dir():
        raise GradingError(f"{out}: the folder {out.parent} does not exist; create it first")
    ids = [normalize_learner(x) for x in learners]
    if len(set(ids)) != len(ids):
        raise GradingError("a learner is listed twice (ids are compared trimmed and in lower case)")
    notebook = Path(__file__).resolve().parent.parent / "notebooks" / "exercises" / exercises.notebook_name(number)
    made = []
    for learner in ids:
        folder = out / _folder_name(learner)
        folder.mkdir(parents=True, exist_ok=True)
        if notebook.is_file():
            shutil.copyfile(notebook, folder / notebook.name)
        write_text_atomic(folder / INPUTS_FILE, json.dumps(inputs_record(number, learner, secret)))
        made.append(folder)
    return made


def _folder_name(learner: str) -> str:
    return re.sub(r"[^a-z0-9._-]+", "_", learner)[:80] or "learner"


# ------------------------------------------------------------------------------------------------
# grading: one notebook per process, answers as plain data
# ------------------------------------------------------------------------------------------------


def collect(namespace: dict, path: str = ANSWERS_FILE) -> None:
    """Write the answers of the graded lesson found in ``namespace`` as plain data (the appended cell).

    Runs in the learner's kernel, so the grader trusts nothing it writes beyond its form.

    Parameters
    ----------
    namespace : dict
        The notebook's globals; the first :class:`~fidlearn.exercises.Lesson` in it is collected.
    path : str
        The answers file to write.
    """
    from .exercises import Lesson

    found = [v for v in namespace.values() if isinstance(v, Lesson)]
    answers = {}
    if found:
        for q in found[0]:
            try:
                answers[q.name] = to_plain(q.answer) if q.answer is not ... else None
            except Exception:  # an answer that cannot be sent: graded as unsupported
                answers[q.name] = {"__unsupported__": type(q.answer).__name__}
    with open(path, "w", encoding="utf-8") as f:
        json.dump({"answers": answers}, f)


@dataclass
class NotebookGrade:
    """One learner's notebook: its score, a (question, status, message) row per question, and why not more.

    Parameters
    ----------
    notebook, learner, lesson : str
        The notebook's path, the learner's id, the lesson.
    results : list of (str, str, str)
        ``(question, status, message)`` per question.
    problem : str
        Why it got 0 or took too long ("" when all went well).
    cell_errors : list of str
        The cells that raised (information only).
    """

    notebook: str
    learner: str
    lesson: str
    results: list = field(default_factory=list)
    problem: str = ""
    cell_errors: list = field(default_factory=list)

    @property
    def score(self) -> int:
        """How many questions are Correct.

        Returns
        -------
        int
        """
        return sum(1 for _, status, _ in self.results if status == "Correct")

    def line(self) -> str:
        """One line for the grader's log: notebook, learner, lesson, score and any problem.

        Returns
        -------
        str
        """
        total = len(self.results)
        head = f"{self.notebook}: learner {self.learner!r}, lesson {self.lesson}: {self.score} of {total} correct"
        return head + (f" ({self.problem})" if self.problem else "")


def grade_one(
    notebook: str | os.PathLike,
    lesson: str,
    learner: str,
    secret: bytes | None,
    *,
    timeout_s: int = 120,
    memory_mb: int = 3000,
    run_as: str | None = None,
) -> NotebookGrade:
    """Run one submitted notebook in its own process and grade its answers in this one.

    With ``secret`` None the notebook is checked against the self-study variant of ``learner``
    (whose answers the learner's own kernel also holds): a practice check, not a grade.

    Parameters
    ----------
    notebook : path
        The learner's ``.ipynb``; it runs in a scratch copy of its own.
    lesson : str
        The lesson, ``"03"`` or ``3``.
    learner : str
        The learner's id (trimmed and lower-cased when graded with a secret).
    secret : bytes or None
        The class secret (:func:`read_secret`), or None for a self-study check.
    timeout_s : int
        Seconds the notebook may run.
    memory_mb : int
        The kernel's memory limit, MB.
    run_as : str, optional
        The user the kernel runs as (default: ``nobody`` when the grader is root, else the
        grader's own user); the kernel runs in a bubblewrap box when bubblewrap works here.

    Returns
    -------
    NotebookGrade
        A (question, status, message) row per question; a notebook that crashed, hung or wrote
        no answers gets 0 with the reason in ``problem``.

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    GradingError
        For a learner id or a ``run_as`` user that cannot be used.
    """
    from . import exercises

    number = exercises.lesson_number(lesson)
    learner = normalize_learner(learner) if secret is not None else str(learner or "").strip()
    notebook = Path(notebook)
    grade = NotebookGrade(str(notebook), learner, number)
    # the key: built here, never written anywhere
    questions = (
        graded_questions(number, learner, secret) if secret is not None else exercises.build_questions(number, learner)
    )
    grade.results = [(q.name, "Not attempted", "no answer") for q in questions]
    plan = sandbox_plan(run_as)
    try:
        inputs_json = json.dumps(inputs_record(number, learner, secret)) if secret is not None else None
        env = {"FIDLEARN_LEARNER": learner} if secret is None and learner else None  # for an empty LEARNER
        t0 = time.monotonic()
        raw, grade.cell_errors = run_notebook(notebook, inputs_json, plan, timeout_s, memory_mb, env)
        answers = read_answers(raw, [q.name for q in questions])
        grade.results = [_judge(q, answers.get(q.name)) for q in questions]
        elapsed = time.monotonic() - t0
        if elapsed > timeout_s + 30:
            grade.problem = f"it took {elapsed:.0f} s"
    except _Zero as exc:
        grade.problem = f"0: {exc}"
    return grade


def _judge(question, answer) -> tuple[str, str, str]:
    """Judge one answer in the grader's process: a bug in a learner's value can only make it wrong."""
    if answer is None:
        return (question.name, "Not attempted", "no answer")
    if isinstance(answer, _Unsupported):
        return (
            question.name,
            "Incorrect",
            f"an answer of type {answer.type_name} cannot be graded; give numbers, arrays or text",
        )
    try:
        r = question.grade(answer)
    except Exception as exc:  # noqa: BLE001 - an answer that breaks the checker is wrong, never fatal
        return (question.name, "Incorrect", f"the answer could not be checked ({type(exc).__name__})")
    return (r.question, r.status, r.message)


def grade(
    notebooks: Sequence[str | os.PathLike],
    lesson: str,
    secret_path: str | os.PathLike,
    csv_path,
    *,
    learner: str | None = None,
    timeout_s: int = 120,
    memory_mb: int = 3000,
    run_as: str | None = None,
    progress=None,
) -> list[NotebookGrade]:
    """Grade a batch; the CSV (one row per question) is written whatever happens to any notebook.

    Parameters
    ----------
    notebooks : sequence of str or os.PathLike
        The submitted notebooks.
    lesson : str or int
        Their lesson.
    secret_path : str or os.PathLike
        The class secret's file.
    csv_path : str or os.PathLike
        The CSV to write.
    learner : str, optional
        One learner id for every notebook; default: each notebook's file name.
    timeout_s, memory_mb, run_as
        As for :func:`grade_one`.
    progress : callable, optional
        ``progress(done, total, grade)`` after each notebook.

    Returns
    -------
    list of NotebookGrade

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    GradingError
        For a secret that cannot be read, or a ``run_as`` user who cannot run fidlearn.
    """
    from . import exercises

    secret = read_secret(secret_path)
    number = exercises.lesson_number(lesson)
    sandbox_plan(run_as)  # a user who cannot run this Python is refused before any notebook runs
    grades: list[NotebookGrade] = []
    try:
        for k, nb in enumerate(notebooks):
            who = learner if learner is not None else learner_from_filename(nb)
            try:
                g = grade_one(nb, number, who, secret, timeout_s=timeout_s, memory_mb=memory_mb, run_as=run_as)
            except FidlearnError as exc:
                g = NotebookGrade(str(nb), who, number, [], f"0: {exc}")
            grades.append(g)
            if progress is not None:
                progress(k + 1, len(notebooks), g)
    finally:
        _write_csv(csv_path, grades)
    return grades


def _write_csv(path, grades: list[NotebookGrade]) -> None:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["notebook", "learner", "lesson", "score", "question", "status", "message", "problem"])
    for g in grades:
        if not g.results:
            w.writerow([g.notebook, g.learner, g.lesson, 0, "", "", "", g.problem])
        for q, status, message in g.results:
            w.writerow([g.notebook, g.learner, g.lesson, g.score, q, status, message, g.problem])
    write_text_atomic(path, buf.getvalue())
