"""The camera widget in a real (headless) Chromium whose camera plays a video of known poses.

``fidlearn.synthetic`` renders a short drive past the seed's markers (``data/world_map.json``,
the ``data/trajectory`` camera), written as a Y4M video that Chromium's fake camera plays
(``--use-file-for-fake-video-capture``, looping). JupyterLab runs notebook 12 with
``FIDLEARN_WEBCAM=1``, so its camera cells run: the widget opens the camera, a snapshot
reaches the kernel, and the live-pose cell streams frames through ``MarkerTracker``.

The fake camera shows markers, never a checkerboard, so the notebook's live calibration
captures nothing; ``out/my_camera/camera.json`` holds the video's true camera beforehand,
as a calibration from an earlier session would.

Checked, by reading the kernel's variables through a second kernel client:

* the snapshot's gray picture equals the source frame it came from: at most 1 gray level
  apart (PNG over the comm is lossless; Y4M video range squeezes 256 levels onto 220);
* every streamed frame is identified among the source frames (mean difference under
  2 gray levels with JPEG 0.92 over the comm, every other frame at least 4 levels away),
  and the pose the notebook computed from it is within 5 mm of that frame's true pose;
* the stream kept to ``max_fps`` (5) and the widget reports the delivered 640 x 480.
"""

from __future__ import annotations

import contextlib
import glob
import json
import os
import queue
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from test_lab import (
    CHROMIUM,
    CHROMIUM_ARGS,
    REDRAW_S,
    SERVER_START_S,
    Lab,
    _js_errors_collector,
    _menu,
)

from fidlearn import Camera, MarkerMap, data_path, render_trajectory
from fidlearn.data import repo_dir
from tests.y4m import write_y4m

NOTEBOOK = "12_your_own_camera.ipynb"
N_FRAMES = 8
REPEAT = 3  # each source frame is shown 3 video frames long (0.3 s at 10 fps)
RUN_ALL_S = 240
STREAM_S = 90
MIN_LOGGED = 12
POSE_TOL_MM = 5.0


@pytest.fixture
def drive():
    camera = Camera.load(data_path("trajectory", "camera.json"))
    world = MarkerMap.load(data_path("world_map.json"))
    return render_trajectory(
        world,
        camera,
        n_frames=N_FRAMES,
        seed=29,
        start_distance_mm=900,
        end_distance_mm=500,
        start_lateral_mm=-250,
        end_lateral_mm=250,
        noise_std_gray=1.0,
    )


