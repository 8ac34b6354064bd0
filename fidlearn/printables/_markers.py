"""Printed ArUco markers: where each goes on the pages, and the pages."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _cv
from ..errors import DictionaryError, PrintError
from ._page import (
    GAP_MM,
    LABEL_MM,
    _cut_marks,
    _draw_strip,
    _fill_rects,
    _marker_rects,
    _page,
    _positive_mm,
    _usable_area,
    _with_suffix,
    paper_size_mm,
    parse_ids,
    save_pages,
)


def marker_cells(dictionary: str, marker_id: int) -> np.ndarray:
    """The marker's cells, black border included, row 0 at the top.

    Parameters
    ----------
    dictionary : str
        ArUco dictionary name.
    marker_id : int
        An id of that dictionary.

    Returns
    -------
    ndarray of bool, shape (n, n)
        True = black; ``n`` is the dictionary's marker size plus 2 (7 for ARUCO_ORIGINAL, 8 for 6X6_250).

    Raises
    ------
    DictionaryError
        For an unknown dictionary or an id it does not have.
    """
    name = _cv.dictionary_name(dictionary)
    size = _cv.dictionary_size(name)
    if not 0 <= int(marker_id) < size:
        raise DictionaryError(f"marker id {marker_id} does not exist in {name}, which has ids 0 to {size - 1}")
    n = _cv.dictionary_marker_bits(name) + 2
    return _cv.generate_marker(name, int(marker_id), n, border_bits=1) < 128


@dataclass(frozen=True)
class MarkerSheet:
    """Where each marker goes on each page.

    Attributes
    ----------
    paper : str
    paper_mm : (float, float)
        Page (width, height) in mm.
    marker_size_mm : float
        Side of each black square (border included), mm.
    cell_mm : float
        Side of one cell, mm (``marker_size_mm`` / cells per side).
    dictionary : str
    pages : list of list of (int, float, float)
        Per page: ``(id, x_mm, y_mm)``, the top-left corner of each black square
        in the page frame (origin top-left of the paper, y down).
    """

    paper: str
    paper_mm: tuple[float, float]
    marker_size_mm: float
    cell_mm: float
    dictionary: str
    pages: list[list[tuple[int, float, float]]] = field(repr=False)

    @property
    def per_page(self) -> int:
        """How many markers fit on one page."""
        return max(len(p) for p in self.pages)

    def __repr__(self) -> str:
        n = sum(len(p) for p in self.pages)
        return (
            f"MarkerSheet({n} markers of {self.marker_size_mm:g} mm, {self.dictionary}, {self.paper} "
            f"{self.paper_mm[0]:g}x{self.paper_mm[1]:g} mm, {len(self.pages)} page(s), {self.per_page} per page)"
        )


def layout_markers(
    ids: Iterable[Any] | str | int, marker_size_mm: float, dictionary: str = "ARUCO_ORIGINAL", paper: str = "a4"
) -> MarkerSheet:
    """Place markers in a grid, as many per page as fit, with a white quiet zone of one cell.

    Each marker's cut rectangle holds the black square, a white margin of one
    cell on every side, and a label strip under it; cut rectangles are
    :data:`GAP_MM` apart.

    Parameters
    ----------
    ids : iterable of int, int or str
        Marker ids in print order, or a string such as ``"0-9"`` (:func:`parse_ids`).
    marker_size_mm : float
        Side of each black square (border included), mm.
    dictionary : str
        ArUco dictionary name.
    paper : {"a4", "letter"}

    Returns
    -------
    MarkerSheet
        Where each marker goes on each page (page frame, mm).

    Raises
    ------
    PrintError
        For no ids, an id that is not a whole number, a size that is not a length or does not fit the
        paper (the largest that fits is named).
    DictionaryError
        For an id the dictionary does not have.
    """
    marker_size_mm = _positive_mm(marker_size_mm, "--size-mm")
    name = _cv.dictionary_name(dictionary)
    if isinstance(ids, str):
        ids = parse_ids(ids)  # "0-9", "0,3,7" as on the command line
    ids = list(ids) if isinstance(ids, Iterable) and not isinstance(ids, (bytes, bytearray)) else [ids]
    wrong = [i for i in ids if isinstance(i, bool) or not isinstance(i, (int, np.integer))]
    if wrong:
        raise PrintError(f"marker id {wrong[0]!r} is not a whole number; give ids like range(10) or [0, 3, 7]")
    ids = [int(i) for i in ids]
    if not ids:
        raise PrintError("no marker ids to print; give --ids like 0-9")
    for i in ids:
        marker_cells(name, i)  # raises for an id outside the dictionary
    paper_mm = paper_size_mm(paper)
    cells = _cv.dictionary_marker_bits(name) + 2
    cell = marker_size_mm / cells
    slot_w = marker_size_mm + 2 * cell
    slot_h = marker_size_mm + 2 * cell + LABEL_MM
    x0, y0, uw, uh = _usable_area(paper_mm)
    cols = int((uw + GAP_MM + 1e-9) // (slot_w + GAP_MM))
    rows = int((uh + GAP_MM + 1e-9) // (slot_h + GAP_MM))
    if cols < 1 or rows < 1:
        largest = min(uw * cells / (cells + 2), (uh - LABEL_MM) * cells / (cells + 2))
        raise PrintError(
            f"a {marker_size_mm:g} mm marker (with its one-cell white margin and label) does not fit on "
            f"{paper} paper; the largest that fits is {math.floor(largest * 10) / 10:g} mm: lower --size-mm"
        )
    grid_w = cols * slot_w + (cols - 1) * GAP_MM
    grid_h = rows * slot_h + (rows - 1) * GAP_MM
    left = x0 + (uw - grid_w) / 2
    top = y0 + (uh - grid_h) / 2
    per_page = cols * rows
    pages = []
    for start in range(0, len(ids), per_page):
        page = []
        for k, mid in enumerate(ids[start : start + per_page]):
            r, c = divmod(k, cols)
            page.append((mid, left + c * (slot_w + GAP_MM) + cell, top + r * (slot_h + GAP_MM) + cell))
        pages.append(page)
    return MarkerSheet(str(paper).lower(), paper_mm, marker_size_mm, cell, name, pages)


def marker_figures(sheet: MarkerSheet, first_page: int = 1, pages: int | None = None) -> list:
    """The pages of a :class:`MarkerSheet` as matplotlib figures (nothing written).

    Parameters
    ----------
    sheet : MarkerSheet
        From :func:`layout_markers`.
    first_page, pages : int, optional
        The first page's number and the whole document's page count, for a sheet printed after others (a map's
        markers of several sizes); by default the sheet's own, from 1.

    Returns
    -------
    list of matplotlib.figure.Figure
        One per page, the size of the paper, drawn in mm.
    """
    figs = []
    cell = sheet.cell_mm
    for k, page in enumerate(sheet.pages):
        fig, ax = _page(sheet.paper_mm)
        title = (
            f"fidlearn markers, {sheet.dictionary}, black square {sheet.marker_size_mm:g} mm, "
            f"page {first_page + k} of {len(sheet.pages) if pages is None else pages}"
        )
        rects = []
        for mid, x, y in page:
            rects += _marker_rects(marker_cells(sheet.dictionary, mid), x, y, cell)
            cut = (x - cell, y - cell, sheet.marker_size_mm + 2 * cell, sheet.marker_size_mm + 2 * cell + LABEL_MM)
            _cut_marks(ax, *cut)
            label_y = y + sheet.marker_size_mm + cell + LABEL_MM / 2
            long = f"id {mid}   {sheet.dictionary}   {sheet.marker_size_mm:g} mm"
            if len(long) * 1.3 > cut[2]:  # about 1.3 mm per character at 7 pt
                second = f"{sheet.dictionary} {sheet.marker_size_mm:g} mm"
                ax.text(x + sheet.marker_size_mm / 2, label_y - 1.4, f"id {mid}", ha="center", va="center", fontsize=7)
                ax.text(
                    x + sheet.marker_size_mm / 2,
                    label_y + 1.6,
                    second,
                    ha="center",
                    va="center",
                    fontsize=_fitting_points(second, cut[2], 5.0),  # within the cut, or cutting halves it
                )
            else:
                ax.text(x + sheet.marker_size_mm / 2, label_y, long, ha="center", va="center", fontsize=7)
        _fill_rects(ax, rects)
        _draw_strip(ax, sheet.paper_mm, "bottom", title)
        figs.append(fig)
    return figs


def _fitting_points(text: str, width_mm: float, most: float) -> float:
    """The font size (pt, at most ``most``) at which ``text`` fits in ``width_mm``: up to 1.65 mm a character at
    7 pt for the capitals of a dictionary's name, in proportion."""
    return min(most, 7.0 * 0.88 * width_mm / (1.65 * max(len(text), 1)))


