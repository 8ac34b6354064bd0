"""One safe id per learner, release that writes whole folders or nothing, grade matched by the roster.

These tests run no notebook: where grading is needed, ``grade_one`` is replaced by a recorder that
gives each learner a known score, so what is checked is which notebook is graded as whom, the
rows of the CSV and of the gradebook imports, and what a full disk or a signal leaves behind.
"""

from __future__ import annotations

import csv
import errno
import io
import json
import re
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import nbformat
import pytest

from fidlearn import exercises, grading
from fidlearn.cli import main
from fidlearn.errors import ExerciseError, FidlearnError, GradingError
from fidlearn.grading import _grader, _learners, _sandbox

LESSON = "01"


def run(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


# -- ids ------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("given", "learner"),
    [("  Carol   Smith ", "carol_smith"), ("carol_smith", "carol_smith"), ("Bob@Uni.EDU", "bob@uni.edu"),
     ("José", "josé"), ("x" * 64, "x" * 64)],
)  # fmt: skip
def test_one_normalization(given, learner):
    assert grading.normalize_learner(given) == learner


@pytest.mark.parametrize(
    ("bad", "why"),
    [("", "non-empty"), ("   ", "non-empty"), ("..", "dot"), (".", "dot"), (".hidden", "dot"),
     ("a/b", "path separator"), ("..\\x", "path separator"), ("alice?", "'?'"), ("a\x00b", "control"),
     ("a\tb", "control"), ("a\u200bb", "control"), ("x" * 65, "at most 64")],
)  # fmt: skip
def test_unsafe_ids_are_refused(bad, why):
    with pytest.raises(GradingError, match=re.escape(why)):
        grading.normalize_learner(bad)


def test_a_roster_with_two_lines_for_one_learner_names_both():
    with pytest.raises(GradingError, match=r"line 2 'a b' and line 4 'a_b' are one learner \('a_b'\)"):
        _learners.read_roster(["alice", "a b", "# comment", "a_b"], "roster.txt")
    with pytest.raises(GradingError, match=r"roster.txt, line 2: learner id '\.\.'"):
        _learners.read_roster(["alice", ".."], "roster.txt")
    long_a, long_b = "x" * 63 + "a", "x" * 63 + "b"  # equal in their first 63 characters, two learners
    assert _learners.read_roster([long_a, long_b], "r") == [long_a, long_b]


def test_a_roster_comment_may_follow_an_id_on_its_line():
    # the teaching guide says "# starts a comment": so it does at the end of a line too
    lines = ["alice  # absent in week 1", "Carol Smith# joined late", "  # only a comment", "bob"]
    assert _learners.read_roster(lines, "roster.txt") == ["alice", "carol_smith", "bob"]
    with pytest.raises(GradingError, match=r"roster.txt: no learner ids"):
        _learners.read_roster(["# nobody yet", "   #"], "roster.txt")


def test_lesson_numbers_are_ascii_digits_only():
    assert exercises.lesson_number(" 1 ") == exercises.lesson_number("01") == "01"
    for bad in ("\u0661", "\uff11", "1\u0660"):  # Arabic-Indic one, fullwidth one, 1 and Arabic-Indic zero
        with pytest.raises(ExerciseError, match="no exercises for lesson"):
            exercises.lesson_number(bad)


# -- release --------------------------------------------------------------------------------------
@pytest.fixture
def secret(tmp_path):
    return grading.new_secret(tmp_path / "class.secret")


def test_release_names_folders_by_id_and_writes_nothing_outside(tmp_path, secret):
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(GradingError, match="line 2"):
        grading.release(LESSON, ["alice", ".."], secret, tmp_path / "out")
    with pytest.raises(GradingError, match="are one learner"):
        grading.release(LESSON, ["a b", "a_b"], secret, tmp_path / "out")
    with pytest.raises(GradingError, match="holds '\\?'"):
        grading.release(LESSON, ["alice?", "alice_"], secret, tmp_path / "out")
    with pytest.raises(GradingError, match="path separator"):
        grading.release(LESSON, ["../escape"], secret, tmp_path / "out")
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no folder, no hidden temporary
    folders = grading.release(LESSON, ["Carol Smith", "bob"], secret, tmp_path / "out")
    assert [f.name for f in folders] == ["carol_smith", "bob"]
    record = json.loads((folders[0] / grading.INPUTS_FILE).read_text())
    assert record["learner"] == "carol_smith"
    assert record["lesson"] == LESSON
    nb = nbformat.read(folders[0] / exercises.notebook_name(LESSON), as_version=4)
    tag = _learners.release_tag(grading.read_secret(secret), LESSON, "carol_smith")
    assert nb.metadata["fidlearn"] == {"lesson": LESSON, "learner": "carol_smith", "tag": tag}
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, "out"])
    with pytest.raises(GradingError, match="not an empty folder"):
        grading.release(LESSON, ["dave"], secret, tmp_path / "out")