@pytest.fixture
def camera_lab(tmp_path, drive):
    notebook = repo_dir() / "notebooks" / NOTEBOOK
    assert notebook.exists(), f"{notebook} is missing: python tools/nbbuild.py notebooks/src/12_your_own_camera.py"
    root = tmp_path / "course" / "notebooks"
    root.mkdir(parents=True)
    shutil.copy2(notebook, root / NOTEBOOK)
    # The notebook writes to ../out/my_camera: the video's true camera stands in for an earlier calibration.
    (root.parent / "out" / "my_camera").mkdir(parents=True)
    drive.camera.save(root.parent / "out" / "my_camera" / "camera.json")
    video = write_y4m(tmp_path / "drive.y4m", [image for image in drive.images for _ in range(REPEAT)], fps=10)
    server = Lab(root, tmp_path / "home")
    server.env["FIDLEARN_WEBCAM"] = "1"
    server.env["PYTHONPATH"] = os.pathsep.join([str(repo_dir())] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    try:
        server.start()
        yield server, video
    finally:
        server.stop()


def _kernel_client(server: Lab):
    from jupyter_client import BlockingKernelClient

    files = glob.glob(str(server.home / "runtime" / "kernel-*.json"))
    assert len(files) == 1, f"expected one kernel, found {files}"
    client = BlockingKernelClient(connection_file=files[0])
    client.load_connection_file()
    client.start_channels()
    # Not client.wait_for_ready: after the kernel's reply it drains IOPub until IOPub is quiet for 0.2 s, which
    # never happens while the notebook streams frames (every frame updates a widget). Ask kernel_info and wait
    # for its reply, then for any IOPub message (the kernel's busy/idle status), so IOPub is connected too.
    deadline = time.monotonic() + 30
    while True:
        msg_id = client.kernel_info()
        with contextlib.suppress(queue.Empty):
            while (
                client.get_shell_msg(timeout=max(0.1, deadline - time.monotonic()))["parent_header"].get("msg_id")
                != msg_id
            ):
                pass
            client.get_iopub_msg(timeout=2)
            return client
        assert time.monotonic() < deadline, "the notebook's kernel did not answer kernel_info in 30 s"


def _run(client, code: str) -> str:
    out: list[str] = []

    def hook(msg):
        if msg["msg_type"] == "stream":
            out.append(msg["content"]["text"])
        elif msg["msg_type"] == "error":
            out.append("\n".join(msg["content"]["traceback"]))

    reply = client.execute_interactive(code, timeout=60, output_hook=hook)
    assert reply["content"]["status"] == "ok", "".join(out)
    return "".join(out)


def _identify(gray: np.ndarray, sources: list[np.ndarray]) -> tuple[int, float, float]:
    """(index of the nearest source frame, its mean |difference|, the next nearest's)."""
    diffs = np.array([np.abs(gray.astype(np.int16) - s).mean() for s in sources])
    order = np.argsort(diffs)
    return int(order[0]), float(diffs[order[0]]), float(diffs[order[1]])


def test_fake_camera_frames_reach_the_kernel_and_give_the_true_poses(camera_lab, drive, tmp_path):
    try:
        from playwright import sync_api as playwright
    except ImportError:
        pytest.fail('the browser test needs playwright: pip install -e ".[browser]" (make test-browser does it)')
    assert Path(CHROMIUM).exists(), f"{CHROMIUM} is missing: apt-get install chromium (make test-browser does it)"
    server, video = camera_lab
    fake_camera = [
        "--use-fake-ui-for-media-stream",
        "--use-fake-device-for-media-stream",
        f"--use-file-for-fake-video-capture={video}",
    ]
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS + fake_camera)
        client = None
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            js_errors = _js_errors_collector(page)
            page.goto(f"{server.url}/lab/tree/{NOTEBOOK}?token={server.token}", timeout=SERVER_START_S * 1000)
            page.wait_for_selector(".jp-NotebookPanel .jp-CodeCell", timeout=SERVER_START_S * 1000)
            server.wait_for_idle_kernel(SERVER_START_S)
            _menu(page, "Edit", "Clear Outputs of All Cells")
            _menu(page, "Run", "Run All Cells")
            try:
                page.wait_for_function(
                    """() => [...document.querySelectorAll('.jp-CodeCell .jp-InputArea-prompt')]
                              .every(p => /\\[\\d+\\]/.test(p.textContent))""",
                    timeout=RUN_ALL_S * 1000,
                )
            except playwright.TimeoutError:
                page.screenshot(path=str(server.home / "run_all.png"))
                raise AssertionError("Run All Cells did not finish") from None
            errors = page.locator("[data-mime-type='application/vnd.jupyter.error']")
            assert errors.count() == 0, errors.first.inner_text()
            # The live pose is on the page, printed by the streaming callback.
            page.wait_for_function(
                "() => [...document.querySelectorAll('.widget-html')].some(e => e.textContent.includes('camera at x'))",
                timeout=STREAM_S * 1000,
            )
            assert page.locator(".fidlearn-webcam video").first.is_visible()

            client = _kernel_client(server)
            deadline = time.monotonic() + STREAM_S
            while int(_run(client, "print(len(live_log))")) < MIN_LOGGED:
                assert time.monotonic() < deadline, f"fewer than {MIN_LOGGED} frames located in {STREAM_S} s"
                time.sleep(1)
            dump = tmp_path / "live.npz"
            facts = json.loads(
                _run(
                    client,
                    f"""
import json, numpy as np
cam.stop()
log = list(live_log)
np.savez({str(dump)!r}, snapshot=frame, grays=np.array([g for g, _ in log]),
         T=np.array([np.full((4, 4), np.nan) if p is None else p.T_world_camera for _, p in log]))
print(json.dumps(dict(status=cam.status, size=[cam.actual_width, cam.actual_height], fps=cam.pacer.measured_fps,
                      frames=cam.frames_received, error=repr(cam.last_error))))
""",
                )
            )
            assert not js_errors, "JavaScript errors on the page:\n" + "\n".join(js_errors)
        finally:
            if client is not None:
                client.stop_channels()
            browser.close()

    assert facts["status"] == "streaming", facts
    assert facts["size"] == [640, 480], facts
    assert facts["error"] == "None", facts
    assert 0 < facts["fps"] <= 5.5, f"the stream ran at {facts['fps']:.2f} fps, max_fps is 5"
    sources = drive.images
    with np.load(dump) as npz:
        data = {name: npz[name] for name in npz.files}

    # The snapshot (PNG over the comm) is one of the rendered frames, to a gray level.
    snap_gray = data["snapshot"][..., 1]
    assert (data["snapshot"][..., 0] == snap_gray).all()
    assert (data["snapshot"][..., 2] == snap_gray).all()
    snap_k, best, second = _identify(snap_gray, sources)
    assert np.abs(snap_gray.astype(int) - sources[snap_k]).max() <= 1, (snap_k, best)
    assert second > 4, f"frames {snap_k} and its nearest neighbour are too alike to tell apart ({second:.2f})"

    # Every streamed frame is a rendered one, and its pose is that frame's truth within 5 mm.
    seen, errors_mm = set(), []
    for i, (gray, T) in enumerate(zip(data["grays"], data["T"])):
        k, best, second = _identify(gray, sources)
        assert best < 2.0, f"streamed frame {i}: nearest source {k} at {best:.2f}, next {second:.2f}"
        assert second > 4.0, f"streamed frame {i}: nearest source {k} at {best:.2f}, next {second:.2f}"
        assert not np.isnan(T).any(), f"streamed frame {i} (source {k}): no pose"
        error_mm = np.linalg.norm(T[:3, 3] - drive.T_world_camera[k][:3, 3])
        assert error_mm < POSE_TOL_MM, f"streamed frame {i} (source {k}): {error_mm:.2f} mm from the truth"
        seen.add(k)
        errors_mm.append(error_mm)
    assert len(seen) >= 3, f"the stream showed only source frames {sorted(seen)}"
    assert len(data["grays"]) >= MIN_LOGGED
    print(
        f"{len(errors_mm)} streamed frames from source frames {sorted(seen)}: pose error max {max(errors_mm):.2f} mm, "
        f"median {np.median(errors_mm):.2f} mm; {facts['fps']:.2f} fps; snapshot = source {snap_k} within 1 level"
    )


