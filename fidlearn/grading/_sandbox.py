"""The sandbox a submitted notebook runs in (see :mod:`fidlearn.grading`).

Each notebook runs in a box of its own (:mod:`fidlearn.grading._box`): with bubblewrap, a root of its own
that holds only the system, the Python and fidlearn (read-only) and a size-limited scratch
folder, no network, its own process namespace (everything it started dies with it), resource
limits, an environment without the instructor's variables and, when the grader is root, the
user ``nobody``. Without bubblewrap it runs as a plain process of that user, in a scratch folder
(see docs/teaching.md for what that does not guarantee). A cell appended to the notebook writes
its answers as plain data, which the grader reads back here with strict bounds.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .._plain import from_plain
from ..errors import GradingError
from . import _box

#: The inputs file a released notebook works with.
INPUTS_FILE = "fidlearn_inputs.json"
#: What the appended collection cell writes in the scratch folder.
ANSWERS_FILE = "fidlearn_answers.json"
#: Largest answers file read (bytes): far above any honest set of answers.
MAX_ANSWERS_BYTES = 5_000_000

COLLECT_CELL = (
    "import json as _fl_json, os as _fl_os\n"
    "from fidlearn import grading as _fl_grading\n"
    "_fl_grading.collect(globals())\n"
)

_FIX = "install bubblewrap (apt-get install bubblewrap) or pass --run-as a user who can run that Python"


@dataclass(frozen=True)
class Plan:
    """How notebooks run: as whom (``ids`` None: the grader's own user), in a box or not, and what to warn."""

    user: str
    ids: tuple | None
    bwrap: str | None
    warning: str = ""


class _Zero(Exception):
    """A notebook that earns 0: the message says why (the grade's ``problem``, after ``0: ``)."""


def _run_as(user: str | None) -> tuple[str, tuple | None]:
    """(name, (uid, gid)) of the notebooks' user: ``user``, or nobody when the grader is root; ids None
    for the grader's own user."""
    import pwd

    if user is not None and not user.strip():
        raise GradingError("--run-as needs a user's name (without it, notebooks run as nobody when graded as root)")
    if user is None and os.geteuid() != 0:
        return pwd.getpwuid(os.geteuid()).pw_name, None
    name = user or "nobody"
    try:
        entry = pwd.getpwnam(name)
    except KeyError:
        raise GradingError(f"--run-as {name}: no such user; give an existing user (e.g. nobody)") from None
    if os.geteuid() != 0:
        if entry.pw_uid != os.geteuid():
            raise GradingError(f"--run-as {name} needs the grader to run as root")
        return name, None
    return name, (entry.pw_uid, entry.pw_gid)


@functools.lru_cache(maxsize=8)
def sandbox_plan(run_as: str | None = None) -> Plan:
    """How this machine runs notebooks for ``run_as``: in bubblewrap when it works, else plainly.

    Raises GradingError when neither works (the notebooks' user cannot run this Python).
    """
    name, ids = _run_as(run_as)
    warning = ""
    if ids is not None and ids[0] == 0:
        warning = f"--run-as {name}: notebooks run as root and can read the class secret and every file here"
    bwrap = _box.bwrap_path()
    why = "bubblewrap is not installed"
    if bwrap is not None:
        failed = _check(Plan(name, ids, bwrap))
        if not failed:
            return Plan(name, ids, bwrap, warning)
        why = f"bubblewrap cannot make a sandbox here ({failed})"
    failed = _check(Plan(name, ids, None))
    if failed:
        raise GradingError(f"the user {name} cannot run {sys.executable} ({failed}); {_FIX}")
    if not warning:
        reach = "what you can (the class secret included)" if ids is None else f"every file {name} can"
        warning = f"{why}: notebooks are not boxed and can read {reach}; install bubblewrap: apt-get install bubblewrap"
    return Plan(name, ids, None, warning)


def _check(plan: Plan) -> str:
    """An empty string when ``plan``'s user can run this Python with fidlearn and Jupyter in its box; else why not."""
    try:
        how, channel, output = _launch(plan, None, _config(plan, 60, 2000, check=True), wall_s=120)
    except OSError as exc:
        where = _closed_folder(os.path.realpath(sys.executable), plan.ids)
        return f"{exc.strerror or exc}: {where or exc.filename}"
    if channel.startswith(b'{"status": "ok"'):
        return ""
    lines = output.decode("utf-8", "replace").strip().splitlines()
    return (lines or [f"it {how} without a word"])[-1][:160]


def _closed_folder(path: str, ids) -> str:
    """The first folder above ``path`` that others cannot enter (for the message), or ""."""
    if ids is None:
        return ""
    for folder in reversed(Path(os.path.abspath(path)).parents):
        st = folder.stat()
        if not st.st_mode & 0o001 and st.st_uid != ids[0]:
            return f"{folder} is closed to others (mode {st.st_mode & 0o777:o})"
    return ""


def _clean_env(home: str) -> dict:
    """The kernel's whole environment: nothing of the instructor's (tokens, paths, FIDLEARN_*)."""
    return {
        "PATH": os.defpath,
        "HOME": home,
        "LANG": "C.UTF-8",
        "PYTHONDONTWRITEBYTECODE": "1",
        "MPLBACKEND": "Agg",
        "JUPYTER_RUNTIME_DIR": f"{home}/.runtime",
        "JUPYTER_CONFIG_DIR": f"{home}/.jupyter",
        "IPYTHONDIR": f"{home}/.ipython",
        "PYTHONPATH": str(Path(__file__).resolve().parents[2]),  # fidlearn itself, wherever it is
    }


def _config(plan: Plan, timeout_s: int, memory_mb: int, scratch: Path | None = None, check: bool = False) -> dict:
    """The runner's settings: where its folders are, its user, its limits."""
    if plan.bwrap is not None:
        work, home, inbox = f"{_box.BOX_TMP}/work", f"{_box.BOX_TMP}/home", _box.BOX_IN
    else:
        base = scratch if scratch is not None else Path(tempfile.gettempdir())
        work, home = str(base / "work"), str(base / "home")
        inbox = work
    return {
        "fd": "{fd}",
        "uid": plan.ids[0] if plan.ids and plan.bwrap else None,
        "gid": plan.ids[1] if plan.ids and plan.bwrap else None,
        "limits": _box.limits(memory_mb, timeout_s),
        "work": work,
        "home": home,
        "inbox": inbox,
        "timeout": max(5, timeout_s),
        "cell": COLLECT_CELL,
        "answers": ANSWERS_FILE,
        "max_answers": MAX_ANSWERS_BYTES,
        "check": check,
    }


def _launch(plan: Plan, scratch: Path | None, cfg: dict, *, wall_s: float, env: dict | None = None):
    """Run the runner with ``cfg`` as ``plan`` says; (how it ended, channel bytes, output bytes)."""
    env = dict(_clean_env(cfg["home"]), **(env or {}))
    args = [sys.executable, "-c", _box.RUNNER, json.dumps(cfg).replace('"{fd}"', "{fd}")]
    cap = MAX_ANSWERS_BYTES + 100_000
    if plan.bwrap is not None:
        inbox = scratch / "in" if scratch is not None else Path(tempfile.mkdtemp(prefix="fidlearn-grade-check-"))
        inbox.chmod(0o755)
        try:
            cmd = _box.bwrap_command(plan.bwrap, inbox, env) + args
            return _box.run_bounded(cmd, wall_s=wall_s, max_channel=cap)
        finally:
            if scratch is None:
                shutil.rmtree(inbox, ignore_errors=True)
    home = Path(cfg["home"])
    if scratch is None:  # the check: a home of its own for the user
        home = Path(tempfile.mkdtemp(prefix="fidlearn-grade-check-"))
        cfg = dict(cfg, work=str(home / "work"), home=str(home / "home"), inbox=str(home / "work"))
        env = dict(_clean_env(cfg["home"]))
        args[-1] = json.dumps(cfg).replace('"{fd}"', "{fd}")
    user = {} if plan.ids is None else {"user": plan.ids[0], "group": plan.ids[1], "extra_groups": []}
    try:
        if plan.ids is not None:
            os.chown(home if scratch is None else scratch, *plan.ids)
        return _box.run_bounded(args, wall_s=wall_s, max_channel=cap, cwd="/", env=env, **user)
    finally:
        if scratch is None:
            shutil.rmtree(home, ignore_errors=True)


def _scratch_copy(scratch: Path, notebook: Path, inputs_json: str | None, plan: Plan) -> None:
    """Lay out the scratch folder: ``in/`` (bubblewrap) or ``work/`` and ``home/`` (plain)."""
    inbox = scratch / ("in" if plan.bwrap else "work")
    inbox.mkdir()
    try:
        shutil.copyfile(notebook, inbox / "submission.ipynb")
    except OSError as exc:
        raise _Zero(f"the notebook cannot be read ({exc.strerror})") from None
    if inputs_json is not None:
        (inbox / INPUTS_FILE).write_text(inputs_json, encoding="utf-8")
    if plan.bwrap:  # bound read-only in the box; the folder above it stays closed
        inbox.chmod(0o755)
        for p in inbox.iterdir():
            p.chmod(0o644)
        return
    (scratch / "home").mkdir()
    if plan.ids is not None:
        for p in (scratch, inbox, scratch / "home", *inbox.iterdir()):
            os.chown(p, *plan.ids)


def run_notebook(notebook: Path, inputs_json: str | None, plan: Plan, timeout_s: int, memory_mb: int, *, env=None):
    """Run one notebook in its box; (answers as plain data parsed, cell errors). Raises _Zero."""
    scratch = Path(tempfile.mkdtemp(prefix="fidlearn-grade-"))
    try:
        _scratch_copy(scratch, notebook, inputs_json, plan)
        cfg = _config(plan, timeout_s, memory_mb, scratch)
        how, channel, _ = _launch(plan, scratch, cfg, wall_s=timeout_s + 60, env=env)
    except OSError as exc:
        raise _Zero(f"its sandbox could not be started ({exc.strerror or exc})") from None
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    head, _, answers = channel.partition(b"\n")
    try:
        said = json.loads(head.decode("utf-8")) if len(head) < 100_000 else {}
        status, errors = str(said["status"]), [str(e)[:200] for e in said["cell_errors"]][:50]
    except (ValueError, TypeError, KeyError, RecursionError):
        if how == "timeout":
            raise _Zero(f"the notebook ran longer than {timeout_s} s and was stopped") from None
        raise _Zero("it stopped before its answers were collected (no reason given)") from None
    if status != "ok":
        why = {
            "timeout": f"a cell ran longer than {timeout_s} s and was stopped",
            "dead": "its kernel died (it used more than a limit, or killed or exited itself)",
        }.get(status, f"it stopped before its answers were collected ({status[:60]})")
        raise _Zero(f"{why}; no answers were collected")
    return answers, errors


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"the number {text[:20]} is not finite")
    return value


