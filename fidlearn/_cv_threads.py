"""OpenCV's own worker threads, for the calls whose answer depends on them."""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator

import cv2

__all__ = ["opencv_single_thread"]

#: Held while OpenCV runs on one thread (:func:`opencv_single_thread`).
_SINGLE_THREAD = threading.Lock()


@contextlib.contextmanager
def opencv_single_thread() -> Iterator[None]:
    """Run the block with OpenCV's own thread pool at one thread, one caller at a time.

    ``cv2.calibrateCamera`` (OpenCV 5.0) splits its sums over OpenCV's worker threads, and the
    order in which the workers' partial sums are added depends on which worker took which stripe;
    a pool that is busy with another Python thread's call runs the stripes serially instead. So
    the same views gave K differing in the 9th to 12th digit from run to run, alone or from 3
    threads at once (2 of 9 calls differed from the single-thread answer, the first to 2.6e-7
    px). With one worker the additions happen in one order and the answer is the same to the last
    bit every time. ``cv2.setNumThreads`` is process-wide, hence the lock: callers take turns, and
    the previous setting is restored for every other OpenCV call. Other threads' OpenCV calls
    meanwhile run on one thread too (slower, never different: detection and pose estimation give
    the same answer on any number of workers).
    """
    with _SINGLE_THREAD:
        before = cv2.getNumThreads()
        cv2.setNumThreads(1)
        try:
            yield
        finally:
            cv2.setNumThreads(before)
