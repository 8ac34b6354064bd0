"""The camera widget's Python side, without a browser: decoding, sizes, pacing, the no-camera advice.

The browser half (getUserMedia, the comm round trip) is tested in tests/browser/test_webcam.py.
"""

from __future__ import annotations

import asyncio

import cv2
import numpy as np
import pytest
from y4m import read_y4m, write_y4m, yuv420_planes

from fidlearn import FidlearnError
from fidlearn._webcam import (
    FAILED,
    STATUSES,
    FramePacer,
    WebcamError,
    decode_frame,
    status_message,
)
from fidlearn.data import data_path
from fidlearn.errors import ImageError
from fidlearn.widgets import Webcam


def _frame(width=64, height=48, seed=0):
    rng = np.random.default_rng(seed)
    return rng.integers(0, 256, (height, width, 3), dtype=np.uint8)


class _Browser:
    """Stands in for the JavaScript end of the comm: records what the kernel sends."""

    def __init__(self, cam):
        self.sent = []
        cam.send = lambda content, buffers=None: self.sent.append(content)  # noqa: ARG005 (Widget.send's signature)


# -- decoding ------------------------------------------------------------------------------
def test_png_frame_decodes_to_the_same_pixels():
    frame = _frame()
    _, png = cv2.imencode(".png", frame)

    out = decode_frame(png.tobytes(), 64, 48)
    assert out.shape == (48, 64, 3)
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out, frame)


def test_jpeg_frame_decodes_within_the_stated_tolerance():
    # A smooth picture (a real camera frame) at the widget's JPEG quality 0.92 stays within a few levels.
    gray = cv2.imread(str(data_path("trajectory", "frame_000.png")), cv2.IMREAD_GRAYSCALE)
    frame = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    _, jpg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 92])
    out = decode_frame(memoryview(jpg.tobytes()), 640, 480)
    diff = np.abs(cv2.cvtColor(out, cv2.COLOR_BGR2GRAY).astype(int) - gray)
    assert diff.mean() < 1.5, (diff.mean(), np.percentile(diff, 99))
    assert np.percentile(diff, 99) <= 6, (diff.mean(), np.percentile(diff, 99))


@pytest.mark.parametrize("data", [b"", b"not an image at all", b"\x89PNG\r\n\x1a\n" + b"\0" * 40])
def test_empty_or_corrupt_bytes_raise_image_error(data):
    with pytest.raises(ImageError, match="camera frame"):
        decode_frame(data)


def test_a_frame_of_another_size_than_announced_is_refused():
    _, png = cv2.imencode(".png", _frame(64, 48))
    with pytest.raises(ImageError, match="64x48 px but the browser announced 640x480"):
        decode_frame(png.tobytes(), 640, 480)


# -- sizes and traits ----------------------------------------------------------------------
def test_size_traits_accept_camera_sizes():
    cam = Webcam(width=1280, height=720)
    assert (cam.width, cam.height) == (1280, 720)
    cam.width = 1920
    assert cam.width == 1920


@pytest.mark.parametrize("bad", [0, 15, 4097, -640, 640.0, "640", True])
def test_size_traits_refuse_what_no_camera_delivers(bad):
    with pytest.raises(WebcamError, match="width"):
        Webcam(width=bad)
    cam = Webcam()
    with pytest.raises(FidlearnError, match="height"):
        cam.height = bad
    assert cam.height == 480


@pytest.mark.parametrize("bad", [0, -1, 61, "fast", None])
def test_max_fps_is_validated(bad):
    with pytest.raises(WebcamError, match="max_fps"):
        Webcam(max_fps=bad)


def test_stream_format_is_png_or_jpeg():
    assert Webcam(stream_format="png").stream_format == "png"
    with pytest.raises(WebcamError, match="'png'.*'jpeg'"):
        Webcam(stream_format="webp")