@pytest.mark.parametrize(
    ("refusal", "status", "words"),
    [
        # What Chromium, Firefox and Safari reject getUserMedia with when the learner (or a policy) blocks the camera,
        ("NotAllowedError", "denied", "permission denied"),
        # and when no camera is plugged in.
        ("NotFoundError", "no-camera", "No camera found"),
    ],
)
def test_without_a_camera_the_notebook_says_why_and_offers_the_bundled_pictures(camera_lab, refusal, status, words):
    """The browser's refusal is the real DOMException a browser raises, injected in place of getUserMedia.

    (Headless Chromium without its fake camera leaves getUserMedia pending instead of refusing:
    measured, with the permission blocked through the DevTools protocol and with no camera.)
    """
    try:
        from playwright import sync_api as playwright
    except ImportError:
        pytest.fail('the browser test needs playwright: pip install -e ".[browser]" (make test-browser does it)')
    server, _video = camera_lab
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            page.add_init_script(
                f"navigator.mediaDevices.getUserMedia = () => Promise.reject(new DOMException('refused', '{refusal}'));"
            )
            page.goto(f"{server.url}/lab/tree/{NOTEBOOK}?token={server.token}", timeout=SERVER_START_S * 1000)
            page.wait_for_selector(".jp-NotebookPanel .jp-CodeCell", timeout=SERVER_START_S * 1000)
            server.wait_for_idle_kernel(SERVER_START_S)
            _menu(page, "Edit", "Clear Outputs of All Cells")
            _menu(page, "Run", "Run All Cells")
            # The widget shows the advice in place of the picture ...
            message = page.locator(".fidlearn-webcam-message").first
            message.wait_for(timeout=RUN_ALL_S * 1000)
            try:
                page.wait_for_function(
                    "(words) => document.querySelector('.fidlearn-webcam-message').textContent.includes(words)",
                    arg=words,
                    timeout=REDRAW_S * 1000,
                )
            except playwright.TimeoutError:
                raise AssertionError(f"the widget says {message.inner_text()!r}, not {words!r}") from None
            assert "HAVE_CAMERA = False" in message.inner_text()
            assert "bundled pictures" in message.inner_text()
            assert not page.locator(".fidlearn-webcam video").first.is_visible()
            # ... and the snapshot cell stops Run All with the same advice, not a hang or a timeout.
            try:
                page.wait_for_function(
                    "() => [...document.querySelectorAll('.jp-OutputArea-output')]"
                    ".some(e => e.textContent.includes('WebcamError'))",
                    timeout=REDRAW_S * 1000,
                )
            except playwright.TimeoutError:
                page.screenshot(path=str(server.home / "no_camera.png"))
                raise AssertionError("the snapshot cell shows no WebcamError") from None
            text = next(t for t in page.locator(".jp-OutputArea-output").all_inner_texts() if "WebcamError" in t)
            last = [line for line in text.splitlines() if line.startswith("WebcamError:")][-1]
            assert words in last, last  # the refusal's advice, not a timeout
            assert "bundled pictures" in last, last
        finally:
            browser.close()
    client = _kernel_client(server)
    try:
        assert _run(client, "print(cam.status)").strip() == status
    finally:
        client.stop_channels()
