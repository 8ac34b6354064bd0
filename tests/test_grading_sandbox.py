"""The grading sandbox against hostile notebooks: each cheat scores 0, the batch completes, the honest keep 5/5.

A class of lesson 03 with two honest learners (the answer key's notebook) and one small notebook per
attack: a saboteur that leaves a daemon killing every process it can, forged answers (an empty
``__detection__``, an array of shape ``[1e400]``), a notebook nested 200,000 levels deep, a flood
of stderr, a huge file, a fork bomb, a connection to a listener this test opens on 127.0.0.1,
reading the secret, another learner's submission and the grader's environment, an endless loop,
eating memory. Graded as the tests run (root in CI: notebooks as nobody in bubblewrap), with no
``--run-as``; then twice more at once, by two grader processes, in other orders.
"""

from __future__ import annotations

import csv
import json
import os
import pwd
import random
import re
import resource
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import nbformat
import pytest
from helpers import as_unprivileged, python_paths

from fidlearn import grading
from fidlearn.grading import _box, _sandbox

ROOT = Path(__file__).resolve().parent.parent
KEY = ROOT / "notebooks" / "exercises" / "solutions" / "03_extrinsics.ipynb"
STUDENT = ROOT / "notebooks" / "exercises" / "03_extrinsics.ipynb"
TOKEN = secrets.token_hex(8)


@pytest.fixture(scope="module")
def needs_box():
    """Skip where bubblewrap is missing or cannot make a sandbox (the grader then falls back and warns)."""
    bwrap = _box.bwrap_path()
    if bwrap is None or _sandbox._check(_sandbox.Plan("", _sandbox._run_as(None)[1], bwrap)):
        pytest.skip("bubblewrap is not installed or cannot make a sandbox here")


CRAFTED = (
    "from fidlearn import grading as _g\n"
    "def _forge(ns, path='fidlearn_answers.json'):\n"
    "    open(path, 'w').write({text!r})\n"
    "_g.collect = _forge\n"
)

CHEATS = {
    "saboteur": (
        "import subprocess\n"
        "subprocess.Popen(['/bin/sh', '-c', 'while :; do kill -9 -1; sleep 0.1; done', 'saboteur-' + TOKEN],\n"
        "                 start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)\n"
    ),
    "empty detection": CRAFTED.format(text='{"answers": {"q1": {"__detection__": []}}}'),
    "shape 1e400": CRAFTED.format(text='{"answers": {"q1": {"__array__": "", "dtype": "<f8", "shape": [1e400]}}}'),
    "nested executed notebook": "open('executed.ipynb', 'w').write('[' * 200000 + ']' * 200000)\n",
    "stderr flood": "import os\nchunk = b'x' * (1 << 20)\nfor _ in range(1024):\n    os.write(2, chunk)\n",
    "huge file": (
        "written = 0\ntry:\n    with open('big.bin', 'wb') as f:\n        for _ in range(2048):\n"
        "            written += f.write(b'\\0' * (1 << 20))\n"
        "except OSError as e:\n    raise RuntimeError(f'wrote {written >> 20} MB') from e\n"
    ),
    "fork bomb": (
        "import os, time\nkids = 0\ntry:\n    while kids < 5000:\n        if os.fork() == 0:\n"
        "            time.sleep(300)\n            os._exit(0)\n        kids += 1\n"
        "except OSError:\n    raise RuntimeError(f'forks refused after {kids}')\n"
    ),
    "connects": "import socket\nsocket.create_connection(('127.0.0.1', PORT), timeout=5)\n",
    "reads": (
        "import glob, os\nfound = []\n"
        "for path in [SECRET, *glob.glob(SUBMISSIONS + '/*')]:\n"
        "    try:\n        open(path, 'rb').read(); found.append(path)\n    except OSError:\n        pass\n"
        "for path in glob.glob('/proc/*/environ'):\n"
        "    try:\n        if TOKEN.encode() in open(path, 'rb').read(): found.append(path)\n"
        "    except OSError:\n        pass\n"
        "raise RuntimeError(f'found {len(found)}: {found[:3]}')\n"
    ),
    "loops forever": "while True:\n    pass\n",
    "eats the memory": "hog = []\nwhile True:\n    hog.append(bytearray(10**8))\n",
}
HONEST = ("honest.one", "honest.two")
SCORES = {**{f"cheat{k:02d}": 0 for k in range(len(CHEATS) + 1)}, **{h: 5 for h in HONEST}}


