"""``fidlearn release`` and ``fidlearn grade``: exercise lessons for a class, and their grading."""

from __future__ import annotations

import sys
from pathlib import Path

from .. import exercises, grading
from ..errors import UsageError
from ..grading import lms_path, read_roster
from ..io import MAX_TEXT_BYTES, read_bytes
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
    p.add_argument(
        "--learners",
        type=Path,
        required=True,
        help="roster: one learner id per line (letters, digits, blanks, . _ - @ +; # starts a comment)",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="a new (or empty) folder for the learners' folders")
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
    lines = _roster_lines(args.learners, "--learners")
    folders = grading.release(args.lesson, lines, args.secret_file, args.output)
    lesson = exercises.lesson_number(args.lesson)  # as the folders name it: " 3" is lesson 03
    print(f"{len(folders)} learner folders in {args.output}/ (lesson {lesson}); hand each learner their own")
    return 0


def _roster_lines(path: Path, option: str) -> list[str]:
    """The roster's lines, checked: every id a safe name, no two lines one learner (with the lines named)."""
    _, data = read_bytes(path, UsageError, "roster", MAX_TEXT_BYTES)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise UsageError(f"{option} {path}: not UTF-8 text (byte {exc.start}); save the roster as UTF-8") from None
    lines = text.splitlines()
    read_roster(lines, f"{option} {path}")
    return lines


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
        description="Run each submitted notebook in a box of its own (bubblewrap: no network, no other "
        "files, its processes killed after it; time, memory, process and file limits; no instructor's "
        "environment; as 'nobody' when run as root) and grade the answers "
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
    p.add_argument(
        "--roster",
        type=Path,
        metavar="FILE",
        help="the roster release used: unknown and missing learners are reported, each learner graded once",
    )
    p.add_argument(
        "--format",
        choices=("csv", "canvas", "moodle"),
        default="csv",
        help="also write a gradebook import beside -o: canvas (grades.canvas.csv) or moodle (grades.moodle.csv)",
    )
    p.add_argument("--timeout", type=int, default=120, help="seconds a notebook may run (default 120)")
    p.add_argument(
        "--memory-mb", type=int, default=3000, metavar="MB", help="memory a notebook may use, MB (default 3000)"
    )
    p.add_argument(
        "--run-as",
        metavar="USER",
        help="run notebooks as this user (default: 'nobody' when root; each in a bubblewrap box where it works)",
    )
    p.add_argument("--new-secret", type=Path, metavar="FILE", help="create a class secret in FILE and stop")
    p.set_defaults(run=run_grade)


def _checked_grade_args(args) -> tuple[Path, list[str] | None]:
    """The CSV to write and the roster's lines, once every option of ``grade`` is checked."""
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
    roster = _roster_lines(args.roster, "--roster") if args.roster is not None else None
    outputs = [("-o", out)] + ([("--format", lms_path(out, args.format))] if args.format != "csv" else [])
    _refuse_clobber(outputs, [*args.notebooks, args.secret_file, *([args.roster] if args.roster else [])])
    secret = args.secret_file.resolve()
    for nb in args.notebooks:
        if nb.is_dir():
            raise UsageError(f"{nb} is a folder; give the notebooks in it ({nb}/*.ipynb)")
        if not nb.is_file():
            raise UsageError(f"{nb}: no such notebook; give the learners' .ipynb files")
        if nb.resolve() == secret:
            raise UsageError(f"{nb} is the class secret ({args.secret_file}), not a notebook: it is never graded")
    return out, roster


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
    out, roster = _checked_grade_args(args)
    plan = grading.sandbox_plan(args.run_as)  # refuses a user who cannot run this Python, before any notebook
    if plan.warning:
        print(f"warning: {plan.warning}; see docs/teaching.md", file=sys.stderr)

    def progress(k: int, n: int, g) -> None:
        print(f"[{k}/{n}] {g.line()}", flush=True)

    grades = grading.grade(
        args.notebooks,
        args.lesson,
        args.secret_file,
        out,
        learner=args.learner,
        roster=roster,
        formats=(args.format,),
        timeout_s=args.timeout,
        memory_mb=args.memory_mb,
        run_as=args.run_as,
        progress=progress,
    )
    counted = sum(1 for g in grades if g.graded)
    others = [g.problem for g in grades if not g.graded]
    extra = f" and {lms_path(out, args.format)}" if args.format != "csv" else ""
    print(f"{counted} notebooks graded; grades in {out}{extra}")
    if others:
        print(f"{len(others)} not graded (the CSV says why): " + "; ".join(others[:5]))
    return 0