def test_the_inputs_file_holds_no_answer_and_the_seed_uses_the_id(secret):
    key = grading.read_secret(secret)
    record = grading.inputs_record(LESSON, "Carol  Smith", key)
    assert record == grading.inputs_record(LESSON, "carol_smith", key)
    questions = grading.graded_questions(LESSON, "carol_smith", key)
    text = json.dumps(record)
    assert "solution" not in text
    assert "expected" not in text
    assert all(q.solution_code not in text for q in questions)


@pytest.mark.parametrize("failure", [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt()])
def test_a_release_that_fails_leaves_nothing(tmp_path, secret, monkeypatch, failure):
    from fidlearn.grading import _release

    calls = []
    real = _release._write

    def write(path, text):
        calls.append(path)
        if len(calls) == 3:  # the second learner's inputs
            raise failure
        real(path, text)

    monkeypatch.setattr(_release, "_write", write)
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(GradingError if isinstance(failure, OSError) else KeyboardInterrupt) as info:
        grading.release(LESSON, ["alice", "bob", "carol"], secret, tmp_path / "out")
    if isinstance(failure, OSError):
        assert "No space left on device" in str(info.value)
        assert "nothing was written" in str(info.value)
    assert len(calls) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_new_secret_on_a_full_disk_leaves_no_file(tmp_path, monkeypatch):

    def full(_fd, _data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(_learners, "_write_all", full)
    code, out, err = run("grade", "--new-secret", tmp_path / "class.secret")
    assert code == 2
    assert err.startswith("error: ")
    assert err.count("\n") == 1
    assert "no secret was made" in err
    assert list(tmp_path.iterdir()) == []


def test_release_cli_names_the_roster_line(tmp_path, secret):
    roster = tmp_path / "roster.txt"
    roster.write_text("alice\n# a comment\nA  B\na_b\n")
    code, _, err = run("release", "--lesson", "1", "--secret-file", secret, "--learners", roster, "-o", tmp_path / "o")
    assert code == 2
    assert err.count("\n") == 1
    assert "line 3 'A B' and line 4 'a_b' are one learner" in err  # the error line merges blanks
    roster.write_text("alice\nbob/../../x\n")
    code, _, err = run("release", "--lesson", "1", "--secret-file", secret, "--learners", roster, "-o", tmp_path / "o")
    assert code == 2
    assert "line 2" in err
    assert "path separator" in err
    roster.write_text("alice\n")
    code, _, err = run(
        "release", "--lesson", "\u0661", "--secret-file", secret, "--learners", roster, "-o", tmp_path / "o"
    )
    assert code == 2
    assert "no exercises for lesson" in err
    assert not (tmp_path / "o").exists()
    code, out, _ = run("release", "--lesson", " 3", "--secret-file", secret, "--learners", roster, "-o", tmp_path / "o")
    assert code == 0
    assert "(lesson 03)" in out


_NO_BOX = _sandbox.Plan(user="nobody", ids=None, bwrap=None)


# -- grade: the roster, the metadata, the gradebooks ----------------------------------------------
@pytest.fixture
def cls(tmp_path, secret, monkeypatch):
    """A released class, its submissions under collected names, and grade_one replaced by a recorder."""
    folders = grading.release(LESSON, ["alice", "bob", "carol", "dave@uni.edu"], secret, tmp_path / "out")
    subs = tmp_path / "subs"
    subs.mkdir()
    name = exercises.notebook_name(LESSON)
    paths = {}
    for folder, as_name in zip(folders, ["bob.ipynb", "x1.ipynb", "carol.ipynb", "d.ipynb"]):
        paths[folder.name] = subs / as_name
        (subs / as_name).write_bytes((folder / name).read_bytes())
    graded = []

    def fake(nb, number, learner, _secret_bytes, **_kwargs):
        graded.append((Path(nb).name, learner))
        scores = {"alice": 5, "bob": 3, "dave@uni.edu": 1, "eve": 4}
        mark = {True: "Correct", False: "Incorrect"}
        results = [exercises.Result(f"q{i}", mark[i <= scores[learner]], "") for i in range(1, 6)]
        return grading.Grade(str(nb), learner, number, results)

    monkeypatch.setattr(_grader, "grade_one", fake)
    monkeypatch.setattr(_grader, "sandbox_plan", lambda _run_as=None: _NO_BOX)  # no notebook runs here
    return {"paths": paths, "subs": subs, "secret": secret, "graded": graded, "tmp": tmp_path}


def test_grade_matches_by_the_notebooks_id_and_reports_the_roster(cls):
    p = cls["paths"]
    eve = cls["subs"] / "eve.ipynb"  # alice's notebook with bob's id put in its metadata
    eve.write_bytes(p["alice"].read_bytes().replace(b'"learner": "alice"', b'"learner": "bob"'))
    nb = nbformat.read(p["alice"], as_version=4)
    del nb.metadata["fidlearn"]
    zed = cls["subs"] / "zed.ipynb"  # not made by release: its file name is its id
    nbformat.write(nb, zed)
    twice = cls["subs"] / "alice-again.ipynb"
    twice.write_bytes(p["alice"].read_bytes())
    roster = ["alice", "bob", "Carol", "dave@uni.edu", "frank"]
    out = cls["tmp"] / "grades.csv"
    grades = grading.grade(
        [p["alice"], p["bob"], twice, eve, zed, p["dave@uni.edu"]], LESSON, cls["secret"], out, roster=roster
    )
    # alice's notebook is called bob.ipynb and bob's x1.ipynb: each is graded as its own learner, once
    assert cls["graded"] == [("bob.ipynb", "alice"), ("x1.ipynb", "bob"), ("d.ipynb", "dave@uni.edu")]
    problems = {(Path(g.notebook).name if g.notebook else "", g.learner): g.problem for g in grades}
    assert "handed in twice; graded" in problems[("alice-again.ipynb", "alice")]
    assert "'zed' is not on the roster" in problems[("zed.ipynb", "zed")]
    assert "its learner id 'bob' was changed after release" in problems[("eve.ipynb", "bob")]
    assert problems[("", "carol")] == problems[("", "frank")] == "missing: no notebook was handed in"
    rows = list(csv.DictReader(out.open(encoding="utf-8")))
    scores = {(r["notebook"], r["learner"]): r["score"] for r in rows}
    assert scores[(str(p["alice"]), "alice")] == "5"
    assert scores[(str(twice), "alice")] == ""
    assert len([r for r in rows if r["learner"] == "alice" and r["score"] == "5"]) == 5  # one row per question


def test_a_notebook_is_never_graded_against_another_learners_variant(cls):
    p = cls["paths"]
    grades = grading.grade([p["alice"]], LESSON, cls["secret"], cls["tmp"] / "g.csv", learner="bob")
    assert cls["graded"] == []
    assert not grades[0].graded
    assert "released to learner 'alice', not 'bob'" in grades[0].problem
    grades = grading.grade([p["alice"]], "02", cls["secret"], cls["tmp"] / "g.csv")
    assert cls["graded"] == []
    assert "released for lesson 01, not 02" in grades[0].problem


def test_canvas_and_moodle_gradebooks(cls):
    p = cls["paths"]
    out = cls["tmp"] / "grades.csv"
    roster = ["alice", "bob", "carol", "dave@uni.edu"]
    grading.grade([p["bob"], p["alice"]], LESSON, cls["secret"], out, roster=roster, formats=("canvas", "moodle"))
    canvas = (cls["tmp"] / "grades.canvas.csv").read_text(encoding="utf-8")
    assert canvas.splitlines() == [
        "Student,ID,SIS User ID,SIS Login ID,Section,fidlearn lesson 01",
        "Points Possible,,,,,5",
        "bob,,,bob,,3",
        "alice,,,alice,,5",
        "carol,,,carol,,",
        "dave@uni.edu,,,dave@uni.edu,,",
    ]
    moodle = list(csv.reader((cls["tmp"] / "grades.moodle.csv").open(encoding="utf-8")))
    assert moodle == [
        ["ID number", "fidlearn lesson 01"],
        ["bob", "3"],
        ["alice", "5"],
        ["carol", ""],
        ["dave@uni.edu", ""],
    ]
    grading.grade([p["dave@uni.edu"]], LESSON, cls["secret"], out, formats=("moodle",))
    moodle = list(csv.reader((cls["tmp"] / "grades.moodle.csv").open(encoding="utf-8")))
    assert moodle == [["Email address", "fidlearn lesson 01"], ["dave@uni.edu", "1"]]


def test_the_grade_command_writes_the_canvas_file(cls):
    p = cls["paths"]
    roster = cls["tmp"] / "roster.txt"
    roster.write_text("alice\nbob\n")
    out = cls["tmp"] / "g.csv"
    code, text, err = run(
        "grade", p["alice"], p["bob"], "--lesson", "1", "--secret-file", cls["secret"], "-o", out,
        "--roster", roster, "--format", "canvas",
    )  # fmt: skip
    assert code == 0, err
    assert f"2 notebooks graded; grades in {out} and {cls['tmp'] / 'g.canvas.csv'}" in text
    assert (cls["tmp"] / "g.canvas.csv").read_text().splitlines()[2:] == ["alice,,,alice,,5", "bob,,,bob,,3"]


@pytest.mark.parametrize("failure", ["disk", "disk at the canvas file", "signal"])
def test_an_interrupted_or_refused_grade_writes_no_csv(cls, monkeypatch, failure):
    p = cls["paths"]
    out = cls["tmp"] / "grades.csv"
    if failure == "signal":
        real = _grader.grade_one

        def stop(nb, *a, **k):
            if cls["graded"]:
                raise KeyboardInterrupt
            return real(nb, *a, **k)

        monkeypatch.setattr(_grader, "grade_one", stop)
        with pytest.raises(KeyboardInterrupt):
            grading.grade([p["alice"], p["bob"]], LESSON, cls["secret"], out)
    else:
        real_write, writes = Path.write_text, []

        def full(self, *a, **k):
            writes.append(self)
            if failure == "disk" or len(writes) == 2:
                raise OSError(errno.ENOSPC, "No space left on device")
            return real_write(self, *a, **k)

        monkeypatch.setattr(Path, "write_text", full)
        with pytest.raises(FidlearnError, match="No space left on device"):
            grading.grade([p["alice"], p["bob"]], LESSON, cls["secret"], out, formats=("canvas",))
    assert not [q for q in cls["tmp"].iterdir() if q.suffix == ".csv" or q.name.startswith(".grades")]


# -- what the learner's kernel shows ---------------------------------------------------------------
def test_a_graded_lesson_records_and_says_so(tmp_path, secret, monkeypatch, capsys):
    folder = grading.release(LESSON, ["alice"], secret, tmp_path / "out")[0]
    monkeypatch.chdir(folder)
    ex = exercises.lesson(LESSON)
    assert isinstance(ex, exercises.GradedLesson)
    assert ex.learner == "alice"
    q = ex.q1
    for absent in ("solution", "solution_code", "_expected", "_parse", "_compare", "_wrong", "_notes", "_judge"):
        assert not hasattr(q, absent), absent
    q.check([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    ex.q2.check(print)
    ex.summary()
    text = capsys.readouterr().out
    assert "Recorded (q1): your answer is kept for your instructor" in text
    assert "Incorrect (q2): an answer of type builtin_function_or_method cannot be handed in" in text
    assert "Lesson 01 for learner 'alice' (graded): 1 of 5 answers recorded" in text
    assert "of 5 correct" not in text
    with pytest.raises(AttributeError, match="not in a graded lesson"):
        q.solution()
    with exercises.strict("correct"), pytest.raises(AssertionError, match="Not attempted"):
        ex.q3.check()


def test_self_study_keeps_checks_and_solutions(capsys):
    ex = exercises.lesson(LESSON, learner="alice")
    ex.q1.solution()
    ex.q1.check(0)
    ex.summary()
    text = capsys.readouterr().out
    assert "one way to do it" in text
    assert "Incorrect (q1)" in text
    assert "0 of 5 correct" in text


@pytest.mark.slow
def test_sigterm_during_release_leaves_nothing(tmp_path, secret):
    import os
    import signal
    import subprocess
    import sys
    import time

    roster = tmp_path / "roster.txt"
    roster.write_text("".join(f"learner{k:03d}\n" for k in range(400)))
    before = sorted(p.name for p in tmp_path.iterdir())
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent))
    cmd = [sys.executable, "-m", "fidlearn", "release", "--lesson", "1", "--secret-file", str(secret)]
    proc = subprocess.Popen(
        [*cmd, "--learners", str(roster), "-o", str(tmp_path / "out")],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(p.name.startswith(".out.") for p in tmp_path.iterdir()):
        time.sleep(0.05)
    time.sleep(0.5)  # some learners' folders are made
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert err == "error: interrupted by SIGTERM; nothing was written\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == before
