"""The ``fidlearn`` parser and :func:`main`: signals, safe printing, one ``error:`` line per failure."""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import signal
import sys
import warnings
from collections.abc import Callable, Sequence

import cv2

from .. import __version__
from ..errors import FidlearnError, FidlearnWarning, UsageError
from ..io import StagedOutputs
from . import calibrate, camera, check_print, compare, corners, doctor, grade, locate, markers, plan, render, survey
from ._common import _error, _exit_status, _Parser, _raise_interrupted, _SafeStdout, _show_warning, _signal_name

#: Subcommand builders, in the order ``fidlearn --help`` lists them.
COMMANDS: list[Callable] = [
    markers.add_board,
    calibrate.add,
    compare.add,
    camera.add,
    markers.add_markers,
    corners.add,
    locate.add,
    survey.add,
    check_print.add,
    render.add,
    plan.add,
    grade.add_release,
    grade.add_grade,
    doctor.add,
]

_WORKFLOW = """\
from printer to pose:
  fidlearn board --pattern 9x6 --square-mm 25 -o board.pdf         print, measure a square
  fidlearn calibrate photos/ --pattern 9x6 --square-mm 25 -o camera.json
  fidlearn markers --ids 0-2 --size-mm 80 -o markers.pdf           print, tape up, measure
  fidlearn corners map.json -o corners.json                        check the map
  fidlearn locate frames/ --camera camera.json --map map.json      the camera's pose
  fidlearn survey photos/ --camera camera.json --map map.json -o surveyed.json   the map from photos
  fidlearn plan map.json --camera camera.json -o plan.png          the error to expect, before printing
'fidlearn COMMAND --help' tells more."""


