"""Windows of a picture to detect markers in: boxes around predicted corners, merged where that costs little."""

from __future__ import annotations

import numpy as np

#: Two windows become one when their bounding box is at most this much larger than the two together
#: (px^2): each detectMarkers call has a fixed cost worth about this many pixels of image.
_MERGE_SLACK_PX2 = 4096


def boxes_around(corners: np.ndarray, pad: np.ndarray, W: int, H: int) -> list:
    """Merged boxes ``(x0, y0, x1, y1)`` around each marker's corners (M, 4, 2), ``pad`` (M,) px beyond them, cut
    to the W x H picture; a box with less than 8 px of the picture in either direction is left out."""
    lo = np.maximum(np.floor(corners.min(axis=1) - pad[:, None]).astype(int), 0)
    hi = np.minimum(np.ceil(corners.max(axis=1) + pad[:, None]).astype(int) + 1, [W, H])
    ok = (hi > lo + 8).all(axis=1)
    return merge_boxes([(*a, *b) for a, b in zip(lo[ok], hi[ok])])


def merge_boxes(boxes: list) -> list:
    """Boxes ``(x0, y0, x1, y1)`` with each pair whose bounding box is at most ``_MERGE_SLACK_PX2``
    larger than the two together replaced by that bounding box, repeated until no such pair is left.

    Other boxes stay apart, overlapping or not (a marker in two is found twice and kept once): one
    big box around a chain of neighbours would cover far more of the image than the windows do.
    """

    def area(b):
        return (b[2] - b[0]) * (b[3] - b[1])

    boxes = [tuple(int(v) for v in b) for b in boxes]
    merged = True
    while merged and len(boxes) > 1:
        merged = False
        out: list = []
        for b in boxes:
            for k, o in enumerate(out):
                u = (min(o[0], b[0]), min(o[1], b[1]), max(o[2], b[2]), max(o[3], b[3]))
                if area(u) <= area(o) + area(b) + _MERGE_SLACK_PX2:
                    out[k] = u
                    merged = True
                    break
            else:
                out.append(b)
        boxes = out
    return boxes
