"""``make lab`` starts JupyterLab on the first notebook, as root and as an ordinary user.

The server is started exactly as the README says (``make lab``, with options that keep it
headless on a free port with a known token), the first notebook is fetched through the
server's contents API, and the server is stopped. The Makefile's own venv stamp is taken as
up to date (``make -o``) so that the test never installs anything.
"""

from __future__ import annotations

import json
import os
import pwd
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from helpers import as_unprivileged, python_paths

ROOT = Path(__file__).resolve().parent.parent
VENV = Path(sys.prefix)
FIRST = "notebooks/00_welcome.ipynb"
USER = "nobody"

pytestmark = pytest.mark.skipif(
    not (VENV / "bin" / "jupyter").exists() or shutil.which("make") is None,
    reason="needs make and JupyterLab in this Python's environment",
)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run_lab(prefix: list[str], home: Path) -> tuple[int, str]:
    """Start ``make lab``, fetch the first notebook through the API, stop it: (HTTP status, log)."""
    port, token = free_port(), secrets.token_hex(16)
    args = f"--no-browser --port={port} --ServerApp.port_retries=0 --IdentityProvider.token={token}"
    cmd = [
        *prefix,
        "env",
        f"HOME={home}",
        f"JUPYTER_RUNTIME_DIR={home}/runtime",
        f"JUPYTER_CONFIG_DIR={home}/config",
        "make",
        "--no-print-directory",
        "-C",
        str(ROOT),
        f"VENV={VENV}",
        "-o",
        f"{VENV}/.fidlearn-installed",
        "lab",
        f"LAB_ARGS={args}",
    ]
    log = home / "lab.log"
    with open(log, "wb") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        status = 0
        try:
            url = f"http://127.0.0.1:{port}/api/contents/{FIRST}?content=0"
            request = urllib.request.Request(url, headers={"Authorization": f"token {token}"})
            deadline = time.monotonic() + 90
            while time.monotonic() < deadline and proc.poll() is None:
                try:
                    with urllib.request.urlopen(request, timeout=5) as response:
                        status = response.status
                        assert json.loads(response.read())["type"] == "notebook"
                        break
                except (urllib.error.URLError, ConnectionError):
                    time.sleep(0.5)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
    return status, log.read_text(errors="replace")


def test_make_lab_serves_the_first_notebook_for_the_current_user(tmp_path):
    status, log = run_lab([], tmp_path)
    assert status == 200, log
    assert f"/lab/tree/{FIRST}?token=" in log  # the printed URL opens the first notebook
    if os.geteuid() == 0:
        assert "running as root (a container?), so JupyterLab is started with --allow-root" in log


@pytest.mark.skipif(
    as_unprivileged(0, 0, []) is None,
    reason="run as root with bubblewrap and setpriv to start the server as an unprivileged user (the other test is "
    "that case)",
)
def test_make_lab_serves_the_first_notebook_for_an_unprivileged_user():
    user = pwd.getpwnam(USER)
    home = Path(tempfile.mkdtemp(prefix="fidlearn-lab-home-"))
    try:
        os.chown(home, user.pw_uid, user.pw_gid)
        status, log = run_lab(as_unprivileged(user.pw_uid, user.pw_gid, python_paths()), home)
        assert status == 200, log
        assert "--allow-root" not in log
        assert f"/lab/tree/{FIRST}?token=" in log
    finally:
        shutil.rmtree(home, ignore_errors=True)
