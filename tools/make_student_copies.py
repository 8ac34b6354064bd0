"""Build the exercise notebooks: answer keys from fidlearn.exercises, student copies from the keys.

One source, two copies. The answer keys ``notebooks/exercises/solutions/NN_topic.ipynb``
are written from the lesson definitions in ``fidlearn/exercises/lessons/`` (tasks, inputs and
the solution code that ``qN.solution()`` shows); each student copy
``notebooks/exercises/NN_topic.ipynb`` is the key with every block between
``### BEGIN SOLUTION`` and ``### END SOLUTION`` replaced by a stub
(``qN.answer = ...``), so its checks say ``Not attempted``. Both are executed so
that their stored outputs are real.

Usage::

    python tools/make_student_copies.py            # rebuild and execute every notebook
    python tools/make_student_copies.py 03 07      # only these lessons
    python tools/make_student_copies.py --check    # exit 1 if a stored notebook is stale
    python tools/make_student_copies.py --no-execute
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import nbformat

from fidlearn import exercises
from fidlearn.data import repo_dir
from fidlearn.io import write_text_atomic

EXERCISES_DIR = repo_dir() / "notebooks" / "exercises"
SOLUTIONS_DIR = EXERCISES_DIR / "solutions"


def sources(nb) -> list[tuple[str, str]]:
    """What a notebook says, without its outputs: (cell type, source) per cell."""
    return [(c.cell_type, c.source) for c in nb.cells]


def expected_notebooks(number: str):
    """The answer key and the student copy of a lesson, built in memory (not executed)."""
    key = exercises.answer_key_notebook(number)
    return key, exercises.student_copy(key)


def execute(nb, timeout: int = 120):
    """Run a notebook in a fresh kernel (the shared class variant: no learner id, no strict mode)."""
    from nbclient import NotebookClient

    env_backup = {k: os.environ.pop(k) for k in ("FIDLEARN_LEARNER", "FIDLEARN_STRICT") if k in os.environ}
    try:
        NotebookClient(
            nb, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": str(EXERCISES_DIR)}}
        ).execute()
    finally:
        os.environ.update(env_backup)
    for cell in nb.cells:
        cell.get("metadata", {}).pop("execution", None)
    return nb


def write(nb, path: Path) -> None:
    write_text_atomic(path, nbformat.writes(nb) + "\n")


def stale(numbers) -> list[str]:
    """Paths of stored notebooks whose sources differ from what the lessons give."""
    out = []
    for number in numbers:
        name = exercises.notebook_name(number)
        key, student = expected_notebooks(number)
        for nb, path in ((key, SOLUTIONS_DIR / name), (student, EXERCISES_DIR / name)):
            if not path.exists() or sources(nbformat.read(path, as_version=4)) != sources(nb):
                out.append(str(path.relative_to(repo_dir())))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("lessons", nargs="*", help="lesson numbers (default: all)")
    parser.add_argument("--check", action="store_true", help="only report stale notebooks; exit 1 if any")
    parser.add_argument("--no-execute", action="store_true", help="write the notebooks without outputs")
    args = parser.parse_args(argv)
    numbers = args.lessons or list(exercises.lessons())
    if args.check:
        bad = stale(numbers)
        for path in bad:
            print(f"stale: {path} (run python tools/make_student_copies.py)")
        return 1 if bad else 0
    for number in numbers:
        name = exercises.notebook_name(number)
        key, _ = expected_notebooks(number)
        if not args.no_execute:
            key = execute(key)
        write(key, SOLUTIONS_DIR / name)
        student = exercises.student_copy(nbformat.read(SOLUTIONS_DIR / name, as_version=4))
        if not args.no_execute:
            student = execute(student)
        write(student, EXERCISES_DIR / name)
        print(
            f"wrote {SOLUTIONS_DIR.relative_to(repo_dir()) / name} and {EXERCISES_DIR.relative_to(repo_dir()) / name}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
