"""Grading a class: the answer key never enters a learner's kernel.

Self-study (``q.check()``, ``q.hint()``, ``q.solution()``) builds each question with its answer in
the learner's own Python, which is what practice needs and what a grade must not rely on: a
notebook could read ``q._expected``, patch the checker, print a fake result. Graded mode splits
the two sides:

* **release** (:func:`release`): the instructor's process builds each learner's questions from a
  class secret (HMAC-SHA256 of the secret, the lesson, the learner and the question seeds the
  numbers, so nobody without the secret can rebuild them from the open library) and writes only
  their *inputs*, as plain data, into ``fidlearn_inputs.json`` beside the learner's notebook.
  In a folder with that file, ``exercises.lesson(...)`` hands out questions without answers:
  ``check()`` only says whether an answer has the right form.
* **grade** (:func:`grade`): each submitted notebook runs in a process of its own, in a scratch
  copy of its folder, with a time limit, a memory limit, an environment without the
  instructor's variables and, when the grader runs as root, as an unprivileged user. A cell
  appended to it writes the learner's answers as plain data (numbers, arrays, text); the
  grader reads them (strict JSON, bounded), rebuilds the questions with their answers in its
  own process and judges there. Nothing printed, patched or written in the notebook can
  change a grade: a notebook that crashes, hangs, is killed or writes nonsense gets 0 with
  the reason, and every other notebook of the batch is still graded; the CSV is always written.
"""

from __future__ import annotations

import base64
import csv
import hashlib
import hmac
import io
import json
import math
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._io import write_text_atomic
from .errors import FidlearnError

#: The inputs file a released notebook works with.
INPUTS_FILE = "fidlearn_inputs.json"
#: What the appended collection cell writes in the scratch folder.
ANSWERS_FILE = "fidlearn_answers.json"
#: Largest answers file read (bytes): far above any honest set of answers.
MAX_ANSWERS_BYTES = 5_000_000
#: Deepest nesting of an answer.
MAX_DEPTH = 32


class GradingError(FidlearnError):
    """A grading run cannot start: a missing secret, a bad roster, an unknown lesson."""


# ------------------------------------------------------------------------------------------------
# the class secret and the learners
# ------------------------------------------------------------------------------------------------
def normalize_learner(learner: str) -> str:
    """A learner id as graded: trimmed and lower-case ("Alice " and "alice" are one learner)."""
    if not isinstance(learner, str) or not learner.strip():
        raise GradingError(f"a learner id must be non-empty text, got {learner!r}")
    text = " ".join(learner.split()).lower()
    if len(text) > 200 or any(ord(c) < 32 for c in text):
        raise GradingError(f"learner id {learner[:40]!r} is too long or holds control characters")
    return text


def new_secret(path: str | os.PathLike) -> Path:
    """Write a new class secret (64 hex digits) to ``path``, readable by its owner only; refuses to overwrite."""
    path = Path(path)
    if path.exists():
        raise GradingError(f"{path} exists; a class keeps one secret for the whole course (delete it only on purpose)")
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(secrets.token_hex(32) + "\n")
    return path


