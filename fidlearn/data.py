"""Paths to the data that comes with fidlearn (``data/`` at the top of the repository).

Notebooks and tests find every file through here, never through a relative or
absolute path of their own. Set ``FIDLEARN_DATA`` to use a copy elsewhere.
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import FidlearnError

__all__ = ["data_dir", "data_path", "repo_dir"]


def repo_dir() -> Path:
    """The repository's top folder (the one holding ``fidlearn/``, ``data/`` and ``notebooks/``).

    Returns
    -------
    pathlib.Path
        An absolute path.

    Examples
    --------
    >>> (repo_dir() / "fidlearn" / "__init__.py").is_file()
    True
    """
    return Path(__file__).resolve().parent.parent


def data_dir() -> Path:
    """The data folder: ``$FIDLEARN_DATA`` if set, else ``data/`` in the repository.

    Returns
    -------
    pathlib.Path
        The folder, which exists.

    Raises
    ------
    FidlearnError
        When the folder does not exist (an installed copy without its data, or a wrong
        ``FIDLEARN_DATA``).
    """
    env = os.environ.get("FIDLEARN_DATA")
    folder = Path(env) if env else repo_dir() / "data"
    if not folder.is_dir():
        raise FidlearnError(
            f"fidlearn's data folder {folder} does not exist; run from a clone of the repository "
            "(pip install -e .) or set FIDLEARN_DATA to a copy of its data/ folder"
        )
    return folder


def data_path(*parts: str) -> Path:
    """A file or folder inside the data folder.

    Parameters
    ----------
    *parts : str
        Path components below the data folder, e.g. ``"scenes", "camera.json"``.

    Returns
    -------
    pathlib.Path
        The path, which exists.

    Raises
    ------
    FidlearnError
        When it is not there.

    Examples
    --------
    >>> data_path("world_map.json").name
    'world_map.json'
    """
    path = data_dir().joinpath(*parts)
    if not path.exists():
        raise FidlearnError(f"{path} is not in fidlearn's data folder; regenerate it with the scripts in tools/")
    return path
