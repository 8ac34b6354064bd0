"""Which learner a submitted notebook belongs to, the roster's check, and the gradebook files.

A notebook that ``fidlearn release`` wrote carries its learner's id and lesson in its metadata;
``grade`` matches it by that id, not by its file name (a file renamed by a collection tool still
finds its learner, and a notebook is never graded against another learner's variant). With a
roster, unknown and missing learners are reported; a learner who handed in twice is graded
once. Besides the detailed CSV, the scores can be written as a Canvas or Moodle gradebook import.
"""

from __future__ import annotations

import csv
import hmac
import io
import json
import os
from pathlib import Path

from .._io import write_text_atomic
from ..errors import GradingError
from ._learners import learner_from_filename, normalize_learner, release_tag

#: The gradebook formats ``grade --format`` writes besides the detailed CSV.
FORMATS = ("csv", "canvas", "moodle")

_MAX_NOTEBOOK_BYTES = 200_000_000


def notebook_claim(path: str | os.PathLike) -> dict:
    """The ``{"lesson", "learner", "tag"}`` a released notebook's metadata names ({} when it names none).

    Parameters
    ----------
    path : str or os.PathLike
        A submitted notebook.

    Returns
    -------
    dict
        ``{"lesson": "03", "learner": "alice", "tag": "..."}``, or ``{}`` for a notebook without
        (or with unreadable) release metadata.
    """
    try:
        if os.path.getsize(path) > _MAX_NOTEBOOK_BYTES:
            return {}
        with open(path, encoding="utf-8") as f:
            meta = json.load(f).get("metadata", {}).get("fidlearn", {})
        return {"lesson": str(meta["lesson"]), "learner": str(meta["learner"]), "tag": str(meta.get("tag", ""))}
    except (OSError, ValueError, TypeError, KeyError, AttributeError, RecursionError):
        return {}


def match(notebooks, number: str, learner: str | None, roster: list[str] | None, secret: bytes) -> list[tuple]:
    """Each notebook's learner, or why it is not graded: ``[(notebook, learner id, problem)]``.

    Parameters
    ----------
    notebooks : sequence of path
        The submitted notebooks, in the order given.
    number : str
        The lesson graded.
    learner : str or None
        One learner id for every notebook (``--learner``), else each notebook's metadata, else its file name.
    roster : list of str or None
        The class's normalized ids.
    secret : bytes
        The class secret: a released notebook's tag must be the one release gave its id.

    Returns
    -------
    list of tuple
        ``(notebook, learner, "")`` to grade, ``(notebook, learner, problem)`` not to grade.
    """
    out: list[tuple] = []
    seen: dict[str, str] = {}
    given = normalize_learner(learner) if learner is not None else None
    for nb in notebooks:
        claim = notebook_claim(nb)
        try:
            claimed = normalize_learner(claim["learner"]) if claim else None
            who = given or claimed or learner_from_filename(nb)
        except GradingError as exc:
            out.append((nb, str(Path(nb).stem), f"not graded: {exc}"))
            continue
        problem = _problem(claim, claimed, who, number, secret)
        if not problem and roster is not None and who not in roster:
            problem = f"not graded: learner {who!r} is not on the roster"
        elif not problem and who in seen:
            problem = f"not graded: learner {who!r} handed in twice; graded {seen[who]}, not this one"
        elif not problem:
            seen[who] = str(nb)
        out.append((nb, who, problem))
    return out


def _problem(claim: dict, claimed: str | None, who: str, number: str, secret: bytes) -> str:
    """Why a released notebook is not graded as ``who`` ("" when it may be)."""
    if not claim:
        return ""
    if claimed != who:
        return f"not graded: released to learner {claimed!r}, not {who!r} (another learner's variant)"
    if claim["lesson"] != number:
        return f"not graded: released for lesson {claim['lesson']}, not {number}"
    if not hmac.compare_digest(claim["tag"], release_tag(secret, number, who)):
        return f"not graded: its learner id {who!r} was changed after release (the release tag does not match)"
    return ""


def missing(matched: list[tuple], roster: list[str] | None) -> list[str]:
    """The roster's learners who handed in no notebook that is graded.

    Parameters
    ----------
    matched : list of tuple
        What :func:`match` returned.
    roster : list of str or None
        The class's ids.

    Returns
    -------
    list of str
        In roster order (``[]`` without a roster).
    """
    graded = {who for _, who, problem in matched if not problem}
    return [who for who in (roster or []) if who not in graded]


def lms_path(csv_path: str | os.PathLike, fmt: str) -> Path:
    """Where ``--format canvas|moodle`` writes: ``grades.csv`` -> ``grades.canvas.csv``.

    Parameters
    ----------
    csv_path : str or os.PathLike
        The detailed CSV.
    fmt : str
        ``"canvas"`` or ``"moodle"``.

    Returns
    -------
    pathlib.Path
    """
    p = Path(csv_path)
    return p.with_name(f"{p.stem}.{fmt}.csv")


def write_lms(path, fmt: str, number: str, scores: dict, out_of: int) -> Path:
    """Write a gradebook import file: one row per learner, their score in one assignment column.

    Parameters
    ----------
    path : path
        The file to write (atomically).
    fmt : str
        ``"canvas"``: ``Student, ID, SIS User ID, SIS Login ID, Section, <assignment>`` with a
        ``Points Possible`` row, the learner id as the SIS Login ID; ``"moodle"``: ``Email
        address`` (when every id is an e-mail) or ``ID number``, then the grade.
    number : str
        The lesson (the assignment's name says it).
    scores : dict
        Learner id -> score, or None for a learner with no graded notebook (left blank).
    out_of : int
        The points possible.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        For an unknown format.
    """
    column = f"fidlearn lesson {number}"
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\r\n")
    if fmt == "canvas":
        w.writerow(["Student", "ID", "SIS User ID", "SIS Login ID", "Section", column])
        w.writerow(["Points Possible", "", "", "", "", out_of])
        for who, score in scores.items():
            w.writerow([who, "", "", who, "", "" if score is None else score])
    elif fmt == "moodle":
        email = bool(scores) and all("@" in who for who in scores)
        w.writerow(["Email address" if email else "ID number", column])
        for who, score in scores.items():
            w.writerow([who, "" if score is None else score])
    else:
        raise ValueError(f"unknown gradebook format {fmt!r}; one of {', '.join(FORMATS)}")
    return write_text_atomic(path, buf.getvalue())
