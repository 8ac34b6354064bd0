"""``fidlearn compare-calibrations A B``: do two calibrations of one camera agree, beyond their noise?

Each of ``A`` and ``B`` is a camera file or a folder of board photos, calibrated here with the board
options. A camera file brings the covariance of its intrinsics when it carries one (``fidlearn calibrate``
writes it into a ``.json`` file); one without is taken as exact beside a calibration, and two without give
"cannot tell". The command prints the verdict of :func:`fidlearn.calibration.compare_calibrations` with its
numbers, and with ``--report`` draws the difference across the picture beside its expected size.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import calibration
from ..camera import Camera
from ..errors import UsageError
from ..io import atomic_write
from ._common import _board, _check_output, _commit, _Progress, _refuse_clobber


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "compare-calibrations",
        help="do two calibrations of one camera agree, beyond their noise?",
        description=(
            "Compare two calibrations of one camera across the picture: unproject a grid of pixels with A, "
            "turn the rays by the fitted rotation between the two cameras, project them with B. The "
            "difference is judged against both calibrations' uncertainty (corner noise plus what each set's "
            "views share): agree, differ beyond noise, or cannot tell. A and B are camera files or folders of "
            "board photos, calibrated here (give the board options, as for fidlearn calibrate). A camera file "
            "written by fidlearn calibrate (.json) carries its calibration's uncertainty; one without (an OpenCV "
            "YAML file, a published or a true camera) is taken as exact, and two without give cannot tell. "
            "Exit status 0 whatever the verdict."
        ),
    )
    p.add_argument("first", type=Path, metavar="A", help="camera file or folder of board photos")
    p.add_argument("second", type=Path, metavar="B", help="camera file or folder of board photos")
    size = p.add_mutually_exclusive_group()
    size.add_argument("--pattern", metavar="CxR", help="inner corners, e.g. 9x6 (for folders of photos)")
    size.add_argument("--squares", metavar="CxR", help="squares, e.g. 5x7 (OpenCV's ChArUco count)")
    p.add_argument("--square-mm", type=float, metavar="MM", help="side of one printed square, mm")
    p.add_argument("--charuco", action="store_true", help="a ChArUco board")
    p.add_argument("--marker-mm", type=float, metavar="MM", help="ChArUco marker side, mm")
    p.add_argument("--dictionary", help="ChArUco dictionary (default 6X6_250)")
    p.add_argument(
        "--tolerance-px",
        type=float,
        default=1.0,
        metavar="PX",
        help="expected differences larger than this (median over the picture) cannot be said to agree (default 1)",
    )
    p.add_argument(
        "--report",
        type=Path,
        metavar="REPORT.png",
        help="draw the difference across the picture beside its expected size",
    )
    p.set_defaults(run=run)


def _check_input(path: Path, args, which: str) -> None:
    """Before any work: a camera file, or a folder of photos with the board given."""
    if path.is_dir():
        if (args.pattern is None and args.squares is None) or args.square_mm is None:
            raise UsageError(
                f"{which} {path} is a folder of photos: give the board (--pattern or --squares, and --square-mm)"
            )
        _board(args)
    elif not path.is_file():
        raise UsageError(f"{which} {path}: no such file or folder; give a camera file or a folder of board photos")


def _load(path: Path, args, which: str):
    """A camera file as a Camera, a folder of photos calibrated."""
    if path.is_dir():
        board = _board(args)
        progress = _Progress(f"calibrate {path}")
        try:
            if board.is_charuco:
                cal = calibration.calibrate_charuco(path, board, progress=progress)
            else:
                cal = calibration.calibrate_checkerboard(path, board=board, progress=progress)
        finally:
            progress.clear()
        progress.finish(sum(1 for v in cal.views if v.found))
        print(f"{which}: {cal!r}")
        return cal
    camera = Camera.load(path)
    carried = "with its calibration's uncertainty" if camera.intrinsics_covariance is not None else "no uncertainty"
    print(f"{which}: {camera!r} (a camera file: {carried})")
    return camera


def run(args) -> int:
    """Load or calibrate both, compare them, print the verdict, draw the plot.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit status: 0 when done, whatever the verdict.

    Raises
    ------
    FidlearnError
        A user error; :func:`fidlearn.cli.main` prints it as one ``error:`` line and exits with status 2.
    """
    if not 0 < args.tolerance_px < float("inf"):  # before calibrating anything
        raise UsageError(f"--tolerance-px must be a positive number of pixels, got {args.tolerance_px:g}")
    plot = _check_output(args.report, (".png",), "--report") if args.report else None
    if plot is not None:
        _refuse_clobber([("--report", plot)], [args.first, args.second])
    _check_input(args.first, args, "A")
    _check_input(args.second, args, "B")
    a, b = _load(args.first, args, "A"), _load(args.second, args, "B")
    result = calibration.compare_calibrations(a, b, tolerance_px=args.tolerance_px)
    print(f"rotation between the two cameras: {result.rotation_deg:.3f} deg")
    print(f"largest difference {float(np.nanmax(result.difference_norm_px)):.2f} px")
    print(f"verdict: {result}")
    if plot is not None:
        fig = result.plot()
        atomic_write(plot, lambda tmp: fig.savefig(tmp, format="png", dpi=100))
        _commit()
        print(f"plot written to {plot}")
    return 0
