"""The class grader: :func:`release`, :func:`grade` and :func:`grade_one` (see :mod:`fidlearn.grading`)."""

from __future__ import annotations

import csv
import io
import json
import os
import time
from collections.abc import Sequence
from pathlib import Path

from .._io import write_text_atomic
from .._plain import _Unsupported, to_plain
from ..data import repo_dir
from ..errors import FidlearnError
from . import _gradebook, _learners, _release
from ._grade import Grade
from ._learners import normalize_learner, read_secret, variant_seed
from ._sandbox import (
    ANSWERS_FILE,
    _Zero,
    read_answers,
    run_notebook,
    sandbox_plan,
)


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
    from .. import exercises

    number = exercises.lesson_number(lesson)
    return list(
        exercises.build_questions(
            number,
            normalize_learner(learner),
            seed=lambda q: variant_seed(secret, number, normalize_learner(learner), q),
        )
    )


def inputs_record(lesson: str, learner: str, secret: bytes) -> dict:
    """What ``fidlearn_inputs.json`` holds for one learner: the lesson, the id, every question's inputs.

    Parameters
    ----------
    lesson, learner, secret
        As for :func:`graded_questions` (which also says what it raises).

    Returns
    -------
    dict
        ``{"fidlearn_graded": 1, "lesson", "learner", "questions": {name: {input: plain data}},
        "about": {name: {"title", "task", "level", "hints"}}}``; no answers, no solutions.
    """
    from .. import exercises

    number = exercises.lesson_number(lesson)
    learner = normalize_learner(learner)
    return _release.inputs_record(number, learner, graded_questions(number, learner, secret))


def release(
    lesson: str, learners: Sequence[str], secret_path: str | os.PathLike, out_dir: str | os.PathLike
) -> list[Path]:
    """Write ``OUT/<learner>/`` for each learner: the lesson's student notebook and its inputs file.

    Every folder is built in a temporary sibling of ``OUT`` and renamed into place at the end: a
    release that fails (a full disk, Ctrl-C) leaves nothing, and nothing is written outside ``OUT``.

    Parameters
    ----------
    lesson : str or int
        The lesson.
    learners : sequence of str
        The learners' ids (the roster's lines; see :func:`normalize_learner`).
    secret_path : str or os.PathLike
        The class secret's file.
    out_dir : str or os.PathLike
        The folder to create (its parent must exist; an existing one must be empty).

    Returns
    -------
    list of pathlib.Path
        One folder per learner, named by their id.

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    GradingError
        For a missing secret or parent folder, an unusable learner id, two lines that are one
        learner (both named), an output folder that is not empty, or a disk that refuses.
    """
    from .. import exercises

    number = exercises.lesson_number(lesson)
    notebook = repo_dir() / "notebooks" / "exercises" / exercises.notebook_name(number)
    return _release.release(
        number,
        learners,
        secret_path,
        out_dir,
        build=graded_questions,
        notebook=notebook if notebook.is_file() else None,
    )


# ------------------------------------------------------------------------------------------------
# grading: one notebook per process, answers as plain data
# ------------------------------------------------------------------------------------------------


def collect(namespace: dict, path: str = ANSWERS_FILE) -> None:
    """Write the answers of the graded lesson found in ``namespace`` as plain data (the appended cell).

    Runs in the learner's kernel, so the grader trusts nothing it writes beyond its form.

    Parameters
    ----------
    namespace : dict
        The notebook's globals; the first lesson (:class:`~fidlearn.exercises.GradedLesson` or
        :class:`~fidlearn.exercises.Lesson`) in it is collected.
    path : str
        The answers file to write.
    """
    from ..exercises import GradedLesson, Lesson

    found = [v for v in namespace.values() if isinstance(v, (GradedLesson, Lesson))]
    answers = {}
    if found:
        for q in found[0]:
            try:
                answers[q.name] = to_plain(q.answer) if q.answer is not ... else None
            except Exception:  # an answer that cannot be sent: graded as unsupported
                answers[q.name] = {"__unsupported__": type(q.answer).__name__}
    with open(path, "w", encoding="utf-8") as f:
        json.dump({"answers": answers}, f)


