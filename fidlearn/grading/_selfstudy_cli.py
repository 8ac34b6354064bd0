"""``python -m fidlearn.exercises grade NOTEBOOK... [--learner ID] [--csv FILE]``."""

from __future__ import annotations

from collections.abc import Sequence

from ._selfstudy import grade_notebook


def _main(argv: Sequence[str] | None = None) -> int:
    """``python -m fidlearn.exercises grade NOTEBOOK... [--learner ID] [--csv FILE]``."""
    import argparse
    import csv
    import io
    import sys

    from .._io import write_text_atomic

    parser = argparse.ArgumentParser(
        prog="python -m fidlearn.exercises",
        description="Check learners' self-study notebooks (for marks: fidlearn grade).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    g = sub.add_parser("grade", help="run notebooks in sandboxes and check every question (self-study variants)")
    g.add_argument("notebooks", nargs="+")
    g.add_argument("--learner", help="the id the learner was told to use (one notebook, or all of one learner)")
    g.add_argument("--csv", help="also write one row per question to this CSV file")
    args = parser.parse_args(argv)
    from ..errors import FidlearnError

    grades = []
    for path in args.notebooks:
        try:
            grade = grade_notebook(path, learner=args.learner)
        except FidlearnError as exc:  # one line and status 2, as every fidlearn command
            print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
            return 2
        print(grade)
        grades.append(grade)
    if args.csv:
        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(["notebook", "lesson", "learner", "question", "status", "message"])
        for grade in grades:
            for r in grade.results:
                w.writerow([grade.notebook, grade.lesson, grade.learner, r.question, r.status, r.message])
            for e in grade.errors:
                w.writerow([grade.notebook, grade.lesson, grade.learner, "", "problem", e])
        write_text_atomic(args.csv, buf.getvalue())
    return 0