@pytest.fixture(scope="module")
def klass(tmp_path_factory, needs_box):  # noqa: ARG001 (a fixture's fixture: skips when there is no box)
    """The class folder: secret, submissions (the nested one written raw), a listener on 127.0.0.1."""
    work = tmp_path_factory.mktemp("class")
    secret = grading.new_secret(work / "class.secret")
    subs = work / "submissions"
    subs.mkdir()
    listener = socket.create_server(("127.0.0.1", 0))
    listener.settimeout(0.1)
    port = listener.getsockname()[1]
    pre = f"SECRET = {str(secret)!r}\nSUBMISSIONS = {str(subs)!r}\nTOKEN = {TOKEN!r}\nPORT = {port}\n"
    for k, code in enumerate(CHEATS.values()):
        nb = nbformat.read(STUDENT, as_version=4)
        nb.cells.append(nbformat.v4.new_code_cell(pre + code))
        nbformat.write(nb, subs / f"cheat{k:02d}.ipynb")
    nested = subs / f"cheat{len(CHEATS):02d}.ipynb"  # the submission itself nested 200,000 levels deep
    text = (subs / "cheat00.ipynb").read_text()
    nested.write_text(text.replace('"metadata": {', '"metadata": {"x": ' + "[" * 200000 + "]" * 200000 + ",", 1))
    for who in HONEST:
        shutil.copyfile(KEY, subs / f"{who}.ipynb")
    os.environ["FIDLEARN_TEST_MARK"] = TOKEN  # in the grader's environment only
    try:
        yield {"work": work, "secret": secret, "subs": subs, "listener": listener}
    finally:
        os.environ.pop("FIDLEARN_TEST_MARK", None)
        listener.close()


def _order(subs: Path, seed: int | None) -> list[Path]:
    """The saboteur first and the honest right after it (seed None), or a shuffle of the class."""
    names = sorted(p.name for p in subs.glob("*.ipynb"))
    if seed is None:
        first = ["cheat00.ipynb", *(f"{h}.ipynb" for h in HONEST)]
        names = first + [n for n in names if n not in first]
    else:
        random.Random(seed).shuffle(names)
    return [subs / n for n in names]


@pytest.fixture(scope="module")
def graded(klass):
    before = {p.name: p.read_bytes() for p in klass["subs"].iterdir()}
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    out = klass["work"] / "grades.csv"
    grades = grading.grade(_order(klass["subs"], None), "03", klass["secret"], out, timeout_s=20, memory_mb=1500)
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - peak) / 1024
    try:
        klass["listener"].accept()
        accepted = True
    except OSError:
        accepted = False
    return {
        "grades": {Path(g.notebook).stem: g for g in grades},
        "csv": out,
        "before": before,
        "grown_mb": grown_mb,
        "accepted": accepted,
    }


def _cheat(graded, name: str):
    return graded["grades"][f"cheat{list(CHEATS).index(name):02d}"]


@pytest.mark.slow
def test_every_cheat_scores_zero_and_the_honest_keep_their_marks(graded):
    scores = {k: g.score for k, g in graded["grades"].items()}
    assert scores == SCORES, {k: (g.problem, g.cell_errors[-1:]) for k, g in graded["grades"].items()}
    rows = list(csv.DictReader(graded["csv"].open()))
    assert {r["learner"]: int(r["score"]) for r in rows} == SCORES


