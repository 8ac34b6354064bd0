"""Private file helpers: strict JSON reading and atomic writes (staged with :mod:`fidlearn._staged`)."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ._files import MAX_TEXT_BYTES, read_bytes
from ._staged import (
    SIGNAL_AT_VARIABLE,
    StagedOutputs,
    current_outputs,
    file_mode_for,
    outputs_together,
    signals_deferred,
)
from .errors import FidlearnError


class _DuplicateKey(Exception):
    def __init__(self, key: str):
        super().__init__(key)
        self.key = key


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict:
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise _DuplicateKey(key)
        seen[key] = value
    return seen


def _reject_constant(name: str) -> float:
    raise ValueError(name)


def read_json(path: str | os.PathLike, error: type[FidlearnError], what: str) -> Any:
    """Read a JSON file strictly.

    Duplicate keys (which Python's ``json`` silently collapses to the last one),
    ``NaN``/``Infinity`` literals, syntax errors, undecodable bytes, missing
    files, FIFOs, devices and files over 10 MB all raise ``error`` with the file
    name and a way to mend it.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    error : type of FidlearnError
        The error class to raise (``MapError`` for a map, ``CameraError`` for a camera...).
    what : str
        What the file should hold, for the messages (``"world map"``).

    Returns
    -------
    object
        The parsed JSON.

    Raises
    ------
    FidlearnError
        ``error``, for every reason above.
    """
    path, raw = read_bytes(path, error, what, MAX_TEXT_BYTES)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(
            f"{path}: not UTF-8 text (byte {exc.start} is 0x{raw[exc.start]:02x}); save the {what} as UTF-8 JSON"
        ) from None
    if not text.strip():
        raise error(f"{path}: the file is empty; expected a {what} in JSON")
    try:
        return json.loads(text, object_pairs_hook=_no_duplicates, parse_constant=_reject_constant)
    except _DuplicateKey as exc:
        raise error(
            f'{path}: key "{exc.key}" appears twice in one object; each key (each marker id) '
            "must be unique, and JSON would silently keep only the last one"
        ) from None
    except json.JSONDecodeError as exc:
        raise error(
            f"{path}: invalid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}; {_json_hint(text, exc.pos)}"
        ) from None
    except ValueError as exc:  # NaN / Infinity literal
        raise error(f"{path}: contains {exc.args[0]}, which is not a number; write a finite measurement") from None
    except RecursionError:
        raise error(
            f"{path}: brackets nested too deeply to be a {what}; check the file (is it the right one?)"
        ) from None


def _json_hint(text: str, pos: int) -> str:
    """How to mend the JSON syntax error at ``pos`` of ``text``: what people write that JSON does not take.

    >>> _json_hint('{"a": 1,}', 8)
    'a comma after the last item: JSON allows none there, remove it'
    >>> print(_json_hint("{'a': 1}", 1))
    JSON takes double quotes: write "a" for 'a'
    >>> _json_hint('{"a": 1, // feet', 9)
    'JSON has no comments: remove the comment'
    """
    here = text[pos:]
    before = text[:pos].rstrip()
    if here.startswith(("//", "/*", "#")):
        return "JSON has no comments: remove the comment"
    if here[:1] in "}]" and before.endswith(","):
        return "a comma after the last item: JSON allows none there, remove it"
    if here.startswith("'"):
        quoted = here[1:].split("'", 1)[0][:20]
        return f"JSON takes double quotes: write \"{quoted}\" for '{quoted}'"
    return "fix the syntax (a missing comma or bracket is the usual cause)"


def atomic_write(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
    """Write a file through a temporary file in the same folder, then rename it.

    ``write`` receives the temporary path and must create the file there.  If it
    raises, the temporary file is removed and ``path`` is untouched: no
    half-written output is ever left behind. Inside an active :class:`StagedOutputs`
    the rename waits for its commit, with the other outputs of the same work.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    write : callable(Path)
        Writes the whole content to the temporary path it receives.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    FidlearnError
        The folder does not exist, ``path`` is a folder, or the disk refused (full, no permission).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     out = atomic_write(Path(folder) / "a.txt", lambda tmp: tmp.write_text("whole"))
    ...     out.read_text(), sorted(p.name for p in Path(folder).iterdir())
    ('whole', ['a.txt'])
    """
    with outputs_together() as outputs:
        return outputs.stage(path, write)


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    text : str
        Its content.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def write_json_atomic(path: str | os.PathLike, obj: Any) -> Path:
    """Write ``obj`` as indented JSON to ``path`` atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    obj : object
        Anything ``json.dumps`` takes.

    Returns
    -------
    Path
        ``path``.
    """
    return write_text_atomic(path, json.dumps(obj, indent=2) + "\n")


__all__ = [
    "SIGNAL_AT_VARIABLE",
    "StagedOutputs",
    "atomic_write",
    "current_outputs",
    "file_mode_for",
    "outputs_together",
    "read_json",
    "signals_deferred",
    "write_json_atomic",
    "write_text_atomic",
]
