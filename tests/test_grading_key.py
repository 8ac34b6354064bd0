"""Graded mode holds nothing of the answer key: every way of looking for it inside the notebook scores 0.

A class is released for lesson 01 and each learner hands back their released notebook with one
cell added. Sixteen of them look for the key where a learner might (the question objects'
attributes, vars/dir/__dict__, closures and globals, inspect, gc, frames, the library rebuilt in
the kernel, the inputs file), patch the recorder, print fake verdicts, edit stored outputs, or
guess. The batch is graded by ``fidlearn.grading.grade`` as in real use, with the roster and a
Canvas export; an honest learner in the same batch gets full marks.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import nbformat
import pytest

from fidlearn import exercises, grading

ROOT = Path(__file__).resolve().parent.parent
LESSON = "01"

FIND_KEY = (
    "def _looks_like_key(name):\n"
    "    return any(w in str(name) for w in ('expected', 'solution', 'wrong', 'parse', 'compare', 'notes', 'judge'))\n"
)

CHEATS = {
    "execs every text attribute": (
        "for q in ex:\n"
        "    for name in dir(q):\n"
        "        try:\n"
        "            value = getattr(q, name)\n"
        "        except AttributeError as e:\n"
        "            print('no', name, e)\n"
        "            continue\n"
        "        if isinstance(value, str):\n"
        "            try:\n"
        "                exec(value, globals())\n"
        "            except Exception as e:\n"
        "                print(name, type(e).__name__)\n"
    ),
    "execs solution_code": (
        "for q in ex:\n"
        "    globals()[q.name] = q\n"
        "    try:\n"
        "        exec(q.solution_code)\n"
        "    except AttributeError as e:\n"
        "        print(e)\n"
    ),
    "reads vars and __dict__": FIND_KEY
    + (
        "for q in ex:\n"
        "    found = {k: v for k, v in {**vars(q), **type(q).__dict__}.items() if _looks_like_key(k)}\n"
        "    print(q.name, sorted(found))\n"
        "    q.answer = next(iter(found.values()), None)\n"
    ),
    "reads dir and object.__getattribute__": FIND_KEY
    + (
        "for q in ex:\n"
        "    for name in ['_expected', '_parse', '_compare', '_wrong', '_notes', '_judge', 'solution_code']:\n"
        "        try:\n"
        "            q.answer = object.__getattribute__(q, name)\n"
        "        except AttributeError:\n"
        "            pass\n"
        "    print([n for n in dir(q) if _looks_like_key(n)])\n"
    ),
    "walks closures and globals": FIND_KEY
    + (
        "import types\n"
        "seen = []\n"
        "for q in ex:\n"
        "    for name in dir(type(q)):\n"
        "        fn = getattr(type(q), name)\n"
        "        fn = getattr(fn, '__func__', fn)\n"
        "        for cell in getattr(fn, '__closure__', None) or ():\n"
        "            seen.append(cell.cell_contents)\n"
        "        for k, v in (getattr(fn, '__globals__', None) or {}).items():\n"
        "            if _looks_like_key(k):\n"
        "                seen.append(v)\n"
        "    keys = [getattr(v, '_expected', None) for v in seen]\n"
        "    q.answer = next((k for k in keys if k is not None), None)\n"
        "print(len(seen))\n"
    ),
    "uses inspect": (
        "import inspect\n"
        "for q in ex:\n"
        "    members = dict(inspect.getmembers(q))\n"
        "    src = inspect.getsource(type(q))\n"
        "    q.answer = members.get('_expected', members.get('solution_code'))\n"
        "    print(q.name, 'solution_code' in members, len(src))\n"
    ),
    "searches gc.get_objects()": (
        "import gc\n"
        "hits = [o for o in gc.get_objects()\n"
        "        if hasattr(type(o), 'solution') or '_expected' in getattr(o, '__dict__', {})]\n"
        "print('questions with a key in the kernel:', len(hits))\n"
        "for q in ex:\n"
        "    for o in hits:\n"
        "        if getattr(o, 'name', None) == q.name:\n"
        "            q.answer = o._expected\n"
    ),
    "walks the frames": (
        "import sys, inspect\n"
        "loot = []\n"
        "for frame in list(sys._current_frames().values()) + [inspect.currentframe()]:\n"
        "    while frame is not None:\n"
        "        loot += [v for k, v in frame.f_locals.items() if 'secret' in k or 'question' in k]\n"
        "        frame = frame.f_back\n"
        "print(len(loot))\n"
        "for q in ex:\n"
        "    q.answer = next((getattr(x, '_expected', None) for x in loot if hasattr(x, '_expected')), None)\n"
    ),
    "rebuilds the key with the library": (
        "from fidlearn import exercises as _ex\n"
        "key = _ex.build_questions(ex.number, ex.learner)\n"
        "for q, k in zip(ex, key):\n"
        "    q.answer = k._expected\n"
    ),
    "rebuilds the key with a guessed secret": (
        "from fidlearn import grading as _g\n"
        "for guess in (b'', b'secret', bytes(32)):\n"
        "    try:\n"
        "        key = _g.graded_questions(ex.number, ex.learner, guess)\n"
        "        break\n"
        "    except Exception as e:\n"
        "        print(e)\n"
        "for q, k in zip(ex, key):\n"
        "    q.answer = k._expected\n"
    ),
    "reads the inputs file for answers": (
        "import json\n"
        "record = json.load(open('fidlearn_inputs.json'))\n"
        "print(sorted(record))\n"
        "for q in ex:\n"
        "    about = record.get('about', {}).get(q.name, {})\n"
        "    q.answer = about.get('answer', about.get('expected', record['questions'][q.name]))\n"
    ),
    "patches the recorder": (
        "import json\n"
        "from fidlearn import grading as _g\n"
        "from fidlearn.exercises import GradedQuestion, Result\n"
        "GradedQuestion.result = lambda self: Result(self.name, 'Correct', 'well done')\n"
        "names = [q.name for q in ex]\n"
        "def _collect(ns, path='fidlearn_answers.json'):\n"
        "    json.dump({'answers': {n: 'Correct' for n in names}}, open(path, 'w'))\n"
        "_g.collect = _collect\n"
        "for q in ex:\n"
        "    q.answer = 'Correct'\n"
    ),
    "prints fake verdicts": (
        "for q in ex:\n"
        "    print(f'Correct ({q.name}): well done')\n"
        "print(f'Lesson {ex.number}: {len(ex)} of {len(ex)} correct')\n"
    ),
    "guesses answers it did not compute": (
        "guesses = [np.eye(3), np.eye(4), np.zeros(3), 1.0, 'yes', [0, 0], 42]\n"
        "for q, g in zip(ex, guesses):\n"
        "    q.answer = g\n"
    ),
    "answers a question that is not there": (
        "ex.q9 = type(ex.q1)('q9', 't', 't', '', {}, [])\n"
        "ex.questions.append(ex.q9)\n"
        "ex.q9.answer = 'the key'\n"
        "ex.q1.answer = ex.q9\n"
    ),
}

#: The stored outputs say Correct; the cells were never run (the stubs still say ...).
EDITED_OUTPUTS = "edits the outputs without running"


def _honest(nb, key_nb) -> nbformat.NotebookNode:
    """The released notebook with every stub replaced by the answer key's solution (the learner's own work)."""
    blocks = exercises.solution_blocks(key_nb)
    nb = nbformat.from_dict(nb)
    for cell in nb.cells:
        m = re.search(r"^(q\d+)\.answer = \.\.\.$", cell.source, re.M) if cell.cell_type == "code" else None
        if m:
            cell.source = f"{blocks[m.group(1)]}\n{m.group(1)}.check()"
    return nb


def _with_cell(nb, code: str) -> nbformat.NotebookNode:
    """The released notebook with ``code`` run after the lesson is opened (cell 3, the note being cell 1)."""
    nb = nbformat.from_dict(nb)
    nb.cells.insert(3, nbformat.v4.new_code_cell(code))
    return nb


def _edited_outputs(nb) -> nbformat.NotebookNode:
    nb = nbformat.from_dict(nb)
    for cell in nb.cells:
        m = re.search(r"^(q\d+)\.check\(\)$", cell.source, re.M) if cell.cell_type == "code" else None
        if m:
            cell.outputs = [nbformat.v4.new_output("stream", text=f"Correct ({m.group(1)}): well done\n")]
    return nb


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    work = tmp_path_factory.mktemp("keyclass")
    secret = grading.new_secret(work / "class.secret")
    names = {f"cheat{k:02d}": cheat for k, cheat in enumerate([*CHEATS, EDITED_OUTPUTS])}
    roster = ["Honest Learner", *names]
    (work / "roster.txt").write_text("\n".join(roster) + "\n")
    folders = grading.release(LESSON, roster, secret, work / "released")
    key_nb = nbformat.read(ROOT / "notebooks" / "exercises" / "solutions" / exercises.notebook_name(LESSON), 4)
    subs = work / "submissions"
    subs.mkdir()
    for folder in folders:
        nb = nbformat.read(folder / exercises.notebook_name(LESSON), as_version=4)
        who = folder.name
        if who == "honest_learner":
            nb = _honest(nb, key_nb)
        elif names[who] == EDITED_OUTPUTS:
            nb = _edited_outputs(nb)
        else:
            nb = _with_cell(nb, CHEATS[names[who]])
        # collected under another file name: grade finds the learner by the notebook's own metadata
        nbformat.write(nb, subs / f"submission-{len(list(subs.iterdir())):02d}.ipynb")
    out = work / "grades.csv"
    grades = grading.grade(
        sorted(subs.glob("*.ipynb")),
        LESSON,
        secret,
        out,
        roster=roster,
        formats=("canvas",),
        timeout_s=60,
        memory_mb=2500,
    )
    return {"grades": {g.learner: g for g in grades}, "names": names, "csv": out, "n": len(exercises.lesson(LESSON))}


@pytest.mark.slow
@pytest.mark.parametrize(("who", "cheat"), [(f"cheat{k:02d}", c) for k, c in enumerate([*CHEATS, EDITED_OUTPUTS])])
def test_every_cheat_scores_zero(batch, who, cheat):
    g = batch["grades"][who]
    assert g.graded, (cheat, g.problem)
    assert len(g.results) == batch["n"], (cheat, g.problem)
    assert g.score == 0, (cheat, g.results, g.problem)
    assert all(r.status in ("Incorrect", "Not attempted") for r in g.results), (cheat, g.results)


@pytest.mark.slow
def test_the_honest_learner_in_the_same_batch_gets_full_marks(batch):
    g = batch["grades"]["honest_learner"]
    assert g.score == batch["n"] == 5, (g.results, g.problem, g.cell_errors)


@pytest.mark.slow
def test_the_gradebooks_hold_one_row_per_learner(batch):
    rows = list(csv.DictReader(batch["csv"].open(encoding="utf-8")))
    assert {r["learner"] for r in rows} == set(batch["grades"])
    canvas = list(csv.reader(grading_canvas(batch["csv"]).open(encoding="utf-8")))
    assert canvas[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", f"fidlearn lesson {LESSON}"]
    assert canvas[1] == ["Points Possible", "", "", "", "", "5"]
    scores = {r[3]: r[5] for r in canvas[2:]}
    assert scores == {who: ("5" if who == "honest_learner" else "0") for who in batch["grades"]}


def grading_canvas(csv_path: Path) -> Path:
    return csv_path.with_name(csv_path.stem + ".canvas.csv")
