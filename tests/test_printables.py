"""Printables are measured, not trusted: each PDF is rasterized at 300 dpi with
pdfium (an independent PDF renderer) and measured with plain OpenCV."""

from __future__ import annotations

import os
import stat

import cv2
import numpy as np
import pytest

from fidlearn import Board, _cv, _cv_charuco
from fidlearn import printables as P
from fidlearn.boards import parse_grid
from fidlearn.printables import PrintError

pdfium = pytest.importorskip("pypdfium2")

DPI = 300
PX_PER_MM = DPI / 25.4


def rasterize(path, dpi=DPI) -> list[np.ndarray]:
    """Every page of a PDF as a gray uint8 image at ``dpi``."""
    doc = pdfium.PdfDocument(str(path))
    try:
        pages = []
        for page in doc:
            rgb = page.render(scale=dpi / 72).to_numpy()
            pages.append(cv2.cvtColor(np.ascontiguousarray(rgb[:, :, :3]), cv2.COLOR_RGB2GRAY))
        return pages
    finally:
        doc.close()


def page_size_pt(path) -> list[tuple[float, float]]:
    doc = pdfium.PdfDocument(str(path))
    try:
        return [tuple(p.get_size()) for p in doc]
    finally:
        doc.close()


def detect(gray, dictionary):
    params = _cv.make_detector_parameters(cornerRefinementMethod=_cv.corner_refine_flag("subpix"))
    corners, ids, _ = _cv.detect(_cv.make_detector(dictionary, params), gray)
    return corners, ids


def side_mm(corners: np.ndarray, px_per_mm: float = PX_PER_MM) -> np.ndarray:
    """The four side lengths (4,) of a detected quad, mm."""
    return np.linalg.norm(corners - np.roll(corners, -1, axis=0), axis=1) / px_per_mm


def black_square_sizes_mm(gray, px_per_mm=PX_PER_MM, min_mm=20):
    """Width and height (mm) of each large dark blob's outer contour: the black squares."""
    _, bw = cv2.threshold(gray, 128, 255, cv2.THRESH_BINARY_INV)
    contours, _ = cv2.findContours(bw, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    sizes = []
    for c in contours:
        x, y, w, h = cv2.boundingRect(c)
        if w > min_mm * px_per_mm and abs(w - h) < 0.2 * w:  # square, not the ruler
            sizes.append((w / px_per_mm, h / px_per_mm))
    return sizes


def ruler_ticks_mm(gray, px_per_mm=PX_PER_MM):
    """Find the ruler (one dark component about 100 mm long) and return its tick positions in mm.

    Works for a horizontal or a vertical ruler. Returns None when there is none.
    """
    _, bw = cv2.threshold(gray, 128, 255, cv2.THRESH_BINARY_INV)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(bw)
    for k in range(1, n):
        x, y, w, h = stats[k, :4]
        long_, short = max(w, h) / px_per_mm, min(w, h) / px_per_mm
        if 99 < long_ < 101.5 and 3 < short < 7:
            blob = (labels[y : y + h, x : x + w] == k).astype(np.uint8)
            if h > w:
                blob = blob.T
            # baseline: the row with the most ink; sample 1 mm beyond it, where only ticks are
            base = int(np.argmax(blob.sum(axis=1)))
            direction = 1 if base < blob.shape[0] / 2 else -1
            row = blob[base + direction * int(round(1.2 * px_per_mm))]
            edges = np.flatnonzero(np.diff(np.r_[0, row, 0]))
            starts, ends = edges[::2], edges[1::2]
            return (starts + ends - 1) / 2 / px_per_mm
    return None


# -- parsing ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "ids"),
    [("0-9", list(range(10))), ("0,3,7", [0, 3, 7]), ("0-3,8", [0, 1, 2, 3, 8]), (" 5 ", [5]), ("12-12", [12])],
)
def test_parse_ids(text, ids):
    assert P.parse_ids(text) == ids


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty"),
        ("a-b", "not an id or a range"),
        ("9-0", "runs backwards; write 0-9"),
        ("0-3,2", "id 2 is listed twice"),
        ("-1", "not an id"),
        ("1,,2", "not an id"),
    ],
)
def test_parse_ids_rejects(text, message):
    with pytest.raises(PrintError, match=message):
        P.parse_ids(text)


