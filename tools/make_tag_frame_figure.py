"""Draw docs/img/tag_frame.png: a WPILib field tag's frame and corner order, and the pose mirrored corners give.

python tools/make_tag_frame_figure.py [OUT.png]     # default: docs/img/tag_frame.png

Left: tag 7 of the 2024 field layout as a robot on the field sees it (OpenCV's APRILTAG_36h11 marker 7),
its corners TL, TR, BR, BL and its frame (x out of the tag towards the viewer, y to the viewer's right,
z up). Right: the field from above near the blue alliance wall: the camera on the field and the pose that the
same picture gives with the tag's corners mirrored (TL and TR swapped), behind the wall.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fidlearn import MarkerMap  # noqa: E402
from fidlearn.data import data_path, repo_dir  # noqa: E402
from fidlearn.markermap import CORNER_NAMES  # noqa: E402
from fidlearn.printables import marker_cells  # noqa: E402

OUT = repo_dir() / "docs" / "img" / "tag_frame.png"


def main(out: Path = OUT) -> Path:
    m = MarkerMap.load(data_path("wpilib", "2024-crescendo.json"), dictionary="apriltag_36h11", marker_size_mm=165.1)
    fig, (ax, top) = plt.subplots(1, 2, figsize=(11, 5), gridspec_kw={"width_ratios": [1, 1.3]})
    img = np.where(marker_cells("APRILTAG_36h11", 7), 0, 255)  # 8 x 8 cells, black border included
    ax.imshow(np.pad(img, 1, constant_values=255), cmap="gray", extent=(-0.625, 0.625, -0.625, 0.625))
    for name, (u, v) in zip(CORNER_NAMES, [(-0.5, 0.5), (0.5, 0.5), (0.5, -0.5), (-0.5, -0.5)]):
        ax.plot(u, v, "o", color="tab:red")
        ax.annotate(name, (u, v), xytext=(u * 1.12, v * 1.12), ha="center", va="center", color="tab:red", weight="bold")
    ax.annotate("", (0.45, 0), (0, 0), arrowprops={"color": "tab:green", "width": 2})
    ax.annotate("", (0, 0.45), (0, 0), arrowprops={"color": "tab:blue", "width": 2})
    ax.text(0.47, 0.03, "y (right)", color="tab:green", weight="bold")
    ax.text(0.03, 0.47, "z (up)", color="tab:blue", weight="bold")
    ax.plot(0, 0, "o", ms=12, mfc="white", mec="tab:orange", mew=2)
    ax.plot(0, 0, ".", color="tab:orange")
    ax.text(-0.3, -0.08, "x: out of the tag", color="tab:orange", weight="bold")
    ax.set_title("tag 7 as seen from the field: pose = its centre", fontsize=10)
    ax.set_axis_off()
    c = m.corners()[7] / 1000.0
    top.plot([0, 0], [4.6, 6.0], color="0.3", lw=6)
    top.text(-0.05, 6.02, "blue alliance wall (x = 0)", fontsize=8, ha="right")
    top.plot(c[:2, 0] + 0.02, c[:2, 1], color="k", lw=4)
    top.annotate("TL", (c[0, 0], c[0, 1]), xytext=(0.1, c[0, 1] - 0.05), color="tab:red")
    top.annotate("TR", (c[1, 0], c[1, 1]), xytext=(0.1, c[1, 1]), color="tab:red")
    top.annotate("", (0.45, 5.548), (0.0, 5.548), arrowprops={"color": "tab:orange", "width": 1.5})
    top.plot(1.0, 5.65, "s", color="tab:green", ms=10)
    top.text(1.05, 5.7, "camera on the field", color="tab:green")
    top.plot(-1.08, 5.44, "X", color="tab:red", ms=12)
    top.text(-1.55, 5.0, "pose from mirrored corners\n(TL, TR swapped):\nbehind the wall, refused", color="tab:red")
    top.set_xlim(-1.6, 1.9)
    top.set_ylim(4.6, 6.2)
    top.set_aspect("equal")
    top.set_xlabel("field x, m")
    top.set_ylabel("field y, m")
    top.set_title("from above (Z up): tag 7 faces +x, into the field", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out


if __name__ == "__main__":
    print(main(Path(sys.argv[1]) if len(sys.argv) > 1 else OUT))
