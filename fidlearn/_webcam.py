"""The learner's own camera in a notebook: frames from the browser's ``getUserMedia`` to the kernel.

On JupyterHub, Binder or any remote kernel the camera sits on the learner's
laptop and the kernel on a server: ``cv2.VideoCapture(0)`` cannot see it, the
browser can. :class:`Webcam` is an anywidget whose JavaScript
(``fidlearn/static/webcam.js``, plain ES module, no build step, no network)
opens the camera in the browser and sends frames to the kernel as PNG or JPEG
bytes over the widget's comm; the kernel decodes them with ``cv2.imdecode``.

Two ways to get frames:

* ``frame = await cam.snapshot()`` in a cell (top-level ``await``): one BGR
  frame. It is asynchronous because a widget message cannot reach a kernel
  whose cell blocks; while the cell awaits, ipykernel (7.x) still dispatches
  the widget's messages, so the frame arrives and the cell goes on.
* ``cam.on_frame(callback)`` then ``cam.start()``: the callback receives every
  frame the browser sends, with back-pressure: the browser sends the next frame
  only after the kernel has acknowledged the last (so a slow callback slows the
  stream instead of queueing frames), and no faster than ``max_fps``
  (:class:`FramePacer` computes how long the browser waits). ``cam.stop()`` ends it.

When no camera is allowed or present, ``status`` says which (``"denied"``,
``"no-camera"``, ``"busy"``, ``"insecure"``, ``"error"``) and ``message`` says
in words what to do, shown in the notebook in place of the picture, and offers
the course's bundled pictures (``data/calibration``, ``data/trajectory``) instead.
"""

from __future__ import annotations

import asyncio
import itertools
import math
import pathlib
import time
from collections.abc import Callable

import anywidget
import cv2
import numpy as np
import traitlets

from ._files import image_size_from_header
from .errors import FidlearnError, ImageError, WebcamError

__all__ = ["STATUSES", "FramePacer", "Webcam", "WebcamError", "decode_frame", "status_message"]

STATIC = pathlib.Path(__file__).resolve().parent / "static"
#: Smallest and largest side (px) a learner may ask for.
MIN_SIDE_PX, MAX_SIDE_PX = 16, 4096
#: Largest frame side (px) and encoded size (bytes) accepted from the browser: twice the largest
#: side asked for (a camera may deliver more than asked), and what a lossless 8192x8192 PNG can take.
MAX_FRAME_SIDE_PX = 2 * MAX_SIDE_PX
MAX_FRAME_BYTES = 256 * 2**20
FALLBACK = (
    "Until it works, use the bundled pictures instead: set HAVE_CAMERA = False in the notebook and run "
    "it again (data/calibration stands in for your calibration views, data/trajectory for your live camera)."
)
#: Every status the widget can be in, with what it means and what to do.
STATUSES = {
    "waiting": "The camera opens when the widget is shown: display it (put `cam` last in a cell).",
    "starting": "Asking the browser for the camera: allow it when the browser asks.",
    "streaming": "",
    "denied": (
        "The browser refused the camera (permission denied). Click the camera or lock icon in the "
        "address bar, allow the camera for this site, then run the cell again."
    ),
    "no-camera": ("No camera found: plug one in (or close the laptop's privacy shutter) and run the cell again."),
    "busy": (
        "The camera is in use by another program or tab (a video call?) or the system refused it: close "
        "that, then run the cell again."
    ),
    "insecure": (
        "The browser gives the camera only to a secure page (https://, or http://localhost): open "
        "JupyterLab through https (ask whoever runs the JupyterHub) or on this computer."
    ),
    "error": "The camera failed to start: see the error above, then run the cell again.",
}
FAILED = {"denied", "no-camera", "busy", "insecure", "error"}


def status_message(status: str, error: str = "") -> str:
    """What the learner reads for a widget ``status`` (and the browser's ``error`` text).

    Every failed status ends with what the notebook does instead (the bundled pictures).
    """
    if status not in STATUSES:
        raise WebcamError(f"status must be one of {sorted(STATUSES)}, got {status!r}")
    text = STATUSES[status]
    if error:
        text = f"{text} (browser: {error})" if text else f"Note: {error}"
    if status in FAILED:
        text = f"{text} {FALLBACK}"
    return text