def test_parse_grid():
    assert parse_grid("9x6") == (9, 6)
    assert parse_grid("5X7") == (5, 7)
    with pytest.raises(PrintError, match="'9by6' is not COLUMNSxROWS; write it like 9x6"):
        parse_grid("9by6")
    with pytest.raises(PrintError, match="at least 2"):
        parse_grid("1x6")


def test_marker_cells_match_opencv_image():
    cells = P.marker_cells("ARUCO_ORIGINAL", 7)
    assert cells.shape == (7, 7)  # black border
    assert cells[0].all()
    assert cells[:, 0].all()
    img = _cv.generate_marker("ARUCO_ORIGINAL", 7, 70)
    assert np.array_equal(cells, img[5::10, 5::10] < 128)
    with pytest.raises(Exception, match="has ids 0 to 249"):
        P.marker_cells("6X6_250", 250)


# -- markers PDF ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def markers_80(tmp_path_factory):
    path = tmp_path_factory.mktemp("markers") / "markers.pdf"
    sheet = P.markers_pdf(path, P.parse_ids("0-9"), 80, dictionary="ARUCO_ORIGINAL", paper="a4")
    return path, sheet, rasterize(path)


def test_markers_pdf_exact_size_and_ids(markers_80):
    path, sheet, pages = markers_80
    found = []
    for gray in pages:
        # pdfium rounds the page size up to whole pixels
        assert np.allclose(gray.shape, (297 * PX_PER_MM, 210 * PX_PER_MM), atol=1)
        corners, ids = detect(gray, "ARUCO_ORIGINAL")
        for c in corners:
            sides = side_mm(c)
            assert np.all(np.abs(sides - 80.0) < 0.5), sides
        for w, h in black_square_sizes_mm(gray):
            assert abs(w - 80.0) < 0.5, (w, h)
            assert abs(h - 80.0) < 0.5, (w, h)
        assert len(black_square_sizes_mm(gray)) == len(ids)
        found += ids.tolist()
    assert sorted(found) == list(range(10))  # every id once, none misread


def text_boxes_px(path, page_index=0, dpi=DPI):
    """{text line: (x0, y0, x1, y1) in px at ``dpi``, y down} for the text of one PDF page."""
    doc = pdfium.PdfDocument(str(path))
    try:
        page = doc[page_index]
        height_pt = page.get_size()[1]
        tp = page.get_textpage()
        text = tp.get_text_range()
        boxes, start = {}, 0
        for line in text.split("\r\n"):
            chars = [tp.get_charbox(start + k) for k in range(len(line)) if not line[k].isspace()]
            if chars:
                x0 = min(c[0] for c in chars)
                x1 = max(c[2] for c in chars)
                y0 = min(c[1] for c in chars)
                y1 = max(c[3] for c in chars)
                k = dpi / 72
                boxes[line] = (x0 * k, (height_pt - y1) * k, x1 * k, (height_pt - y0) * k)
            start += len(line) + 2
        return boxes
    finally:
        doc.close()


def test_each_marker_has_its_id_under_it(markers_80):
    path, sheet, pages = markers_80
    cell_px = 80 / 7 * PX_PER_MM
    for k, gray in enumerate(pages):
        boxes = text_boxes_px(path, k)
        corners, ids = detect(gray, "ARUCO_ORIGINAL")
        for c, i in zip(corners, ids):
            x0, x1 = c[:, 0].min(), c[:, 0].max()
            bottom = c[:, 1].max()
            ((label, (bx0, by0, bx1, by1)),) = [(t, b) for t, b in boxes.items() if t.startswith(f"id {i} ")]
            assert label == f"id {i} ARUCO_ORIGINAL 80 mm"
            assert x0 < (bx0 + bx1) / 2 < x1  # centred under the marker
            assert bottom + cell_px < by0  # below its quiet zone
            assert by1 < bottom + cell_px + 7 * PX_PER_MM
        assert "100 mm ruler: print at 100 % (actual size)," in boxes
        assert f"fidlearn markers, ARUCO_ORIGINAL, black square 80 mm, page {k + 1} of 5" in boxes


