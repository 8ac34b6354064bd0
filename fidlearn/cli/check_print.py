"""``fidlearn check-print``: the printed markers' scale against the map's sizes, from one photo."""

from __future__ import annotations

from pathlib import Path

from ..images import load_image
from ..survey import check_print
from ._common import _add_image_size_option, _add_map_options, _load_camera, _load_map


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "check-print",
        help="how large the markers printed, from one photo of 4 or more of them",
        description=(
            "Estimate the common scale of the printed markers against the map's sizes from one photo that shows "
            "4 or more of them, spread out, with the calibrated camera: a printer at 98 %% makes every marker "
            "2 %% small, and every pose off by as much. Prints the scale with its standard error and the "
            "size_mm to write in the map (or reprint at 100 %%)."
        ),
    )
    p.add_argument("photo", type=Path, metavar="PHOTO", help="a photo of 4 or more of the map's markers")
    _add_map_options(p)
    p.add_argument("--camera", type=Path, required=True, metavar="CAMERA", help="camera file (fidlearn JSON or YAML)")
    _add_image_size_option(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Print the markers' print scale and what to do about it.

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
    marker_map = _load_map(args)
    camera = _load_camera(args)
    result = check_print(load_image(args.photo), marker_map, camera)
    print(result.advice())
    print(f"  from {len(result.marker_ids)} markers of {args.map}: {[str(k) for k in result.marker_ids]}")
    if result.left_out:
        print(
            f"  left out: {[str(k) for k in result.left_out]}, not where the map puts them beside the others "
            "(moved after they were measured, or a wrong id?)"
        )
    if result.repeated:
        print(
            f"  left out: {[str(k) for k in result.repeated]}, each detected twice "
            "(a reflection, or one id printed twice)"
        )
    return 0