def markers_pdf(
    path, ids: Sequence[int], marker_size_mm: float, *, dictionary: str = "ARUCO_ORIGINAL", paper: str = "a4"
) -> MarkerSheet:
    """Write a (multi-page) PDF of markers at exact size.

    Parameters
    ----------
    path : path-like
        The ``.pdf`` file to write (atomically).
    ids : sequence of int
        Marker ids, in print order.
    marker_size_mm : float
        Side of each black square (border included), mm.
    dictionary : str
        ArUco dictionary name, e.g. ``"ARUCO_ORIGINAL"`` or ``"6X6_250"``.
    paper : {"a4", "letter"}

    Returns
    -------
    MarkerSheet
        The layout.

    Raises
    ------
    PrintError
        As :func:`layout_markers`, or when ``path`` is not a ``.pdf``.
    """
    sheet = layout_markers(ids, marker_size_mm, dictionary, paper)
    save_pages(marker_figures(sheet), _with_suffix(path, ".pdf"))
    return sheet


def markers_png(
    path,
    ids: Sequence[int],
    marker_size_mm: float,
    *,
    dictionary: str = "ARUCO_ORIGINAL",
    paper: str = "a4",
    dpi: float = 300,
) -> tuple[MarkerSheet, list[Path]]:
    """Write the marker pages as PNG at ``dpi``.

    Parameters
    ----------
    path : path-like
        The ``.png`` file (``stem-1.png``, ``stem-2.png``, ... for several pages).
    ids, marker_size_mm, dictionary, paper :
        As for :func:`markers_pdf`.
    dpi : float
        Resolution, 30 to 2400.

    Returns
    -------
    sheet : MarkerSheet
        The layout.
    files : list of Path
        The files written.

    Raises
    ------
    PrintError
        As :func:`layout_markers` and :func:`save_pages`.
    """
    sheet = layout_markers(ids, marker_size_mm, dictionary, paper)
    return sheet, save_pages(marker_figures(sheet), _with_suffix(path, ".png"), dpi=dpi)


