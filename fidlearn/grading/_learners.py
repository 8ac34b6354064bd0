"""The class secret and the learners' ids (see :mod:`fidlearn.grading`).

A graded lesson seeds each learner's numbers with HMAC-SHA256 of a class secret, so nobody
without the secret can rebuild them from the open library. One normalization
(:func:`normalize_learner`) makes a learner's id, which is their folder's name, the seed of their
numbers and what ``grade`` matches submissions by.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import re
import secrets
import tempfile
import unicodedata
from pathlib import Path

from ..errors import GradingError

#: The longest learner id (characters, after normalization): ids are folder names, never cut short.
MAX_ID = 64

_ID_PUNCTUATION = "._-@+"


def normalize_learner(learner: str) -> str:
    """A learner id as released, seeded and graded: one safe name per learner.

    Unicode is put in NFKC form, blanks are trimmed and inner runs of blanks become one ``_``,
    letters are lower-cased: ``" Carol  Smith"`` is ``carol_smith``, and so is ``carol_smith``
    (one learner). The result is the learner's folder name, so anything that is no safe name is
    refused rather than changed.

    Parameters
    ----------
    learner : str
        The id as given (a name, an e-mail, a student number).

    Returns
    -------
    str
        Letters, digits and ``. _ - @ +`` only, at most :data:`MAX_ID` characters, not starting
        with a dot.

    Raises
    ------
    GradingError
        For an empty id, a control character, a path separator, ``.``/``..`` or a leading dot,
        any other character, or more than :data:`MAX_ID` characters.

    Examples
    --------
    >>> normalize_learner("  Carol   Smith "), normalize_learner("Bob@Uni.edu")
    ('carol_smith', 'bob@uni.edu')
    """
    if not isinstance(learner, str) or not learner.strip():
        raise GradingError(f"a learner id must be non-empty text, got {learner!r}")
    text = unicodedata.normalize("NFKC", learner)
    shown = repr(learner[:40])
    if any(unicodedata.category(c).startswith("C") for c in text):
        raise GradingError(f"learner id {shown} holds control or invisible characters; type it plainly")
    if "/" in text or "\\" in text:
        raise GradingError(f"learner id {shown} holds a path separator (/ or \\); ids become folder names")
    text = "_".join(text.split()).lower()
    if text.startswith("."):
        raise GradingError(f"learner id {shown} starts with a dot ('.', '..' and hidden names cannot be folders)")
    bad = sorted({c for c in text if not (c.isalnum() or c in _ID_PUNCTUATION)})
    if bad:
        raise GradingError(
            f"learner id {shown} holds {''.join(bad)!r}; use letters, digits, blanks and {_ID_PUNCTUATION} only"
        )
    if len(text) > MAX_ID:
        raise GradingError(f"learner id {shown}... has {len(text)} characters; at most {MAX_ID}")
    return text


def read_roster(lines: list[str], where: str) -> list[str]:
    """The learner ids of a roster (one per line; blank lines and comments, from ``#`` to the end of the line,
    skipped), each once.

    Parameters
    ----------
    lines : list of str
        The roster's lines.
    where : str
        The roster's name, for the messages.

    Returns
    -------
    list of str
        The normalized ids (:func:`normalize_learner`), in roster order.

    Raises
    ------
    GradingError
        For an id that is no safe name (with its line), two lines that are one learner (both named),
        or a roster without ids.

    Examples
    --------
    >>> read_roster(["# class A", "Alice", "", "Carol Smith  # joined in week 3"], "roster.txt")
    ['alice', 'carol_smith']
    """
    seen: dict[str, tuple[int, str]] = {}
    for n, line in enumerate(lines, 1):
        raw = line.split("#", 1)[0].strip()  # no id holds a "#" (normalize_learner)
        if not raw:
            continue
        try:
            learner = normalize_learner(raw)
        except GradingError as exc:
            raise GradingError(f"{where}, line {n}: {exc}") from None
        if learner in seen:
            m, first = seen[learner]
            raise GradingError(
                f"{where}: line {m} {first!r} and line {n} {raw!r} are one learner ({learner!r}); "
                "give each learner an id of their own"
            )
        seen[learner] = (n, raw)
    if not seen:
        raise GradingError(f"{where}: no learner ids (one per line)")
    return list(seen)


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
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise GradingError(f"{path}: the folder {folder} does not exist; create it first")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=folder)  # private: 0o600
    except OSError as exc:
        raise GradingError(f"{path}: cannot write in {folder} ({exc.strerror}); no secret was made") from None
    try:
        _write_all(fd, (secrets.token_hex(32) + "\n").encode())
        os.fsync(fd)
        os.close(fd)
        fd = -1
        os.link(tmp, path)  # appears whole or not at all, and never replaces a secret made meanwhile
    except FileExistsError:
        raise GradingError(f"{path} exists; a class keeps one secret for the whole course") from None
    except OSError as exc:
        raise GradingError(
            f"{path}: cannot write it ({exc.strerror or exc}); check the free disk space; no secret was made"
        ) from None
    finally:
        if fd >= 0:
            os.close(fd)
        os.unlink(tmp)
    return path


def _write_all(fd: int, data: bytes) -> None:
    while data:
        data = data[os.write(fd, data) :]


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
    from .._files import MAX_TEXT_BYTES, read_bytes

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


def release_tag(secret: bytes, lesson: str, learner: str) -> str:
    """The tag a released notebook carries beside its learner's id: nobody without the secret can make it.

    Parameters
    ----------
    secret : bytes
        The class secret.
    lesson, learner : str
        ``"03"`` and the normalized learner id.

    Returns
    -------
    str
        32 hex digits of HMAC-SHA256: a notebook whose id was edited to another learner's no longer matches.

    Examples
    --------
    >>> len(release_tag(b"secret", "03", "alice"))
    32
    """
    return hmac.new(secret, f"fidlearn-release/{lesson}/{learner}".encode(), hashlib.sha256).hexdigest()[:32]


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