def test_a_received_frame_records_the_delivered_size():
    cam = Webcam(width=1280, height=720)
    _Browser(cam)
    _, png = cv2.imencode(".png", _frame(640, 480))
    cam.streaming = True
    cam._on_message(cam, {"type": "frame", "kind": "stream", "seq": 1, "width": 640, "height": 480}, [png.tobytes()])
    assert (cam.actual_width, cam.actual_height) == (640, 480)
    assert (cam.width, cam.height) == (1280, 720)  # asked for, not delivered
    assert cam.status == "streaming"


# -- pacing and back-pressure ----------------------------------------------------------------
def test_pacer_waits_out_the_rest_of_the_frame_period():
    pacer = FramePacer(max_fps=5)  # 200 ms per frame
    assert pacer.wait_s(10.0, 10.05) == pytest.approx(0.15)
    assert pacer.wait_s(10.2, 10.2) == pytest.approx(0.2)
    # A callback slower than the period: no wait, the stream runs at the kernel's pace.
    assert pacer.wait_s(10.4, 10.9) == 0.0
    assert pacer.frames == 3
    with pytest.raises(WebcamError, match="before"):
        pacer.wait_s(2.0, 1.0)


def test_pacer_measures_the_arrival_rate():
    pacer = FramePacer(max_fps=10)
    for i in range(11):
        pacer.wait_s(0.25 * i, 0.25 * i + 0.01)
    assert pacer.measured_fps == pytest.approx(4.0)


def test_each_stream_frame_is_acknowledged_after_the_callbacks_ran():
    cam = Webcam(max_fps=4)
    browser = _Browser(cam)
    seen = []
    cam.on_frame(lambda frame: (seen.append(frame.shape), browser.sent.copy())[0])
    cam.start()
    _, png = cv2.imencode(".png", _frame())
    for seq in (1, 2):
        cam._on_message(
            cam, {"type": "frame", "kind": "stream", "seq": seq, "width": 64, "height": 48}, [png.tobytes()]
        )
    assert seen == [(48, 64, 3), (48, 64, 3)]
    acks = [m for m in browser.sent if m["type"] == "ack"]
    assert [a["seq"] for a in acks] == [1, 2]
    assert all(0 < a["wait_ms"] <= 250 for a in acks)  # 4 fps: 250 ms minus the handling time
    assert cam.frames_received == 2


def test_a_failing_callback_stops_the_stream_and_still_acknowledges():
    cam = Webcam()
    browser = _Browser(cam)

    def broken(_frame):
        raise RuntimeError("boom")

    cam.on_frame(broken)
    cam.start()
    _, png = cv2.imencode(".png", _frame())
    with pytest.raises(RuntimeError, match="boom"):
        cam._on_message(cam, {"type": "frame", "kind": "stream", "seq": 7, "width": 64, "height": 48}, [png.tobytes()])
    assert cam.streaming is False
    assert isinstance(cam.last_error, RuntimeError)
    assert browser.sent[-1]["type"] == "ack"
    assert browser.sent[-1]["seq"] == 7


def test_a_corrupt_stream_frame_is_dropped_and_the_next_good_one_delivered():
    cam = Webcam()
    browser = _Browser(cam)
    seen = []
    cam.on_frame(lambda frame: seen.append(frame.shape))
    cam.start()
    cam._on_message(cam, {"type": "frame", "kind": "stream", "seq": 1, "width": 64, "height": 48}, [b"garbage"])
    assert cam.streaming is True
    assert cam.frames_dropped == 1
    assert "neither PNG nor JPEG" in cam.drop_reason
    assert isinstance(cam.last_error, ImageError)  # acknowledged all the same
    assert browser.sent[-1]["seq"] == 1
    _, png = cv2.imencode(".png", _frame())
    cam._on_message(cam, {"type": "frame", "kind": "stream", "seq": 2, "width": 64, "height": 48}, [png.tobytes()])
    assert seen == [(48, 64, 3)]
    assert cam.frames_received == 1
    assert cam.frames_dropped == 1


