"""Draw docs/img/conventions.png: the world frame, the north wall, one marker's corners and the camera frame.

python tools/make_conventions_figure.py [OUT.png]     # default: docs/img/conventions.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fidlearn import MarkerMap, frames  # noqa: E402
from fidlearn.data import data_path, repo_dir  # noqa: E402
from fidlearn.markermap import CORNER_NAMES  # noqa: E402

OUT = repo_dir() / "docs" / "img" / "conventions.png"


def arrow(ax, origin, direction, color, label, length=300.0):
    o = np.asarray(origin, float)
    d = np.asarray(direction, float) * length
    ax.quiver(*o, *d, color=color, arrow_length_ratio=0.12, linewidth=2)
    ax.text(*(o + d * 1.12), label, color=color, fontsize=10, fontweight="bold")


def main(out: Path = OUT) -> Path:
    m = MarkerMap.load(data_path("world_map.json"))
    fig = plt.figure(figsize=(9, 7))
    ax = fig.add_subplot(projection="3d")

    # the north wall: the world YZ plane (x = 0)
    ys, zs = np.meshgrid([-150, 600], [0, 500])
    ax.plot_surface(np.zeros_like(ys), ys, zs, color="0.85", alpha=0.35, linewidth=0)
    ax.text(0, 560, 480, "north wall (x = 0)", color="0.35", fontsize=9)

    # world frame at the origin, Z up
    for axis, color, name in zip(np.eye(3), "rgb", "XYZ"):
        arrow(ax, [0, 0, 0], axis, color, f"world {name}", length=160)

    # markers: outline; marker 0 gets its corners labelled in the winding order
    for mid, c in m.corners().items():
        loop = np.vstack([c, c[:1]])
        ax.plot(*loop.T, color="k", linewidth=1.5)
        ax.text(*(c.mean(axis=0) + [0, -10, 0]), f"id {mid}", fontsize=8)
    c0 = m.corners()[0]
    for name, p, off in zip(CORNER_NAMES, c0, ([0, -40, 12], [0, 8, 12], [0, 8, -28], [0, -40, -28])):
        ax.scatter(*p, color="m", s=18)
        ax.text(*(p + off), name, color="m", fontsize=9, fontweight="bold")

    # a camera in the room looking back at the wall: OpenCV camera frame x right, y down, z forward
    # looking at the wall (-X): right is +Y, down is -Z, forward is -X; the columns of R are those axes
    R_world_camera = np.column_stack([[0, 1, 0], [0, 0, -1], [-1, 0, 0]])
    T_world_camera = frames.make_transform(R_world_camera, [1200.0, 200.0, 260.0])
    origin = T_world_camera[:3, 3]
    for axis, color, name in zip(T_world_camera[:3, :3].T, "rgb", ("x right", "y down", "z forward")):
        arrow(ax, origin, axis, color, f"camera {name}", length=220)
    ax.text(*(origin + [0, 0, 90]), "camera", fontsize=10)

    ax.set_xlabel("X (mm, out of the wall)")
    ax.set_ylabel("Y (mm, along the wall)")
    ax.set_zlabel("Z (mm, up)")
    ax.set_box_aspect((1.4, 0.9, 0.6))
    ax.set_xlim(0, 1400)
    ax.set_ylim(-150, 600)
    ax.set_zlim(0, 500)
    ax.view_init(elev=18, azim=28)
    ax.set_title("fidlearn's frames: world Z up (ROS), marker corners TL, TR, BR, BL, camera as OpenCV's")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


if __name__ == "__main__":
    print(main(Path(sys.argv[1]) if len(sys.argv) > 1 else OUT))
