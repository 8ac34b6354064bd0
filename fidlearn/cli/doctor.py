"""``fidlearn doctor``: check the Python, numpy and OpenCV installation.

It imports only :mod:`fidlearn.doctor`, which needs neither numpy nor OpenCV: when those cannot
import, :mod:`fidlearn._entry` runs the doctor without the rest of the command line.
"""

from __future__ import annotations

from .. import doctor


def doctor_report() -> tuple[list[str], list[str]]:
    """Lines describing the environment, and the problems found (see :mod:`fidlearn.doctor`).

    Returns
    -------
    lines : list of str
        Python, numpy, OpenCV and their wheels, one per line.
    problems : list of str
        What is broken and the ``pip`` command that mends it (empty when nothing is).
    """
    return doctor.report()


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "doctor", help="check the Python, numpy and OpenCV installation", description="Check the installation."
    )
    p.set_defaults(run=run)


def run(args) -> int:  # noqa: ARG001 (every command's run takes the parsed arguments; doctor has none)
    """Print the report; 1 when a problem was found.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit status: 0 when the installation is sound, 1 when a problem was found.
    """
    return doctor.run()
