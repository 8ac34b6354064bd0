"""The interactive views: their drawing functions are pure and follow the camera model."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from fidlearn import Camera, widgets  # noqa: E402
from fidlearn.errors import CameraError  # noqa: E402

BASE = dict(fx=500.0, fy=500.0, cx=319.5, cy=239.5)


def grid_centre(polylines):
    """The pixel of the grid's centre point (the middle of the middle vertical line)."""
    n_vertical = len(np.arange(-widgets.GRID_HALF_WIDTH_MM, widgets.GRID_HALF_WIDTH_MM + 1e-9, widgets.GRID_STEP_MM))
    mid = polylines[n_vertical // 2]
    return mid[len(mid) // 2]


def test_grid_centre_lands_on_the_principal_point():
    lines = widgets.intrinsics_view_polylines(500, 450, 300.0, 200.0, k1=-0.2)
    assert np.allclose(grid_centre(lines), [300.0, 200.0])


def test_projection_follows_u_equals_fx_x_over_z_plus_cx():
    lines = widgets.intrinsics_view_polylines(**BASE)
    pts = widgets.grid_polylines_mm()
    for px, xyz in zip(lines, pts):
        u = BASE["fx"] * xyz[:, 0] / xyz[:, 2] + BASE["cx"]
        v = BASE["fy"] * xyz[:, 1] / xyz[:, 2] + BASE["cy"]
        assert np.allclose(px, np.column_stack([u, v]))


def test_doubling_fx_doubles_horizontal_distances_from_cx():
    a = widgets.intrinsics_view_polylines(**BASE)
    b = widgets.intrinsics_view_polylines(**{**BASE, "fx": 1000.0})
    for la, lb in zip(a, b):
        assert np.allclose(lb[:, 0] - BASE["cx"], 2 * (la[:, 0] - BASE["cx"]))
        assert np.allclose(lb[:, 1], la[:, 1])


def test_distortion_bends_straight_lines():
    def bend(line):  # largest distance of a line's points from the chord joining its ends
        a, b = line[0], line[-1]
        d = (b - a) / np.linalg.norm(b - a)
        rel = line - a
        return np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0]).max()

    straight = widgets.intrinsics_view_polylines(**BASE, k1=0.0)
    barrel = widgets.intrinsics_view_polylines(**BASE, k1=-0.3)
    assert max(bend(line) for line in straight) < 1e-6
    assert max(bend(line) for line in barrel) > 5.0  # pixels


def test_render_is_pure_and_changes_when_fx_changes():
    n_before = len(plt.get_fignums())
    fig_a = widgets.render_intrinsics_view(**BASE)
    fig_b = widgets.render_intrinsics_view(**{**BASE, "fx": 900.0})
    assert len(plt.get_fignums()) == n_before  # pyplot never sees these figures
    (ax_a,), (ax_b,) = fig_a.axes, fig_b.axes
    n_lines = len(widgets.grid_polylines_mm())
    xa = np.concatenate([line.get_xdata() for line in ax_a.lines[:n_lines]])
    xb = np.concatenate([line.get_xdata() for line in ax_b.lines[:n_lines]])
    assert not np.allclose(xa, xb)
    assert "fx=500" in ax_a.get_title()
    assert "fx=900" in ax_b.get_title()
    # the field of view in the title is the camera's
    hfov = Camera([[500, 0, 319.5], [0, 500, 239.5], [0, 0, 1]], None, (640, 480)).fov_deg[0]
    assert f"{hfov:.1f} x" in ax_a.get_title()
    assert ax_a.get_xlim() == (-0.5, 639.5)
    assert ax_a.get_ylim() == (479.5, -0.5)
    png_a, png_b = widgets.figure_png(fig_a), widgets.figure_png(fig_b)
    assert png_a.startswith(b"\x89PNG")
    assert png_a != png_b
    assert widgets.figure_png(widgets.render_intrinsics_view(**BASE)) == png_a  # same input, same picture


def test_render_rejects_impossible_intrinsics():
    from fidlearn import CameraError

    with pytest.raises(CameraError, match="focal lengths"):
        widgets.render_intrinsics_view(0.0, 500, 320, 240)


def _sliders(box):
    import ipywidgets as W

    found = {}

    def walk(w):
        if isinstance(w, W.FloatSlider):
            found[w.description] = w
        for child in getattr(w, "children", ()):
            walk(child)

    walk(box)
    return found


def test_explorer_has_the_five_sliders_starting_at_the_camera(monkeypatch):
    import ipywidgets as W

    calls = []
    real = widgets.render_intrinsics_view

    def spy(*args, **kw):
        calls.append((*args, *kw.values()))
        return real(*args, **kw)

    monkeypatch.setattr(widgets, "render_intrinsics_view", spy)
    cam = Camera([[700.0, 0, 300.0], [0, 710.0, 250.0], [0, 0, 1]], [-0.1, 0, 0, 0, 0], (640, 480))
    box = widgets.intrinsics_explorer(cam)
    assert isinstance(box, W.VBox)
    assert isinstance(box.children[-1], W.Output)
    s = _sliders(box)
    assert set(s) == {"fx", "fy", "cx", "cy", "k1"}
    assert all(not sl.continuous_update for sl in s.values())
    assert (s["fx"].value, s["fy"].value, s["cx"].value, s["cy"].value, s["k1"].value) == (700, 710, 300, 250, -0.1)
    assert calls[-1] == (700.0, 710.0, 300.0, 250.0, -0.1, (640, 480))  # drawn once at start
    s["fx"].value = 1200.0  # moving a slider redraws with the new value
    assert calls[-1][0] == 1200.0
    assert len(calls) == 2
    # a long lens starts where it is (the sliders stopped at 2000 and clamped it there); a fisheye is refused
    tele = Camera.from_fov(30, (1920, 1080))
    assert _sliders(widgets.intrinsics_explorer(tele))["fx"].value == pytest.approx(tele.fx, abs=10)
    fish = Camera(cam.K, [0.4, 0, 0, 0], (640, 480), model="fisheye")
    with pytest.raises(CameraError, match="is a fisheye"):
        widgets.intrinsics_explorer(fish)