@pytest.mark.slow
def test_each_cheat_is_stopped_by_its_own_limit(graded):
    assert "__detection__ is [id, corners]" in _cheat(graded, "empty detection").problem
    assert "not finite" in _cheat(graded, "shape 1e400").problem
    assert "RecursionError" in graded["grades"][f"cheat{len(CHEATS):02d}"].problem
    assert "a cell ran longer than 20 s" in _cheat(graded, "loops forever").problem
    huge = " ".join(_cheat(graded, "huge file").cell_errors)
    assert f"wrote {_box.MAX_FILE_BYTES >> 20} MB" in huge, huge
    forks = " ".join(_cheat(graded, "fork bomb").cell_errors)
    kids = int(forks.split("forks refused after ")[1].split()[0].rstrip(":"))
    assert 0 < kids < _box.MAX_PROCESSES, forks
    assert "ConnectionRefusedError" in " ".join(_cheat(graded, "connects").cell_errors)
    assert not graded["accepted"]
    assert "found 0: []" in " ".join(_cheat(graded, "reads").cell_errors)
    memory = _cheat(graded, "eats the memory")
    assert "MemoryError" in " ".join(memory.cell_errors) or "kernel died" in memory.problem


@pytest.mark.slow
def test_nothing_outlives_its_notebook_and_the_grader_stays_small(graded, klass):
    left = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            if f"saboteur-{TOKEN}".encode() in cmdline.read_bytes():
                left.append(cmdline.parent.name)
        except OSError:
            pass
    assert left == []
    assert graded["grown_mb"] < 100  # a gigabyte of stderr went through a bounded reader
    assert {p.name: p.read_bytes() for p in klass["subs"].iterdir()} == graded["before"]


@pytest.mark.slow
@pytest.mark.usefixtures("graded")
def test_two_graders_at_once_in_other_orders_give_the_same_grades(klass, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    runs = []
    for seed in (1, 2):
        out = tmp_path / f"grades{seed}.csv"
        cmd = [sys.executable, "-m", "fidlearn", "grade", *map(str, _order(klass["subs"], seed))]
        cmd += ["--lesson", "03", "--secret-file", str(klass["secret"]), "-o", str(out), "--timeout", "20"]
        cmd += ["--memory-mb", "1500"]
        runs.append((subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE), out))
    for proc, out in runs:
        _, err = proc.communicate(timeout=1500)
        assert proc.returncode == 0, err[-2000:]
        assert b"warning" not in err
        rows = list(csv.DictReader(out.open()))
        assert {r["learner"]: int(r["score"]) for r in rows} == SCORES


