"""``fidlearn corners``: a world map (marker placements) to the 3D corners of each marker, mm."""

from __future__ import annotations

from pathlib import Path

from ..markermap import MarkerMap
from ._common import UNITS, _commit, _refuse_clobber


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "corners",
        help="world map (marker placements) to marker corners in mm",
        description="Turn a world map into the 3D corners of each marker (TL, TR, BR, BL, mm).",
    )
    p.add_argument("map", type=Path, metavar="MAP.json", help="world map JSON (bare seed layout or full layout)")
    p.add_argument("--units", choices=UNITS, help="units of a map that does not declare them")
    p.add_argument(
        "--marker-size-mm", type=float, metavar="MM", help="side of the black square in mm, if the map does not say"
    )
    p.add_argument("--dictionary", help="ArUco dictionary, if the map does not say (default ARUCO_ORIGINAL)")
    p.add_argument("-o", "--output", type=Path, required=True, help="corner file to write (JSON)")
    p.set_defaults(run=run)


def run(args) -> int:
    """Write the corner file; print how many markers and whether they are coplanar.

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
    _refuse_clobber([("-o", args.output)], [args.map])
    m = MarkerMap.load(args.map, units=args.units, marker_size_mm=args.marker_size_mm, dictionary=args.dictionary)
    m.save_corners(args.output)
    _commit()
    plane = (
        f"coplanar (within {m.planarity_mm():.2f} mm)"
        if m.is_coplanar()
        else f"not coplanar ({m.planarity_mm():.1f} mm off a plane)"
    )
    markers = f"{len(m)} marker{'s' if len(m) != 1 else ''}"
    print(f"{args.output}: corners of {markers} {m.ids}, {m.marker_size_mm:g} mm, {plane}")
    return 0
