"""Write a YUV4MPEG2 (``.y4m``) video: the file format Chromium's fake camera plays.

Chromium started with ``--use-fake-device-for-media-stream
--use-file-for-fake-video-capture=video.y4m`` hands the file's frames to
``getUserMedia`` as if a webcam had filmed them, looping at the end. That lets
a test feed a browser a camera whose every frame (and so every true pose) is
known.

A Y4M file is one text header line (``YUV4MPEG2 W640 H480 F10:1 Ip A1:1 C420jpeg``),
then per frame the line ``FRAME`` and the raw planes: Y (``W x H`` bytes), then
U and V (``ceil(W/2) x ceil(H/2)`` bytes each, for 4:2:0 subsampling). Colours
are converted with the full-range BT.601 (JPEG) matrix of :func:`cv2.cvtColor`
(``COLOR_BGR2YUV``), then squeezed into video range (Y 16-235, U and V
16-240), which is how Chromium reads a Y4M file (measured: a file holding full-range
``Y = gray`` came out of the canvas as ``1.165 gray - 18.7``). The chroma planes are
averaged over 2 x 2 pixel blocks: colour edges blur, luma stays exact up to the
rounding of 256 gray levels onto 220 (at most one level after the round trip).
A gray frame gives ``Y = 16 + 219 gray / 255`` and ``U = V = 128``.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import cv2
import numpy as np

from fidlearn.errors import ImageError

__all__ = ["read_y4m", "write_y4m", "yuv420_planes"]


def _as_bgr(frame: np.ndarray, index: int) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.dtype != np.uint8:
        raise ImageError(
            f"frame {index}: Y4M frames must be uint8 images, got dtype {frame.dtype}; "
            "convert with np.clip(x, 0, 255).astype(np.uint8)"
        )
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    if frame.ndim == 3 and frame.shape[2] == 3:
        return frame
    raise ImageError(f"frame {index}: expected a gray (H, W) or BGR (H, W, 3) image, got shape {frame.shape}")


def yuv420_planes(frame: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Y, U and V planes of one gray or BGR uint8 frame, chroma subsampled 2 x 2.

    Returns
    -------
    y : ndarray, (H, W) uint8, video range 16-235
    u, v : ndarray, (ceil(H/2), ceil(W/2)) uint8
    """
    bgr = _as_bgr(frame, 0)
    h, w = bgr.shape[:2]
    yuv = cv2.cvtColor(bgr, cv2.COLOR_BGR2YUV).astype(np.float32)
    y = np.clip(np.rint(16.0 + yuv[:, :, 0] * (219.0 / 255.0)), 0, 255).astype(np.uint8)
    yuv[:, :, 1:] = 128.0 + (yuv[:, :, 1:] - 128.0) * (224.0 / 255.0)
    # Pad to even size by repeating the last row / column, then average 2 x 2 blocks.
    padded = np.pad(yuv[:, :, 1:], ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
    hh, ww = padded.shape[0] // 2, padded.shape[1] // 2
    chroma = padded.reshape(hh, 2, ww, 2, 2).mean(axis=(1, 3))
    chroma = np.clip(np.rint(chroma), 0, 255).astype(np.uint8)
    return y, chroma[:, :, 0].copy(), chroma[:, :, 1].copy()


def write_y4m(path: str | os.PathLike, frames: Iterable[np.ndarray], fps: float = 10.0) -> Path:
    """Write frames (all the same size, gray or BGR uint8) to a ``.y4m`` file; returns its path.

    Parameters
    ----------
    path : path-like
        The file to write (replaced atomically: a failure leaves no half-written file).
    frames : iterable of ndarray, (H, W) or (H, W, 3) uint8
    fps : float
        Frame rate written to the header (as a fraction with denominator 1000).
    """
    path = Path(path)
    if not fps > 0:
        raise ImageError(f"fps must be positive, got {fps!r}")
    tmp = path.with_name(path.name + ".part")
    size = None
    n = 0
    try:
        with tmp.open("wb") as f:
            for i, frame in enumerate(frames):
                bgr = _as_bgr(frame, i)
                if size is None:
                    size = bgr.shape[:2]
                    f.write(f"YUV4MPEG2 W{size[1]} H{size[0]} F{round(fps * 1000)}:1000 Ip A1:1 C420jpeg\n".encode())
                elif bgr.shape[:2] != size:
                    raise ImageError(
                        f"frame {i} is {bgr.shape[1]}x{bgr.shape[0]}, frame 0 is {size[1]}x{size[0]}: "
                        "all frames of a video must have one size"
                    )
                f.write(b"FRAME\n")
                for plane in yuv420_planes(bgr):
                    f.write(plane.tobytes())
                n += 1
        if n == 0:
            raise ImageError("no frames to write: a Y4M video needs at least one frame")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def read_y4m(path: str | os.PathLike) -> list[np.ndarray]:
    """The gray frames of a ``.y4m`` file (its Y planes stretched back from video range): list of (H, W) uint8."""
    data = Path(path).read_bytes()
    end = data.find(b"\n")
    header = data[:end].split()
    if end < 0 or header[:1] != [b"YUV4MPEG2"]:
        raise ImageError(f"{path}: not a YUV4MPEG2 file (its first line must start with 'YUV4MPEG2')")
    fields = {t[:1]: t[1:] for t in header[1:]}
    w, h = int(fields[b"W"]), int(fields[b"H"])
    frame_bytes = w * h + 2 * ((w + 1) // 2) * ((h + 1) // 2)
    frames, pos = [], end + 1
    while pos < len(data):
        line_end = data.find(b"\n", pos)
        if not data[pos:line_end].startswith(b"FRAME") or line_end + 1 + frame_bytes > len(data):
            raise ImageError(f"{path}: frame {len(frames)} is truncated or lacks its FRAME line")
        y = np.frombuffer(data, np.uint8, w * h, line_end + 1).reshape(h, w)
        frames.append(np.clip(np.rint((y.astype(np.float32) - 16.0) * (255.0 / 219.0)), 0, 255).astype(np.uint8))
        pos = line_end + 1 + frame_bytes
    return frames
