"""The intrinsics notebook in JupyterLab, in a real (headless) Chromium.

nbval proves that every cell computes what it stored; only a browser proves that a learner
who opens the notebook sees it work: JupyterLab loads, Run All Cells finishes without an
error, the widget renders, and moving a slider redraws the figure. Any JavaScript error on
the page fails the test.

The notebook is copied into a temporary folder and JupyterLab is rooted there, with its
settings, workspaces and runtime files in that folder too: the repository is never written
to. JupyterLab (and the kernel it started) is shut down and its process group killed at the
end, whatever happened.

Needs Debian's ``chromium`` (``/usr/bin/chromium``, or ``FIDLEARN_CHROMIUM``) and the
``playwright`` package (``pip install -e ".[browser]"``); ``make test-browser`` installs both. It fails,
never skips, when either is missing: it runs only when asked for.
No browser is downloaded.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from fidlearn.data import repo_dir

CHROMIUM = os.environ.get("FIDLEARN_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
NOTEBOOK_GLOB = "01_*.ipynb"
SERVER_START_S = 120
RUN_ALL_S = 300
REDRAW_S = 60


def _notebook() -> Path:
    found = sorted((repo_dir() / "notebooks").glob(NOTEBOOK_GLOB))
    assert found, f"no notebooks/{NOTEBOOK_GLOB} in {repo_dir()}"
    return found[0]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _processes_mentioning(text: str) -> list[int]:
    """Pids whose command line contains ``text`` (the kernels JupyterLab started from our runtime folder)."""
    pids = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit() or int(proc.name) == os.getpid():
            continue
        try:
            if text in (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace"):
                pids.append(int(proc.name))
        except OSError:
            continue
    return pids


class Lab:
    """JupyterLab on a free localhost port with a random token, rooted in a temporary folder."""

    def __init__(self, root: Path, home: Path):
        self.root, self.home = root, home
        self.port = _free_port()
        self.token = secrets.token_hex(16)
        self.url = f"http://127.0.0.1:{self.port}"
        settings = home / "settings" / "@jupyterlab" / "apputils-extension"
        settings.mkdir(parents=True)
        # No news and no update check: no network, and no toast over the notebook.
        (settings / "notification.jupyterlab-settings").write_text(
            json.dumps({"fetchNews": "false", "checkForUpdates": False})
        )
        notebook_settings = home / "settings" / "@jupyterlab" / "notebook-extension"
        notebook_settings.mkdir(parents=True)
        # Every cell in the page (no windowing), so that the test sees all execution counts.
        (notebook_settings / "tracker.jupyterlab-settings").write_text(json.dumps({"windowingMode": "none"}))
        self.env = {
            **os.environ,
            "JUPYTER_CONFIG_DIR": str(home / "config"),
            "JUPYTER_RUNTIME_DIR": str(home / "runtime"),
            "JUPYTER_PLATFORM_DIRS": "1",
            "IPYTHONDIR": str(home / "ipython"),
            "MPLCONFIGDIR": str(home / "matplotlib"),
            "PYTHONDONTWRITEBYTECODE": "1",
        }
        self.log = (home / "jupyterlab.log").open("w")
        self.proc: subprocess.Popen | None = None

    def start(self) -> None:
        jupyter = Path(sys.executable).with_name("jupyter")
        cmd = [
            str(jupyter),
            "lab",
            "--no-browser",
            "--ip=127.0.0.1",
            f"--port={self.port}",
            "--port-retries=0",
            f"--IdentityProvider.token={self.token}",
            f"--ServerApp.root_dir={self.root}",
            f"--LabApp.user_settings_dir={self.home / 'settings'}",
            f"--LabApp.workspaces_dir={self.home / 'workspaces'}",
            "--LabApp.news_url=",
            "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate",
            "--LabApp.extension_manager=readonly",
            "--ServerApp.terminals_enabled=False",
        ]
        if os.geteuid() == 0:  # CI runs as root
            cmd.append("--allow-root")
        self.proc = subprocess.Popen(
            cmd,
            cwd=self.root,
            env=self.env,
            stdout=self.log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        deadline = time.monotonic() + SERVER_START_S
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise AssertionError(f"JupyterLab exited with {self.proc.returncode}:\n{self.log_text()}")
            try:
                with urllib.request.urlopen(f"{self.url}/api/status?token={self.token}", timeout=2) as r:
                    if r.status == 200:
                        return
            except OSError:
                time.sleep(0.5)
        raise AssertionError(f"JupyterLab did not answer on {self.url} within {SERVER_START_S} s:\n{self.log_text()}")

    def wait_for_idle_kernel(self, timeout_s: float) -> None:
        """Wait until the notebook's session has a kernel that reports ``idle`` to the server."""
        deadline = time.monotonic() + timeout_s
        states: list = []
        while time.monotonic() < deadline:
            with urllib.request.urlopen(f"{self.url}/api/sessions?token={self.token}", timeout=5) as r:
                states = [s["kernel"]["execution_state"] for s in json.load(r) if s.get("kernel")]
            if states and all(s == "idle" for s in states):
                return
            time.sleep(0.5)
        raise AssertionError(f"the kernel is not idle after {timeout_s} s: {states}\n{self.log_text()}")

    def log_text(self) -> str:
        if not self.log.closed:
            self.log.flush()
        return (self.home / "jupyterlab.log").read_text(errors="replace")[-4000:]

    def stop(self) -> None:
        if self.proc is None:
            return
        # Shut the kernels down through the API, then stop the server and its whole process group.
        try:
            req = urllib.request.Request(f"{self.url}/api/kernels?token={self.token}")
            with urllib.request.urlopen(req, timeout=5) as r:
                for kernel in json.load(r):
                    urllib.request.urlopen(
                        urllib.request.Request(
                            f"{self.url}/api/kernels/{kernel['id']}?token={self.token}", method="DELETE"
                        ),
                        timeout=10,
                    ).close()
        except OSError:
            pass
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=15)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(timeout=15)
        # Kernels run in a session of their own: end any that the server left behind, by pid.
        for pid in _processes_mentioning(str(self.home / "runtime")):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        self.log.close()