def grade_one(
    notebook: str | os.PathLike,
    lesson: str,
    learner: str,
    secret: bytes | None,
    *,
    timeout_s: int = 120,
    memory_mb: int = 3000,
    run_as: str | None = None,
) -> Grade:
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
    Grade
        A :class:`~fidlearn.exercises.Result` per question; a notebook that crashed, hung or wrote
        no answers gets 0 with the reason in ``problem``.

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    GradingError
        For a learner id or a ``run_as`` user that cannot be used.
    """
    from .. import exercises
    from ..exercises import NOT_ATTEMPTED, Result

    number = exercises.lesson_number(lesson)
    learner = normalize_learner(learner) if secret is not None else str(learner or "").strip()
    notebook = Path(notebook)
    grade = Grade(str(notebook), learner, number)
    # the key: built here, never written anywhere
    questions = (
        graded_questions(number, learner, secret) if secret is not None else exercises.build_questions(number, learner)
    )
    grade.results = [Result(q.name, NOT_ATTEMPTED, "no answer") for q in questions]
    plan = sandbox_plan(run_as)
    try:
        inputs_json = json.dumps(inputs_record(number, learner, secret)) if secret is not None else None
        env = {"FIDLEARN_LEARNER": learner} if secret is None and learner else None  # for an empty LEARNER
        t0 = time.monotonic()
        raw, grade.cell_errors = run_notebook(notebook, inputs_json, plan, timeout_s, memory_mb, env=env)
        answers = read_answers(raw, [q.name for q in questions])
        grade.results = [_judge(q, answers.get(q.name)) for q in questions]
        elapsed = time.monotonic() - t0
        if elapsed > timeout_s + 30:
            grade.problem = f"it took {elapsed:.0f} s"
    except _Zero as exc:
        grade.problem = f"0: {exc}"
    return grade


def _judge(question, answer):
    """Judge one answer in the grader's process: a bug in a learner's value can only make it wrong."""
    from ..exercises import INCORRECT, NOT_ATTEMPTED, Result

    if answer is None:
        return Result(question.name, NOT_ATTEMPTED, "no answer")
    if isinstance(answer, _Unsupported):
        return Result(
            question.name,
            INCORRECT,
            f"an answer of type {answer.type_name} cannot be graded; give numbers, arrays or text",
        )
    try:
        r = question.grade(answer)
    except Exception as exc:  # noqa: BLE001 - an answer that breaks the checker is wrong, never fatal
        return Result(question.name, INCORRECT, f"the answer could not be checked ({type(exc).__name__})")
    return r


def grade(
    notebooks: Sequence[str | os.PathLike],
    lesson: str,
    secret_path: str | os.PathLike,
    csv_path,
    *,
    learner: str | None = None,
    roster: Sequence[str] | None = None,
    formats: Sequence[str] = (),
    timeout_s: int = 120,
    memory_mb: int = 3000,
    run_as: str | None = None,
    progress=None,
) -> list[Grade]:
    """Grade a batch; the CSV (one row per question) is written once the whole batch is graded.

    Each notebook is matched to its learner by the id its metadata carries (written by
    :func:`release`), else ``learner``, else its file name. A notebook released to another
    learner, for another lesson, of a learner not on the roster, or of a learner already graded
    in this batch is not run: its row says why. With a roster, its learners who handed in
    nothing get a row too. Whatever happens to a notebook, the batch goes on; an interrupted
    batch (Ctrl-C, SIGTERM) writes nothing.

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
        One learner id for every notebook; default: each notebook's metadata, else its file name.
    roster : sequence of str, optional
        The roster's lines (the file ``release`` used).
    formats : sequence of str
        Gradebook imports to write besides the CSV: ``"canvas"`` (``grades.canvas.csv``),
        ``"moodle"`` (``grades.moodle.csv``).
    timeout_s, memory_mb, run_as
        As for :func:`grade_one`.
    progress : callable, optional
        ``progress(done, total, grade)`` after each notebook.

    Returns
    -------
    list of Grade
        One per notebook given, then one per roster learner who handed in nothing.

    Raises
    ------
    ExerciseError
        For an unknown lesson.
    GradingError
        For a secret that cannot be read, a roster or ``learner`` that cannot be used, or a
        ``run_as`` user who cannot run fidlearn.
    """
    from .. import exercises

    secret = read_secret(secret_path)
    number = exercises.lesson_number(lesson)
    ids = _learners.read_roster(list(roster), "the roster") if roster is not None else None
    matched = _gradebook.match(notebooks, number, learner, ids, secret)
    sandbox_plan(run_as)  # a user who cannot run this Python is refused before any notebook runs
    grades: list[Grade] = []
    for k, (nb, who, problem) in enumerate(matched):
        if problem:
            g = Grade(str(nb), who, number, [], problem, graded=False)
        else:
            try:
                g = grade_one(nb, number, who, secret, timeout_s=timeout_s, memory_mb=memory_mb, run_as=run_as)
            except FidlearnError as exc:
                g = Grade(str(nb), who, number, [], f"0: {exc}")
        grades.append(g)
        if progress is not None:
            progress(k + 1, len(matched), g)
    for who in _gradebook.missing(matched, ids):
        grades.append(Grade("", who, number, [], "missing: no notebook was handed in", graded=False))
    _write_all(csv_path, grades, number, [f for f in formats if f != "csv"])
    return grades


def _write_all(csv_path, grades: list[Grade], number: str, formats: list[str]) -> None:
    """The CSV and the gradebook imports, each atomically; all of them or (on a failure) none."""
    from .. import exercises

    out_of = len(exercises.build_questions(number, "")) if formats else 0
    scores = {g.learner: g.score if g.graded else None for g in grades if g.graded or g.notebook == ""}
    written: list[Path] = []
    try:
        _write_csv(csv_path, grades)
        written.append(Path(csv_path))
        for fmt in formats:
            written.append(_gradebook.write_lms(_gradebook.lms_path(csv_path, fmt), fmt, number, scores, out_of))
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        raise


def _write_csv(path, grades: list[Grade]) -> None:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["notebook", "learner", "lesson", "score", "question", "status", "message", "problem"])
    for g in grades:
        score = g.score if g.graded else ""
        if not g.results:
            w.writerow([g.notebook, g.learner, g.lesson, 0 if g.graded else "", "", "", "", g.problem])
        for r in g.results:
            w.writerow([g.notebook, g.learner, g.lesson, score, r.question, r.status, r.message, g.problem])
    write_text_atomic(path, buf.getvalue())