def decode_frame(data: bytes | memoryview, width: int | None = None, height: int | None = None) -> np.ndarray:
    """Decode PNG or JPEG bytes from the browser into a BGR image.

    The browser is untrusted input: the bytes' size, the announced size and the size the picture's
    header declares are checked before anything is decoded, so a 74-byte PNG that claims
    100000x100000 pixels is refused without allocating them.

    Parameters
    ----------
    data : bytes or memoryview
        The encoded frame (at most ``MAX_FRAME_BYTES``).
    width, height : int, optional
        The size the browser reported (px, 1 to ``MAX_FRAME_SIDE_PX``); the decoded picture must have it.

    Returns
    -------
    ndarray, (height, width, 3) uint8, BGR

    Raises
    ------
    ImageError
        Empty, oversized or undecodable bytes, an announced size that is not a whole number of
        pixels in range, or a picture of another size than reported.
    """
    raw = _frame_bytes(data)
    announced = None if width is None and height is None else (_side(width, "width"), _side(height, "height"))
    head = image_size_from_header(raw)
    if head is None or head[0] not in ("PNG", "JPEG"):
        raise ImageError(
            f"the camera frame ({len(raw)} bytes, starting {raw[:8]!r}) is neither PNG nor JPEG: it cannot be decoded"
        )
    fmt, w, h = head
    if not (0 < w <= MAX_FRAME_SIDE_PX and 0 < h <= MAX_FRAME_SIDE_PX):
        said = f"says {w}x{h} pixels" if w >= 0 and h >= 0 else "gives no size"
        raise ImageError(f"the camera frame's {fmt} header {said}; a frame is 1 to {MAX_FRAME_SIDE_PX} px a side")
    if announced is not None and (w, h) != announced:
        raise ImageError(
            f"the camera frame's {fmt} header says {w}x{h} px but the browser announced "
            f"{announced[0]}x{announced[1]} px"
        )
    if (fmt == "PNG" and b"IEND" not in raw[-16:]) or (fmt == "JPEG" and not raw.endswith(b"\xff\xd9")):
        raise ImageError(f"the camera frame ({len(raw)} bytes of {fmt}) is cut short: it has no end")
    try:
        image = cv2.imdecode(np.frombuffer(raw, dtype=np.uint8), cv2.IMREAD_COLOR)
    except cv2.error:
        image = None
    if image is None or image.shape[:2] != (h, w):
        raise ImageError(f"the camera frame ({len(raw)} bytes of {fmt}) is damaged: it cannot be decoded")
    return image


def _frame_bytes(data) -> bytes:
    """The frame's bytes: bytes-like, not empty, at most MAX_FRAME_BYTES; ImageError otherwise."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ImageError(f"the camera frame must be bytes, got {type(data).__name__}")
    raw = bytes(data)
    if not raw:
        raise ImageError("the camera frame is empty (0 bytes): the browser sent no picture; run the cell again")
    if len(raw) > MAX_FRAME_BYTES:
        raise ImageError(f"the camera frame has {len(raw)} bytes, more than the limit of {MAX_FRAME_BYTES}")
    return raw


def _side(value, name: str) -> int:
    """A frame side the browser announced: a whole number of pixels, 1 to MAX_FRAME_SIDE_PX."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 < value <= MAX_FRAME_SIDE_PX:
        raise ImageError(
            f"the browser announced a frame {name} of {value!r:.40}; it must be a whole number of pixels, "
            f"1 to {MAX_FRAME_SIDE_PX}"
        )
    return int(value)