@pytest.fixture
def lab(tmp_path):
    notebook = _notebook()
    before = _sha256(notebook)
    root = tmp_path / "notebooks"
    root.mkdir()
    shutil.copy2(notebook, root / notebook.name)
    server = Lab(root, tmp_path / "home")
    try:
        server.start()
        yield server, notebook
    finally:
        server.stop()
        assert not _processes_mentioning(str(tmp_path / "home" / "runtime")), "a kernel outlived JupyterLab"
        assert _sha256(notebook) == before, f"{notebook} was modified by the browser test"


def _settled_picture(widget, server: Lab) -> tuple[str, bytes]:
    """The widget's picture once the kernel is idle and its <img> has stopped changing: (src, PNG screenshot).

    Each slider change redraws (clear the Output, show a new <img>), so an element taken too early
    can be replaced while it is photographed.
    """
    deadline = time.monotonic() + REDRAW_S
    last = None
    while time.monotonic() < deadline:
        server.wait_for_idle_kernel(REDRAW_S)
        picture = widget.locator(".widget-output img").first
        picture.wait_for(timeout=REDRAW_S * 1000)
        src = picture.get_attribute("src")
        if src == last:
            try:
                return src, picture.screenshot()
            except Exception:  # replaced while photographed: look again
                pass
        last = src
        time.sleep(0.5)
    raise AssertionError(f"the widget's picture kept changing for {REDRAW_S} s")


def _menu(page, menu: str, item: str) -> None:
    """Click a menu of JupyterLab's menu bar, then one of its items, by their labels."""
    page.locator(".lm-MenuBar-itemLabel", has_text=re.compile(f"^{re.escape(menu)}$")).click()
    page.locator(".lm-Menu-itemLabel", has_text=re.compile(f"^{re.escape(item)}$")).click()


def _js_errors_collector(page) -> list[str]:
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(f"uncaught: {exc}"))
    page.on("console", lambda msg: errors.append(f"console.error: {msg.text}") if msg.type == "error" else None)
    return errors


