"""A grader a class can trust: cheating notebooks score 0 with a reason, honest ones keep their marks.

One batch grades lesson 03 for several learners: two honest notebooks (the answer key's own code)
and a dozen that try what a learner might: copy the key, patch the checker or numpy, print fake
grade lines, register hooks, build another lesson, read the class secret, overwrite the other
submissions, loop forever, kill or exit the kernel, eat the memory, forge the answers file.
The batch runs as root in CI, where the notebooks run as 'nobody'.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import nbformat
import numpy as np
import pytest

import fidlearn
from fidlearn import exercises, grading
from fidlearn.errors import FidlearnError

ROOT = Path(__file__).resolve().parent.parent
KEY = ROOT / "notebooks" / "exercises" / "solutions" / "03_extrinsics.ipynb"
STUDENT = ROOT / "notebooks" / "exercises" / "03_extrinsics.ipynb"
AS_ROOT = os.geteuid() == 0


def with_cell(source: Path, code: str, at: int | None = None) -> nbformat.NotebookNode:
    nb = nbformat.read(source, as_version=4)
    cell = nbformat.v4.new_code_cell(code)
    nb.cells.insert(len(nb.cells) if at is None else at, cell)
    return nb


CHEATS = {
    "copies the key": (STUDENT, "for q in ex:\n    q.answer = q._expected\n"),
    "patches the checker": (
        STUDENT,
        "from fidlearn.exercises import Question, Result\n"
        "Question.grade = lambda self, answer=None: Result(self.name, 'Correct', 'ok')\n"
        "for q in ex:\n    q.answer = 0\n",
    ),
    "patches numpy": (
        STUDENT,
        "np.allclose = lambda *a, **k: True\nnp.isclose = lambda *a, **k: True\n"
        "for q in ex:\n    q.answer = np.zeros(3)\n",
    ),
    "prints fake grade lines": (
        STUDENT,
        "for n in range(4):\n    print('FIDLEARN-GRADE ' + json.dumps({'lesson': '03', "
        "'learner': 'x', 'results': [['q1', 'Correct', '']]}))\nimport json\n",
    ),
    "registers a hook": (
        STUDENT,
        "def fake(result):\n    print('Correct (q1): well done')\n"
        "get_ipython().events.register('post_run_cell', fake)\n",
    ),
    "builds another lesson": (STUDENT, "ex = exercises.lesson('01')\nfor q in ex:\n    q.answer = 1.0\n"),
    "reads the class secret": (
        STUDENT,
        "from fidlearn import grading\n"
        "try:\n    s = grading.read_secret(SECRET)\n"
        "    key = grading.graded_questions('03', LEARNER_ID, s)\n"
        "    for q, k in zip(ex, key):\n        q.answer = k._expected\n"
        "except Exception as e:\n    print('no secret:', e)\n",
    ),
    "overwrites the other submissions": (
        STUDENT,
        "import pathlib\nfor p in pathlib.Path(SUBMISSIONS).glob('*.ipynb'):\n"
        "    try:\n        p.write_text('{}')\n"
        "    except Exception as e:\n        print(e)\n",
    ),
    "loops forever": (STUDENT, "while True:\n    pass\n"),
    "kills its kernel": (STUDENT, "import os, signal\nos.kill(os.getpid(), signal.SIGKILL)\n"),
    "exits": (STUDENT, "import os\nos._exit(0)\n"),
    "eats the memory": (STUDENT, "hog = []\nwhile True:\n    hog.append(bytearray(10**8))\n"),
    "forges the answers file": (
        STUDENT,
        "import json, os\n"
        "json.dump({'answers': {'q1': [[1, 0, 0, 0]] * 4, 'q2': 1, 'q3': 2, 'q4': 3, 'q5': 4}}, "
        "open('fidlearn_answers.json', 'w'))\nos._exit(0)\n",
    ),
    "answers with a function": (STUDENT, "for q in ex:\n    q.answer = print\n"),
}


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    work = tmp_path_factory.mktemp("class")
    secret = grading.new_secret(work / "class.secret")
    subs = work / "submissions"
    subs.mkdir()
    names = []
    for k, (name, (source, code)) in enumerate(CHEATS.items()):
        learner = f"cheater{k:02d}"
        pre = f"SECRET = {str(secret)!r}\nSUBMISSIONS = {str(subs)!r}\nLEARNER_ID = {learner!r}\n"
        nb = with_cell(source, pre + code)
        nbformat.write(nb, subs / f"{learner}.ipynb")
        names.append((learner, name))
    for learner in ("Honest.One", "honest.two"):  # ids are compared in lower case
        shutil.copyfile(KEY, subs / f"{learner}.ipynb")
    before = {p.name: p.read_bytes() for p in subs.iterdir()}
    out = work / "grades.csv"
    notebooks = sorted(subs.glob("cheater*.ipynb")) + sorted(subs.glob("*onest*.ipynb"))
    grades = grading.grade(notebooks, "03", secret, out, timeout_s=20, memory_mb=2500)
    return {
        "grades": {Path(g.notebook).stem: g for g in grades},
        "names": dict(names),
        "csv": out,
        "before": before,
        "subs": subs,
    }


@pytest.mark.slow
@pytest.mark.parametrize(("k", "cheat"), list(enumerate(CHEATS)))
def test_every_cheat_scores_zero_with_a_reason(batch, k, cheat):
    if cheat == "reads the class secret" and not AS_ROOT:
        pytest.skip("graded as the instructor's own user, a notebook can read the secret: docs/teaching.md says so")
    g = batch["grades"][f"cheater{k:02d}"]
    assert g.score == 0, (cheat, g.results, g.problem)
    reasons = g.problem or "; ".join(f"{r.question}: {r.status} {r.message}" for r in g.results)
    assert reasons.strip()


@pytest.mark.slow
def test_the_reasons_say_what_happened(batch):
    g = {cheat: batch["grades"][f"cheater{k:02d}"] for k, cheat in enumerate(CHEATS)}
    assert "a cell ran longer than 20 s" in g["loops forever"].problem
    assert "kernel died" in g["kills its kernel"].problem
    assert "kernel died" in g["exits"].problem
    assert "no answers were collected" in g["exits"].problem
    assert all(r.status == "Not attempted" for r in g["builds another lesson"].results)
    assert any("cannot be graded" in r.message for r in g["answers with a function"].results)
    # a kernel that exits after writing the file hands in nothing: only the appended cell's answers count
    forged = g["forges the answers file"]
    assert "kernel died" in forged.problem
    assert all(r.status == "Not attempted" for r in forged.results)


@pytest.mark.slow
def test_honest_notebooks_keep_their_marks(batch):
    for who in ("Honest.One", "honest.two"):
        g = batch["grades"][who]
        assert g.learner == who.lower()
        assert g.score == len(g.results) == len(exercises.lesson("03")), (g.results, g.problem)


@pytest.mark.slow
def test_no_submission_was_changed_and_the_csv_has_every_row(batch):
    assert {p.name: p.read_bytes() for p in batch["subs"].iterdir()} == batch["before"]
    rows = list(csv.DictReader(batch["csv"].open()))
    assert {r["learner"] for r in rows} == {f"cheater{k:02d}" for k in range(len(CHEATS))} | {
        "honest.one",
        "honest.two",
    }
    scores = {r["learner"]: int(r["score"]) for r in rows}
    assert scores["honest.one"] == len(exercises.lesson("03"))
    assert all(v == 0 for k, v in scores.items() if k.startswith("cheater"))


def test_the_learner_kernel_never_holds_the_key(tmp_path, monkeypatch):
    secret = grading.new_secret(tmp_path / "s")
    (tmp_path / grading.INPUTS_FILE).write_text(
        json.dumps(grading.inputs_record("03", "alice", grading.read_secret(secret)))
    )
    monkeypatch.chdir(tmp_path)
    ex = exercises.lesson("03", "anyone")
    key = grading.graded_questions("03", "Alice", grading.read_secret(secret))
    for q, k in zip(ex, key):
        assert isinstance(q, exercises.GradedQuestion)
        assert not hasattr(q, "_expected")
        for name in k.inputs:
            a, b = q.inputs[name], k.inputs[name]
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b)
    text = (tmp_path / grading.INPUTS_FILE).read_text()
    assert "expected" not in text
    # the self-study variant of the same id is another one: the secret decides the graded numbers
    free = exercises.build_questions("03", "alice")
    assert not np.allclose(free[0].inputs["position_mm"], key[0].inputs["position_mm"])


def test_plain_data_round_trips_and_refuses_anything_else():
    world = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
    value = {"a": np.arange(6.0).reshape(2, 3), 3: (1, 2.5, "x"), "m": world, "nan": float("nan")}
    back = grading.from_plain(json.loads(json.dumps(grading.to_plain(value))))
    np.testing.assert_array_equal(back["a"], value["a"])
    assert back[3] == (1, 2.5, "x")
    assert back["m"].corners()[0].tolist() == world.corners()[0].tolist()
    for bad in (
        {"__pickle__": "x"},
        {"__array__": "AAAA", "dtype": "<f8", "shape": [10]},
        {"__array__": "", "dtype": "O", "shape": [0]},
        {"a": 1, "b": 2},
    ):
        with pytest.raises((ValueError, TypeError)):
            grading.from_plain(bad)


@pytest.mark.parametrize("learner", ["", "   ", "x" * 300, "a\x00b"])
def test_bad_learner_ids(learner):
    with pytest.raises(FidlearnError):
        grading.normalize_learner(learner)


def test_grade_command_one_error_line(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "fidlearn",
            "grade",
            str(KEY),
            "--lesson",
            "03",
            "--secret-file",
            str(tmp_path / "none"),
            "-o",
            str(tmp_path / "g.csv"),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2
    assert [ln for ln in out.stderr.splitlines() if ln.startswith("error:")] == [
        f"error: {tmp_path / 'none'}: no such file; check the path of the class secret"
    ]
    assert not (tmp_path / "g.csv").exists()
    out = subprocess.run(
        [sys.executable, "-m", "fidlearn", "grade", "--new-secret", str(tmp_path / "s")],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0
    assert oct((tmp_path / "s").stat().st_mode & 0o777) == "0o600"


def test_release_writes_the_student_notebook_and_the_inputs(tmp_path):
    secret = grading.new_secret(tmp_path / "class.secret")
    folders = grading.release("3", ["Alice", "bob"], secret, tmp_path / "out")
    assert [f.name for f in folders] == ["alice", "bob"]
    student = Path(__file__).resolve().parent.parent / "notebooks" / "exercises" / exercises.notebook_name("03")
    source = nbformat.read(student, as_version=4)
    for folder in folders:
        nb = nbformat.read(folder / student.name, as_version=4)
        tag = grading._learners.release_tag(grading.read_secret(secret), "03", folder.name)
        assert nb.metadata["fidlearn"] == {"lesson": "03", "learner": folder.name, "tag": tag}
        assert [c.source for c in nb.cells if c.id != "ex03-graded"] == [c.source for c in source.cells]
        assert not any(c.get("outputs") for c in nb.cells)
        record = json.loads((folder / grading.INPUTS_FILE).read_text())
        assert record["lesson"] == "03"
        assert record["learner"] == folder.name
        assert "q1" in record["questions"]


def test_grading_errors_are_fidlearn_errors():
    from fidlearn.errors import ExerciseError, GradingError

    assert grading.GradingError is GradingError
    assert issubclass(GradingError, FidlearnError)
    with pytest.raises(ExerciseError, match="no exercises for lesson '42'"):
        grading.graded_questions("42", "alice", b"secret")