class FramePacer:
    """How long the browser waits before the next stream frame: at most ``max_fps`` frames a second.

    The browser sends one frame, the kernel handles it and then acknowledges it
    with a wait: ``max(0, 1 / max_fps - handling time)``. A frame never waits in
    a queue: when the kernel is slower than ``max_fps`` the stream runs at the
    kernel's pace.

    Parameters
    ----------
    max_fps : float
        Upper limit of frames per second (> 0).
    """

    def __init__(self, max_fps: float):
        self.max_fps = check_max_fps(max_fps)
        self.frames = 0
        self._arrivals: list[float] = []

    def wait_s(self, received_at_s: float, done_at_s: float) -> float:
        """Seconds the browser waits before sending the next frame (the frame arrived, then was handled)."""
        if not all(isinstance(t, (int, float)) and math.isfinite(t) for t in (received_at_s, done_at_s)):
            raise WebcamError(f"times must be finite numbers of seconds, got {received_at_s!r:.30}, {done_at_s!r:.30}")
        if done_at_s < received_at_s:
            raise WebcamError(f"done_at_s ({done_at_s}) is before received_at_s ({received_at_s})")
        self.frames += 1
        self._arrivals = (self._arrivals + [received_at_s])[-30:]
        return max(0.0, 1.0 / self.max_fps - (done_at_s - received_at_s))

    @property
    def measured_fps(self) -> float:
        """Frames per second over the last (up to) 30 arrivals (0 before two frames)."""
        if len(self._arrivals) < 2 or self._arrivals[-1] <= self._arrivals[0]:
            return 0.0
        return (len(self._arrivals) - 1) / (self._arrivals[-1] - self._arrivals[0])


def check_max_fps(value) -> float:
    try:
        fps = float(value)
    except (TypeError, ValueError):
        raise WebcamError(f"max_fps must be a number of frames per second, got {value!r}") from None
    if not 0 < fps <= 60:
        raise WebcamError(f"max_fps must be between 0 (excluded) and 60 frames per second, got {value!r}")
    return fps