def test_markers_pdf_is_vector_not_raster(markers_80):
    import pypdfium2.raw as pdfium_raw

    path, _, _ = markers_80
    doc = pdfium.PdfDocument(str(path))
    try:
        kinds = {obj.type for page in doc for obj in page.get_objects()}
    finally:
        doc.close()
    assert pdfium_raw.FPDF_PAGEOBJ_PATH in kinds
    assert pdfium_raw.FPDF_PAGEOBJ_IMAGE not in kinds  # no bitmap anywhere: every cell is a path


def test_markers_pdf_is_multipage_a4(markers_80):
    path, sheet, pages = markers_80
    # A4 is 210 mm wide: one 80 mm marker plus its 2 x 11.4 mm quiet zone per row, two rows.
    assert [tuple(round(v) for v in s) for s in page_size_pt(path)] == [(595, 842)] * 5
    assert len(pages) == len(sheet.pages) == 5


def test_markers_have_a_quiet_zone_of_one_cell(markers_80):
    _, sheet, pages = markers_80
    corners, _ = detect(pages[0], "ARUCO_ORIGINAL")
    _, bw = cv2.threshold(pages[0], 128, 255, cv2.THRESH_BINARY_INV)
    cell_px = 80 / 7 * PX_PER_MM
    for c in corners:
        x0, y0 = c.min(axis=0)
        x1, y1 = c.max(axis=0)
        m = int(cell_px) - 2
        ring = bw[int(y0) - m : int(y1) + m, int(x0) - m : int(x1) + m].copy()
        ring[m - 3 : ring.shape[0] - m + 3, m - 3 : ring.shape[1] - m + 3] = 0  # blank the marker itself
        assert ring.max() == 0, "something printed within one cell of a marker"


def test_cut_marks_at_the_corners_of_each_piece(markers_80):
    _, sheet, pages = markers_80
    _, bw = cv2.threshold(pages[0], 160, 255, cv2.THRESH_BINARY_INV)
    corners, _ = detect(pages[0], "ARUCO_ORIGINAL")
    cell = 80 / 7 * PX_PER_MM
    mm = PX_PER_MM
    for c in corners:
        left, top = c[:, 0].min() - cell, c[:, 1].min() - cell  # the piece: marker plus its quiet zone...
        right = c[:, 0].max() + cell
        bottom = c[:, 1].max() + cell + 7 * mm  # ...plus the label strip
        for x, y, sx, sy in ((left, top, -1, -1), (right, top, 1, -1), (left, bottom, -1, 1), (right, bottom, 1, 1)):
            xi, yi = int(round(x)), int(round(y))
            # a horizontal mark on the cut line, from 1 to 4 mm outside the corner, and a vertical one
            seg_x = sorted((int(x + sx * 1.3 * mm), int(x + sx * 3.7 * mm)))
            seg_y = sorted((int(y + sy * 1.3 * mm), int(y + sy * 3.7 * mm)))
            assert bw[yi - 2 : yi + 3, seg_x[0] : seg_x[1]].any(axis=0).all(), (x, y)
            assert bw[seg_y[0] : seg_y[1], xi - 2 : xi + 3].any(axis=1).all(), (x, y)
            assert not bw[yi - 2 : yi + 3, int(x - sx * 0.5 * mm) - 1 : int(x - sx * 0.5 * mm) + 2].any()  # not inside


def test_ruler_is_100mm_with_mm_ticks(markers_80):
    _, _, pages = markers_80
    for gray in pages:
        ticks = ruler_ticks_mm(gray)
        assert ticks is not None, "no 100 mm ruler on the page"
        assert len(ticks) == 101
        assert ticks[-1] - ticks[0] == pytest.approx(100.0, abs=0.2)
        assert np.allclose(np.diff(ticks), 1.0, atol=0.1)