def read_secret(path: str | os.PathLike) -> bytes:
    """The class secret from its file (made by :func:`new_secret`)."""
    from ._files import MAX_TEXT_BYTES, read_bytes

    path, data = read_bytes(path, GradingError, "class secret", MAX_TEXT_BYTES)
    text = data.decode("ascii", "replace").strip()
    if not re.fullmatch(r"[0-9a-f]{32,}", text):
        raise GradingError(f"{path}: not a class secret (64 hex digits, as 'fidlearn grade --new-secret' writes it)")
    return bytes.fromhex(text[: len(text) // 2 * 2])


def variant_seed(secret: bytes, lesson: str, learner: str, question: str) -> int:
    """The seed of one learner's numbers for one question: HMAC-SHA256 of the class secret."""
    digest = hmac.new(secret, f"fidlearn-graded/{lesson}/{learner}/{question}".encode(), hashlib.sha256).digest()
    return int.from_bytes(digest[:8], "little")


# ------------------------------------------------------------------------------------------------
# plain data: what crosses between the grader and a learner's kernel
# ------------------------------------------------------------------------------------------------
def to_plain(value: Any, depth: int = 0) -> Any:
    """``value`` as JSON-ready plain data, fidlearn's own types and arrays tagged."""
    from .camera import Camera
    from .detection import Detection
    from .markermap import MarkerMap

    if depth > MAX_DEPTH:
        raise ValueError("nested too deeply")
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else {"__float__": repr(v)}
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            return {"__unsupported__": f"array of {value.dtype}"}
        raw = np.ascontiguousarray(value)
        return {
            "__array__": base64.b64encode(raw.tobytes()).decode("ascii"),
            "dtype": raw.dtype.str,
            "shape": list(raw.shape),
        }
    if isinstance(value, tuple):
        return {"__tuple__": [to_plain(v, depth + 1) for v in value]}
    if isinstance(value, list):
        return [to_plain(v, depth + 1) for v in value]
    if isinstance(value, dict):
        return {"__dict__": [[to_plain(k, depth + 1), to_plain(v, depth + 1)] for k, v in value.items()]}
    if isinstance(value, Camera):
        return {"__camera__": value.to_dict()}
    if isinstance(value, MarkerMap):
        return {"__map__": value.to_dict()}
    if isinstance(value, Detection):
        return {"__detection__": [int(value.id), to_plain(np.asarray(value.corners, dtype=float))]}
    return {"__unsupported__": type(value).__name__}


_ARRAY_KINDS = {"b", "i", "u", "f"}


def from_plain(value: Any, depth: int = 0) -> Any:
    """The inverse of :func:`to_plain`; anything else (an unknown tag) raises ``ValueError``."""
    from .camera import Camera
    from .detection import Detection
    from .markermap import MarkerMap

    if depth > MAX_DEPTH:
        raise ValueError("nested too deeply")
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        return [from_plain(v, depth + 1) for v in value]
    if not isinstance(value, dict) or len(value) not in (1, 3):
        raise ValueError("not plain data")
    if "__array__" in value:
        dtype = np.dtype(str(value["dtype"]))
        shape = tuple(int(n) for n in value["shape"])
        if (
            dtype.kind not in _ARRAY_KINDS
            or len(shape) > 8
            or any(n < 0 for n in shape)
            or math.prod(shape) > 50_000_000
        ):
            raise ValueError("not an array fidlearn reads")
        raw = base64.b64decode(value["__array__"], validate=True)
        if len(raw) != math.prod(shape) * dtype.itemsize:
            raise ValueError("array size does not match its shape")
        return np.frombuffer(raw, dtype=dtype).reshape(shape).copy()
    ((tag, body),) = value.items()
    if tag == "__float__":
        return float(body) if body in ("nan", "inf", "-inf") else _bad(tag)
    if tag == "__tuple__":
        return tuple(from_plain(v, depth + 1) for v in body)
    if tag == "__dict__":
        out = {}
        for item in body:
            k = from_plain(item[0], depth + 1)
            out[k if not isinstance(k, list) else tuple(k)] = from_plain(item[1], depth + 1)
        return out
    if tag == "__camera__":
        return Camera.from_dict(body, source="an answer")
    if tag == "__map__":
        return MarkerMap.from_dict(body, source="an answer")
    if tag == "__detection__":
        return Detection(int(body[0]), from_plain(body[1], depth + 1))
    if tag == "__unsupported__":
        return _Unsupported(str(body)[:80])
    return _bad(tag)


def _bad(tag: str):
    raise ValueError(f"unknown tag {tag[:40]!r}")


@dataclass(frozen=True)
class _Unsupported:
    """An answer of a type that cannot be sent as plain data (a function, an open file...)."""

    type_name: str


# ------------------------------------------------------------------------------------------------
# release: the learner's inputs, without answers
# ------------------------------------------------------------------------------------------------
def graded_questions(lesson: str, learner: str, secret: bytes) -> list:
    """The questions of ``lesson`` for ``learner`` built from the class secret (with their answers)."""
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
    """What ``fidlearn_inputs.json`` holds for one learner: the lesson, the id and every question's inputs."""
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
    """Write ``OUT/<learner>/`` for each learner: the lesson's student notebook and its inputs file."""
    from . import exercises

    secret = read_secret(secret_path)
    number = exercises.lesson_number(lesson)
    out = Path(out_dir)
    if not out.parent.is_dir():
        raise GradingError(f"{out}: the folder {out.parent} does not exist; create it first")
    ids = [normalize_learner(x) for x in learners]
    if len(set(ids)) != len(ids):
        raise GradingError("a learner is listed twice (ids are compared trimmed and in lower case)")
    notebook = (
        Path(exercises.__file__).resolve().parent.parent / "notebooks" / "exercises" / exercises.notebook_name(number)
    )
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
COLLECT_CELL = (
    "import json as _fl_json, os as _fl_os\n"
    "from fidlearn import grading as _fl_grading\n"
    "_fl_grading.collect(globals())\n"
)


def collect(namespace: dict, path: str = ANSWERS_FILE) -> None:
    """Write the answers of the graded lesson found in ``namespace`` as plain data (the appended cell).

    Runs in the learner's kernel, so the grader trusts nothing it writes beyond its form.
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
    """One learner's notebook: its score, a (question, status, message) row per question, and why not more."""

    notebook: str
    learner: str
    lesson: str
    results: list = field(default_factory=list)
    problem: str = ""
    cell_errors: list = field(default_factory=list)

    @property
    def score(self) -> int:
        return sum(1 for _, status, _ in self.results if status == "Correct")

    def line(self) -> str:
        total = len(self.results)
        head = f"{self.notebook}: learner {self.learner!r}, lesson {self.lesson}: {self.score} of {total} correct"
        return head + (f" ({self.problem})" if self.problem else "")


def _run_as(user: str | None):
    """(uid, gid) to run kernels as: the named user, or 'nobody' when the grader is root; None otherwise
    (and for ``""``: the grader's own user, as a self-study check does)."""
    if user == "" or (os.geteuid() != 0 and user is None):
        return None
    import pwd

    name = user or "nobody"
    try:
        entry = pwd.getpwnam(name)
    except KeyError:
        raise GradingError(f"--run-as {name}: no such user; create one (useradd --system {name})") from None
    if os.geteuid() != 0 and entry.pw_uid != os.geteuid():
        raise GradingError(f"--run-as {name} needs the grader to run as root")
    return entry.pw_uid, entry.pw_gid


def _limits(memory_mb: int, ids):
    def apply() -> None:
        import resource

        os.setsid()
        limit = memory_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        if ids is not None:
            os.setgroups([])
            os.setgid(ids[1])
            os.setuid(ids[0])

    return apply


#: The program a notebook runs under, in its own process: execute it, keep going after errors.
_RUNNER = r"""
import sys, nbformat
from nbclient import NotebookClient
nb = nbformat.read(sys.argv[1], as_version=4)
nb.cells.append(nbformat.v4.new_code_cell(sys.argv[3]))
client = NotebookClient(nb, timeout=int(sys.argv[2]), kernel_name="python3", allow_errors=True,
                        resources={"metadata": {"path": "."}})
try:
    client.execute()
    nbformat.write(nb, "executed.ipynb")
except Exception as exc:
    kind = type(exc).__name__
    print("FIDLEARN-RUNNER " + ("timeout" if "Timeout" in kind else "dead" if "Dead" in kind else kind), file=sys.stderr)
    sys.exit(3)
"""


def _clean_env(home: Path) -> dict:
    """The kernel's whole environment: nothing of the instructor's (tokens, paths, FIDLEARN_*)."""
    env = {
        "PATH": os.defpath,
        "HOME": str(home),
        "LANG": "C.UTF-8",
        "PYTHONDONTWRITEBYTECODE": "1",
        "MPLBACKEND": "Agg",
        "JUPYTER_RUNTIME_DIR": str(home / ".runtime"),
        "JUPYTER_CONFIG_DIR": str(home / ".jupyter"),
        "IPYTHONDIR": str(home / ".ipython"),
    }
    here = str(Path(__file__).resolve().parent.parent)
    env["PYTHONPATH"] = here  # fidlearn itself, wherever it was installed from
    return env


def _read_answers(path: Path) -> dict:
    from ._files import read_bytes

    _, data = read_bytes(path, GradingError, "answers", MAX_ANSWERS_BYTES)
    record = json.loads(data.decode("utf-8"))
    if not isinstance(record, dict) or not isinstance(record.get("answers"), dict):
        raise ValueError("not an answers record")
    return {str(k): v for k, v in record["answers"].items()}


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
    ids = _run_as(run_as)
    scratch = Path(tempfile.mkdtemp(prefix="fidlearn-grade-"))
    try:
        work, home = scratch / "work", scratch / "home"
        work.mkdir()
        home.mkdir()
        try:
            shutil.copyfile(notebook, work / "submission.ipynb")
        except OSError as exc:
            grade.problem = f"0: the notebook cannot be read ({exc.strerror})"
            return grade
        if secret is not None:
            (work / INPUTS_FILE).write_text(json.dumps(inputs_record(number, learner, secret)), encoding="utf-8")
        if ids is not None:
            for p in (scratch, work, home, *work.iterdir()):
                os.chown(p, *ids)
        cmd = [sys.executable, "-c", _RUNNER, "submission.ipynb", str(max(5, timeout_s)), COLLECT_CELL]
        env = _clean_env(home)
        if secret is None and learner:
            env["FIDLEARN_LEARNER"] = learner  # a self-study notebook whose LEARNER is empty uses it
        t0 = time.monotonic()
        try:
            proc = subprocess.Popen(
                cmd,
                cwd=work,
                env=env,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                preexec_fn=_limits(memory_mb, ids),
            )
            try:
                _, err = proc.communicate(timeout=timeout_s + 60)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.communicate()
                grade.problem = f"0: the notebook ran longer than {timeout_s} s and was stopped"
                return grade
        finally:
            _kill_group_leftovers(locals().get("proc"))
        answers_path = work / ANSWERS_FILE
        if not answers_path.is_file() or answers_path.is_symlink():
            said = [ln for ln in err.decode("utf-8", "replace").splitlines() if ln.startswith("FIDLEARN-RUNNER ")]
            kind = said[-1].split(" ", 1)[1] if said else ""
            why = {
                "timeout": f"a cell ran longer than {timeout_s} s and was stopped",
                "dead": "its kernel died (it used more than the memory limit, or killed or exited itself)",
            }.get(kind, f"it stopped before its answers were collected ({kind or 'no reason given'})")
            grade.problem = f"0: {why}; no answers were collected"
            return grade
        try:
            raw = _read_answers(answers_path)
            answers = {name: from_plain(value) for name, value in raw.items()}
        except (ValueError, TypeError, KeyError, RecursionError, FidlearnError) as exc:
            grade.problem = f"0: its answers are not plain data ({str(exc)[:80]})"
            return grade
        grade.results = [_judge(q, answers.get(q.name)) for q in questions]
        grade.cell_errors = _cell_errors(work / "executed.ipynb")
        elapsed = time.monotonic() - t0
        if elapsed > timeout_s + 30:
            grade.problem = f"it took {elapsed:.0f} s"
        return grade
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _preflight(ids, run_as: str | None) -> None:
    """The notebooks' user must be able to run this Python and import fidlearn and nbclient."""
    if ids is None:
        return
    home = Path(tempfile.mkdtemp(prefix="fidlearn-grade-check-"))
    try:
        os.chown(home, *ids)
        out = subprocess.run(
            [sys.executable, "-c", "import fidlearn, nbclient, ipykernel"],
            cwd=home,
            env=_clean_env(home),
            capture_output=True,
            text=True,
            timeout=120,
            preexec_fn=_limits(4000, ids),
        )
    finally:
        shutil.rmtree(home, ignore_errors=True)
    if out.returncode != 0:
        who = run_as or "nobody"
        last = (out.stderr.strip().splitlines() or ["it exited with status %d" % out.returncode])[-1]
        raise GradingError(
            f"the user {who} cannot run {sys.executable} with fidlearn ({last[:120]}); install "
            "Python and fidlearn where that user can read them (see docs/teaching.md), or pass "
            "--run-as a user who can"
        )


def _cell_errors(path: Path) -> list[str]:
    """``cell N raised NAME: VALUE`` for each failing cell of the executed notebook (information only)."""
    try:
        if not path.is_file() or path.is_symlink() or path.stat().st_size > 50_000_000:
            return []
        nb = json.loads(path.read_text(encoding="utf-8"))
        out = []
        for i, cell in enumerate(nb.get("cells", [])[:-1]):
            for o in cell.get("outputs", []) or []:
                if isinstance(o, dict) and o.get("output_type") == "error":
                    out.append(f"cell {i} raised {str(o.get('ename'))[:60]}: {str(o.get('evalue'))[:120]}")
        return out[:50]
    except (OSError, ValueError, AttributeError):
        return []


def _kill_group_leftovers(proc) -> None:
    if proc is not None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # a kernel left running by a notebook that detached it
        except (ProcessLookupError, PermissionError, OSError):
            pass


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


def learner_from_filename(path: str | os.PathLike) -> str:
    """``submissions/Alice.Smith.ipynb`` -> ``alice.smith``: the file's name without ``.ipynb``."""
    name = Path(path).name
    return normalize_learner(name[: -len(".ipynb")] if name.lower().endswith(".ipynb") else Path(path).stem)


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
    """Grade a batch; the CSV (one row per question) is written whatever happens to any notebook."""
    from . import exercises

    secret = read_secret(secret_path)
    number = exercises.lesson_number(lesson)
    _preflight(_run_as(run_as), run_as)  # a user who cannot run this Python is refused before any notebook runs
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
