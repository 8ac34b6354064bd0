"""The sandbox a submitted notebook runs in (see :mod:`fidlearn.grading`).

A notebook runs in a process of its own, in a scratch copy of its folder, with a time limit, a
memory limit, an environment without the instructor's variables and, when the grader is root, as
an unprivileged user; a cell appended to it writes the learner's answers as plain data, which the
grader reads back here (strict JSON, bounded).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from ._plain import from_plain
from .errors import FidlearnError, GradingError

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


def _run_as(user: str | None):
    """(uid, gid) to run kernels as: the named user, or 'nobody' when the grader is root; None otherwise
    (and for ``""``: the grader's own user, as a self-study check does)."""
    if user == "" or (os.geteuid() != 0 and user is None):
        return None
    import pwd

    name = user or "nobody"
    try:
        entry = pwd.getpwnam(name)
    except KeyError:
        raise GradingError(f"--run-as {name}: no such user; create one (useradd --system {name})") from None
    if os.geteuid() != 0 and entry.pw_uid != os.geteuid():
        raise GradingError(f"--run-as {name} needs the grader to run as root")
    return entry.pw_uid, entry.pw_gid


def _limits(memory_mb: int, ids):
    def apply() -> None:
        import resource

        os.setsid()
        limit = memory_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        if ids is not None:
            os.setgroups([])
            os.setgid(ids[1])
            os.setuid(ids[0])

    return apply


#: The program a notebook runs under, in its own process: execute it, keep going after errors.
_RUNNER = r"""
import sys, nbformat
from nbclient import NotebookClient
nb = nbformat.read(sys.argv[1], as_version=4)
nb.cells.append(nbformat.v4.new_code_cell(sys.argv[3]))
client = NotebookClient(nb, timeout=int(sys.argv[2]), kernel_name="python3", allow_errors=True,
                        resources={"metadata": {"path": "."}})
try:
    client.execute()
    nbformat.write(nb, "executed.ipynb")
except Exception as exc:
    kind = type(exc).__name__
    said = "timeout" if "Timeout" in kind else "dead" if "Dead" in kind else kind
    print("FIDLEARN-RUNNER " + said, file=sys.stderr)
    sys.exit(3)
"""


def _clean_env(home: Path) -> dict:
    """The kernel's whole environment: nothing of the instructor's (tokens, paths, FIDLEARN_*)."""
    env = {
        "PATH": os.defpath,
        "HOME": str(home),
        "LANG": "C.UTF-8",
        "PYTHONDONTWRITEBYTECODE": "1",
        "MPLBACKEND": "Agg",
        "JUPYTER_RUNTIME_DIR": str(home / ".runtime"),
        "JUPYTER_CONFIG_DIR": str(home / ".jupyter"),
        "IPYTHONDIR": str(home / ".ipython"),
    }
    here = str(Path(__file__).resolve().parent.parent)
    env["PYTHONPATH"] = here  # fidlearn itself, wherever it was installed from
    return env


def _read_answers(path: Path) -> dict:
    from ._files import read_bytes

    _, data = read_bytes(path, GradingError, "answers", MAX_ANSWERS_BYTES)
    record = json.loads(data.decode("utf-8"))
    if not isinstance(record, dict) or not isinstance(record.get("answers"), dict):
        raise ValueError("not an answers record")
    return {str(k): v for k, v in record["answers"].items()}


class _Zero(Exception):
    """A notebook that earns 0: the message says why (the grade's ``problem``, after ``0: ``)."""


def _scratch_copy(scratch: Path, notebook: Path, inputs_json: str | None, ids) -> tuple[Path, Path]:
    """The scratch folders ``work`` (the notebook and, when graded, its inputs file) and ``home``."""
    work, home = scratch / "work", scratch / "home"
    work.mkdir()
    home.mkdir()
    try:
        shutil.copyfile(notebook, work / "submission.ipynb")
    except OSError as exc:
        raise _Zero(f"the notebook cannot be read ({exc.strerror})") from None
    if inputs_json is not None:
        (work / INPUTS_FILE).write_text(inputs_json, encoding="utf-8")
    if ids is not None:
        for p in (scratch, work, home, *work.iterdir()):
            os.chown(p, *ids)
    return work, home


def _run_and_collect(work: Path, env: dict, timeout_s: int, memory_mb: int, ids) -> dict:
    """Run ``work/submission.ipynb`` in a process of its own and read back its answers (plain data)."""
    cmd = [sys.executable, "-c", _RUNNER, "submission.ipynb", str(max(5, timeout_s)), COLLECT_CELL]
    proc = None
    try:
        proc = subprocess.Popen(
            cmd,
            cwd=work,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            preexec_fn=_limits(memory_mb, ids),
        )
        try:
            _, err = proc.communicate(timeout=timeout_s + 60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise _Zero(f"the notebook ran longer than {timeout_s} s and was stopped") from None
    finally:
        _kill_group_leftovers(proc)
    answers_path = work / ANSWERS_FILE
    if not answers_path.is_file() or answers_path.is_symlink():
        said = [ln for ln in err.decode("utf-8", "replace").splitlines() if ln.startswith("FIDLEARN-RUNNER ")]
        kind = said[-1].split(" ", 1)[1] if said else ""
        why = {
            "timeout": f"a cell ran longer than {timeout_s} s and was stopped",
            "dead": "its kernel died (it used more than the memory limit, or killed or exited itself)",
        }.get(kind, f"it stopped before its answers were collected ({kind or 'no reason given'})")
        raise _Zero(f"{why}; no answers were collected")
    try:
        raw = _read_answers(answers_path)
        return {name: from_plain(value) for name, value in raw.items()}
    except (ValueError, TypeError, KeyError, RecursionError, FidlearnError) as exc:
        raise _Zero(f"its answers are not plain data ({str(exc)[:80]})") from None


def _preflight(ids, run_as: str | None) -> None:
    """The notebooks' user must be able to run this Python and import fidlearn and nbclient."""
    if ids is None:
        return
    home = Path(tempfile.mkdtemp(prefix="fidlearn-grade-check-"))
    try:
        os.chown(home, *ids)
        out = subprocess.run(
            [sys.executable, "-c", "import fidlearn, nbclient, ipykernel"],
            cwd=home,
            env=_clean_env(home),
            capture_output=True,
            text=True,
            timeout=120,
            preexec_fn=_limits(4000, ids),
        )
    finally:
        shutil.rmtree(home, ignore_errors=True)
    if out.returncode != 0:
        who = run_as or "nobody"
        last = (out.stderr.strip().splitlines() or [f"it exited with status {out.returncode:d}"])[-1]
        raise GradingError(
            f"the user {who} cannot run {sys.executable} with fidlearn ({last[:120]}); install "
            "Python and fidlearn where that user can read them (see docs/teaching.md), or pass "
            "--run-as a user who can"
        )


def _cell_errors(path: Path) -> list[str]:
    """``cell N raised NAME: VALUE`` for each failing cell of the executed notebook (information only)."""
    try:
        if not path.is_file() or path.is_symlink() or path.stat().st_size > 50_000_000:
            return []
        nb = json.loads(path.read_text(encoding="utf-8"))
        out = []
        for i, cell in enumerate(nb.get("cells", [])[:-1]):
            for o in cell.get("outputs", []) or []:
                if isinstance(o, dict) and o.get("output_type") == "error":
                    out.append(f"cell {i} raised {str(o.get('ename'))[:60]}: {str(o.get('evalue'))[:120]}")
        return out[:50]
    except (OSError, ValueError, AttributeError):
        return []


def _kill_group_leftovers(proc) -> None:
    if proc is not None:
        with contextlib.suppress(ProcessLookupError, PermissionError, OSError):
            os.killpg(proc.pid, signal.SIGKILL)  # a kernel left running by a notebook that detached it