def _short_int(text: str) -> int:
    if len(text) > 40:
        raise ValueError("an integer of more than 40 digits")
    return int(text)


def _no_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


def read_answers(data: bytes, names) -> dict:
    """The answers record ``data`` (bytes a notebook wrote) as ``{question: value}``, strictly.

    At most :data:`MAX_ANSWERS_BYTES`, UTF-8 JSON, finite numbers only, the one key ``answers``
    holding the lesson's question names (``names``) only, each value plain data nested at most
    ``MAX_DEPTH`` deep with bounded arrays. Anything else raises _Zero with the reason.
    """
    if len(data) > MAX_ANSWERS_BYTES:
        raise _Zero(f"its answers file is larger than {MAX_ANSWERS_BYTES // 1_000_000} MB")
    try:
        record = json.loads(
            data.decode("utf-8"), parse_float=_finite, parse_int=_short_int, parse_constant=_no_constant
        )
        if not isinstance(record, dict) or set(record) != {"answers"} or not isinstance(record["answers"], dict):
            raise ValueError("not an answers record")
        unknown = sorted(set(record["answers"]) - set(names))
        if unknown:
            raise ValueError(f"questions this lesson does not have: {', '.join(unknown)[:60]}")
        return {k: from_plain(v) for k, v in record["answers"].items()}
    except RecursionError:
        raise _Zero("its answers are not plain data (nested too deeply)") from None
    except Exception as exc:  # noqa: BLE001 - whatever a crafted file does is this learner's 0
        raise _Zero(f"its answers are not plain data ({str(exc)[:80] or type(exc).__name__})") from None