# -- snapshot ---------------------------------------------------------------------------------
def test_snapshot_resolves_with_the_browser_reply():
    cam = Webcam()
    browser = _Browser(cam)
    frame = _frame()
    _, png = cv2.imencode(".png", frame)

    async def run():
        task = asyncio.ensure_future(cam.snapshot(timeout_s=5))
        await asyncio.sleep(0)
        request = browser.sent[-1]
        assert request["type"] == "snap"
        assert request["format"] == "png"
        cam._on_message(
            cam, {"type": "frame", "kind": "snap", "id": request["id"], "width": 64, "height": 48}, [png.tobytes()]
        )
        return await task

    np.testing.assert_array_equal(asyncio.run(run()), frame)


def test_snapshot_without_a_displayed_widget_times_out_with_advice():
    cam = Webcam()
    _Browser(cam)
    with pytest.raises(WebcamError, match="display the widget"):
        asyncio.run(cam.snapshot(timeout_s=0.05))


# -- no camera ----------------------------------------------------------------------------------
@pytest.mark.parametrize("status", sorted(FAILED))
def test_every_failure_says_what_to_do_and_offers_the_bundled_pictures(status):
    text = status_message(status, "NotAllowedError: Permission denied")
    assert "bundled pictures" in text
    assert "NotAllowedError" in text
    cam = Webcam()
    cam.status, cam.error = status, "NotFoundError: Requested device not found"
    assert cam.failed
    assert not cam.available
    assert cam.message == status_message(status, cam.error)
    with pytest.raises(WebcamError, match="bundled pictures"):
        cam.start()
    with pytest.raises(WebcamError, match="bundled pictures"):
        asyncio.run(cam.snapshot())


def test_insecure_context_names_https():
    assert "https" in status_message("insecure")
    assert "permission denied" in status_message("denied")


def test_unknown_status_is_refused():
    with pytest.raises(WebcamError, match="status"):
        status_message("sleeping")
    with pytest.raises(WebcamError):
        Webcam().status = "sleeping"
    assert "streaming" in STATUSES


def test_the_javascript_ships_in_the_package():
    from fidlearn._webcam import STATIC

    js = (STATIC / "webcam.js").read_text()
    assert "export default" in js  # no network, no build
    assert "getUserMedia" in js
    assert "import " not in js


# -- Y4M ------------------------------------------------------------------------------------------
def test_y4m_round_trip_keeps_gray_within_one_level(tmp_path):
    gray = cv2.imread(str(data_path("trajectory", "frame_000.png")), cv2.IMREAD_GRAYSCALE)
    path = write_y4m(tmp_path / "v.y4m", [gray, 255 - gray], fps=10)
    data = path.read_bytes()
    assert data.startswith(b"YUV4MPEG2 W640 H480 F10000:1000 ")
    assert len(data) == len(data.split(b"\n", 1)[0]) + 1 + 2 * (6 + 640 * 480 * 3 // 2)
    back = read_y4m(path)
    assert len(back) == 2
    assert np.abs(back[0].astype(int) - gray).max() <= 1
    assert np.abs(back[1].astype(int) - (255 - gray)).max() <= 1


def test_y4m_planes_of_gray_and_colour():
    y, u, v = yuv420_planes(np.full((5, 7), 255, np.uint8))
    assert y.shape == (5, 7)
    assert u.shape == v.shape == (3, 4)
    assert (y == 235).all()
    assert (u == 128).all()
    assert (v == 128).all()
    red = np.zeros((4, 4, 3), np.uint8)
    red[..., 2] = 255
    _, u, v = yuv420_planes(red)
    assert (v > 200).all()
    assert (u < 128).all()


def test_y4m_refuses_mixed_sizes_and_leaves_no_file(tmp_path):
    with pytest.raises(ImageError, match="frame 1"):
        write_y4m(tmp_path / "v.y4m", [np.zeros((4, 4), np.uint8), np.zeros((6, 4), np.uint8)])
    with pytest.raises(ImageError, match="no frames"):
        write_y4m(tmp_path / "w.y4m", [])
    with pytest.raises(ImageError, match="uint8"):
        write_y4m(tmp_path / "x.y4m", [np.zeros((4, 4), np.float32)])
    assert list(tmp_path.iterdir()) == []