def test_markers_fit_one_page_when_small(tmp_path):
    path = tmp_path / "small.pdf"
    P.markers_pdf(path, [0, 3, 7, 8], 40, dictionary="6X6_250", paper="letter")
    ((w, h),) = page_size_pt(path)
    assert (w, h) == pytest.approx((612, 792), abs=0.01)  # US letter, 8.5 x 11 in
    (gray,) = rasterize(path)
    corners, ids = detect(gray, "6X6_250")
    assert sorted(ids.tolist()) == [0, 3, 7, 8]
    for c in corners:
        assert np.all(np.abs(side_mm(c) - 40.0) < 0.5)


def test_markers_png_at_dpi(tmp_path):
    sheet, files = P.markers_png(tmp_path / "m.png", [4, 5], 80, dictionary="ARUCO_ORIGINAL", paper="a4", dpi=150)
    assert files == [tmp_path / "m.png"]
    img = cv2.imread(str(files[0]), cv2.IMREAD_GRAYSCALE)
    assert img.shape == (round(297 / 25.4 * 150), round(210 / 25.4 * 150)) == (1754, 1240)
    corners, ids = detect(img, "ARUCO_ORIGINAL")
    assert sorted(ids.tolist()) == [4, 5]
    for c in corners:
        assert np.all(np.abs(side_mm(c, 150 / 25.4) - 80.0) < 0.5)
    assert ruler_ticks_mm(img, 150 / 25.4) is not None


def test_markers_png_several_pages_are_numbered(tmp_path):
    _, files = P.markers_png(tmp_path / "m.png", [0, 1, 2], 80, dpi=40)
    assert files == [tmp_path / "m-1.png", tmp_path / "m-2.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m-1.png", "m-2.png"]


def test_marker_too_big_for_the_paper_names_the_largest(tmp_path):
    with pytest.raises(PrintError, match=r"does not fit on a4 paper; the largest that fits is (\d+\.?\d*) mm") as e:
        P.markers_pdf(tmp_path / "m.pdf", [0], 200)
    largest = float(e.value.args[0].split("largest that fits is ")[1].split(" mm")[0])
    P.layout_markers([0], largest)  # the size it names does fit
    assert list(tmp_path.iterdir()) == []


def test_marker_id_outside_dictionary(tmp_path):
    with pytest.raises(Exception, match="marker id 50 does not exist in 4X4_50, which has ids 0 to 49"):
        P.markers_pdf(tmp_path / "m.pdf", [49, 50], 50, dictionary="4X4_50")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("size", [0, -80, float("nan")])
def test_marker_size_must_be_positive(size):
    with pytest.raises(PrintError, match="--size-mm must be a positive length in mm"):
        P.layout_markers([0], size)


# -- boards -------------------------------------------------------------------------------------
def chessboard_spacing_mm(gray, pattern, px_per_mm=PX_PER_MM):
    found, corners = cv2.findChessboardCorners(gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH)
    assert found, "OpenCV does not find the printed chessboard"
    corners = cv2.cornerSubPix(
        gray, corners, (11, 11), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
    )
    grid = corners.reshape(pattern[1], pattern[0], 2)
    along_rows = np.linalg.norm(np.diff(grid, axis=1), axis=2).ravel()
    along_cols = np.linalg.norm(np.diff(grid, axis=0), axis=2).ravel()
    return np.r_[along_rows, along_cols] / px_per_mm


def test_checkerboard_pdf_square_size(tmp_path):
    path = tmp_path / "board.pdf"
    sheet = P.board_pdf(path, Board.checkerboard((9, 6), 25), "a4")
    assert sheet.board.squares == (10, 7)
    assert sheet.board.inner_corners == (9, 6)
    (gray,) = rasterize(path)
    # 250 x 175 mm only fits A4 turned to landscape
    assert np.allclose(gray.shape, (210 * PX_PER_MM, 297 * PX_PER_MM), atol=1)
    spacing = chessboard_spacing_mm(gray, (9, 6))
    assert len(spacing) == 8 * 6 + 9 * 5
    assert np.all(np.abs(spacing - 25.0) < 0.2), (spacing.min(), spacing.max())
    assert abs(spacing.mean() - 25.0) < 0.05
    ticks = ruler_ticks_mm(gray)
    assert ticks is not None
    assert len(ticks) == 101
    assert ticks[-1] - ticks[0] == pytest.approx(100.0, abs=0.2)