class _TopHelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps each command and its help on one line (argparse forgets the commands' extra indent)."""

    def __init__(self, prog):
        super().__init__(prog, max_help_position=24, width=100)

    def add_argument(self, action):
        super().add_argument(action)
        if isinstance(action, argparse._SubParsersAction):
            longest = max((len(name) for name in action.choices), default=0)
            self._action_max_length = max(self._action_max_length, longest + 2 * self._indent_increment + 2)


def build_parser() -> argparse.ArgumentParser:
    """The ``fidlearn`` argument parser with every command.

    Returns
    -------
    argparse.ArgumentParser
        Its errors raise :class:`~fidlearn.errors.UsageError` (one line) instead of exiting.

    Examples
    --------
    >>> sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    >>> sorted(sub.choices)[:3]
    ['board', 'calibrate', 'camera']
    """
    parser = _Parser(
        prog="fidlearn",
        description="Camera localization from ArUco fiducials: calibrate, map, detect, locate.",
        epilog=_WORKFLOW,
        formatter_class=_TopHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"fidlearn {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for add in COMMANDS:
        add(sub)
    return parser


def _quiet_opencv() -> None:
    """The command's own process: OpenCV's and FFmpeg's log lines would break the one-line errors.

    fidlearn reports every failure itself. This sets OpenCV's log level for this process (the
    command line owns it); the library never does, and never redirects file descriptors.
    """
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET, read when a video is opened
    log = getattr(getattr(cv2, "utils", None), "logging", None)
    if log is not None and hasattr(log, "LOG_LEVEL_SILENT"):
        log.setLogLevel(log.LOG_LEVEL_SILENT)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line.

    SIGTERM and SIGHUP are handled as Ctrl-C is: a streaming output keeps every frame finished,
    under its final name. A standard output that closes (``| head``) silences the rest of the
    printing, not the work.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after ``fidlearn`` (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status: 0 ok, 1 a problem found (``doctor``), 2 a user error, 128 + N stopped by signal N.
    """
    stdout, handlers = sys.stdout, {}
    done: list[StagedOutputs] = []  # the command's outputs, once it has any
    try:
        for sig in (signal.SIGTERM, signal.SIGHUP):
            with contextlib.suppress(ValueError, OSError):  # not the main thread: leave signals alone
                handlers[sig] = signal.signal(sig, _raise_interrupted)
        _quiet_opencv()
        sys.stdout = _SafeStdout(stdout)
        return _main(argv, done)
    except KeyboardInterrupt as exc:  # outside the command's own handling (a second signal, or before it began)
        _error(f"interrupted by {_signal_name(exc)}; {done[0].written() if done else 'nothing was written'}")
        return _exit_status(exc)
    finally:
        for sig in handlers:  # the command has said how it ended: a signal now changes nothing of it
            signal.signal(sig, signal.SIG_IGN)
        for sig, old in handlers.items():
            signal.signal(sig, old)
        sys.stdout.flush()
        sys.stdout = stdout


def _main(argv: Sequence[str] | None, done: list) -> int:
    outputs = None
    try:
        parser = build_parser()
        args = parser.parse_args(_join_negative_values(sys.argv[1:] if argv is None else list(argv)))
        if not getattr(args, "run", None):
            if getattr(args, "command", None):  # a command whose verbs were not given: fidlearn camera
                raise UsageError(
                    f"fidlearn {args.command}: give export or import (see 'fidlearn {args.command} --help')"
                )
            parser.print_help()
            return 2
        with warnings.catch_warnings(), _outputs_of(args) as outputs:
            if outputs is not None:  # what it writes, for a line about a signal that comes while it ends
                done.append(outputs)
            # a library's deprecation notice is for its developers, not a line for the command's user
            warnings.simplefilter("ignore", DeprecationWarning)
            warnings.simplefilter("ignore", PendingDeprecationWarning)
            warnings.simplefilter("always", FidlearnWarning)
            warnings.showwarning = _show_warning
            return int(args.run(args) or 0)
    except FidlearnError as exc:
        _error(_with_written(str(exc), outputs))
        return 2
    except KeyboardInterrupt as exc:
        _error(f"interrupted by {_signal_name(exc)}; {outputs.written() if outputs else 'nothing was written'}")
        return _exit_status(exc)
    except OSError as exc:  # the disk, not the code: permission denied, disk full, ...
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        _error(_with_written(f"{where}{exc.strerror or exc}; check the path and its permissions", outputs))
        return 2
    except Exception as exc:
        signalled = _interruption_in(exc)  # a C extension's import turns a signal into "initialization failed"
        if signalled is None:
            raise
        _error(f"interrupted by {_signal_name(signalled)}; {outputs.written() if outputs else 'nothing was written'}")
        return _exit_status(signalled)


def _interruption_in(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The signal's ``KeyboardInterrupt`` that caused ``exc``, if one did."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


#: Commands that write their files themselves, each as soon as it is ready (see fidlearn.grading).
_WRITE_AS_THEY_GO = ("release", "grade")


def _outputs_of(args):
    """The command's outputs, staged and renamed together at its end (:class:`fidlearn.io.StagedOutputs`)."""
    if args.command in _WRITE_AS_THEY_GO:
        return contextlib.nullcontext()
    return StagedOutputs()


def _with_written(message: str, outputs: StagedOutputs | None) -> str:
    """An error's line, saying what the command wrote before it when it wrote something."""
    if outputs is None or not outputs.committed or outputs.written() in message:
        return message
    return f"{message}; {outputs.written()}"


#: Options whose value is a comma-separated list of numbers that may start with a minus sign.
_NUMBER_LIST_OPTIONS = ("--pose", "--look-at", "--from", "--area")
_NUMBER_LIST = re.compile(r"-\d*\.?\d+(e[-+]?\d+)?(,\s*-?\d*\.?\d+(e[-+]?\d+)?)*", re.IGNORECASE)


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--from -1000,190,230`` -> ``--from=-1000,190,230``.

    argparse takes a value starting with ``-`` for an option unless it is a single
    negative number, so a camera behind the wall (x < 0) failed with "expected one argument".
    """
    out: list[str] = []
    k = 0
    while k < len(argv):
        arg = argv[k]
        if arg in _NUMBER_LIST_OPTIONS and k + 1 < len(argv) and _NUMBER_LIST.fullmatch(argv[k + 1]):
            out.append(f"{arg}={argv[k + 1]}")
            k += 2
            continue
        out.append(arg)
        k += 1
    return out