def layout_map_markers(marker_map, paper: str = "a4") -> list[MarkerSheet]:
    """Lay out every marker of a world map at its own size, from its own dictionary.

    Markers of one dictionary and one size share a :class:`MarkerSheet` (laid out as
    :func:`layout_markers` does); a map whose markers all have the map's size and dictionary gives one. A
    board entry's markers are left out: a board is printed whole (:func:`board_figure`), its squares and
    spacing with them; a bundle's markers are loose markers stuck on one object, and are laid out here.

    Parameters
    ----------
    marker_map : MarkerMap
        The map; each marker's ``marker_size(key)`` and ``marker_dictionary(key)``.
    paper : {"a4", "letter"}

    Returns
    -------
    list of MarkerSheet
        One per (dictionary, size), the map's dictionary first, then by size.

    Raises
    ------
    PrintError
        A marker too large for the paper (the largest that fits is named), or a map whose markers are all on
        boards.

    Examples
    --------
    >>> from fidlearn import MarkerMap
    >>> m = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80, "markers": {
    ...     "0": {"translation": [0, 0, 0]}, "1": {"translation": [0, 100, 0]},
    ...     "4X4_50:0": {"translation": [0, 300, 0], "size_mm": 140}}})
    >>> [(s.dictionary, s.marker_size_mm, s.pages[0][0][0]) for s in layout_map_markers(m)]
    [('ARUCO_ORIGINAL', 80.0, 0), ('4X4_50', 140.0, 0)]
    """
    groups: dict[tuple[int, float, str], list[int]] = {}
    order = {name: k for k, name in enumerate(marker_map.dictionaries)}
    on_boards = {k for k, owner in marker_map.owner.items() if getattr(marker_map.entries[owner], "kind", None)}
    if marker_map.ids and on_boards >= set(marker_map.ids):
        raise PrintError(
            f"{marker_map.source}: every marker of the map is on a board, which is printed whole with its squares "
            "and spacing: fidlearn board (a ChArUco board), or its cv_board().generateImage()"
        )
    for key in marker_map.ids:
        if key in on_boards:  # printed with its board, never as a loose marker
            continue
        name = marker_map.marker_dictionary(key)
        groups.setdefault((order[name], marker_map.marker_size(key), name), []).append(int(key))
    sheets = []
    for (_, size, name), ids in sorted(groups.items()):
        try:
            sheets.append(layout_markers(ids, size, name, paper))
        except PrintError as exc:
            largest = str(exc).split("; ")[-1].split(":")[0]
            keys = [str(k) for k in marker_map.ids if marker_map.marker_size(k) == size]
            raise PrintError(
                f"{marker_map.source}: marker{'s' if len(keys) > 1 else ''} {', '.join(keys)} "
                f"{'are' if len(keys) > 1 else 'is'} {size:g} mm, too large for one {paper} page "
                f"({largest}); print those with a print shop's large-format printer at 100 %, and the others here "
                "from a map without them"
            ) from None
    return sheets
