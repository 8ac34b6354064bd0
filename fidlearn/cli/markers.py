"""``fidlearn markers`` and ``fidlearn board``: markers and calibration boards to print at exact size."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import printables
from ..errors import UsageError
from ..markermap import MarkerMap
from ._common import UNITS, _board, _check_dpi, _check_output, _commit, _refuse_clobber


def add_markers(sub) -> None:
    """Register ``fidlearn markers`` on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "markers",
        help="print ArUco markers at exact size (PDF or PNG)",
        description=(
            "Print ArUco markers at exact physical size: each black square measures --size-mm when "
            "the page is printed at 100 % (no scaling). Each marker has a white margin of one cell, "
            "its id and dictionary under it and cut marks; every page has a 100 mm ruler. "
            "Markers that do not fit on one page go on the next."
        ),
    )
    p.add_argument("--ids", help="marker ids: 0-9, 0,3,7 or 0-3,8")
    p.add_argument(
        "--map",
        type=Path,
        metavar="MAP.json",
        help="print every marker of a world map instead, each at its own size from its own dictionary",
    )
    p.add_argument("--units", choices=UNITS, help="units of a map that does not declare them")
    p.add_argument(
        "--size-mm",
        "--marker-size-mm",
        dest="size_mm",
        type=float,
        metavar="MM",
        help="side of the black square, mm (with --map: if the map does not say)",
    )
    p.add_argument("--dictionary", help="ArUco dictionary (default ARUCO_ORIGINAL, or the map's)")
    p.add_argument("--paper", choices=["a4", "letter"], default="a4", help="paper size (default a4)")
    p.add_argument("--dpi", type=float, default=300, help="pixels per inch of PNG output (default 300)")
    p.add_argument("-o", "--output", type=Path, required=True, help="markers.pdf (vector) or markers.png")
    p.set_defaults(run=run_markers)


def run_markers(args) -> int:
    """Write the marker pages; print where, how many, and how to print them.

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
    out = _check_output(args.output, (".pdf", ".png"))
    _refuse_clobber([("-o", out)], [Path(args.map)] if getattr(args, "map", None) else [])
    _check_dpi(args.dpi)
    sheets = _sheets(args)
    total, starts = sum(len(s.pages) for s in sheets), np.cumsum([0] + [len(s.pages) for s in sheets])
    figures = [fig for k, sheet in enumerate(sheets) for fig in printables.marker_figures(sheet, 1 + starts[k], total)]
    files = printables.save_pages(figures, out, dpi=args.dpi)
    _commit()
    pages = len(figures)
    where = ", ".join(str(f) for f in files)
    extra = f" at {args.dpi:g} dpi" if out.suffix.lower() == ".png" else ""
    several = f", {sheets[0].per_page} per page" if pages > 1 and len(sheets) == 1 else ""
    kinds = []
    for sheet in sheets:
        n = sum(len(p) for p in sheet.pages)
        kinds.append(f"{n} marker{'s' if n > 1 else ''} of {sheet.marker_size_mm:g} mm ({sheet.dictionary})")
    print(f"{where}: {' and '.join(kinds)} on {pages} {sheets[0].paper} page{'s' if pages > 1 else ''}{extra}{several}")
    print("print at 100 % (actual size, no 'fit to page') and check the 100 mm ruler with calipers")
    return 0


def _sheets(args) -> list:
    """The sheets to print: the ids at one size, or every marker of ``--map`` at its own."""
    if args.map is not None:
        if args.ids is not None:
            raise UsageError("give --ids or --map, not both: --map prints every marker of the map")
        marker_map = MarkerMap.load(args.map, units=args.units, marker_size_mm=args.size_mm, dictionary=args.dictionary)
        sheets = printables.layout_map_markers(marker_map, args.paper)
        for name, e in marker_map.entries.items():
            if getattr(e, "kind", None):
                print(f"board {name!r} is not on these pages: {_board_command(e, name)}")
        return sheets
    if args.ids is None or args.size_mm is None:
        raise UsageError("give --ids and --size-mm (e.g. --ids 0-9 --size-mm 80), or --map MAP.json")
    ids = printables.parse_ids(args.ids)
    return [printables.layout_markers(ids, args.size_mm, args.dictionary or "ARUCO_ORIGINAL", args.paper)]


def _board_command(e, name: str) -> str:
    """How to print a map's board entry whole."""
    if e.kind == "charuco" and e.first_id == 0 and not e.legacy:
        return (
            f"fidlearn board --squares {e.counts[0]}x{e.counts[1]} --square-mm {e.square_size_mm:g} --charuco "
            f"--marker-mm {e.marker_size_mm:g} --dictionary {e.dictionary} -o {name.replace(' ', '_')}.pdf"
        )
    return f"print it whole, with OpenCV's picture of it (MarkerMap.entries[{name!r}].cv_board().generateImage)"


def add_board(sub) -> None:
    """Register ``fidlearn board`` on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "board",
        help="print a checkerboard or ChArUco board at exact size",
        description=(
            "Print a calibration board at exact physical size with a 100 mm ruler. --pattern counts "
            "INNER corners, as OpenCV's findChessboardCorners does (9x6 gives 10x7 squares); "
            "--squares counts squares, as OpenCV's CharucoBoard does. The page turns to landscape "
            "when the board only fits that way."
        ),
    )
    size = p.add_mutually_exclusive_group(required=True)
    size.add_argument("--pattern", metavar="CxR", help="inner corners, e.g. 9x6 (10x7 squares)")
    size.add_argument("--squares", metavar="CxR", help="squares, e.g. 5x7 (4x6 inner corners)")
    p.add_argument("--square-mm", type=float, required=True, metavar="MM", help="side of one square, mm")
    p.add_argument("--charuco", action="store_true", help="a ChArUco board (markers in the white squares)")
    p.add_argument("--dictionary", help="ChArUco dictionary (default 6X6_250)")
    p.add_argument("--marker-mm", type=float, metavar="MM", help="ChArUco marker side, mm (smaller than the square)")
    p.add_argument("--paper", choices=["a4", "letter"], default="a4", help="paper size (default a4)")
    p.add_argument("--dpi", type=float, default=300, help="pixels per inch of PNG output (default 300)")
    p.add_argument("-o", "--output", type=Path, required=True, help="board.pdf (vector) or board.png")
    p.set_defaults(run=run_board)


def run_board(args) -> int:
    """Write the board page; print what it holds and how to print it.

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
    out = _check_output(args.output, (".pdf", ".png"))
    _check_dpi(args.dpi)
    sheet = printables.layout_board(_board(args), args.paper)
    files = printables.save_pages([printables.board_figure(sheet)], out, dpi=args.dpi)
    _commit()
    turn = ", landscape" if sheet.landscape else ""
    print(f"{files[0]}: {sheet.describe()}, {sheet.paper}{turn}")
    print("print at 100 % (actual size, no 'fit to page') and check the 100 mm ruler with calipers")
    return 0