def test_checkerboard_png_square_size(tmp_path):
    sheet, files = P.board_png(tmp_path / "board.png", Board.checkerboard((6, 4), 20), "letter", dpi=200)
    assert files == [tmp_path / "board.png"]
    assert not sheet.landscape
    gray = cv2.imread(str(tmp_path / "board.png"), cv2.IMREAD_GRAYSCALE)
    assert gray.shape == (round(279.4 / 25.4 * 200), round(215.9 / 25.4 * 200)) == (2200, 1700)
    spacing = chessboard_spacing_mm(gray, (6, 4), 200 / 25.4)
    assert np.all(np.abs(spacing - 20.0) < 0.2)


def test_charuco_pdf_detected_by_opencv(tmp_path):
    path = tmp_path / "charuco.pdf"
    sheet = P.board_pdf(path, Board.parse("4x6", 30, charuco=True, marker_size_mm=22, dictionary="6X6_250"), "a4")
    assert sheet.board.squares == (5, 7)
    (gray,) = rasterize(path)
    board = _cv_charuco.charuco_board((5, 7), 30.0, 22.0, "6X6_250")
    ch_corners, ch_ids, m_corners, m_ids = _cv_charuco.charuco_detector(board).detectBoard(gray)
    assert ch_ids is not None
    assert sorted(np.asarray(ch_ids).ravel().tolist()) == list(range(4 * 6))
    assert sorted(np.asarray(m_ids).ravel().tolist()) == list(range(17))  # (5*7)//2 markers
    for c in m_corners:
        assert np.all(np.abs(side_mm(np.asarray(c).reshape(4, 2)) - 22.0) < 0.5)
    # corner 0 and corner 3 are one row of 3 squares apart
    pts = np.asarray(ch_corners).reshape(-1, 2)[np.argsort(np.asarray(ch_ids).ravel())]
    assert np.linalg.norm(pts[3] - pts[0]) / PX_PER_MM == pytest.approx(90.0, abs=0.3)
    assert ruler_ticks_mm(gray) is not None


def test_charuco_board_size_printed_on_page():
    sheet = P.layout_board(Board.charuco((10, 7), 25, 20, "DICT_6X6_250"), "a4")
    assert sheet.describe() == "ChArUco 10x7 squares (9x6 inner corners), square 25 mm, marker 20 mm, 6X6_250"
    fig = P.board_figure(sheet)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "fidlearn " + sheet.describe() in texts


def test_board_keeps_its_quiet_zone_inside_the_margins():
    for pattern, square, paper in [
        ((10, 7), 25, "a4"),
        ((10, 7), 25, "letter"),
        ((7, 5), 30, "a4"),
        ((12, 9), 12, "letter"),
    ]:
        sheet = P.layout_board(Board("checkerboard", pattern, square), paper)
        q = P.board_quiet_zone_mm(square)
        (x, y), (w, h), (pw, ph) = sheet.origin_mm, sheet.board_mm, sheet.paper_mm
        assert x - q >= P.PAGE_MARGIN_MM - 1e-9
        assert y - q >= P.PAGE_MARGIN_MM - 1e-9
        assert x + w + q <= pw - P.PAGE_MARGIN_MM + 1e-9
        assert y + h + q <= ph - P.PAGE_MARGIN_MM + 1e-9
        # and off the ruler strip
        if sheet.strip == "bottom":
            assert y + h + q <= ph - P.PAGE_MARGIN_MM - P.STRIP_MM + 1e-9
        else:
            assert x + w + q <= pw - P.PAGE_MARGIN_MM - P.STRIP_MM + 1e-9


def test_board_too_big_names_largest_square(tmp_path):
    with pytest.raises(PrintError, match=r"the largest square that fits is (\d+\.\d) mm: use --square-mm") as e:
        P.board_pdf(tmp_path / "b.pdf", Board.checkerboard((9, 6), 40), "a4")
    largest = float(e.value.args[0].split("use --square-mm ")[1].split(" ")[0])
    P.layout_board(Board.checkerboard((9, 6), largest), "a4")  # fits
    with pytest.raises(PrintError):
        P.layout_board(Board.checkerboard((9, 6), largest + 0.2), "a4")
    assert list(tmp_path.iterdir()) == []