def check_side(value, name: str) -> int:
    """A requested picture side in pixels: a whole number from 16 to 4096."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise WebcamError(f"{name} must be a whole number of pixels, got {value!r}")
    if not MIN_SIDE_PX <= int(value) <= MAX_SIDE_PX:
        raise WebcamError(
            f"{name} must be {MIN_SIDE_PX} to {MAX_SIDE_PX} px, got {value}: common webcam sizes "
            "are 640x480, 1280x720 and 1920x1080"
        )
    return int(value)


class Webcam(anywidget.AnyWidget):
    """The browser's camera as a widget: a live preview, and frames for the kernel.

    Parameters (traits)
    -------------------
    width, height : int
        The resolution asked for (px). The camera delivers the nearest it can:
        ``actual_width`` and ``actual_height`` report what it delivers; a
        calibration made from these frames records that size in ``camera.json``.
    max_fps : float
        Upper limit of the stream's frames per second (default 5).
    stream_format : {"jpeg", "png"}
        Encoding of stream frames: JPEG (``jpeg_quality``, default 0.92: smaller,
        corners move by well under 0.1 px) or PNG (lossless, larger).
    status, error, message : str
        Set by the browser (see :data:`STATUSES`); ``message`` is the advice in words.
    frames_dropped, drop_reason : int, str
        Malformed messages from the browser (a frame that cannot be decoded, a size that is not a
        number or beyond ``MAX_FRAME_SIDE_PX``, a header that disagrees, a state update with a
        status no camera has) are dropped, never raised in the kernel: how many so far, and why the
        last one was.

    Examples
    --------
    >>> cam = Webcam(width=640, height=480)
    >>> cam.status, cam.streaming
    ('waiting', False)
    """

    _esm = STATIC / "webcam.js"
    width = traitlets.Any(640).tag(sync=True)  # validated by check_side, so every refusal is a WebcamError
    height = traitlets.Any(480).tag(sync=True)
    actual_width = traitlets.Int(0).tag(sync=True)
    actual_height = traitlets.Int(0).tag(sync=True)
    display_width = traitlets.Int(480).tag(sync=True)
    status = traitlets.Unicode("waiting").tag(sync=True)
    error = traitlets.Unicode("").tag(sync=True)
    message = traitlets.Unicode(STATUSES["waiting"]).tag(sync=True)
    streaming = traitlets.Bool(False).tag(sync=True)
    max_fps = traitlets.Any(5.0).tag(sync=True)
    stream_format = traitlets.Unicode("jpeg").tag(sync=True)
    jpeg_quality = traitlets.Float(0.92).tag(sync=True)
    frames_dropped = traitlets.Int(0).tag(sync=True)
    drop_reason = traitlets.Unicode("").tag(sync=True)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._callbacks: list[Callable[[np.ndarray], object]] = []
        self._pending: dict[int, asyncio.Future] = {}
        self._ids = itertools.count(1)
        self.pacer = FramePacer(self.max_fps)
        self.frames_received = 0
        self.last_error: BaseException | None = None
        self.on_msg(self._on_message)

    # -- validation ------------------------------------------------------------------
    @traitlets.validate("width", "height")
    def _valid_side(self, proposal):
        return check_side(proposal["value"], proposal["trait"].name)

    @traitlets.validate("max_fps")
    def _valid_fps(self, proposal):
        return check_max_fps(proposal["value"])

    @traitlets.validate("stream_format")
    def _valid_format(self, proposal):
        return _check_format(proposal["value"])

    @traitlets.validate("status")
    def _valid_status(self, proposal):
        if proposal["value"] not in STATUSES:
            raise WebcamError(f"status must be one of {sorted(STATUSES)}, got {proposal['value']!r}")
        return proposal["value"]

    @traitlets.observe("status", "error")
    def _update_message(self, _change):
        self.message = status_message(self.status, self.error)

    @traitlets.observe("max_fps")
    def _new_pacer(self, change):
        self.pacer = FramePacer(change["new"])

    # -- public ----------------------------------------------------------------------
    @property
    def available(self) -> bool:
        """True once the browser streams the camera."""
        return self.status == "streaming"

    @property
    def failed(self) -> bool:
        """True when no camera is allowed or present (see ``message``)."""
        return self.status in FAILED

    def on_frame(self, callback: Callable[[np.ndarray], object], remove: bool = False) -> None:
        """Call ``callback(frame_bgr)`` for each stream frame ((H, W, 3) uint8); ``remove=True`` unregisters it.

        Raises :class:`WebcamError` for a callback that is not a function, or one to remove that was
        never registered.
        """
        if remove:
            if callback not in self._callbacks:
                raise WebcamError(
                    f"on_frame(remove=True): {callback!r:.60} was not registered; registered: {len(self._callbacks)}"
                )
            self._callbacks.remove(callback)
        elif not callable(callback):
            raise WebcamError(f"on_frame needs a function of one frame, got {type(callback).__name__}")
        else:
            self._callbacks.append(callback)

    def start(self) -> None:
        """Start streaming frames to the ``on_frame`` callbacks (at most ``max_fps`` a second)."""
        self._raise_if_failed()
        self.last_error = None
        self.streaming = True

    def stop(self) -> None:
        """Stop the stream (the preview stays)."""
        self.streaming = False

    async def snapshot(self, timeout_s: float = 10.0, format: str = "png") -> np.ndarray:
        """One frame from the camera, as BGR (H, W, 3) uint8: ``frame = await cam.snapshot()``.

        Awaited in a cell (top-level ``await``), so that the kernel still
        receives the widget's reply while the cell waits. ``format="png"``
        (default) is lossless; ``"jpeg"`` is smaller and lossy. Raises
        :class:`WebcamError` when no camera is allowed or present, or no frame
        arrives within ``timeout_s`` (the widget is not displayed?).
        """
        _check_format(format)
        if isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float)) or not 0 < timeout_s <= 3600:
            raise WebcamError(
                f"timeout_s must be a number of seconds, more than 0 and at most 3600, got {timeout_s!r:.40}"
            )
        self._raise_if_failed()
        request = next(self._ids)
        future = asyncio.get_running_loop().create_future()
        self._pending[request] = future
        self.send({"type": "snap", "id": request, "format": format, "quality": self.jpeg_quality})
        try:
            return await asyncio.wait_for(future, timeout_s)
        except asyncio.TimeoutError:
            raise WebcamError(
                f"no frame from the camera within {timeout_s} s (status {self.status!r}): display the "
                "widget (put it last in a cell) and allow the camera"
            ) from None
        finally:
            self._pending.pop(request, None)

    # -- messages from the browser -----------------------------------------------------
    def _raise_if_failed(self) -> None:
        if self.failed:
            raise WebcamError(self.message)

    def _on_message(self, _widget, content, buffers) -> None:
        """A message from the browser. It is untrusted: a malformed one is dropped (``frames_dropped``,
        ``drop_reason``), never raised here, so the next good frame still arrives. Only an ``on_frame``
        callback's own exception propagates (and stops the stream)."""
        if not isinstance(content, dict) or content.get("type") != "frame":
            return
        buffers = buffers if isinstance(buffers, (list, tuple)) else []
        kind = content.get("kind")
        if kind == "snap":
            self._answer_snapshot(content, buffers)
        elif kind == "stream":
            self._handle_stream_frame(content, buffers)
        else:  # dropped, and acknowledged so that a stream waiting for it goes on
            self._drop(WebcamError(f"a frame message of kind {kind!r:.40}; the browser sends 'snap' or 'stream'"))
            self.send({"type": "ack", "seq": _seq(content), "wait_ms": 0})

    def set_state(self, sync_data) -> None:
        """Apply a state update from the browser, key by key: a malformed value (a status no camera has, text
        for a size) is dropped as a malformed frame is (``frames_dropped``, ``drop_reason``), never raised."""
        if not isinstance(sync_data, dict):
            self._drop(WebcamError(f"a state update that is not a mapping ({type(sync_data).__name__})"))
            return
        for key, value in sync_data.items():
            if not isinstance(key, str):
                self._drop(WebcamError(f"a state update with the key {key!r:.40}, not a name"))
                continue
            before = getattr(self, key) if self.has_trait(key) else None
            try:
                super().set_state({key: value})
            except (traitlets.TraitError, FidlearnError) as exc:
                if before is not None:  # traitlets rolls back only its own TraitError
                    self.set_trait(key, before)
                self._drop(WebcamError(f"the browser set {key!r:.40} to {value!r:.40}: {exc}"))

    def _drop(self, exc: BaseException) -> None:
        """Count a malformed message from the browser and say why (``drop_reason``, ``last_error``)."""
        self.frames_dropped += 1
        self.drop_reason = str(exc)
        self.last_error = exc

    def _decode(self, content: dict, buffers) -> np.ndarray:
        return decode_frame(buffers[0] if buffers else b"", content.get("width"), content.get("height"))

    def _answer_snapshot(self, content: dict, buffers) -> None:
        request = content.get("id")
        future = self._pending.get(request) if isinstance(request, int) else None
        if future is None or future.done():
            return
        failed = content.get("failed")
        if failed:
            # The reply carries the failure too: the status shown is right even if a state update was lost.
            failed = failed if isinstance(failed, str) and failed in FAILED else "error"
            self.error = str(content.get("error", self.error))[:500]
            self.status = failed
            future.set_exception(WebcamError(status_message(failed, self.error)))
            return
        try:
            frame = self._decode(content, buffers)
        except ImageError as exc:
            self._drop(exc)
            future.set_exception(exc)
            return
        self._note_size(frame)
        future.set_result(frame)

    def _note_size(self, frame: np.ndarray) -> None:
        # A frame proves the camera streams at its size, even if the trait updates are still on their way.
        height, width = frame.shape[:2]
        if (self.actual_width, self.actual_height) != (width, height):
            self.actual_width, self.actual_height = width, height
        if self.status != "streaming":
            self.status = "streaming"

    def _handle_stream_frame(self, content: dict, buffers) -> None:
        received = time.monotonic()
        try:
            if self.streaming:
                try:
                    frame = self._decode(content, buffers)
                except ImageError as exc:
                    self._drop(exc)
                    return
                self.frames_received += 1
                self._note_size(frame)
                for callback in list(self._callbacks):
                    callback(frame)
        except Exception as exc:
            # A failing callback stops the stream (no error scrolls by unseen frame after frame) and is re-raised.
            self.last_error = exc
            self.streaming = False
            raise
        finally:
            wait_s = self.pacer.wait_s(received, time.monotonic())
            self.send({"type": "ack", "seq": _seq(content), "wait_ms": round(1000 * wait_s)})


def _seq(content: dict) -> int | None:
    """The message's sequence number when it is one (a whole number), else None."""
    seq = content.get("seq")
    return seq if isinstance(seq, int) and not isinstance(seq, bool) else None


def _check_format(value) -> str:
    if value not in ("png", "jpeg"):
        raise WebcamError(f"format must be 'png' (lossless) or 'jpeg' (smaller), got {value!r}")
    return value
