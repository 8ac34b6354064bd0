"""The box a submitted notebook runs in: bubblewrap's namespaces, the runner, limits, bounded output.

With bubblewrap (``bwrap``) a notebook sees a root of its own: the system folders, the Python
and fidlearn read-only, a size-limited ``/tmp`` (its working folder and ``HOME``), a fresh
``/proc`` of its own process namespace, no network. Nothing else of the machine is there: not the
submissions, not the class secret, not the grader's environment. The runner below starts inside
it, lowers its limits (CPU time, memory, processes, open files, file size), drops to the
notebook's user when the grader is root, executes the notebook and sends the answers back through
a pipe. When the runner ends, the kernel tears its process namespace down: nothing a notebook
started outlives its grading.

As root, bubblewrap runs without a user namespace and the runner itself becomes the notebook's
user: ``bwrap --unshare-user --uid 65534`` would only rename root inside the box (the process
would still own, and read, root's files), whereas ``setuid`` makes it the real ``nobody``. Its
own user namespace, made afterwards, gives the box a process count of its own.
"""

from __future__ import annotations

import contextlib
import os
import selectors
import signal
import subprocess
import sys
import time
from pathlib import Path

#: Where the notebook's folders are, inside the box (a tmpfs).
BOX_TMP = "/tmp"
#: Where the grader's inputs (the submission, the inputs file) are bound read-only, inside the box.
BOX_IN = "/fidlearn-in"
#: Size of the box's ``/tmp`` (the notebook's working folder and home), bytes.
TMP_BYTES = 1 << 30
#: Largest file a notebook may write, bytes.
MAX_FILE_BYTES = 256 << 20
#: Processes (and threads) a notebook may have at once.
MAX_PROCESSES = 256
#: Files a notebook's process may have open.
MAX_OPEN_FILES = 1024
#: Bytes of the notebook's stdout and stderr kept (the rest is read and dropped).
KEEP_OUTPUT_BYTES = 64_000

_SYSTEM = ("/usr", "/bin", "/sbin", "/lib", "/lib64", "/lib32", "/libx32", "/etc")

#: The program a notebook runs under: limits, the user, the notebook executed, the answers sent.
RUNNER = r"""
import json, os, resource, shutil, sys
cfg = json.loads(sys.argv[1])
out = os.fdopen(cfg["fd"], "wb")

def send(status, errors=(), answers=b""):
    out.write(json.dumps({"status": status, "cell_errors": list(errors)[:50]}).encode() + b"\n" + answers)
    out.close()

def own_userns(uid, gid):
    import ctypes
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(38, 1, 0, 0, 0)  # no new privileges: no setuid program gives them back
    if libc.unshare(0x10000000) != 0:  # a user namespace: the process count is this box's own
        return
    for name, text in (("setgroups", "deny"), ("uid_map", f"{uid} {uid} 1"), ("gid_map", f"{gid} {gid} 1")):
        try:
            with open(f"/proc/self/{name}", "w") as f:
                f.write(text)
        except OSError:
            pass

if cfg["uid"] is not None:
    hard = resource.getrlimit(resource.RLIMIT_NPROC)[1]
    resource.setrlimit(resource.RLIMIT_NPROC, (hard, hard))  # the box's own limit comes in its namespace
    os.setgroups([])
    os.setgid(cfg["gid"])
    os.setuid(cfg["uid"])
own_userns(os.getuid(), os.getgid())
for name, value in cfg["limits"].items():
    resource.setrlimit(getattr(resource, name), (value, value))
for folder in (cfg["work"], cfg["home"]):
    os.makedirs(folder, exist_ok=True)
if cfg.get("check"):  # can this user run this Python with fidlearn and Jupyter?
    import fidlearn, ipykernel, nbclient, nbformat
    send("ok")
    sys.exit(0)
if cfg["inbox"] != cfg["work"]:
    for name in os.listdir(cfg["inbox"]):
        shutil.copyfile(os.path.join(cfg["inbox"], name), os.path.join(cfg["work"], name))
os.chdir(cfg["work"])
try:
    import nbformat
    from nbclient import NotebookClient
    nb = nbformat.read("submission.ipynb", as_version=4)
    nb.cells.append(nbformat.v4.new_code_cell(cfg["cell"]))
    NotebookClient(nb, timeout=cfg["timeout"], kernel_name="python3", allow_errors=True,
                   resources={"metadata": {"path": "."}}).execute()
except BaseException as exc:
    kind = type(exc).__name__
    send("timeout" if "Timeout" in kind else "dead" if "Dead" in kind else kind[:60])
    sys.exit(3)
errors = []
for i, cell in enumerate(nb.cells[:-1]):
    for o in cell.get("outputs", []) or []:
        if isinstance(o, dict) and o.get("output_type") == "error":
            errors.append(f"cell {i} raised {str(o.get('ename'))[:60]}: {str(o.get('evalue'))[:120]}")
try:
    with open(cfg["answers"], "rb") as f:
        send("ok", errors, f.read(cfg["max_answers"] + 1))
except OSError:
    send("no answers", errors)
"""


def bwrap_path() -> str | None:
    """The ``bwrap`` program on ``PATH`` (None when bubblewrap is not installed)."""
    import shutil

    return shutil.which("bwrap")


