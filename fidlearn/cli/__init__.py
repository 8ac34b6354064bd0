"""The ``fidlearn`` command line.

Every command reports a user error as one line ``error: ...`` on stderr and
exits with status 2: never a traceback, never a half-written output file.
Inputs and output paths are checked before any work starts.

What "no partial output" means for each kind of output:

* every output of a command (``-o``, ``--truth``, ``--report``, ``--plot``, PNG pages,
  annotated pictures): written to a hidden temporary file beside its name, and all of
  them renamed together when the command has done its work
  (:class:`fidlearn.io.StagedOutputs`), with SIGINT, SIGTERM and SIGHUP deferred
  during the renames: an interruption or a full disk at any moment leaves every output
  or none, and no temporary file; the ``error:`` line says which (``nothing was
  written``, or ``written: ...``).
* ``locate --json``: one JSON line per frame, flushed as each frame is done
  into a hidden temporary file, renamed to its name when the whole run ends
  well (stopping a live camera with Ctrl-C is a good end; an error in frame
  57 of a video leaves no file). Interrupted by a signal, ``locate`` keeps every
  finished frame: its records and its annotated pictures, and says how many.
* ``--annotate DIR``: images are staged in a hidden folder beside ``DIR`` and
  moved into ``DIR`` (created if needed) with the other outputs.

Warnings (:class:`~fidlearn.errors.FidlearnWarning`) print as one line
``warning: ...`` on stderr and do not change the exit status.

Every command is argument parsing, printing and file handling over library calls: one
module per command (``corners``, ``doctor``, ``markers`` with ``board``, ``render``,
``calibrate``, ``locate``, ``survey``, ``plan``, ``grade`` with ``release``), each with ``add(sub)``
registering it and ``run(args)`` doing it; ``_common`` holds what they share and
``_main`` the parser and :func:`main`.
"""

from __future__ import annotations

# Importing the commands loads OpenCV: one that cannot import fails here, where fidlearn._entry reports it.
from ._main import build_parser, main

__all__ = ["main", "build_parser"]
