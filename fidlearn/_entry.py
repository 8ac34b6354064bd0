"""The ``fidlearn`` command's entry point: start the command line, or say why it cannot start.

When numpy, OpenCV or matplotlib cannot import (two OpenCV wheels, an OpenCV built for numpy 1
beside numpy 2, a half-finished install), ``fidlearn doctor`` still runs and says which pair is
broken and the one ``pip`` command that mends it; every other command prints one ``error:`` line
pointing to it, never a traceback.
"""

from __future__ import annotations

import contextlib
import signal
import sys
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``fidlearn``: the command line, or ``fidlearn doctor`` alone when the rest cannot import.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after ``fidlearn`` (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (see :func:`fidlearn.cli.main`); 2 when fidlearn cannot start.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    handlers = _stop_on_signals()
    try:
        from .cli import main as cli_main
    except BaseException as exc:  # noqa: BLE001 - a broken binary module fails in many ways; all are reported
        for sig, old in handlers.items():
            signal.signal(sig, old)
        return _cannot_start(exc, args)
    for sig, old in handlers.items():
        # the process's own command: ignored until the command line puts its own handler (no silent death)
        signal.signal(sig, signal.SIG_IGN if argv is None else old)
    status = cli_main(args)
    if argv is None:  # the process's own command, done and said so: a signal while it exits changes nothing
        for sig in (signal.SIGINT, *handlers):
            signal.signal(sig, signal.SIG_IGN)
        if status >= 128:  # stopped by a signal, outputs settled and said: end now, as the signal would have
            _end_now(status)
    return status


def _end_now(status: int) -> None:
    """Leave the process at once with ``status``, its streams flushed.

    A command stopped by a signal has committed or removed its outputs and printed its line; the
    interpreter's own shutdown after an interruption can still abort in a library's threads
    (OpenCV's, BLAS's), so it is skipped, as the signal's default action would skip it.
    """
    import os

    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(status)


def _cannot_start(exc: BaseException, args: list[str]) -> int:
    """The command line did not load: a signal, or a broken package (``fidlearn doctor`` still runs)."""
    if isinstance(exc, KeyboardInterrupt):  # Ctrl-C, SIGTERM or SIGHUP while the command line loads
        signum = getattr(exc, "signum", signal.SIGINT)
        print(f"error: interrupted by {signal.Signals(signum).name}; nothing was written", file=sys.stderr)
        return 128 + signum
    if not isinstance(exc, Exception):
        raise exc
    if args[:1] == ["doctor"]:
        from .doctor import run

        return run()
    reason = " ".join(f"{type(exc).__name__}: {exc}".split())
    print(
        f"error: fidlearn cannot start ({reason}); run 'fidlearn doctor' to see which package is broken "
        "and the pip command that mends it",
        file=sys.stderr,
    )
    return 2


class _Stopped(KeyboardInterrupt):
    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _stop(signum, _frame) -> None:
    raise _Stopped(signum)


def _stop_on_signals() -> dict:
    """SIGTERM and SIGHUP stop the start as Ctrl-C does (one line, not a silent death); the old handlers."""
    handlers = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            with contextlib.suppress(ValueError, OSError):  # not the main thread
                handlers[sig] = signal.signal(sig, _stop)
    return handlers