def _grade_cli(tmp_path, *extra, path=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    if path is not None:
        env["PATH"] = path
    secret = tmp_path / "class.secret"
    if not secret.exists():
        grading.new_secret(secret)
    cmd = [sys.executable, "-m", "fidlearn", "grade", str(KEY), "--lesson", "03", "--learner", "alice"]
    cmd += ["--secret-file", str(secret), "-o", str(tmp_path / "g.csv"), *extra]
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("user", ["", "no-such-user-fidlearn"])
def test_run_as_nobody_in_particular_or_an_unknown_user_is_refused(tmp_path, user):
    out = _grade_cli(tmp_path, "--run-as", user)
    assert out.returncode == 2
    assert len(out.stderr.strip().splitlines()) == 1
    assert out.stderr.startswith("error: --run-as")
    assert not (tmp_path / "g.csv").exists()


@pytest.mark.slow
@pytest.mark.skipif(os.geteuid() != 0, reason="--run-as root needs the grader to be root")
def test_run_as_root_grades_and_warns_in_one_line(tmp_path):
    out = _grade_cli(tmp_path, "--run-as", "root")
    assert out.returncode == 0, out.stderr
    warnings = [ln for ln in out.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1
    assert "can read the class secret" in warnings[0]
    assert {int(r["score"]) for r in csv.DictReader((tmp_path / "g.csv").open())} == {5}


@pytest.mark.slow
@pytest.mark.skipif(os.geteuid() != 0, reason="as root, notebooks run as nobody: this checks nobody's Python")
def test_without_bubblewrap_the_grader_says_who_cannot_run_what(tmp_path):
    closed = _sandbox._closed_folder(os.path.realpath(sys.executable), (65534, 65534))
    out = _grade_cli(tmp_path, path=str(tmp_path / "no-bin"))  # bwrap is not on this PATH
    if closed:  # a Python nobody cannot reach (pyenv under /root): one line naming user, path and fix
        assert out.returncode == 2
        assert len(out.stderr.strip().splitlines()) == 1
        assert out.stderr.startswith(f"error: the user nobody cannot run {sys.executable} (")
        assert closed in out.stderr
        assert "apt-get install bubblewrap" in out.stderr
        assert not (tmp_path / "g.csv").exists()
    else:  # a Python for everyone: graded without a box, and said so
        assert out.returncode == 0
        assert "warning: bubblewrap is not installed" in out.stderr


def test_answers_are_read_with_strict_bounds():
    names = ["q1", "q2"]
    ok = b'{"answers": {"q1": {"__array__": "AAAAAAAA8D8=", "dtype": "<f8", "shape": [1]}, "q2": 2}}'
    assert _sandbox.read_answers(ok, names)["q1"].tolist() == [1.0]
    bad = {
        b'{"answers": {"q1": {"__detection__": []}}}': "__detection__ is [id, corners]",
        b'{"answers": {"q1": {"__array__": "", "dtype": "<f8", "shape": [1e400]}}}': "not finite",
        b'{"answers": {"q1": {"__array__": "", "dtype": "<f8", "shape": [1.0]}}}': "whole numbers",
        b'{"answers": {"q1": {"__array__": "", "dtype": "<f8", "shape": [-1]}}}': "whole numbers",
        b'{"answers": {"q1": NaN}}': "NaN is not a number",
        b'{"answers": {"q9": 1}}': "questions this lesson does not have: q9",
        b'{"answers": {}, "more": 1}': "not an answers record",
        b'{"answers": {"q1": ' + b"[" * 200000 + b"]" * 200000 + b"}}": "nested too deeply",
        b'{"answers": {"q1": ' + b"9" * 100 + b"}}": "more than 40 digits",
        b"\xff": "can't decode",
        b" " * (_sandbox.MAX_ANSWERS_BYTES + 1): "larger than 5 MB",
    }
    for data, why in bad.items():
        with pytest.raises(_sandbox._Zero, match=re.escape(why)):
            _sandbox.read_answers(data, names)


@pytest.mark.slow
@pytest.mark.skipif(as_unprivileged(0, 0, []) is None, reason="needs root, bubblewrap and setpriv to become nobody")
def test_an_ordinary_user_grades_in_a_box_that_hides_their_own_secret():
    """Graded by an ordinary user (nobody here), notebooks run as that user yet see neither secret nor class."""
    nobody = pwd.getpwnam("nobody")
    work = Path(tempfile.mkdtemp(prefix="fidlearn-user-class-"))
    try:
        subs = work / "submissions"
        subs.mkdir()
        secret = grading.new_secret(work / "class.secret")
        shutil.copyfile(KEY, subs / "honest.ipynb")
        nb = nbformat.read(STUDENT, as_version=4)
        pre = f"SECRET = {str(secret)!r}\nSUBMISSIONS = {str(subs)!r}\nTOKEN = {TOKEN!r}\n"
        nb.cells.append(nbformat.v4.new_code_cell(pre + CHEATS["reads"]))
        nbformat.write(nb, subs / "reader.ipynb")
        for p in (work, subs, secret, *subs.iterdir()):
            os.chown(p, nobody.pw_uid, nobody.pw_gid)
        script = (
            "import json, sys\nfrom fidlearn import grading\n"
            f"gs = grading.grade(sorted(__import__('glob').glob({str(subs)!r} + '/*.ipynb')), '03', "
            f"{str(secret)!r}, {str(work / 'g.csv')!r}, timeout_s=60)\n"
            "print(json.dumps({g.learner: [g.score, g.cell_errors[-1:], g.problem] for g in gs}))\n"
        )
        cmd = as_unprivileged(nobody.pw_uid, nobody.pw_gid, python_paths())
        cmd += ["env", f"PYTHONPATH={ROOT}", f"HOME={work}", f"FIDLEARN_TEST_MARK={TOKEN}"]
        cmd += [sys.executable, "-c", script]
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=900, cwd=work)
        assert out.returncode == 0, out.stderr[-2000:]
        got = json.loads(out.stdout.strip().splitlines()[-1])
        assert got["honest"][0] == 5, got
        assert got["reader"][0] == 0, got
        assert "found 0: []" in got["reader"][1][0], got
    finally:
        shutil.rmtree(work, ignore_errors=True)
