"""``fidlearn calibrate``: camera intrinsics and distortion from photos of a board.

The command reads the photos, calls :func:`fidlearn.calibrate_checkerboard` or
:func:`fidlearn.calibrate_charuco`, prints the result with its ``warnings`` and the coach's
advice, and writes the camera, the coach's picture and the annotations together, only when all of them are done.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from .. import calibration
from ..boards import Board
from ..drawing import draw_calibration_view
from ..errors import CalibrationError, FidlearnWarning
from ..images import expand_inputs
from ..io import atomic_write
from ..planning.coach import coach_calibration
from ._common import _board, _check_output, _commit, _Progress, _refuse_clobber, _Staging


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "calibrate",
        help="camera intrinsics and distortion from photos of a board",
        description=(
            "Calibrate a camera from photos of a printed checkerboard (or a ChArUco board with --charuco). "
            "Prints a table of every photo (board found, reprojection error, rejected and why), the "
            "intrinsics with their standard deviations, how well the corners cover the picture, and "
            "warnings when the views are too few (< 10), too alike, or leave parts of the picture empty. "
            "Measure one printed square with calipers and give that as --square-mm."
        ),
    )
    p.add_argument(
        "inputs", nargs="+", type=Path, metavar="IMAGE_OR_FOLDER", help="photos of the board, or folders of them"
    )
    size = p.add_mutually_exclusive_group(required=True)
    size.add_argument("--pattern", metavar="CxR", help="inner corners, e.g. 9x6 (a board of 10x7 squares)")
    size.add_argument("--squares", metavar="CxR", help="squares, e.g. 5x7 (OpenCV's ChArUco count)")
    p.add_argument("--square-mm", type=float, required=True, metavar="MM", help="side of one printed square, mm")
    p.add_argument("--charuco", action="store_true", help="a ChArUco board")
    p.add_argument("--marker-mm", type=float, metavar="MM", help="ChArUco marker side, mm")
    p.add_argument("--dictionary", help="ChArUco dictionary (default 6X6_250)")
    p.add_argument("--annotate", type=Path, metavar="DIR", help="save each photo with its detected corners drawn")
    p.add_argument(
        "--model",
        choices=("pinhole", "fisheye", "auto"),
        default="pinhole",
        help="lens model: pinhole (OpenCV's 5 coefficients, default), fisheye (cv2.fisheye, 120 degrees and "
        "more) or auto (the fisheye when its error on held-out views is at least 10 %% lower)",
    )
    p.add_argument(
        "--report",
        type=Path,
        metavar="REPORT.png",
        help="draw the calibration's reprojection uncertainty over the picture and the next photo to take",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="camera file to write (.json, or OpenCV .yml/.xml)")
    p.set_defaults(run=run)


def _calibrate(paths: list[str], board: Board, model: str = "pinhole") -> calibration.Calibration:
    progress = _Progress("calibrate")
    try:
        if board.is_charuco:
            cal = calibration.calibrate_charuco(paths, board, progress=progress, model=model)
        else:
            cal = calibration.calibrate_checkerboard(paths, board=board, progress=progress, model=model)
    finally:
        progress.clear()
    progress.finish(sum(1 for v in cal.views if v.found))
    return cal


def _print_result(cal: calibration.Calibration) -> None:
    """The table of views, the camera with its standard deviations, the coverage; the warnings on stderr."""
    c, white = cal.camera, cal.std_intrinsics or {}
    try:
        u = calibration.intrinsics_uncertainty(cal)
        sd, k2 = {**white, **u.std}, u.k2
    except CalibrationError:  # too few points to tell: OpenCV's alone
        sd, k2 = white, None
    print(cal.table())
    print()
    print(
        f"camera {c.width}x{c.height} from {len(cal.used)} of {len(cal.views)} views of a {cal.board_description}, "
        f"RMS reprojection error {cal.rms_px:.3f} px"
    )
    if k2 is not None:
        print(
            f"standard deviations with what the views share beyond corner noise (k^2 = {k2:.1f}); "
            "corner noise alone (OpenCV's) in brackets"
        )
    for name, value in (("fx", c.fx), ("fy", c.fy), ("cx", c.cx), ("cy", c.cy)):
        print(f"  {name} {value:10.2f} ± {sd.get(name, float('nan')):.2f} px ({white.get(name, float('nan')):.2f})")
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4") if c.model == "fisheye" else calibration.INTRINSIC_NAMES
    dist_names = names[4 : 4 + len(c.dist)]
    print(
        "  distortion " + ", ".join(f"{n} {v:.4f} ± {sd.get(n, float('nan')):.4f}" for n, v in zip(dist_names, c.dist))
    )
    if cal.held_out_rms_px:
        errs = ", ".join(f"{m} {e:.3f} px" for m, e in cal.held_out_rms_px.items())
        print(f"lens model {c.model}, chosen by the RMS reprojection error on held-out views: {errs}")
    print("board corners per ninth of the picture (3x3 grid):")
    for row in cal.coverage if cal.coverage is not None else []:  # a run's Calibration has its coverage
        print("  " + " ".join(f"{v:6d}" for v in row))
    for sentence in cal.warnings:
        warnings.warn(sentence, FidlearnWarning, stacklevel=2)


def run(args) -> int:
    """Calibrate, print, then write the annotations, the coach's picture and the camera.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit status: 0 when done.

    Raises
    ------
    FidlearnError
        A user error (``UsageError`` for the command line itself); :func:`fidlearn.cli.main` prints it
        as one ``error:`` line and exits with status 2.
    """
    out = _check_output(args.output, (".json", ".yml", ".yaml", ".xml"))
    report = _check_output(args.report, (".png",), "--report") if args.report else None
    items = expand_inputs(args.inputs, videos=False, once=True)
    _refuse_clobber([("-o", out), ("--report", report)], [p for _, p in items], args.annotate)
    staging = _Staging(args.annotate)
    board = _board(args)
    paths = [str(p) for _, p in items]
    cal = _calibrate(paths, board, args.model)
    _print_result(cal)
    coached = coach_calibration(cal)  # the pinhole's or the fisheye's uncertainty, as calibrated
    print("calibration coach: " + coached.report(omit=cal.warnings).replace("\n", "\n  "))  # each warning once
    with staging:
        if args.annotate:
            for view, path in zip(cal.views, paths):  # views come back in input order
                pts = cal.image_points_px.get(view.name)
                staging.save(Path(path).name, draw_calibration_view(Path(path), view, pts, board))
        if report is not None:
            from ..planning.figure import coach_figure  # matplotlib: only when a picture is drawn (faster start)

            fig = coach_figure(coached, cal.camera)
            atomic_write(report, lambda tmp: fig.savefig(tmp, format="png", dpi=100))
        # a fidlearn camera file carries the calibration's covariance: poses located with it include its error
        carried = out.suffix.lower() == ".json" and cal.camera.model == "pinhole"
        (calibration.camera_with_uncertainty(cal) if carried else cal.camera).save(out)
    _commit()  # the camera, the report and the annotations take their names together
    said = " with its calibration's covariance (poses located with it include the calibration's error)"
    print(
        f"camera written to {out}"
        + (said if carried else "")
        + (f"; the coach's picture in {report}" if report else "")
    )
    if args.annotate:
        print(staging.said())
    return 0
