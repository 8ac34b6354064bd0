"""Helpers shared by tests that run something as another, unprivileged user."""

from __future__ import annotations

import os
import stat
import sys
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@contextmanager
def traversable_by_others(*paths: Path):
    """Give 'others' the r and x bits on every folder above ``paths`` for the test, as a shared install has them.

    The checkout, its venv and the Python it was made from (pyenv's lives under /root here)
    must be reachable by the unprivileged user; the modes are put back afterwards.
    """
    changed = []
    for path in paths:
        for folder in [path, *path.parents]:
            mode = folder.stat().st_mode
            if not mode & stat.S_IXOTH or not mode & stat.S_IROTH:
                changed.append((folder, mode))
                folder.chmod(mode | stat.S_IXOTH | stat.S_IROTH)
    try:
        yield
    finally:
        for folder, mode in reversed(changed):
            folder.chmod(stat.S_IMODE(mode))


def python_paths() -> list[Path]:
    """The checkout, the venv and the base interpreter's installation."""
    return [ROOT, Path(sys.prefix), Path(os.path.realpath(sys.executable)).parent, Path(sys.base_prefix)]
