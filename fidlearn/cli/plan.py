"""``fidlearn plan``: the position error to expect over a room, before printing (:mod:`fidlearn.planning.command`)."""

from __future__ import annotations

from ..planning import command


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser("plan", help=command.HELP, description=command.__doc__)
    command.add_arguments(p)
    p.set_defaults(run=command.run)
