"""Cross-validation of calibrations on real photos: do independent sets of one camera agree within their noise?

    python benchmarks/bench_crossval.py                  # the bundled real sets (about 30 s on an idle machine)
    python benchmarks/bench_crossval.py --fisheye DIR    # also the fisheye sets under DIR (mono/, stereo/)

Each real set is split in two (alternate photos; first and last photos) and each half calibrated
(``calibrate_checkerboard`` / ``calibrate_charuco``, the pinhole model with 5 coefficients). For
each pair: the views' pull beyond white noise ``k^2`` of each half (``intrinsics_uncertainty``),
the largest difference of ``fx, fy, cx, cy`` in combined standard deviations with OpenCV's (white)
and with the inflated ones, and ``compare_calibrations``'s ratio (RMS over the picture of the
projection difference in its own standard deviations) with both, and its verdict. Independent sets
of one camera should give ratios under 2. The fisheye sets (``--fisheye``: the folder
``fisheye_checkerboard`` of ros-perception/image_pipeline's fisheye calibration reference: one
160-degree lens, ``mono/left-*`` 24 photos, and a stereo pair of such lenses) are calibrated with
the pinhole model too, which cannot describe that lens near its edges: the worst case for white noise.

Then the bent-board test on every real set: the views called bent by significance alone (the
F-test, as before ``BENT_MIN_SAG_MM``) and by significance and size (now), each with its fitted sag.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from fidlearn import Board, calibrate_charuco, calibrate_checkerboard  # noqa: E402
from fidlearn.calibration import compare_calibrations, intrinsics_uncertainty  # noqa: E402
from fidlearn.data import data_path  # noqa: E402
from fidlearn.planning import bent_board  # noqa: E402

CHECKER = Board.checkerboard((9, 6), 25)  # the square size was never published: 25 mm stands in
ROBOT = Board.charuco((5, 7), 36.195, 18.256, "DICT_6X6_250")
FISHEYE = Board.checkerboard((8, 6), 25)  # 6 x 8 inner corners; square size not published


def _sets(fisheye: Path | None) -> dict:
    right = sorted(data_path("real", "opencv_checkerboard_right").glob("right*.jpg"))
    robot = [data_path("real", "robot_charuco", f"{i}.png") for i in range(16)]
    out = {
        "OpenCV right*.jpg (13)": (right, CHECKER),
        "robot ChArUco (16)": (robot, ROBOT),
    }
    if fisheye is not None:
        out["fisheye mono (24), pinhole model"] = (sorted((fisheye / "mono").glob("left-*.png")), FISHEYE)
    return out


def _calibrate(photos, board):
    if board.is_charuco:
        return calibrate_charuco(photos, board)
    return calibrate_checkerboard(photos, board=board)


LAST: list[float] = []
RATIOS: list[float] = []  # compare_calibrations' inflated ratio of every pair of the bundled sets
FLAT_FLAGGED: list[int] = []  # views called bent on the rigid real boards (robot, tutorial ChArUco)


def _pair(a, b) -> str:
    ua, ub = intrinsics_uncertainty(a), intrinsics_uncertainty(b)
    va = np.array([a.camera.fx, a.camera.fy, a.camera.cx, a.camera.cy])
    vb = np.array([b.camera.fx, b.camera.fy, b.camera.cx, b.camera.cy])
    names = ("fx", "fy", "cx", "cy")
    z_white = np.abs(va - vb) / np.hypot([ua.white_std[n] for n in names], [ub.white_std[n] for n in names])
    z_honest = np.abs(va - vb) / np.hypot([ua.std[n] for n in names], [ub.std[n] for n in names])
    white = compare_calibrations(a, b, inflate=False)
    honest = compare_calibrations(a, b)
    LAST[:] = [honest.ratio]
    return (
        f"{ua.k2:5.1f} {ub.k2:5.1f}  {z_white.max():6.1f} {z_honest.max():6.1f}  "
        f"{white.ratio:6.1f} {honest.ratio:6.1f}  {honest.rms_difference_px:7.2f}  {honest.verdict}"
    )


def crossval(fisheye: Path | None) -> None:
    print("1. Halves of one set (and two sets of one lens): k^2 of each half, the largest |difference| of")
    print("   fx, fy, cx, cy in combined standard deviations, compare_calibrations' ratio, white and inflated")
    print(
        f"   {'pair':<52} {'k2 a':>5} {'k2 b':>5}  {'z wht':>6} {'z inf':>6}  {'r wht':>6} {'r inf':>6}  {'rms px':>7}"
    )
    for name, (photos, board) in _sets(fisheye).items():
        n = len(photos)
        for split, (pa, pb) in (
            ("alternate", (photos[0::2], photos[1::2])),
            ("first/last", (photos[: n // 2], photos[n // 2 :])),
        ):
            print(f"   {name + ', ' + split:<52} {_pair(_calibrate(pa, board), _calibrate(pb, board))}")
            if "fisheye" not in name:
                RATIOS.append(LAST[0])
    if fisheye is not None:
        mono = sorted((fisheye / "mono").glob("left-*.png"))
        left = sorted((fisheye / "stereo").glob("left-*.png"))
        print(
            f"   {'fisheye mono vs stereo left (one lens), pinhole':<52} "
            f"{_pair(_calibrate(mono, FISHEYE), _calibrate(left, FISHEYE))}"
        )


def bends(fisheye: Path | None) -> None:
    print()
    print(
        f"2. Bent boards: views called bent by significance alone, and by significance and a sag >= "
        f"{bent_board.BENT_MIN_SAG_MM:g} mm (now)"
    )
    sets = dict(_sets(fisheye))
    sets["OpenCV right*.jpg, outlier right02 kept"] = (sets["OpenCV right*.jpg (13)"][0], CHECKER, False)
    sets["OpenCV ChArUco tutorial (5)"] = (
        sorted(data_path("real", "opencv_charuco").glob("*.jpg")),
        Board.charuco((5, 7), 40, 20, "DICT_6X6_250"),
    )
    for name, spec in sets.items():
        photos, board = spec[:2]
        cal = (
            calibrate_checkerboard(photos, board=board, reject_outliers=False)
            if len(spec) == 3
            else _calibrate(photos, board)
        )
        views = (cal.camera, cal.board_points_mm, cal.image_points_px, cal.T_camera_board)
        now = bent_board.board_bends(*views)
        saved = bent_board.BENT_MIN_SAG_MM
        bent_board.BENT_MIN_SAG_MM = 0.0
        try:
            before = bent_board.board_bends(*views)
        finally:
            bent_board.BENT_MIN_SAG_MM = saved

        def said(bs):
            return ", ".join(f"{Path(b.name).name} {b.sag_mm:.2f}±{b.sag_std_mm:.2f}" for b in bs) or "none"

        if "robot" in name or "tutorial" in name:
            FLAT_FLAGGED.append(len(now))
        print(f"   {name} ({len(cal.used)} views)")
        print(f"      significance alone: {len(before)}: {said(before)}")
        print(f"      and sag >= {bent_board.BENT_MIN_SAG_MM:g} mm:  {len(now)}: {said(now)}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--fisheye", type=Path, help="the fisheye_checkerboard folder (mono/, stereo/)")
    args = p.parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    crossval(args.fisheye)
    bends(args.fisheye)
    print(f"\n{time.perf_counter() - t0:.0f} s")
    worst = max(RATIOS)
    print(
        "<!-- target: crossval: halves of one real set agree within 2 x their stated noise (compare_calibrations "
        f"ratio, bundled sets) | {worst:.1f} at worst over {len(RATIOS)} pairs | {'yes' if worst <= 2 else 'no'} -->"
    )
    print(
        "<!-- target: crossval: no view of a rigid real board (robot, tutorial ChArUco) called bent | "
        f"{sum(FLAT_FLAGGED)} | {'yes' if sum(FLAT_FLAGGED) == 0 else 'no'} -->"
    )


if __name__ == "__main__":
    main()
