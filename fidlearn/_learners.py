"""The class secret and the learners' ids (see :mod:`fidlearn.grading`).

A graded lesson seeds each learner's numbers with HMAC-SHA256 of a class secret, so nobody
without the secret can rebuild them from the open library; learner ids are compared trimmed and
in lower case.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import re
import secrets
from pathlib import Path

from .errors import GradingError


def fold_learner(learner) -> str:
    """A learner id folded to the form every variant is seeded with: blanks trimmed and merged, lower case.

    Parameters
    ----------
    learner : object
        The id as given (``None`` counts as ``""``, the class's shared variant).

    Returns
    -------
    str
        ``"  Alice   Smith "`` -> ``"alice smith"``; ``""`` stays ``""``.

    Examples
    --------
    >>> fold_learner("Alice "), fold_learner(None)
    ('alice', '')
    """
    return " ".join(str(learner or "").split()).lower()


def normalize_learner(learner: str) -> str:
    """A learner id as graded: trimmed and lower-case ("Alice " and "alice" are one learner).

    Parameters
    ----------
    learner : str
        The id as given (a name, an e-mail, a student number).

    Returns
    -------
    str
        Inner runs of blanks made one space, lower case.

    Raises
    ------
    GradingError
        For an empty id, one over 200 characters, or one with control characters.

    Examples
    --------
    >>> normalize_learner("  Alice   Smith ")
    'alice smith'
    """
    if not isinstance(learner, str) or not learner.strip():
        raise GradingError(f"a learner id must be non-empty text, got {learner!r}")
    text = fold_learner(learner)
    if len(text) > 200 or any(ord(c) < 32 for c in text):
        raise GradingError(f"learner id {learner[:40]!r} is too long or holds control characters")
    return text


def new_secret(path: str | os.PathLike) -> Path:
    """Write a new class secret (64 hex digits) to ``path``, readable by its owner only.

    Parameters
    ----------
    path : str or os.PathLike
        The file to create.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    GradingError
        When ``path`` exists: a class keeps one secret for the whole course.
    """
    path = Path(path)
    if path.exists():
        raise GradingError(f"{path} exists; a class keeps one secret for the whole course (delete it only on purpose)")
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(secrets.token_hex(32) + "\n")
    return path


def read_secret(path: str | os.PathLike) -> bytes:
    """The class secret from its file (made by :func:`new_secret`).

    Parameters
    ----------
    path : str or os.PathLike
        The secret's file.

    Returns
    -------
    bytes
        The secret.

    Raises
    ------
    GradingError
        When the file cannot be read or does not hold a secret (hex digits).
    """
    from ._files import MAX_TEXT_BYTES, read_bytes

    path, data = read_bytes(path, GradingError, "class secret", MAX_TEXT_BYTES)
    text = data.decode("ascii", "replace").strip()
    if not re.fullmatch(r"[0-9a-f]{32,}", text):
        raise GradingError(f"{path}: not a class secret (64 hex digits, as 'fidlearn grade --new-secret' writes it)")
    return bytes.fromhex(text[: len(text) // 2 * 2])


def variant_seed(secret: bytes, lesson: str, learner: str, question: str) -> int:
    """The seed of one learner's numbers for one question: HMAC-SHA256 of the class secret.

    Parameters
    ----------
    secret : bytes
        The class secret.
    lesson, learner, question : str
        ``"03"``, the normalized learner id, ``"q1"``.

    Returns
    -------
    int
        The first 8 bytes of the HMAC, little-endian: nobody without the secret can repeat it.

    Examples
    --------
    >>> variant_seed(b"secret", "03", "alice", "q1") == variant_seed(b"secret", "03", "alice", "q1")
    True
    """
    digest = hmac.new(secret, f"fidlearn-graded/{lesson}/{learner}/{question}".encode(), hashlib.sha256).digest()
    return int.from_bytes(digest[:8], "little")


def learner_from_filename(path: str | os.PathLike) -> str:
    """``submissions/Alice.Smith.ipynb`` -> ``alice.smith``: the file's name without ``.ipynb``.

    Parameters
    ----------
    path : str or os.PathLike
        A submitted notebook.

    Returns
    -------
    str
        The normalized learner id.

    Raises
    ------
    GradingError
        For a name that is no usable learner id.

    Examples
    --------
    >>> learner_from_filename("submissions/Alice.Smith.ipynb")
    'alice.smith'
    """
    name = Path(path).name
    return normalize_learner(name[: -len(".ipynb")] if name.lower().endswith(".ipynb") else Path(path).stem)