def test_intrinsics_notebook_runs_and_its_slider_redraws_the_figure(lab):
    # Fail, never skip: this test runs only when asked for (make test-browser, CI), so a skip would hide it.
    try:
        from playwright import sync_api as playwright
    except ImportError:
        pytest.fail('the browser test needs playwright: pip install -e ".[browser]" (make test-browser does it)')
    assert Path(CHROMIUM).exists(), f"{CHROMIUM} is missing: apt-get install chromium (make test-browser does it)"
    server, notebook = lab
    name = notebook.name
    n_code = sum(c["cell_type"] == "code" for c in json.loads(notebook.read_text())["cells"])
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            js_errors = _js_errors_collector(page)
            page.goto(f"{server.url}/lab/tree/{name}?token={server.token}", timeout=SERVER_START_S * 1000)

            # The notebook is open, every code cell is on the page, and its kernel is ready.
            page.wait_for_function(
                "(n) => document.querySelectorAll('.jp-NotebookPanel .jp-CodeCell .jp-InputArea-prompt').length === n",
                arg=n_code,
                timeout=SERVER_START_S * 1000,
            )
            server.wait_for_idle_kernel(SERVER_START_S)

            # Edit > Clear Outputs of All Cells: the stored execution counts go, so fresh ones prove the run.
            _menu(page, "Edit", "Clear Outputs of All Cells")
            page.wait_for_function(
                """() => [...document.querySelectorAll('.jp-CodeCell .jp-InputArea-prompt')]
                          .every(p => !/\\d/.test(p.textContent))""",
                timeout=REDRAW_S * 1000,
            )
            assert page.locator(".widget-slider").count() == 0

            # Run > Run All Cells, from the menu as a learner does it.
            _menu(page, "Run", "Run All Cells")

            # Every code cell gets an execution count ([*] while it waits or runs), then the kernel idles.
            code_prompts = page.locator(".jp-CodeCell .jp-InputArea-prompt")
            try:
                page.wait_for_function(
                    """() => [...document.querySelectorAll('.jp-CodeCell .jp-InputArea-prompt')]
                              .every(p => /\\[\\d+\\]/.test(p.textContent))""",
                    timeout=RUN_ALL_S * 1000,
                )
            except Exception:
                page.screenshot(path=str(server.home / "run_all.png"))
                raise AssertionError(
                    f"Run All Cells did not finish: prompts {code_prompts.all_text_contents()}"
                ) from None
            server.wait_for_idle_kernel(RUN_ALL_S)
            counts = [int(re.search(r"\d+", t).group()) for t in code_prompts.all_text_contents()]
            assert sorted(counts) == list(range(1, n_code + 1)), f"cells ran out of order or twice: {counts}"
            assert page.locator("[data-mime-type='application/vnd.jupyter.error']").count() == 0, page.locator(
                "[data-mime-type='application/vnd.jupyter.error']"
            ).first.inner_text()

            # The widget rendered: five sliders above a picture.
            widget = page.locator(".jp-OutputArea-output .widget-vbox").filter(has=page.locator(".widget-slider")).first
            widget.wait_for(timeout=REDRAW_S * 1000)
            assert widget.locator(".widget-slider").count() == 5
            src_before, shot_before = _settled_picture(widget, server)

            fx = widget.locator(".widget-slider").filter(has=page.locator("label", has_text=re.compile(r"^fx$")))
            readout = fx.locator(".widget-readout")
            value_before = readout.inner_text()
            # Keyboard, as a learner without a mouse does it; continuous_update=False redraws on each change.
            fx.locator(".noUi-handle").focus()
            for _ in range(5):
                page.keyboard.press("ArrowRight")
            # The Output widget clears and shows a new <img>: wait for one with another picture in it,
            # then for the last of the five redraws to settle.
            page.wait_for_function(
                """(before) => {
                    const img = document.querySelector('.widget-output img');
                    return img !== null && img.getAttribute('src') !== before;
                }""",
                arg=src_before,
                timeout=REDRAW_S * 1000,
            )
            src_after, shot_after = _settled_picture(widget, server)
            value_after = readout.inner_text()
            assert float(value_after) > float(value_before), (value_before, value_after)
            assert src_after != src_before, "the figure did not change when fx moved"
            assert shot_after != shot_before, "the figure's pixels did not change when fx moved"

            assert not js_errors, "JavaScript errors on the page:\n" + "\n".join(js_errors)
        finally:
            browser.close()
