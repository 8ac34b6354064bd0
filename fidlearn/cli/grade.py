"""``fidlearn release`` and ``fidlearn grade``: exercise lessons for a class, and their grading."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .. import grading
from .._files import MAX_TEXT_BYTES, read_bytes
from ..errors import UsageError
from ._common import _check_output, _refuse_clobber


def add_release(sub) -> None:
    """Register ``fidlearn release`` on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "release",
        help="an exercise lesson for each learner of a class, its answers kept by the instructor",
        description="Write OUTPUT/LEARNER/ for every learner of the roster: the lesson's student notebook and "
        "fidlearn_inputs.json, that learner's numbers without their answers (seeded by the class "
        "secret). 'fidlearn grade' grades what comes back.",
    )
    p.add_argument("--lesson", required=True, help="lesson number, e.g. 03")
    p.add_argument(
        "--secret-file", type=Path, required=True, help="the class secret ('fidlearn grade --new-secret FILE')"
    )
    p.add_argument("--learners", type=Path, required=True, help="roster: one learner id per line")
    p.add_argument("-o", "--output", type=Path, required=True, help="folder to write the learners' folders in")
    p.set_defaults(run=run_release)


def run_release(args) -> int:
    """Write every learner's folder; print how many.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit status: 0 when done.

    Raises
    ------
    FidlearnError
        A user error (``UsageError`` for the command line itself); :func:`fidlearn.cli.main` prints it
        as one ``error:`` line and exits with status 2.
    """
    _, data = read_bytes(args.learners, UsageError, "roster", MAX_TEXT_BYTES)
    learners = [
        line.strip()
        for line in data.decode("utf-8", "replace").splitlines()
        if line.strip() and not line.startswith("#")
    ]
    if not learners:
        raise UsageError(f"--learners {args.learners}: no learner ids (one per line)")
    folders = grading.release(args.lesson, learners, args.secret_file, args.output)
    print(f"{len(folders)} learner folders in {args.output}/ (lesson {args.lesson}); hand each learner their own")
    return 0


def add_grade(sub) -> None:
    """Register ``fidlearn grade`` on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "grade",
        help="grade learners' exercise notebooks, each in a sandbox, the answer key outside it",
        description="Run each submitted notebook in a process of its own (scratch folder, time and memory "
        "limits, no instructor's environment; as 'nobody' when run as root) and grade the answers "
        "it leaves in the grader's process, against the variant the class secret gives that "
        "learner. A notebook that crashes, hangs or cheats gets 0 with the reason; the CSV is "
        "always written. Grading runs learners' code: see docs/teaching.md.",
    )
    p.add_argument("notebooks", nargs="*", type=Path, metavar="NOTEBOOK", help="submitted notebooks (.ipynb)")
    p.add_argument("--lesson", help="lesson number, e.g. 03")
    p.add_argument("--secret-file", type=Path, help="the class secret")
    p.add_argument(
        "--learner", help="the learner of every notebook given (default: each file's name, e.g. alice.ipynb)"
    )
    p.add_argument("-o", "--output", type=Path, help="grades.csv: one row per question")
    p.add_argument("--timeout", type=int, default=120, help="seconds a notebook may run (default 120)")
    p.add_argument(
        "--memory-mb", type=int, default=3000, metavar="MB", help="memory a notebook may use, MB (default 3000)"
    )
    p.add_argument("--run-as", metavar="USER", help="run notebooks as this user (default 'nobody' when root)")
    p.add_argument("--new-secret", type=Path, metavar="FILE", help="create a class secret in FILE and stop")
    p.set_defaults(run=run_grade)


def run_grade(args) -> int:
    """Make a class secret, or grade the notebooks into a CSV; print one line per notebook.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit status: 0 when done.

    Raises
    ------
    FidlearnError
        A user error (``UsageError`` for the command line itself); :func:`fidlearn.cli.main` prints it
        as one ``error:`` line and exits with status 2.
    """
    if args.new_secret is not None:
        grading.new_secret(args.new_secret)
        print(f"{args.new_secret}: a new class secret; keep it private (it decides every learner's numbers)")
        return 0
    missing = [
        opt
        for opt, v in (("--lesson", args.lesson), ("--secret-file", args.secret_file), ("-o", args.output))
        if v is None
    ]
    if missing or not args.notebooks:
        raise UsageError(
            "give the notebooks, --lesson, --secret-file and -o grades.csv"
            if not missing
            else f"{missing[0]} is required to grade"
        )
    out = _check_output(args.output, (".csv",))
    if not 5 <= args.timeout <= 3600 or not 200 <= args.memory_mb <= 65536:
        raise UsageError("--timeout is 5 to 3600 s and --memory-mb 200 to 65536")
    _refuse_clobber([("-o", out)], [*args.notebooks, args.secret_file])
    for nb in args.notebooks:
        if not nb.is_file():
            raise UsageError(f"{nb}: no such notebook; give the learners' .ipynb files")
    if os.geteuid() != 0 and args.run_as is None:
        print(
            "warning: grading as your own user: a notebook can read what you can; see docs/teaching.md", file=sys.stderr
        )

    def progress(k: int, n: int, g) -> None:
        print(f"[{k}/{n}] {g.line()}", flush=True)

    grades = grading.grade(
        args.notebooks,
        args.lesson,
        args.secret_file,
        out,
        learner=args.learner,
        timeout_s=args.timeout,
        memory_mb=args.memory_mb,
        run_as=args.run_as,
        progress=progress,
    )
    print(f"{len(grades)} notebooks graded; grades in {out}")
    return 0
