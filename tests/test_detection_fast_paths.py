"""The shortcuts of the detection give what the code they replaced gave: the edges refinement's profiles sampled
sample by sample (S, M, 4, N) instead of side by side (M, 4, N, S), their levels and edge crossings, the profiles
read a part at a time, the outline check's order and Detections, OpenCV's corners converted in one call, and a
map's ids checked once."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn import Camera, MarkerMap, MarkerPlacement, _cv
from fidlearn import refinement as R
from fidlearn._detector import _checked_ids, _wanted_ids
from fidlearn.detection import (
    Detection,
    _detector,
    _outlined,
    detect_markers,
)
from fidlearn.errors import DictionaryError, FidlearnError
from fidlearn.frames import look_at
from fidlearn.synthetic import render_scene

CELLS = 6  # 4X4_50 with its one-cell border


def _profiles_side_by_side(gray, Z, cells, u, v, shift):
    """The profiles as the edges refinement sampled them before, side by side: (M, 4, N, S) float32 (the code
    :func:`fidlearn.refinement._profiles_across` replaced, kept here as the reference)."""
    M = Z.shape[0]
    n_lines, n_samples = u.size, v.size
    Dz = Z[:, R._NEXT] - Z
    L = np.maximum(np.abs(Dz), 1e-9)
    nz = Dz * (np.where((Dz[:, 0].conj() * Dz[:, 1]).imag >= 0, -1j, 1j)[:, None] / L)
    cell = L.sum(1) * (0.25 / cells)
    h = np.minimum(np.maximum(0.6 * cell, 1.5), 5.0)
    margin = np.minimum((0.5 * cell[:, None] + 1.5) / L, 0.3)
    span = 1.0 - 2.0 * margin
    t = margin[..., None] + span[..., None] * u
    pts = (Z[..., None] + t * Dz[..., None])[..., None] + (shift + h[:, None] * v)[:, None, None, :] * nz[
        ..., None, None
    ]
    maps = pts.astype(np.complex64).view(np.float32).reshape(M * 4, n_lines * n_samples, 2)
    prof = cv2.remap(gray, maps, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    prof = prof.reshape(M, 4, n_lines, n_samples).astype(np.float32)
    return Dz, L, nz, cell, h, margin, span, prof


def _refine_side_by_side(gray, corners, cells, inverted=False, iterations=1, expand_px=0.5, gamma=1.0):
    """The edges refinement as it was, profile by profile (``_levels`` and ``_edge_offsets`` are still the
    fisheye side fit's)."""
    C = np.ascontiguousarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    u, v, U3 = R._profile_grid(16, 13)
    Z = C.view(np.complex128)[..., 0]
    shift = float(expand_px)
    fitted = np.ones(len(C), dtype=bool)
    for _ in range(iterations):
        Dz, L, nz, cell, h, margin, span, prof = _profiles_side_by_side(gray, Z, cells, u, v, shift)
        prof, dark, light, level = R._levels(prof, inverted, gamma)
        off, w = R._edge_offsets(prof, level, dark, light, h, shift, R._CHECK_CONTRAST)
        alpha, beta, sw, det = R._fit_lines(w, off, u, U3)
        b = beta / span
        a = alpha - b * margin
        A, d = Z + a * nz, Dz + b * nz
        Ap, dp = A[:, R._PREV], d[:, R._PREV]
        den = (dp.conj() * d).imag
        ok = ((sw >= 4) & (det > 1e-9) & (np.abs(den) > 1e-9 * L * L)).all(1)
        new = Ap + ((A - Ap).conj() * d).imag / np.where(ok[:, None], den, 1.0) * dp
        ok &= np.abs(new - Z).max(1) < np.maximum(3.0, 0.5 * cell)
        fitted &= ok
        Z = np.where((ok & (light - dark > R._FIT_CONTRAST).all(1))[:, None], new, Z)
        shift = 0.0
    return np.stack([Z.real, Z.imag], axis=-1), fitted


@pytest.fixture(scope="module")
def wall():
    """A 640x480 wall of 12 4X4_50 markers (30-40 px) tilted and rolled, its rendered corners, OpenCV's raw quads
    of them, and those quads moved about: (gray, truth {id: (4, 2)}, quads (M, 4, 2))."""
    places = {
        i: MarkerPlacement(i, (0.0, (i % 4) * 260.0, 1500.0 - (i // 4) * 260.0), (0.0, 0.0, 0.0)) for i in range(12)
    }
    m = MarkerMap(places, 160.0, dictionary="4X4_50", units="mm")
    cam = Camera.from_fov(70, (640, 480))
    T = look_at([2600.0, 700.0, 1600.0], [0.0, 390.0, 1240.0], roll_deg=8)
    scene = render_scene(m, cam, T, seed=4, blur_px=0.7, noise_std_gray=1.5, gradient=0.15)
    gray = scene.image
    det, cells, _ = _detector("DICT_4X4_50", "edges", None, None)
    raw, ids, _ = _cv.detect_stacked(det, gray)
    assert sorted(ids.tolist()) == list(range(12))
    rng = np.random.default_rng(11)
    moved = raw + rng.normal(0, 0.8, raw.shape)
    # quads reaching past the picture's edges (sampled with the border replicated), and a flat one
    off = raw[:3] - raw[:3].min(axis=(1, 2), keepdims=True) - 6.0
    flat = np.array([[[300.0, 5.0], [330.0, 5.0], [330.0, 35.0], [300.0, 35.0]]])
    quads = np.concatenate([raw, moved, off, flat])
    return gray, {int(i): scene.truth[int(i)] for i in ids}, quads, raw, ids


def test_profiles_sample_by_sample_are_the_profiles_side_by_side(wall):
    gray, _, quads, _, _ = wall
    u, v, _ = R._profile_grid(16, 13)
    Z = quads.view(np.complex128)[..., 0]
    for shift in (0.5, 0.0):
        new = R._profiles_across(gray, Z, CELLS, u, v, shift)
        old = _profiles_side_by_side(gray, Z, CELLS, u, v, shift)
        for a, b in zip(new[:-1], old[:-1]):  # the geometry: the same code
            assert np.array_equal(a, b)
        assert new[-1].shape == (13, len(quads), 4, 16)
        assert new[-1].dtype == np.uint8
        # the sampled points may differ in the last bit of a float32: the same gray levels but for rare samples
        same = np.moveaxis(new[-1], 0, -1).astype(np.float32) == old[-1]
        assert same.mean() > 0.999


@pytest.mark.parametrize("inverted", [False, True, None])
@pytest.mark.parametrize("gamma", [1.0, 2.2])
def test_levels_and_edges_sample_by_sample_are_the_same_numbers(wall, inverted, gamma):
    """The same profiles in both layouts give the same levels, edge offsets and weights, to the bit: real
    profiles, the picture turned negative, and random ones (crossings at the first sample, none at all)."""
    gray, _, quads, _, _ = wall
    u, v, _ = R._profile_grid(16, 13)
    Z = quads.view(np.complex128)[..., 0]
    rng = np.random.default_rng(5)
    h = np.linspace(1.5, 5.0, len(quads) + 1)
    real = R._profiles_across(gray, Z, CELLS, u, v, 0.5)[-1]
    noise = rng.integers(0, 256, size=(13, 4, 4, 16)).astype(np.uint8)
    noise[:, 0] = 200  # flat: no crossing
    noise[:, 1, :, :] = np.where(np.arange(13)[:, None, None] < 6, 20, 230).astype(np.uint8)  # a clean edge
    weights = []
    for prof in (real, 255 - real, noise):
        hh = h[: prof.shape[1]]
        across = R._levels_across(prof, inverted, gamma)
        side = R._levels(np.moveaxis(prof, 0, -1).astype(np.float32), inverted, gamma)
        assert np.array_equal(np.moveaxis(np.asarray(across[0], np.float32), 0, -1), side[0])
        for a, b in zip(across[1:], side[1:]):
            assert a.dtype == b.dtype
            assert np.array_equal(a, b)
        _, dark, light, level = side
        off_a, w_a = R._edge_offsets_across(across[0], level, dark, light, hh, 0.5, R._CHECK_CONTRAST)
        off_s, w_s = R._edge_offsets(side[0], level, dark, light, hh, 0.5, R._CHECK_CONTRAST)
        assert np.array_equal(w_a, w_s)
        assert np.array_equal(off_a, off_s, equal_nan=True)
        weights.append(w_s.ravel())
    assert np.concatenate(weights).any()
    assert not np.concatenate(weights).all()


@pytest.mark.parametrize(
    ("inverted", "gamma", "iterations"), [(False, 1.0, 1), (None, 1.0, 1), (False, 2.2, 2), (True, 1.0, 1)]
)
def test_the_refinement_gives_the_corners_it_gave_profile_by_profile(wall, inverted, gamma, iterations):
    gray, truth, quads, raw, ids = wall
    image = 255 - gray if inverted else gray
    new, ok_new = R._refine_edges(image, quads, CELLS, inverted, 16, 13, iterations, 0.5, gamma)
    old, ok_old = _refine_side_by_side(image, quads, CELLS, inverted, iterations, 0.5, gamma)
    assert np.array_equal(ok_new, ok_old)
    assert np.abs(new - old).max() < 1e-6
    assert not ok_new[-1]  # the flat quad
    if gamma == 1.0:  # and both at the rendered corners
        err = new[: len(raw)] - np.stack([truth[int(i)] for i in ids])
        assert np.sqrt((err**2).sum(-1).mean()) < 0.1


def test_many_markers_profiles_are_read_a_part_at_a_time(wall, monkeypatch):
    gray, _, quads, _, _ = wall
    whole = R._refine_edges(gray, quads, CELLS)
    monkeypatch.setattr(R, "_ROW_POINTS", 13 * 4 * 16 * 4 - 5)  # a little under four markers' samples a read
    parts = R._refine_edges(gray, quads, CELLS)
    assert np.array_equal(whole[0], parts[0])
    assert np.array_equal(whole[1], parts[1])


def test_the_outline_check_orders_and_builds_the_detections_as_before(wall):
    gray, _, quads, raw, ids = wall
    # repeated ids, and first corners at the same height, so that every key of the order counts
    corners = np.concatenate([raw, raw[:4] + [0.4, 0.0], raw[4:6] + [0.0, 0.3]])
    given = np.concatenate([ids, ids[:4], ids[4:6]]).tolist()
    for refine in (True, False):
        dets, dropped = _outlined(gray, corners, given, CELLS, False, refine, "4X4_50")
        fitted, ok = R._refine_edges(gray, corners, CELLS, False)
        assert ok.all()
        assert not dropped
        used = fitted if refine else corners
        order = sorted(range(len(given)), key=lambda k: (given[k], float(used[k][0, 1]), float(used[k][0, 0])))
        expected = [Detection(given[k], used[k], "4X4_50") for k in order]
        assert [(d.id, d.dictionary) for d in dets] == [(e.id, e.dictionary) for e in expected]
        for d, e in zip(dets, expected):
            assert type(d.id) is int
            assert d.corners_px.dtype == np.float64
            assert d.corners_px.shape == (4, 2)
            assert np.array_equal(d.corners_px, e.corners_px)
    # a list of (4, 2) quads, as the tracker passes them, gives the same
    listed, _ = _outlined(gray, list(corners), given, CELLS, False, True)
    assert [(d.id, d.dictionary) for d in listed] == [(d.id, None) for d in dets]
    assert _outlined(gray, [], [], CELLS, False, True) == ([], [])


def test_opencvs_corners_converted_at_once_are_the_per_marker_ones(wall):
    gray = wall[0]
    det, _, _ = _detector("DICT_4X4_50", "none", None, None)
    stacked, ids, rejected = _cv.detect_stacked(det, gray)
    corners, ids_each, rejected_each = _cv.detect_with_raw_rejected(det, gray)
    assert stacked.dtype == np.float64
    assert stacked.shape == (len(corners), 4, 2)
    assert np.array_equal(stacked, np.stack(corners))
    assert ids.dtype == np.int64
    assert np.array_equal(ids, ids_each)
    assert len(rejected) == len(rejected_each)
    none, no_ids, _ = _cv.detect_stacked(det, np.full((80, 80), 255, np.uint8))
    assert none.shape == (0, 4, 2)
    assert no_ids.shape == (0,)
    assert no_ids.dtype == np.int64


def test_a_maps_ids_checked_once_are_the_checked_ids():
    ids = [7, 3, 3, 12]
    assert _wanted_ids(ids, "DICT_4X4_50") == _checked_ids(ids, "DICT_4X4_50") == (3, 7, 12)
    assert _wanted_ids(ids, "DICT_4X4_50") is _wanted_ids(list(ids), "DICT_4X4_50")  # remembered
    assert _wanted_ids(np.array(ids), "DICT_4X4_50") == (3, 7, 12)  # numpy ids take the full check
    with pytest.raises(FidlearnError, match="whole marker ids"):  # as before: a generator is read only once
        _wanted_ids((i for i in ids), "DICT_4X4_50")
    with pytest.raises(FidlearnError, match=r"got \[\]"):  # the error names the ids as they were given
        _wanted_ids([], "DICT_4X4_50")
    with pytest.raises(DictionaryError, match="has ids 0 to 49"):
        _wanted_ids([3, 50], "DICT_4X4_50")
    with pytest.raises(FidlearnError, match="whole marker ids"):
        _wanted_ids([2**60 + 1], "DICT_4X4_50")  # not a float's whole number: refused, as before


def test_detect_markers_on_the_wall_finds_every_marker_at_its_corners(wall):
    gray, truth, _, _, _ = wall
    dets = detect_markers(gray, "4X4_50", ids=list(range(12)))
    assert [d.id for d in dets] == list(range(12))
    assert all(d.dictionary == _cv.dictionary_name("4X4_50") for d in dets)
    err = np.stack([d.corners_px - truth[d.id] for d in dets])
    assert np.sqrt((err**2).sum(-1).mean()) < 0.1


@pytest.mark.parametrize("interpolation", [cv2.INTER_LINEAR, cv2.INTER_CUBIC])
@pytest.mark.parametrize(("rows", "cols"), [(390, 64), (1, 5), (120, 208), (700, 64)])
def test_points_read_in_one_row_are_remaps_values_of_the_map(interpolation, rows, cols):
    """``_read_at`` reads the map's points as one row (serial in OpenCV), in parts of ``_ROW_POINTS`` when there
    are more (700 x 64 = 44,800): the values ``cv2.remap`` gives the map as it is shaped."""
    rng = np.random.default_rng(rows)
    gray = rng.integers(0, 256, size=(480, 640), dtype=np.uint8)
    maps = rng.uniform(-20, 660, size=(rows, cols, 2)).astype(np.float32)
    expected = cv2.remap(gray, maps, None, interpolation, borderMode=cv2.BORDER_REPLICATE)
    got = R._read_at(gray, maps, interpolation)
    assert got.shape == (rows, cols)
    assert np.array_equal(got, expected)