def python_mounts() -> list[str]:
    """The folders the notebook's Python needs: the interpreter's installation, the venv, fidlearn."""
    from ..data import repo_dir

    paths = {sys.base_prefix, sys.prefix, str(Path(os.path.realpath(sys.executable)).parent)}
    here = Path(__file__).resolve().parent.parent  # the fidlearn package
    paths.add(str(here))
    if (repo_dir() / "data").is_dir():
        paths.add(str(repo_dir() / "data"))
    for entry in sys.path:  # site-packages folders outside the prefixes (a --user install, ...)
        if entry.endswith("-packages") and os.path.isdir(entry):
            paths.add(entry)
    kept = sorted(p for p in paths if os.path.isdir(p))
    # a folder inside another bound one adds nothing
    return [p for p in kept if not any(p != q and p.startswith(q.rstrip("/") + "/") for q in kept)]


def bwrap_command(bwrap: str, inbox: Path, env: dict) -> list[str]:
    """The bubblewrap command line (up to the program) for one notebook whose inputs are ``inbox``."""
    cmd = [bwrap, "--unshare-pid", "--unshare-net", "--unshare-ipc", "--unshare-uts", "--unshare-cgroup-try"]
    cmd += ["--die-with-parent", "--new-session", "--clearenv"]
    if os.geteuid() != 0:  # an ordinary user's bubblewrap needs a user namespace (its own uid inside)
        cmd += ["--unshare-user"]
    for folder in _SYSTEM:
        cmd += ["--ro-bind-try", folder, folder]
    # the scratch /tmp first: a Python or a checkout that lives under /tmp is bound on top of it
    cmd += ["--dev", "/dev", "--proc", "/proc", "--perms", "1777", "--size", str(TMP_BYTES), "--tmpfs", BOX_TMP]
    mounts = python_mounts()
    above = {str(a) for m in mounts for a in Path(m).parents if str(a) != "/"}
    opened = sorted(
        (a for a in above if a != BOX_TMP and not any(a == s or a.startswith(s + "/") for s in _SYSTEM)), key=len
    )
    for folder in opened:  # open to the notebook's user, whatever the modes of the machine's folders
        cmd += ["--perms", "0755", "--dir", folder]
    for folder in mounts:
        cmd += ["--ro-bind", folder, folder]
    cmd += ["--ro-bind", str(inbox), BOX_IN, "--chdir", BOX_TMP]
    for key, value in env.items():
        cmd += ["--setenv", key, value]
    return cmd


def limits(memory_mb: int, timeout_s: int) -> dict:
    """The resource limits of a notebook's processes (names of :mod:`resource`'s constants)."""
    return {
        "RLIMIT_AS": memory_mb * 1024 * 1024,
        "RLIMIT_CPU": timeout_s + 30,
        "RLIMIT_NPROC": MAX_PROCESSES,
        "RLIMIT_NOFILE": MAX_OPEN_FILES,
        "RLIMIT_FSIZE": MAX_FILE_BYTES,
        "RLIMIT_CORE": 0,
    }


def run_bounded(cmd: list[str], *, wall_s: float, max_channel: int, **popen) -> tuple[str, bytes, bytes]:
    """Run ``cmd`` in a session of its own; read its output (kept up to a cap) and its channel pipe.

    The command gets the pipe's writing end as ``{fd}`` in its arguments (formatted here). Returns
    ``(how, channel, output)``: ``how`` is ``"exited"`` or ``"timeout"``; the channel bytes are
    cut at ``max_channel`` and the output (stdout and stderr) at :data:`KEEP_OUTPUT_BYTES`. The
    whole process group is killed when the command ends or runs out of time.
    """
    read_end, write_end = os.pipe()
    cmd = [c.replace("{fd}", str(write_end)) for c in cmd]
    proc = None
    try:
        proc = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            pass_fds=(write_end,),
            start_new_session=True,
            **popen,
        )
        os.close(write_end)
        write_end = -1
        return _pump(proc, read_end, wall_s, max_channel)
    finally:
        if write_end >= 0:
            os.close(write_end)
        os.close(read_end)
        if proc is not None:
            _kill(proc)


def _pump(proc, channel_fd: int, wall_s: float, max_channel: int) -> tuple[str, bytes, bytes]:
    deadline = time.monotonic() + wall_s
    kept = {channel_fd: bytearray(), proc.stdout.fileno(): bytearray()}
    caps = {channel_fd: max_channel, proc.stdout.fileno(): KEEP_OUTPUT_BYTES}
    with selectors.DefaultSelector() as sel:
        for fd in kept:
            sel.register(fd, selectors.EVENT_READ)
        while sel.get_map():
            if proc.poll() is not None:  # ended: what is still in the pipes comes within a moment
                deadline = min(deadline, time.monotonic() + 2.0)
            left = deadline - time.monotonic()
            if left <= 0:
                how = "exited" if proc.poll() is not None else "timeout"
                return how, bytes(kept[channel_fd]), bytes(kept[proc.stdout.fileno()])
            for key, _ in sel.select(timeout=min(left, 1.0)):
                chunk = os.read(key.fd, 65536)
                if not chunk:
                    sel.unregister(key.fd)
                elif len(kept[key.fd]) < caps[key.fd]:
                    kept[key.fd] += chunk[: caps[key.fd] + 1 - len(kept[key.fd])]
    try:
        proc.wait(timeout=max(1.0, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:
        return "timeout", bytes(kept[channel_fd]), bytes(kept[proc.stdout.fileno()])
    return "exited", bytes(kept[channel_fd]), bytes(kept[proc.stdout.fileno()])


def _kill(proc) -> None:
    """Kill the command's whole process group and wait for it (a box takes its namespace with it)."""
    with contextlib.suppress(ProcessLookupError, PermissionError, OSError):
        os.killpg(proc.pid, signal.SIGKILL)
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=30)
    if proc.stdout is not None:
        proc.stdout.close()