def test_charuco_rejects_marker_bigger_than_square():
    with pytest.raises(PrintError, match=r"marker_size_mm \(30\) must be smaller than square_size_mm \(25\)"):
        Board.charuco((10, 7), 25, 30)
    with pytest.raises(PrintError, match="needs 55 markers but 4X4_50 has only 50"):
        Board.charuco((11, 10), 10, 7, "4X4_50")
    with pytest.raises(PrintError, match=r"board must be a fidlearn.Board"):
        P.layout_board((10, 7), "a4")


def test_unknown_output_type(tmp_path):
    with pytest.raises(PrintError, match="name the file .pdf or .png"):
        P.save_pages([], tmp_path / "m.svg")


@pytest.mark.skipif(os.name != "posix", reason="POSIX permission bits")
def test_png_pages_get_umask_permissions(tmp_path):
    # The pages are rendered to mkstemp files (mode 0o600) and renamed: they must end up
    # readable as any file the user writes (0o644 under umask 022), not private.
    old = os.umask(0o022)
    try:
        _, files = P.markers_png(tmp_path / "m.png", [0, 1, 2], 80, dpi=40)
    finally:
        os.umask(old)
    assert [stat.S_IMODE(os.stat(f).st_mode) for f in files] == [0o644, 0o644]


@pytest.mark.parametrize(
    "make", [lambda out: P.markers_pdf(out, [0], 0.08), lambda out: P.board_pdf(out, Board.checkerboard((9, 6), 0.025))]
)
def test_sizes_in_metres_are_refused(tmp_path, make):
    # 0.08 (metres, as OpenCV's tutorials write it) printed a sheet of 0.08 mm markers.
    with pytest.raises(PrintError, match=r"under 1 mm; if that is metres, give millimetres \((80|25)\)"):
        make(tmp_path / "out.pdf")
    assert list(tmp_path.iterdir()) == []


def test_a_sheet_printed_after_others_is_numbered_in_the_whole_document():
    """A map of two sizes printed two sheets into one PDF, each page saying 'page 1 of 1'."""
    import matplotlib.pyplot as plt  # noqa: PLC0415

    sheet = P.layout_markers([0, 1], 80, "ARUCO_ORIGINAL")
    own = P.marker_figures(sheet)
    joined = P.marker_figures(sheet, first_page=3, pages=4)

    def titles(figs):
        return [t.get_text() for f in figs for ax in f.axes for t in ax.texts if "page" in t.get_text()] + [
            ax.get_title() for f in figs for ax in f.axes if "page" in ax.get_title()
        ]

    assert any("page 1 of 1" in t for t in titles(own))
    assert any("page 3 of 4" in t for t in titles(joined))
    plt.close("all")


@pytest.mark.parametrize(
    ("dictionary", "size_mm"), [("ARUCO_ORIGINAL", 10), ("ARUCO_ORIGINAL", 15), ("APRILTAG_36h11", 12)]
)
def test_a_small_markers_label_fits_in_its_cut_rectangle(dictionary, size_mm):
    """The label's second line ran wider than the rectangle cut around the marker (23 mm in 19 mm at 15 mm), so
    that cutting halved it and neighbouring labels met."""
    import matplotlib.pyplot as plt  # noqa: PLC0415
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415

    sheet = P.layout_markers(range(100, 106), size_mm, dictionary)
    fig = P.marker_figures(sheet)[0]
    FigureCanvasAgg(fig)
    ax = fig.axes[0]
    label = next(t for t in ax.texts if t.get_text().startswith(dictionary))
    box = label.get_window_extent(fig.canvas.get_renderer())
    (x0, _), (x1, _) = ax.transData.inverted().transform([[box.x0, box.y0], [box.x1, box.y1]])
    assert x1 - x0 <= size_mm + 2 * sheet.cell_mm
    plt.close("all")
