"""Printable markers and calibration boards at exact physical size.

Every page is drawn in millimetres on a figure the size of the paper, and every
black cell of a marker or square of a board is a vector rectangle, so the
printed black square measures exactly the size asked for when the page is
printed at 100 % ("actual size", no "fit to page"). Each page carries a
100 mm ruler with millimetre ticks to check that with calipers.

The page frame: origin at the paper's top-left corner, x to the right, y down,
millimetres. Nothing here opens a window: PDF pages go through matplotlib's
PDF backend, PNG pages through Agg, both used directly (no ``pyplot``, no
change to matplotlib's global state).

Examples
--------
>>> parse_ids("0-3,8")
[0, 1, 2, 3, 8]
>>> from fidlearn import Board
>>> layout_board(Board.checkerboard((9, 6), 25)).board.squares
(10, 7)
"""

from __future__ import annotations

from ..errors import PrintError
from ._boards import (
    QUIET_FRACTION,
    QUIET_MIN_MM,
    BoardSheet,
    board_figure,
    board_pdf,
    board_png,
    board_quiet_zone_mm,
    layout_board,
)
from ._markers import (
    MarkerSheet,
    layout_map_markers,
    layout_markers,
    marker_cells,
    marker_figures,
    markers_pdf,
    markers_png,
)
from ._page import (
    CUT_MARK_MM,
    CUT_MARK_OFFSET_MM,
    GAP_MM,
    LABEL_MM,
    LINE_PT,
    MAX_ID_COUNT,
    PAGE_MARGIN_MM,
    PAPERS,
    RULER_MM,
    STRIP_GAP_MM,
    STRIP_LEN_MM,
    STRIP_MM,
    paper_size_mm,
    parse_ids,
    save_pages,
)

__all__ = [
    "PAPERS",
    "PrintError",
    "MarkerSheet",
    "BoardSheet",
    "parse_ids",
    "paper_size_mm",
    "marker_cells",
    "layout_markers",
    "layout_map_markers",
    "layout_board",
    "board_quiet_zone_mm",
    "marker_figures",
    "board_figure",
    "markers_pdf",
    "markers_png",
    "board_pdf",
    "board_png",
    "save_pages",
    "QUIET_FRACTION",
    "QUIET_MIN_MM",
    "CUT_MARK_MM",
    "CUT_MARK_OFFSET_MM",
    "GAP_MM",
    "LABEL_MM",
    "LINE_PT",
    "MAX_ID_COUNT",
    "PAGE_MARGIN_MM",
    "RULER_MM",
    "STRIP_GAP_MM",
    "STRIP_LEN_MM",
    "STRIP_MM",
]
